"""Viewing rays of pixels, and a planar target's pose from rays however wide the lens.

PnP on undistorted normalised coordinates ``(x / z, y / z)`` breaks down for a wide lens:
they grow without bound towards 90 degrees off the axis and do not exist beyond it.  Here the
points' unit rays are turned into a virtual camera looking along their mean ray before IPPE
(``cv2.solvePnPGeneric``) sees their normalised coordinates, and the poses are turned back:
any board the lens sees within about 80 degrees of its own centre ray, at whatever angle off
the lens axis, is posed as well as a board straight ahead (issue 33).

Synopsis
--------
>>> rays = bearings(uv, intrinsics)                     # (N, 3) unit rays  # doctest: +SKIP
>>> for rvec, tvec in ippe_on_rays(object_points, rays): ...                # doctest: +SKIP
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core import lens
from multieye.core.intrinsics import Intrinsics

__all__ = ["bearings", "ippe_on_rays", "WIDE_DEG", "virtual_rotation"]

F64 = NDArray[np.float64]

#: Rays further off the lens axis than this (degrees) are posed in a virtual camera turned
#: towards them (:func:`ippe_on_rays`); nearer ones as they are (the pinhole path unchanged).
WIDE_DEG = 50.0
_COS_WIDE = float(np.cos(np.radians(WIDE_DEG)))
_EYE3 = np.eye(3)
_EYE3.flags.writeable = False


def bearings(pixels: F64, intrinsics: Intrinsics) -> F64:
    """Unit viewing rays of pixels, (N, 3), camera frame; NaN where the lens has none.

    :func:`multieye.core.lens.unproject_points` where the lens module has it (every model,
    rays beyond 90 degrees for the wide models); else the normalised coordinates of
    :func:`multieye.core.lens.undistort_points` made unit rays (z > 0 only).
    """
    unproject = getattr(lens, "unproject_points", None)
    if unproject is not None:
        return unproject(pixels, intrinsics)
    xy = lens.undistort_points(pixels, intrinsics)
    ray = np.column_stack([xy, np.ones(len(xy))])
    return ray / np.linalg.norm(ray, axis=1)[:, None]


def virtual_rotation(rays: F64) -> F64:
    """``R_v_cam``: the rotation taking the mean of ``rays`` (N, 3) onto the z axis (the
    smallest such turn), identity when they are centred on it already."""
    m = np.nanmean(rays, axis=0)
    m = m / np.linalg.norm(m)
    axis = np.cross(m, [0.0, 0.0, 1.0])
    s, c = np.linalg.norm(axis), float(m[2])
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return cv2.Rodrigues(axis / s * np.arctan2(s, c))[0]


def ippe_on_rays(object_points: F64, rays: F64) -> list[tuple[F64, F64]]:
    """IPPE's candidate poses ``(rvec, tvec)`` (camera from target) of planar points (z = 0)
    from their unit rays, in IPPE's order.

    When a ray is more than :data:`WIDE_DEG` off the lens axis the rays are first turned
    into a virtual camera looking along their mean (:func:`virtual_rotation`); the poses
    come back in the real camera's frame.  Rays on or behind that virtual camera's plane
    (a board seen over more than 180 degrees) leave the list of candidates empty.

    Parameters
    ----------
    object_points : ndarray, shape (N, 3)
        Target frame, z = 0, at least 4 points not on one line.
    rays : ndarray, shape (N, 3)
        Unit rays, camera frame, finite.
    """
    R_v = None
    if np.minimum.reduce(rays[:, 2]) < _COS_WIDE:
        R_v = virtual_rotation(rays)
        rays = rays @ R_v.T
    if np.minimum.reduce(rays[:, 2]) <= 1e-9:
        return []
    xy = np.ascontiguousarray(rays[:, :2] / rays[:, 2:3])
    _, rvecs, tvecs, _ = cv2.solvePnPGeneric(np.ascontiguousarray(object_points, np.float64),
                                             xy, _EYE3, None, flags=cv2.SOLVEPNP_IPPE)
    out = []
    for rvec, tvec in zip(rvecs, tvecs):
        rvec, tvec = rvec.reshape(3).copy(), tvec.reshape(3).copy()
        if R_v is not None:
            R = R_v.T @ cv2.Rodrigues(rvec)[0]
            rvec, tvec = cv2.Rodrigues(R)[0].reshape(3), R_v.T @ tvec
        out.append((rvec, tvec))
    return out
