"""Marker boards whose markers are too small for OpenCV's contour-based detector, looked for
again in the image upsampled twice.

OpenCV's ArUco / AprilTag detector finds a marker from the contour of its black border; below
about 20 pixels per marker (2.5 pixels per cell of an AprilTag 36h11 with Kalibr's 2-bit
border) the adaptive threshold merges the cells and no marker is found, so a whole AprilGrid
seen from 0.9 m by a 460 px lens is missed.  Found in none of them, the image is resampled
at twice its size (bilinear: ``cv2.INTER_LINEAR``) and searched again; the points found are
mapped back to the image's pixels (the centre of pixel ``x`` of the upsampled image lies at
``(x - 0.5) / 2``).  Only images of at most :data:`MAX_PIXELS` are upsampled (the second look
costs about four times the first: 4 ms for 640 x 480, once per image without a board).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["at_twice_the_size", "MAX_PIXELS"]

#: Largest image (pixels) looked at again at twice its size: 1920 x 1080.
MAX_PIXELS = 1920 * 1080


def at_twice_the_size(detect: Callable, gray: NDArray[np.uint8], target):
    """``detect(gray, target)`` on ``gray`` upsampled twice, its points in ``gray``'s pixels;
    None when the image is larger than :data:`MAX_PIXELS` or nothing is found there either.

    Parameters
    ----------
    detect : callable
        A marker board's detector, ``(gray, target) -> Detection | None``
        (:mod:`multieye.imaging.detect`).
    gray : ndarray, shape (H, W), uint8
    target : Target
    """
    if gray.shape[0] * gray.shape[1] > MAX_PIXELS:
        return None
    found = detect(cv2.resize(gray, None, fx=2.0, fy=2.0, interpolation=cv2.INTER_LINEAR),
                   target)
    if found is None:
        return None
    return replace(found, image_points=(np.asarray(found.image_points) - 0.5) / 2.0)
