"""Many datasets at once (multieye.many, ``multieye calibrate-many``) on the local process
pool and on a local Dask cluster: each dataset to its own folder, failures their own
outcome, the worst status, and no worker process left behind."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pose_dataset import write_pose_dataset
from proc_tree import working_descendants

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.many import calibrate_many, worst_status

pytest.importorskip("distributed", reason="the distributed extra is not installed")


def _datasets(tmp_path: Path):
    good = []
    for seed in (0, 1):
        folder = tmp_path / f"rig{seed}"
        folder.mkdir()
        _, X, Y = write_pose_dataset(folder, seed=seed)
        good.append((folder, X))
    bad = tmp_path / "broken"
    bad.mkdir()
    (bad / "rig.yaml").write_text("setup: eye-to-base\ncameras: {}\n")
    return good, bad


def _check(outcome, good, bad, out_root):
    assert [o.status for o in outcome.outcomes] == [0, 0, 2]
    assert outcome.status == 2
    for (folder, X), o in zip(good, outcome.outcomes):
        assert o.out == str(out_root / folder.name) and o.message == "ok"
        cal = json.loads((out_root / folder.name / "calibration.json").read_text())
        T = np.array(cal["cameras"]["cam1"]["T_ref_cam"])
        truth = g.inv(X[0]) @ X[1]
        assert np.allclose(T, truth, atol=1e-6)
    assert not (out_root / bad.name).exists()            # nothing written for the failure
    assert "cameras" in outcome.outcomes[2].message


@pytest.mark.parametrize("engine", ["local", "dask"])
def test_many_datasets_each_to_its_own_folder(tmp_path, engine):
    good, bad = _datasets(tmp_path)
    before = working_descendants()
    seen = []
    out = calibrate_many([good[0][0], good[1][0], bad], tmp_path / "out", engine=engine,
                         workers=2, on_done=seen.append)
    _check(out, good, bad, tmp_path / "out")
    assert sorted(o.dataset for o in seen) == sorted(o.dataset for o in out.outcomes)
    # the pool's or the cluster's worker processes are gone once the call returns
    assert out.engine == engine
    assert not working_descendants() - before


def test_worst_status_orders_failure_over_doubt():
    assert worst_status([0, 3, 0]) == 3
    assert worst_status([3, 2, 0]) == 2
    assert worst_status([]) == 0


def test_same_folder_name_is_refused(tmp_path):
    (tmp_path / "a" / "rig").mkdir(parents=True)
    (tmp_path / "b" / "rig").mkdir(parents=True)
    with pytest.raises(InputError, match="same folder name"):
        calibrate_many([tmp_path / "a" / "rig", tmp_path / "b" / "rig"], tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_unreachable_scheduler_is_one_line():
    from multieye.imaging.engines import DaskEngine

    before = working_descendants()
    with pytest.raises(InputError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9") as e:
        DaskEngine("tcp://127.0.0.1:9", timeout_s=2)
    assert "\n" not in str(e.value)
    assert not working_descendants() - before


def test_command_line_prints_each_dataset_and_exits_with_the_worst(tmp_path):
    good, bad = _datasets(tmp_path)
    r = subprocess.run([sys.executable, "-m", "multieye", "calibrate-many", str(good[0][0]),
                        str(bad), "--out-root", str(tmp_path / "out"), "--workers", "1"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert f"{good[0][0]}: ok" in r.stdout
    assert f"{bad}: error:" in r.stderr and "Traceback" not in r.stderr
    assert "1 of 2 datasets written (local engine)" in r.stdout
    assert (tmp_path / "out" / "rig0" / "calibration.json").is_file()
