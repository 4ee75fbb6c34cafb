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

Synopsis
--------
>>> phi = curve_parameters(lens, theta_max)                           # doctest: +SKIP
>>> C_phi = curve_covariance(lens, C, theta_max)                      # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from multieye.core.intrinsics import Intrinsics, parameter_names
from multieye.core.lens import project_with_jacobian

__all__ = ["CURVE_MODELS", "curve_parameters", "curve_jacobian", "curve_covariance",
           "curve_names"]

F64 = NDArray[np.float64]

#: Per model: the indices in ``params`` (fx fy cx cy dist...) replaced by the curve's pixels.
CURVE_MODELS = {"unified": (0, 5, 6), "double-sphere": (0, 5)}


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
