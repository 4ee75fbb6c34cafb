"""Degenerate and malformed input raises a CalibrationError a user can act on."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import eye_to_base

import multieye
from multieye.core import geometry as g
from multieye.solvers import METHODS, solve
from multieye.solvers.checks import check_transforms, rotation_spread


@pytest.fixture
def rig():
    return eye_to_base(np.random.default_rng(1), [6, 6, 6])


@pytest.mark.parametrize("method", METHODS)
def test_fewer_than_three_measurements(rig, method):
    A, B, _, _ = rig
    A[1], B[1] = A[1][:2], B[1][:2]
    with pytest.raises(multieye.TooFewMeasurementsError, match=r"camera cam1 has 2 measurements.*at least 3"):
        solve(A, B, method)


@pytest.mark.parametrize("method", METHODS)
def test_nan_names_camera_and_index(rig, method):
    A, B, _, _ = rig
    B[2] = B[2].copy()
    B[2][4, 1, 3] = np.nan
    with pytest.raises(multieye.InputError, match=r"B\[cam2\]\[4\].*NaN"):
        solve(A, B, method)


def test_non_rigid_and_reflection_and_bottom_row(rig):
    A, B, _, _ = rig
    A0 = A[0].copy()
    A0[3, :3, :3] *= 1.01
    with pytest.raises(multieye.InputError, match=r"A\[cam0\]\[3\].*not orthonormal"):
        solve([A0] + A[1:], B)
    A0 = A[0].copy()
    A0[1, :3, 2] *= -1
    with pytest.raises(multieye.InputError, match=r"A\[cam0\]\[1\].*det -1.*reflection"):
        solve([A0] + A[1:], B)
    A0 = A[0].copy()
    A0[2, 3, 0] = 0.5
    with pytest.raises(multieye.InputError, match=r"bottom row"):
        solve([A0] + A[1:], B)


def test_rounding_level_deviations_are_accepted(rig):
    """float32 round trips and printed matrices are rigid enough (tolerance 1e-5)."""
    A, B, _, _ = rig
    A0 = A[0].astype(np.float32).astype(np.float64)
    A0[:, 3, 3] = 1.0 + 1e-9
    A0[:, 3, :3] = 1e-9
    sol = solve([A0] + A[1:], B)
    assert sol.X.shape == (3, 4, 4)


def test_mismatched_counts_and_cameras(rig):
    A, B, _, _ = rig
    with pytest.raises(multieye.InputError, match="3 cameras but B has 2"):
        solve(A, B[:2])
    with pytest.raises(multieye.InputError, match="camera cam1: 6 A measurements but 5 B"):
        solve(A, [B[0], B[1][:5], B[2]])


def test_wrong_shape_and_unknown_method(rig):
    A, B, _, _ = rig
    with pytest.raises(multieye.InputError, match=r"shape \(N, 4, 4\), got \(6, 3, 4\)"):
        solve([A[0][:, :3]], [B[0]])
    with pytest.raises(multieye.InputError, match="unknown method 'kabsch'.*joint"):
        solve(A, B, "kabsch")


def _single_axis(rng, n, axis):
    T_world_marker = g.transform_from_rotvec(np.outer(rng.uniform(-1, 1, n), axis),
                                             rng.normal(size=(n, 3)))
    X = g.random_transforms(rng)
    Y = g.random_transforms(rng)
    A = g.inv(T_world_marker)
    B = g.inv(g.inv(X) @ T_world_marker @ Y)
    return A, B


@pytest.mark.parametrize("method", METHODS)
def test_rotation_about_single_axis_raises(method):
    rng = np.random.default_rng(2)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    A, B = _single_axis(rng, 12, axis)
    with pytest.raises(multieye.DegenerateMotionError, match="single axis.*second axis"):
        solve([A], [B], method)


def test_no_rotation_at_all_raises():
    rng = np.random.default_rng(3)
    A = g.make_transform(np.repeat(np.eye(3)[None], 5, axis=0), rng.normal(size=(5, 3)))
    with pytest.raises(multieye.DegenerateMotionError, match="never rotates"):
        solve([A], [A])


def test_rotation_spread_measures_rms_angles():
    rng = np.random.default_rng(4)
    # 10 deg about z then 10 deg about x, alternately: RMS ~ 10/sqrt(2) deg about each
    rv = np.zeros((41, 3))
    rv[1::2, 2] = np.radians(10)
    rv[2::2, 0] = np.radians(10)
    A = g.transform_from_rotvec(rv, rng.normal(size=(41, 3)))
    s = np.degrees(rotation_spread(A))
    assert s[0] == pytest.approx(10 / np.sqrt(2), rel=0.01)
    assert s[1] == pytest.approx(10 / np.sqrt(2), rel=0.01)
    assert s[2] < 1e-6


def test_check_transforms_accepts_single_matrix_and_lists():
    T = check_transforms(np.eye(4).tolist())
    assert T.shape == (1, 4, 4) and T.dtype == np.float64
    with pytest.raises(multieye.InputError, match="must be an array"):
        check_transforms([[1, 2], [3]])


def test_errors_share_one_base():
    for exc in (multieye.InputError, multieye.TooFewMeasurementsError,
                multieye.DegenerateMotionError, multieye.DatasetError, multieye.DisconnectedError):
        assert issubclass(exc, multieye.CalibrationError)


def test_turntable_motion_with_noise_is_refused_not_solved():
    """Rotation about one axis plus motion-capture noise (0.05 deg) is not a second axis."""
    rng = np.random.default_rng(7)
    axis = np.array([0.0, 0.0, 1.0])
    A, B = _single_axis(rng, 30, axis)
    A = A @ g.transform_from_rotvec(rng.normal(scale=np.radians(0.05), size=(30, 3)), np.zeros((30, 3)))
    for method in ("joint", "shah"):
        with pytest.raises(multieye.DegenerateMotionError, match="single axis"):
            solve([A], [B], method)


def test_list_of_single_matrices_gets_a_pointed_message(rig):
    A, B, _, _ = rig
    with pytest.raises(multieye.InputError, match=r"list of 6 single 4x4 matrices.*np.stack"):
        solve(list(A[0]), list(B[0]))


def test_refinement_options_without_refine_are_refused(rig):
    A, B, _, _ = rig
    with pytest.raises(multieye.InputError, match="loss.*refine=True"):
        solve(A, B, loss="huber")


def test_normalize_rotation_never_returns_a_reflection():
    from multieye.solvers.kronecker import normalize_rotation

    for M in (np.diag([1.0, -1.0, 0.0]), np.diag([1.0, 1.0, 0.0]), np.diag([-1.0, -2.0, -3.0])):
        R = normalize_rotation(M)
        assert np.linalg.det(R) == pytest.approx(1.0)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)


@pytest.mark.parametrize("args, kw, message", [
    ((None, None), {}, "A is None: give one (N, 4, 4) array of transforms per camera"),
    (("A", "B"), {}, "A must be a list with one (N, 4, 4) array of transforms per camera, got str"),
    (({"a": 1}, [1]), {}, "A must be a list with one (N, 4, 4) array of transforms per camera, "
                          "got dict"),
    ((None, "rig"), {"names": ["a"]}, "names has 1 entries but there are 3 cameras"),
    ((None, "rig"), {"names": "abc"}, "names must be a list of 3 strings"),
    ((None, "rig"), {"names": [1, 2, 3]}, "names must be non-empty strings"),
    ((None, "rig"), {"names": ["a", "b", "a"]}, "names must be distinct"),
    ((None, "rig"), {"method": None}, "unknown method None"),
    ((None, "rig"), {"method": ["joint"]}, "unknown method ['joint']"),
    ((None, "rig"), {"refine": True, "max_iter": 0}, "max_iter must be a whole number >= 1, got 0"),
    ((None, "rig"), {"refine": True, "max_iter": -3}, "max_iter must be a whole number >= 1"),
    ((None, "rig"), {"refine": True, "max_iter": None}, "max_iter must be a whole number >= 1"),
    ((None, "rig"), {"refine": True, "loss": None}, "unknown loss None"),
    ((None, "rig"), {"refine": True, "bogus": 1}, "unknown refinement option bogus"),
    ((None, "rig"), {"refine": True, "tol": None}, "tol must be a number, got None"),
    ((None, "rig"), {"refine": True, "tol": -1.0}, "tol must be a non-negative number"),
    ((None, "rig"), {"max_iter": 5}, "given without refine=True"),
])
def test_bad_arguments_are_input_errors(rig, args, kw, message):
    A, B, _, _ = rig
    if args == (None, "rig"):
        args = (A, B)
    with pytest.raises(multieye.InputError) as info:
        solve(*args, **kw)
    assert message in str(info.value)


def test_complex_transforms_are_refused_not_cast(rig):
    A, B, _, _ = rig
    with pytest.raises(multieye.InputError, match=r"A\[cam0\] must be real, got complex"):
        solve([A[0] + 1e-3j, *A[1:]], B)
    with pytest.raises(multieye.InputError, match=r"A\(x, y\) must be real, got complex"):
        multieye.solve_general([("x", "y", A[0].astype(complex), B[0])])


@pytest.mark.parametrize("groups, message", [
    (None, "groups must be an iterable of (x_name, y_name, A, B), got NoneType"),
    (5, "groups must be an iterable of (x_name, y_name, A, B), got int"),
    ("xyAB", "groups must be an iterable of (x_name, y_name, A, B), got str"),
    ([("x", "y", None, None)], "A(x, y) is None"),
])
def test_solve_general_bad_groups(groups, message):
    with pytest.raises(multieye.InputError) as info:
        multieye.solve_general(groups)
    assert message in str(info.value)


def test_solve_general_bad_options(rig):
    A, B, _, _ = rig
    groups = [(f"x{j}", "y", A[j], B[j]) for j in range(3)]
    with pytest.raises(multieye.InputError, match="max_iter must be a whole number >= 1"):
        multieye.solve_general(groups, refine=True, max_iter=0)
    with pytest.raises(multieye.InputError, match="unknown refinement option iterations"):
        multieye.solve_general(groups, refine=True, iterations=3)
    with pytest.raises(multieye.InputError, match="unknown method None"):
        multieye.solve_general(groups, method=None)
