"""Projection and undistortion for :class:`multieye.core.intrinsics.Intrinsics` (OpenCV models).

Two models, both as OpenCV defines them:

- ``"pinhole"``: ``cv2.projectPoints`` with 0, 4, 5, 8, 12 or 14 coefficients
  (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tauX tauY]]]]);
- ``"fisheye"``: ``cv2.fisheye`` equidistant model, k1..k4 (Kalibr ``equidistant``).

Normalised coordinates are ``(X / Z, Y / Z)`` of a point in the camera frame (x right, y
down, z forward); pixel (0, 0) is the centre of the top-left pixel (docs/conventions.md,
section 5).

Synopsis
--------
>>> import numpy as np
>>> from multieye.core.intrinsics import Intrinsics
>>> from multieye.core.lens import project_points, undistort_points
>>> cam = Intrinsics(K=[[600, 0, 400], [0, 600, 300], [0, 0, 1]], dist=[-0.2, 0.05, 0, 0])
>>> uv = project_points(np.array([[0.1, -0.05, 1.0]]), cam)
>>> np.allclose(undistort_points(uv, cam), [[0.1, -0.05]])
True
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics

__all__ = ["project_points", "project_with_jacobian", "distort_points", "undistort_points"]

F64 = NDArray[np.float64]

#: Points per call of the OpenCV routines, to bound temporary memory on large pixel grids.
_CHUNK = 1 << 18


def _as_points(points: ArrayLike, dim: int, name: str) -> F64:
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim == 1 and arr.size == dim:
        arr = arr.reshape(1, dim)
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise InputError(f"{name} must have shape (N, {dim}), got {arr.shape}")
    return arr


def distort_points(normalised: ArrayLike, intrinsics: Intrinsics) -> F64:
    """Pixels of normalised image coordinates (apply distortion and the camera matrix).

    Parameters
    ----------
    normalised : array_like, shape (N, 2)
        ``(X / Z, Y / Z)`` of points in front of the camera.
    intrinsics : Intrinsics

    Returns
    -------
    ndarray, shape (N, 2)
        Pixels; rows with non-finite input are NaN.
    """
    xy = _as_points(normalised, 2, "normalised points")
    return project_points(np.column_stack([xy, np.ones(len(xy))]), intrinsics)


def project_points(points_cam: ArrayLike, intrinsics: Intrinsics) -> F64:
    """Pixels of 3D points given in the camera frame.

    Parameters
    ----------
    points_cam : array_like, shape (N, 3)
        Points in the camera frame, metres (any unit: only ratios matter).
    intrinsics : Intrinsics

    Returns
    -------
    ndarray, shape (N, 2)
        Pixels. Points on or behind the camera plane (``Z <= 0``) and non-finite points give
        NaN: neither model defines their projection (the pinhole formula would mirror them).

    Notes
    -----
    Far outside the field of view a polynomial distortion model can fold back on itself, so
    the pixel it gives is meaningless even though it is finite; :func:`undistort_points`
    detects that case on the way back.
    """
    P = _as_points(points_cam, 3, "camera-frame points")
    out = np.full((len(P), 2), np.nan)
    ok = np.all(np.isfinite(P), axis=1) & (P[:, 2] > 0)
    if not np.any(ok):
        return out
    out[ok] = _project_normalised(P[ok, :2] / P[ok, 2:3], intrinsics)
    return out


def project_with_jacobian(points_cam: ArrayLike, intrinsics: Intrinsics
                          ) -> tuple[F64, F64, F64]:
    """Pixels of camera-frame points with their derivatives, from OpenCV's own Jacobians.

    ``cv2.projectPoints`` / ``cv2.fisheye.projectPoints`` are called with a zero pose, so the
    derivative of each pixel with respect to the translation is the derivative with respect
    to the point itself (``p_cam = R(0) p + t``).

    Parameters
    ----------
    points_cam : array_like, shape (P, 3)
        Points in the camera frame (x right, y down, z forward), metres, ``z > 0``.
    intrinsics : Intrinsics

    Returns
    -------
    uv : ndarray, shape (P, 2)
        Pixels, as :func:`project_points` (NaN on or behind the camera plane).
    J_point : ndarray, shape (P, 2, 3)
        ``d uv / d points_cam``, pixels per metre (NaN where ``uv`` is).
    J_intrinsics : ndarray, shape (P, 2, 4 + len(dist))
        ``d uv / d (fx, fy, cx, cy, dist...)``: the distortion coefficients in OpenCV's order
        (pinhole k1 k2 p1 p2 [k3 [k4 k5 k6 ...]]; fisheye k1..k4).
    """
    P = _as_points(points_cam, 3, "camera-frame points")
    n, nd = len(P), intrinsics.dist.size
    uv = np.full((n, 2), np.nan)
    J_point = np.full((n, 2, 3), np.nan)
    J_intr = np.full((n, 2, 4 + nd), np.nan)
    ok = np.all(np.isfinite(P), axis=1) & (P[:, 2] > 0)
    if not np.any(ok):
        return uv, J_point, J_intr
    obj = P[ok].reshape(-1, 1, 3)
    zero = np.zeros(3)
    if intrinsics.model == "fisheye":
        out, jac = cv2.fisheye.projectPoints(obj, zero, zero, intrinsics.K, intrinsics.dist)
        jac = jac.reshape(-1, 2, jac.shape[-1])
        jp, ji = jac[:, :, 11:14], jac[:, :, 0:8]
    else:
        out, jac = cv2.projectPoints(obj, zero, zero, intrinsics.K, intrinsics.dist)
        jac = jac.reshape(-1, 2, jac.shape[-1])
        jp, ji = jac[:, :, 3:6], jac[:, :, 6:10 + nd]
    uv[ok] = out.reshape(-1, 2)
    J_point[ok] = jp
    J_intr[ok] = ji
    return uv, J_point, J_intr


def _project_normalised(xy: F64, intrinsics: Intrinsics) -> F64:
    """Pixels of finite normalised coordinates (no checks)."""
    out = np.empty_like(xy)
    zero = np.zeros(3)
    for start in range(0, len(xy), _CHUNK):
        part = xy[start:start + _CHUNK]
        obj = np.column_stack([part, np.ones(len(part))]).reshape(-1, 1, 3)
        if intrinsics.model == "fisheye":
            uv, _ = cv2.fisheye.projectPoints(obj, zero, zero, intrinsics.K, intrinsics.dist)
        else:
            uv, _ = cv2.projectPoints(obj, zero, zero, intrinsics.K, intrinsics.dist)
        out[start:start + _CHUNK] = uv.reshape(-1, 2)
    return out


def undistort_points(pixels: ArrayLike, intrinsics: Intrinsics, *, tol_px: float = 1e-6,
                     max_newton: int = 8) -> F64:
    """Normalised image coordinates of pixels (remove the camera matrix and distortion).

    OpenCV's iterative undistortion (``cv2.undistortPointsIter``, ``cv2.fisheye.undistortPoints``)
    gives the starting point; Newton steps on the forward model (2x2 Jacobian by central
    differences) then bring the round trip :func:`distort_points` back to the input pixel.

    Parameters
    ----------
    pixels : array_like, shape (N, 2)
        Pixel coordinates.
    intrinsics : Intrinsics
    tol_px : float
        Round-trip error, pixels, at which a point counts as converged.
    max_newton : int
        Newton iterations at most.

    Returns
    -------
    ndarray, shape (N, 2)
        ``(X / Z, Y / Z)`` of the viewing ray of each pixel. NaN where the distortion model
        cannot be inverted to ``tol_px`` (pixels outside the region where the model is
        one-to-one, e.g. image corners of a strongly distorted lens with a polynomial model),
        and for non-finite input.
    """
    uv = _as_points(pixels, 2, "pixels")
    out = np.full((len(uv), 2), np.nan)
    ok = np.all(np.isfinite(uv), axis=1)
    if not np.any(ok):
        return out
    xy = _initial_undistort(uv[ok], intrinsics)
    target = uv[ok]
    h = 1e-7
    for _ in range(max_newton):
        f0 = _project_normalised(xy, intrinsics)
        r = target - f0
        err = np.hypot(r[:, 0], r[:, 1])
        active = np.isfinite(err) & (err > 0.01 * tol_px)
        if not np.any(active):
            break
        xa = xy[active]
        fx1 = _project_normalised(xa + [h, 0.0], intrinsics)
        fx0 = _project_normalised(xa - [h, 0.0], intrinsics)
        fy1 = _project_normalised(xa + [0.0, h], intrinsics)
        fy0 = _project_normalised(xa - [0.0, h], intrinsics)
        a, c = ((fx1 - fx0) / (2 * h)).T   # d(u, v)/dx
        b, d = ((fy1 - fy0) / (2 * h)).T   # d(u, v)/dy
        det = a * d - b * c
        ra = r[active]
        with np.errstate(divide="ignore", invalid="ignore"):
            dx = (d * ra[:, 0] - b * ra[:, 1]) / det
            dy = (-c * ra[:, 0] + a * ra[:, 1]) / det
        xy[active] = xa + np.column_stack([dx, dy])
    f0 = _project_normalised(xy, intrinsics)
    err = np.hypot(*(target - f0).T)
    xy[~(err <= tol_px)] = np.nan
    out[ok] = xy
    return out


def _initial_undistort(uv: F64, intrinsics: Intrinsics) -> F64:
    """OpenCV's iterative undistortion, as the start of the Newton polish."""
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-10)
    out = np.empty_like(uv)
    for start in range(0, len(uv), _CHUNK):
        part = uv[start:start + _CHUNK].reshape(-1, 1, 2)
        if intrinsics.model == "fisheye":
            xy = cv2.fisheye.undistortPoints(part, intrinsics.K, intrinsics.dist, criteria=criteria)
        else:
            xy = cv2.undistortPointsIter(part, intrinsics.K, intrinsics.dist, None, None, criteria)
        out[start:start + _CHUNK] = xy.reshape(-1, 2)
    return out
