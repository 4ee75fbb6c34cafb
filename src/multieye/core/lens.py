"""Projection and undistortion for :class:`multieye.core.intrinsics.Intrinsics`: the one lens
module the engine calls.

The wide-angle models (``"unified"``, ``"double-sphere"``, ``"eucm"``) are evaluated by
:mod:`multieye.core.lens_wide`, which defines them and their valid regions; the two OpenCV
models as OpenCV defines them:

- ``"pinhole"``: ``cv2.projectPoints`` with 0, 4, 5, 8, 12 or 14 coefficients
  (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tauX tauY]]]]);  OpenCV's formula is evaluated
  here in numpy for up to 12 coefficients (:func:`_pinhole`; the same pixels and Jacobians to
  rounding, 30 times faster: ``cv2.projectPoints`` always forms its 2N x 18 Jacobian and
  copies it out, about 0.35 us a point), by OpenCV with the tilt terms;
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

from multieye.core import lens_wide
from multieye.core.errors import InputError
from multieye.core.intrinsics import WIDE_MODELS, Intrinsics

__all__ = ["project_points", "project_with_jacobian", "distort_points", "undistort_points",
           "unproject_points", "projectable"]

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
        Pixels. Points outside the model's valid region (:func:`projectable`) and non-finite
        points give NaN: for the pinhole and fisheye models points on or behind the camera
        plane (``Z <= 0``; the pinhole formula would mirror them).

    Notes
    -----
    Far outside the field of view a polynomial distortion model can fold back on itself, so
    the pixel it gives is meaningless even though it is finite; :func:`undistort_points`
    detects that case on the way back.
    """
    P = _as_points(points_cam, 3, "camera-frame points")
    if intrinsics.model in WIDE_MODELS:
        return lens_wide.project(P, intrinsics)[0]
    ok = _in_front(P)
    if ok.all():
        return _project_normalised(P[:, :2] / P[:, 2:3], intrinsics)
    out = np.full((len(P), 2), np.nan)
    if not np.any(ok):
        return out
    out[ok] = _project_normalised(P[ok, :2] / P[ok, 2:3], intrinsics)
    return out


def _in_front(P: F64) -> NDArray[np.bool_]:
    """Finite points in front of the camera plane (``z > 0``)."""
    return np.all(np.isfinite(P), axis=1) & (P[:, 2] > 0)


def projectable(points_cam: ArrayLike, intrinsics: Intrinsics) -> NDArray[np.bool_]:
    """Which points the lens model projects: its valid region.

    Parameters
    ----------
    points_cam : array_like, shape (N, 3)
        Points in the camera frame (x right, y down, z forward).
    intrinsics : Intrinsics

    Returns
    -------
    ndarray, shape (N,), bool
        Pinhole and fisheye: finite points with ``z > 0``. Unified, double-sphere, eucm: the
        model's own region (:func:`multieye.core.lens_wide.projectable`), which admits rays
        beyond 90 degrees (``z <= 0``) for a wide lens.  :func:`project_points` and
        :func:`project_with_jacobian` give NaN exactly where this is False.
    """
    P = _as_points(points_cam, 3, "camera-frame points")
    if intrinsics.model in WIDE_MODELS:
        return lens_wide.projectable(P, intrinsics)
    return _in_front(P)


def unproject_points(pixels: ArrayLike, intrinsics: Intrinsics, *, tol_px: float = 1e-6,
                     max_newton: int = 8) -> F64:
    """Unit viewing rays of pixels, every model.

    Parameters
    ----------
    pixels : array_like, shape (N, 2)
        Pixel coordinates.
    intrinsics : Intrinsics
    tol_px, max_newton : float, int
        As :func:`undistort_points` (pinhole, fisheye, the unified model's distortion; the
        unified model takes at least 20 Newton steps).

    Returns
    -------
    ndarray, shape (N, 3)
        Unit rays in the camera frame; NaN where the pixel has no ray in the model's valid
        region (:func:`projectable`) or the distortion cannot be inverted to ``tol_px``.
    """
    uv = _as_points(pixels, 2, "pixels")
    if intrinsics.model in WIDE_MODELS:
        return lens_wide.unproject(uv, intrinsics, tol_px=tol_px,
                                   max_newton=max(max_newton, 20))
    xy = undistort_points(uv, intrinsics, tol_px=tol_px, max_newton=max_newton)
    ray = np.column_stack([xy, np.ones(len(xy))])
    # np.linalg.norm(ray, axis=1) as it computes it, without its overhead
    return ray / np.sqrt(np.add.reduce(ray * ray, axis=1))[:, None]


def project_with_jacobian(points_cam: ArrayLike, intrinsics: Intrinsics, *,
                          lens_jacobian: bool = True) -> tuple[F64, F64, F64 | None]:
    """Pixels of camera-frame points with their derivatives, from OpenCV's own Jacobians.

    ``cv2.projectPoints`` / ``cv2.fisheye.projectPoints`` are called with a zero pose, so the
    derivative of each pixel with respect to the translation is the derivative with respect
    to the point itself (``p_cam = R(0) p + t``).

    Parameters
    ----------
    points_cam : array_like, shape (P, 3)
        Points in the camera frame (x right, y down, z forward), metres, ``z > 0``.
    intrinsics : Intrinsics
    lens_jacobian : bool
        Also ``J_intrinsics`` (else None: a lens held fixed needs no derivative by it).

    Returns
    -------
    uv : ndarray, shape (P, 2)
        Pixels, as :func:`project_points` (NaN on or behind the camera plane).
    J_point : ndarray, shape (P, 2, 3)
        ``d uv / d points_cam``, pixels per metre (NaN where ``uv`` is).
    J_intrinsics : ndarray, shape (P, 2, 4 + len(dist)), or None
        ``d uv / d (fx, fy, cx, cy, dist...)``: the distortion coefficients in OpenCV's order
        (pinhole k1 k2 p1 p2 [k3 [k4 k5 k6 ...]]; fisheye k1..k4); the wide-angle models'
        parameters in :attr:`Intrinsics.dist`'s order (analytic derivatives,
        :func:`multieye.core.lens_wide.project`).
    """
    P = _as_points(points_cam, 3, "camera-frame points")
    if intrinsics.model in WIDE_MODELS:
        return lens_wide.project(P, intrinsics, jacobians=True, lens_jacobian=lens_jacobian)
    n, nd = len(P), intrinsics.dist.size
    ok = _in_front(P)
    every = bool(ok.all())
    if every and _numpy_pinhole(intrinsics):
        return _pinhole_points(P, intrinsics, lens_jacobian)
    uv = np.full((n, 2), np.nan)
    J_point = np.full((n, 2, 3), np.nan)
    J_intr = np.full((n, 2, 4 + nd), np.nan) if lens_jacobian else None
    if not np.any(ok):
        return uv, J_point, J_intr
    if _numpy_pinhole(intrinsics):
        uv[ok], J_point[ok], ji = _pinhole_points(P[ok], intrinsics, lens_jacobian)
        if lens_jacobian:
            J_intr[ok] = ji
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
    if lens_jacobian:
        J_intr[ok] = ji
    return uv, J_point, J_intr


def _numpy_pinhole(intrinsics: Intrinsics) -> bool:
    """Whether :func:`_pinhole` evaluates this lens (a pinhole without the tilt terms)."""
    return intrinsics.model != "fisheye" and intrinsics.dist.size <= 12


def _pinhole(xy: F64, intrinsics: Intrinsics, jacobians: bool = False,
             lens_jacobian: bool = True):
    """OpenCV's pinhole model (``cvProjectPoints2``) on normalised coordinates, in numpy.

    With ``x, y`` the normalised coordinates, ``r2 = x^2 + y^2`` and the coefficients
    k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 (missing ones zero)::

        c  = (1 + k1 r2 + k2 r2^2 + k3 r2^3) / (1 + k4 r2 + k5 r2^2 + k6 r2^3)
        xd = x c + 2 p1 x y + p2 (r2 + 2 x^2) + s1 r2 + s2 r2^2
        yd = y c + p1 (r2 + 2 y^2) + 2 p2 x y + s3 r2 + s4 r2^2
        u  = fx xd + cx,   v = fy yd + cy        (the skew K[0, 1] is ignored, as OpenCV does)

    Parameters
    ----------
    xy : ndarray, shape (N, 2)
        Finite normalised coordinates.
    intrinsics : Intrinsics
        Pinhole, at most 12 distortion coefficients.
    jacobians : bool
        Also return the derivatives (``J_intrinsics`` only with ``lens_jacobian``).
    lens_jacobian : bool

    Returns
    -------
    uv : ndarray, shape (N, 2)
        Pixels.
    J_xy : ndarray, shape (N, 2, 2)
        ``d uv / d xy`` (with ``jacobians``, else None).
    J_intrinsics : ndarray, shape (N, 2, 4 + len(dist))
        ``d uv / d (fx, fy, cx, cy, dist...)`` (with ``jacobians``, else None).
    """
    nd = intrinsics.dist.size
    k = np.zeros(12)
    k[:nd] = intrinsics.dist
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = k
    K = intrinsics.K
    fx, fy = K[0, 0], K[1, 1]
    x, y = xy[:, 0], xy[:, 1]
    x2, y2, xy2 = x * x, y * y, 2.0 * x * y
    r2 = x2 + y2
    r4 = r2 * r2
    r6 = r4 * r2
    num = 1.0 + k1 * r2 + k2 * r4 + k3 * r6
    den = 1.0 / (1.0 + k4 * r2 + k5 * r4 + k6 * r6)
    c = num * den
    xd = x * c + p1 * xy2 + p2 * (r2 + 2.0 * x2) + s1 * r2 + s2 * r4
    yd = y * c + p1 * (r2 + 2.0 * y2) + p2 * xy2 + s3 * r2 + s4 * r4
    uv = np.empty((len(xy), 2))
    uv[:, 0] = fx * xd + K[0, 2]
    uv[:, 1] = fy * yd + K[1, 2]
    if not jacobians:
        return uv, None, None
    # d c / d r2, and the derivatives of xd, yd by x and y
    dc = ((k1 + 2.0 * k2 * r2 + 3.0 * k3 * r4) - c * (k4 + 2.0 * k5 * r2 + 3.0 * k6 * r4)) * den
    sx, sy = s1 + 2.0 * s2 * r2, s3 + 2.0 * s4 * r2
    J_xy = np.empty((len(xy), 2, 2))
    J_xy[:, 0, 0] = fx * (c + 2.0 * x2 * dc + 2.0 * p1 * y + 6.0 * p2 * x + 2.0 * sx * x)
    J_xy[:, 0, 1] = fx * (xy2 * dc + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * sx * y)
    J_xy[:, 1, 0] = fy * (xy2 * dc + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * sy * x)
    J_xy[:, 1, 1] = fy * (c + 2.0 * y2 * dc + 6.0 * p1 * y + 2.0 * p2 * x + 2.0 * sy * y)
    if not lens_jacobian:
        return uv, J_xy, None
    J_k = np.zeros((len(xy), 2, 4 + nd))
    J_k[:, 0, 0], J_k[:, 1, 1] = xd, yd
    J_k[:, 0, 2] = J_k[:, 1, 3] = 1.0
    # d (xd, yd) / d coefficient, OpenCV's order: k1 k2 (x, y times r2, r4 over the
    # denominator), p1 p2, k3 (r6), k4 k5 k6 (minus c times r2, r4, r6 over it), s1 s2 s3 s4
    powers = (r2, r4, r6)
    for i in range(nd):
        if i in (0, 1, 4, 5, 6, 7):
            f = powers[(0, 1, -1, -1, 2, 0, 1, 2)[i]] * den * (-c if i >= 5 else 1.0)
            J_k[:, 0, 4 + i] = fx * x * f
            J_k[:, 1, 4 + i] = fy * y * f
        elif i == 2:
            J_k[:, 0, 4 + i] = fx * xy2
            J_k[:, 1, 4 + i] = fy * (r2 + 2.0 * y2)
        elif i == 3:
            J_k[:, 0, 4 + i] = fx * (r2 + 2.0 * x2)
            J_k[:, 1, 4 + i] = fy * xy2
        else:                                      # s1 s2 move xd, s3 s4 move yd
            row = (i - 8) // 2
            J_k[:, row, 4 + i] = (fx, fy)[row] * powers[i % 2]
    return uv, J_xy, J_k


def _pinhole_points(P: F64, intrinsics: Intrinsics, lens_jacobian: bool = True
                    ) -> tuple[F64, F64, F64 | None]:
    """:func:`project_with_jacobian` of points in front of a pinhole camera, by
    :func:`_pinhole`: ``d xy / d p = [[1, 0, -x], [0, 1, -y]] / z``."""
    inv_z = 1.0 / P[:, 2]
    xy = P[:, :2] * inv_z[:, None]
    uv, jx, ji = _pinhole(xy, intrinsics, jacobians=True, lens_jacobian=lens_jacobian)
    jp = np.empty((len(P), 2, 3))
    jp[:, :, :2] = jx * inv_z[:, None, None]
    jp[:, :, 2] = -(jp[:, :, 0] * xy[:, 0:1] + jp[:, :, 1] * xy[:, 1:2])
    return uv, jp, ji


def _project_normalised(xy: F64, intrinsics: Intrinsics) -> F64:
    """Pixels of finite normalised coordinates (no checks)."""
    if _numpy_pinhole(intrinsics):
        return _pinhole(xy, intrinsics)[0]
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
        for non-finite input, and, for the wide-angle models, where the ray has ``Z <= 0``
        (:func:`unproject_points` gives those rays).
    """
    uv = _as_points(pixels, 2, "pixels")
    if intrinsics.model in WIDE_MODELS:
        ray = unproject_points(uv, intrinsics, tol_px=tol_px, max_newton=max_newton)
        with np.errstate(invalid="ignore", divide="ignore"):
            xy = ray[:, :2] / ray[:, 2:3]
        xy[~(ray[:, 2] > 0)] = np.nan
        return xy
    out = np.full((len(uv), 2), np.nan)
    ok = np.all(np.isfinite(uv), axis=1)
    if not np.any(ok):
        return out
    xy = _initial_undistort(uv[ok], intrinsics)
    target = uv[ok]
    h = 1e-7
    f0 = _project_normalised(xy, intrinsics)
    for _ in range(max_newton):
        r = target - f0
        err = np.hypot(r[:, 0], r[:, 1])
        active = np.isfinite(err) & (err > 0.01 * tol_px)
        if not np.any(active):
            break
        xa = xy[active]
        # the four central-difference points in one call (the model is per point)
        fx1, fx0, fy1, fy0 = np.split(_project_normalised(np.concatenate(
            [xa + [h, 0.0], xa - [h, 0.0], xa + [0.0, h], xa - [0.0, h]]), intrinsics), 4)
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
