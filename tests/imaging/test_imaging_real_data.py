"""Real images from ../shared/data: every image detected, sub-pixel or near fits, and poses in
one consistent target frame (no flipped orders between images)."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core.geometry import rotation_angle_between
from multieye.imaging.batch import detect_and_estimate
from multieye.imaging.targets import target_from_spec
from multieye.core.intrinsics import Intrinsics


def young_intrinsics() -> Intrinsics:
    """young_mocap_cam PROVENANCE.md: rational model, k1 k2 p1 p2 k3 k4 k5 k6."""
    return Intrinsics(K=[[607.88, 0, 641.875], [0, 607.966, 365.585], [0, 0, 1]],
                      dist=[0.458331, -2.87024, 0.00048617, -9.82262e-05, 1.74446, 0.331466,
                            -2.66947, 1.65473], width=1280, height=720)


def open3dv_intrinsics(folder) -> Intrinsics:
    """open3dv_eih PROVENANCE.md: param.txt numbers 0-8 the camera matrix (row-major),
    9-13 the distortion k1 k2 p1 p2 k3."""
    numbers = np.loadtxt(folder / "param.txt")
    return Intrinsics(K=numbers[:9].reshape(3, 3), dist=numbers[9:14])


def assert_one_target_frame(results, max_turn_deg):
    """z into the board (away from the camera) in every view, and no two views turned by
    more than the motion allows: a flipped point order would show as a half turn."""
    T = np.array([r.pose.T_cam_target for r in results])
    assert np.all(T[:, 2, 2] > 0)
    turns = np.degrees([rotation_angle_between(a, b) for a in T for b in T])
    assert turns.max() < max_turn_deg


def test_young_chessboard_images(shared_data):
    folder = shared_data / "young_mocap_cam" / "example_dataset" / "rgb_images"
    paths = [folder / f"{k}.png" for k in range(30)]
    board = target_from_spec({"type": "chessboard", "rows": 8, "cols": 11, "spacing": 0.03})
    results = detect_and_estimate(paths, board, young_intrinsics(), processes=2, progress=False)
    assert [r.reason for r in results] == [None] * 30
    assert all(r.pose.n_points == 88 and r.pose.rms_px < 1.0 for r in results)
    assert not any(r.warnings for r in results)               # 8 + 11 odd: order resolved
    # PROVENANCE: the 30 frames span about 15 degrees
    assert_one_target_frame(results, max_turn_deg=40.0)


@pytest.mark.parametrize("setup, spacing, count", [("input_EyeInHand", 0.020, 8), ("input_EyeToHand", 0.040, 5)])
def test_open3dv_light_circle_grid_images(shared_data, setup, spacing, count):
    folder = shared_data / "open3dv_eih" / setup
    paths = [folder / f"pos{k}.bmp" for k in range(count)]
    board = target_from_spec({"type": "asymmetric-circles", "rows": 11, "cols": 7, "spacing": spacing})
    results = detect_and_estimate(paths, board, open3dv_intrinsics(folder), processes=1, progress=False)
    assert [r.reason for r in results] == [None] * count
    assert all(r.pose.n_points == 77 and r.pose.rms_px < 0.2 for r in results)
    assert not any(r.warnings for r in results)               # 11 rows: not half-turn symmetric
    # PROVENANCE: at most about 25 degrees of rotation between poses
    assert_one_target_frame(results, max_turn_deg=60.0)
