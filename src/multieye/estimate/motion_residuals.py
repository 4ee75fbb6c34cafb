"""A moving rig in front of boards that stand still, as residual groups for the engine (issue 34).

What is measured are the boards' points' pixels.  The unknowns are each camera's pose in the
rig (the reference camera's frame) ``T_ref_cam^j`` (the reference camera's is the identity),
the world in the rig at every instant ``S(t) = T_ref_world(t) = inv(T_world_rig(t))`` (one per
instant, however many cameras saw boards then), every board's pose in the world
``T_world_board^b`` (the world is the first board's frame: board 0 is the identity, not an
unknown; boards whose pose is given, rig.yaml's ``pose:``, are held at it, not unknowns
either) and, when estimated, the lenses::

    p_cam = inv(T_ref_cam^j) @ S(t) @ T_world_board^b @ p          u = pi_j(p_cam)

With one board this is :mod:`multieye.estimate.rig_residuals`' problem (``S`` is then the
target's pose in the rig at each instant).  Cameras that never see a board at one instant are
linked through the rig's motion: a board seen by camera a at one instant and by camera b at
another is one unknown pose, and each instant's ``S`` is shared by the cameras that saw
boards then.

Block families (:class:`multieye.optimize.blocks.Blocks`): ``C`` (the m - 1 cameras other
than the reference, camera order), ``W`` (the boards not held, :attr:`MotionViews.free_boards`,
in board order), ``K:<camera>`` (estimated lenses),
``S`` (one per instant, eliminated by the Schur complement); poses ``se3-left``.

Jacobians at zero perturbation, with ``w = R_W p``, ``q_w = w + t_W`` (the point in the
world), ``s = R_S q_w``, ``d = s + t_S - t_C`` and ``a^T [v]_x = (a x v)^T``::

    d p_cam / d phi_C = R_C^T [d]_x             d p_cam / d tau_C = -R_C^T
    d p_cam / d phi_S = -R_C^T [s]_x            d p_cam / d tau_S = R_C^T
    d p_cam / d phi_W = -R_C^T R_S [w]_x        d p_cam / d tau_W = R_C^T R_S

chained with the lens model's ``d uv / d p_cam`` and ``d uv / d intrinsics``
(:func:`multieye.core.lens.project_with_jacobian`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, project_with_jacobian
from multieye.estimate.image_data import view_points
from multieye.estimate.image_residuals import cross_rows, intrinsics_family
from multieye.optimize.blocks import Blocks, ResidualGroup

__all__ = ["MotionViews", "MotionPixelResiduals"]

F64 = NDArray[np.float64]


class MotionViews:
    """Board points and pixels of every view (one image of one camera at one instant, one board).

    Views are numbered camera by camera; points view by view.

    Parameters
    ----------
    views : mapping of camera name to sequence of (object_points, image_points, instant, board)
        Board points (n, 3), metres in the board's frame; their pixels (n, 2); the instant
        (0..K-1); the board (0..nb-1, board 0 is the world).  Non-finite points are left out;
        a camera sees a board once per instant.
    intrinsics : sequence of Intrinsics
        One per camera (the starting values of the estimated ones).
    reference : int
        The camera whose frame is the rig's.
    free_intrinsics : sequence of bool, optional
        Per camera: estimate its lens (default: all held fixed).
    board_poses : mapping of int to array_like (4, 4), optional
        Boards held at a given pose ``T_world_board`` (metres), the others estimated; the
        world is the frame these poses are in.  Default ``{0: identity}``: board 0 is the
        world.  At least one board (the gauge).

    Attributes
    ----------
    camera, instant, board : ndarray of int, shape (n_views,)
    n_instants, n_boards : int
    held : dict of int to ndarray (4, 4)
        The boards held at a pose.
    held_poses : ndarray, shape (nb, 4, 4)
        Every board's pose when held, the identity for the others.
    free_boards : list of int
        The boards estimated, in order: the blocks of family ``W``.
    object_points, image_points : ndarray, shape (P, 3), (P, 2)
    view : ndarray of int, shape (P,)
    """

    def __init__(self, views: Mapping[str, Sequence], intrinsics: Sequence[Intrinsics],
                 reference: int = 0, *, free_intrinsics: Sequence[bool] | None = None,
                 board_poses: Mapping[int, F64] | None = None):
        if not isinstance(views, Mapping):
            raise InputError("views must be a mapping of camera name to views, got "
                             f"{type(views).__name__}")
        names, views, intrinsics = tuple(views), list(views.values()), list(intrinsics)
        m = len(views)
        if m == 0 or len(intrinsics) != m:
            raise InputError(f"{m} cameras of views and {len(intrinsics)} intrinsics; give "
                             "one of each per camera")
        if not 0 <= int(reference) < m:
            raise InputError(f"reference camera {reference} is not one of the {m} cameras")
        self.m, self.names, self.reference = m, names, int(reference)
        self.intrinsics = tuple(intrinsics)
        free = [False] * m if free_intrinsics is None else [bool(f) for f in free_intrinsics]
        if len(free) != m:
            raise InputError(f"free_intrinsics has {len(free)} entries for {m} cameras")
        self.free = tuple(free)
        obj, uv, of_point, cams, insts, boards = [], [], [], [], [], []
        for j, images in enumerate(views):
            for i, item in enumerate(images):
                where = f"camera {names[j]}, view {i}"
                if not isinstance(item, (tuple, list)) or len(item) != 4:
                    raise InputError(f"{where}: expected (object_points, image_points, "
                                     "instant, board)")
                o, u, t, ok = view_points(tuple(item[:3]), where, "instant", 4)
                b = item[3]
                for what, x in (("instant", t), ("board", b)):
                    if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or x < 0:
                        raise InputError(f"{where}: {what} must be a whole number >= 0, "
                                         f"got {x!r}")
                obj.append(o[ok])
                uv.append(u[ok])
                of_point.append(np.full(int(ok.sum()), len(cams)))
                cams.append(j)
                insts.append(int(t))
                boards.append(int(b))
        if not cams:
            raise InputError("no views given")
        self.camera = np.asarray(cams, dtype=np.int64)
        self.instant = np.asarray(insts, dtype=np.int64)
        self.board = np.asarray(boards, dtype=np.int64)
        for what, idx in (("instants", self.instant), ("boards", self.board)):
            if np.unique(idx).size != idx.max() + 1:
                raise InputError(f"{what} must be numbered 0..n-1, each with a view")
        key = (self.camera * (self.instant.max() + 1) + self.instant) * (self.board.max() + 1) \
            + self.board
        if np.unique(key).size != key.size:
            raise InputError("a camera sees a board at most once per instant")
        self.n_instants = int(self.instant.max()) + 1
        self.n_boards = int(self.board.max()) + 1
        self.object_points = np.concatenate(obj)
        self.image_points = np.concatenate(uv)
        self.view = np.concatenate(of_point)
        self.n_views = len(cams)
        self.counts = np.bincount(self.camera, minlength=m)
        self.held = _held(board_poses, self.n_boards)
        #: every board's pose when held, identity for the others (nb, 4, 4)
        self.held_poses = np.tile(np.eye(4), (self.n_boards, 1, 1))
        for b, T in self.held.items():
            self.held_poses[b] = T
        self.free_boards = [b for b in range(self.n_boards) if b not in self.held]
        #: per board its block of ``W``, -1 for a board held at its pose
        self.board_slot = np.full(self.n_boards, -1, dtype=np.int64)
        self.board_slot[self.free_boards] = np.arange(len(self.free_boards))

    def estimated(self, board) -> NDArray[np.bool_]:
        """Whether each of ``board`` (board indices) is estimated (not held)."""
        return self.board_slot[np.asarray(board)] >= 0

    @property
    def others(self) -> list[int]:
        """The cameras other than the reference, in order: the blocks of family ``C``."""
        return [j for j in range(self.m) if j != self.reference]

    def families(self, T_ref_cam: F64, T_world_board: F64, T_ref_world: F64,
                 intrinsics: Sequence[Intrinsics] | None = None) -> list[Blocks]:
        """``C`` (m - 1), ``W`` (nb - 1), ``K:<camera>`` per estimated lens, ``S`` (K,
        eliminated)."""
        intrinsics = self.intrinsics if intrinsics is None else intrinsics
        fams = []
        if self.m > 1:
            fams.append(Blocks("C", np.asarray(T_ref_cam)[self.others], "se3-left"))
        if self.free_boards:
            fams.append(Blocks("W", np.asarray(T_world_board)[self.free_boards], "se3-left"))
        fams += [Blocks(intrinsics_family(n), intrinsics[j].params[None], "euclidean")
                 for j, n in enumerate(self.names) if self.free[j]]
        fams.append(Blocks("S", T_ref_world, "se3-left", eliminate=True))
        return fams

    def groups(self, sigma_px: float) -> list[ResidualGroup]:
        """Per camera one :class:`MotionPixelResiduals` of its views of the boards held at
        their poses and one of the others (those that exist)."""
        out = []
        for j in range(self.m):
            for moved in (False, True):
                if np.any((self.camera == j) & (self.estimated(self.board) == moved)):
                    out.append(MotionPixelResiduals(self, j, moved, sigma_px))
        return out

    def T_ref_cam(self, values: Mapping[str, F64]) -> F64:
        """Every camera's ``T_ref_cam`` (m, 4, 4) from the values of family ``C``."""
        out = np.tile(np.eye(4), (self.m, 1, 1))
        if self.m > 1:
            out[self.others] = values["C"]
        return out

    def T_world_board(self, values: Mapping[str, F64]) -> F64:
        """Every board's pose in the world (nb, 4, 4): the held ones' poses, the others'
        from the values of family ``W``."""
        out = self.held_poses.copy()
        if self.free_boards:
            out[self.free_boards] = values["W"]
        return out

    def current_intrinsics(self, values: Mapping[str, F64]) -> tuple[Intrinsics, ...]:
        """Every camera's lens at the values (the estimated ones from ``K:<camera>``)."""
        return tuple(self.intrinsics[j].with_params(values[intrinsics_family(n)][0])
                     if self.free[j] else self.intrinsics[j]
                     for j, n in enumerate(self.names))


def _held(board_poses, n_boards: int) -> dict[int, F64]:
    """The boards held at a pose, checked (default: board 0 at the identity)."""
    if board_poses is None:
        return {0: np.eye(4)}
    if not isinstance(board_poses, Mapping) or not board_poses:
        raise InputError("board_poses must map at least one board to its pose (the gauge)")
    out = {}
    for b, T in board_poses.items():
        T = np.asarray(T, dtype=np.float64)
        if (isinstance(b, bool) or not isinstance(b, (int, np.integer)) or not 0 <= b < n_boards
                or T.shape != (4, 4) or not np.all(np.isfinite(T))):
            raise InputError(f"board_poses: board {b!r} is not one of the {n_boards} boards "
                             "or its pose is not a finite 4 x 4 matrix")
        out[int(b)] = T
    return out


class MotionPixelResiduals(ResidualGroup):
    """One camera's board-point pixel residuals over ``sigma_px``, of its views of the boards
    held at a pose (``moved=False``: no ``W`` block, the points placed in the world by the
    given pose) or of the others (module docstring)."""

    def __init__(self, data: MotionViews, camera: int, moved: bool, sigma_px: float):
        views = np.flatnonzero((data.camera == camera) & (data.estimated(data.board) == moved))
        pts = np.flatnonzero(np.isin(data.view, views))
        self.is_ref = camera == data.reference
        self.free, self.moved = data.free[camera], bool(moved)
        name = data.names[camera]
        slots = (([] if self.is_ref else ["C"]) + ["S"] + (["W"] if moved else [])
                 + ([intrinsics_family(name)] if self.free else []))
        cols = [] if self.is_ref else [np.full(views.size, data.others.index(camera))]
        cols.append(data.instant[views])
        if moved:
            cols.append(data.board_slot[data.board[views]])
        if self.free:
            cols.append(np.zeros(views.size, dtype=np.int64))
        seg = np.searchsorted(views, data.view[pts])
        super().__init__(slots, np.column_stack(cols), seg, 2)
        self.data, self.camera, self.name = data, camera, name
        self.instants = data.instant[views]
        self.boards = data.board[views]
        self.sigma = float(sigma_px)
        self._p = data.object_points[pts]
        if not moved:           # a held board's points in the world, once
            G = data.held_poses[self.boards[self.segment]]
            self._p = np.einsum("pij,pj->pi", G[:, :3, :3], self._p) + G[:, :3, 3]
        self._uv = data.image_points[pts]

    def _intrinsics(self, values: Mapping[str, F64]) -> Intrinsics | None:
        if not self.free:
            return self.data.intrinsics[self.camera]
        try:
            return self.data.intrinsics[self.camera].with_params(
                values[intrinsics_family(self.name)][0])
        except InputError:
            return None

    def _chain(self, values: Mapping[str, F64]):
        """Per point: ``w = R_W p``, ``R_S`` (P, 3, 3), ``s = R_S q_w``, ``d`` and ``p_cam``."""
        C = np.eye(4) if self.is_ref else values["C"][self.data.others.index(self.camera)]
        S = values["S"][self.instants[self.segment]]
        if self.moved:
            W = values["W"][self.data.board_slot[self.boards[self.segment]]]
            w = np.einsum("pij,pj->pi", W[:, :3, :3], self._p)
            q_w = w + W[:, :3, 3]
        else:
            w = q_w = self._p
        s = np.einsum("pij,pj->pi", S[:, :3, :3], q_w)
        d = s + S[:, :3, 3] - C[:3, 3]
        return C, S[:, :3, :3], w, s, d, d @ C[:3, :3]

    def _rows(self, values: Mapping[str, F64], intr: Intrinsics):
        """Residuals (P, 2) and their Jacobian against the slots' blocks side by side
        (P, 2, c), written in place (module docstring)."""
        C, RS, w, s, d, pc = self._chain(values)
        uv, Jp, Jk = project_with_jacobian(pc, intr)
        r = (uv - self._uv) / self.sigma
        JpR = (Jp / self.sigma) @ C[:3, :3].T                                 # (P, 2, 3)
        J = np.empty((len(r), 2, self.width))
        at = 0
        if not self.is_ref:
            J[:, :, 0:3], J[:, :, 3:6], at = cross_rows(JpR, d), -JpR, 6
        J[:, :, at:at + 3], J[:, :, at + 3:at + 6] = -cross_rows(JpR, s), JpR
        at += 6
        if self.moved:
            JpRS = JpR @ RS
            J[:, :, at:at + 3], J[:, :, at + 3:at + 6] = -cross_rows(JpRS, w), JpRS
            at += 6
        if self.free:
            J[:, :, at:] = Jk / self.sigma
        return r, J

    @property
    def width(self) -> int:
        """Columns of a row's Jacobian: 6 per pose slot, the lens's parameters."""
        lens = self.data.intrinsics[self.camera].params.size if self.free else 0
        return 6 * (len(self.slots) - self.free) + lens

    def linearize(self, values: Mapping[str, F64]):
        intr = self._intrinsics(values)
        if intr is None:
            raise InputError(f"camera {self.name}: intrinsics outside the model's valid range")
        r, J = self._rows(values, intr)
        return r, self.pad(J), self.pad(r)

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        intr = self._intrinsics(values)
        if intr is None:
            return np.full((self.n_rows, 2), np.nan), None
        if not jacobians:
            return (project_points(self._chain(values)[5], intr) - self._uv) / self.sigma, None
        r, J = self._rows(values, intr)
        cuts = np.cumsum([0] + [6] * (len(self.slots) - self.free)
                         + ([J.shape[2] - 6 * (len(self.slots) - 1)] if self.free else []))
        return r, [J[:, :, a:b] for a, b in zip(cuts[:-1], cuts[1:])]
