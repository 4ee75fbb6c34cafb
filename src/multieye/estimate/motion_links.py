"""The start of a rig linked by its own motion in front of boards that stand still (issue 34).

When the rig moves rigidly and the boards stand still, every view (camera ``j`` sees board
``b`` at instant ``t``, PnP pose ``T_j_b``) closes a loop of three unknowns::

    T_world_rig(t) @ T_ref_cam^j @ T_j_b(t) = T_world_board^b

so any two of them give the third.  The start grows from the reference camera
(``T_ref_cam = I``) and the board it sees most (the world while growing):

1. *chaining* (the rule: :mod:`multieye.estimate.motion_growth`, which ``multieye check``
   follows too): an instant whose rig pose two known things give (a known camera seeing a known
   board then), a board a known camera sees at a known instant, a camera that sees a known
   board at a known instant, each the robust mean of every loop that gives it
   (:func:`multieye.estimate.covisibility.relative_pose`), until nothing more follows.  A
   camera placed by a board that another camera saw at the same instant is linked by
   *overlap*; by a board only it saw then, through the rig's pose that instant (from other
   cameras' boards), by *motion*;
2. *hand-eye*: when cameras are left whose boards are all unknown, the known instants' rig
   poses play the motion capture's part in the seed's joint problem ``A_i X^j = Y^b B_i``
   with ``A_i = T_world_rig(t)``, ``X^j = T_ref_cam^j``, ``Y^b = T_world_board^b``,
   ``B_i = inv(T_j_b(t))`` (eye-on-hand), every such camera and board at once
   (:func:`multieye.solvers.general.solve_general`, one call per connected part).  When the
   rig turned about one axis only the rotations of that system are not determined; a part of
   one camera and one board is then started by :func:`single_axis_hand_eye` (its
   translation along the axis is not determined: :mod:`multieye.estimate.observability`
   says so after the refinement); then back to 1.

A reference camera that sees boards at few instants places too few rig poses for step 2 to
place the others, which the rig's motion at their many instants links: when the growth from
the reference camera fails, it grows from the other cameras in turn (most instants first)
and the first that places everything is re-expressed in the reference camera's frame
(:func:`_from_other_camera`).

At the end the world is moved to the refinement's gauge
(:mod:`multieye.estimate.motion_residuals`): the first board's frame (board 0), or the frame
of the boards held at given poses (``views.held``).  Those boards are known from the start:
when there are several and the reference camera sees one, the growth starts from it with
every held board placed (they may link cameras the views alone would not); otherwise the
world is the robust mean of what the growth found for them against their given poses.  Either way the held boards start
exactly at their given poses.  Exact on noise-free poses.

Synopsis
--------
>>> st = motion_start(views, T_cam_board)                             # doctest: +SKIP
>>> st.T_ref_cam, st.T_world_board, st.links[2]                       # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.errors import DegenerateMotionError, DisconnectedError, InputError
from multieye.core.lie import exp_so3, log_so3
from multieye.estimate.covisibility import relative_pose
from multieye.estimate.motion_growth import Link, chain_round, hand_eye_views, link_of
from multieye.estimate.observability import turn_axis
from multieye.solvers.general import solve_general

__all__ = ["MotionStart", "motion_start", "single_axis_hand_eye", "Link"]

F64 = NDArray[np.float64]

#: The joint hand-eye answer of a part is taken when its loops close to within this (mean
#: rotation residual of every group, degrees; PnP poses are good to a fraction of it).
LOOP_LIMIT_DEG = 5.0
#: A group's poses turned about one axis, for the start, when their turns' second singular
#: value is below this fraction of the first (PnP poses: 0.3 degrees of tilt noise gave 0.026
#: on a rig driven on a floor; 6-DoF motion with 12 degrees of tilt about 0.15).
START_SPREAD = 0.06
#: Singular values of the single-axis translation system below this fraction of the
#: largest are taken as the axis (a turn's noise tilt: 0.005 against 1.4 on a planar rig).
_AXIS_RCOND = 0.05
#: ... and when the joint problem fails, this (a rig on a floor whose PnP poses tilt by half
#: a degree: 0.08).
FALLBACK_SPREAD = 0.25


@dataclass(frozen=True)
class MotionStart:
    """Starting values, world = board 0.

    Attributes
    ----------
    T_ref_cam : ndarray, shape (m, 4, 4)
    T_world_board : ndarray, shape (nb, 4, 4)
    T_world_rig : ndarray, shape (K, 4, 4)
    links : tuple of Link
        Per camera what placed it (overlap wins when a camera has both).
    single_axis : tuple of int
        Cameras started by :func:`single_axis_hand_eye` (a translation left undetermined).
    """

    T_ref_cam: F64
    T_world_board: F64
    T_world_rig: F64
    links: tuple[Link, ...]
    single_axis: tuple[int, ...] = ()


def _mean(T: list) -> F64:
    """Robust mean of a few estimates of one pose."""
    T = np.asarray(T)
    return relative_pose(T, np.tile(np.eye(4), (len(T), 1, 1)))


class _Growth:
    """The known poses while the start grows (module docstring)."""

    def __init__(self, T_jb, camera, instant, board, reference, seed: dict):
        self.T = T_jb
        self.cam, self.inst, self.board = (np.asarray(a).tolist() for a in (camera, instant, board))
        self.cams: dict[int, F64] = {reference: np.eye(4)}
        self.boards: dict[int, F64] = dict(seed)
        self.insts: dict[int, F64] = {}
        self.placed_by: dict[int, set] = {}              # instant -> {(camera, board)}
        self.links: dict[int, Link] = {reference: Link("reference")}
        self.single_axis: list[int] = []

    def _placed(self) -> tuple:
        return self.cam, self.inst, self.board, self.cams, self.insts, self.boards

    def chain(self) -> None:
        """Step 1 of the module docstring until nothing more follows
        (:func:`multieye.estimate.motion_growth.chain_round`, with the poses)."""
        while True:
            r = chain_round(*self._placed())
            for t, vs in r.instants.items():
                self.insts[t] = _mean([self.boards[self.board[v]] @ g.inv(self.T[v])
                                       @ g.inv(self.cams[self.cam[v]]) for v in vs])
                self.placed_by[t] = {(self.cam[v], self.board[v]) for v in vs}
            for b, vs in r.boards.items():
                self.boards[b] = _mean([self.insts[self.inst[v]] @ self.cams[self.cam[v]]
                                        @ self.T[v] for v in vs])
            for j, vs in r.cameras.items():
                self.cams[j] = _mean([g.inv(self.insts[self.inst[v]]) @ self.boards[self.board[v]]
                                      @ g.inv(self.T[v]) for v in vs])
                self.links[j] = self._link(vs)
            if not r:
                return

    def _link(self, vs) -> Link:
        """What placed a camera from its views ``vs`` (instants known)."""
        return link_of([(self.inst[v], self.board[v]) for v in vs], self.placed_by)

    def hand_eye(self) -> bool:
        """Step 2: the unknown cameras and boards from the known instants; whether any was
        placed."""
        groups: dict[tuple[int, int], list[int]] = {}
        for v in hand_eye_views(*self._placed()):
            groups.setdefault((self.cam[v], self.board[v]), []).append(v)
        placed = False
        for part in _components(list(groups)):
            solved = self._solve(part, groups)
            if solved is None:
                continue
            X, Y = solved
            for j, T in X.items():
                self.cams[j] = T
                vs = [v for (c, _), vv in groups.items() if c == j for v in vv]
                self.links[j] = self._link(vs)
            self.boards.update(Y)
            placed = True
        return placed

    def _group(self, j: int, b: int, vs: list[int]):
        return (f"c{j}", f"b{b}", np.stack([self.insts[self.inst[v]] for v in vs]),
                np.stack([g.inv(self.T[v]) for v in vs]))

    def _solve(self, part, groups):
        """One connected part's cameras and boards ``({camera: T_ref_cam}, {board: pose})``
        all at once by the joint hand-eye problem (its loops closed to within
        :data:`LOOP_LIMIT_DEG`).  When the rig turned about one axis only, to within the
        poses' noise (:data:`START_SPREAD`), that problem's rotations are undetermined
        about the axis (noise can make a wrong answer look determined, its loops closed),
        and when the joint problem fails on a part that turned mostly about one axis
        (:data:`FALLBACK_SPREAD`), the part's largest group alone is started by
        :func:`single_axis_hand_eye` and the chaining places the rest.  None when nothing
        gives them (maybe a later round)."""
        gs = {p: self._group(*p, groups[p]) for p in part}
        j, b = max(part, key=lambda p: len(groups[p]))
        if turn_axis(np.concatenate([x[2] for x in gs.values()]), START_SPREAD) is None:
            try:
                sol = solve_general(list(gs.values()))
                if max(r.e_R_deg for r in sol.residuals.values()) <= LOOP_LIMIT_DEG:
                    return ({int(k[1:]): T for k, T in sol.X.items()},
                            {int(k[1:]): T for k, T in sol.Y.items()})
            except DegenerateMotionError:
                pass
            if turn_axis(gs[j, b][2], FALLBACK_SPREAD) is None:
                return None
        try:
            X0, Y0 = single_axis_hand_eye(*gs[j, b][2:])
        except DegenerateMotionError:                  # too few poses
            return None
        self.single_axis.append(j)
        return {j: X0}, {b: Y0}


def _components(pairs: list[tuple[int, int]]) -> list[list[tuple[int, int]]]:
    """Connected parts of the bipartite graph camera - board whose edges are ``pairs``."""
    left = list(pairs)
    out = []
    while left:
        part, cams, boards = [left.pop(0)], set(), set()
        cams.add(part[0][0])
        boards.add(part[0][1])
        grew = True
        while grew:
            grew = False
            for p in list(left):
                if p[0] in cams or p[1] in boards:
                    part.append(p)
                    left.remove(p)
                    cams.add(p[0])
                    boards.add(p[1])
                    grew = True
        out.append(part)
    return out


def motion_start(views, T_cam_board) -> MotionStart:
    """Start every ``T_ref_cam``, board pose and rig pose (module docstring).

    Parameters
    ----------
    views : MotionViews
        Camera, instant and board of every view, the reference camera and the cameras' names
        (:class:`multieye.estimate.motion_residuals.MotionViews`).
    T_cam_board : array_like, shape (n_views, 4, 4)
        The board in the camera of each view (PnP).

    Raises
    ------
    DisconnectedError
        Cameras that neither overlap nor the rig's motion link to the reference camera (no
        instant at which they see a board while a linked camera sees one); ``names`` holds
        them.
    """
    T = np.asarray(T_cam_board, dtype=np.float64).reshape(-1, 4, 4)
    camera, instant, board, m = views.camera, views.instant, views.board, views.m
    ref, label = views.reference, views.names
    if len(T) != camera.size:
        raise InputError(f"{len(T)} poses for {camera.size} views")
    own = board[camera == ref]
    if own.size == 0:
        raise DisconnectedError(f"the reference camera {label[ref]} sees no board",
                                (label[ref],))
    held = dict(getattr(views, "held", None) or {0: np.eye(4)})
    try:
        grow = _from_anchor(T, views, held, ref)
    except (DegenerateMotionError, DisconnectedError) as exc:
        grow = _from_other_camera(T, views, held, exc)
    nb, K = int(board.max()) + 1, int(instant.max()) + 1
    to_world = _mean([G @ g.inv(grow.boards[b]) for b, G in held.items()])
    T_world_board = np.stack([to_world @ grow.boards[b] for b in range(nb)])
    for b, G in held.items():
        T_world_board[b] = G
    return MotionStart(
        T_ref_cam=np.stack([grow.cams[j] for j in range(m)]),
        T_world_board=T_world_board,
        T_world_rig=np.stack([to_world @ grow.insts[t] for t in range(K)]),
        links=tuple(grow.links[j] for j in range(m)), single_axis=tuple(grow.single_axis))


def _from_anchor(T: F64, views, held: dict, anchor: int) -> _Growth:
    """The growth from camera ``anchor`` (its frame the rig's while growing) and the boards
    :func:`_seed` gives it; when grown from several boards at given poses fails, from the
    views alone."""
    own = views.board[views.camera == anchor]
    seed = _seed(own, held)
    try:
        return _grown(T, views, seed, anchor)
    except (DegenerateMotionError, DisconnectedError):
        if len(seed) < 2:
            raise
        # grown from the boards at given poses it failed: from the views alone, as without
        return _grown(T, views, {int(np.bincount(own).argmax()): np.eye(4)}, anchor)


def _from_other_camera(T: F64, views, held: dict, failed: Exception) -> _Growth:
    """The growth from another camera when the one from the reference camera ``failed``,
    re-expressed in the reference camera's frame.

    A reference camera that sees boards at few instants places few rig poses, too few for
    the hand-eye step to place the other cameras, which see boards at many (the rig's
    motion links them; only the reference camera's own pose rests on its few views).  The
    cameras are tried in order of how many instants they see a board at; the first growth
    that places every camera, board and instant is taken.

    Raises
    ------
    DegenerateMotionError, DisconnectedError
        ``failed`` when no camera's growth places everything.
    """
    ref = views.reference
    counts = [len(set(views.instant[views.camera == j].tolist())) for j in range(views.m)]
    for anchor in sorted(range(views.m), key=lambda j: -counts[j]):
        if anchor == ref or counts[anchor] <= counts[ref]:
            continue
        try:
            grow = _from_anchor(T, views, held, anchor)
        except (DegenerateMotionError, DisconnectedError):
            continue
        return _reframed(grow, ref, anchor)
    raise failed


def _reframed(grow: _Growth, ref: int, anchor: int) -> _Growth:
    """A growth from camera ``anchor`` in the frame of camera ``ref``: every ``T_ref_cam``
    and rig pose moved by ``T_anchor_ref``; ``ref`` is the reference, ``anchor`` linked by
    what placed ``ref`` (the link read the other way)."""
    T_a_r = grow.cams[ref]
    grow.cams = {j: g.inv(T_a_r) @ T for j, T in grow.cams.items()}
    grow.insts = {t: T @ T_a_r for t, T in grow.insts.items()}
    back = grow.links[ref]
    grow.links[anchor] = (Link("overlap", (ref,)) if back.kind == "overlap"
                          and anchor in back.cameras else
                          Link("motion", tuple(sorted({ref, *back.cameras} - {anchor})),
                               back.boards))
    grow.links[ref] = Link("reference")
    return grow


def _grown(T: F64, views, seed: dict, anchor: int) -> _Growth:
    """The growth from camera ``anchor`` and ``seed`` (boards known at the start) until
    every camera, board and instant is placed (module docstring, steps 1 and 2).

    Raises
    ------
    DegenerateMotionError, DisconnectedError
        As :func:`motion_start`.
    """
    camera, instant, board, m = views.camera, views.instant, views.board, views.m
    ref, label = anchor, views.names
    grow = _Growth(T, camera, instant, board, ref, seed)
    while True:
        grow.chain()
        if len(grow.cams) == m or not grow.hand_eye():
            break
    apart = [label[j] for j in range(m) if j not in grow.cams]
    tried = {label[grow.cam[v]] for v in hand_eye_views(*grow._placed())}
    if apart and tried:
        raise DegenerateMotionError(
            f"cameras {', '.join(sorted(tried))} see boards while a linked camera does, but "
            "the rig's motion at those instants does not determine their poses (it turned "
            "about one axis only, too little, or at too few instants): turn the rig about two "
            "different axes while they see boards")
    if apart:
        raise DisconnectedError(
            f"cameras {', '.join(apart)} are linked to the reference camera {label[ref]} "
            "neither by views they share nor by the rig's motion: give them images of a board "
            "taken at instants (synchronised or stamped) when a linked camera sees a board, or "
            "motion capture (mocap: in rig.yaml)", tuple(apart))
    nb, K = int(board.max()) + 1, int(instant.max()) + 1
    missing = [f"board {b}" for b in range(nb) if b not in grow.boards] + [
        f"instant {t}" for t in range(K) if t not in grow.insts]
    if missing:
        raise DisconnectedError("nothing links " + ", ".join(missing[:5]) + " to the rig: "
                                "seen only when no linked camera sees a linked board", ())
    return grow


def _seed(own, held: dict) -> dict[int, F64]:
    """The boards the growth starts from: with boards at given poses (more than one held)
    the held board the reference camera sees most with every held board placed relative to
    it, else (or when it sees none of them) the board it sees most, alone."""
    counts = np.bincount(own)
    mine = [b for b in held if b < counts.size and counts[b]]
    if len(held) < 2 or not mine:
        return {int(counts.argmax()): np.eye(4)}
    start = g.inv(held[max(mine, key=lambda b: counts[b])])
    return {b: start @ G for b, G in held.items()}


def single_axis_hand_eye(A, B) -> tuple[F64, F64]:
    """``A_i X = Y B_i`` when every ``inv(A_i) A_0`` turns about one axis (planar motion).

    The rotation of X is the rotation about the axis ``k`` (in X's left frame) that carries
    ``B``'s axis onto ``k``, times the turn ``theta`` about ``k`` that best fits the
    translations ``(R_P - I) t_X = R_X t_Q - t_P`` of the relative motions ``P_i X = X Q_i``
    (a scan of ``theta`` then a bounded search).  The translation of X along ``k`` is not
    determined: it is set to zero (the least-squares solution of least norm).

    Parameters
    ----------
    A, B : array_like, shape (n, 4, 4)

    Returns
    -------
    X, Y : ndarray, shape (4, 4)
    """
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    if len(A) < 3:
        raise DegenerateMotionError("fewer than 3 poses: the turn is not determined")
    P = g.inv(A[1:]) @ A[0]
    Q = g.inv(B[1:]) @ B[0]
    wP = np.array([log_so3(R) for R in P[:, :3, :3]])
    wQ = np.array([log_so3(R) for R in Q[:, :3, :3]])
    kP = np.linalg.svd(wP)[2][0]
    kQ = np.linalg.svd(wQ)[2][0]
    if (wQ @ kQ) @ (wP @ kP) < 0:
        kQ = -kQ
    R0 = _carry(kQ, kP)

    def fit(theta: float):
        R = exp_so3(theta * kP) @ R0
        M = (P[:, :3, :3] - np.eye(3)).reshape(-1, 3)
        rhs = (Q[:, :3, 3] @ R.T - P[:, :3, 3]).reshape(-1)
        # the axis's singular value is the poses' tilt noise, not information: left out
        t = np.linalg.lstsq(M, rhs, rcond=_AXIS_RCOND)[0]
        return float(np.sum((M @ t - rhs) ** 2)), g.make_transform(R, t)

    grid = np.radians(np.arange(-180.0, 180.0, 1.0))
    best = grid[int(np.argmin([fit(a)[0] for a in grid]))]
    from scipy.optimize import minimize_scalar  # noqa: PLC0415 (scipy.optimize imports scipy.spatial: only for a rig turning about one axis, off a calibration's usual path)

    theta = minimize_scalar(lambda a: fit(a)[0], bounds=(best - 0.02, best + 0.02),
                            method="bounded", options={"xatol": 1e-12}).x
    X = fit(theta)[1]
    return X, _mean(list(A @ X @ g.inv(B)))


def _carry(a: F64, b: F64) -> F64:
    """The smallest rotation carrying unit vector ``a`` onto ``b``."""
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        perp = np.linalg.svd(a[None])[2][1]
        return exp_so3(np.pi * perp)
    return exp_so3(axis / s * np.arctan2(s, c))
