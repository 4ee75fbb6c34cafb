"""Wide-angle lens models in numpy: projection, analytic Jacobians, unprojection, valid region.

Three models of :class:`multieye.core.intrinsics.Intrinsics` (``dist`` after fx fy cx cy), each
``u = fx m_x + cx, v = fy m_y + cy`` of a point ``X = (x, y, z)`` in the camera frame (x right,
y down, z forward; any unit) through its own ``m``:

``"unified"`` (xi, k1, k2, p1, p2)
    Mei and Rives, "Single View Point Omnidirectional Camera Calibration from Planar Grids",
    ICRA 2007, section II (Kalibr ``omni`` + ``radtan``, BoofCV ``omnidirectional_universal``
    with ``mirror_offset`` = xi): the point on the unit sphere ``s = X / |X|`` seen from
    ``(0, 0, -xi)``, ``m_u = (s_x, s_y) / (s_z + xi) = (x, y) / (z + xi |X|)``, then OpenCV's
    (and Kalibr's, BoofCV's) radial-tangential distortion ``m = dist(m_u)`` with k1 k2 p1 p2.
``"double-sphere"`` (xi, alpha)
    Usenko, Demmel and Cremers, "The Double Sphere Camera Model", 3DV 2018, eqs. (40)-(42)
    (Kalibr ``ds``, Basalt ``ds``): ``d1 = |X|``, ``k = xi d1 + z``,
    ``d2 = |(x, y, k)|``, ``m = (x, y) / (alpha d2 + (1 - alpha) k)``.
``"eucm"`` (alpha, beta)
    Khomutenko, Garcia and Martinet, "An Enhanced Unified Camera Model", IEEE RA-L 1(1) 2016,
    as written in Usenko et al. 2018, section 3 (Kalibr ``eucm``, Basalt ``eucm``):
    ``d = sqrt(beta (x^2 + y^2) + z^2)``, ``m = (x, y) / (alpha d + (1 - alpha) z)``.

Each model is defined on its valid region (:func:`projectable`), which for a wide lens
includes rays beyond 90 degrees (``z <= 0``); outside it the pixel is NaN, and so is the ray of
a pixel that no ray of the region maps to (:func:`unproject`).  Special cases, which the tests
check: unified with xi = 0 is the pinhole with radial-tangential distortion; eucm with
alpha = 0 is the pinhole; double-sphere with xi = 0 and eucm with beta = 1 are the unified
camera model (UCM) with alpha; the UCM with alpha is the undistorted unified model with
``xi = alpha / (1 - alpha)`` and focal lengths ``f / (1 - alpha)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from multieye.core.intrinsics import Intrinsics

__all__ = ["projectable", "project", "unproject"]

F64 = NDArray[np.float64]


def _w_ucm(alpha: float) -> float:
    """Usenko et al. 2018 eq. (45), ``w1``: the bound ``cos > -w`` on the angle of a ray from
    the optical axis within which the UCM with ``alpha`` is one-to-one with a positive
    denominator.  Its radius ``sin p / (alpha + (1 - alpha) cos p)`` has the derivative's sign
    of ``alpha cos p + 1 - alpha``, so it grows up to ``cos p = -(1 - alpha) / alpha``
    (binding for alpha > 1/2); the denominator is positive for
    ``cos p > -alpha / (1 - alpha)`` (binding for alpha <= 1/2)."""
    return (1.0 - alpha) / alpha if alpha > 0.5 else alpha / (1.0 - alpha)


def _region_cosine(intrinsics: Intrinsics) -> float:
    """``w`` of the valid region ``z > -w d`` (:func:`projectable`), at most 1."""
    model, dist = intrinsics.model, intrinsics.dist
    if model == "eucm":
        return _w_ucm(dist[0])
    xi = dist[0]
    if xi > 1.0:
        return 1.0 / xi
    if model == "unified":
        return xi
    w1 = _w_ucm(dist[1])
    c = 1.0 - w1 * w1
    return min(1.0, xi * c + w1 * np.sqrt(max(0.0, 1.0 - xi * xi * c)))


def projectable(P: F64, intrinsics: Intrinsics) -> NDArray[np.bool_]:
    """The model's valid region: the finite points it projects one-to-one.

    Every region is ``z > -w d`` for a constant ``w <= 1``, with ``d = |X|`` (eucm:
    ``d = sqrt(beta (x^2 + y^2) + z^2)``):

    - unified: ``w = xi`` for ``xi <= 1`` (the ray from the viewpoint ``(0, 0, -xi)`` meets
      the sphere point in front of it, ``s_z + xi > 0``; Mei and Rives 2007, section II) and
      ``w = 1 / xi`` for ``xi > 1`` (then ``s_z + xi > 0`` everywhere, but the viewpoint is
      outside the unit sphere and each of its rays meets the sphere twice: only the cap in
      front of its tangent cone, ``s_z > -1/xi``, is seen once); Kalibr's
      ``OmniProjection`` uses the same bound;
    - eucm: ``w = w1(alpha)`` (:func:`_w_ucm`; Usenko et al. 2018, section 3.3): the eucm is
      the UCM of ``(sqrt(beta) x, sqrt(beta) y, z)``, scaled;
    - double-sphere: the sphere point ``s = X / |X|`` is seen by the UCM from
      ``(0, 0, -xi)``, at the angle ``cos p = (s_z + xi) / sqrt(1 + 2 xi s_z + xi^2)``, which
      must satisfy ``cos p > -w1``.  For ``-1 < xi <= 1`` (viewpoint inside the sphere, ``p``
      growing with the angle of ``s``) that is ``s_z > -w`` with
      ``w = xi (1 - w1^2) + w1 sqrt(1 - xi^2 (1 - w1^2))`` (the root of
      ``(s_z + xi)^2 = w1^2 (1 + 2 xi s_z + xi^2)`` with ``s_z + xi <= 0``); for ``xi > 1``
      the tangent cone binds first, ``w = 1 / xi``, as for the unified model (which is the
      double sphere with alpha = 0).  Usenko et al. 2018 eqs. (43)-(44), which Kalibr and
      Basalt use, give instead ``w2 = (w1 + xi) / sqrt(2 w1 xi + xi^2 + 1)``: equal for
      ``xi = 0`` and for alpha = 1/2, smaller (a region short of the model's) for
      ``0 < xi < 1``, and larger for ``xi > 1``, where it admits rays whose pixel another
      ray of the region has too.

    Parameters
    ----------
    P : ndarray, shape (N, 3)
        Points in the camera frame.
    intrinsics : Intrinsics
        A model of :data:`multieye.core.intrinsics.WIDE_MODELS`.

    Returns
    -------
    ndarray, shape (N,), bool
    """
    x, y, z = P[:, 0], P[:, 1], P[:, 2]
    with np.errstate(invalid="ignore", over="ignore"):
        r2 = x * x + y * y
        if intrinsics.model == "eucm":
            r2 = intrinsics.dist[1] * r2
        return np.all(np.isfinite(P), axis=1) & (
            z > -_region_cosine(intrinsics) * np.sqrt(r2 + z * z))


def _denominator(P: F64, intrinsics: Intrinsics, jacobians: bool):
    """The model's ``D`` in ``m = (x, y) / D`` (before the unified model's distortion), with
    ``d D / d X`` (N, 3) and ``d D / d (model parameters before any distortion)`` (N, k)."""
    x, y, z = P[:, 0], P[:, 1], P[:, 2]
    r2 = x * x + y * y
    model, dist = intrinsics.model, intrinsics.dist
    if model == "eucm":
        alpha, beta = dist
        d = np.sqrt(beta * r2 + z * z)
        D = alpha * d + (1.0 - alpha) * z
        if not jacobians:
            return D, None, None
        dD = alpha * np.column_stack([beta * x, beta * y, z]) / d[:, None]
        dD[:, 2] += 1.0 - alpha
        return D, dD, np.column_stack([d - z, alpha * r2 / (2.0 * d)])
    xi = dist[0]
    d1 = np.sqrt(r2 + z * z)
    if model == "unified":
        D = z + xi * d1
        if not jacobians:
            return D, None, None
        dD = xi * P / d1[:, None]
        dD[:, 2] += 1.0
        return D, dD, d1[:, None]
    alpha = dist[1]
    k = xi * d1 + z
    d2 = np.sqrt(r2 + k * k)
    D = alpha * d2 + (1.0 - alpha) * k
    if not jacobians:
        return D, None, None
    dk = xi * P / d1[:, None]
    dk[:, 2] += 1.0
    g = alpha * k / d2 + (1.0 - alpha)                 # d D / d k
    dD = g[:, None] * dk
    dD[:, :2] += alpha * P[:, :2] / d2[:, None]
    return D, dD, np.column_stack([g * d1, d2 - k])


def _radtan(m: F64, k: F64, jacobians: bool):
    """OpenCV's (Kalibr's, BoofCV's) radial-tangential distortion with k1 k2 p1 p2:
    ``c = 1 + k1 r2 + k2 r2^2``, ``x' = x c + 2 p1 x y + p2 (r2 + 2 x^2)``,
    ``y' = y c + p1 (r2 + 2 y^2) + 2 p2 x y``; with ``d m' / d m`` (N, 2, 2) and
    ``d m' / d (k1, k2, p1, p2)`` (N, 2, 4)."""
    k1, k2, p1, p2 = k
    x, y = m[:, 0], m[:, 1]
    x2, y2, xy = x * x, y * y, x * y
    r2 = x2 + y2
    c = 1.0 + k1 * r2 + k2 * r2 * r2
    out = np.column_stack([x * c + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2),
                           y * c + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy])
    if not jacobians:
        return out, None, None
    dc = k1 + 2.0 * k2 * r2                            # d c / d r2
    Jm = np.empty((len(m), 2, 2))
    Jm[:, 0, 0] = c + 2.0 * x2 * dc + 2.0 * p1 * y + 6.0 * p2 * x
    Jm[:, 0, 1] = Jm[:, 1, 0] = 2.0 * xy * dc + 2.0 * p1 * x + 2.0 * p2 * y
    Jm[:, 1, 1] = c + 2.0 * y2 * dc + 6.0 * p1 * y + 2.0 * p2 * x
    Jk = np.empty((len(m), 2, 4))
    Jk[:, 0, 0], Jk[:, 1, 0] = x * r2, y * r2
    Jk[:, 0, 1], Jk[:, 1, 1] = x * r2 * r2, y * r2 * r2
    Jk[:, 0, 2], Jk[:, 1, 2] = 2.0 * xy, r2 + 2.0 * y2
    Jk[:, 0, 3], Jk[:, 1, 3] = r2 + 2.0 * x2, 2.0 * xy
    return out, Jm, Jk


def project(P: F64, intrinsics: Intrinsics, jacobians: bool = False,
            lens_jacobian: bool = True) -> tuple[F64, F64 | None, F64 | None]:
    """Pixels of camera-frame points, and their analytic derivatives.

    Parameters
    ----------
    P : ndarray, shape (N, 3)
        Points in the camera frame, any unit.
    intrinsics : Intrinsics
        A model of :data:`multieye.core.intrinsics.WIDE_MODELS`.
    jacobians : bool
        Also ``d uv / d P`` (and ``d uv / d params`` with ``lens_jacobian``).
    lens_jacobian : bool

    Returns
    -------
    uv : ndarray, shape (N, 2)
        Pixels; NaN where :func:`projectable` is False.
    J_point : ndarray, shape (N, 2, 3), or None
        ``d uv / d P`` (NaN where ``uv`` is).
    J_intrinsics : ndarray, shape (N, 2, 4 + len(dist)), or None
        ``d uv / d (fx, fy, cx, cy, dist...)``.
    """
    n, nd = len(P), intrinsics.dist.size
    ok = projectable(P, intrinsics)
    uv = np.full((n, 2), np.nan)
    J_point = np.full((n, 2, 3), np.nan) if jacobians else None
    J_intr = np.full((n, 2, 4 + nd), np.nan) if jacobians and lens_jacobian else None
    if not np.any(ok):
        return uv, J_point, J_intr
    Q = P[ok]
    K = intrinsics.K
    f = np.array([K[0, 0], K[1, 1]])
    D, dD, dDp = _denominator(Q, intrinsics, jacobians)
    m = Q[:, :2] / D[:, None]
    unified = intrinsics.model == "unified"
    if unified:
        md, Jd, Jk = _radtan(m, intrinsics.dist[1:], jacobians)
    else:
        md = m
    uv[ok] = md * f + K[:2, 2]
    if not jacobians:
        return uv, None, None
    # d m / d X = ([I2 | 0] - m dD/dX) / D;  d m / d theta = -m dD/dtheta / D
    Jm = -m[:, :, None] * dD[:, None, :]
    Jm[:, 0, 0] += 1.0
    Jm[:, 1, 1] += 1.0
    Jm /= D[:, None, None]
    Jt = -m[:, :, None] * dDp[:, None, :] / D[:, None, None]
    if unified:
        Jm = np.einsum("nij,njk->nik", Jd, Jm)
        Jt = np.concatenate([np.einsum("nij,njk->nik", Jd, Jt), Jk], axis=2)
    J_point[ok] = Jm * f[None, :, None]
    if lens_jacobian:
        Ji = np.zeros((len(Q), 2, 4 + nd))
        Ji[:, 0, 0], Ji[:, 1, 1] = md[:, 0], md[:, 1]
        Ji[:, 0, 2] = Ji[:, 1, 3] = 1.0
        Ji[:, :, 4:] = Jt * f[None, :, None]
        J_intr[ok] = Ji
    return uv, J_point, J_intr


def _undistort_radtan(md: F64, k: F64, f: F64, tol_px: float, max_newton: int) -> F64:
    """``m_u`` with ``_radtan(m_u) = md``, by Newton's method from ``m_u = md`` with the
    analytic 2x2 Jacobian; NaN where the residual stays above ``tol_px`` pixels (``f`` the
    focal lengths, to measure it in pixels), e.g. where the polynomial folds back."""
    mu = md.copy()
    if not np.any(k):
        return mu
    active = np.ones(len(md), dtype=bool)
    for _ in range(max_newton):
        out, J, _ = _radtan(mu[active], k, True)
        r = md[active] - out
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.column_stack([J[:, 1, 1] * r[:, 0] - J[:, 0, 1] * r[:, 1],
                                    J[:, 0, 0] * r[:, 1] - J[:, 1, 0] * r[:, 0]]) / det[:, None]
        mu[active] += step
        small = ~(np.abs(step * f).max(axis=1) > 1e-6 * tol_px)   # NaN steps stop too
        idx = np.flatnonzero(active)
        active[idx[small]] = False
        if not np.any(active):
            break
    with np.errstate(invalid="ignore"):
        err = np.abs((_radtan(mu, k, False)[0] - md) * f).max(axis=1)
    mu[~(err <= tol_px)] = np.nan
    return mu


def unproject(uv: F64, intrinsics: Intrinsics, tol_px: float = 1e-6,
              max_newton: int = 20) -> F64:
    """Unit viewing rays of pixels (closed forms; the unified model's distortion by Newton).

    - unified: ``m_u`` from the distorted ``m`` by Newton's method, then Mei and Rives'
      lift to the sphere, ``s = eta (m_x, m_y, 1) - (0, 0, xi)`` with
      ``eta = (xi + sqrt(1 + (1 - xi^2) r^2)) / (1 + r^2)``, ``r^2 = |m_u|^2``;
    - double-sphere: Usenko et al. 2018 eqs. (46)-(50): ``m_z = (1 - alpha^2 r^2) /
      (alpha sqrt(1 - (2 alpha - 1) r^2) + 1 - alpha)`` and
      ``s = (m_z xi + sqrt(m_z^2 + (1 - xi^2) r^2)) / (m_z^2 + r^2) (m_x, m_y, m_z) - (0, 0, xi)``,
      defined for ``r^2 <= 1 / (2 alpha - 1)`` when alpha > 1/2 (eq. (51));
    - eucm: ``m_z = (1 - beta alpha^2 r^2) / (alpha sqrt(1 - (2 alpha - 1) beta r^2) + 1 -
      alpha)``, ray ``(m_x, m_y, m_z)``, for ``r^2 <= 1 / (beta (2 alpha - 1))`` when
      alpha > 1/2 (the root of ``alpha d + (1 - alpha) m_z = 1``).

    Parameters
    ----------
    uv : ndarray, shape (N, 2)
        Pixels.
    intrinsics : Intrinsics
        A model of :data:`multieye.core.intrinsics.WIDE_MODELS`.
    tol_px : float
        Unified model: the distortion's round trip error, pixels, accepted.
    max_newton : int
        Unified model: Newton iterations at most.

    Returns
    -------
    ndarray, shape (N, 3)
        Unit rays in the camera frame; NaN for non-finite pixels, pixels outside the model's
        image of the sphere, and rays outside :func:`projectable` (so that projecting a ray
        returned gives its pixel back).
    """
    K, dist = intrinsics.K, intrinsics.dist
    f = np.array([K[0, 0], K[1, 1]])
    m = (uv - K[:2, 2]) / f
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if intrinsics.model == "unified":
            xi = dist[0]
            mu = _undistort_radtan(m, dist[1:], f, tol_px, max_newton)
            r2 = np.sum(mu * mu, axis=1)
            eta = (xi + np.sqrt(1.0 + (1.0 - xi * xi) * r2)) / (1.0 + r2)
            ray = np.column_stack([eta * mu[:, 0], eta * mu[:, 1], eta - xi])
        else:
            r2 = np.sum(m * m, axis=1)
            alpha, b = (dist[1], 1.0) if intrinsics.model == "double-sphere" else dist
            mz = (1.0 - b * alpha * alpha * r2) / (
                alpha * np.sqrt(1.0 - (2.0 * alpha - 1.0) * b * r2) + 1.0 - alpha)
            ray = np.column_stack([m, mz])
            if intrinsics.model == "double-sphere":
                xi = dist[0]
                mz2 = mz * mz
                eta = (mz * xi + np.sqrt(mz2 + (1.0 - xi * xi) * r2)) / (mz2 + r2)
                ray = eta[:, None] * ray
                ray[:, 2] -= xi
        ray /= np.linalg.norm(ray, axis=1)[:, None]
    ray[~projectable(ray, intrinsics)] = np.nan
    return ray
