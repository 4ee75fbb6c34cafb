"""Projection error of an estimated lens against the true one over the observed area.

Shared by ``bench_peers.py``, ``bench_lens_sweep.py`` and ``mrcal_script.py`` (numpy, scipy
and OpenCV only, so that mrcal's interpreter runs it too).

The observed area is the camera-frame rays of the observed corners (unprojected through the
true lens). The error of a lens is ``|pi_est(ray) - pi_true(ray)|``, RMS over the rays, and
also after the rotation ``R`` between the two camera frames that fits best,
``min_R RMS |pi_est(R ray) - pi_true(ray)|``: what mrcal's ``projection_diff`` fits (at
infinite range), since a principal point off by ``d`` pixels is, for every pixel, the camera
turned by ``d / f`` radians; the extrinsics estimated with that lens absorb the rotation.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from scipy.optimize import least_squares

_ITER = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-14)


def project(rays: np.ndarray, K, dist, fisheye: bool = False) -> np.ndarray:
    """(n, 2) pixels of camera-frame rays (n, 3) through an OpenCV lens."""
    K, dist = np.asarray(K, float), np.asarray(dist, float)
    pts = np.ascontiguousarray(rays, float).reshape(-1, 1, 3)
    if fisheye:
        return cv2.fisheye.projectPoints(pts, np.zeros((3, 1)), np.zeros((3, 1)), K,
                                         dist)[0].reshape(-1, 2)
    return cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, dist)[0].reshape(-1, 2)


def unproject(pixels: np.ndarray, K, dist, fisheye: bool = False) -> np.ndarray:
    """(n, 3) camera-frame rays (z = 1) of pixels (n, 2) through an OpenCV lens."""
    K, dist = np.asarray(K, float), np.asarray(dist, float)
    px = np.ascontiguousarray(pixels, float).reshape(-1, 1, 2)
    if fisheye:
        xy = cv2.fisheye.undistortPoints(px, K, dist, criteria=_ITER).reshape(-1, 2)
    else:
        xy = cv2.undistortPointsIter(px, K, dist, None, None, _ITER).reshape(-1, 2)
    return np.column_stack([xy, np.ones(len(xy))])


def errors(project_est: Callable[[np.ndarray], np.ndarray], rays: np.ndarray,
           pixels_true: np.ndarray) -> tuple[float, float]:
    """RMS projection error (px) of ``project_est`` against ``pixels_true`` of ``rays``, and
    the same after the best-fitting rotation of the rays."""
    raw = float(np.sqrt(np.mean(np.sum((project_est(rays) - pixels_true) ** 2, axis=1))))

    def residuals(r):
        return (project_est(rays @ cv2.Rodrigues(r)[0].T) - pixels_true).ravel()

    fit = least_squares(residuals, np.zeros(3), x_scale=1e-3)
    return raw, float(np.sqrt(2 * np.mean(fit.fun ** 2)))


def lens_errors(K, dist, K_true, dist_true, pixels: np.ndarray,
                fisheye: bool = False) -> tuple[float, float]:
    """:func:`errors` of the OpenCV lens ``K, dist`` over the rays of ``pixels`` (n, 2)."""
    rays = unproject(pixels, K_true, dist_true, fisheye)
    truth = project(rays, K_true, dist_true, fisheye)
    return errors(lambda r: project(r, K, dist, fisheye), rays, truth)
