"""Maximum likelihood of a rig linked by co-observations: ``T_ref_cam``, lenses, target poses.

Without motion capture, what ties cameras together is the target seen by several of them at
one instant (docs/rig-yaml.md, section 2).  This module minimises the pixels' negative
log-likelihood::

    min  sum_points rho(||pi_j(inv(T_ref_cam^j) T_ref_target(t) p_k) - u||^2 / sigma_px^2)

over every ``T_ref_cam^j`` (the reference camera fixed at the identity), every instant's
``T_ref_target(t)`` and the estimated lenses, started from the co-visibility graph
(:func:`multieye.estimate.covisibility.initial_rig`, strongest links first).  It is the
problem of :func:`multieye.estimate.refine_motion.refine_motion` with one board, the world
(:class:`multieye.estimate.rig_residuals.RigViews`), solved by it from this start: the same
engine, pixel noise estimate, robust loss, stopping rule and covariance
(``kappa sigma^2 (J^T J)^-1`` of the reduced system, the target poses marginalised); this
module states its result in the target's names.

Synopsis
--------
>>> views = RigViews(views_by_name, intrinsics, free_intrinsics=free)      # doctest: +SKIP
>>> res = refine_rig(views, T_cam_target)                                    # doctest: +SKIP
>>> res.T_ref_cam, res.covariance                                            # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.estimate.covisibility import Covisibility, RigStart, covisibility, initial_rig
from multieye.estimate.motion_growth import Link
from multieye.estimate.motion_links import MotionStart
from multieye.estimate.refine_motion import refine_motion
from multieye.estimate.rig_residuals import RigViews

__all__ = ["RigResult", "refine_rig"]

F64 = NDArray[np.float64]


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
    T = np.asarray(T_cam_target, dtype=np.float64).reshape(-1, 4, 4)
    if len(T) != views.n_views:
        raise InputError(f"{len(T)} starting poses for {views.n_views} views")
    start = initial_rig(T, views.camera, views.instant, views.m, views.reference, views.names)
    links = tuple(Link("reference") if p < 0 else Link("overlap", (int(p),))
                  for p in start.parent)
    res = refine_motion(views, T, pixel_sigma=pixel_sigma, loss=loss, f_scale=f_scale,
                        max_iter=max_iter,
                        start=MotionStart(start.T_ref_cam, np.eye(4)[None],
                                          g.inv(start.T_ref_target), links))
    return RigResult(T_ref_cam=res.T_ref_cam, T_ref_target=res.T_ref_target,
                     intrinsics=res.intrinsics, covariance=res.covariance,
                     intrinsics_covariance=res.intrinsics_covariance,
                     joint_covariance=res.joint_covariance, pixel_sigma=res.pixel_sigma,
                     residuals_px=res.residuals_px, camera_rms_px=res.camera_rms_px,
                     start=start, covisibility=covisibility(views.camera, views.instant,
                                                            views.m),
                     iterations=res.iterations, converged=res.converged,
                     undetermined=res.undetermined)
