"""Issue 20 on a published robot set: Open3DV eye-in-hand with its intrinsics in JSON (``K`` and
``dist``, as many toolkits write them) calibrates exactly as with the committed OpenCV YAML;
before, ``dist`` was dropped without a word. The same file without its distortion moves the
camera, which is what the dropped key cost."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from multieye.cli import main
from multieye.core import geometry as g
from multieye.io.intrinsics_files import read_intrinsics

from robot_sets import published_with_rig  # noqa: E402


def _run(shared, tmp_path, name, intrinsics_text=None):
    dataset = published_with_rig(shared, tmp_path / name, "open3dv_eih")
    if intrinsics_text is not None:
        (dataset / "cam0.json").write_text(intrinsics_text)
        rig = (dataset / "rig.yaml").read_text()
        assert "intrinsics: cam0.yaml" in rig
        (dataset / "rig.yaml").write_text(rig.replace("intrinsics: cam0.yaml",
                                                      "intrinsics: cam0.json"))
    out = tmp_path / f"{name}_out"
    res = CliRunner().invoke(main, ["calibrate", str(dataset), "-o", str(out),
                                    "--processes", "1"])
    assert res.exit_code in (0, 3), (res.exit_code, res.stdout, res.stderr)
    cal = json.loads((out / "calibration.json").read_text())
    return res.exit_code, np.array(cal["cameras"]["cam0"]["T_body_cam"])


def test_open3dv_json_k_dist_calibrates_as_opencv_yaml(shared_data, tmp_path):
    yaml_intr = read_intrinsics(published_with_rig(shared_data, tmp_path / "read", "open3dv_eih")
                                / "cam0.yaml")
    layout = {"K": yaml_intr.K.tolist(), "dist": [yaml_intr.dist.tolist()],
              "width": yaml_intr.width, "height": yaml_intr.height}
    status_yaml, T_yaml = _run(shared_data, tmp_path, "yaml")
    status_json, T_json = _run(shared_data, tmp_path, "json", json.dumps(layout))
    assert status_yaml == status_json == 0
    np.testing.assert_array_equal(T_json, T_yaml)        # the same numbers, the same result
    del layout["dist"]
    _, T_nodist = _run(shared_data, tmp_path, "nodist", json.dumps(layout))
    d = g.inv(T_yaml) @ T_nodist
    angle = np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1, 1)))
    shift_mm = 1e3 * np.linalg.norm(d[:3, 3])
    print(f"without dist: {angle:.3f} deg, {shift_mm:.2f} mm from the result with it")
    assert shift_mm > 0.3          # what dropping dist silently cost: 0.039 deg, 0.71 mm
