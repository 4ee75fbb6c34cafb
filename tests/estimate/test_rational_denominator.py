"""The rational lens model's numerator and denominator nearly share a factor over an image's
field of view (issue 32: hd-jpeg rigs' joint lenses at k1 -117, k2 3386 ..., the principal
point's standard deviation 0.01-0.07 px where 0.15 held elsewhere): its start leaves the
denominator at 1 and the joint refinement draws it there (DenominatorPrior)."""

from __future__ import annotations

import numpy as np

from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.estimate.image_residuals import (
    RATIONAL_DENOMINATOR,
    intrinsics_family,
    rational_edge,
)
from multieye.estimate.refine_images import refine_images
from multieye.imaging.calibrate import initial_intrinsics
from multieye.sim.images import simulate_images

#: k3 = k6 = 0: multiplying numerator and denominator by (1 + a r^2) gives the same lens for
#: every a (k1 + a, k2 + a k1, a k2 over k4 + a, k5 + a k4, a k5): an exactly flat family.
FLAT = Intrinsics(K=[[814.0, 0, 646.7], [0, 813.0, 367.7], [0, 0, 1]],
                  dist=[-0.295, 0.078, -8e-4, -6e-4, 0.0, 0.027, -0.0099, 0.0],
                  width=1280, height=720)


def _along_the_family(intr: Intrinsics, a: float) -> Intrinsics:
    k1, k2, p1, p2, _, k4, k5, _ = intr.dist
    return Intrinsics(K=intr.K, dist=[k1 + a, k2 + a * k1, p1, p2, a * k2, k4 + a,
                                      k5 + a * k4, a * k5], width=intr.width, height=intr.height)


def _denominator_terms(intr: Intrinsics) -> np.ndarray:
    x = rational_edge(intr)
    return intr.params[list(RATIONAL_DENOMINATOR)] * x ** np.arange(1, 4)


def test_joint_refinement_leaves_the_shared_factor():
    """Started 30 along the exactly flat family, the refinement returns to a denominator
    near 1 and reports every direction determined (before: it stayed at k1 = 29.7 with
    the intrinsics flagged as not determined)."""
    sc = simulate_images(2, n_cameras=2, images=15, pixel_sigma=0.05,
                         intrinsics=[FLAT, simulate_images(0).intrinsics[0]])
    start = [_along_the_family(FLAT, 30.0), sc.intrinsics[1]]
    rays = np.column_stack([np.tan(np.radians(np.random.default_rng(0).uniform(
        [-35, -20], [35, 20], size=(200, 2)))), np.ones(200)])
    assert np.abs(project_points(rays, start[0]) - project_points(rays, FLAT)).max() < 1e-9
    res = refine_images(sc.setup, sc.observations, start, sc.X, sc.Y, pixel_sigma=0.05,
                        loss="linear", free_intrinsics=[True, False])
    assert np.all(np.abs(_denominator_terms(res.intrinsics[0])) < 2.0)      # 36 at the start
    assert intrinsics_family("cam0") not in res.undetermined
    e = res.intrinsics[0].params[:4] - FLAT.params[:4]            # fx fy cx cy, pixels
    nees = e @ np.linalg.solve(res.intrinsics_covariance[0][:4, :4], e)
    assert nees < 18.5                                           # chi2(4), 99.9 %


def test_the_lens_start_does_not_land_on_the_shared_factor():
    """OpenCV's 8-coefficient calibration of these views lands far along the family
    (denominator terms of tens at the image's edge); the start is OpenCV's 5 coefficients
    with the denominator at 1, as close to the views."""
    true = Intrinsics(K=FLAT.K, dist=[-0.295, 0.078, -8e-4, -6e-4, 0.01, 0.027, -0.0099,
                                      0.0049], width=1280, height=720)
    sc = simulate_images(4, n_cameras=1, images=40, pixel_sigma=0.05, intrinsics=[true])
    views = [(o, u) for o, u, _ in sc.observations[0]]
    start = initial_intrinsics(views, (1280, 720), "pinhole-rational")
    assert np.all(_denominator_terms(start.intrinsics) == 0.0)
    assert start.rms_px < 0.08          # 0.05 px per coordinate: 0.071 for the true lens
