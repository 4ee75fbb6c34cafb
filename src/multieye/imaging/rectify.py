"""Stereo rectification of two cameras that see the target together (OpenCV's).

For a pair ``(a, b)`` with their lenses and ``T_a_b`` (camera b in camera a), OpenCV's
``cv2.stereoRectify`` (two pinhole lenses) or ``cv2.fisheye.stereoRectify`` (two fisheye
lenses) gives per camera the rotation ``R`` from the camera frame to its rectified frame and the
projection ``P`` (3x4) of the rectified image, as the ROS ``CameraInfo`` and OpenCV's stereo
tools take them: ``P_b[0, 3] = -f B`` for a horizontal pair (``B`` the baseline, metres),
camera a the first (left).  A pinhole lens paired with a fisheye one has no OpenCV
rectification: :func:`stereo_rectification` refuses it.

``cv2.stereoRectify`` takes ``R, T`` with ``p_b = R p_a + T``, i.e. ``T_b_a = inv(T_a_b)``.

Synopsis
--------
>>> import numpy as np
>>> from multieye.core.intrinsics import Intrinsics
>>> lens = Intrinsics(K=[[500, 0, 319.5], [0, 500, 239.5], [0, 0, 1]], dist=np.zeros(5),
...                   width=640, height=480)
>>> T_a_b = np.eye(4); T_a_b[0, 3] = 0.12            # b 12 cm to the right of a
>>> rect = stereo_rectification(lens, lens, T_a_b)
>>> float(round(-rect.P_b[0, 3] / rect.P_b[0, 0], 6))   # baseline, metres
0.12
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics

__all__ = ["Rectification", "stereo_rectification"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Rectification:
    """Rectification of a pair of cameras ``(a, b)``.

    Attributes
    ----------
    R_a, R_b : ndarray, shape (3, 3)
        Rotation from each camera's frame to its rectified frame.
    P_a, P_b : ndarray, shape (3, 4)
        Projection matrices of the rectified images, pixels (``P_b[:, 3]`` holds the baseline).
    Q : ndarray, shape (4, 4)
        Disparity-to-depth matrix (OpenCV's).
    """

    R_a: F64
    R_b: F64
    P_a: F64
    P_b: F64
    Q: F64


def stereo_rectification(lens_a: Intrinsics, lens_b: Intrinsics, T_a_b: F64) -> Rectification:
    """OpenCV's rectification of cameras a and b (module docstring).

    Parameters
    ----------
    lens_a, lens_b : Intrinsics
        Both with the image size (``width``, ``height``), equal for the two cameras, and both
        pinhole or both fisheye.
    T_a_b : ndarray, shape (4, 4)
        Camera b in camera a, metres.

    Raises
    ------
    InputError
        Different models, an unknown or different image size, or a zero baseline.
    """
    for lens in (lens_a, lens_b):
        if lens.model not in ("pinhole", "fisheye"):
            raise InputError(f"no rectification for a {lens.model} lens (OpenCV has none)")
    if lens_a.model != lens_b.model:
        raise InputError(f"no rectification for a {lens_a.model} lens paired with a "
                         f"{lens_b.model} one (OpenCV has none)")
    size = (lens_a.width, lens_a.height)
    if None in size or size != (lens_b.width, lens_b.height):
        raise InputError("rectification needs both image sizes, and equal ones; got "
                         f"{lens_a.width}x{lens_a.height} and {lens_b.width}x{lens_b.height}")
    T_b_a = np.linalg.inv(np.asarray(T_a_b, dtype=np.float64))
    R, t = T_b_a[:3, :3].copy(), T_b_a[:3, 3].reshape(3, 1).copy()
    if np.linalg.norm(t) < 1e-9:
        raise InputError("rectification needs two cameras apart (zero baseline)")
    if lens_a.model == "fisheye":
        R1, R2, P1, P2, Q = cv2.fisheye.stereoRectify(
            lens_a.K, lens_a.dist, lens_b.K, lens_b.dist, size, R, t,
            flags=cv2.CALIB_ZERO_DISPARITY, newImageSize=size, balance=0.0, fov_scale=1.0)
    else:
        R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(
            lens_a.K, lens_a.dist, lens_b.K, lens_b.dist, size, R, t,
            flags=cv2.CALIB_ZERO_DISPARITY, alpha=0.0)
    return Rectification(*(np.asarray(x, dtype=np.float64) for x in (R1, R2, P1, P2, Q)))
