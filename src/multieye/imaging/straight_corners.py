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


def _edge_frames(points: F64, rows: int, cols: int) -> tuple[F64, F64, F64, F64]:
    """Per corner the grid's local frame: the inverse Jacobian of the mapping from the
    grid's (row, column) indices to pixels (N, 2, 2: index steps per pixel), the second
    derivatives of that mapping along the rows' index and along the columns' (N, 2 each:
    pixels per square squared), and the Jacobian's columns' lengths stacked (N, 2).

    Along each index the mapping is the quadratic through the block of 3 corners around the
    corner (moved inward at the grid's border; a line where the grid has 2)."""
    g = points.reshape(rows, cols, 2)
    da, ha = _differences(g, 0)
    db, hb = _differences(g, 1)
    da, db, ha, hb = (x.reshape(-1, 2) for x in (da, db, ha, hb))
    jac = np.stack([da, db], axis=-1)                                 # (N, d, a|b)
    return np.linalg.inv(jac), ha, hb, np.stack([np.hypot(*da.T), np.hypot(*db.T)], axis=1)


def _bend(ux: NDArray, uy: NDArray, frames: tuple) -> tuple[NDArray, NDArray]:
    """The bend (x and y, pixels) at pixel offsets ``ux``, ``uy`` (broadcast against
    (N, 1, 1)) from each corner: near the edge along the columns' index (the grid's row
    through the corner) the displacement of that row's point at the same column offset,
    ``H_bb db^2 / 2``, the same across the edge; nearer the other edge its ``H_aa da^2 /
    2``.  So each edge is moved onto its tangent as a whole: a displacement that varied
    across an edge (the whole quadratic map's ``H_aa da^2 / 2`` near the row's edge) would
    move its blurred profile's centre by about that second derivative times the blur's
    variance."""
    inv, ha, hb, lengths = frames
    c = lambda x: x[:, None, None]  # noqa: E731  (per corner, against the offsets)
    a = c(inv[:, 0, 0]) * ux + c(inv[:, 0, 1]) * uy
    b = c(inv[:, 1, 0]) * ux + c(inv[:, 1, 1]) * uy
    near_row = np.abs(a) * c(lengths[:, 0]) < np.abs(b) * c(lengths[:, 1])
    a2, b2 = 0.5 * a * a, 0.5 * b * b
    return (np.where(near_row, c(hb[:, 0]) * b2, c(ha[:, 0]) * a2),
            np.where(near_row, c(hb[:, 1]) * b2, c(ha[:, 1]) * a2))


def _differences(g: F64, axis: int) -> tuple[F64, F64]:
    """First and second derivative along ``axis`` (0: rows, 1: columns) of the quadratic
    through each point's block of 3 (moved inward at the border; with 2 points the line,
    no bend), at every point of ``g`` (R, C, 2)."""
    if axis == 1:
        d, h = _differences(g.transpose(1, 0, 2), 0)
        return d.transpose(1, 0, 2), h.transpose(1, 0, 2)
    if len(g) == 2:
        return np.broadcast_to(g[1] - g[0], g.shape), np.zeros_like(g)
    d, h = np.empty_like(g), np.empty_like(g)
    d[1:-1] = 0.5 * (g[2:] - g[:-2])
    d[0] = -1.5 * g[0] + 2.0 * g[1] - 0.5 * g[2]
    d[-1] = 1.5 * g[-1] - 2.0 * g[-2] + 0.5 * g[-3]
    h[1:-1] = g[2:] - 2.0 * g[1:-1] + g[:-2]
    h[0], h[-1] = h[1], h[-2]
    return d, h


def _blocks(gray: NDArray[np.uint8], centres: NDArray[np.int64], r: int) -> NDArray[np.uint8]:
    """The (2 r + 1)-pixel squares of ``gray`` around the whole pixels ``centres`` (N, 2),
    (N, 2 r + 1, 2 r + 1); past the image's edge its border pixels repeated."""
    h, w = gray.shape
    x, y = centres[:, 0], centres[:, 1]
    if x.min() >= r and y.min() >= r and x.max() < w - r and y.max() < h - r:
        windows = np.lib.stride_tricks.sliding_window_view(gray, (2 * r + 1, 2 * r + 1))
        return windows[y - r, x - r]
    reach = np.arange(-r, r + 1)
    iy = np.clip(y[:, None] + reach, 0, h - 1)
    ix = np.clip(x[:, None] + reach, 0, w - 1)
    return gray[iy[:, :, None], ix[:, None, :]]


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
    ``p + u* + t(u*)``."""
    n = len(points)
    frames = tuple(x.astype(np.float32) for x in _edge_frames(points, rows, cols))
    t = half + MARGIN_PX
    side = 2 * t + 1
    base = np.rint(points).astype(np.int64)
    shift = (base - points).astype(np.float32)                        # (N, 2)
    off = np.arange(-t, t + 1, dtype=np.float32)
    ux = (off + shift[:, 0, None])[:, None, :]                        # (N, 1, side)
    uy = (off + shift[:, 1, None])[:, :, None]                        # (N, side, 1)
    bx, by = _bend(ux, uy, frames)                                    # (N, side, side)
    # the image on each tile's whole pixels and one beyond (replicated past the image's edge)
    block = _blocks(gray, base, t + 1).astype(np.float32)
    # moved by the bend: first order in it, central differences (no resampling grid)
    tiles = block[:, 1:-1, 1:-1] + 0.5 * bx * (block[:, 1:-1, 2:] - block[:, 1:-1, :-2])
    tiles += 0.5 * by * (block[:, 2:, 1:-1] - block[:, :-2, 1:-1])
    per_row = int(np.ceil(np.sqrt(n)))
    mosaic_rows = int(np.ceil(n / per_row))
    full = np.empty((mosaic_rows * per_row, side, side), np.float32)
    full[:n], full[n:] = tiles, tiles[:1]
    mosaic = full.reshape(mosaic_rows, per_row, side, side).transpose(0, 2, 1, 3)
    mosaic = np.ascontiguousarray(mosaic.reshape(mosaic_rows * side, per_row * side))
    k = np.arange(n)
    centre = np.column_stack([(k % per_row) * side, (k // per_row) * side]) + float(t)
    pts = (centre - shift).astype(np.float32).reshape(-1, 1, 2)
    cv2.cornerSubPix(mosaic, pts, (half, half), (-1, -1), SUBPIX_CRITERIA)
    u = pts.reshape(-1, 2).astype(np.float64) - centre + shift
    back = _bend(u[:, :1, None], u[:, 1:, None], tuple(x.astype(np.float64) for x in frames))
    return points + u + np.column_stack([back[0].ravel(), back[1].ravel()])
