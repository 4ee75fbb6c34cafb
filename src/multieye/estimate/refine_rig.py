"""Maximum likelihood of a rig linked by co-observations: ``T_ref_cam``, lenses, target poses.

Without motion capture, what ties cameras together is the target seen by several of them at
one instant (docs/rig-yaml.md, section 2).  This module minimises the pixels' negative
log-likelihood::

    min  sum_points rho(||pi_j(inv(T_ref_cam^j) T_ref_target(t) p_k) - u||^2 / sigma_px^2)

over every ``T_ref_cam^j`` (the reference camera fixed at the identity), every instant's
``T_ref_target(t)`` and the estimated lenses (residuals and Jacobians:
:mod:`multieye.estimate.rig_residuals`), started from the co-visibility graph
(:func:`multieye.estimate.covisibility.initial_rig`, strongest links first), on the engine:
Levenberg-Marquardt with the target poses eliminated by the Schur complement.

Covariance of ``T_ref_cam`` and the lenses: ``kappa sigma^2 (J^T J)^-1`` of the reduced
system (the target poses marginalised), ``kappa`` the efficiency factor of the robust loss
for Gaussian residuals.  When the pixel noise is not given it is estimated as
``sigma^2 = sum(w r^2) / (c_w (n - p))`` (``w`` the loss's IRLS weights, ``c_w`` their
expectation for Gaussian residuals, ``n - p`` the redundancy), re-solving until it settles.
As any linearised covariance it covers the pixel noise only (not a wrong lens model or a
board that is not flat).

Synopsis
--------
>>> views = RigViews(views_by_name, intrinsics, free_intrinsics=free)      # doctest: +SKIP
>>> res = refine_rig(views, T_cam_target)                                    # doctest: +SKIP
>>> res.T_ref_cam, res.covariance                                            # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.robust_loss import gaussian_kappa, gaussian_scale_constant, rho
from multieye.estimate.covisibility import Covisibility, RigStart, covisibility, initial_rig
from multieye.estimate.image_residuals import intrinsics_family
from multieye.estimate.rig_residuals import RigViews
from multieye.optimize.levenberg_marquardt import (NEAR_DAMPING, Options, covariance, evaluate,
                                                   minimize)
from multieye.optimize.threads import threads_for

__all__ = ["RigResult", "refine_rig"]

F64 = NDArray[np.float64]

_MAX_SIGMA_PASSES = 4
#: Relative change of the pixel noise at which its estimate counts as settled.
_SETTLED = 0.02
#: Stopping tolerance of the passes after the first (relative decrease of the cost).
_LATER_TOL = 1e-7
#: Relative decrease of the cost below which the first pass steps on the robust cost's own
#: curvature (:class:`~multieye.optimize.levenberg_marquardt.Options`).
_NEWTON_BELOW = 1e-5


@dataclass(frozen=True)
class RigResult:
    """What :func:`refine_rig` reached.

    Attributes
    ----------
    T_ref_cam : ndarray, shape (m, 4, 4)
    T_ref_target : ndarray, shape (K, 4, 4)
        The target at each instant, in ``ref``.
    intrinsics : tuple of Intrinsics
        Every camera's lens (the estimated ones at the optimum).
    covariance : ndarray, shape (m, 6, 6)
        Of each ``T_ref_cam``: rotation vector then translation, left perturbation in ``ref``,
        radians and metres (zeros for the reference camera).
    intrinsics_covariance : tuple of (ndarray or None)
        Per camera, over ``fx fy cx cy`` then the distortion (None for a fixed lens).
    joint_covariance : ndarray, shape (k, k)
        Over every kept unknown (``C`` then each ``K:<camera>``, the engine's layout).
    pixel_sigma : float
        The pixel noise used (estimated when not given), pixels.
    residuals_px : ndarray, shape (P, 2)
        Pixel residuals of every point at the optimum (point order of the views).
    camera_rms_px : ndarray, shape (m,)
    start : RigStart
    covisibility : Covisibility
    iterations : int
    converged : bool
    undetermined : tuple of str
        Families (``C``, ``K:<camera>``) with a direction the data do not determine (their
        covariance then covers the other directions only).
    """

    T_ref_cam: F64
    T_ref_target: F64
    intrinsics: tuple[Intrinsics, ...]
    covariance: F64
    intrinsics_covariance: tuple
    joint_covariance: F64
    pixel_sigma: float
    residuals_px: F64
    camera_rms_px: F64
    start: RigStart
    covisibility: Covisibility
    iterations: int
    converged: bool
    undetermined: tuple[str, ...] = ()


def _settled_scale(e: F64, sigma: float, loss: str, f_scale: float, denominator: float) -> float:
    """The pixel noise ``s = sqrt(sum(w(e / s) (e / s)^2) s^2 / denominator)`` on fixed
    residuals ``e`` (pixels), iterated from ``sigma`` to its fixed point.

    One step of it from the scale a pass was solved with is the estimate of the module
    docstring; its fixed point on the same residuals is where the passes end up, since the
    optimum hardly moves when only the loss's scale changes.  Taking it at once saves a
    re-solve (on ``benchmarks/bench_overlap.py``: two passes instead of three).
    """
    s = sigma
    for _ in range(50):
        z = e / s
        w = rho((z / f_scale) ** 2, loss)[1]
        new = s * float(np.sqrt(float(w @ z ** 2) / denominator))
        done = abs(new - s) <= 1e-4 * s
        s = max(new, 1e-12)
        if done or loss == "linear":
            break
    return s


def refine_rig(views: RigViews, T_cam_target, *, pixel_sigma: float | None = None,
               loss: str = "huber", f_scale: float = 2.0, max_iter: int = 100) -> RigResult:
    """Refine the rig on the pixels from PnP starting poses (module docstring).

    Parameters
    ----------
    views : RigViews
    T_cam_target : array_like, shape (n_views, 4, 4)
        Starting pose of the target in the camera of each view (PnP with the starting lens).
    pixel_sigma : float, optional
        Pixel noise; estimated when not given.
    loss : str
        Robust loss on every pixel residual (scipy's names).
    f_scale : float
        Where the loss departs from least squares, in sigmas.
    max_iter : int

    Raises
    ------
    InputError
        Cameras that share no instant (one line naming the groups), or a refinement that
        leaves the lens models' valid range.
    """
    # the BLAS threads of the reduced system's size for the whole refinement, not only in
    # the solves: the residuals' and Jacobians' products and the covariance use BLAS too,
    # and on a small problem OpenBLAS's threads cost more than they give (optimize/threads.py;
    # on benchmarks/bench_overlap.py 0.1 CPU-s of 0.4)
    k = 6 * (views.m - 1) + sum(views.intrinsics[j].params.size
                                for j in range(views.m) if views.free[j])
    with threads_for(k):
        return _refine_rig(views, T_cam_target, pixel_sigma, loss, f_scale, max_iter)


def _refine_rig(views: RigViews, T_cam_target, pixel_sigma: float | None, loss: str,
                f_scale: float, max_iter: int) -> RigResult:
    """:func:`refine_rig` within its BLAS thread limit."""
    T = np.asarray(T_cam_target, dtype=np.float64).reshape(-1, 4, 4)
    if len(T) != views.n_views:
        raise InputError(f"{len(T)} starting poses for {views.n_views} views")
    start = initial_rig(T, views.camera, views.instant, views.m, views.reference, views.names)
    fams = views.families(start.T_ref_cam, start.T_ref_target)
    sigma = 1.0 if pixel_sigma is None else float(pixel_sigma)
    if not (np.isfinite(sigma) and sigma > 0):
        raise InputError(f"pixel_sigma must be a positive number, got {pixel_sigma!r}")
    # the robust cost's own curvature near the optimum (IRLS converges only linearly there),
    # and from the start of the passes after the first, which start at its optimum with a
    # damping that does not shorten the lenses' ill-determined directions
    # (NEAR_DAMPING): on benchmarks/bench_overlap.py's seed 0, 6 + 5 iterations became 6 + 3
    opts = Options(loss=loss, f_scale=f_scale, max_iter=max_iter, newton_below=_NEWTON_BELOW)
    later = replace(opts, tol=_LATER_TOL, newton_below=np.inf, initial_damping=NEAR_DAMPING)
    c_w = gaussian_scale_constant(loss, f_scale)
    iterations, converged = 0, True
    for k in range(_MAX_SIGMA_PASSES):
        groups = views.groups(sigma)
        # after the first pass only the loss's scale moved: a looser stop is enough
        res = minimize(fams, groups, opts if k == 0 else later)
        fams, iterations, converged = res.families, iterations + res.iterations, res.converged
        if pixel_sigma is not None:
            break
        z = np.concatenate([e[0].ravel() for e in evaluate(fams, groups, False)])
        n_params = sum(f.count * f.size for f in fams)
        new = _settled_scale(z * sigma, sigma, loss, f_scale, c_w * max(z.size - n_params, 1))
        # settled; or every residual within the loss's quadratic zone at both scales (the
        # optimum is then the least-squares one, whatever the scale)
        quadratic = (loss == "linear"
                     or float(np.abs(z).max()) <= f_scale * min(1.0, new / sigma))
        settled = abs(new - sigma) <= _SETTLED * sigma or quadratic
        sigma = max(float(new), 1e-6)
        if settled:
            break
    groups = views.groups(sigma)
    ev = evaluate(fams, groups, True)
    cov = covariance(fams, groups, evaluated=ev)
    kept = cov.kept * gaussian_kappa(loss, f_scale)
    values = {f.name: f.value for f in fams}
    T_ref_cam = views.T_ref_cam(values)
    cam_cov = np.zeros((views.m, 6, 6))
    if views.m > 1:
        o = cov.layout.offset["C"]
        for b, j in enumerate(views.others):
            s = o + 6 * b
            cam_cov[j] = kept[s:s + 6, s:s + 6]
    k_cov = []
    for j, name in enumerate(views.names):
        fam = intrinsics_family(name)
        if views.free[j]:
            o, n = cov.layout.offset[fam], views.intrinsics[j].params.size
            k_cov.append(kept[o:o + n, o:o + n])
        else:
            k_cov.append(None)
    resid = np.concatenate([e[0] for e in ev]) * sigma     # groups camera by camera, as points
    cam_of_point = views.camera[views.view]
    rms = np.array([float(np.sqrt(np.mean(np.sum(resid[cam_of_point == j] ** 2, axis=1))))
                    if views.counts[j] else float("nan") for j in range(views.m)])
    return RigResult(T_ref_cam=T_ref_cam, T_ref_target=values["S"],
                     intrinsics=views.current_intrinsics(values), covariance=cam_cov,
                     intrinsics_covariance=tuple(k_cov), joint_covariance=kept,
                     pixel_sigma=float(sigma), residuals_px=resid, camera_rms_px=rms,
                     start=start, covisibility=covisibility(views.camera, views.instant,
                                                            views.m),
                     iterations=iterations, converged=converged,
                     undetermined=tuple(f.name for f in fams if not f.eliminate
                                        and cov.undetermined_in(f.name, f.count, f.size)))
