"""The rig.yaml files of docs/results/robot_sets/ against the published robot data sets in
../shared/data, run as a user runs them: the data set's folder as published, with only the
committed rig.yaml (and, for Open3DV, the intrinsics copied from its param.txt) added, through
``multieye calibrate``. The bounds are the figures of docs/results/robot_sets.md with margin."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from multieye.cli import main

REPO = Path(__file__).resolve().parents[2]
COMMITTED = REPO / "docs" / "results" / "robot_sets"

#: committed folder -> (the published folder it goes into, other published folders it names)
SETS = {
    "open3dv_eih": ("open3dv_eih/input_EyeInHand", ()),
    "yizhong_eye_in_hand": ("yizhong_toolkit/sample_data/eye_in_hand_test_data", ()),
    "yizhong_eye_to_hand": ("yizhong_toolkit/sample_data/eye_to_hand_test_data",
                            ("yizhong_toolkit/sample_data/intrinsic_calib_grid_test_images",)),
}


def _link(src: Path, dst: Path) -> None:
    try:
        os.symlink(src, dst)
    except OSError:  # pragma: no cover - file systems without symlinks
        (shutil.copytree if src.is_dir() else shutil.copy)(src, dst)


def published_with_rig(shared: Path, out: Path, name: str) -> Path:
    """The published folder of ``name`` rebuilt under ``out`` (every file linked, same
    relative layout, so ``../`` paths in rig.yaml resolve) plus the committed files."""
    folder, others = SETS[name]
    dst = out / folder
    dst.mkdir(parents=True)
    for f in sorted((shared / folder).iterdir()):
        _link(f, dst / f.name)
    for other in others:
        (out / other).parent.mkdir(parents=True, exist_ok=True)
        _link(shared / other, out / other)
    for f in sorted((COMMITTED / name).iterdir()):
        shutil.copy(f, dst / f.name)
    return dst


def _calibrate(shared: Path, tmp_path: Path, name: str) -> tuple[dict, str]:
    dataset = published_with_rig(shared, tmp_path / "data", name)
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["calibrate", str(dataset), "-o", str(out),
                                    "--processes", "1"])
    assert res.exit_code == 0, (res.exit_code, res.stdout, res.stderr)
    return json.loads((out / "calibration.json").read_text()), res.stdout


def test_committed_sets_are_the_tested_ones():
    assert sorted(p.name for p in COMMITTED.iterdir() if p.is_dir()) == sorted(SETS)
    for name in SETS:
        assert (COMMITTED / name / "rig.yaml").is_file()


def test_open3dv_eye_in_hand(shared_data, tmp_path):
    """8 circle-grid images + pos<k>.txt, intrinsics from param.txt: robot_sets.md: 0.03 px,
    0.050 deg / 0.50 mm loop residual, camera at (220.7, 68.3, -177.9) mm in the TCP frame."""
    cal, _ = _calibrate(shared_data, tmp_path, "open3dv_eih")
    cam = cal["cameras"]["cam0"]
    assert cam["measurements_used"] == 8
    assert cal["frames"] == {"world": "base", "body": "tcp"}          # pose: T_base_tcp
    assert [r["item"] for r in cam["rejected"]] == ["param.txt"]     # a .txt without an image
    assert cal["plausibility"] == []
    assert cam["residuals"]["reprojection_rms_px"] < 0.1
    assert cam["residuals"]["e_R_deg"] < 0.1 and cam["residuals"]["e_t_m"] < 1e-3
    # no published result; PROVENANCE.md's independent OpenCV check: (220.5, 68.4, -177.7) mm
    t = np.array(cam["T_body_cam"])[:3, 3] * 1e3
    np.testing.assert_allclose(t, [220.5, 68.4, -177.7], atol=2.0)
    u = cam["uncertainty"]["T_body_cam"]
    assert u["std_rot_deg"] < 0.3 and u["std_trans_m"] < 4e-3


def test_yizhong_eye_in_hand(shared_data, tmp_path):
    """6 chessboard images + <k>.json end2base, the lens estimated from the same images:
    0.11 px, 0.14 deg / 0.71 mm, fx 641.8 +- 0.5 px."""
    cal, out = _calibrate(shared_data, tmp_path, "yizhong_eye_in_hand")
    cam = cal["cameras"]["cam0"]
    assert cam["measurements_used"] == 6
    assert [r["item"] for r in cam["rejected"]] == ["chessboard_config.json"]
    assert cal["plausibility"] == []
    assert cam["residuals"]["reprojection_rms_px"] < 0.25
    assert cam["residuals"]["e_R_deg"] < 0.3 and cam["residuals"]["e_t_m"] < 1.5e-3
    lens = cam["intrinsics"]
    assert lens["estimated"] and lens["image_size"] == [960, 540]
    # PROVENANCE.md's OpenCV calibration of the 6 images: fx 621, fy 622, cx 469, cy 296
    K = np.array(lens["K"])
    assert abs(K[0, 0] / 641.8 - 1) < 0.02 and abs(K[1, 1] / 641.4 - 1) < 0.02
    assert abs(K[0, 2] - 475) < 10 and abs(K[1, 2] - 290) < 10
    # PROVENANCE.md's check: camera at (0.100, -0.001, 0.145) m in the end effector's frame
    np.testing.assert_allclose(np.array(cam["T_body_cam"])[:3, 3], [0.100, -0.001, 0.145],
                               atol=0.015)
    assert "only 6 images of the target" in out
    # the robot's frame names (pose: T_base_tool0) on screen; calibration.json keeps the keys
    assert "T_tool0_cam (calibration.json: T_body_cam) of every camera:" in out
    assert cal["frames"] == {"world": "base", "body": "tool0"}


def test_yizhong_eye_to_hand_single_marker(shared_data, tmp_path):
    """8 images of one 53 mm ArUco marker + <k>.json, the lens estimated with the 7 published
    ArUco-grid views: all 15 views used, 0.75 px, fx 963 +- 4 px."""
    cal, out = _calibrate(shared_data, tmp_path, "yizhong_eye_to_hand")
    cam = cal["cameras"]["cam0"]
    assert cam["measurements_used"] == 8                     # the marker in every image
    # every grid view starts the lens with the marker views: none rejected as a bad fit
    assert [r["item"] for r in cam["rejected"]] == ["chessboard_config.json"]
    assert "only 8 images" not in out
    assert cal["plausibility"] == []
    assert cam["residuals"]["reprojection_rms_px"] < 1.0
    assert cam["residuals"]["e_R_deg"] < 1.5 and cam["residuals"]["e_t_m"] < 8e-3
    K = np.array(cam["intrinsics"]["K"])
    assert abs(K[0, 0] / 963.4 - 1) < 0.02 and abs(K[1, 1] / 960.7 - 1) < 0.02
    assert abs(K[0, 2] - 478) < 10 and abs(K[1, 2] - 269) < 15
    # no published result: the camera where the run put it, within 5 std (1.2 mm)
    np.testing.assert_allclose(np.array(cam["T_world_cam"])[:3, 3], [0.5731, 0.5736, 0.4014],
                               atol=6e-3)
    assert cam["uncertainty"]["T_world_cam"]["std_rot_deg"] < 1.0
    assert "T_base_cam (calibration.json: T_world_cam) of every camera:" in out
    assert "T_tool0_target (calibration.json: T_marker_target): t = (" in out
