"""Cameras linked by what they see together: the co-visibility graph and the rig's start.

An *instant* is one pose of the target seen by every camera that took an image then (images
with equal stamps within ``sync_tolerance``, or equal names: docs/rig-yaml.md, section 2).
Two cameras that share instants are linked by them: at each shared instant ``t``::

    T_a_b = T_a_target(t) @ inv(T_b_target(t))

whatever the target's pose.  The *co-visibility graph* has the cameras as nodes and the
number of instants two cameras share as edge weights.  The rig's start is read off it
strongest links first: the maximum spanning tree of the graph, walked from the reference
camera, places each camera relative to its tree parent by the relative pose averaged over
their shared instants (chordal L2 mean of the rotations, per-axis median of the
translations, both robust to a few wrong PnP poses), and each instant's ``T_ref_target``
starts from the mean of its cameras' ``T_ref_cam @ T_cam_target`` that agree with their
medoid (one wrong PnP pose does not pull it).

Cameras that share no instant, directly or through others, fall into *groups* that nothing in
the images links; only motion capture can (every camera with motion capture is linked to every
other such camera through it).  :func:`link_groups` finds them, :func:`unlinked_message` says
so in one line.

Synopsis
--------
>>> import numpy as np
>>> shared = np.array([[0, 5, 0], [5, 0, 2], [0, 2, 0]])
>>> spanning_tree(shared, root=0).tolist()
[-1, 0, 1]
>>> link_groups(shared > 0, [False] * 3)
[(0, 1, 2)]
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.errors import DisconnectedError, InputError

__all__ = ["Covisibility", "covisibility", "spanning_tree", "link_groups", "unlinked_message",
           "pairing_hint",
           "relative_pose", "RigStart", "initial_rig"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Covisibility:
    """Which cameras see the target together.

    Attributes
    ----------
    shared : ndarray of int, shape (m, m)
        Instants seen by both cameras (diagonal: instants of each camera).
    instant_cameras : tuple of tuple of int
        Per instant, the cameras that saw it.
    """

    shared: NDArray[np.int64]
    instant_cameras: tuple[tuple[int, ...], ...]

    def partners(self, camera: int) -> dict[int, int]:
        """Other cameras sharing instants with ``camera``: camera -> instants shared."""
        row = self.shared[camera]
        return {int(k): int(row[k]) for k in np.flatnonzero(row) if k != camera}


def covisibility(camera, instant, m: int) -> Covisibility:
    """The co-visibility graph of views ``(camera[v], instant[v])``.

    Parameters
    ----------
    camera, instant : array_like of int, shape (n_views,)
        Camera and instant (0..K-1) of each view; a camera sees an instant at most once.
    m : int
        Number of cameras.

    Returns
    -------
    Covisibility
    """
    camera = np.asarray(camera, dtype=np.int64).reshape(-1)
    instant = np.asarray(instant, dtype=np.int64).reshape(-1)
    if camera.shape != instant.shape:
        raise InputError(f"{camera.size} cameras for {instant.size} instants of views")
    n_inst = int(instant.max()) + 1 if instant.size else 0
    seen = np.zeros((n_inst, m), dtype=np.int64)
    np.add.at(seen, (instant, camera), 1)
    if np.any(seen > 1):
        t, j = np.argwhere(seen > 1)[0]
        raise InputError(f"camera {j} has {seen[t, j]} images at instant {t}; a camera sees "
                         "an instant at most once")
    shared = seen.T @ seen
    cams = tuple(tuple(int(j) for j in np.flatnonzero(row)) for row in seen)
    return Covisibility(shared, cams)


def spanning_tree(shared, root: int) -> NDArray[np.int64]:
    """Maximum spanning tree of the co-visibility graph, grown from ``root`` (Prim).

    Parameters
    ----------
    shared : array_like, shape (m, m)
        Edge weights (instants shared); zero means no edge.
    root : int

    Returns
    -------
    ndarray of int, shape (m,)
        Tree parent of each camera: -1 for the root and for cameras the tree cannot reach.
        Cameras are attached strongest link first (ties: lowest camera number).
    """
    W = np.asarray(shared, dtype=np.float64).copy()
    m = len(W)
    np.fill_diagonal(W, 0.0)
    parent = np.full(m, -1, dtype=np.int64)
    inside = np.zeros(m, dtype=bool)
    inside[root] = True
    best = W[root].copy()
    via = np.full(m, root, dtype=np.int64)
    while True:
        cand = np.where(inside, 0.0, best)
        k = int(np.argmax(cand))
        if cand[k] <= 0:
            return parent
        parent[k] = via[k]
        inside[k] = True
        better = W[k] > best
        best[better], via[better] = W[k][better], k


def link_groups(linked, mocap: Sequence[bool]) -> list[tuple[int, ...]]:
    """Groups of cameras that something links: shared instants, or motion capture for all.

    Parameters
    ----------
    linked : array_like of bool, shape (m, m)
        Cameras sharing at least one instant.
    mocap : sequence of bool, length m
        Cameras with motion capture: all of them are linked to each other through it.

    Returns
    -------
    list of tuple of int
        Connected components, each sorted, ordered by their first camera.
    """
    A = np.asarray(linked, dtype=bool).copy()
    m = len(A)
    with_mocap = np.flatnonzero(np.asarray(mocap, dtype=bool))
    A[np.ix_(with_mocap, with_mocap)] = True
    label = np.full(m, -1)
    for start in range(m):
        if label[start] >= 0:
            continue
        stack = [start]
        label[start] = start
        while stack:
            k = stack.pop()
            for n in np.flatnonzero(A[k] | A[:, k]):
                if label[n] < 0:
                    label[n] = start
                    stack.append(int(n))
    return [tuple(int(j) for j in np.flatnonzero(label == s)) for s in np.unique(label)]


def unlinked_message(groups: Sequence[Sequence[str]], tolerance: float | None = None,
                     sync: str = "time") -> str:
    """One line saying that ``groups`` (two or more, each of camera names) are not linked,
    and what would link them (``tolerance``: the ``sync_tolerance`` used, seconds, named when
    given; ``sync``: rig.yaml's, when images pair by name)."""
    shown = [("{" + ", ".join(grp) + "}") for grp in groups]
    listing = ", ".join(shown[:-1]) + " and " + shown[-1]
    within = "" if tolerance is None else f" = {tolerance:g} s"
    how = (f"stamps within sync_tolerance{within}" if sync == "time"
           else f"names that pair under sync: {sync}")
    return (f"cameras fall into {len(groups)} groups that nothing links: {listing}; give them "
            f"views of the board at the same instants ({how}), motion capture (mocap: in "
            "rig.yaml), or several boards standing still (targets: in rig.yaml) that the "
            "cameras see while the rig moves")


def pairing_hint(groups: Sequence[Sequence[int]], stamps: Sequence | None = None,
                 stems: Sequence[Sequence[str]] | None = None, sync: str = "time",
                 labels: Sequence[str] | None = None) -> str:
    """What would make the images of unlinked camera groups one instant, for
    :func:`unlinked_message`: ``"; ..."`` or ``""``.

    Parameters
    ----------
    groups : sequence of sequence of int
        The camera groups (:func:`link_groups`), camera indices.
    stamps : sequence of array_like, optional
        ``sync: time``: each camera's image stamps, seconds (its time offset added). When the
        nearest images of the first group and the others are under a second apart and a
        tolerance of 1.5 times that gap stays under half of every camera's shortest interval
        between images, that ``sync_tolerance`` is suggested (cameras triggered together with
        stamps a little apart).  Else, when shifting the stamps of the other groups'
        camera with most images by one offset of a second or more makes at least half of
        them meet the first group's, that ``time_offset`` is suggested (a camera on its own
        clock).
    stems : sequence of sequence of str, optional
        ``sync: name``: each camera's image names without extension; when the last numbers
        in them agree across the groups, ``sync: number`` is suggested (``left01``,
        ``right01``).
    sync : str
        rig.yaml's ``sync``.
    labels : sequence of str, optional
        The cameras' names, for the ``time_offset`` suggestion.
    """
    first, rest = list(groups[0]), [j for g in groups[1:] for j in g]
    if sync == "time" and stamps is not None:
        a = np.sort(np.concatenate([np.asarray(stamps[j], np.float64) for j in first]))
        b = np.concatenate([np.asarray(stamps[j], np.float64) for j in rest])
        if len(a) and len(b):
            k = np.searchsorted(a, b)               # the first of a at or after each of b
            lo, hi = a[np.clip(k - 1, 0, len(a) - 1)], a[np.clip(k, 0, len(a) - 1)]
            gap = float(np.min(np.minimum(np.abs(b - lo), np.abs(b - hi))))
            steps = [np.diff(np.sort(np.asarray(t, np.float64))) for t in stamps if len(t) > 1]
            shortest = min((float(d[d > 0].min()) for d in steps if np.any(d > 0)), default=np.inf)
            suggest = float(np.ceil(gap * 1.5 * 1e3) / 1e3)
            if 0 < gap < 1.0 and suggest < shortest / 2:
                return (f"; the nearest images of two groups are {gap * 1e3:.3g} ms apart: if "
                        f"the cameras were triggered together, sync_tolerance: {suggest:g} in "
                        "rig.yaml makes such images one instant")
            rest_cam = max(rest, key=lambda j: len(stamps[j]))
            hint = _offset_hint(a, np.sort(np.asarray(stamps[rest_cam], np.float64)),
                                min(0.01, shortest / 4),
                                f"camera {labels[rest_cam]}" if labels else "that camera")
            if hint:
                return hint
    if sync == "name" and stems is not None:
        def numbers(cams):
            found = ((re.findall(r"\d+", s), s) for j in cams for s in stems[j])
            return {int(n[-1]): s for n, s in found if n}
        mine, others = numbers(first), numbers(rest)
        both = sorted(set(mine) & set(others))
        if both:
            return (f"; the names differ but the numbers in them agree ({mine[both[0]]} with "
                    f"{others[both[0]]}): sync: number pairs images by the (frame) number in "
                    "their names")
    return ""


def _offset_hint(a: F64, b: F64, tol: float, who: str, most: int = 300) -> str:
    """``"; ..."`` naming the clock offset that makes most images of one camera (stamps
    ``b``, sorted) one instant with the first group's (``a``, sorted), when its clock is a
    second or more off (each camera on its own computer's clock); ``""`` when no offset
    pairs at least half of the fewer images (and 3).  Candidates: every ``a - b`` of the
    first 5 of ``b`` (at most ``most`` of each, evenly spread)."""
    a = a[np.linspace(0, len(a) - 1, min(len(a), most)).round().astype(int)]
    b = b[np.linspace(0, len(b) - 1, min(len(b), most)).round().astype(int)]
    if not np.isfinite(tol) or min(len(a), len(b)) < 3:
        return ""
    cand = (a[:, None] - b[None, :5]).ravel()
    shifted = b[None, :] + cand[:, None]                            # (candidates, len(b))
    k = np.clip(np.searchsorted(a, shifted), 1, len(a) - 1)
    near = np.minimum(np.abs(a[k] - shifted), np.abs(a[k - 1] - shifted)) <= tol
    best = int(np.argmax(near.sum(axis=1)))
    hits = int(near[best].sum())
    if hits < max(3, min(len(a), len(b)) / 2) or abs(cand[best]) < 1.0:
        return ""
    k_b = np.flatnonzero(near[best])
    offset = float(np.median(a[np.clip(np.searchsorted(a, b[k_b] + cand[best]), 0, len(a) - 1)]
                             - b[k_b])) if hits else float(cand[best])
    offset = float(cand[best]) if abs(offset - cand[best]) > tol else offset
    shown = f"{offset:.6f}".rstrip("0").rstrip(".")
    return (f"; {who}'s stamps plus {shown} s meet the first group's at {hits} of its "
            f"{len(b)} images: if its clock is that far off, time_offset: {shown} (added to "
            "any it has) in rig.yaml makes them one instant")


def relative_pose(T_a_target, T_b_target) -> F64:
    """``T_a_b`` from views of one target at the same instants, averaged robustly.

    Per instant ``T_a_b = T_a_target @ inv(T_b_target)``; the rotations are averaged by their
    chordal L2 mean after leaving out those more than 3 times the median angle (and 1 degree)
    from a first mean, the translations by their per-axis median.

    Parameters
    ----------
    T_a_target, T_b_target : array_like, shape (n, 4, 4)
        The target in cameras a and b at n shared instants.

    Returns
    -------
    ndarray, shape (4, 4)
    """
    Ta = np.asarray(T_a_target, dtype=np.float64).reshape(-1, 4, 4)
    Tb = np.asarray(T_b_target, dtype=np.float64).reshape(-1, 4, 4)
    if len(Ta) == 0 or len(Ta) != len(Tb):
        raise InputError(f"relative pose needs the same number (> 0) of views of each camera, "
                         f"got {len(Ta)} and {len(Tb)}")
    T_ab = Ta @ g.inv(Tb)
    R = T_ab[:, :3, :3]
    R_mean = g.rotation_mean(R)
    angle = g.rotation_angle(np.swapaxes(R, 1, 2) @ R_mean)
    keep = angle <= max(3.0 * float(np.median(angle)), np.radians(1.0))
    R_mean = g.rotation_mean(R[keep])
    return g.make_transform(R_mean, np.median(T_ab[keep, :3, 3], axis=0))


@dataclass(frozen=True)
class RigStart:
    """Starting values of the rig from the co-visibility graph.

    Attributes
    ----------
    T_ref_cam : ndarray, shape (m, 4, 4)
        Each camera in the reference camera's frame (identity for the reference).
    T_ref_target : ndarray, shape (K, 4, 4)
        The target at each instant, in the reference camera's frame.
    parent : ndarray of int, shape (m,)
        Tree parent of each camera (-1 for the reference).
    """

    T_ref_cam: F64
    T_ref_target: F64
    parent: NDArray[np.int64]


def initial_rig(T_cam_target, camera, instant, m: int, reference: int = 0,
                names: Sequence[str] | None = None) -> RigStart:
    """Start ``T_ref_cam`` and every ``T_ref_target`` from per-view PnP poses (module docstring).

    Parameters
    ----------
    T_cam_target : array_like, shape (n_views, 4, 4)
        The target in the camera of each view (PnP).
    camera, instant : array_like of int, shape (n_views,)
        Camera (0..m-1) and instant (0..K-1) of each view; every instant has a view.
    m : int
    reference : int
        The camera whose frame is ``ref``.
    names : sequence of str, optional
        Camera names for the message when cameras are not linked.

    Raises
    ------
    DisconnectedError
        When some camera shares no instant with the reference camera's group
        (:func:`unlinked_message`; ``names`` holds the cameras outside that group).
    """
    T = np.asarray(T_cam_target, dtype=np.float64).reshape(-1, 4, 4)
    camera = np.asarray(camera, dtype=np.int64)
    instant = np.asarray(instant, dtype=np.int64)
    cov = covisibility(camera, instant, m)
    groups = link_groups(cov.shared > 0, [False] * m)
    if len(groups) > 1:
        names = list(names) if names is not None else [f"cam{j}" for j in range(m)]
        apart = [names[j] for grp in groups if reference not in grp for j in grp]
        raise DisconnectedError(unlinked_message([[names[j] for j in grp] for grp in groups]),
                                tuple(apart))
    parent = spanning_tree(cov.shared, reference)
    n_inst = len(cov.instant_cameras)
    view = np.full((n_inst, m), -1, dtype=np.int64)
    view[instant, camera] = np.arange(len(T))
    T_ref_cam = np.tile(np.eye(4), (m, 1, 1))
    placed = np.zeros(m, dtype=bool)
    placed[reference] = True
    while not placed.all():
        for j in np.flatnonzero(~placed):
            p = parent[j]
            if not placed[p]:
                continue
            both = (view[:, p] >= 0) & (view[:, j] >= 0)
            T_p_j = relative_pose(T[view[both, p]], T[view[both, j]])
            T_ref_cam[j] = T_ref_cam[p] @ T_p_j
            placed[j] = True
    in_ref = T_ref_cam[camera] @ T                                   # (n_views, 4, 4)
    T_ref_target = np.stack([_consensus_pose(in_ref[view[t][view[t] >= 0]])
                             for t in range(n_inst)])
    return RigStart(T_ref_cam, T_ref_target, parent)


def _consensus_pose(T: F64) -> F64:
    """One pose from a few estimates of it (n, 4, 4): the mean of those within 2 degrees of
    the medoid (the estimate nearest the others in rotation), so that one wrong PnP pose (a
    board's mirrored solution) does not pull the start."""
    if len(T) == 1:
        return T[0]
    R = T[:, :3, :3]
    angle = g.rotation_angle(np.swapaxes(R, 1, 2)[:, None] @ R[None])          # (n, n)
    near = angle[int(np.argmin(angle.sum(axis=1)))] <= np.radians(2.0)
    return g.make_transform(g.rotation_mean(R[near]), T[near, :3, 3].mean(axis=0))
