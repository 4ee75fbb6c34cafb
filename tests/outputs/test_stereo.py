"""Stereo pairs of a calibration get OpenCV's rectification in the exports (issue 23, item 5)."""

from __future__ import annotations

import numpy as np
import yaml

from multieye.core import geometry as g
from multieye.io.calibration_json import CalibrationRecord, CameraRecord, Residuals
from multieye.io.intrinsics_files import camera_info_text
from multieye.outputs.stereo import opencv_stereo_lines, per_camera, stereo_pairs
from multieye.sim.overlap import OverlapSpec, overlap_rig
from multieye.sim.dataset import default_intrinsics


def _record():
    _, T_ref_cam = overlap_rig(OverlapSpec())
    X = g.transform_from_rotvec([0, 0, 0.3], [1, 2, 0]) @ T_ref_cam
    zero = Residuals(0.0, 0.0)
    cams = [CameraRecord(f"cam{j}", X[j], T_ref_cam[j], 20, residuals=zero) for j in range(3)]
    return CalibrationRecord("eye-to-base", "joint", "cam0", np.eye(4), cams, zero)


def test_overlapping_pinhole_cameras_are_rectified_left_then_right():
    rec = _record()
    lenses = default_intrinsics(3, 800, 600, fisheye=(2,))
    intr = {f"cam{j}": lenses[j] for j in range(3)}
    overlaps = {"cam0": ("cam1", "cam2"), "cam1": ("cam0", "cam2"), "cam2": ("cam0", "cam1")}
    pairs, notes = stereo_pairs(rec, intr, overlaps)
    assert [(p.left, p.right) for p in pairs] == [("cam1", "cam0")]   # cam1 is left of cam0
    assert notes == []
    baseline = g.translation_distance(rec.cameras[0].T_ref_cam, rec.cameras[1].T_ref_cam)
    P2 = pairs[0].rectification.P_b
    assert abs(-P2[0, 3] / P2[0, 0] - baseline) < 1e-9
    rect = per_camera(pairs)
    info = yaml.safe_load(camera_info_text(intr["cam0"], "cam0", rect["cam0"]))
    assert np.allclose(np.reshape(info["rectification_matrix"]["data"], (3, 3)), rect["cam0"][0])
    assert np.allclose(np.reshape(info["projection_matrix"]["data"], (3, 4)), rect["cam0"][1])
    plain = yaml.safe_load(camera_info_text(intr["cam2"], "cam2", rect.get("cam2")))
    assert np.allclose(np.reshape(plain["rectification_matrix"]["data"], (3, 3)), np.eye(3))
    lines = opencv_stereo_lines(pairs, lambda n, M, ind: [f"{ind}{n}: {M.shape}"])
    assert lines[0] == "stereo_pairs:" and any("R1" in x for x in lines)


def test_a_pinhole_fisheye_pair_is_named_not_rectified():
    rec = _record()
    lenses = default_intrinsics(3, 800, 600, fisheye=(2,))
    intr = {f"cam{j}": lenses[j] for j in range(3)}
    pairs, notes = stereo_pairs(rec, intr, {"cam0": ("cam2",), "cam1": (), "cam2": ("cam0",)})
    assert pairs == []
    assert notes == ["no stereo rectification for cam2 and cam0 (no rectification for a "
                     "fisheye lens paired with a pinhole one (OpenCV has none))"]
    assert stereo_pairs(rec, intr, None) == ([], [])
