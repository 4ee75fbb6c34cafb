"""Variance components of the image refinement: the secant step reaches the fixed point of a
contraction, and the refinement's noise estimates are at their fixed point, where the plain
alternation of full passes ends up."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import multieye
from multieye.core import geometry as g
from multieye.core.robust_loss import gaussian_scale_constant
from multieye.estimate import variance_components as vc
from multieye.estimate.image_data import ImageProblem, image_data
from multieye.estimate.refine_images import refine_images
from multieye.optimize.levenberg_marquardt import Options, covariance_and_residuals, minimize
from multieye.sim.images import simulate_images

ALL = np.array([True, True, True])


def test_secant_lands_on_the_fixed_point_of_a_log_linear_contraction():
    # log f(s) = a + c log s: fixed point exp(a / (1 - c)), whatever the two sigmas tried
    for c in (0.05, 0.2, 0.6):
        a = np.log([0.3, 2e-3, 4e-4]) * (1.0 - c)
        def f(s, a=a, c=c):
            return np.exp(a + c * np.log(s))

        s1, s2 = np.array([1.0, 1e-2, 1e-3]), np.array([0.5, 5e-3, 6e-4])
        out, extrapolated = vc.secant(s2, f(s2), (s1, f(s1)), ALL)
        assert extrapolated
        np.testing.assert_allclose(out, np.exp(a / (1.0 - c)), rtol=1e-12)


def test_secant_takes_the_plain_estimate_where_the_steps_are_no_contraction():
    s1, s2 = np.array([1.0, 1e-2, 1e-3]), np.array([0.5, 5e-3, 6e-4])
    e1, e2 = np.array([0.5, 8e-3, 2e-4]), np.array([0.6, 7e-3, 6e-4])
    # no previous step: the estimate; slope outside [0, 2/3] (px: 0.26 / -0.69 < 0): the
    # estimate for that component, and "not extrapolated"
    assert np.array_equal(vc.secant(s2, e2, None, ALL)[0], e2)
    out, extrapolated = vc.secant(s2, e2, (s1, e1), ALL)
    assert not extrapolated and out[0] == e2[0]
    # components not estimated stay as used; the motion capture's are floored
    out, _ = vc.secant(s2, e2, (s1, e1), np.array([True, False, False]))
    assert out[0] == e2[0] and np.array_equal(out[1:], s2[1:])
    tiny = vc.secant(np.array([1.0, 1e-12, 1e-12]), np.array([1.0, 1e-13, 1e-13]), None, ALL)[0]
    assert np.all(tiny[1:] >= vc.MOCAP_SIGMA_FLOOR)


def _fixed_point_by_full_passes(sc, X0, Y0, s_px, s_rot, s_t):
    """The plain alternation, every pass to 1e-12 and the estimates (the pooled pixel sigma
    and each image's over it) iterated until they move by less than 1e-6: the fixed point
    the refinement's shortcut must reach."""
    data = image_data(ImageProblem(sc.setup, sc.observations, sc.intrinsics))
    fams = data.families(X0, Y0)
    c_w = gaussian_scale_constant("huber", 2.0)
    s = np.array([s_px, s_rot, s_t])
    free = np.array([True, False, False])
    opts = Options(loss="huber", f_scale=2.0, tol=1e-12, newton_below=1e-6)
    for _ in range(60):
        groups = data.groups(*s)
        fams = minimize(fams, groups, opts).families
        cov, ev = covariance_and_residuals(fams, groups, local=True)
        sums = vc.weighted_sums(groups, ev, "huber", 2.0)
        red = vc.redundancy(data, fams, groups, cov, sums.n_pixels)
        new = np.where(free, vc.estimate(s, sums, red, c_w), s)
        f = vc.image_noise(data, ev, red, sums.n_pixels, "huber", 2.0, c_w)
        f0 = np.ones(len(f)) if data.image_noise is None else data.image_noise
        done = abs(new[0] / s[0] - 1.0) < 1e-6 and np.max(np.abs(f / f0 - 1.0)) < 1e-6
        s, data = new, replace(data, image_noise=f)
        if done:
            break
    groups = data.groups(*s)
    fams = minimize(fams, groups, opts).families
    return s, data.image_noise, {f.name: f.value for f in fams}, \
        covariance_and_residuals(fams, groups)[0]


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_estimated_pixel_noise_is_the_fixed_point_of_full_passes(setup):
    """4 cameras x 12 images, 0.3 px: the refinement's pixel sigma within 0.2 % of the fixed
    point of the plain alternation of converged passes, each image's within 0.5 %, its X and
    Y within 1 % of a standard deviation of that solution's."""
    sc = simulate_images(np.random.default_rng(31), n_cameras=4, images=12, setup=setup)
    sol = multieye.solve(sc.A, sc.B)
    res = refine_images(sc.setup, sc.observations, sc.intrinsics, sol.X, sol.Y)
    assert res.pixel_sigma_estimated and res.converged
    s, f, values, cov = _fixed_point_by_full_passes(sc, sol.X, sol.Y, res.pixel_sigma,
                                                    res.mocap_rot_sigma_rad,
                                                    res.mocap_trans_sigma_m)
    assert abs(res.pixel_sigma / s[0] - 1.0) < 2e-3, (res.pixel_sigma, s[0])
    each = np.concatenate(res.image_sigma_px) / (s[0] * f)          # each image's, too
    assert np.max(np.abs(each - 1.0)) < 5e-3, np.max(np.abs(each - 1.0))
    # X^j then Y, each (rotation vector of R R_hat^T, translation): the covariance's order
    poses = np.concatenate([res.X, res.Y[None]])
    fixed = np.concatenate([values["X"], values["Y"]])
    delta = np.concatenate([np.concatenate([g.rotvec_from_transform(T @ g.inv(F)),
                                            T[:3, 3] - F[:3, 3]]) for T, F in zip(poses, fixed)])
    std = np.sqrt(np.diag(cov.kept))[:delta.size]
    assert np.max(np.abs(delta) / std) < 0.01, np.max(np.abs(delta) / std)
