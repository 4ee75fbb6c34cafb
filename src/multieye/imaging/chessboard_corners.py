"""A chessboard's inner corners in an image: OpenCV's two detectors, the refinement and a check.

``cv2.findChessboardCorners`` (the classic detector) and ``cv2.findChessboardCornersSB``
return the corners in their own orders (the two start from opposite corners of some boards);
:func:`locate` runs them in turn (:func:`search_order`), refines the corners at full size
(:func:`refine_grid`), checks that every corner is a saddle of the image (:func:`saddle_grid`)
and that the classic detector's grid is smooth (:func:`consistent_grid`);
:func:`multieye.imaging.detect.detect` then puts them in the canonical order, so that the ids
do not depend on the detector.  OpenCV's frames for each detector's order:
:mod:`multieye.imaging.board_frames`.

Synopsis
--------
>>> corners = locate(gray, board)                                           # doctest: +SKIP
>>> raw = find_chessboard(gray, board, detector="classic", half=False)      # doctest: +SKIP
>>> refined = refine_grid(gray, raw, board)                                 # doctest: +SKIP
>>> consistent_grid(refined, board)                                         # doctest: +SKIP
>>> saddle_grid(gray, refined, board)                                       # doctest: +SKIP
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.imaging.targets import Chessboard, Target

__all__ = ["locate", "search_order", "find_chessboard", "refine_grid", "refine_corners",
           "corner_window", "consistent_grid", "saddle_grid", "min_spacing", "CLASSIC_FLAGS",
           "HALF_SIZE_SEARCH_ABOVE_PX", "MAX_SECOND_DIFFERENCE"]

F64 = NDArray[np.float64]

#: Images whose longer side has at least this many pixels are searched at half size first,
#: by either detector (the classic one 1.5x faster on 800 x 600 images, 5x on 1280 x 720;
#: SB 2.5-4x); the corners are then refined at full size, so accuracy is unchanged.
HALF_SIZE_SEARCH_ABOVE_PX = 640

#: The classic detector's flags: adaptive threshold on the normalised image (OpenCV's
#: default).  ``CALIB_CB_FAST_CHECK`` is not set: it rejects an image without a board faster,
#: but costs 2.5x on the images that show one (800 x 600 rendered images: 5.7 against 2.2 ms)
#: and, at half size, missed the board in 44 % of them; calibration images nearly all show
#: the board.
CLASSIC_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE

#: Largest departure of a corner's second difference along its row or column from the
#: median of that row's (column's), as a fraction of the median spacing (at least 1 px), in a
#: grid the classic detector found; beyond it, the next search of :func:`search_order` runs
#: (the classic detector at full size after half size, then SB).
MAX_SECOND_DIFFERENCE = 0.05

#: :func:`saddle_grid`: the circle a corner is checked on has this fraction of the distance
#: to its nearest grid neighbour as its radius (at least :data:`SADDLE_MIN_RADIUS_PX`), and
#: is sampled at :data:`SADDLE_SAMPLES` points.
SADDLE_RADIUS = 0.3
SADDLE_MIN_RADIUS_PX = 2.0
SADDLE_SAMPLES = 64
#: Least correlation of a corner's circle of greys with itself turned by half a turn.
SADDLE_MIN_CORRELATION = 0.3


def consistent_grid(points: F64, target: Target) -> bool:
    """Whether refined grid corners lie on a smooth grid: along every row and column the
    second differences ``p[j-1] - 2 p[j] + p[j+1]`` (which perspective and lens distortion
    change slowly) stay within :data:`MAX_SECOND_DIFFERENCE` of the spacing of their median.

    A corner off by ``e`` moves the second differences around it by ``e`` to ``2 e``: the
    classic detector put a corner 12 px off on a blurred JPEG (yizhong_toolkit's 16.jpg, squares of
    20 px) where SB found it. A departure flagged wrongly only costs the next search."""
    rows, cols = target.grid_shape()
    grid = points.reshape(rows, cols, 2)
    spacing = float(_median(_lengths(grid[:, 1:] - grid[:, :-1]).ravel(), 0))
    limit = max(1.0, MAX_SECOND_DIFFERENCE * spacing)
    for g in (grid, grid.transpose(1, 0, 2)):
        if g.shape[1] < 3:
            continue
        d2 = g[:, :-2] - 2.0 * g[:, 1:-1] + g[:, 2:]
        if _lengths(d2 - _median(d2, 1)[:, None]).max() > limit:
            return False
    return True


def saddle_grid(gray: NDArray[np.uint8], points: F64, target: Target) -> bool:
    """Whether every corner is a saddle of the image, as a chessboard's inner corner is: on
    a circle around it (radius :data:`SADDLE_RADIUS` of the distance to its nearest grid
    neighbour) the grey repeats itself after a half turn (the squares across the corner have
    the same colour), which the correlation of the circle's greys with themselves turned by
    half a turn measures: at least :data:`SADDLE_MIN_CORRELATION` at every corner.  A point
    on an edge (the two sides differ: near -1) or inside a square (noise: near 0) fails it.

    Unlike :func:`consistent_grid` this holds however bent the board's image is (a fisheye
    near 180 degrees: 0.6 and more at every corner of boofcv_fisheye's grids, real and
    rendered), and it catches what SB finds wrong there: a row of corners put on the edge
    between the squares and the board's margin, 21 px off, on rendered 190-degree views
    (-0.37; ``benchmarks/bench_boofcv_reference.py``)."""
    rows, cols = target.grid_shape()
    grid = points.reshape(rows, cols, 2)
    near = np.full((rows, cols), np.inf)
    down, right = _lengths(grid[1:] - grid[:-1]), _lengths(grid[:, 1:] - grid[:, :-1])
    near[1:], near[:-1] = np.minimum(near[1:], down), np.minimum(near[:-1], down)
    near[:, 1:], near[:, :-1] = np.minimum(near[:, 1:], right), np.minimum(near[:, :-1], right)
    radius = np.maximum(SADDLE_RADIUS * near.ravel(), SADDLE_MIN_RADIUS_PX)
    phi = np.linspace(0.0, 2 * np.pi, SADDLE_SAMPLES, endpoint=False)
    u = (points[:, :1] + radius[:, None] * np.cos(phi)).astype(np.float32)
    v = (points[:, 1:] + radius[:, None] * np.sin(phi)).astype(np.float32)
    ring = cv2.remap(gray, u, v, cv2.INTER_LINEAR,       # whole greys: enough for the sign
                     borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
    ring -= ring.mean(axis=1, keepdims=True)
    turned = np.roll(ring, SADDLE_SAMPLES // 2, axis=1)
    power = np.maximum(np.einsum("ij,ij->i", ring, ring), 1e-9)
    return bool(np.all(np.einsum("ij,ij->i", ring, turned) / power >= SADDLE_MIN_CORRELATION))


def _median(a: F64, axis: int) -> F64:
    """``np.median(a, axis)`` by a sort (the same values, less overhead on small arrays)."""
    s = np.sort(a, axis=axis)
    n = s.shape[axis]
    return (s.take((n - 1) // 2, axis=axis) + s.take(n // 2, axis=axis)) / 2


def _lengths(v: F64) -> F64:
    """Lengths of the 2-vectors along the last axis (``np.linalg.norm(v, axis=-1)``, with
    less overhead on the small arrays of one board)."""
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def search_order(gray: NDArray[np.uint8]) -> tuple[tuple[str, bool], ...]:
    """The searches :func:`locate` makes, in order: ``(detector, at half size)``; the classic
    detector before SB, each at half size first on images of
    :data:`HALF_SIZE_SEARCH_ABOVE_PX` and more."""
    halves = (True, False) if max(gray.shape) >= HALF_SIZE_SEARCH_ABOVE_PX else (False,)
    return tuple((detector, half) for detector in ("classic", "sb") for half in halves)


def find_chessboard(gray: NDArray[np.uint8], target: Chessboard, *,
                    detector: str | None = None, half: bool | None = None) -> F64 | None:
    """Unrefined inner corners, shape (rows * cols, 2), full-size pixels, in the order of the
    detector that found them.

    ``detector`` ("classic" or "sb") and ``half`` (search the image halved) restrict the
    searches of :func:`search_order` to those; the first that finds the board wins.

    Raises
    ------
    ValueError
        ``detector`` is neither "classic" nor "sb" (a restriction that matches no search
        would otherwise read as a board not found)."""
    if detector not in (None, "classic", "sb"):
        raise ValueError(f"detector must be 'classic' or 'sb', not {detector!r}")
    size = (target.cols, target.rows)
    for name, at_half in search_order(gray):
        if (detector is not None and name != detector) or (half is not None and at_half != half):
            continue
        image = cv2.resize(gray, (gray.shape[1] // 2, gray.shape[0] // 2),
                           interpolation=cv2.INTER_AREA) if at_half else gray
        if name == "classic":
            found, corners = cv2.findChessboardCorners(image, size, flags=CLASSIC_FLAGS)
        else:
            found, corners = cv2.findChessboardCornersSB(image, size, flags=0)
        if found:
            corners = corners.reshape(-1, 2).astype(np.float64)
            return 2.0 * corners + 0.5 if at_half else corners     # pixel centres
    return None


def locate(gray: NDArray[np.uint8], target: Chessboard) -> F64 | None:
    """The board's inner corners refined at full size (:func:`refine_grid`), in the order of
    the detector that found them, or None.

    The searches of :func:`search_order` run until one finds the board; either detector's
    corners are kept only if every one is a saddle of the image (:func:`saddle_grid`), the
    classic detector's only on a smooth grid too (:func:`consistent_grid`), else the next
    search runs.  A board the classic detector finds at half size is not searched again at
    full size, however small its squares: a corner it misplaces there (5 px on 640 x 480
    images with squares of 8.6 half-size pixels) breaks the grid, and the full-size search
    follows.  When no search gives a grid that passes its checks, the first classic grid of
    saddles that only the smoothness check refused is taken: a board bent by a lens near
    180 degrees (boofcv_fisheye's 20.jpg and 22.jpg, which SB does not find)."""
    bent = None
    for detector, half in search_order(gray):
        raw = find_chessboard(gray, target, detector=detector, half=half)
        if raw is None:
            continue
        corners = refine_grid(gray, raw, target)
        if not saddle_grid(gray, corners, target):
            continue
        if detector == "sb" or consistent_grid(corners, target):
            return corners
        bent = corners if bent is None else bent
    return bent


def min_spacing(points: NDArray, target: Target) -> float:
    """Smallest distance between neighbouring grid points, pixels."""
    rows, cols = target.grid_shape()
    grid = np.asarray(points, dtype=np.float64).reshape(rows, cols, 2)
    return float(min(_lengths(grid[1:] - grid[:-1]).min(), _lengths(grid[:, 1:] - grid[:, :-1]).min()))


def corner_window(points: F64, target: Target) -> int:
    """Half-size of the cornerSubPix window: 40 % of the smallest neighbour distance."""
    return int(np.clip(0.4 * min_spacing(points, target), 2, 11))


def refine_grid(gray: NDArray[np.uint8], points: F64, target: Target) -> F64:
    """Grid corners refined by ``cornerSubPix`` in a window of 40 % of the smallest square
    (:func:`corner_window`), measured on the refined corners: when the unrefined corners
    (found at half size, say) gave another window, they are refined again in that one."""
    window = corner_window(points, target)
    refined = refine_corners(gray, points, window)
    again = corner_window(refined, target)
    return refined if again == window else refine_corners(gray, refined, again)


def refine_corners(gray: NDArray[np.uint8], points: F64, half: int) -> F64:
    """``cv2.cornerSubPix`` of ``points`` (N, 2), pixels, in a (2 half + 1) px window."""
    pts = points.astype(np.float32).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    cv2.cornerSubPix(gray, pts, (half, half), (-1, -1), criteria)
    return pts.reshape(-1, 2).astype(np.float64)
