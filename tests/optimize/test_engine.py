"""The optimisation engine: exact answers on linear problems, the Schur complement against the
dense normal equations, robust losses against scipy, manifolds, and its error messages."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import least_squares

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.lie import exp_so3
from multieye.optimize.blocks import Blocks

from linear_groups import Linear, _dense
from multieye.optimize.gradient_check import numerical_jacobians
from multieye.optimize.levenberg_marquardt import Options, covariance, minimize


def _linear_problem(rng, n_global=3, n_local=20, rows_per_local=4, dim=2):
    """Globals (n_global, 2), locals (n_local, 3); each local segment touches one global."""
    seg_global = rng.integers(0, n_global, size=n_local)
    index = np.column_stack([seg_global, np.arange(n_local)])
    segment = np.repeat(np.arange(n_local), rows_per_local)
    n = segment.size
    Ag = rng.normal(size=(n, dim, 2))
    Al = rng.normal(size=(n, dim, 3))
    b = rng.normal(size=(n, dim))
    prior = Linear(("G",), np.arange(n_global)[:, None], np.arange(n_global),
                   np.tile(np.eye(2), (n_global, 1, 1)), None, rng.normal(size=(n_global, 2)))
    fams = [Blocks("G", np.zeros((n_global, 2)), "euclidean"),
            Blocks("L", np.zeros((n_local, 3)), "euclidean", eliminate=True)]
    return fams, [Linear(("G", "L"), index, segment, Ag, Al, b), prior]


def test_linear_problem_solved_exactly_with_the_dense_covariance(rng):
    fams, groups = _linear_problem(rng)
    J, r0 = _dense(fams, groups)
    x = np.linalg.lstsq(J, -r0, rcond=None)[0]
    res = minimize(fams, groups, Options(tol=1e-14))
    got = np.concatenate([res.value("G").ravel(), res.value("L").ravel()])
    np.testing.assert_allclose(got, x, atol=1e-10)
    cov = covariance(res.families, groups, local=True)
    full = np.linalg.inv(J.T @ J)
    np.testing.assert_allclose(cov.kept, full[:6, :6], rtol=1e-9, atol=1e-12)
    blocks = np.stack([full[6 + 3 * b:9 + 3 * b, 6 + 3 * b:9 + 3 * b] for b in range(20)])
    np.testing.assert_allclose(cov.local, blocks, rtol=1e-9, atol=1e-12)


def test_covariance_where_a_huge_parameter_trades_off_with_eliminated_ones(rng):
    """Each global's first coordinate moves the residuals as its segments' first local
    coordinates do, 1e11 times as strongly (information 1e22; only its prior, of information
    1, tells them apart: a rational lens whose numerator and denominator nearly share a
    factor): that difference is below double precision, so the reduced diagonal cancels.
    The covariance comes out finite, the other coordinates' exact (the first ones are the
    same problem reparameterised: without them the rest is unchanged), where the unscaled
    Schur complement's diagonal went negative and the Cholesky's scaling overflowed (a
    calibration ended in a traceback)."""
    fams, (lin, prior) = _linear_problem(rng)
    lin.Ag[:, :, 0] = 1e11 * lin.Al[:, :, 0]
    cov = covariance(fams, [lin, prior], local=False)
    assert np.all(np.isfinite(cov.kept))
    J, _ = _dense(fams, [lin, prior])
    keep = [j for j in range(J.shape[1]) if j >= 6 or j % 2 == 1]   # all but G[:, 0]
    full = np.linalg.inv(J[:, keep].T @ J[:, keep])
    np.testing.assert_allclose(cov.kept[1::2, 1::2], full[:3, :3], rtol=1e-6)


def test_eliminated_blocks_shared_by_several_groups_match_the_dense_solution(rng):
    """An eliminated block touched by segments of several groups, each with other kept
    blocks (one motion-capture pose seen by several cameras): the Schur complement's step and
    covariance against the dense normal equations."""
    fams, (lin, prior) = _linear_problem(rng)
    n_local, rows = 20, 4
    more = []
    for _ in range(2):                  # two more "cameras" seeing every block, other globals
        segment = np.repeat(np.arange(n_local), rows)
        n = segment.size
        more.append(Linear(("G", "L"), np.column_stack([rng.integers(0, 3, size=n_local),
                                                        np.arange(n_local)]), segment,
                           rng.normal(size=(n, 2, 2)), rng.normal(size=(n, 2, 3)),
                           rng.normal(size=(n, 2))))
    groups = [lin, prior] + more
    J, r0 = _dense(fams, groups)
    x = np.linalg.lstsq(J, -r0, rcond=None)[0]
    res = minimize(fams, groups, Options(tol=1e-14))
    got = np.concatenate([res.value("G").ravel(), res.value("L").ravel()])
    np.testing.assert_allclose(got, x, atol=1e-10)
    cov = covariance(res.families, groups, local=True)
    full = np.linalg.inv(J.T @ J)
    np.testing.assert_allclose(cov.kept, full[:6, :6], rtol=1e-9, atol=1e-12)
    blocks = np.stack([full[6 + 3 * b:9 + 3 * b, 6 + 3 * b:9 + 3 * b] for b in range(20)])
    np.testing.assert_allclose(cov.local, blocks, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("loss", ["huber", "soft_l1", "cauchy"])
def test_robust_nonlinear_problem_matches_scipy(loss, rng):
    fams, groups = _linear_problem(rng, n_local=10)
    groups[0].nonlinear = 0.05
    groups[0].b[::7] += 8.0                                   # outliers for the loss to meet
    res = minimize(fams, groups, Options(loss=loss, f_scale=1.5, tol=1e-15, max_iter=200))
    sizes = [f.count * f.size for f in fams]

    def residuals(p):
        values = {f.name: f.retract(p[o:o + s]).value
                  for f, o, s in zip(fams, np.cumsum([0] + sizes[:-1]), sizes)}
        return np.concatenate([grp.evaluate(values, False)[0].ravel() for grp in groups])

    kw = dict(loss=loss, f_scale=1.5, jac="3-point")
    ref = least_squares(residuals, np.zeros(sum(sizes)), ftol=1e-15, xtol=1e-15, gtol=1e-15, **kw)
    got = np.concatenate([res.value("G").ravel(), res.value("L").ravel()])
    assert res.converged
    # Neither solver stops exactly at the optimum, and where each stops depends on the library
    # version's arithmetic. What the problem guarantees: both are at the same minimum, and two
    # points whose gradients are g1 and g2 lie within (|g1| + |g2|) / lambda_min of each other,
    # lambda_min the smallest eigenvalue of the Gauss-Newton Hessian (the loss-weighted J^T J
    # scipy returns). The gradients are scipy's own, at both points, by the same differences.
    here = least_squares(residuals, got, max_nfev=1, **kw)       # evaluates, takes no step
    assert np.array_equal(here.x, got)
    lam_min = np.linalg.eigvalsh(ref.jac.T @ ref.jac)[0]
    assert lam_min > 1e-3                                          # the problem is well posed
    bound = 2.0 * (np.linalg.norm(here.grad) + np.linalg.norm(ref.grad)) / lam_min
    assert np.linalg.norm(got - ref.x) <= bound
    assert bound < 1e-4                                            # and both near the optimum
    assert here.cost <= ref.cost * (1 + 1e-12) + 1e-12


def test_gradient_check_of_the_test_group(rng):
    fams, groups = _linear_problem(rng, n_local=5)
    groups[0].nonlinear = 0.1
    fams = [f.retract(rng.normal(scale=0.3, size=f.count * f.size)) for f in fams]
    _, analytic = groups[0].evaluate({f.name: f.value for f in fams}, True)
    for a, n in zip(analytic, numerical_jacobians(fams, groups[0])):
        np.testing.assert_allclose(a, n, atol=1e-7)


def test_manifolds_retract_as_documented(rng):
    T = g.random_transforms(rng, 4)
    d = rng.normal(scale=0.1, size=(4, 6))
    left = Blocks("T", T, "se3-left").retract(d).value
    right = Blocks("T", T, "se3-right").retract(d).value
    R = exp_so3(d[:, :3])
    np.testing.assert_allclose(left[:, :3, :3], R @ T[:, :3, :3], atol=1e-14)
    np.testing.assert_allclose(right[:, :3, :3], T[:, :3, :3] @ R, atol=1e-14)
    for out in (left, right):
        np.testing.assert_allclose(out[:, :3, 3], T[:, :3, 3] + d[:, 3:], atol=1e-14)
    v = Blocks("v", np.zeros((2, 3)), "euclidean").retract(np.arange(6.0)).value
    assert np.array_equal(v, np.arange(6.0).reshape(2, 3))


def test_bad_problems_are_refused(rng):
    fams, groups = _linear_problem(rng, n_local=4)
    with pytest.raises(InputError, match="names must be unique"):
        minimize([fams[0], fams[0]], groups[1:])
    with pytest.raises(InputError, match="unknown block families"):
        minimize(fams[:1], groups)
    with pytest.raises(InputError, match="manifold must be one of"):
        Blocks("T", np.eye(4)[None], "so3")
    with pytest.raises(InputError, match=r"pose values must be \(count, 4, 4\)"):
        Blocks("T", np.eye(3)[None])
    with pytest.raises(InputError, match="segment by segment"):
        Linear(("G",), np.zeros((2, 1), int), [1, 0], None, None, np.zeros((2, 2)))
    with pytest.raises(InputError, match="unknown loss"):
        Options(loss="l2")
    with pytest.raises(InputError, match="max_iter must be a whole number"):
        Options(max_iter=0)
    two_local = Linear(("L", "L"), np.zeros((1, 2), int), [0], np.zeros((1, 2, 3)),
                       np.zeros((1, 2, 3)), np.zeros((1, 2)))
    with pytest.raises(InputError, match="two eliminated blocks"):
        minimize(fams, [two_local])


def test_unobserved_parameters_make_the_covariance_refuse(rng):
    fams, groups = _linear_problem(rng, n_global=3, n_local=4)
    extra = Blocks("H", np.zeros((1, 2)), "euclidean")
    with pytest.raises(InputError, match="information matrix is singular"):
        covariance(fams + [extra], groups)


def test_parameters_the_data_cannot_tell_apart_are_named_not_hidden(rng):
    """Two globals that enter every residual only through their sum: each is observed, their
    difference is not. The covariance covers the sum; the difference is returned as the
    undetermined direction."""
    n = 30
    A = rng.normal(size=(n, 1, 1))
    group = Linear(("G",), np.zeros((n, 1), int), np.arange(n),
                   np.concatenate([A, A], axis=2), None, rng.normal(size=(n, 1)))
    fams = [Blocks("G", np.zeros((1, 2)), "euclidean")]
    cov = covariance(fams, [group])
    assert cov.undetermined.shape == (2, 1)
    np.testing.assert_allclose(np.abs(cov.undetermined[:, 0]), [2 ** -0.5] * 2, atol=1e-6)
    assert cov.undetermined_in("G", 1, 2)
    # the sum's variance is the least-squares one
    s = np.array([1.0, 1.0])
    assert s @ cov.kept @ s == pytest.approx(1.0 / np.sum(A ** 2), rel=1e-9)


def _robust_problem(rng, nonlinear=0.0):
    """Small residuals (the target pixels' kind: the model nearly linear at their scale)
    and outliers beyond the loss's threshold."""
    fams, groups = _linear_problem(rng, n_local=30)
    groups[0].b *= 0.1
    groups[0].nonlinear = nonlinear
    groups[0].b[::5] += 6.0
    return fams, groups


@pytest.mark.parametrize("loss", ["huber", "soft_l1"])
def test_steps_with_the_robust_curvature_reach_the_same_optimum_sooner(loss, rng):
    """Near the optimum the steps on the robust cost's own curvature (Options.newton_below)
    converge faster than the IRLS steps, to the same minimum (lower or equal cost at the same
    stopping rule).  Only the convex losses: the others' negative curvature is clipped at 0,
    so no faster convergence is claimed for them."""
    fams, groups = _robust_problem(rng)
    near = minimize(fams, groups, Options(loss=loss, f_scale=1.0, tol=1e-4))
    opts = Options(loss=loss, f_scale=1.0, tol=1e-10)
    irls = minimize(near.families, groups, opts)
    newton = minimize(near.families, groups, replace(opts, newton_below=np.inf))
    exact = minimize(newton.families, groups, replace(opts, tol=0.0, max_iter=50,
                                                      newton_below=np.inf))
    assert newton.converged
    assert newton.iterations < irls.iterations
    assert newton.cost - exact.cost <= irls.cost - exact.cost
    for name in ("G", "L"):
        np.testing.assert_allclose(newton.value(name), exact.value(name), atol=1e-6)
        np.testing.assert_allclose(irls.value(name), exact.value(name), atol=1e-3)


def test_far_from_the_optimum_the_irls_steps_are_kept_until_the_switch(rng):
    """From a far start, newton_below switches only once the IRLS steps have nearly stopped
    lowering the cost; the result is the optimum either way, and the linear loss (no
    curvature to correct) is untouched."""
    fams, groups = _robust_problem(rng)
    opts = Options(loss="huber", f_scale=1.0, tol=1e-12, max_iter=200)
    switched = minimize(fams, groups, replace(opts, newton_below=1e-3))
    plain = minimize(fams, groups, opts)
    assert switched.converged and switched.iterations <= plain.iterations
    for name in ("G", "L"):
        np.testing.assert_allclose(switched.value(name), plain.value(name), atol=1e-4)
    lin = Options(loss="linear", tol=1e-12)
    a = minimize(fams, groups, lin)
    b = minimize(fams, groups, replace(lin, newton_below=np.inf))
    assert a.iterations == b.iterations
    for name in ("G", "L"):
        np.testing.assert_array_equal(a.value(name), b.value(name))


@pytest.mark.parametrize("bad", [-1.0, float("nan"), "1e-3", None])
def test_newton_below_must_be_a_non_negative_number(bad):
    with pytest.raises(InputError, match="newton_below"):
        Options(newton_below=bad)
