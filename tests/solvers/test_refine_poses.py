"""Maximum-likelihood refinement of the pose residuals: Jacobian, accuracy, covariance against
Monte Carlo, robustness, the single-Y adapter behind solve(refine=True)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.solvers.general import MeasurementGroup, random_general_problem, solve_general
from multieye.optimize.blocks import Blocks
from multieye.optimize.gradient_check import numerical_jacobians
from multieye.solvers.groups import as_groups
from multieye.solvers.refine_poses import (
    PoseResiduals,
    refine_general,
    refine_solution,
    relative_pose_covariance,
)
from multieye.solvers import solve


def _stacked(sol, unknowns) -> np.ndarray:
    return np.stack([(sol.X if side == "X" else sol.Y)[name] for side, name in unknowns])


def _perturbation(T, T_true) -> np.ndarray:
    """(phi, tau) of T relative to T_true in the refinement's convention, (k, 6)."""
    phi = Rotation.from_matrix(T[:, :3, :3] @ np.swapaxes(T_true[:, :3, :3], 1, 2)).as_rotvec()
    return np.concatenate([phi, T[:, :3, 3] - T_true[:, :3, 3]], axis=1)


def _errors(sol, X, Y) -> np.ndarray:
    """(rotation angle rad, translation m) of every unknown against the truth."""
    return np.array([[g.rotation_angle_between(D[k], T[k]), g.translation_distance(D[k], T[k])]
                     for D, T in ((sol.X, X), (sol.Y, Y)) for k in T])


def _renoised(groups, rng, rot_sigma, trans_sigma):
    """Same A and noise-free B as ``groups``, with fresh noise on B as the generator adds it."""
    out = []
    for gr in groups:
        n = len(gr.A)
        noise = g.transform_from_rotvec(rng.normal(scale=rot_sigma, size=(n, 3)),
                                        rng.normal(scale=trans_sigma, size=(n, 3)))
        out.append(MeasurementGroup(gr.x_name, gr.y_name, gr.A, gr.B @ noise))
    return out


def test_analytic_jacobian_matches_finite_differences(rng):
    groups, _, _ = random_general_problem(rng, 2, 3, 40, rot_noise_rad=0.05, trans_noise_m=0.02)
    groups = as_groups(groups)
    sol = solve_general(groups)
    xs, ys = list(sol.X), list(sol.Y)
    moved = lambda T: g.transform_from_rotvec(rng.normal(scale=0.3, size=(len(T), 3)),   # noqa: E731
                                              rng.normal(scale=0.3, size=(len(T), 3))) @ T
    fams = [Blocks("X", moved(np.stack([sol.X[n] for n in xs]))),
            Blocks("Y", moved(np.stack([sol.Y[n] for n in ys])))]
    group = PoseResiduals(groups, xs, ys, 0.01, 0.02)
    _, analytic = group.evaluate({f.name: f.value for f in fams}, True)
    for a, n in zip(analytic, numerical_jacobians(fams, group)):
        assert np.abs(a - n).max() < 1e-6 * np.abs(n).max()


def test_noise_free_truth_is_a_fixed_point(rng):
    groups, X, Y = random_general_problem(rng, 2, 2, 30)
    sol = refine_general(groups, solve_general(groups), rot_sigma_rad=0.01, trans_sigma_m=0.01)
    assert np.abs(_errors(sol, X, Y)).max() < 1e-9


def test_refinement_is_more_accurate_than_the_closed_form():
    closed, refined = [], []
    for seed in range(10):
        rng = np.random.default_rng(seed)
        groups, X, Y = random_general_problem(rng, 2, 3, 60, rot_noise_rad=0.02,
                                              trans_noise_m=0.005)
        sol = solve_general(groups)
        closed.append(_errors(sol, X, Y))
        refined.append(_errors(refine_general(groups, sol), X, Y))
    rms_closed = np.sqrt(np.mean(np.square(closed), axis=(0, 1)))
    rms_refined = np.sqrt(np.mean(np.square(refined), axis=(0, 1)))
    assert np.all(rms_refined < 0.8 * rms_closed)


@pytest.mark.parametrize("loss, given, trials, band, chi2_tol", [
    ("linear", True, 150, (0.65, 1.5), 0.15),
    ("huber", False, 100, (0.6, 1.7), 0.3),
])
def test_predicted_covariance_matches_monte_carlo_spread(loss, given, trials, band, chi2_tol):
    rng = np.random.default_rng(11)
    truth, X, Y = random_general_problem(rng, 2, 2, 40, n_groups=3)
    rot_sigma, trans_sigma = 0.01, 0.005
    unknowns = solve_general(truth).unknowns
    T_true = np.stack([(X if side == "X" else Y)[name] for side, name in unknowns])
    sigmas = {"rot_sigma_rad": rot_sigma, "trans_sigma_m": trans_sigma} if given else {}
    errors, covs = [], []
    for _ in range(trials):
        groups = _renoised(truth, rng, rot_sigma, trans_sigma)
        sol = refine_general(groups, solve_general(groups), loss=loss, **sigmas)
        assert sol.unknowns == unknowns
        errors.append(_perturbation(_stacked(sol, sol.unknowns), T_true).ravel())
        covs.append(sol.covariance)
    errors = np.array(errors)
    predicted = np.mean(covs, axis=0)
    ratio = np.diag(np.cov(errors.T)) / np.diag(predicted)
    assert band[0] < ratio.min() and ratio.max() < band[1]
    # Mean squared Mahalanobis distance of the errors: the dimension if the covariance is right.
    chi2 = np.mean([e @ np.linalg.solve(c, e) for e, c in zip(errors, covs)])
    assert abs(chi2 / errors.shape[1] - 1.0) < chi2_tol


def test_estimated_sigmas_follow_the_noise(rng):
    groups, _, _ = random_general_problem(rng, 2, 3, 300, rot_noise_rad=0.02, trans_noise_m=0.004)
    sol = solve_general(groups, refine=True)
    assert sol.sigma_rot_rad == pytest.approx(0.02, rel=0.15)
    assert sol.sigma_trans_m == pytest.approx(0.004, rel=0.15)
    k = len(sol.unknowns)
    assert sol.covariance.shape == (6 * k, 6 * k)
    assert np.allclose(sol.covariance, sol.covariance.T)
    assert np.all(np.linalg.eigvalsh(sol.covariance) > 0)
    name = sol.unknowns[-1][1]
    assert np.array_equal(sol.covariance_of("Y", name), sol.covariance[-6:, -6:])


def test_huber_resists_outliers_that_pull_least_squares(rng):
    groups, X, Y = random_general_problem(rng, 2, 2, 200, rot_noise_rad=0.005,
                                          trans_noise_m=0.002)
    bad = []
    for gr in groups:
        B = gr.B.copy()
        hit = rng.random(len(B)) < 0.08
        B[hit] = B[hit] @ g.transform_from_rotvec(rng.normal(scale=0.2, size=(hit.sum(), 3)),
                                                  rng.normal(scale=0.2, size=(hit.sum(), 3)))
        bad.append(MeasurementGroup(gr.x_name, gr.y_name, gr.A, B))
    start = solve_general(bad)
    robust = _errors(refine_general(bad, start, loss="huber"), X, Y)
    plain = _errors(refine_general(bad, start, loss="linear"), X, Y)
    assert robust[:, 1].max() < 0.5 * plain[:, 1].max()
    assert robust[:, 0].max() < 0.5 * plain[:, 0].max()


def test_scipy_least_squares_reaches_the_same_optimum(rng):
    """The engine against scipy's trust-region least squares with the same robust loss."""
    from scipy.optimize import least_squares

    groups, _, _ = random_general_problem(rng, 2, 2, 40, n_groups=3, rot_noise_rad=0.02,
                                          trans_noise_m=0.01)
    groups = as_groups(groups)
    start = solve_general(groups)
    ours = refine_general(groups, start, rot_sigma_rad=0.02, trans_sigma_m=0.01, loss="huber",
                          tol=1e-14)
    xs, ys = list(start.X), list(start.Y)
    fams = [Blocks("X", np.stack([start.X[n] for n in xs])),
            Blocks("Y", np.stack([start.Y[n] for n in ys]))]
    group = PoseResiduals(groups, xs, ys, 0.02, 0.01)

    def moved(p):
        return [fams[0].retract(p[:12]).value, fams[1].retract(p[12:]).value]

    def residuals(p):
        X, Y = moved(p)
        return group.evaluate({"X": X, "Y": Y}, False)[0].ravel()

    res = least_squares(residuals, np.zeros(24), loss="huber", f_scale=1.345, method="trf",
                        ftol=1e-15, xtol=1e-15, gtol=1e-15)
    X, Y = moved(res.x)
    for k, name in enumerate(xs):
        assert np.abs(ours.X[name] - X[k]).max() < 1e-7
    for k, name in enumerate(ys):
        assert np.abs(ours.Y[name] - Y[k]).max() < 1e-7


def test_solve_refine_fills_the_single_y_covariance(rng):
    groups, X, Y = random_general_problem(rng, 3, 1, 90, rot_noise_rad=0.02, trans_noise_m=0.005)
    A = [gr.A for gr in groups]
    B = [gr.B for gr in groups]
    closed = solve(A, B)
    refined = solve(A, B, refine=True)
    general = refine_general(groups, solve_general(groups))
    m = len(groups)
    assert refined.method == closed.method
    assert refined.covariance.shape == (6 * (m + 1), 6 * (m + 1))
    # Same order (X^1..X^m then Y) and same numbers as the general refinement.
    assert np.allclose(refined.covariance, general.covariance, rtol=1e-6, atol=1e-14)
    for j, gr in enumerate(groups):
        assert np.abs(refined.X[j] - general.X[gr.x_name]).max() < 1e-9
    assert refined.residuals[0].n == len(groups[0].A)
    truth_error = np.linalg.norm(refined.Y[:3, 3] - Y["y0"][:3, 3])
    assert truth_error < np.linalg.norm(closed.Y[:3, 3] - Y["y0"][:3, 3])


def test_refine_solution_needs_the_measurements(rng):
    groups, _, _ = random_general_problem(rng, 2, 1, 20)
    sol = solve([gr.A for gr in groups], [gr.B for gr in groups])
    bare = type(sol)(X=sol.X, Y=sol.Y, method=sol.method)
    with pytest.raises(InputError, match="without its measurements"):
        refine_solution(bare)


def test_relative_pose_covariance_matches_numerical_propagation(rng):
    T_w_r, T_w_c = g.random_transforms(rng, 2)
    L = rng.normal(size=(12, 12))
    cov = L @ L.T * 1e-4

    def relative(p):
        Tr = g.make_transform(Rotation.from_rotvec(p[0:3]).as_matrix() @ T_w_r[:3, :3],
                              T_w_r[:3, 3] + p[3:6])
        Tc = g.make_transform(Rotation.from_rotvec(p[6:9]).as_matrix() @ T_w_c[:3, :3],
                              T_w_c[:3, 3] + p[9:12])
        return g.inv(Tr) @ Tc

    T0 = relative(np.zeros(12))
    J = np.empty((6, 12))
    h = 1e-7
    for j in range(12):
        e = np.zeros(12)
        e[j] = h
        J[:, j] = _perturbation(relative(e)[None], T0[None]).ravel() / h
    expected = J @ cov @ J.T
    assert np.allclose(relative_pose_covariance(T_w_r, T_w_c, cov), expected,
                       rtol=1e-5, atol=1e-10)


@pytest.mark.parametrize("options, message", [
    ({"loss": "tukey"}, "unknown loss 'tukey'"),
    ({"rot_sigma_rad": -1.0}, "rot_sigma_rad must be a positive number"),
    ({"trans_sigma_m": float("nan")}, "trans_sigma_m must be a positive number"),
    ({"loss_scale": 0.0}, "loss_scale must be a positive number"),
])
def test_bad_options_are_rejected(rng, options, message):
    groups, _, _ = random_general_problem(rng, 1, 1, 10)
    with pytest.raises(InputError, match=message):
        refine_general(groups, solve_general(groups), **options)


def test_initial_solution_must_hold_every_unknown(rng):
    groups, _, _ = random_general_problem(rng, 2, 2, 20)
    sol = solve_general(groups[:1])
    with pytest.raises(InputError, match="no unknown named"):
        refine_general(groups, sol)
