"""Property-based tests of the SE(3) helpers (hypothesis)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from multieye.core import geometry as g

finite = st.floats(-10, 10, allow_nan=False, width=64)
rotvecs = arrays(np.float64, (3,), elements=st.floats(-1.8, 1.8, allow_nan=False)).filter(
    lambda r: np.linalg.norm(r) < 3.1)     # the rotation vector is unique below pi
vec3 = arrays(np.float64, (3,), elements=finite)
mats3 = arrays(np.float64, (3, 3), elements=finite)
quats = arrays(np.float64, (4,), elements=st.floats(-1, 1, allow_nan=False)).filter(
    lambda q: np.linalg.norm(q) > 0.1)


@st.composite
def transforms(draw):
    return g.transform_from_rotvec(draw(rotvecs), draw(vec3))


@settings(max_examples=200, deadline=None)
@given(transforms(), transforms(), transforms())
def test_inverse_and_composition(T1, T2, T3):
    np.testing.assert_allclose(g.inv(T1) @ T1, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(g.inv(g.inv(T1)), T1, atol=1e-12)
    np.testing.assert_allclose(g.compose(T1, T2, T3), (T1 @ T2) @ T3, atol=1e-9)
    np.testing.assert_allclose(g.inv(T1 @ T2), g.inv(T2) @ g.inv(T1), atol=1e-10)
    # batched inverse equals one by one
    batch = np.stack([T1, T2, T3])
    np.testing.assert_allclose(g.inv(batch), np.stack([g.inv(T) for T in batch]), atol=0)


@settings(max_examples=200, deadline=None)
@given(mats3)
def test_project_to_so3_is_a_rotation_and_idempotent(M):
    R = g.project_to_so3(M)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-9)
    assert np.linalg.det(R) > 0
    np.testing.assert_allclose(g.project_to_so3(R), R, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(rotvecs)
def test_project_to_so3_is_nearest(rv):
    R = Rotation.from_rotvec(rv).as_matrix()
    # a perturbed rotation projects back closer than the perturbation
    P = g.project_to_so3(R + 1e-3 * np.arange(9).reshape(3, 3) / 9)
    assert np.linalg.norm(P - R) < np.linalg.norm(1e-3 * np.arange(9).reshape(3, 3) / 9) * 2


@settings(max_examples=200, deadline=None)
@given(quats, vec3)
def test_quaternion_round_trip_both_orders(q, t):
    q = q / np.linalg.norm(q)
    T = g.transform_from_quat(q, t)
    q2 = g.quat_from_transform(T)
    assert np.allclose(q2, q, atol=1e-9) or np.allclose(q2, -q, atol=1e-9)
    T_wxyz = g.transform_from_quat(np.r_[q[3], q[:3]], t, scalar_first=True)
    np.testing.assert_allclose(T_wxyz, T, atol=1e-12)
    q3 = g.quat_from_transform(T, scalar_first=True)
    assert q3[0] >= 0
    np.testing.assert_allclose(q3, np.r_[q2[3], q2[:3]], atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(rotvecs, vec3)
def test_rotvec_round_trip_and_angle(rv, t):
    T = g.transform_from_rotvec(rv, t)
    np.testing.assert_allclose(g.rotvec_from_transform(T), rv, atol=1e-8)
    assert abs(g.rotation_angle(T[:3, :3]) - np.linalg.norm(rv)) < 1e-9
    assert abs(g.rotation_angle_between(np.eye(4), T) - np.linalg.norm(rv)) < 1e-9


def test_rotation_angle_is_accurate_near_zero_and_pi():
    for ang in (1e-12, 1e-8, 1e-4, np.pi - 1e-6, np.pi):
        R = Rotation.from_rotvec([0, ang, 0]).as_matrix()
        assert abs(g.rotation_angle(R) - ang) < 1e-12 + 1e-9 * (ang > 3)


@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, (3,), elements=st.floats(-1.5, 1.5, allow_nan=False)))
def test_ypr_convention(ypr):
    yaw, pitch, roll = ypr
    R = Rotation.from_euler("z", yaw).as_matrix() @ Rotation.from_euler("y", pitch).as_matrix() \
        @ Rotation.from_euler("x", roll).as_matrix()
    np.testing.assert_allclose(g.ypr_from_rotation(R), ypr, atol=1e-9)


def test_rotation_mean_of_symmetric_perturbations():
    rng = np.random.default_rng(0)
    R0 = Rotation.random(random_state=1).as_matrix()
    d = rng.normal(scale=0.05, size=(10, 3))
    Rs = np.concatenate([R0 @ Rotation.from_rotvec(d).as_matrix(),
                         R0 @ Rotation.from_rotvec(-d).as_matrix()])
    # R0 (exp(d) + exp(-d)) = R0 (symmetric positive definite): its projection is exactly R0
    assert g.rotation_angle_between(g.rotation_mean(Rs), R0) < 1e-12


def test_skew_is_cross_product():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(2, 3))
    np.testing.assert_allclose(g.skew(a) @ b, np.cross(a, b), atol=1e-15)


def test_rotation_from_quat_gives_scipys_bits_without_importing_scipy():
    """The motion capture is read before the detection starts (issue 21): its quaternions
    become matrices by SciPy's operations in SciPy's order, without scipy.spatial."""
    rng = np.random.default_rng(7)
    q = np.concatenate([rng.normal(size=(5000, 4)) * rng.uniform(1e-3, 1e3, (5000, 1)),
                        [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, -1.0], [1.0, 0.0, 0.0, 0.0]]])
    assert np.array_equal(g.rotation_from_quat(q), Rotation.from_quat(q).as_matrix())
    T = g.transform_from_quat(q[:6].reshape(2, 3, 4), np.ones((2, 3, 3)))
    assert T.shape == (2, 3, 4, 4)
    assert np.array_equal(T[1, 2, :3, :3], Rotation.from_quat(q[5]).as_matrix())
    for bad in ([0.0, 0.0, 0.0, 0.0], [np.nan, 0.0, 0.0, 1.0]):   # refused as SciPy does
        with pytest.raises(ValueError, match="zero norm"):
            Rotation.from_quat(bad)
        with pytest.raises(ValueError, match="zero norm"):
            g.transform_from_quat(bad, [0.0, 0.0, 0.0])
    assert not _imports("scipy", "g.transform_from_quat([[0.1, 0.2, 0.3, 0.9]], [[0, 0, 0]])")


def test_quat_from_transform_gives_scipys_canonical_bits_without_importing_scipy():
    """Matrices become quaternions by SciPy's method (``from_matrix(...).as_quat(canonical=
    True)``), the same bits, half turns included (``qw = 0``: the first non-zero part made
    positive), without scipy.spatial (issue 21: about 0.1 CPU-s of every calibration)."""
    rng = np.random.default_rng(3)
    axes = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1],
                     [0, 1, -1], [0, -1, 1], [1, -1, 0], [-1, 1, 1]], float)
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    R = np.concatenate([Rotation.random(20000, random_state=4).as_matrix(),
                        Rotation.from_rotvec(np.pi * axes).as_matrix(), np.eye(3)[None]])
    T = g.make_transform(R, rng.normal(size=(len(R), 3)))
    q = g.quat_from_transform(T)
    assert np.array_equal(q, Rotation.from_matrix(R).as_quat(canonical=True))
    assert np.array_equal(g.quat_from_transform(T[-3:].reshape(1, 3, 4, 4)), q[None, -3:])
    assert not _imports("scipy.spatial", "g.quat_from_transform(np.eye(4)[None])")


def _imports(module: str, call: str) -> bool:
    """Whether ``module`` is imported by a fresh interpreter that imports numpy and
    ``multieye.core.geometry`` (as ``g``) and runs ``call``."""
    code = ("import sys, numpy as np\nfrom multieye.core import geometry as g\n"
            f"{call}\nprint({module!r} in sys.modules)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    return run.stdout.split() == ["True"]
