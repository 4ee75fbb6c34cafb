"""Detection of a calibration on Dask distributed (calibrate(engine="dask"),
``multieye calibrate --engine dask``): the local pool's result, no worker left behind."""

from __future__ import annotations


import numpy as np
import pytest
from click.testing import CliRunner

from proc_tree import working_descendants
from small_dataset import render_small

from multieye.cli import main
from multieye.core.errors import InputError
from multieye.pipeline import calibrate

pytest.importorskip("distributed", reason="the distributed extra is not installed")


def test_detection_on_a_local_dask_cluster_gives_the_local_result(tmp_path):
    render_small(tmp_path / "d")
    here = calibrate(tmp_path / "d", processes=1)
    before = working_descendants()
    there = calibrate(tmp_path / "d", processes=2, engine="dask")
    assert not working_descendants() - before
    for name in here.cameras:
        assert [o.name for o in there.cameras[name].observations] == \
            [o.name for o in here.cameras[name].observations]
        np.testing.assert_allclose(there.T_ref_cam[name], here.T_ref_cam[name], atol=1e-9)
    with pytest.raises(InputError, match="needs the dask engine"):
        calibrate(tmp_path / "d", scheduler="tcp://127.0.0.1:8786")
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path / "d"), "-o", str(tmp_path / "o"),
                                    "--engine", "dask", "--processes", "2"])
    assert res.exit_code in (0, 3), res.output
    assert (tmp_path / "o" / "calibration.json").is_file()
    assert not working_descendants() - before
