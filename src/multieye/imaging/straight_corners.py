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
(per grid axis) through the 3 x 3 block of detected corners around it (the block moved
inward at the grid's border): it passes through the corners of the rows and columns that
meet there, so the edges between them, as the lens bends them, follow it to second order.
The patch around the corner is resampled (``cv2.remap``, bicubic) at the points this
mapping gives for a grid of pixel offsets transformed by its inverse Jacobian at the
corner: a patch that equals the image to first order (same scale, same window), its edges
straight.  ``cornerSubPix`` refines the corner there, in the same window, and the result is
mapped back.  Under a pinhole lens the edges are straight already and the three corners of
a row lie on its line, so the mapping changes nothing but the resampling.

Synopsis
--------
>>> refined = refine_straightened(gray, corners, rows, cols, half)          # doctest: +SKIP
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["refine_straightened", "MARGIN_PX"]

F64 = NDArray[np.float64]

#: Pixels of each resampled patch beyond the refinement window (``cornerSubPix`` reads one
#: pixel beyond it, and the corner may move a little).
MARGIN_PX = 4


def _lagrange(t: F64, nodes: F64) -> tuple[F64, F64]:
    """The Lagrange basis over ``nodes`` (m,) at ``t`` (...,): values and derivatives,
    shape (..., m)."""
    m = len(nodes)
    val, der = np.empty(t.shape + (m,)), np.empty(t.shape + (m,))
    for i in range(m):
        others = [j for j in range(m) if j != i]
        denom = np.prod([nodes[i] - nodes[j] for j in others])
        factors = [t - nodes[j] for j in others]
        val[..., i] = np.prod(factors, axis=0) / denom
        der[..., i] = sum(np.prod([f for q, f in enumerate(factors) if q != skip], axis=0)
                          for skip in range(len(factors))) / denom
    return val, der


def _blocks(n: int) -> tuple[NDArray[np.int64], NDArray[np.int64], F64]:
    """Per grid index along an axis of ``n`` corners: the first index of its block (3 corners,
    2 when ``n`` is 2), its own position in the block's coordinates (the block's nodes at 0, 1,
    2), and the nodes."""
    m = min(n, 3)
    first = np.clip(np.arange(n) - 1, 0, n - m)
    return first, np.arange(n) - first, np.arange(m, dtype=np.float64)


def _maps(points: F64, rows: int, cols: int, half: int) -> tuple[F64, F64, F64, tuple]:
    """Per corner the image positions of its straightened patch's pixels, shape
    (N, 2 T + 1, 2 T + 1, 2) with ``T = half + MARGIN_PX``, and the quantities
    :func:`refine_straightened` maps back with: the block's corners (N, 3, 3, 2), the
    inverse Jacobians (N, 2, 2) and the corners' block coordinates and nodes."""
    grid = points.reshape(rows, cols, 2)
    ra, ta, na = _blocks(rows)
    cb, tb, nb = _blocks(cols)
    r, c = np.divmod(np.arange(rows * cols), cols)
    ia = ra[r][:, None] + np.arange(len(na))
    ib = cb[c][:, None] + np.arange(len(nb))
    block = grid[ia[:, :, None], ib[:, None, :]]                      # (N, ma, mb, 2)
    ta, tb = ta[r].astype(np.float64), tb[c].astype(np.float64)
    va, da = _lagrange(ta, na)
    vb, db = _lagrange(tb, nb)
    jac = np.stack([np.einsum("ki,kj,kijd->kd", da, vb, block),
                    np.einsum("ki,kj,kijd->kd", va, db, block)], axis=-1)   # d pixel / d (a, b)
    inv = np.linalg.inv(jac)
    t = half + MARGIN_PX
    off = np.arange(-t, t + 1, dtype=np.float64)
    xy = np.stack(np.meshgrid(off, off), axis=-1)                     # (2T+1, 2T+1, 2): x, y
    shift = np.rint(points) - points                                  # the patch on whole pixels
    ab = np.einsum("kij,kpqj->kpqi", inv, xy[None] + shift[:, None, None, :])
    pa, _ = _lagrange(ta[:, None, None] + ab[..., 0], na)
    pb, _ = _lagrange(tb[:, None, None] + ab[..., 1], nb)
    where = np.einsum("kpqi,kpqj,kijd->kpqd", pa, pb, block)
    return where, block, inv, (ta, tb, na, nb, shift)


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
    """
    where, block, inv, (ta, tb, na, nb, shift) = _maps(points, rows, cols, half)
    n, side = where.shape[0], where.shape[1]
    per_row = int(np.ceil(np.sqrt(n)))
    mosaic_rows = int(np.ceil(n / per_row))
    tiles = np.zeros((mosaic_rows * per_row, side, side, 2), dtype=np.float32)
    tiles[:n] = where
    tiles[n:] = -100.0
    mosaic = tiles.reshape(mosaic_rows, per_row, side, side, 2).transpose(0, 2, 1, 3, 4)
    mosaic = mosaic.reshape(mosaic_rows * side, per_row * side, 2)
    patch = cv2.remap(gray, mosaic[..., 0], mosaic[..., 1], cv2.INTER_CUBIC,
                      borderMode=cv2.BORDER_REPLICATE)
    k = np.arange(n)
    centre = np.column_stack([(k % per_row) * side, (k // per_row) * side]) + (side - 1) / 2
    pts = (centre - shift).astype(np.float32).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    cv2.cornerSubPix(patch, pts, (half, half), (-1, -1), criteria)
    moved = pts.reshape(-1, 2).astype(np.float64) - centre
    ab = np.einsum("kij,kj->ki", inv, moved + shift)
    pa, _ = _lagrange(ta + ab[:, 0], na)
    pb, _ = _lagrange(tb + ab[:, 1], nb)
    return np.einsum("ki,kj,kijd->kd", pa, pb, block)
