"""Paper section V-A metrics and the ground-truth table."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from multieye.core import geometry as g
from multieye.core.metrics import error_table, extrinsic_errors, loop_residuals, pose_row, relative_extrinsics


def test_loop_residuals_measure_known_offsets():
    rng = np.random.default_rng(0)
    A = g.random_transforms(rng, 5)
    X = g.random_transforms(rng)
    Y = g.random_transforms(rng)
    B = g.inv(Y) @ A @ X
    rot, trans = loop_residuals(A, B, X, Y)
    assert rot.max() < 1e-12 and trans.max() < 1e-12
    # perturb B by 2 degrees about some axis and 3 mm: rotation residual is exactly 2 degrees
    D = g.transform_from_rotvec(np.radians(2.0) * np.array([0.0, 0.6, 0.8]), [0.0, 0.0, 0.0])
    rot, _ = loop_residuals(A, B @ D, X, Y)
    np.testing.assert_allclose(rot, 2.0, atol=1e-9)
    E = g.make_transform(np.eye(3), [0.003, 0, 0])
    _, trans = loop_residuals(A, E @ B, X, Y)      # shifts Y B's translation by R_Y (3 mm)
    np.testing.assert_allclose(trans, 0.003, atol=1e-12)


def test_relative_extrinsics_cancel_the_shared_frame():
    rng = np.random.default_rng(1)
    X = g.random_transforms(rng, 4)
    G = g.random_transforms(rng)
    np.testing.assert_allclose(relative_extrinsics(G @ X), relative_extrinsics(X), atol=1e-12)
    np.testing.assert_allclose(relative_extrinsics(X)[0], np.eye(4), atol=1e-12)
    np.testing.assert_allclose(relative_extrinsics(X, reference=2)[2], np.eye(4), atol=1e-12)


def test_error_table_and_pose_row():
    R = Rotation.from_euler("ZYX", [30, -10, 5], degrees=True).as_matrix()
    T = g.make_transform(R, [0.1, -0.2, 0.3])
    np.testing.assert_allclose(pose_row(T), [0.1, -0.2, 0.3, 30, -10, 5], atol=1e-12)
    T2 = T @ g.transform_from_rotvec([0, 0, np.radians(1)], [0, 0, 0.002])
    rows = error_table({"a": np.eye(4), "b": T2}, {"a": np.eye(4), "b": T})
    assert rows[1].camera == "b"
    assert rows[1].rot_err_deg == pytest.approx(1.0)
    assert rows[1].trans_err_m == pytest.approx(0.002)
    rot, trans = extrinsic_errors(T2, T)
    assert rot == pytest.approx(1.0) and trans == pytest.approx(0.002)
