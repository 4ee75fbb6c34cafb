"""A second renderer of chessboard images: a board picture warped into the camera.

:mod:`multieye.sim.render` traces every sub-pixel's ray to the board and evaluates the
printed pattern there exactly.  This module makes the image another way, so that the
detection is not tuned to one renderer's look: a picture of the board (``px_per_square``
pixels per square, the squares on the picture's pixel grid) is resampled bilinearly
(``cv2.remap``) through the homography of the board plane composed with the lens's
distortion (each output sub-pixel's undistorted ray, :func:`multieye.core.lens.undistort_points`,
per camera once), at twice the output resolution, then shrunk by ``cv2.INTER_AREA``. The
scene behind differs too: a brightness gradient with cluttering rectangles (sharp corners
the detector must not take for the board); over it a vignetting gain, a Gaussian blur and
sensor noise.

The inner corners land where :func:`multieye.core.lens.project_points` puts them (to the
bilinear resampling's few hundredths of a pixel), which is what the corner-accuracy checks
of the detection compare against.

Synopsis
--------
>>> import numpy as np
>>> from multieye.core.intrinsics import Intrinsics
>>> from multieye.imaging.targets import Chessboard
>>> from multieye.sim.warped import render_warped
>>> cam = Intrinsics(K=[[600, 0, 399.5], [0, 600, 299.5], [0, 0, 1]], width=800, height=600)
>>> T = np.eye(4); T[:3, 3] = [-0.16, -0.1, 0.8]
>>> render_warped(Chessboard(rows=6, cols=9, spacing=0.04), cam, T).shape
(600, 800)
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from multieye.core.arguments import transform
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import undistort_points
from multieye.imaging.targets import Chessboard

__all__ = ["render_warped"]

F64 = NDArray[np.float64]

#: Sub-pixels per output pixel side of the resampled image (shrunk by area averaging).
_SUPERSAMPLE = 2


def _board_picture(target: Chessboard, px: int, black: float, white: float) -> NDArray[np.float32]:
    """The printed board with a white margin of one square: ``(rows + 3) * px`` by
    ``(cols + 3) * px`` pixels; square (i, j) (i along x from -1) black when i + j is even,
    as :class:`~multieye.imaging.targets.Chessboard` prints it."""
    j, i = np.mgrid[-2:target.rows + 1, -2:target.cols + 1]
    inside = (i >= -1) & (i < target.cols) & (j >= -1) & (j < target.rows)
    cells = np.where(inside & ((i + j) % 2 == 0), black, white).astype(np.float32)
    return cv2.resize(cells, None, fx=px, fy=px, interpolation=cv2.INTER_NEAREST)


@lru_cache(maxsize=8)
def _rays(params: tuple, model: str, w: int, h: int) -> NDArray[np.float32]:
    """Undistorted normalised coordinates (x/z, y/z) of every sub-pixel of a
    ``_SUPERSAMPLE`` times larger grid, shape (h * s, w * s, 2), float32 (NaN where the lens
    cannot be inverted)."""
    fx, fy, cx, cy, *dist = params
    intr = Intrinsics(K=[[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dist=dist, model=model,
                      width=w, height=h)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    xy = undistort_points(np.column_stack([u.ravel(), v.ravel()]), intr).reshape(h, w, 2)
    s = _SUPERSAMPLE
    # cv2.resize puts output pixel k at input coordinate (k + 0.5) / s - 0.5: the sub-pixels
    return cv2.resize(xy.astype(np.float32), (w * s, h * s), interpolation=cv2.INTER_LINEAR)


def _scene(rng: np.random.Generator, w: int, h: int) -> NDArray[np.float32]:
    """A brightness gradient with 6-12 rectangles of random grey (sharp corners: clutter)."""
    gy, gx = np.mgrid[0:h, 0:w].astype(np.float32)
    a, b = rng.uniform(-40, 40, 2)
    img = 120.0 + a * gx / w + b * gy / h
    for _ in range(int(rng.integers(6, 13))):
        x0, y0 = rng.uniform(0, w), rng.uniform(0, h)
        rw, rh = rng.uniform(0.03, 0.2) * w, rng.uniform(0.03, 0.2) * h
        img[int(y0):int(y0 + rh), int(x0):int(x0 + rw)] = rng.uniform(30, 220)
    return img.astype(np.float32)


def render_warped(target: Chessboard, intrinsics: Intrinsics, T_cam_target: ArrayLike, *,
                  rng: np.random.Generator | None = None, blur_sigma: float = 0.8,
                  noise_sigma: float = 2.0, px_per_square: int = 48) -> NDArray[np.uint8]:
    """A grayscale image of a chessboard at ``T_cam_target``, made by warping its picture.

    Parameters
    ----------
    target : Chessboard
    intrinsics : Intrinsics
        Any model :func:`multieye.core.lens.undistort_points` inverts; its ``width`` and
        ``height`` give the image size.
    T_cam_target : array_like, shape (4, 4)
        The board's pose in the camera frame, metres.
    rng : numpy.random.Generator, optional
        Scene, vignetting and noise (default a fixed seed).
    blur_sigma : float
        Gaussian blur, pixels (0: none).
    noise_sigma : float
        Gaussian sensor noise, grey levels.
    px_per_square : int
        Pixels per square of the board's picture.

    Returns
    -------
    ndarray, shape (height, width), uint8
    """
    if not isinstance(target, Chessboard):
        raise InputError(f"render_warped draws chessboards only, not {type(target).__name__}")
    if intrinsics.width is None or intrinsics.height is None:
        raise InputError("render_warped needs the image size in the intrinsics")
    T = transform(T_cam_target, "T_cam_target", rigid=True)
    rng = np.random.default_rng(0) if rng is None else rng
    w, h, s = int(intrinsics.width), int(intrinsics.height), _SUPERSAMPLE
    picture = _board_picture(target, int(px_per_square), rng.uniform(20, 45), rng.uniform(190, 235))
    # picture pixel centre k at board coordinate (k + 0.5) / px * spacing - 2 spacing
    to_picture = np.array([[px_per_square / target.spacing, 0, 2 * px_per_square - 0.5],
                           [0, px_per_square / target.spacing, 2 * px_per_square - 0.5],
                           [0, 0, 1]])
    H = to_picture @ np.linalg.inv(np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]))
    rays = _rays(tuple(float(p) for p in intrinsics.params), intrinsics.model, w, h)
    x, y = rays[..., 0], rays[..., 1]
    den = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        facing = den > 0                      # the board in front of the camera
        mx = np.where(facing, (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / den, -1e6)
        my = np.where(facing, (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / den, -1e6)
    mx, my = np.nan_to_num(mx, nan=-1e6), np.nan_to_num(my, nan=-1e6)
    scene = cv2.resize(_scene(rng, w, h), (w * s, h * s), interpolation=cv2.INTER_NEAREST)
    board = cv2.remap(picture, mx.astype(np.float32), my.astype(np.float32), cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)
    image = cv2.resize(np.where(board >= 0, board, scene), (w, h), interpolation=cv2.INTER_AREA)
    gy, gx = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((gx - w / 2) ** 2 + (gy - h / 2) ** 2) / (0.25 * (w * w + h * h))
    image *= 1.0 - rng.uniform(0.1, 0.3) * r2              # vignetting
    if blur_sigma > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur_sigma)
    image += rng.normal(0.0, noise_sigma, image.shape).astype(np.float32)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)
