"""The boards of a rig with several targets (rig.yaml's ``targets:``) as marks of the rig
figures (:func:`multieye.outputs.figures_rig.rig_pngs`): each board's printed pattern as a
rectangle at its pose, a short line along its normal (towards the side it is seen from), its
name, and the 3-sigma ellipsoid of its position when its pose has a covariance.  Plain numpy:
the figure module draws what this computes.

Synopsis
--------
>>> import numpy as np
>>> from multieye.core.target_spec import TargetSpec
>>> from multieye.outputs.board_marks import board_mark
>>> mark = board_mark("north", TargetSpec("chessboard", 6, 9, 0.1), np.eye(4))
>>> mark.corners().shape
(5, 3)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from multieye.core.target_spec import TargetSpec
from multieye.imaging.targets import target_from_spec
from multieye.io.calibration_json import CalibrationRecord

__all__ = ["BoardMark", "board_mark", "board_lines", "board_legend", "record_boards",
           "BOARD_COLOUR"]

#: The colour of the boards' marks (the cameras have theirs).
BOARD_COLOUR = "#3a3a3a"


@dataclass(frozen=True)
class BoardMark:
    """One board as the rig figures draw it.

    Attributes
    ----------
    name : str
    T_frame_board : ndarray, shape (4, 4)
        The board's pose in the frame the figures are drawn in, metres.
    bounds : (float, float, float, float)
        ``x_min, x_max, y_min, y_max`` of the printed pattern in the board frame, metres.
    z_into_board : bool
        Whether the board's +z points away from the side it is seen from.
    covariance : ndarray, shape (6, 6), or None
        Of ``T_frame_board``: rotation vector then translation, left perturbation in the
        figures' frame, radians and metres (docs/conventions.md, section 6).
    given : bool
        The pose was given in rig.yaml (held, not estimated).
    """

    name: str
    T_frame_board: np.ndarray
    bounds: tuple[float, float, float, float]
    z_into_board: bool = True
    covariance: np.ndarray | None = None
    given: bool = False

    def corners(self) -> np.ndarray:
        """The pattern's rectangle, closed, in the figures' frame, shape (5, 3)."""
        x0, x1, y0, y1 = self.bounds
        local = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0], [x0, y0, 0]])
        return local @ self.T_frame_board[:3, :3].T + self.T_frame_board[:3, 3]

    def centre(self) -> np.ndarray:
        """The pattern's centre in the figures' frame, shape (3,)."""
        return self.corners()[:4].mean(axis=0)

    def normal(self) -> np.ndarray:
        """Unit vector from the board towards the side it is seen from, shape (3,)."""
        z = self.T_frame_board[:3, 2]
        return -z if self.z_into_board else z


def board_mark(name: str, spec: TargetSpec, T_frame_board, covariance=None, *,
               given: bool = False) -> BoardMark:
    """The :class:`BoardMark` of a board described by rig.yaml (``spec``) at a pose."""
    target = target_from_spec(spec)
    cov = None if covariance is None else np.asarray(covariance, dtype=np.float64)
    return BoardMark(name, np.asarray(T_frame_board, dtype=np.float64), target.bounds(),
                     target.z_into_board, cov, given)


def record_boards(record: CalibrationRecord, details) -> tuple[BoardMark, ...]:
    """The boards of ``calibration.json``'s ``targets`` as the rig figures draw them.

    Where the boards and the cameras are in one frame, for boards whose outline the file
    holds (``bounds``): with motion capture and ``details.json`` (eye-on-hand: the boards in
    the motion capture's frame, the cameras at ``T_world_body_shown``), and without it for a
    rig linked by its motion (``details.frame``: the boards in the first board's frame, the
    cameras at the rig's pose of its middle instant).  Empty otherwise (no ``details.json``,
    or a file of an earlier version that keeps no rig pose).
    """
    if details is None or not record.targets or not (
            record.mocap or getattr(details, "frame", None) is not None):
        return ()
    return tuple(BoardMark(name, b.T_world_target, b.bounds, b.z_into_board,
                           None if b.uncertainty is None or not np.any(b.uncertainty.covariance)
                           else b.uncertainty.covariance, b.given)     # zero: the world
                 for name, b in record.targets.items() if b.bounds is not None)


def board_lines(boards: Sequence[BoardMark], disp: Callable, rings: Callable | None
                ) -> tuple[list, list]:
    """The boards' lines for the figures: per board its rectangle (thick), its normal (a
    fifth of its width) and, with ``rings`` (a function of a 3 x 3 position covariance that
    gives its 3-sigma ellipses as a NaN-broken polyline around 0, magnified as the cameras'),
    those rings; as ``(polyline in display coordinates, colour, width)``, and the points to
    keep in view.  ``disp`` maps figure-frame points to display coordinates."""
    lines, points = [], []
    for b in boards:
        box = disp(b.corners())
        lines.append((box, BOARD_COLOUR, 2.2 if not b.given else 1.2))
        width = float(np.linalg.norm(b.corners()[1] - b.corners()[0]))
        c = b.centre()
        lines.append((disp(np.stack([c, c + 0.2 * width * b.normal()])), BOARD_COLOUR, 1.0))
        points.append(box)
        if rings is not None and b.covariance is not None:
            ring = disp(rings(b.covariance[3:, 3:]) + c)
            ok = np.all(np.isfinite(ring), axis=1)
            parts = np.split(ring, np.flatnonzero(~ok))
            lines += [(p[np.all(np.isfinite(p), axis=1)], BOARD_COLOUR, 0.8) for p in parts
                      if np.all(np.isfinite(p), axis=1).sum() >= 2]
    return lines, points


def board_legend(boards: Sequence[BoardMark]) -> list[str]:
    """The figures' caption sentence for the boards (none without boards)."""
    if not boards:
        return []
    given = [b.name for b in boards if b.given]
    with_cov = any(b.covariance is not None for b in boards)
    text = (f"dark rectangles: the {len(boards)} boards, each with a short line towards the "
            "side it is seen from" + (" and the 3σ ellipsoid of its position, magnified as "
                                      "the cameras'" if with_cov else ""))
    if given:
        text += f"; thin: given in rig.yaml ({', '.join(given)})"
    return [text]
