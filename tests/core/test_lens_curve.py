"""A wide lens' radial curve and its covariance (issue 33), what calibration.json states as
``lens_curve``: the pixel radii of three rays over the observed field, the marginal of the
curve parameters' covariance, and honest where the unified model's parameters' is not."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core.lens import project_points
from multieye.core.lens_curve import (CURVE_MODELS, curve_covariance, observed_angles,
                                      observed_curve, radial_curve)
from multieye.imaging.generic_start import _Problem, fit_lens
from multieye.sim.wide_lens import board_views, wide_lens


def _lens_covariance(views, fit, sigma):
    prob = _Problem(views, fit.intrinsics, fit.T_cam_target)
    J = prob.jacobian(np.concatenate([fit.intrinsics.params, np.zeros(6 * len(views))]))
    return sigma ** 2 * np.linalg.inv(J.T @ J)[:prob.n_lens, :prob.n_lens]


def _points(views, T):
    return np.concatenate([o @ Ti[:3, :3].T + Ti[:3, 3] for (o, _), Ti in zip(views, T)])


@pytest.mark.parametrize("model", sorted(CURVE_MODELS))
def test_radial_curve_is_the_radii_block_of_the_curve_parameters(model):
    lens = wide_lens(model, 190.0)
    rng = np.random.default_rng(3)
    A = rng.normal(size=(lens.params.size, lens.params.size))
    C = A @ A.T * 1e-4
    theta_max = np.radians(95.0)
    n = len(CURVE_MODELS[model])
    angles = 0.9 * theta_max * np.arange(1, n + 1) / n          # curve_jacobian's rays
    curve = radial_curve(lens, C, angles)
    np.testing.assert_allclose(curve.covariance, curve_covariance(lens, C, theta_max)[:n, :n],
                               rtol=1e-12, atol=1e-12)
    rays = np.column_stack([np.sin(angles), np.zeros(n), np.cos(angles)])
    np.testing.assert_allclose(curve.radii_px, project_points(rays, lens)[:, 0] - lens.K[0, 2])
    np.testing.assert_allclose(curve.angles_deg, np.degrees(angles))


@pytest.mark.parametrize("model", ["fisheye", "unified", "double-sphere", "eucm"])
def test_radial_curve_covariance_against_central_differences(model):
    lens = wide_lens(model, 170.0 if model == "fisheye" else 220.0)
    p = lens.params
    rng = np.random.default_rng(4)
    A = rng.normal(size=(p.size, p.size))
    C = A @ A.T * 1e-4
    angles = np.radians([25.0, 50.0, 75.0])
    J = np.empty((3, p.size))
    for j in range(p.size):
        h = 1e-6 * max(1.0, abs(p[j]))
        e = np.zeros(p.size)
        e[j] = h
        J[:, j] = (radial_curve(lens.with_params(p + e), C, angles).radii_px
                   - radial_curve(lens.with_params(p - e), C, angles).radii_px) / (2 * h)
    np.testing.assert_allclose(radial_curve(lens, C, angles).covariance, J @ C @ J.T,
                               rtol=1e-6, atol=1e-9)


def test_observed_angles_reach_the_widest_ray_the_lens_projects():
    lens = wide_lens("unified", 220.0)
    theta = np.radians([10.0, 60.0, 104.0])
    P = np.column_stack([np.sin(theta), np.zeros(3), np.cos(theta)]) * 0.4
    np.testing.assert_allclose(observed_angles(lens, P), 0.9 * np.radians(104.0) * np.array(
        [1, 2, 3]) / 3)
    pinhole_only = wide_lens("eucm", 190.0).with_params([300.0, 300.0, 511.5, 511.5, 0.0, 1.0])
    assert observed_angles(pinhole_only, P[2:]) is None           # behind a pinhole lens
    assert observed_curve(lens.with_params(lens.params), np.eye(9), P) is not None
    from multieye.core.intrinsics import Intrinsics
    pinhole = Intrinsics(K=[[300.0, 0, 320], [0, 300, 240], [0, 0, 1]], dist=np.zeros(5))
    assert observed_curve(pinhole, np.eye(9), P[:2]) is None       # not a wide model


def test_unified_curve_covariance_is_honest_where_its_parameters_are_not():
    """Ten views of a unified lens of 190 degrees, 0.2 px noise, 25 draws each fitted (from the
    truth: the pipeline's start reaches the same optimum, docs/results/wide_render.md): the
    exported radii's NEES / 3 averages about 1, the parameters' (the same draws, the same
    covariance) far above it."""
    true = wide_lens("unified", 190.0)
    clean, T = board_views(true, 190.0, 10, np.random.default_rng(11), noise_px=0.0)
    rng = np.random.default_rng(21)
    nees_curve, nees_par = [], []
    for _ in range(25):
        views = [(o, u + rng.normal(0.0, 0.2, u.shape)) for o, u in clean]
        fit = fit_lens(views, true, T, huber_px=None, max_iterations=500)
        C = _lens_covariance(views, fit, 0.2)
        curve = observed_curve(fit.intrinsics, C, _points(views, fit.T_cam_target))
        e = curve.radii_px - radial_curve(true, C, np.radians(curve.angles_deg)).radii_px
        nees_curve.append(e @ np.linalg.solve(curve.covariance, e) / 3)
        ep = fit.intrinsics.params - true.params
        nees_par.append(ep @ np.linalg.solve(C, ep) / ep.size)
    assert 0.5 < np.mean(nees_curve) < 2.0, np.mean(nees_curve)
    assert np.mean(nees_par) > 5.0, np.mean(nees_par)


def test_undetermined_parameters_are_those_whose_sd_dwarfs_their_scale():
    """fx with a standard deviation over 10 % of it, cx/cy over 50 px, xi/alpha/beta over 1
    are named (NaN too); k1 k2 are not judged."""
    from multieye.core.lens_curve import undetermined_parameters

    lens = wide_lens("double-sphere", 190.0)
    C = np.diag([1.0, 1.0, 0.01, 0.01, 0.01, 1e-4])
    assert undetermined_parameters(lens, C) == []
    fx = lens.params[0]
    C = np.diag([(0.2 * fx) ** 2, 1.0, 60.0 ** 2, 0.01, 4.0, np.nan])
    assert [n for n, _, _ in undetermined_parameters(lens, C)] == ["fx", "cx", "xi", "alpha"]
    uni = wide_lens("unified", 190.0)
    assert undetermined_parameters(uni, np.diag([1.0] * 4 + [0.01, 1e6, 1e6, 1e6, 1e6])) == []
