"""A chessboard's inner corners in an image: OpenCV's two detectors, the refinement and a check.

``cv2.findChessboardCorners`` (the classic detector) and ``cv2.findChessboardCornersSB``
return the corners in their own orders (the two start from opposite corners of some boards);
:func:`locate` runs them in turn (:func:`search_order`), refines the corners at full size
(:func:`refine_grid`), checks that every corner is a saddle of the image (:func:`saddle_grid`),
that no saddle lies one square beyond the grid (:func:`whole_board`: not a board cut by the
image edge, shifted) and that each detector's grid is smooth (:func:`consistent_grid`);
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
>>> whole_board(gray, refined, board)                                       # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.imaging.straight_corners import SUBPIX_CRITERIA, refine_straightened
from multieye.imaging.targets import Chessboard, Target

__all__ = ["locate", "locate_board", "Located", "search_order", "quick_check", "find_chessboard", "refine_grid",
           "refine_corners", "corner_window", "consistent_grid", "saddle_grid", "whole_board", "min_spacing",
           "CLASSIC_FLAGS", "HALF_SIZE_SEARCH_ABOVE_PX", "MAX_SECOND_DIFFERENCE",
           "MIN_DEPARTURE_PX", "BEYOND_MAX_CORRELATION"]

F64 = NDArray[np.float64]

#: Images whose longer side has at least this many pixels are searched at half size first,
#: by either detector (the classic one 1.5x faster on 800 x 600 images, 5x on 1280 x 720;
#: SB 2.5-4x); the corners are then refined at full size, so accuracy is unchanged.  Until
#: issue 32 it was 640: on 640 x 480 images the half-size search is the slower (0.98 against
#: 2.5 CPU-ms per image on 400 rendered JPEGs with a 5 x 7 board; 4.8 against 6.0 on 40
#: hard views), the squares there being small, for the same boards and corners.
HALF_SIZE_SEARCH_ABOVE_PX = 800

#: The classic detector's flags: adaptive threshold on the normalised image (OpenCV's
#: default).  ``CALIB_CB_FAST_CHECK`` is not set for the first search: it rejects an image
#: without a board faster, but costs 2.5x on the images that show one (800 x 600 rendered
#: images: 5.7 against 2.2 ms) and, at half size, missed the board in 44 % of them;
#: calibration images nearly all show the board.  The second search sets it
#: (:func:`search_order`).
CLASSIC_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE

#: Largest departure of a corner's second difference along its row or column from the
#: smooth surface the others follow (:func:`consistent_grid`), as a fraction of the median
#: spacing (at least :data:`MIN_DEPARTURE_PX`), in a grid either detector found (SB's at
#: half size only: :func:`locate`); beyond it, the next search of :func:`search_order` runs.
MAX_SECOND_DIFFERENCE = 0.05

#: The least departure :func:`consistent_grid` flags, pixels: a right grid of small squares
#: (12-16 px) with blurred corners departed by up to 0.92 px on the renders of issue 32.
MIN_DEPARTURE_PX = 1.5

#: :func:`saddle_grid`: the circle a corner is checked on has this fraction of the distance
#: to its nearest grid neighbour as its radius (at least :data:`SADDLE_MIN_RADIUS_PX`), and
#: is sampled at :data:`SADDLE_SAMPLES` points.
SADDLE_RADIUS = 0.3
SADDLE_MIN_RADIUS_PX = 2.0
SADDLE_SAMPLES = 64
#: Least correlation of a corner's circle of greys with itself turned by half a turn.
SADDLE_MIN_CORRELATION = 0.3
#: :func:`whole_board`: a point one square beyond the grid whose correlation reaches this
#: is a corner of the board beyond the grid (the cut column's corner beyond SB's shifted
#: grid of issue 35: 1.00; the board's edge: about -1/3, -0.3 to -0.4 on that view; up to
#: 0.80 where the extension of a board bent by a 190-degree lens falls off the board,
#: tests/imaging/test_bent_boards.py's RIM view, so a beyond corner as weak as the 0.6 of
#: some real corners on such views is not seen).
BEYOND_MAX_CORRELATION = 0.9
#: :func:`whole_board`: near the image's edge the circle shrinks to fit in the image, down to
#: this fraction of the square it extends (at least :data:`SADDLE_MIN_RADIUS_PX`).
BEYOND_MIN_RADIUS = 0.1


def consistent_grid(points: F64, target: Target) -> bool:
    """Whether refined grid corners lie on a smooth grid.

    The second differences ``p[j-1] - 2 p[j] + p[j+1]`` along the rows form a field over
    (row, column) that perspective and lens distortion change smoothly in both directions
    (the columns' likewise).  Each value is compared with the quadratic surface in (row,
    column) fitted to the field's other values (:func:`_surface_departures`); none may
    depart by more than :data:`MAX_SECOND_DIFFERENCE` of the median spacing (at least
    :data:`MIN_DEPARTURE_PX`).  Fields of 7 values or fewer are compared with their row's
    median instead.

    A corner off by ``e`` moves the second differences around it by ``e`` to ``2 e``: the
    classic detector put a corner 12 px off on a blurred JPEG (yizhong_toolkit's 16.jpg,
    squares of 20 px) where SB found it; SB at half size put corners 5-9 px off on blurred
    rendered views (issue 32).  Until issue 32 each value was compared with its row's median:
    on a board seen close and steeply (squares of 17-50 px, a lens with k1 = -0.3) the
    second differences of a right grid drift along a row by 6-15 % of the spacing, and such
    boards went on to slower searches.  On the views rendered for that issue the surface
    leaves right grids within 1 px (4.6 % of the spacing at most where it exceeds 20 px) and
    misplaced ones 5 px and more off.  A departure flagged wrongly only costs the next
    search."""
    rows, cols = target.grid_shape()
    grid = points.reshape(rows, cols, 2)
    spacing = float(_median(_lengths(grid[:, 1:] - grid[:, :-1]).ravel(), 0))
    limit = max(MIN_DEPARTURE_PX, MAX_SECOND_DIFFERENCE * spacing)
    for g in (grid, grid.transpose(1, 0, 2)):
        if g.shape[1] < 3:
            continue
        d2 = g[:, :-2] - 2.0 * g[:, 1:-1] + g[:, 2:]
        if _surface_departures(d2).max() > limit:
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
    # the squared distances to the next corner down and to the right (the last row's and
    # column's: to the one before), the nearer of the two per corner, one root taken
    down, right = _squares(grid[1:] - grid[:-1]), _squares(grid[:, 1:] - grid[:, :-1])
    near = np.minimum(np.concatenate([down, down[-1:]]),
                      np.concatenate([right, right[:, -1:]], axis=1))
    radius = np.maximum(SADDLE_RADIUS * np.sqrt(near.ravel()), SADDLE_MIN_RADIUS_PX)
    return bool(np.all(_saddle_correlations(gray, points, radius) >= SADDLE_MIN_CORRELATION))


def _saddle_correlations(gray: NDArray[np.uint8], points: F64, radius: F64) -> F64:
    """Per point (N, 2), pixels: the correlation of the greys on a circle of ``radius``
    (N,) around it with themselves turned by half a turn (:func:`saddle_grid`).  Shape
    (N,)."""
    cos, sin = _circle(SADDLE_SAMPLES)
    u = (points[:, :1] + radius[:, None] * cos).astype(np.float32)
    v = (points[:, 1:] + radius[:, None] * sin).astype(np.float32)
    ring = cv2.remap(gray, u, v, cv2.INTER_LINEAR,       # whole greys: enough for the sign
                     borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
    ring -= np.add.reduce(ring, axis=1, keepdims=True) / SADDLE_SAMPLES      # the mean
    half = SADDLE_SAMPLES // 2                  # np.roll's result, without its overhead
    turned = np.concatenate([ring[:, half:], ring[:, :half]], axis=1)
    power = np.maximum(np.einsum("ij,ij->i", ring, ring), 1e-9)
    return np.einsum("ij,ij->i", ring, turned) / power


@lru_cache(maxsize=4)
def _circle(samples: int) -> tuple[F64, F64]:
    """Cosines and sines of ``samples`` angles evenly around the circle from 0, shape
    (samples,) each: the same arrays for every corner of every image (read only)."""
    phi = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    cos, sin = np.cos(phi), np.sin(phi)
    cos.flags.writeable = sin.flags.writeable = False
    return cos, sin


def whole_board(gray: NDArray[np.uint8], points: F64, target: Target) -> bool:
    """Whether the grid is the whole board: no saddle of the image one square beyond it.

    Each side of the grid is extended by one square along the rows and columns, by the
    parabola through the last three corners (``3 p[0] - 3 p[1] + p[2]``; linearly where
    there are two; the four diagonal corners left out); where such a point is in the image
    (its circle shrunk to fit, down to :data:`BEYOND_MIN_RADIUS` of the square), it must not
    be a saddle: its correlation (:func:`saddle_grid`'s, radius :data:`SADDLE_RADIUS` of the
    square it extends) below :data:`BEYOND_MAX_CORRELATION`.  One square beyond a whole board's outer corners lies
    the board's edge: its outer squares on one side, the margin or the background on the
    other (-1/3 for a black square and three white quadrants, whatever the margin).  Beyond
    a grid shifted by a row or column off a board cut by the image edge lies the board's
    next corner, a saddle where it is in the image (issue 35: SB at full size returned a
    6 x 9 grid of a board whose last column was cut, one column shifted onto the board's
    edge: 0.07 px PnP and 380 px off; it also fails :func:`saddle_grid`), as beyond a grid
    that is part of a larger board.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
    points : ndarray, shape (rows * cols, 2)
        Refined corners, pixels, row by row in either detector's order.
    target : Target
    """
    edge, inner, third, linear = _beyond_indices(*target.grid_shape())
    edge, inner = points[edge], points[inner]
    p = 3 * edge - 3 * inner + points[third]
    if linear.any():
        p[linear] = (2 * edge - inner)[linear]
    step = _lengths(edge - inner)
    h, w = gray.shape
    room = np.minimum(p, np.array([w - 1.0, h - 1.0]) - p).min(axis=1) - 1.0
    radius = np.minimum(SADDLE_RADIUS * step, room)
    seen = radius >= np.maximum(BEYOND_MIN_RADIUS * step, SADDLE_MIN_RADIUS_PX)
    if not seen.any():
        return True
    return bool(np.all(_saddle_correlations(gray, p[seen], radius[seen]) < BEYOND_MAX_CORRELATION))


@lru_cache(maxsize=32)
def _beyond_indices(rows: int, cols: int) -> tuple[NDArray[np.int64], ...]:
    """For :func:`whole_board`, per point one square beyond a grid of ``rows`` x ``cols``
    (the first row, the last, the first column, the last, in turn): the indices (row by
    row) of the grid's corner it extends, of the next one inward and of the one after
    (the last there is where the grid has 2), and whether the extension is linear (a grid
    of 2 along that direction).  Four arrays of shape (2 cols + 2 rows,), read only."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    parts: list[list] = [[], [], [], []]
    for g in (idx, idx.T):
        for edge, inner, third in ((g[0], g[1], g[min(2, len(g) - 1)]),
                                   (g[-1], g[-2], g[max(-3, -len(g))])):
            for part, value in zip(parts, (edge, inner, third, np.full(len(edge), len(g) < 3))):
                part.append(value)
    out = tuple(np.concatenate(part) for part in parts)
    for a in out:
        a.flags.writeable = False
    return out


def _surface_departures(d2: F64) -> F64:
    """Per value of the field ``d2`` (R, n, 2): its distance from the quadratic surface in
    (row, column) fitted by least squares to the other values (the leave-one-out residual
    ``r / (1 - h)``, ``h`` the fit's leverage); from its row's median where the field has
    7 values or fewer.  Shape (R, n)."""
    R, n = d2.shape[:2]
    if R * n <= 7:
        return _lengths(d2 - _median(d2, 1)[:, None])
    hat, leverage = _quadratic_hat(R, n)
    y = d2.reshape(R * n, 2)
    return (_lengths(y - hat @ y) / (1.0 - leverage)).reshape(R, n)


@lru_cache(maxsize=32)
def _quadratic_hat(R: int, n: int) -> tuple[F64, F64]:
    """The hat matrix of a least-squares quadratic in (row, column) over an R x n grid of
    values, and its diagonal (the leverages)."""
    r, j = np.meshgrid(np.arange(R) - (R - 1) / 2, np.arange(n) - (n - 1) / 2, indexing="ij")
    r, j = r.ravel(), j.ravel()
    A = np.column_stack([np.ones_like(r), r, j, r * r, r * j, j * j])
    hat = A @ np.linalg.pinv(A)
    return hat, np.diag(hat).copy()


def _median(a: F64, axis: int) -> F64:
    """``np.median(a, axis)`` by a sort (the same values, less overhead on small arrays)."""
    s = np.sort(a, axis=axis)
    n = s.shape[axis]
    return (s.take((n - 1) // 2, axis=axis) + s.take(n // 2, axis=axis)) / 2


def _lengths(v: F64) -> F64:
    """Lengths of the 2-vectors along the last axis (``np.linalg.norm(v, axis=-1)``, with
    less overhead on the small arrays of one board)."""
    return np.sqrt(_squares(v))


def _squares(v: F64) -> F64:
    """Squared lengths of the 2-vectors along the last axis."""
    return np.einsum("...i,...i->...", v, v)


def search_order(gray: NDArray[np.uint8]) -> tuple[tuple[str, bool], ...]:
    """The searches :func:`locate` makes, in order: ``(detector, at half size)``.

    On images of :data:`HALF_SIZE_SEARCH_ABOVE_PX` and more: the classic detector at half
    size; where it fails, the classic detector at full size behind OpenCV's quick check
    (``"quick"``: ``cv2.checkChessboard``, :func:`quick_check`), SB at half and at full size,
    and last the classic detector at full size, only where the quick check turned the image
    down (:func:`locate`).  The quick check bounds the cost of a
    full-size classic search that finds nothing: on blurred, steep or small boards among
    clutter it took 60-650 ms per 960 x 720 image before giving up (the quick check 4-9 ms),
    where SB then found the board in 40-70 ms; where the quick check rejects a board the
    classic detector would find, SB or the last search finds it, so no board is lost.
    Smaller images: the classic detector, then SB, at full size."""
    if max(gray.shape) < HALF_SIZE_SEARCH_ABOVE_PX:
        return (("classic", False), ("sb", False))
    return (("classic", True), ("quick", False), ("sb", True), ("sb", False), ("classic", False))


def find_chessboard(gray: NDArray[np.uint8], target: Chessboard, *,
                    detector: str | None = None, half: bool | None = None) -> F64 | None:
    """Unrefined inner corners, shape (rows * cols, 2), full-size pixels, in the order of the
    detector that found them.

    ``detector`` ("classic", "quick": the classic one where :func:`quick_check` passes, or
    "sb")
    and ``half`` (search the image halved) restrict the searches of :func:`search_order` to
    those; the first that finds the board wins.

    Raises
    ------
    ValueError
        ``detector`` is none of those (a restriction that matches no search would otherwise
        read as a board not found)."""
    if detector not in (None, "classic", "quick", "sb"):
        raise ValueError(f"detector must be 'classic', 'quick' or 'sb', not {detector!r}")
    size = (target.cols, target.rows)
    for name, at_half in search_order(gray):
        if (detector is not None and name != detector) or (half is not None and at_half != half):
            continue
        image = cv2.resize(gray, (gray.shape[1] // 2, gray.shape[0] // 2),
                           interpolation=cv2.INTER_AREA) if at_half else gray
        if name == "sb":
            found, corners = cv2.findChessboardCornersSB(image, size, flags=0)
        elif name == "quick" and not quick_check(image, target):
            continue
        else:
            found, corners = cv2.findChessboardCorners(image, size, flags=CLASSIC_FLAGS)
        if found:
            corners = corners.reshape(-1, 2).astype(np.float64)
            return 2.0 * corners + 0.5 if at_half else corners     # pixel centres
    return None


def quick_check(gray: NDArray[np.uint8], target: Chessboard) -> bool:
    """OpenCV's quick test whether the image may show the board (``cv2.checkChessboard``,
    the test ``CALIB_CB_FAST_CHECK`` makes): a few ms, where a full-size classic search that
    finds nothing can take seconds on 1920 x 1080 images."""
    return bool(cv2.checkChessboard(gray, (target.cols, target.rows)))


def locate(gray: NDArray[np.uint8], target: Chessboard) -> F64 | None:
    """The board's inner corners refined at full size, or None: :func:`locate_board`'s
    corners."""
    return locate_board(gray, target).corners


@dataclass(frozen=True)
class Located:
    """What :func:`locate_board` found.

    Attributes
    ----------
    corners : ndarray, shape (rows * cols, 2), or None
        The board's inner corners, pixels, in the order of the detector that found them;
        None when no grid passed the checks.
    beyond : bool
        No grid passed, and a grid was found with a saddle of the image one square beyond
        it (:func:`whole_board` refused it): the board runs past the image's edge, or it
        has more inner corners than the target states.
    """

    corners: F64 | None
    beyond: bool = False


def locate_board(gray: NDArray[np.uint8], target: Chessboard) -> Located:
    """The board's inner corners refined at full size (:func:`refine_grid`), in the order of
    the detector that found them, or None.

    The searches of :func:`search_order` run until one finds the board on a smooth grid
    (:func:`consistent_grid`) of saddles of the image (:func:`saddle_grid`, every grid) with
    no saddle one square beyond it (:func:`whole_board`, every grid: a board cut by the
    image edge is not found rather than found shifted by a row or column); a
    grid of saddles that is not smooth sends the search on, whichever search found it but SB
    at full size, whose corners are kept (SB's were all kept until issue 32: at half size,
    on blurred rendered views of 960 x 720, it put corners 5-9 px off, which the grid check
    sees; at full size its corners stayed within 0.5 px on every view rendered for that
    issue, also on squares of 8 px, whose corner noise the check's 1 px can take for a
    misplaced corner; on rendered views of a 190-degree lens it put a row on the edge of the
    board's margin, 21 px off, which the saddle check sees).  A board the classic detector
    finds at half size is not searched again at full size, however small its squares: a
    corner it misplaces there (5 px on 640 x 480 images with squares of 8.6 half-size
    pixels) breaks the grid, and the full-size search follows.  When no search gives a grid
    that passes both checks, the first grid of saddles that only the smoothness check
    refused is taken: a board bent by a lens near 180 degrees (boofcv_fisheye's 20.jpg and
    22.jpg, which SB does not find)."""
    order = search_order(gray)
    bent, beyond = None, False
    for detector, half in order:
        if (detector, half) == ("classic", False) and ("quick", False) in order \
                and quick_check(gray, target):
            continue                  # the quick search ran this one already
        raw = find_chessboard(gray, target, detector=detector, half=half)
        if raw is None:
            continue
        corners = refine_grid(gray, raw, target)
        if not whole_board(gray, corners, target):
            beyond = True
            continue
        if not saddle_grid(gray, corners, target):
            continue
        if (detector == "sb" and not half) or consistent_grid(corners, target):
            return Located(corners)
        bent = corners if bent is None else bent
    return Located(bent, beyond=bent is None and beyond)


def min_spacing(points: NDArray, target: Target) -> float:
    """Smallest distance between neighbouring grid points, pixels."""
    rows, cols = target.grid_shape()
    grid = np.asarray(points, dtype=np.float64).reshape(rows, cols, 2)
    down, right = grid[1:] - grid[:-1], grid[:, 1:] - grid[:, :-1]
    # the square root of the least square length: the least length, one root taken
    return float(np.sqrt(min(_squares(down).min(), _squares(right).min())))


def corner_window(points: F64, target: Target) -> int:
    """Half-size of the cornerSubPix window: 40 % of the smallest neighbour distance."""
    return int(min(max(0.4 * min_spacing(points, target), 2), 11))


def refine_grid(gray: NDArray[np.uint8], points: F64, target: Target) -> F64:
    """Grid corners refined by ``cornerSubPix`` in a window of 40 % of the smallest square
    (:func:`corner_window`), measured on the refined corners: when the unrefined corners
    (found at half size, say) gave another window, they are refined again in that one.
    Then once more on patches whose edges the local quadratic of the grid straightens
    (:func:`multieye.imaging.straight_corners.refine_straightened`): ``cornerSubPix``
    alone puts corners whose edges the lens bends off them towards the edges' convex side,
    outward of the image centre under barrel distortion (``benchmarks/corner_bias.py``)."""
    window = corner_window(points, target)
    refined = refine_corners(gray, points, window)
    again = corner_window(refined, target)
    if again != window:
        refined, window = refine_corners(gray, refined, again), again
    rows, cols = target.grid_shape()
    if min(rows, cols) < 2:
        return refined
    return refine_straightened(gray, refined, rows, cols, window)


def refine_corners(gray: NDArray[np.uint8], points: F64, half: int) -> F64:
    """``cv2.cornerSubPix`` of ``points`` (N, 2), pixels, in a (2 half + 1) px window."""
    pts = points.astype(np.float32).reshape(-1, 1, 2)
    cv2.cornerSubPix(gray, pts, (half, half), (-1, -1), SUBPIX_CRITERIA)
    return pts.reshape(-1, 2).astype(np.float64)
