"""Views a start leaves unprojectable: solved without them, re-posed, brought back.

A start of :func:`multieye.estimate.refine_motion.refine_motion` can put some board points
outside a camera's model (behind it, or beyond a wide lens's valid region) when one view's
PnP pose was far off and alone placed an instant, a board or a camera: a strip of ten
corners of a board 2 m away fits a pose 15 degrees wrong as well as the true one, and the
growth of :mod:`multieye.estimate.motion_links` carries that error on.  Such points have no
residual, and the engine cannot start from them.  Instead:

1. :func:`unprojectable_views`: the views with a point the start does not project;
2. :func:`reposed_start`: the problem without them (the instants, boards and cameras only
   they saw left out too; held boards, or the first board left, held at their starting
   poses so that the world stays the start's), solved by the caller's solve from the same
   start; what those views alone saw placed from their PnP poses and the solved rest (the
   robust mean of every loop, as the growth does); the result is the start of the whole
   problem, those views brought back.

The same re-posing serves a second look after a refinement: a start placed wrongly (a PnP
pose 15 degrees off) can also lead the refinement to a local optimum where a few views lie
far off (:func:`far_off_views`) and the robust loss discounts them; solved without them from
that optimum, re-posed and brought back, the refinement reaches the better optimum, kept when
its robust cost (:func:`robust_cost`) is lower.

When the views are unprojectable even from the solved rest, they disagree with it (a wrong
board name, a wrong instant): :class:`UnprojectableViewsError` names them, for the caller to
leave them out.

Synopsis
--------
>>> bad = unprojectable_views(views, start)                                 # doctest: +SKIP
>>> start = reposed_start(views, T_cam_board, start, bad, solve)            # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.lens import project_points
from multieye.core.robust_loss import rho
from multieye.estimate.covisibility import relative_pose
from multieye.estimate.motion_links import MotionStart
from multieye.estimate.motion_residuals import MotionViews

__all__ = ["UnprojectableViewsError", "unprojectable_views", "reposed_start", "describe_views",
           "far_off_views", "robust_cost", "FAR_OFF_Z2"]

#: A view is far off the solution when the median of its points' squared normalised
#: residuals exceeds chi-square(2)'s quantile at 1 - 1e-4 (the outlier rule of
#: :mod:`multieye.estimate.refine_images`, ``OUTLIER_PROBABILITY``): 18.4.
FAR_OFF_Z2 = 18.42

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


class UnprojectableViewsError(InputError):
    """Views whose board points no camera pose near the rest of the solution projects.

    Attributes
    ----------
    views : tuple of int
        Their indices in the :class:`~multieye.estimate.motion_residuals.MotionViews`.
    """

    def __init__(self, message: str, views: tuple[int, ...]):
        super().__init__(message)
        self.views = tuple(int(v) for v in views)


def describe_views(views: MotionViews, which) -> str:
    """``"cam3 at instants 3, 39"``-like words for the views ``which``, camera by camera."""
    which = np.asarray(which, dtype=np.int64)
    parts = []
    for j in sorted(set(views.camera[which].tolist())):
        inst = sorted(set(views.instant[which][views.camera[which] == j].tolist()))
        parts.append(f"{views.names[j]} at instant{'s' if len(inst) > 1 else ''} "
                     + ", ".join(str(t) for t in inst))
    return "; ".join(parts)


def unprojectable_views(views: MotionViews, start: MotionStart,
                        intrinsics=None) -> I64:
    """The views with a board point the start does not project (NaN: behind the camera or
    outside the lens model's valid region), in view order.

    Parameters
    ----------
    views : MotionViews
    start : MotionStart
        ``T_ref_cam`` (m), ``T_world_board`` (nb), ``T_world_rig`` (K), world = the views'
        gauge.
    intrinsics : sequence of Intrinsics, optional
        Default the views' (the starting lenses).
    """
    intrinsics = views.intrinsics if intrinsics is None else intrinsics
    T_cam_board = (g.inv(start.T_ref_cam[views.camera]) @ g.inv(start.T_world_rig[views.instant])
                   @ start.T_world_board[views.board])
    T = T_cam_board[views.view]
    p = np.einsum("pij,pj->pi", T[:, :3, :3], views.object_points) + T[:, :3, 3]
    finite = np.zeros(len(p), dtype=bool)
    for j in range(views.m):
        mine = views.camera[views.view] == j
        if np.any(mine):
            uv = project_points(p[mine], intrinsics[j])
            finite[mine] = np.all(np.isfinite(uv), axis=1)
    bad = np.zeros(views.n_views, dtype=bool)
    np.logical_or.at(bad, views.view, ~finite)
    return np.flatnonzero(bad)


def _renumber(values: I64, keep: NDArray[np.bool_]) -> tuple[I64, I64]:
    """The values the kept entries hold, in order, and the new number of each old value
    (-1 where none is kept)."""
    kept = np.unique(values[keep])
    new = np.full(int(values.max()) + 1, -1, dtype=np.int64)
    new[kept] = np.arange(kept.size)
    return kept, new


def _sub_problem(views: MotionViews, start: MotionStart, keep: NDArray[np.bool_], lenses: list):
    """The views ``keep`` as a problem of their own, started at ``lenses``: its views,
    start, and the cameras, instants and boards it holds (old indices)."""
    cams = np.unique(views.camera[keep])
    if views.reference not in cams:
        raise UnprojectableViewsError(
            f"the start leaves every view of the reference camera {views.names[views.reference]}"
            " unprojectable", tuple(np.flatnonzero(views.camera == views.reference)))
    insts, new_t = _renumber(views.instant, keep)
    boards, new_b = _renumber(views.board, keep)
    per: dict[str, list] = {views.names[j]: [] for j in cams}
    for v in np.flatnonzero(keep):
        pts = views.view == v
        per[views.names[views.camera[v]]].append(
            (views.object_points[pts], views.image_points[pts], int(new_t[views.instant[v]]),
             int(new_b[views.board[v]])))
    held = {int(new_b[b]): G for b, G in views.held.items() if new_b[b] >= 0} or {
        0: start.T_world_board[boards[0]]}
    sub = MotionViews(per, [lenses[j] for j in cams],
                      int(np.flatnonzero(cams == views.reference)[0]),
                      free_intrinsics=[views.free[j] for j in cams], board_poses=held)
    sub_start = MotionStart(start.T_ref_cam[cams], start.T_world_board[boards],
                            start.T_world_rig[insts], tuple(start.links[j] for j in cams))
    return sub, sub_start, (cams, insts, boards)


def _mean(T: list) -> F64:
    T = np.asarray(T)
    return relative_pose(T, np.tile(np.eye(4), (len(T), 1, 1)))


def _place_rest(views: MotionViews, T: F64, known: tuple[dict, dict, dict]) -> None:
    """Place the cameras, instants and boards ``known`` lacks from the views' PnP poses
    ``T`` and what it holds, round by round (in place); what nothing places stays out."""
    cams, insts, boards = known
    c, t, b = views.camera, views.instant, views.board
    for _ in range(views.n_views):
        placed = False
        for k in range(views.n_instants):
            vs = [v for v in np.flatnonzero(t == k) if c[v] in cams and b[v] in boards]
            if k not in insts and vs:
                insts[k] = _mean([boards[b[v]] @ g.inv(T[v]) @ g.inv(cams[c[v]]) for v in vs])
                placed = True
        for k in range(views.n_boards):
            vs = [v for v in np.flatnonzero(b == k) if c[v] in cams and t[v] in insts]
            if k not in boards and vs:
                boards[k] = _mean([insts[t[v]] @ cams[c[v]] @ T[v] for v in vs])
                placed = True
        for k in range(views.m):
            vs = [v for v in np.flatnonzero(c == k) if t[v] in insts and b[v] in boards]
            if k not in cams and vs:
                cams[k] = _mean([g.inv(insts[t[v]]) @ boards[b[v]] @ g.inv(T[v]) for v in vs])
                placed = True
        if not placed:
            return


def reposed_start(views: MotionViews, T_cam_board, start: MotionStart, bad,
                  solve: Callable, intrinsics=None) -> tuple[MotionStart, tuple]:
    """The start of the whole problem from the problem without the views ``bad`` (module
    docstring).

    Parameters
    ----------
    views : MotionViews
    T_cam_board : array_like, shape (n_views, 4, 4)
        PnP poses of the views.
    start : MotionStart
        The start that leaves ``bad`` unprojectable.
    bad : array_like of int
        Those views.
    solve : callable
        ``solve(sub_views, sub_T_cam_board, sub_start) -> MotionResult`` (on the pixels
        alone: the start of a motion-capture problem comes from the views too, and the
        motion capture's own start from the rig's poses this gives).
    intrinsics : sequence of Intrinsics, optional
        The lenses to start from (default the views').

    Returns
    -------
    start : MotionStart
        Every pose, the views ``bad`` brought back (links and single-axis cameras as
        ``start``'s).
    intrinsics : tuple of Intrinsics
        The lenses solved without them (the estimated ones' start for the whole problem).
    """
    T = np.asarray(T_cam_board, dtype=np.float64)
    keep = np.ones(views.n_views, dtype=bool)
    keep[np.asarray(bad, dtype=np.int64)] = False
    lenses = list(views.intrinsics if intrinsics is None else intrinsics)
    sub, sub_start, (cams, insts, boards) = _sub_problem(views, start, keep, lenses)
    res = solve(sub, T[keep], sub_start)
    known = ({int(j): res.T_ref_cam[k] for k, j in enumerate(cams)},
             {int(t): res.T_world_rig[k] for k, t in enumerate(insts)},
             {int(b): res.T_world_board[k] for k, b in enumerate(boards)})
    _place_rest(views, T, known)
    for k, j in enumerate(cams):
        lenses[j] = res.intrinsics[k]

    def pick(have: dict, old: F64) -> F64:
        return np.stack([have.get(i, old[i]) for i in range(len(old))])

    return (MotionStart(pick(known[0], start.T_ref_cam), pick(known[2], start.T_world_board),
                        pick(known[1], start.T_world_rig), start.links, start.single_axis),
            tuple(lenses))


def far_off_views(views: MotionViews, residuals_px: F64, sigma: float) -> I64:
    """The views whose points' median squared normalised residual exceeds
    :data:`FAR_OFF_Z2` (residuals ``(P, 2)`` in point order, pixels; ``sigma`` pixels)."""
    z2 = np.sum((np.asarray(residuals_px) / sigma) ** 2, axis=1)
    return np.array([v for v in range(views.n_views)
                     if np.median(z2[views.view == v]) > FAR_OFF_Z2], dtype=np.int64)


def robust_cost(residuals_px: F64, sigma: float, loss: str, f_scale: float) -> float:
    """The pixels' robust cost ``sum rho((r / sigma / f_scale)^2)`` over every coordinate."""
    z = np.asarray(residuals_px).ravel() / sigma / f_scale
    return float(np.sum(rho(z ** 2, loss)[0]))
