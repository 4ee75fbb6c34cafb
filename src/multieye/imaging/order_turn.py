"""The other point order of a board that looks the same after a half turn.

A chessboard with ``rows + cols`` even, a symmetric circle grid and an asymmetric circle grid
with an even number of rows are unchanged by the half turn ``H`` about their centre normal:
the image cannot tell point k from point ``N - 1 - k``, and
:func:`multieye.imaging.detect.canonical_order` takes the order whose x axis points towards
the image's lower right.  Both orders fit the pixels alike: the detected one with the PnP pose
``T_cam_target``, the other with ``T_cam_target @ H`` once the image points are permuted
(:attr:`HalfTurn.order`).  Which one agrees with the other views is for the rig's geometry to
decide (:mod:`multieye.pipeline.half_turns`).

Synopsis
--------
>>> from multieye.imaging.targets import Chessboard
>>> turn = half_turn(Chessboard(rows=3, cols=3, spacing=0.1))
>>> turn.order.tolist()
[8, 7, 6, 5, 4, 3, 2, 1, 0]
>>> half_turn(Chessboard(rows=3, cols=4, spacing=0.1)) is None      # rows + cols odd
True
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from multieye.imaging.targets import AsymmetricCircleGrid, Chessboard, CircleGrid, Target

__all__ = ["HalfTurn", "half_turn", "turn_order"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class HalfTurn:
    """A board's half turn about its centre normal.

    Attributes
    ----------
    T_target_turned : ndarray, shape (4, 4)
        The half turn in the target frame (``diag(-1, -1, 1)`` about the points' centre, an
        involution): the other order's pose is ``T_cam_target @ T_target_turned``.
    order : ndarray of int, shape (N,)
        Of the target's object points (:meth:`Target.object_points`): the turn takes point
        ``order[k]`` onto point k's place, so the other order's image points are
        ``image_points[order]``.
    """

    T_target_turned: F64
    order: NDArray[np.int64]


def _turn(points: F64) -> F64:
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    centre[2] = 0.0
    H = np.diag([-1.0, -1.0, 1.0, 1.0])
    H[:3, 3] = 2.0 * centre * np.array([1.0, 1.0, 0.0])
    return H


def turn_order(object_points, T_target_turned) -> NDArray[np.int64] | None:
    """Where ``T_target_turned`` takes each of ``object_points`` (shape (N, 3)): the index of
    the point at its place, or None when some point lands where no point is (a partial view,
    a board that is not symmetric).

    Every whole view of a board asks this of the same points and turn: the answer is kept
    by value (:func:`_turn_order`), and each call gets its own copy."""
    P = np.asarray(object_points, dtype=np.float64).reshape(-1, 3)
    H = np.ascontiguousarray(T_target_turned, dtype=np.float64)
    order = _turn_order(P.tobytes(), H.tobytes(), H.shape)
    return None if order is None else order.copy()


@lru_cache(maxsize=64)
def _turn_order(points: bytes, turn: bytes, shape: tuple[int, ...]) -> NDArray[np.int64] | None:
    """:func:`turn_order` of the points (N, 3) and the turn (of ``shape``) given by their
    float64 bytes, row by row (read only)."""
    P = np.frombuffer(points, dtype=np.float64).reshape(-1, 3)
    if len(P) < 2:
        return None
    H = np.frombuffer(turn, dtype=np.float64).reshape(shape)
    moved = P @ H[:3, :3].T + H[:3, 3]
    d = np.linalg.norm(moved[:, None, :] - P[None, :, :], axis=2)       # (N, N)
    idx = np.argmin(d, axis=1)
    scale = float(np.ptp(P[:, :2], axis=0).max())
    if np.any(d[np.arange(len(P)), idx] > 1e-6 * max(scale, 1e-9)):
        return None
    if len(np.unique(idx)) != len(P):
        return None
    idx = idx.astype(np.int64)
    idx.flags.writeable = False
    return idx


def half_turn(target: Target) -> HalfTurn | None:
    """The half turn of a board whose point order the image cannot decide (module
    docstring), or None: boards with ids (ChArUco, AprilGrid, markers), a chessboard with
    ``rows + cols`` odd (the colours decide), an asymmetric grid with an odd number of rows.
    Square grids also look the same after a quarter turn; only the half turn is given.
    The same board's :class:`HalfTurn` is one object, its arrays read only."""
    if isinstance(target, Chessboard):
        if not target.half_turn_symmetric:
            return None
    elif not isinstance(target, (CircleGrid, AsymmetricCircleGrid)):
        return None
    return _half_turn(np.asarray(target.object_points(), dtype=np.float64).tobytes())


@lru_cache(maxsize=32)
def _half_turn(points: bytes) -> HalfTurn | None:
    """:func:`half_turn` of the board whose object points (N, 3) have these float64 bytes."""
    P = np.frombuffer(points, dtype=np.float64).reshape(-1, 3)
    H = _turn(P)
    order = turn_order(P, H)
    if order is None:
        return None
    H.flags.writeable = order.flags.writeable = False
    return HalfTurn(H, order)
