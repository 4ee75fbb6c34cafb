"""shah and li agree with OpenCV 4.x calibrateRobotWorldHandEye on noisy data.

This comparison must run in CI: opencv-python-headless 4.x is a dependency and is not
skipped.  OpenCV solves A X = Z B with A = world->cam (our A), X = base->world (our X),
Z = gripper->cam (our Y), B = base->gripper (our B).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from synthetic import eye_on_hand, eye_to_base

from multieye.solvers import solve

OPENCV = {"shah": cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH, "li": cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI}


def test_opencv_is_4x_with_robot_world_hand_eye():
    assert cv2.__version__.startswith("4."), cv2.__version__
    assert hasattr(cv2, "calibrateRobotWorldHandEye")


def _opencv(A, B, flag):
    RX, tX, RY, tY = cv2.calibrateRobotWorldHandEye(
        list(A[:, :3, :3]), list(A[:, :3, 3]), list(B[:, :3, :3]), list(B[:, :3, 3]), method=flag)
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = RX, tX.ravel()
    Y = np.eye(4)
    Y[:3, :3], Y[:3, 3] = RY, tY.ravel()
    return X, Y


@pytest.mark.parametrize("method", ["shah", "li"])
@pytest.mark.parametrize("setup", [eye_to_base, eye_on_hand])
def test_agreement_with_opencv_on_noisy_data(method, setup):
    rng = np.random.default_rng(2024)
    worst = 0.0
    for _trial in range(25):
        n = int(rng.integers(3, 80))
        A, B, _, _ = setup(rng, [n], rot_noise=float(rng.uniform(0, 0.1)),
                           trans_noise=float(rng.uniform(0, 0.05)))
        X_cv, Y_cv = _opencv(A[0], B[0], OPENCV[method])
        sol = solve(A, B, method)
        worst = max(worst, np.abs(sol.X[0] - X_cv).max(), np.abs(sol.Y - Y_cv).max())
    assert worst < 1e-8, worst


@pytest.mark.parametrize("method", ["shah", "li"])
def test_rig_runs_opencv_per_camera(method):
    """On a rig, X of every camera and each per-camera Y equal OpenCV's single-camera result."""
    rng = np.random.default_rng(11)
    A, B, _, _ = eye_to_base(rng, [20, 7, 33], rot_noise=0.03, trans_noise=0.01)
    sol = solve(A, B, method)
    for j in range(3):
        X_cv, Y_cv = _opencv(A[j], B[j], OPENCV[method])
        assert np.abs(sol.X[j] - X_cv).max() < 1e-8
        assert np.abs(sol.Y_per_camera[j] - Y_cv).max() < 1e-8
