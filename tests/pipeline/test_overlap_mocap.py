"""The Jacobians that carry the joint covariance of the rig with motion capture and several
boards to X = T_body_cam and to each board in the motion capture's frame
(multieye.pipeline.overlap_mocap), against central differences in the engine's perturbation."""

import numpy as np

from multieye.core import geometry as g
from multieye.core.lie import exp_so3, log_so3
from multieye.optimize.blocks import Blocks
from multieye.pipeline.overlap_mocap import board_jacobians, body_cam_jacobians


def _pose(rng):
    return g.make_transform(exp_so3(rng.normal(size=3)), rng.normal(size=3))


def _moved(T, d):
    return Blocks("x", T[None], "se3-left").retract(d).value[0]


def _diff(T, T0):
    return np.concatenate([log_so3(T[:3, :3] @ T0[:3, :3].T), T[:3, 3] - T0[:3, 3]])


def _numeric(f, a, b, which, h=1e-6):
    J = np.zeros((6, 6))
    for k in range(6):
        d = np.zeros(6)
        d[k] = h
        args_p = (_moved(a, d), b) if which == 0 else (a, _moved(b, d))
        args_m = (_moved(a, -d), b) if which == 0 else (a, _moved(b, -d))
        J[:, k] = (_diff(f(*args_p), f(a, b)) - _diff(f(*args_m), f(a, b))) / (2 * h)
    return J


def test_jacobians_match_central_differences():
    rng = np.random.default_rng(3)
    for _ in range(3):
        A, B = _pose(rng), _pose(rng)
        j_m, j_c = body_cam_jacobians(A, B)
        body_cam = lambda m, c: g.inv(m) @ c                     # noqa: E731
        assert np.allclose(j_m, _numeric(body_cam, A, B, 0), atol=1e-6)
        assert np.allclose(j_c, _numeric(body_cam, A, B, 1), atol=1e-6)
        j_y, j_w = board_jacobians(A, B)
        assert np.allclose(j_y, _numeric(lambda y, w: y @ w, A, B, 0), atol=1e-6)
        assert np.allclose(j_w, _numeric(lambda y, w: y @ w, A, B, 1), atol=1e-6)
