"""The views of one instant made to agree on a half-turn symmetric board's point order.

Without motion capture, cameras are linked by the board they see at one instant
(:mod:`multieye.estimate.covisibility`): ``T_a_b = T_a_target(t) @ inv(T_b_target(t))``.  A
board that looks the same after the half turn ``H`` about its centre normal
(:mod:`multieye.imaging.order_turn`) may be detected by camera a in one order and by camera
b in the other (b rolled by more than a quarter turn from a, or the board near the diagonal
where the detector's rule, "x towards the image's lower right", changes its mind); then
``T_a_target(t) @ inv(T_b_target(t) @ H)`` is the link, and a link averaged over instants
of both kinds is wrong.  :func:`choose_turns` decides per view whether to take its other
order, in three steps:

1. along the strongest-first spanning tree of the co-visibility graph, each camera's link to
   its parent is the relative pose that most shared instants agree with, each instant taking
   ``T_p @ inv(T_j)`` or ``T_p @ H @ inv(T_j)`` (the two differ by a half turn, so they never
   agree with the same link): a consensus over the instants, then the robust mean of
   :func:`multieye.estimate.covisibility.relative_pose` over the agreeing ones;
2. with every camera placed (``T_ref_cam``), each instant's views are stated in ``ref`` and
   the orders chosen that agree best with one of them (each view tried as the anchor);
3. turning every view of an instant changes only that instant's board pose (a gauge): the
   choice that turns fewer views is kept.

Synopsis
--------
>>> turn = choose_turns(T, camera, instant, H, m=2, reference=0)    # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.estimate.covisibility import covisibility, link_groups, relative_pose, spanning_tree

__all__ = ["choose_turns", "AGREE_DEG"]

F64 = NDArray[np.float64]

#: Two estimates of one link agree when their rotations are within this angle, degrees (the
#: two orders' links are 180 degrees apart; PnP's rotation errors are a few degrees at most).
AGREE_DEG = 20.0


def _angles(R: F64, S: F64) -> F64:
    """Rotation angles between every R (n, 3, 3) and every S (k, 3, 3), shape (n, k)."""
    return g.rotation_angle(np.swapaxes(R, 1, 2)[:, None] @ S[None])


def _edge_turns(Tp: F64, Tj: F64, H: F64, can: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Per shared instant of a parent and a child camera: is the child's view to be taken in
    the other order relative to the parent's?  ``H`` (n, 4, 4): the child's views' half
    turns (NaN where ``can`` is False)."""
    n = len(Tp)
    first = Tp @ g.inv(Tj)
    other = first.copy()
    other[can] = Tp[can] @ H[can] @ g.inv(Tj[can])
    cand = np.concatenate([first, other[can]])
    R = cand[:, :3, :3]
    near = _angles(R, R) <= np.radians(AGREE_DEG)                    # (c, c)
    owner = np.concatenate([np.arange(n), np.flatnonzero(can)])       # instant of each
    support = [len(np.unique(owner[near[c]])) for c in range(len(cand))]
    # the candidate most instants agree with; ties: the detected orders (listed first)
    best = int(np.argmax(support))
    Rb = cand[best, :3, :3][None]
    a0 = _angles(first[:, :3, :3], Rb)[:, 0]
    a1 = np.full(n, np.inf)
    a1[can] = _angles(other[can, :3, :3], Rb)[:, 0]
    return a1 < a0


def _place(T: F64, H: F64, can, view: NDArray[np.int64], parent, reference: int) -> F64:
    """``T_ref_cam`` of every camera, each from its tree parent over the instants they share,
    the child's views in the order that agrees (:func:`_edge_turns`)."""
    m = view.shape[1]
    T_ref_cam = np.tile(np.eye(4), (m, 1, 1))
    placed = np.zeros(m, dtype=bool)
    placed[reference] = True
    while not placed.all():
        progress = False
        for j in np.flatnonzero(~placed):
            p = parent[j]
            if p < 0 or not placed[p]:
                continue
            both = (view[:, p] >= 0) & (view[:, j] >= 0)
            vp, vj = view[both, p], view[both, j]
            ok = can[vp] & can[vj]
            flip = _edge_turns(T[vp], T[vj], H[vj], ok)
            Tj = T[vj].copy()
            Tj[flip] = Tj[flip] @ H[vj[flip]]
            T_ref_cam[j] = T_ref_cam[p] @ relative_pose(T[vp], Tj)
            placed[j] = progress = True
        if not progress:
            break
    return T_ref_cam


def _instant_turns(P: F64, H: F64) -> NDArray[np.bool_]:
    """The views of one instant (their boards in ``ref``, (k, 4, 4), each turnable by its
    ``H``): which to turn so that all agree, the fewest (step 2 and 3)."""
    k = len(P)
    turned = P @ H
    best, best_cost = np.zeros(k, dtype=bool), np.inf
    for a in range(k):
        ra = P[a, :3, :3][None]
        a0 = _angles(P[:, :3, :3], ra)[:, 0]
        a1 = _angles(turned[:, :3, :3], ra)[:, 0]
        choice = a1 < a0
        choice[a] = False
        cost = float(np.minimum(a0, a1).sum())
        if cost < best_cost - 1e-9:
            best, best_cost = choice, cost
    if 2 * best.sum() > k:
        best = ~best
    return best


def choose_turns(T_cam_target, camera, instant, H, m: int, reference: int = 0
                 ) -> NDArray[np.bool_]:
    """Which views to take in their board's other order (module docstring).

    Parameters
    ----------
    T_cam_target : array_like, shape (n, 4, 4)
        PnP pose of every view, in its detected order.
    camera, instant : array_like of int, shape (n,)
        Camera (0..m-1) and instant of each view; a camera sees an instant at most once.
        Views of different boards at one real instant must have different instants here.
    H : array_like, shape (n, 4, 4)
        Each view's board half turn (``T_target_turned``), NaN for a view without another
        order.
    m : int
    reference : int

    Returns
    -------
    ndarray of bool, shape (n,)
        True: take ``T_cam_target @ H`` and the permuted image points.  All False when the
        cameras are not linked (the solve then says so).
    """
    T = np.asarray(T_cam_target, dtype=np.float64).reshape(-1, 4, 4)
    H = np.asarray(H, dtype=np.float64).reshape(-1, 4, 4)
    camera = np.asarray(camera, dtype=np.int64)
    instant = np.asarray(instant, dtype=np.int64)
    can = np.isfinite(H[:, 0, 0])
    out = np.zeros(len(T), dtype=bool)
    if not can.any() or len(T) == 0:
        return out
    cov = covisibility(camera, instant, m)
    if len(link_groups(cov.shared > 0, [False] * m)) > 1:
        return out
    view = np.full((len(cov.instant_cameras), m), -1, dtype=np.int64)
    view[instant, camera] = np.arange(len(T))
    T_ref_cam = _place(T, H, can, view, spanning_tree(cov.shared, reference), reference)
    P = T_ref_cam[camera] @ T
    for t in range(len(view)):
        vs = view[t][view[t] >= 0]
        vs = vs[can[vs]]
        if len(vs) > 1:
            out[vs] = _instant_turns(P[vs], H[vs])
    return out
