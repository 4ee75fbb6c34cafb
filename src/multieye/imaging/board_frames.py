"""From multieye's board frame to the frame of OpenCV's object points, per target type.

multieye's target frame (:mod:`multieye.imaging.targets`) is fixed by the board alone, so that
results keep their meaning; OpenCV's object points put the origin elsewhere for some boards.
:func:`T_opencv_target` gives the rigid transform ``T_opencv_target`` that maps a point in
multieye's target frame into OpenCV's board frame (``p_opencv = T_opencv_target @ p_target``),
so that a pose from an OpenCV script compares with multieye's as

    ``T_cam_target (multieye) = T_cam_opencv (OpenCV's solvePnP) @ T_opencv_target``

and ``T_marker_target = T_marker_opencv @ T_opencv_target``.  docs/conventions.md, section 5,
lists the same table; tests/imaging/test_board_frames.py applies it to OpenCV's own detectors,
boards and ``cv2.solvePnP``.

Synopsis
--------
>>> from multieye.imaging.targets import Chessboard
>>> T = T_opencv_target(Chessboard(rows=6, cols=9, spacing=0.04))
>>> T[:3, 3].round(3).tolist()
[0.32, 0.2, 0.0]
"""

from __future__ import annotations

import numpy as np

from multieye.core.errors import InputError
from multieye.imaging.targets import (
    AprilGrid,
    ArucoGrid,
    ArucoMarker,
    AsymmetricCircleGrid,
    Charuco,
    Chessboard,
    CircleGrid,
    Target,
)

__all__ = ["T_opencv_target", "CHESSBOARD_DETECTORS"]

#: OpenCV's two chessboard detectors: ``sb`` (``findChessboardCornersSB``) and ``classic``
#: (``findChessboardCorners``); they start from opposite corners.
CHESSBOARD_DETECTORS = ("sb", "classic")


def _half_turn_about_z(x: float, y: float) -> np.ndarray:
    """A half turn about z, then a shift by ``(x, y, 0)``: point ``(0, 0)`` goes to ``(x, y)``."""
    return np.array([[-1.0, 0, 0, x], [0, -1.0, 0, y], [0, 0, 1.0, 0], [0, 0, 0, 1.0]])


def T_opencv_target(target: Target, *, chessboard_detector: str = "sb") -> np.ndarray:
    """``T_opencv_target``, shape (4, 4), metres: multieye's target frame in OpenCV's.

    Parameters
    ----------
    target : Target
    chessboard_detector : {"sb", "classic"}
        Which OpenCV detector ordered the chessboard corners that an OpenCV script paired
        with its object points ``(j * s, i * s, 0)`` (OpenCV's tutorial).

    Returns
    -------
    ndarray, shape (4, 4)
        - chessboard (``rows + cols`` odd): ``sb``: a half turn about z, origin at the
          opposite corner (multieye's last point, ``((cols-1) s, (rows-1) s, 0)``);
          ``classic``: the identity;
        - asymmetric-circles (odd ``rows``), with ``findCirclesGrid``'s order and OpenCV's
          sample object points ``((2 j + i % 2) s/2, i s/2, 0)``: the identity;
        - charuco: a shift by one square, ``(s, s, 0)`` (OpenCV's origin is the outer corner
          of the board; ``board.getChessboardCorners()[k]`` is multieye's point k);
        - aruco-grid: the identity (``GridBoard.getObjPoints()``);
        - aruco: OpenCV's single-marker points (``SOLVEPNP_IPPE_SQUARE``: origin at the
          marker's centre, y up, z out of the marker): a half turn about x after a shift
          by ``(-L/2, -L/2, 0)``.

    Raises
    ------
    InputError
        Boards whose point order OpenCV leaves to the image (a chessboard with ``rows + cols``
        even, a symmetric circle grid, an asymmetric grid with even ``rows``), and the
        AprilGrid, which OpenCV has no board for (multieye keeps Kalibr's frame).
    """
    if chessboard_detector not in CHESSBOARD_DETECTORS:
        raise InputError(f"chessboard_detector must be one of {', '.join(CHESSBOARD_DETECTORS)}, "
                         f"got {chessboard_detector!r}")
    s = target.spacing
    if isinstance(target, Chessboard):
        if target.half_turn_symmetric:
            raise InputError(f"chessboard {target.rows}x{target.cols} looks the same after a "
                             "half turn: OpenCV's corner order follows the image, no fixed "
                             "transform")
        if chessboard_detector == "classic":
            return np.eye(4)
        return _half_turn_about_z((target.cols - 1) * s, (target.rows - 1) * s)
    if isinstance(target, AsymmetricCircleGrid):
        if target.rows % 2 == 0:
            raise InputError(f"asymmetric-circles with {target.rows} rows look the same after "
                             "a half turn: OpenCV's order follows the image, no fixed transform")
        return np.eye(4)
    if isinstance(target, CircleGrid):
        raise InputError("a symmetric circle grid looks the same after a half turn: OpenCV's "
                         "order follows the image, no fixed transform")
    if isinstance(target, Charuco):
        T = np.eye(4)
        T[:2, 3] = s
        return T
    if isinstance(target, ArucoGrid):
        return np.eye(4)
    if isinstance(target, ArucoMarker):
        half = s / 2
        return np.array([[1.0, 0, 0, -half], [0, -1.0, 0, half], [0, 0, -1.0, 0],
                         [0, 0, 0, 1.0]])
    if isinstance(target, AprilGrid):
        raise InputError("OpenCV has no AprilGrid board: multieye keeps Kalibr's frame and "
                         "point ids (the identity to Kalibr's)")
    raise InputError(f"no OpenCV frame known for target type {target.kind!r}")
