"""A wide-angle lens written by the pixels of its radial curve, where its parameters have a
curved valley (issue 33).

The unified model's focal length, ``k1`` and ``k2`` move with its ``xi`` along a curved valley
of nearly equal images, and the double sphere's focal length and ``alpha`` with its ``xi``
(:mod:`multieye.imaging.lens_valley`).  The estimate's error then lies along that curve, and
the covariance of the published parameters, a straight ellipsoid, does not describe it: on 20
views of a unified lens of 190 degrees (0.2 px noise, 60 draws; ``benchmarks/
bench_wide_lens.py`` section 2b) the error's NEES / dim in those parameters averages 267,
while the spread of ``fx``, ``xi``, ``k1`` is half the one predicted.  The same lens written
by the pixels of its curve is nearly linear in the data (NEES / dim 1.96 there, 1.08 without
``xi``, whose own cost is not quadratic):

- unified ``(xi, k1, k2, p1, p2)``: ``fx``, ``k1``, ``k2`` replaced by ``rho_1..rho_3``;
- double-sphere ``(xi, alpha)``: ``fx``, ``alpha`` replaced by ``rho_1, rho_2``;

with ``rho_j`` the pixel offset from ``cx`` along the image's x axis of the ray at
``theta_j = 0.9 theta_max j / n`` off the axis, and ``fy`` replaced by ``fy / fx``; ``cx``,
``cy`` and the other parameters kept.  Given ``xi`` (and the unified model's ``p1, p2``),
``rho`` is linear in ``(fx, fx k1, fx k2)`` (unified) or in ``(fx, alpha)`` after multiplying
by the denominator (double sphere), so the map is one-to-one.  The Gauss-Newton covariance of
an estimator in these parameters is exactly ``G C G^T`` of the published one, ``G`` the
derivative of the map at the estimate (its Jacobian is the published one times ``G^-1``), so
:func:`curve_covariance` is what such an estimator reports, at the same optimum.

What a user is given (calibration.json's ``lens_curve``) is :func:`radial_curve`: for any
wide or fisheye lens (:data:`RADIAL_CURVE_MODELS`), the pixel radii of :data:`CURVE_RAYS`
rays spread over the observed field (:func:`observed_angles`) and their covariance, the
marginal of the curve parameters' (for the unified model at the same rays, the ``rho`` block
of :func:`curve_covariance`).  Where the published parameters' covariance is not honest (the
unified model's at 190 degrees, rendered: NEES / dim 12.5 over 10 runs, one at 98, the
estimate at the truth's optimum but the cost not quadratic in ``xi``) these radii's is (NEES /
3 0.91 on the same runs; docs/results/wide_render.md, sections 4 and 5).

Synopsis
--------
>>> phi = curve_parameters(lens, theta_max)                           # doctest: +SKIP
>>> C_phi = curve_covariance(lens, C, theta_max)                      # doctest: +SKIP
>>> curve = observed_curve(lens, C, points_cam)                     # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
from dataclasses import dataclass

from numpy.typing import NDArray

from multieye.core.intrinsics import Intrinsics, parameter_names
from multieye.core.lens import project_with_jacobian, projectable

__all__ = ["undetermined_parameters", "CURVE_MODELS", "curve_parameters", "curve_jacobian", "curve_covariance",
           "curve_names", "RadialCurve", "radial_curve", "observed_angles", "CURVE_RAYS",
           "RADIAL_CURVE_MODELS", "observed_curve"]

F64 = NDArray[np.float64]

#: Per model: the indices in ``params`` (fx fy cx cy dist...) replaced by the curve's pixels.
CURVE_MODELS = {"unified": (0, 5, 6), "double-sphere": (0, 5)}
#: The models (``Intrinsics.model``) whose :func:`radial_curve` calibration.json states.
RADIAL_CURVE_MODELS = ("fisheye", "unified", "double-sphere", "eucm")
#: Rays of the radial curve stated (:func:`observed_angles`).
CURVE_RAYS = 3


def _angles(model: str, theta_max: float) -> F64:
    n = len(CURVE_MODELS[model])
    return 0.9 * theta_max * np.arange(1, n + 1) / n


def _kept(intrinsics: Intrinsics) -> list[int]:
    gone = set(CURVE_MODELS[intrinsics.model]) | {1}
    return [i for i in range(intrinsics.params.size) if i not in gone]


def curve_names(intrinsics: Intrinsics) -> list[str]:
    """Names of :func:`curve_parameters`' entries (``rho_1``.., ``fy/fx``, the kept ones)."""
    names = parameter_names(intrinsics)
    n = len(CURVE_MODELS[intrinsics.model])
    return [f"rho_{j + 1}" for j in range(n)] + ["fy/fx"] + [names[i] for i in
                                                               _kept(intrinsics)]


def curve_jacobian(intrinsics: Intrinsics, theta_max: float) -> tuple[F64, F64]:
    """The lens' curve parameters and their derivative in its published parameters.

    Parameters
    ----------
    intrinsics : Intrinsics
        A model of :data:`CURVE_MODELS`.
    theta_max : float
        Radians off the axis up to which the lens is observed (sets the rays' angles).

    Returns
    -------
    phi : ndarray, shape (p,)
        ``(rho_1.., fy / fx, cx, cy, the other parameters)``; rho in pixels.
    G : ndarray, shape (p, p)
        ``d phi / d params`` (params = ``intrinsics.params``).
    """
    p = intrinsics.params
    theta = _angles(intrinsics.model, theta_max)
    rays = np.column_stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)])
    uv, _, Ji = project_with_jacobian(rays, intrinsics)
    kept = _kept(intrinsics)
    n = len(theta)
    G = np.zeros((n + 1 + len(kept), p.size))
    G[:n] = Ji[:, 0, :]
    G[:n, 2] -= 1.0                                    # rho = u - cx
    G[n, 0], G[n, 1] = -p[1] / p[0] ** 2, 1.0 / p[0]
    G[n + 1 + np.arange(len(kept)), kept] = 1.0
    phi = np.concatenate([uv[:, 0] - p[2], [p[1] / p[0]], p[kept]])
    return phi, G


def curve_parameters(intrinsics: Intrinsics, theta_max: float) -> F64:
    """The lens' curve parameters (:func:`curve_jacobian`'s ``phi``)."""
    return curve_jacobian(intrinsics, theta_max)[0]


def curve_covariance(intrinsics: Intrinsics, covariance: F64, theta_max: float) -> F64:
    """The covariance of the curve parameters, ``G C G^T``, from the published parameters'
    ``covariance`` (p, p) at ``intrinsics`` (module docstring)."""
    G = curve_jacobian(intrinsics, theta_max)[1]
    return G @ np.asarray(covariance, np.float64) @ G.T


@dataclass(frozen=True)
class RadialCurve:
    """A lens' radial curve at a few rays and its uncertainty.

    Attributes
    ----------
    angles_deg : ndarray, shape (n,)
        Angles of the rays off the optical axis, degrees (in the plane y = 0, x > 0).
    radii_px : ndarray, shape (n,)
        Per ray, the pixel offset from ``cx`` along the image's x axis of its image (for
        ``fx = fy`` its distance from the principal point), pixels.
    covariance : ndarray, shape (n, n)
        Of ``radii_px``, pixels squared.
    """

    angles_deg: F64
    radii_px: F64
    covariance: F64


def observed_angles(intrinsics: Intrinsics, points_cam: F64, n: int = CURVE_RAYS
                    ) -> F64 | None:
    """``n`` ray angles over the observed field: ``0.9 theta_max j / n``, ``j = 1..n``, as
    :func:`curve_jacobian`'s, ``theta_max`` the largest angle off the optical axis of
    ``points_cam`` (P, 3; camera frame) that the lens projects; radians; None when it
    projects none of them."""
    P = np.asarray(points_cam, np.float64).reshape(-1, 3)
    P = P[projectable(P, intrinsics)]
    if P.size == 0:
        return None
    theta_max = float(np.max(np.arctan2(np.hypot(P[:, 0], P[:, 1]), P[:, 2])))
    return 0.9 * theta_max * np.arange(1, n + 1) / n


def radial_curve(intrinsics: Intrinsics, covariance: F64, angles: F64) -> RadialCurve | None:
    """The pixel radii of rays at ``angles`` (radians) and their covariance ``J C J^T``.

    Parameters
    ----------
    intrinsics : Intrinsics
        Any model.
    covariance : ndarray, shape (p, p)
        Over ``intrinsics.params`` (fx fy cx cy dist...).
    angles : ndarray, shape (n,)
        Radians off the optical axis.

    Returns
    -------
    RadialCurve or None
        None when the lens does not project one of the rays.  The covariance is singular
        when ``covariance`` is (a pseudo-inverse over a field that leaves a direction of the
        parameters undetermined) or when the rays' radii are tied within it.
    """
    theta = np.asarray(angles, np.float64)
    rays = np.column_stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)])
    uv, _, Ji = project_with_jacobian(rays, intrinsics)
    J = Ji[:, 0, :].copy()
    J[:, 2] -= 1.0                                     # rho = u - cx
    if not (np.all(np.isfinite(uv)) and np.all(np.isfinite(J))):
        return None
    C = J @ np.asarray(covariance, np.float64) @ J.T
    return RadialCurve(np.degrees(theta), uv[:, 0] - intrinsics.params[2], (C + C.T) / 2)


def observed_curve(intrinsics: Intrinsics, covariance: F64, points_cam: F64
                   ) -> RadialCurve | None:
    """The :func:`radial_curve` calibration.json states for a lens of
    :data:`RADIAL_CURVE_MODELS` estimated with ``covariance``: at :func:`observed_angles`
    of the observed target points ``points_cam`` (P, 3; camera frame); None for other
    models, or when the lens projects none of the points or rays."""
    if intrinsics.model not in RADIAL_CURVE_MODELS:
        return None
    angles = observed_angles(intrinsics, points_cam)
    return None if angles is None else radial_curve(intrinsics, covariance, angles)


#: A parameter the views do not determine by itself: a focal length whose standard deviation
#: exceeds this share of it, a principal point coordinate beyond :data:`UNDETERMINED_CENTRE_PX`,
#: a shape parameter of a wide model (``xi``, ``alpha``, ``beta``, of order 1) beyond
#: :data:`UNDETERMINED_SHAPE`.
UNDETERMINED_FOCAL_SHARE = 0.1
UNDETERMINED_CENTRE_PX = 50.0
UNDETERMINED_SHAPE = 1.0


def undetermined_parameters(intrinsics: Intrinsics, covariance: F64
                            ) -> list[tuple[str, float, float]]:
    """The lens parameters whose standard deviation says the views do not determine them one
    by one (they trade against each other along a flat valley, e.g. the double sphere's
    ``xi`` near 0 against ``fx`` and ``alpha``), while the projection may still be well
    determined (:func:`radial_curve`).

    Parameters
    ----------
    intrinsics : Intrinsics
    covariance : ndarray, shape (p, p)
        Over ``intrinsics.params`` (fx fy cx cy, then the model's parameters).

    Returns
    -------
    list of (name, value, standard deviation)
        In parameter order; the radial and tangential coefficients are not judged (their
        scale depends on the model and the field).
    """
    names = parameter_names(intrinsics)
    sd = np.sqrt(np.clip(np.diag(np.asarray(covariance, np.float64)), 0.0, None))
    out = []
    for name, value, s in zip(names, intrinsics.params, sd):
        if name in ("fx", "fy"):
            limit = UNDETERMINED_FOCAL_SHARE * abs(value)
        elif name in ("cx", "cy"):
            limit = UNDETERMINED_CENTRE_PX
        elif name in ("xi", "alpha", "beta"):
            limit = UNDETERMINED_SHAPE
        else:
            continue
        if not s <= limit:                                   # NaN counts as undetermined
            out.append((name, float(value), float(s)))
    return out
