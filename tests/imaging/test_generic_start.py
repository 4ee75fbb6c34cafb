"""The lens start from a generic model (issue 33): wide lenses of every model recovered, the
fit's Jacobian, PnP on rays beyond 90 degrees, and images rejected on the start lens taken
back when they fit the refined one."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.optimize import least_squares

from multieye.core.lens import project_points
from multieye.imaging.batch import ImageResult
from multieye.imaging.calibrate import accept_on_refined_lens, poses_from_detections
from multieye.imaging.detect import Detection
from multieye.imaging.generic_start import _Problem, fit_lens, generic_start
from multieye.imaging.pnp import estimate_pose
from multieye.imaging.rays import bearings
from multieye.sim.wide_lens import IMAGE_SIDE, board_views, wide_lens

SIZE = (IMAGE_SIDE, IMAGE_SIDE)


def lens_error_px(est, true, views) -> float:
    """RMS pixel distance between where ``est`` and ``true`` put the true rays of every
    observed pixel, after the rotation between the two camera frames that fits best."""
    uv = np.concatenate([u for _, u in views])
    rays = bearings(uv, true)
    want = project_points(rays, true)

    def residual(w):
        d = project_points(rays @ cv2.Rodrigues(w)[0].T, est) - want
        return np.nan_to_num(d, nan=100.0).ravel()

    e = least_squares(residual, np.zeros(3)).fun
    return float(np.sqrt(np.mean(e ** 2) * 2))


# noise-free: the equidistant and eucm fits reach the truth exactly; the unified and
# double-sphere models have a nearly flat valley (xi against f and k1, or alpha), whose far
# end the fit may stop in, a few hundredths of a pixel from the truth (measured 0.01-0.05)
@pytest.mark.parametrize("model, fov, tol_px", [
    ("fisheye", 170.0, 1e-6), ("unified", 190.0, 0.1), ("unified", 220.0, 0.1),
    ("double-sphere", 190.0, 0.1), ("double-sphere", 220.0, 0.1), ("eucm", 190.0, 1e-6),
    ("eucm", 220.0, 1e-6)])
def test_generic_start_recovers_a_wide_lens_without_noise(model, fov, tol_px):
    true = wide_lens(model, fov)
    views, _ = board_views(true, fov, 12, np.random.default_rng(2), noise_px=0.0)
    fit = generic_start(views, SIZE, model)
    assert np.all(np.isfinite(fit.rms_px))          # every view posed, beyond 90 deg too
    assert lens_error_px(fit.intrinsics, true, views) < tol_px
    assert fit.rms_px.max() < 0.02


@pytest.mark.parametrize("model, fov", [("unified", 220.0), ("double-sphere", 190.0),
                                        ("eucm", 220.0)])
def test_generic_start_with_noise_reaches_the_noise_floor(model, fov):
    true = wide_lens(model, fov)
    views, T = board_views(true, fov, 16, np.random.default_rng(5), noise_px=0.2)
    fit = generic_start(views, SIZE, model)
    n = sum(len(o) for o, _ in views)
    cost = float(np.sum(fit.rms_px ** 2 * [len(o) for o, _ in views]))
    # the optimum started from the truth costs no less: the start found the global one
    best = fit_lens(views, true, T, huber_px=None)
    best_cost = float(np.sum(best.rms_px ** 2 * [len(o) for o, _ in views]))
    # (within half the noise variance, a chi-square of 0.5: the unified model's flat valley)
    assert cost <= best_cost + 0.5 * 0.2 ** 2
    # a sum of squares of 2n - (6 views + lens) residuals of 0.2 px noise
    assert 0.8 < cost / (0.04 * (2 * n - 6 * len(views) - 9)) < 1.2
    assert lens_error_px(fit.intrinsics, best.intrinsics, views) < 0.05


def test_the_fits_jacobian_matches_central_differences():
    true = wide_lens("unified", 220.0)
    views, T = board_views(true, 220.0, 3, np.random.default_rng(3), noise_px=0.3)
    prob = _Problem(views, true, T)
    rng = np.random.default_rng(4)
    x = np.concatenate([true.params, rng.normal(0, 1e-2, 6 * len(views))])
    J = prob.jacobian(x)
    for j in range(len(x)):
        h = 1e-6 * max(1.0, abs(x[j]))
        e = np.zeros_like(x)
        e[j] = h
        num = (prob.residual(x + e) - prob.residual(x - e)) / (2 * h)
        assert np.allclose(J[:, j], num, rtol=1e-5, atol=1e-5 * np.abs(num).max() + 1e-7), j


def test_pnp_on_rays_poses_a_board_beyond_90_degrees():
    lens = wide_lens("unified", 220.0)
    views, T = board_views(lens, 220.0, 40, np.random.default_rng(6), noise_px=0.0)
    obj = views[0][0]
    theta = [np.degrees(np.arctan2(np.hypot(*P[:, :2].T), P[:, 2])).max()
             for P in (obj @ Ti[:3, :3].T + Ti[:3, 3] for Ti in T)]
    k = int(np.argmax(theta))
    assert theta[k] > 95.0                            # a board partly behind the lens plane
    det = Detection(np.arange(len(obj)), views[k][1], obj)
    pose = estimate_pose(det, lens)
    assert pose.n_points == len(obj)
    assert np.allclose(pose.T_cam_target, T[k], atol=1e-6)


def _results(views) -> list[ImageResult]:
    return [ImageResult(path=f"{i}.png", pose=None, image_size=SIZE, reason=None,
                        detection=Detection(np.arange(len(o)), u, o))
            for i, (o, u) in enumerate(views)]


def test_images_rejected_on_the_start_lens_are_taken_back_on_the_refined_one():
    true = wide_lens("fisheye", 170.0)
    views, _ = board_views(true, 170.0, 24, np.random.default_rng(7), noise_px=0.2)
    p = true.params.copy()
    p[0] *= 1.03                             # a start 3 % off in focal length, k1 off
    p[1] *= 1.03
    p[4] += 0.03
    start = true.with_params(p)
    posed = poses_from_detections(_results(views), start)
    early = [r for r in posed if r.reason is not None]
    assert early and all(r.reason.startswith("bad fit") for r in early)
    lens, accepted = accept_on_refined_lens(posed, start)
    assert all(r.ok for r in accepted), [r.reason for r in accepted if not r.ok]
    assert max(r.pose.rms_px for r in accepted) < 1.0
    assert lens_error_px(lens, true, views) < lens_error_px(start, true, views) / 5


def test_nothing_changes_when_no_image_was_rejected():
    true = wide_lens("fisheye", 150.0)
    views, _ = board_views(true, 150.0, 6, np.random.default_rng(8), noise_px=0.2)
    posed = poses_from_detections(_results(views), true)
    lens, accepted = accept_on_refined_lens(posed, true)
    assert lens is true and accepted == posed


def test_a_truly_bad_view_stays_rejected():
    true = wide_lens("eucm", 190.0)
    views, _ = board_views(true, 190.0, 12, np.random.default_rng(9), noise_px=0.2)
    o, u = views[3]
    views[3] = (o, u + np.random.default_rng(10).normal(0, 6.0, u.shape))   # 6 px noise
    posed = poses_from_detections(_results(views), true)
    assert posed[3].reason.startswith("bad fit")
    _, accepted = accept_on_refined_lens(posed, true)
    assert accepted[3].reason.startswith("bad fit")
    assert sum(r.ok for r in accepted) == 11
