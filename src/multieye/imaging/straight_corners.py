"""Chessboard corners refined where the lens's bending of the squares' edges is undone.

``cv2.cornerSubPix`` puts a corner where the lines through its window's edge pixels, each
perpendicular to the grey-level gradient there, meet best.  Where the lens bends the edges
(any radial distortion, away from the image centre), those tangent lines pass on the convex
side of the corner, and the refined corner lies off it by about the edge's curvature times
the window's mean square radius: outward of the image centre under barrel distortion, by a
few thousandths of a pixel with the windows of :func:`~multieye.imaging.chessboard_corners.
corner_window` (``benchmarks/corner_bias.py``).  That is a twentieth of the corner noise of
a good image, but of one sign on every corner: the board looks nearer than it is, and with
many images the pose of a camera is off by more than its reported uncertainty
(docs/results/nees.md).

:func:`refine_straightened` takes the bending out before ``cornerSubPix`` sees the corner.
Around each corner the board's grid coordinates are mapped to the image by the quadratic
(per grid axis) through the 3 x 3 block of refined corners around it (the block moved
inward at the grid's border): it passes through the corners of the row and the column that
meet there, so the edges between them, as the lens bends them, follow it to second order.
Each pixel of the patch around the corner takes the image's grey displaced by the bend of
the edge it is nearer (:func:`_bend`: that row's or column's second-order term at the
pixel's offset along it, the same across the edge, hundredths of a pixel), to first order
with central differences on the whole pixels: a patch that equals the image but for the
bend, its edges straight, in the same window.  ``cornerSubPix`` refines the corner there
and the result is mapped back.  Under a pinhole lens the edges are straight already and the
three corners of a row lie on its line: the bend moves the patch only along its edges.  The
whole quadratic map would also vary the displacement across each edge (by the other grid
line's bend), which moves a blurred edge's centre by about that second derivative times
the blur's variance: on exact renders an overshoot that grew with the blur.

``cv2.remap`` is not used to move the patch: it puts the sample positions on a grid of 1/32
pixel (``INTER_BITS``), which turned the hundredths-of-a-pixel bend into steps and moved the
corners inward by 1-2 thousandths of a pixel beyond the truth on exact renders.

Synopsis
--------
>>> refined = refine_straightened(gray, corners, rows, cols, half)          # doctest: +SKIP
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["refine_straightened", "MARGIN_PX", "SUBPIX_CRITERIA"]

F64 = NDArray[np.float64]

#: Pixels of each patch beyond the refinement window (``cornerSubPix`` reads one pixel
#: beyond it and interpolates, and the corner may move a little).
MARGIN_PX = 3
#: ``cv2.cornerSubPix``'s stopping rule, here and in
#: :func:`multieye.imaging.chessboard_corners.refine_corners`.
SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)


def _edge_frames(points: F64, rows: int, cols: int) -> F64:
    """Per corner the grid's local frame, shape (N, 10): the inverse Jacobian of the
    mapping from the grid's (row, column) indices to pixels (columns 0-3: its rows' entries,
    index steps per pixel), the Jacobian's columns' lengths (4, 5: pixels per square), and
    the second derivatives of that mapping along the rows' index (6, 7: x and y) and along
    the columns' (8, 9), pixels per square squared.

    Along each index the mapping is the quadratic through the block of 3 corners around the
    corner (moved inward at the grid's border; a line where the grid has 2)."""
    g = points.reshape(rows, cols, 2)
    da, ha = _differences(g, 0)
    db, hb = _differences(np.ascontiguousarray(g.transpose(1, 0, 2)), 0)
    da, ha = da.reshape(-1, 2), ha.reshape(-1, 2)
    db, hb = db.transpose(1, 0, 2).reshape(-1, 2), hb.transpose(1, 0, 2).reshape(-1, 2)
    inv = np.linalg.inv(np.stack([da, db], axis=-1))                  # (N, a|b, d)
    return np.column_stack([inv.reshape(-1, 4), np.hypot(da[:, 0], da[:, 1]),
                            np.hypot(db[:, 0], db[:, 1]), ha, hb])


def _bend(ux: NDArray, uy: NDArray, frames: NDArray) -> tuple[NDArray, NDArray]:
    """The bend (x and y, pixels) at pixel offsets ``ux``, ``uy`` (N, ...) from each corner
    (``frames`` (N, 10) of :func:`_edge_frames`): near the edge along the columns' index
    (the grid's row through the corner) the displacement of that row's point at the same
    column offset, ``H_bb db^2 / 2``, the same across the edge; nearer the other edge its
    ``H_aa da^2 / 2``.  So each edge is moved onto its tangent as a whole: a displacement
    that varied across an edge (the whole quadratic map's ``H_aa da^2 / 2`` near the row's
    edge) would move its blurred profile's centre by about that second derivative times the
    blur's variance.  :func:`_straightened_mosaic` computes the same per pixel of the
    patches."""
    f = frames.T
    a = f[0] * ux + f[1] * uy
    b = f[2] * ux + f[3] * uy
    near_row = np.abs(a) * f[4] < np.abs(b) * f[5]
    a2, b2 = 0.5 * a * a, 0.5 * b * b
    return (np.where(near_row, f[8] * b2, f[6] * a2),
            np.where(near_row, f[9] * b2, f[7] * a2))


def _differences(g: F64, axis: int = 0) -> tuple[F64, F64]:
    """First and second derivative along the first axis (rows) of the quadratic through
    each point's block of 3 (moved inward at the border; with 2 points the line, no bend),
    at every point of ``g`` (R, C, 2)."""
    if len(g) == 2:
        return np.broadcast_to(g[1] - g[0], g.shape), np.zeros_like(g)
    d, h = np.empty_like(g), np.empty_like(g)
    d[1:-1] = 0.5 * (g[2:] - g[:-2])
    d[0] = -1.5 * g[0] + 2.0 * g[1] - 0.5 * g[2]
    d[-1] = 1.5 * g[-1] - 2.0 * g[-2] + 0.5 * g[-3]
    h[1:-1] = g[2:] - 2.0 * g[1:-1] + g[:-2]
    h[0], h[-1] = h[1], h[-2]
    return d, h


def _gather(gray: NDArray[np.uint8], centres: NDArray[np.int64], r: int) -> NDArray[np.float32]:
    """The (2 r + 1)-pixel squares of ``gray`` around the whole pixels ``centres`` (N, 2),
    shape (N, 2 r + 1, 2 r + 1), as float32; past the image's edge its border pixels
    repeated."""
    h, w = gray.shape
    side = 2 * r + 1
    lo, hi = centres.min(axis=0), centres.max(axis=0)
    if (lo.min() >= r and hi[0] < w - r and hi[1] < h - r and gray.dtype == np.uint8
            and gray.flags.c_contiguous):
        # every square inside: a strided view of the squares' corners, indexed
        windows = np.ndarray((h - 2 * r, w - 2 * r, side, side), np.uint8, gray, 0, (w, 1, w, 1))
        return windows[centres[:, 1] - r, centres[:, 0] - r].astype(np.float32)
    reach = np.arange(-r, r + 1)
    iy = np.minimum(np.maximum(centres[:, 1:] + reach, 0), h - 1)     # (N, side)
    ix = np.minimum(np.maximum(centres[:, :1] + reach, 0), w - 1)
    return gray[iy[:, :, None], ix[:, None, :]].astype(np.float32)


def _mosaic_shape(n: int) -> tuple[int, int]:
    """Rows and columns of tiles of the mosaic that holds ``n`` tiles."""
    per_row = math.ceil(math.sqrt(n))
    return math.ceil(n / per_row), per_row


def _straightened_mosaic(gray: NDArray[np.uint8], base: NDArray[np.int64],
                         shift: NDArray[np.float32], frames: NDArray[np.float32],
                         t: int) -> NDArray[np.float32]:
    """The patches of :func:`refine_straightened` (side ``2 t + 1`` around the whole pixels
    ``base`` (N, 2), ``shift = base - points``, ``frames`` of :func:`_edge_frames`, float32),
    each moved by its bend, laid out in one image: tile k at row ``k // per_row``, column
    ``k % per_row`` (:func:`_mosaic_shape`), the places beyond the last tile holding copies
    of the first.

    The arithmetic is :func:`_bend`'s per pixel, in float32 and in the same order, with
    fewer passes over the pixels: the nearer edge is chosen once for both components, by a
    masked copy (``cv2.copyTo``, not ``np.where``), and the factors 1/2 of the bend and of
    the central difference are moved onto the per-corner second derivatives (exact: powers
    of two)."""
    n = len(base)
    rows_, per_row = _mosaic_shape(n)
    side = 2 * t + 1
    order = np.arange(rows_ * per_row)
    order[n:] = 0                                               # copies of the first tile
    f = np.concatenate([frames[:, :6], 0.25 * frames[:, 6:], shift], axis=1)[order].T
    f = f[:, :, None, None]                                     # per tile, against pixels
    off = np.arange(-t, t + 1, dtype=np.float32)
    ux, uy = off + f[10, :, :, :1], (off + f[11, :, 0, :1])[:, :, None]   # (M, 1|side, side|1)
    a = f[0] * ux + f[1] * uy                                   # (M, side, side)
    b = f[2] * ux + f[3] * uy
    mask = (np.abs(a) * f[4] < np.abs(b) * f[5]).view(np.uint8).reshape(-1, side)
    s = cv2.copyTo(b.reshape(-1, side), mask, a.reshape(-1, side)).reshape(a.shape)
    s *= s                                    # the offset along the nearer edge, squared
    block = _gather(gray, base[order], t + 1)
    tiles = block[:, 1:-1, 1:-1].copy()
    for i, (ahead, behind) in enumerate(((block[:, 1:-1, 2:], block[:, 1:-1, :-2]),
                                         (block[:, 2:, 1:-1], block[:, :-2, 1:-1]))):
        step = f[6 + i] * s                   # half the bend: 1/4 of H_aa da^2, per pixel
        cv2.copyTo((f[8 + i] * s).reshape(-1, side), mask, step.reshape(-1, side))
        step *= ahead - behind
        tiles += step
    mosaic = tiles.reshape(rows_, per_row, side, side).transpose(0, 2, 1, 3)
    return np.ascontiguousarray(mosaic).reshape(rows_ * side, per_row * side)


def refine_straightened(gray: NDArray[np.uint8], points: F64, rows: int, cols: int,
                        half: int) -> F64:
    """Grid corners refined by ``cornerSubPix`` on patches whose edges are straightened
    (module docstring).

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
    points : ndarray, shape (rows * cols, 2)
        The grid's corners, pixels, row by row, already refined (they place the patches and
        the mapping: an error of a few hundredths of a pixel changes the result by far less).
    rows, cols : int
        The grid's shape, at least 2 each.
    half : int
        Half-size of ``cornerSubPix``'s window, pixels.

    Returns
    -------
    ndarray, shape (rows * cols, 2)
        Pixels.

    Notes
    -----
    The patch of corner ``p`` is sampled on the whole pixels around it: its pixel at offset
    ``x`` from ``round(p)`` (offset ``u = x + round(p) - p`` from ``p``) takes the image's
    grey at ``p + u + t(u)``, ``t`` the bend (:func:`_edge_frames`, :func:`_bend`), as
    ``I + t . grad I`` with central differences; the patch's corner ``p + u*`` goes back to
    ``p + u* + t(u*)``.  The patches are refined in one call, side by side in one image
    (:func:`_straightened_mosaic`)."""
    n = len(points)
    frames = _edge_frames(points, rows, cols).astype(np.float32)
    t = half + MARGIN_PX
    side = 2 * t + 1
    base = np.rint(points).astype(np.int64)
    shift = (base - points).astype(np.float32)                        # (N, 2)
    mosaic = _straightened_mosaic(gray, base, shift, frames, t)
    per_row = _mosaic_shape(n)[1]
    k = np.arange(n)
    centre = np.empty((n, 2))
    centre[:, 0], centre[:, 1] = (k % per_row) * side + t, (k // per_row) * side + t
    pts = (centre - shift).astype(np.float32).reshape(-1, 1, 2)
    cv2.cornerSubPix(mosaic, pts, (half, half), (-1, -1), SUBPIX_CRITERIA)
    u = pts.reshape(-1, 2).astype(np.float64) - centre + shift
    back = np.column_stack(_bend(u[:, 0], u[:, 1], frames.astype(np.float64)))
    return points + u + back
