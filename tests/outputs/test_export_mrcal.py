"""``multieye export --format mrcal``: one .cameramodel per camera, read back by multieye's
intrinsics reader (and by mrcal itself when it is importable or MULTIEYE_MRCAL_PYTHON names a
Python that has it)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.io.intrinsics_files import read_intrinsics
from multieye.outputs.details import write_run_details
from multieye.outputs.export import export
from multieye.outputs.write import write_outputs

from export_runs import NAMES, make_run  # noqa: E402


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mrcal")
    run, _ = make_run(folder, "eye-to-base")
    write_outputs(run, folder)
    write_run_details(folder / "details.json", run)
    return folder, run.record


def test_one_cameramodel_per_camera_reads_back(out):
    folder, rec = out
    notes: list[str] = []
    paths = export(folder, "mrcal", notes=notes)
    assert notes == []
    # names that cannot be file names are reduced as docs/outputs.md says (core.names.file_stem)
    assert paths == [folder / "export" / "mrcal" / f"{n}.cameramodel"
                     for n in ("cam0", "front left", "rear_&__q_")]
    for j, (path, cam) in enumerate(zip(paths, rec.cameras)):
        back = read_intrinsics(path)
        np.testing.assert_array_equal(back.K, [[500 + 10 * j, 0, 319.5], [0, 501 + 10 * j, 239.5],
                                               [0, 0, 1]])
        np.testing.assert_array_equal(back.dist, [-0.2, 0.05, 1e-4, -2e-4])
        assert (back.width, back.height) == (640, 480)
        text = path.read_text()
        assert "'lensmodel':  'LENSMODEL_OPENCV4'" in text
        rt = json.loads(text.split("'rt_cam_ref': ", 1)[1].split(",\n", 1)[0])
        T_cam_ref = g.transform_from_rotvec(rt[:3], rt[3:])
        np.testing.assert_allclose(g.inv(T_cam_ref), cam.T_ref_cam, atol=1e-12)
    _mrcal_check(paths, rec)


def _mrcal_check(paths, rec):
    """mrcal's own reader: lens model, intrinsics and rt_cam_ref as written."""
    python = None
    try:
        import mrcal  # noqa: F401
        python = sys.executable
    except ImportError:
        python = os.environ.get("MULTIEYE_MRCAL_PYTHON")
    if not python:
        return           # the reading by multieye above stands; mrcal's is in test_io_*
    code = ("import sys, json, mrcal\nfor p in sys.argv[1:]:\n    m = mrcal.cameramodel(p)\n"
            "    print(json.dumps([m.intrinsics()[0], m.intrinsics()[1].tolist(), "
            "m.rt_cam_ref().tolist()]))\n")
    res = subprocess.run([python, "-c", code, *map(str, paths)], capture_output=True,
                         text=True, timeout=120, check=True)
    for line, cam in zip(res.stdout.splitlines(), rec.cameras):
        name, values, rt = json.loads(line)
        assert name == "LENSMODEL_OPENCV4" and values[4:] == [-0.2, 0.05, 1e-4, -2e-4]
        T = g.transform_from_rotvec(rt[:3], rt[3:])
        np.testing.assert_allclose(g.inv(T), cam.T_ref_cam, atol=1e-12)


def test_cameras_mrcal_cannot_hold_are_named(out, tmp_path, monkeypatch):
    import multieye.outputs.export as exp

    folder, rec = out
    real = exp._intrinsics

    def fisheye_first(o, r, *, required):
        found = dict(real(o, r, required=required))
        first = rec.cameras[0].name
        found[first] = Intrinsics(found[first].K, [0.1, 0.01, 0.0, 0.0], "fisheye", 640, 480)
        found[rec.cameras[1].name] = None
        return found

    monkeypatch.setattr(exp, "_intrinsics", fisheye_first)
    notes: list[str] = []
    paths = export(folder, "mrcal", dest=tmp_path, notes=notes)
    assert [p.name for p in paths] == ["rear_&__q_.cameramodel"]
    assert notes == [f"no .cameramodel for {NAMES[0]} (mrcal has no lens model for OpenCV's "
                     f"fisheye); {NAMES[1]} (no intrinsics)"]
