"""Weak-motion diagnostics: numbers and warnings that name the camera."""

from __future__ import annotations

import json

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.sim import rigs as sim
from multieye.estimate.diagnostics import motion_diagnostics


def _rig_with(kind: str, camera: int, setup: str = "eye-to-base", seed: int = 51):
    """A simulated 3-camera rig where one camera's target motion is replaced by ``kind``."""
    rng = np.random.default_rng(seed)
    sc = sim.simulate_rig(rng, n_cameras=3, measurements=30, setup=setup)
    A, B = list(sc.A), list(sc.B)
    n = 30
    if kind == "axis":          # the board turns about the camera's y axis only
        rv = np.outer(rng.uniform(-0.6, 0.6, n), [0.0, 1.0, 0.0])
    elif kind == "range":       # small tilts: 6 degrees apart at most
        rv = rng.normal(size=(n, 3))
        rv *= np.radians(rng.uniform(0.0, 3.0, (n, 1))) / np.linalg.norm(rv, axis=1,
                                                                         keepdims=True)
    else:                       # small but about every axis, over 10 degrees of range
        rv = rng.normal(scale=np.radians(2.5), size=(n, 3))
    P = g.transform_from_rotvec(rv, rng.normal(scale=0.1, size=(n, 3))) @ sc.T_cam_target[camera][0]
    X, Y = sc.X[camera], sc.Y
    if setup == "eye-to-base":
        A[camera] = g.inv(X @ P @ g.inv(Y))
    else:
        A[camera] = Y @ g.inv(P) @ g.inv(X)
    B[camera] = g.inv(P)
    return A, B


def test_good_motion_gives_no_warning_and_finite_numbers():
    sc = sim.simulate_rig(50, n_cameras=4, measurements=40)
    diag = motion_diagnostics(sc.A, sc.B)
    assert diag.warnings == ()
    for cam in diag.cameras:
        assert cam.rotation_range_deg > 90
        assert cam.rotation_spread_deg[1] > 10
        assert 1.0 <= cam.rotation_condition < 10 and 1.0 <= cam.translation_condition < 10
    json.dumps(diag.as_dict())


@pytest.mark.parametrize("setup, advice", [
    ("eye-to-base", "rotate the target about a second axis in front of cam2"),
    ("eye-on-hand", "rotate the rig about a second axis while cam2 sees the target")])
def test_rotation_about_one_axis_is_named(setup, advice):
    A, B = _rig_with("axis", 2, setup)
    diag = motion_diagnostics(A, B, setup=setup)
    (w,) = diag.warnings
    assert w.startswith("cam2: all rotations are about one axis")
    assert w.endswith(advice)
    cam2 = diag.cameras[2]
    assert cam2.rotation_spread_deg[1] < 1e-4
    assert cam2.rotation_condition > 1e6 and cam2.translation_condition > 1e6
    assert json.loads(json.dumps(diag.as_dict()))["warnings"] == [w]


def test_small_rotation_range_is_named():
    A, B = _rig_with("range", 1)
    diag = motion_diagnostics(A, B, names=["front", "left", "back"])
    (w,) = diag.warnings
    rng_deg = diag.cameras[1].rotation_range_deg
    assert rng_deg < 6.0 + 1e-9
    assert w.startswith(f"left: rotation range {rng_deg:.1f} deg < 10 deg")
    assert w.endswith("tilt the target by 30 deg or more about two axes in front of left")


def test_small_rotations_over_10_degrees_warn_by_condition():
    A, B = _rig_with("small", 0)
    diag = motion_diagnostics(A, B)
    assert diag.cameras[0].rotation_range_deg > 10
    (w,) = diag.warnings
    assert w.startswith("cam0: the rotations are small about some axis (RMS ")
    assert diag.cameras[0].translation_condition > 100


def test_rotation_range_is_the_largest_pairwise_angle():
    angles = np.radians([0.0, 5.0, 37.0, 12.0])
    R = g.transform_from_rotvec(np.outer(angles, [0.0, 0.0, 1.0]), np.zeros((4, 3)))
    R2 = g.transform_from_rotvec(np.outer(angles, [1.0, 0.0, 0.0]), np.zeros((4, 3)))
    A = np.concatenate([R, R2 @ R[2]])
    B = A.copy()                         # X = Y = I
    diag = motion_diagnostics([A], [B])
    expected = np.degrees(g.rotation_angle_between(A[:, None], A[None]).max())
    assert diag.cameras[0].rotation_range_deg == pytest.approx(expected, abs=1e-6)


def test_single_camera_warning_does_not_point_at_other_cameras():
    A, B = _rig_with("axis", 0)
    A[0] = A[0].copy()
    A[0][::3] = A[0][::3] @ g.transform_from_rotvec([0.02, 0.0, 0.0], [0.0, 0.0, 0.0])
    (w,) = motion_diagnostics(A[:1], B[:1]).warnings
    assert w.startswith("cam0: all rotations are about one axis")
    assert "so its extrinsic is poorly determined" in w and "other cameras" not in w
