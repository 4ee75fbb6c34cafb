"""Maximum likelihood of a rig linked by its motion in front of still boards (issue 34).

Minimises the pixels' negative log-likelihood::

    min  sum_points rho(||pi_j(inv(T_ref_cam^j) S(t) T_world_board^b p_k) - u||^2 / sigma_px^2)

over every ``T_ref_cam^j`` (the reference camera's the identity), every board pose
``T_world_board^b`` (board 0 is the world), the world in the rig at every instant
``S(t) = inv(T_world_rig(t))`` and the estimated lenses (residuals and Jacobians:
:mod:`multieye.estimate.motion_residuals`), from the start of
:func:`multieye.estimate.motion_links.motion_start`, on the engine (Levenberg-Marquardt,
the instants' poses eliminated by the Schur complement; views the start leaves unprojectable
solved without first and brought back, and a local optimum with views far off looked at
again: :mod:`multieye.estimate.motion_repose`).  Overlap (two cameras seeing one
board at one instant) and motion links are the same residuals here: one problem.

Covariance of ``T_ref_cam``, the boards and the lenses: ``kappa sigma^2 (J^T J)^-1`` of the
reduced system, ``kappa`` the robust loss's efficiency for Gaussian residuals.  When the
pixel noise is not given it is estimated as ``sigma^2 = sum(w r^2) / (c_w (n - p))`` (``w``
the loss's IRLS weights, ``c_w`` their expectation for Gaussian residuals, ``n - p`` the
redundancy), re-solving until it settles.  As any linearised covariance it covers the pixel
noise only (not a wrong lens model or a board that is not flat).  What the data leave
undetermined (planar motion) is found from this covariance by
:mod:`multieye.estimate.observability`.  With one board this is the rig linked by
co-observations alone (:func:`multieye.estimate.refine_rig.refine_rig`).

Synopsis
--------
>>> views = MotionViews(views_by_name, intrinsics, free_intrinsics=free)     # doctest: +SKIP
>>> res = refine_motion(views, T_cam_board)                                   # doctest: +SKIP
>>> res.T_ref_cam, res.covariance, res.T_world_board                          # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.errors import CalibrationError, InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.robust_loss import gaussian_kappa, gaussian_scale_constant, rho
from multieye.estimate.image_residuals import intrinsics_family
from multieye.estimate.motion_links import MotionStart, motion_start
from multieye.estimate.motion_mocap import MocapPoseResiduals, RigMocap, mocap_families
from multieye.estimate.motion_repose import (UnprojectableViewsError, describe_views,
                                             far_off_views, reposed_start, robust_cost,
                                             unprojectable_views)
from multieye.estimate.motion_residuals import MotionViews
from multieye.optimize.levenberg_marquardt import (NEAR_DAMPING, Options, covariance, evaluate,
                                                   minimize)
from multieye.optimize.threads import threads_for

__all__ = ["MotionResult", "refine_motion"]

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
class MotionResult:
    """What :func:`refine_motion` reached.

    Attributes
    ----------
    T_ref_cam : ndarray, shape (m, 4, 4)
    T_world_board : ndarray, shape (nb, 4, 4)
        World = board 0 (its pose the identity), or the frame of the boards held at given
        poses (:class:`~multieye.estimate.motion_residuals.MotionViews`' ``board_poses``).
    T_world_rig : ndarray, shape (K, 4, 4)
        The rig (reference camera) at every instant.
    intrinsics : tuple of Intrinsics
    covariance : ndarray, shape (m, 6, 6)
        Of each ``T_ref_cam``: rotation vector then translation, left perturbation in the
        rig's frame, radians and metres (zeros for the reference camera).
    board_covariance : ndarray, shape (nb, 6, 6)
        Of each ``T_world_board``, left perturbation in the world (zeros for the boards held:
        board 0, or those at given poses).
    intrinsics_covariance : tuple of (ndarray or None)
    joint_covariance : ndarray, shape (k, k)
        Over ``C`` (m - 1 cameras), ``W`` (the boards estimated), each ``K:<camera>``.
    offsets : dict of str to int
        Where each family starts in ``joint_covariance``.
    pixel_sigma : float
    residuals_px : ndarray, shape (P, 2)
    camera_rms_px : ndarray, shape (m,)
    start : MotionStart
    iterations : int
    converged : bool
    undetermined : tuple of str
        Families with a direction the data do not determine at all (numerically singular).
    null_space : ndarray, shape (m, 6, r)
        Per camera its part of those directions (zeros for the reference camera; r = 0 in a
        regular problem), for :func:`multieye.estimate.observability.observability`.
    T_mocap_world, T_rig_marker : ndarray, shape (4, 4), or None
        With motion capture: its frame's pose in the world, the marker's in the rig.
    reposed : tuple of int
        The views the start left unprojectable, solved without first, then brought back
        (:mod:`multieye.estimate.motion_repose`); empty when the start projected them all.
    second_look : tuple of int
        The views a first refinement left far off, solved without, re-posed and brought
        back, when that reached a lower robust cost (a local optimum left); else empty.
    """

    T_ref_cam: F64
    T_world_board: F64
    T_world_rig: F64
    intrinsics: tuple[Intrinsics, ...]
    covariance: F64
    board_covariance: F64
    intrinsics_covariance: tuple
    joint_covariance: F64
    offsets: dict
    pixel_sigma: float
    residuals_px: F64
    camera_rms_px: F64
    start: MotionStart
    iterations: int
    converged: bool
    undetermined: tuple[str, ...] = ()
    null_space: F64 | None = None
    T_mocap_world: F64 | None = None
    T_rig_marker: F64 | None = None
    reposed: tuple[int, ...] = ()
    second_look: tuple[int, ...] = ()

    @property
    def T_ref_target(self) -> F64:
        """The first board (the world) in the rig at every instant, (K, 4, 4): with one
        board, :class:`~multieye.estimate.refine_rig.RigResult`'s target poses."""
        return g.inv(self.T_world_rig)


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


def refine_motion(views: MotionViews, T_cam_board, *, pixel_sigma: float | None = None,
                  loss: str = "huber", f_scale: float = 2.0, max_iter: int = 100,
                  start: MotionStart | None = None, mocap: RigMocap | None = None
                  ) -> MotionResult:
    """Refine the rig, the boards and the lenses on the pixels (module docstring).

    Parameters
    ----------
    views : MotionViews
    T_cam_board : array_like, shape (n_views, 4, 4)
        PnP pose of the board in the camera of each view (for the start).
    pixel_sigma : float, optional
        Pixel noise; estimated when not given.
    loss : str
    f_scale : float
    max_iter : int
    start : MotionStart, optional
        Instead of :func:`~multieye.estimate.motion_links.motion_start` on ``T_cam_board``.
    mocap : RigMocap, optional
        The rig's motion capture, in the same problem
        (:mod:`multieye.estimate.motion_mocap`; the pixel noise is estimated from the pixels
        alone, the motion capture's is taken as given).

    Raises
    ------
    DisconnectedError
        Cameras nothing links (:func:`~multieye.estimate.motion_links.motion_start`).
    InputError
        Malformed input, or a refinement that leaves the lens models' valid range.
    UnprojectableViewsError
        Views whose board points stay unprojectable (behind the camera) from the rest of
        the problem solved without them (:mod:`multieye.estimate.motion_repose`; ``views``
        names them).
    """
    T = np.asarray(T_cam_board, dtype=np.float64).reshape(-1, 4, 4)
    if len(T) != views.n_views:
        raise InputError(f"{len(T)} starting poses for {views.n_views} views")
    sigma = 1.0 if pixel_sigma is None else float(pixel_sigma)
    if not (np.isfinite(sigma) and sigma > 0):
        raise InputError(f"pixel_sigma must be a positive number, got {pixel_sigma!r}")
    if start is None:
        start = motion_start(views, T)
    settings = (loss, f_scale, max_iter)
    return _second_look(views, T, _refined(views, T, start, pixel_sigma, settings, mocap),
                        pixel_sigma, settings, mocap)


def _refined(views: MotionViews, T: F64, start: MotionStart, given: float | None,
             settings: tuple, mocap: RigMocap | None, lenses=None) -> MotionResult:
    """One refinement from ``start`` (and the estimated lenses from ``lenses``, default the
    views'), made projectable first (:func:`_projectable_start`)."""
    start, lenses, reposed = _projectable_start(views, T, start, given, settings, lenses)
    sigma = 1.0 if given is None else float(given)
    # the BLAS threads of the reduced system's size for the whole refinement, not only in
    # the solves: the residuals' and Jacobians' products and the covariance use BLAS too,
    # and on a small problem OpenBLAS's threads cost more than they give (optimize/threads.py;
    # on benchmarks/bench_overlap.py 0.1 CPU-s of 0.4)
    k = 6 * (views.m - 1 + len(views.free_boards)) + sum(
        views.intrinsics[j].params.size for j in range(views.m) if views.free[j])
    with threads_for(k):
        fams, sigma, iterations, converged = _solve(views, start, given, sigma, settings, mocap,
                                                    lenses)
        res = _result(views, start, fams, sigma, settings[:2], iterations, converged, mocap)
    return replace(res, reposed=reposed)


def _second_look(views: MotionViews, T: F64, res: MotionResult, given: float | None,
                 settings: tuple, mocap: RigMocap | None) -> MotionResult:
    """``res``, or the refinement again from it without its far-off views, re-posed and
    brought back (:mod:`multieye.estimate.motion_repose`), when that reaches a lower robust
    cost (a local optimum left: the start placed wrongly by a PnP pose far off)."""
    far = far_off_views(views, res.residuals_px, res.pixel_sigma)
    if not far.size or far.size == views.n_views:
        return res
    loss, f_scale, _ = settings
    first = MotionStart(res.T_ref_cam, res.T_world_board, res.T_world_rig, res.start.links,
                        res.start.single_axis)

    def solve(sub, sub_T, sub_start):
        return _refined(sub, sub_T, sub_start, given, settings, None)

    try:
        start, lenses = reposed_start(views, T, first, far, solve, res.intrinsics)
        other = _refined(views, T, start, given, settings, mocap, lenses)
    except CalibrationError:
        return res
    s = min(res.pixel_sigma, other.pixel_sigma)
    before = robust_cost(res.residuals_px, s, loss, f_scale)
    # lower by more than rounding (the same optimum reached again: a real outlier kept)
    if robust_cost(other.residuals_px, s, loss, f_scale) >= before - max(1.0, 1e-3 * before):
        return res
    return replace(other, start=res.start, reposed=res.reposed,
                   second_look=tuple(int(v) for v in far))


def _projectable_start(views: MotionViews, T: F64, start: MotionStart, given: float | None,
                       settings: tuple, lenses=None):
    """``start`` when it projects every view's points, else the start
    :func:`~multieye.estimate.motion_repose.reposed_start` gives from the problem without
    the views it does not (:mod:`multieye.estimate.motion_repose`); with the lenses to start
    from (None: the views') and those views' indices.

    Raises
    ------
    UnprojectableViewsError
        Views unprojectable from the rest of the problem solved without them.
    """
    bad = unprojectable_views(views, start, lenses)
    if not bad.size:
        return start, lenses, ()

    def solve(sub, sub_T, sub_start):
        return _refined(sub, sub_T, sub_start, given, settings, None)

    start, lenses = reposed_start(views, T, start, bad, solve, lenses)
    still = unprojectable_views(views, start, lenses)
    if still.size:
        raise UnprojectableViewsError(
            f"views of {describe_views(views, still)} put board points behind the camera (or "
            "outside its lens model) wherever the other views place the rig, the boards and "
            "the cameras: they disagree with the rest (a wrong board, a wrong instant)",
            tuple(still.tolist()))
    return start, lenses, tuple(int(v) for v in bad)


def _groups(views: MotionViews, sigma: float, mocap: RigMocap | None) -> list:
    return views.groups(sigma) + ([] if mocap is None else [MocapPoseResiduals(mocap)])


def _solve(views: MotionViews, start: MotionStart, given: float | None, sigma: float,
           settings: tuple, mocap: RigMocap | None, lenses=None):
    """The passes of the refinement, the pixel noise re-estimated between them (from the
    pixels alone); the estimated lenses started from ``lenses`` (default the views')."""
    loss, f_scale, max_iter = settings
    fams = views.families(start.T_ref_cam, start.T_world_board, g.inv(start.T_world_rig),
                          lenses)
    if mocap is not None:
        fams = fams[:-1] + mocap_families(mocap, start.T_world_rig) + fams[-1:]
    # the robust cost's own curvature near the optimum (IRLS converges only linearly there),
    # and from the start of the passes after the first, which start at its optimum with a
    # damping that does not shorten the lenses' ill-determined directions
    # (NEAR_DAMPING): on benchmarks/bench_overlap.py's seed 0, 6 + 5 iterations became 6 + 3
    opts = Options(loss=loss, f_scale=f_scale, max_iter=max_iter, newton_below=_NEWTON_BELOW)
    later = replace(opts, tol=_LATER_TOL, newton_below=np.inf, initial_damping=NEAR_DAMPING)
    c_w = gaussian_scale_constant(loss, f_scale)
    iterations, converged = 0, True
    for k in range(_MAX_SIGMA_PASSES):
        groups = _groups(views, sigma, mocap)
        # after the first pass only the loss's scale moved: a looser stop is enough
        res = minimize(fams, groups, opts if k == 0 else later)
        fams, iterations, converged = res.families, iterations + res.iterations, res.converged
        if given is not None:
            break
        pixels = groups[:len(groups) - (mocap is not None)]
        z = np.concatenate([e[0].ravel() for e in evaluate(fams, pixels, False)])
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
    return fams, sigma, iterations, converged


def _blocks(kept: F64, offset: int, count: int, n: int) -> F64:
    return np.stack([kept[offset + n * b:offset + n * (b + 1), offset + n * b:offset + n * (b + 1)]
                     for b in range(count)]) if count else np.zeros((0, n, n))


def _result(views: MotionViews, start: MotionStart, fams, sigma: float, robust: tuple,
            iterations: int, converged: bool, mocap: RigMocap | None) -> MotionResult:
    """The result at the optimum; ``robust`` is ``(loss, f_scale)``."""
    loss, f_scale = robust
    groups = _groups(views, sigma, mocap)
    ev = evaluate(fams, groups, True)
    cov = covariance(fams, groups, evaluated=ev)
    kept = cov.kept * gaussian_kappa(loss, f_scale)
    values = {f.name: f.value for f in fams}
    offsets = dict(cov.layout.offset)
    cam_cov = np.zeros((views.m, 6, 6))
    if views.m > 1:
        cam_cov[views.others] = _blocks(kept, offsets["C"], views.m - 1, 6)
    board_cov = np.zeros((views.n_boards, 6, 6))
    if views.free_boards:
        board_cov[views.free_boards] = _blocks(kept, offsets["W"], len(views.free_boards), 6)
    und = cov.undetermined if cov.undetermined is not None else np.zeros((len(kept), 0))
    null = np.zeros((views.m, 6, und.shape[1]))
    for b, j in enumerate(views.others):
        null[j] = und[offsets["C"] + 6 * b:offsets["C"] + 6 * b + 6]
    k_cov = []
    for j, name in enumerate(views.names):
        if views.free[j]:
            o, n = offsets[intrinsics_family(name)], views.intrinsics[j].params.size
            k_cov.append(kept[o:o + n, o:o + n])
        else:
            k_cov.append(None)
    # residuals back in point order (the groups hold each camera's views in two parts)
    resid = np.zeros((len(views.view), 2))
    for grp, e in zip(groups[:len(groups) - (mocap is not None)], ev):
        mine = np.flatnonzero((views.camera[views.view] == grp.camera)
                              & (views.estimated(views.board[views.view]) == grp.moved))
        resid[mine] = e[0] * sigma
    cam_of_point = views.camera[views.view]
    rms = np.array([float(np.sqrt(np.mean(np.sum(resid[cam_of_point == j] ** 2, axis=1))))
                    if views.counts[j] else float("nan") for j in range(views.m)])
    return MotionResult(
        T_ref_cam=views.T_ref_cam(values), T_world_board=views.T_world_board(values),
        T_world_rig=g.inv(values["S"]), intrinsics=views.current_intrinsics(values),
        covariance=cam_cov, board_covariance=board_cov, intrinsics_covariance=tuple(k_cov),
        joint_covariance=kept, offsets={n: int(o) for n, o in offsets.items()},
        pixel_sigma=float(sigma), residuals_px=resid, camera_rms_px=rms, start=start,
        iterations=iterations, converged=converged, null_space=null,
        T_mocap_world=None if mocap is None else values["Ym"][0],
        T_rig_marker=None if mocap is None else values["Xm"][0],
        undetermined=tuple(f.name for f in fams if not f.eliminate
                           and cov.undetermined_in(f.name, f.count, f.size)))
