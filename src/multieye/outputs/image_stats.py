"""Numbers about where a camera saw the target, for the report's per-camera section and figures.

Everything here works on a camera's ``details.json`` entry
(:class:`multieye.io.run_details.CameraDetails`): its target points and their reprojection
residuals (:class:`multieye.io.pixel_details.ImagePoints`) and its intrinsics.  No matplotlib:
:mod:`multieye.outputs.figures` draws what these functions compute, and
:mod:`multieye.outputs.report` prints it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from multieye.io.run_details import CameraDetails

__all__ = ["ImageFrame", "image_frame", "stacked", "coverage", "radial_bins", "position_bins",
           "mean_vectors", "arrow_scale", "worst_images", "COVERAGE_CELLS", "MAX_ARROWS"]

#: Cells across and down in which the coverage of the image is counted (as the pipeline's
#: weak-data warning for estimated intrinsics counts it).
COVERAGE_CELLS = 4
#: Above this many points the residual vectors are drawn as one mean per cell of the image
#: (:func:`mean_vectors`): one arrow per point would cover the image.
MAX_ARROWS = 800


@dataclass(frozen=True)
class ImageFrame:
    """The image rectangle a camera's points are drawn in.

    Attributes
    ----------
    width, height : int
        Pixels.
    known : bool
        False when neither the intrinsics nor ``points.image_size`` give the size: then it is
        ``2 cx + 1`` by ``2 cy + 1``, widened to hold every point.
    cx, cy : float or None
        Principal point, pixels (None without intrinsics).
    """

    width: int
    height: int
    known: bool
    cx: float | None
    cy: float | None


def stacked(cam: CameraDetails) -> tuple[np.ndarray, np.ndarray]:
    """Every kept point of the camera and its residual, ``(P, 2)`` each (empty without points)."""
    p = cam.points
    if p is None or p.kept == 0:
        return np.zeros((0, 2)), np.zeros((0, 2))
    return np.concatenate(p.uv), np.concatenate(p.residual_px)


def image_frame(cam: CameraDetails) -> ImageFrame:
    """The image size and principal point of a camera (see :class:`ImageFrame`)."""
    intr = cam.intrinsics
    cx = cy = None
    if intr is not None:
        cx, cy = float(intr.K[0, 2]), float(intr.K[1, 2])
    size = cam.points.image_size if cam.points is not None else None
    if size is None and intr is not None and intr.width and intr.height:
        size = (intr.width, intr.height)
    if size is not None:
        return ImageFrame(int(size[0]), int(size[1]), True, cx, cy)
    uv, _ = stacked(cam)
    w = 2 * cx + 1 if cx is not None else 1.0
    h = 2 * cy + 1 if cy is not None else 1.0
    if len(uv):
        w, h = max(w, float(uv[:, 0].max()) + 1), max(h, float(uv[:, 1].max()) + 1)
    return ImageFrame(int(math.ceil(w)), int(math.ceil(h)), False, cx, cy)


def coverage(uv: np.ndarray, frame: ImageFrame, cells: int = COVERAGE_CELLS) -> float:
    """Share of the ``cells x cells`` grid over the image that holds at least one point."""
    if len(uv) == 0:
        return 0.0
    idx = np.clip((uv / [frame.width, frame.height] * cells).astype(int), 0, cells - 1)
    return len(np.unique(idx[:, 0] * cells + idx[:, 1])) / cells ** 2


def radial_bins(uv: np.ndarray, residual: np.ndarray, frame: ImageFrame, bins: int = 10
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Residual lengths binned by the distance of the point from the principal point.

    The bins split ``0 .. r_corner`` (the farthest image corner) evenly, so that cameras and
    runs compare.

    Returns
    -------
    edges : ndarray, shape (bins + 1,)
        Pixels.
    rms, median : ndarray, shape (bins,)
        Of the residual lengths in each bin, pixels; NaN for an empty bin.
    count : ndarray, shape (bins,)
        Points per bin.
    """
    cx = frame.cx if frame.cx is not None else (frame.width - 1) / 2
    cy = frame.cy if frame.cy is not None else (frame.height - 1) / 2
    corners = np.array([[-0.5, -0.5], [frame.width - 0.5, -0.5], [-0.5, frame.height - 0.5],
                        [frame.width - 0.5, frame.height - 0.5]])
    r_max = float(np.max(np.hypot(corners[:, 0] - cx, corners[:, 1] - cy)))
    edges = np.linspace(0.0, r_max, bins + 1)
    rms, med = np.full(bins, np.nan), np.full(bins, np.nan)
    count = np.zeros(bins, dtype=int)
    if len(uv):
        r = np.hypot(uv[:, 0] - cx, uv[:, 1] - cy)
        e = np.hypot(residual[:, 0], residual[:, 1])
        k = np.clip(np.searchsorted(edges, r, side="right") - 1, 0, bins - 1)
        for b in range(bins):
            v = e[(k == b) & np.isfinite(e)]
            count[b] = v.size
            if v.size:
                rms[b], med[b] = float(np.sqrt(np.mean(v ** 2))), float(np.median(v))
    return edges, rms, med, count


def position_bins(uv: np.ndarray, residual: np.ndarray, frame: ImageFrame, columns: int = 8,
                  min_points: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """RMS residual length in a grid of cells over the image (``columns`` across, rows from
    the aspect ratio); NaN in cells with fewer than ``min_points`` points.

    Returns
    -------
    rms : ndarray, shape (rows, columns)
        Pixels.
    count : ndarray, shape (rows, columns)
    """
    rows = max(int(round(columns * frame.height / frame.width)), 1)
    rms = np.full((rows, columns), np.nan)
    count = np.zeros((rows, columns), dtype=int)
    if len(uv) == 0:
        return rms, count
    e2 = np.sum(residual ** 2, axis=1)
    ok = np.isfinite(e2)
    col = np.clip(((uv[ok, 0] + 0.5) / frame.width * columns).astype(int), 0, columns - 1)
    row = np.clip(((uv[ok, 1] + 0.5) / frame.height * rows).astype(int), 0, rows - 1)
    np.add.at(count, (row, col), 1)
    total = np.zeros((rows, columns))
    np.add.at(total, (row, col), e2[ok])
    enough = count >= min_points
    rms[enough] = np.sqrt(total[enough] / count[enough])
    return rms, count


def mean_vectors(uv: np.ndarray, residual: np.ndarray, frame: ImageFrame, columns: int = 16,
                 min_points: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mean residual vector in each cell of a grid over the image (``columns`` across,
    rows from the aspect ratio), for cells with at least ``min_points`` points: what is
    systematic in the residuals (a lens model that does not fit bends them alike).

    Returns
    -------
    centres : ndarray, shape (k, 2)
        Cell centres, pixels.
    mean : ndarray, shape (k, 2)
        Mean residual, pixels.
    count : ndarray, shape (k,)
        Points per cell.
    """
    rows = max(int(round(columns * frame.height / frame.width)), 1)
    ok = np.all(np.isfinite(residual), axis=1)
    col = np.clip(((uv[ok, 0] + 0.5) / frame.width * columns).astype(int), 0, columns - 1)
    row = np.clip(((uv[ok, 1] + 0.5) / frame.height * rows).astype(int), 0, rows - 1)
    cell = row * columns + col
    count = np.bincount(cell, minlength=rows * columns)
    sums = np.stack([np.bincount(cell, residual[ok, k], rows * columns) for k in (0, 1)], axis=1)
    keep = np.flatnonzero(count >= min_points)
    centres = np.column_stack([(keep % columns + 0.5) * frame.width / columns - 0.5,
                               (keep // columns + 0.5) * frame.height / rows - 0.5])
    return centres, sums[keep] / count[keep, None], count[keep]


def arrow_scale(residual: np.ndarray, frame: ImageFrame, share: float = 0.06
                ) -> tuple[float, float]:
    """How to draw residual vectors on the image: ``(key_px, magnify)``.

    ``key_px`` is a round residual length (1, 2 or 5 times a power of ten) near the 95th
    percentile of the lengths; ``magnify`` makes an arrow of that length ``share`` of the
    image width long.
    """
    e = np.hypot(residual[:, 0], residual[:, 1]) if len(residual) else np.zeros(0)
    e = e[np.isfinite(e)]
    p95 = float(np.percentile(e, 95)) if e.size else 1.0
    p95 = p95 if p95 > 0 else 1.0
    decade = 10.0 ** math.floor(math.log10(p95))
    key = min((m * decade for m in (1, 2, 5, 10)), key=lambda k: abs(math.log(k / p95)))
    return key, share * frame.width / key


def worst_images(cam: CameraDetails, k: int = 5) -> list[tuple[str, float]]:
    """The ``k`` used images of highest reprojection RMS, worst first: ``(name, rms_px)``."""
    if cam.points is None:
        return []
    rms = cam.points.rms_px
    order = [i for i in np.argsort(-np.nan_to_num(rms, nan=-1.0)) if np.isfinite(rms[i])]
    return [(cam.names[i], float(rms[i])) for i in order[:k]]
