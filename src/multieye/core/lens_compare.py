"""How far apart two lenses put the same rays: a lens against a reference, or the truth.

Two calibrations of one camera may differ by a rotation of the camera frame (each fixes its
own), which moves no ray relative to the others.  :func:`lens_difference_px` takes the rays
one lens gives the observed pixels, turns them by the rotation that fits best, and measures
where the other lens puts them (the comparison ``boofcv_fisheye``'s PROVENANCE.md asks for,
issue 33).

Synopsis
--------
>>> d = lens_difference_px(ours, reference, corners)        # (N,) pixels  # doctest: +SKIP
>>> float(np.sqrt(np.mean(d[radius <= 250] ** 2)))                          # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from multieye.core.geometry import rotation_from_rotvec
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, unproject_points

__all__ = ["lens_difference_px"]

#: Pixels of a ray the other lens does not project, in the fit of the rotation.
_OUTSIDE_PX = 100.0


def lens_difference_px(lens: Intrinsics, other: Intrinsics, pixels: ArrayLike) -> NDArray[np.float64]:
    """Per pixel, the distance from it to where ``other`` puts the ray ``lens`` gives it,
    after the rotation between the two camera frames that fits best (least squares).

    Parameters
    ----------
    lens, other : Intrinsics
        Any models.
    pixels : array_like, shape (N, 2)
        Observed pixels (e.g. every detected corner).

    Returns
    -------
    ndarray, shape (N,)
        Pixels; NaN where ``lens`` has no ray for the pixel or ``other`` does not project it.
    """
    uv = np.asarray(pixels, np.float64).reshape(-1, 2)
    rays = unproject_points(uv, lens)
    ok = np.isfinite(rays).all(axis=1)

    def residual(w):
        d = project_points(rays[ok] @ rotation_from_rotvec(w).T, other) - uv[ok]
        return np.where(np.isfinite(d), d, _OUTSIDE_PX).ravel()

    w = least_squares(residual, np.zeros(3)).x if ok.sum() >= 3 else np.zeros(3)
    out = np.full(len(uv), np.nan)
    d = project_points(rays[ok] @ rotation_from_rotvec(w).T, other) - uv[ok]
    out[ok] = np.hypot(d[:, 0], d[:, 1])
    return out
