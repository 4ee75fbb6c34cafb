"""Solvers: exact recovery, equivariance under frame changes, joint = Shah on one camera."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from synthetic import eye_on_hand, eye_to_base

import multieye
from multieye.core import geometry as g
from multieye.core.metrics import relative_extrinsics
from multieye.solvers import JOINT_METHODS, METHODS, SINGLE_METHODS, methods, registry, solve

CLOSED_FORM = ["joint", "wang2022", "shah", "li"]
ITERATIVE = ["tabb-c1", "tabb-c2"]


def _errors(T_est, T_true):
    rot = np.degrees(g.rotation_angle_between(T_est, T_true)).max()
    trans = g.translation_distance(T_est, T_true).max()
    return rot, trans


@pytest.mark.parametrize("setup", [eye_to_base, eye_on_hand])
@pytest.mark.parametrize("method", CLOSED_FORM + ITERATIVE)
def test_noise_free_recovery_1_to_8_cameras_unequal_counts(setup, method):
    tol = 1e-9 if method in CLOSED_FORM else 1e-5
    # a seed per case that is the same in every run (str hash() is salted per process, which
    # made this test draw new rigs each run and, now and then, a degenerate one)
    rng = np.random.default_rng(zlib.crc32(f"{setup.__name__}/{method}".encode()))
    for m in (1, 2, 4, 8):
        counts = list(rng.integers(3, 25, size=m))
        A, B, X, Y = setup(rng, counts)
        sol = solve(A, B, method=method)
        assert sol.X.shape == (m, 4, 4) and sol.Y.shape == (4, 4)
        for est, true in ((sol.X, X), (sol.Y, Y)):
            rot, trans = _errors(est, true)
            assert rot < tol and trans < tol, (m, method, rot, trans)
        assert sol.e_R_deg < tol and sol.e_t_m < tol
        assert [r.n for r in sol.residuals] == counts


def test_public_entry_point_and_registry():
    assert multieye.solve is solve
    assert set(METHODS) == {"joint", "wang2022", "shah", "li", "tabb-c1", "tabb-c2"}
    assert set(JOINT_METHODS) | set(SINGLE_METHODS) == set(METHODS)


@pytest.mark.parametrize("method", ["joint", "wang2022", "shah", "li", "tabb-c1"])
def test_change_of_world_frame_moves_X_and_keeps_Y(method):
    """T_world'_marker = G T_world_marker: X' = G X exactly, Y unchanged (eye-to-base)."""
    rng = np.random.default_rng(7)
    A, B, _, _ = eye_to_base(rng, [12, 9, 15], rot_noise=0.01, trans_noise=0.005)
    G = g.random_transforms(rng, translation_scale=5.0)
    A2 = [Aj @ g.inv(G) for Aj in A]          # inv(G T_world_marker) = A inv(G)
    s1 = solve(A, B, method=method)
    s2 = solve(A2, B, method=method)
    tol = 1e-9 if method != "tabb-c1" else 1e-6
    rot, trans = _errors(s2.X, G @ s1.X)
    assert rot < tol and trans < tol
    rot, trans = _errors(s2.Y, s1.Y)
    assert rot < tol and trans < tol
    # and the relative extrinsics do not move at all
    rot, trans = _errors(relative_extrinsics(s2.X), relative_extrinsics(s1.X))
    assert rot < tol and trans < tol


@pytest.mark.parametrize("method,counts", [("joint", [10, 14]), ("wang2022", [10, 14]),
                                           ("shah", [10])])
def test_change_of_target_frame_moves_Y_and_keeps_X(method, counts):
    """T_cam_target' = T_cam_target H: Y' = Y H, X unchanged.

    Single-camera methods only on one camera: the paper's combination of per-camera Y
    (mean of translations) is not equivariant under a change of target frame, since
    mean_j(R_Yj t_H + t_Yj) differs from mean(R_Yj) t_H + mean(t_Yj).
    """
    rng = np.random.default_rng(8)
    A, B, _, _ = eye_to_base(rng, counts, rot_noise=0.01, trans_noise=0.005)
    H = g.random_transforms(rng, translation_scale=0.3)
    B2 = [g.inv(H) @ Bj for Bj in B]          # T_target'_cam = inv(H) T_target_cam
    s1 = solve(A, B, method=method)
    s2 = solve(A, B2, method=method)
    rot, trans = _errors(s2.Y, s1.Y @ H)
    assert rot < 1e-9 and trans < 1e-9
    rot, trans = _errors(s2.X, s1.X)
    assert rot < 1e-9 and trans < 1e-9


def test_li_translation_is_not_target_frame_equivariant():
    """Li keeps the translations of its linear solve, which used the unnormalised R_Y, so a
    change of target frame moves t_Y by (R_Y,linear - R_Y) t_H: its rotations are equivariant,
    its translations only approximately (a property of the baseline, kept as OpenCV has it)."""
    rng = np.random.default_rng(8)
    A, B, _, _ = eye_to_base(rng, [10], rot_noise=0.01, trans_noise=0.005)
    H = g.random_transforms(rng, translation_scale=0.3)
    s1 = solve(A, B, method="li")
    s2 = solve(A, [g.inv(H) @ B[0]], method="li")
    rot, trans = _errors(s2.Y, s1.Y @ H)
    assert rot < 1e-9
    assert 1e-7 < trans < 1e-2


def test_joint_with_one_camera_equals_shah_on_noisy_data():
    rng = np.random.default_rng(3)
    for _trial in range(20):
        A, B, _, _ = eye_on_hand(rng, [int(rng.integers(3, 60))], rot_noise=0.05, trans_noise=0.02)
        sj = solve(A, B, "joint")
        ss = solve(A, B, "shah")
        assert np.abs(sj.X - ss.X).max() < 1e-10
        assert np.abs(sj.Y - ss.Y).max() < 1e-10


def test_joint_and_wang2022_are_different_estimators_of_the_same_truth():
    """wang2022 stacks the per-camera *summed* equations (N_j y - K_j x_j, N_j x_j - L_j y)
    with one norm on all blocks; joint solves the per-measurement rows with ||vec R_Y||
    fixed.  Equal without noise (see the recovery test); on noise both are close to the truth
    and to each other at the noise level, not to rounding."""
    rng = np.random.default_rng(4)
    A, B, X, Y = eye_to_base(rng, [40, 35, 20, 41], rot_noise=0.02, trans_noise=0.01)
    sj = solve(A, B, "joint")
    sw = solve(A, B, "wang2022")
    for sol in (sj, sw):
        rot, trans = _errors(sol.Y, Y)
        assert rot < 1.0 and trans < 0.05
    rot, _ = _errors(sj.Y, sw.Y)
    assert 1e-9 < rot < 0.5


def test_single_camera_methods_keep_per_camera_Y_and_combine_by_means():
    rng = np.random.default_rng(5)
    A, B, _, _ = eye_to_base(rng, [15, 15, 15], rot_noise=0.02, trans_noise=0.01)
    sol = solve(A, B, "shah")
    assert sol.Y_per_camera.shape == (3, 4, 4)
    np.testing.assert_allclose(sol.Y[:3, 3], sol.Y_per_camera[:, :3, 3].mean(axis=0))
    # rotation mean: each per-camera Y is close to the combined one
    assert np.degrees(g.rotation_angle_between(sol.Y_per_camera, sol.Y)).max() < 5
    for j in range(3):
        alone = solve([A[j]], [B[j]], "shah")
        np.testing.assert_allclose(alone.X[0], sol.X[j], atol=1e-12)
        np.testing.assert_allclose(alone.Y, sol.Y_per_camera[j], atol=1e-12)
    assert solve(A, B, "joint").Y_per_camera is None


def test_noisy_recovery_within_noise_tied_tolerance():
    """With rotation noise sigma (rad) on n measurements the error shrinks like sigma/sqrt(n)."""
    rng = np.random.default_rng(6)
    sigma_r, sigma_t = 1e-3, 1e-3
    A, B, X, Y = eye_to_base(rng, [200, 200, 200], rot_noise=sigma_r, trans_noise=sigma_t)
    sol = solve(A, B, "joint")
    rot, trans = _errors(sol.X, X)
    assert np.radians(rot) < 6 * sigma_r / np.sqrt(200) * 3
    # translation error also gets the lever arm of the rotation error (scale ~2 m here)
    assert trans < 6 * (sigma_t + 2.0 * sigma_r) / np.sqrt(200) * 3


def test_joint_solves_camera_with_single_axis_motion_through_shared_Y():
    """A camera whose own motion is about one axis is still determined once Y is known."""
    rng = np.random.default_rng(9)
    A, B, X, Y = eye_to_base(rng, [12, 12])
    # camera 2: target rotated about one world axis only
    axis = np.array([0.0, 0.0, 1.0])
    T_world_marker = g.transform_from_rotvec(np.outer(np.linspace(0, 1.0, 8), axis),
                                             rng.normal(size=(8, 3)))
    Xc = g.random_transforms(rng)
    A.append(g.inv(T_world_marker))
    B.append(g.inv(g.inv(Xc) @ T_world_marker @ Y))
    sol = solve(A, B, "joint")
    rot, trans = _errors(sol.X[2], Xc)
    assert rot < 1e-9 and trans < 1e-9
    with pytest.raises(multieye.DegenerateMotionError, match="camera cam2.*single axis"):
        solve(A, B, "shah")


@pytest.mark.parametrize("method", CLOSED_FORM + ITERATIVE)
def test_noise_free_recovery_on_the_papers_realistic_rig(method):
    """Small, physically plausible board motions (not uniform random rotations): the
    accuracy of the Kronecker forms degrades like eps / angle^2, still far below 1e-9 here."""
    from multieye.sim.rigs import simulate_rig

    tol = 1e-9 if method in CLOSED_FORM else 1e-5
    for setup in ("eye-to-base", "eye-on-hand"):
        sc = simulate_rig(11, n_cameras=4, measurements=[40, 25, 12, 33], setup=setup)
        sol = solve(sc.A, sc.B, method)
        for est, true in ((sol.X, sc.X), (sol.Y, sc.Y)):
            rot, trans = _errors(est, true)
            assert rot < tol and trans < tol, (setup, rot, trans)


def test_joint_memory_grows_at_most_linearly_with_measurements():
    """Peak allocation (tracemalloc) of a joint solve on 4 cameras x n: no term above O(n).

    Any array with a dimension per pair of measurements would make the ratio grow with n;
    the benchmark prints the same figure up to 64000 measurements.
    """
    import tracemalloc

    def peak(n):
        A, B, _, _ = eye_to_base(np.random.default_rng(0), [n] * 4)
        tracemalloc.start()
        solve(A, B, method="joint")
        used = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return used

    small, large = peak(500), peak(4000)
    assert large / small <= 8.0 * 1.05        # 8x the measurements, at most 8x the memory
    assert large / (4 * 4000) < 2000           # bytes per measurement


def test_the_method_names_known_without_the_solvers_are_the_registrys():
    """Options are checked against multieye.solvers.methods before the solvers are imported
    (issue 21): the same names, in the same order, as the registry solves."""
    assert methods.JOINT_METHOD_NAMES == tuple(registry.JOINT_METHODS)
    assert methods.SINGLE_METHOD_NAMES == tuple(registry.SINGLE_METHODS)
    assert methods.METHODS == registry.METHODS


@pytest.mark.parametrize("method", ["joint", "shah"])
def test_a_non_finite_closed_form_is_refused_not_returned(monkeypatch, method):
    """A method whose linear algebra gives NaN (here forced) must raise, naming the camera,
    never hand back NaN extrinsics."""
    A, B, _, _ = eye_to_base(np.random.default_rng(5), [8, 8, 8])
    if method == "joint":
        inner = registry.JOINT_METHODS["joint"]

        def nan_y(meas):
            X, Y = inner(meas)
            return X, np.full_like(Y, np.nan)

        monkeypatch.setitem(registry.JOINT_METHODS, "joint", nan_y)
        where = "non-finite Y"
    else:
        inner = registry.SINGLE_METHODS["shah"]
        calls = []

        def nan_x(Aj, Bj):
            X, Y = inner(Aj, Bj)
            calls.append(1)
            return (np.full_like(X, np.nan) if len(calls) == 2 else X), Y

        monkeypatch.setitem(registry.SINGLE_METHODS, "shah", nan_x)
        where = "non-finite X of camera cam1"
    with pytest.raises(multieye.DegenerateMotionError, match=f"method {method}: .*{where}"):
        solve(A, B, method=method)
