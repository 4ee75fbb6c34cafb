"""Small pictures of camera images with their detected points and residuals drawn on the pixels.

For the report (:mod:`multieye.outputs.report_images`): one image is read (grayscale,
decoded at a reduced size when it is much larger than the picture), scaled down to at most
``max_width`` pixels across, and the detected target points (small rings) and their
reprojection residuals (projection minus detection, magnified ``magnify`` times, as lines
from the point) are drawn on it in colour, then encoded as JPEG.  The grey image makes the
marks stand out whatever the scene.

Synopsis
--------
>>> from multieye.imaging.thumbnails import residual_thumbnail
>>> jpeg = residual_thumbnail("cam0/1.5.png", uv, residual, magnify=50.0)  # doctest: +SKIP
"""

from __future__ import annotations

import math
import os

import cv2
import numpy as np

from multieye.imaging.image_file import checked_bytes, decode_gray, turns_to_fit

#: The drawn images' JPEG quality, 0-100.
JPEG_QUALITY = 82

__all__ = ["residual_thumbnail", "crop_box", "POINT_BGR", "RESIDUAL_BGR"]

#: Colour of the detected points (cyan) and of the residual lines (magenta), BGR.
POINT_BGR = (255, 220, 0)
RESIDUAL_BGR = (255, 0, 230)


def _read_reduced(path: str, max_width: int, fit=None) -> tuple[np.ndarray, float] | None:
    """The image in grayscale at a reduced size, and the factor from full-size pixels to it;
    read with the same bounds and header checks as detection (:mod:`multieye.imaging.image_file`).

    JPEG decoders scale by 2, 4 or 8 while decoding (much faster than a full decode); the
    reduction is chosen so that the decoded image stays at least ``max_width`` wide.
    """
    data, header, reason = checked_bytes(path)
    if reason is not None:
        return None
    reduce = 1
    turn = turns_to_fit(header, fit)      # as detection read it (image_file.read_gray)
    width = header.height if turn else header.width
    if header.format == "JPEG":
        reduce = next((f for f in (8, 4, 2) if width / f >= max_width), 1)
    image, reason = decode_gray(data, reduce, orient=turn)
    if image is None:
        return None
    return image, image.shape[1] / width


def crop_box(uv: np.ndarray, width: float, height: float, margin: float = 0.25,
             least: float = 0.4) -> tuple[int, int, int, int]:
    """The part of an image to show around points: their bounding box widened by ``margin``
    of its size on every side, at least ``least`` of the image across and down, inside the
    image; ``(x0, y0, x1, y1)`` full-size pixels (the whole image without points)."""
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    uv = uv[np.all(np.isfinite(uv), axis=1)]
    if len(uv) == 0:
        return 0, 0, int(width), int(height)
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    size = np.maximum((hi - lo) * (1 + 2 * margin), least * np.array([width, height]))
    size = np.minimum(size, [width, height])
    centre = (lo + hi) / 2
    x0 = float(np.clip(centre[0] - size[0] / 2, 0, width - size[0]))
    y0 = float(np.clip(centre[1] - size[1] / 2, 0, height - size[1]))
    return int(x0), int(y0), int(math.ceil(x0 + size[0])), int(math.ceil(y0 + size[1]))


def residual_thumbnail(path: str | os.PathLike, uv: np.ndarray, residual: np.ndarray, *,
                       magnify: float, max_width: int = 480,
                       image_size: tuple[int, int] | None = None, crop: bool = True,
                       region: tuple[int, int, int, int] | None = None) -> bytes | None:
    """A downscaled grey copy of an image with its points and magnified residuals, as JPEG.

    Parameters
    ----------
    path : path-like
        The image file.
    uv : ndarray, shape (n, 2)
        Detected target points, full-size pixels (x right, y down; pixel centres at integers).
    residual : ndarray, shape (n, 2)
        Projection minus detection, pixels (NaN rows are not drawn).
    magnify : float
        Drawn length of a residual line per pixel of residual (in full-size pixels).
    max_width : int
        Width of the picture at most, pixels (never enlarged).
    image_size : (int, int), optional
        Full-size width and height; when given, a file of another size is refused (None).
    crop : bool
        Show only the part of the image around the points (:func:`crop_box`).
    region : (x, y, width, height), optional
        Show nothing outside this part of the image (a camera's half of a side-by-side
        stereo frame), full-size pixels.

    Returns
    -------
    bytes or None
        The JPEG, or None when the file cannot be read or does not have ``image_size``.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        return None
    read = _read_reduced(path, max_width * 3 if crop else max_width, image_size)
    if read is None:
        return None
    image, reduced = read
    full_w = image.shape[1] / reduced
    full_h = image.shape[0] / reduced
    if image_size is not None and (abs(full_w - image_size[0]) > 8
                                   or abs(full_h - image_size[1]) > 8):
        return None
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    residual = np.asarray(residual, dtype=np.float64).reshape(-1, 2)
    x0, y0, x1, y1 = crop_box(uv, full_w, full_h) if crop else (0, 0, full_w, full_h)
    if region is not None:
        x0, y0 = max(x0, region[0]), max(y0, region[1])
        x1, y1 = min(x1, region[0] + region[2]), min(y1, region[1] + region[3])
        if x1 <= x0 or y1 <= y0:
            return None
    part = image[int(y0 * reduced):int(math.ceil(y1 * reduced)),
                 int(x0 * reduced):int(math.ceil(x1 * reduced))]
    scale = min(reduced, max_width / (x1 - x0))  # full-size pixels -> picture pixels
    size = (max(int(round((x1 - x0) * scale)), 1), max(int(round((y1 - y0) * scale)), 1))
    if (part.shape[1], part.shape[0]) != size:
        part = cv2.resize(part, size, interpolation=cv2.INTER_AREA)
    # lighter and flatter grey, so that the marks are what one sees
    grey = (96 + part.astype(np.float32) * (150.0 / 255.0)).astype(np.uint8)
    picture = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)
    ok = np.all(np.isfinite(uv), axis=1) & np.all(np.isfinite(residual), axis=1)
    shift = 4                                   # sub-pixel drawing: coordinates * 16
    at = (uv[ok] - [x0, y0] + 0.5) * scale - 0.5
    tip = at + residual[ok] * magnify * scale
    a = np.round(at * (1 << shift)).astype(np.int32)
    b = np.round(tip * (1 << shift)).astype(np.int32)
    lines = np.stack([a, b], axis=1)           # (k, 2, 2): one polyline per residual
    for p in a:                                 # rings first, the residual lines on top
        cv2.circle(picture, (int(p[0]), int(p[1])), 3 << shift, POINT_BGR, 1, cv2.LINE_AA,
                   shift)
    cv2.polylines(picture, list(lines), False, RESIDUAL_BGR, 1, cv2.LINE_AA, shift)
    ok_, jpeg = cv2.imencode(".jpg", picture, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    return bytes(jpeg) if ok_ else None
