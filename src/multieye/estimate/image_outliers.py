"""Images whose residuals in a joint refinement lie far beyond the pixel noise (issue 33).

A camera's image ``i`` with ``n_i`` target points leaves, at the optimum of the joint
refinement, the pixel residuals' sum of squares ``S_i`` (pixels squared) over its
``d_i = 2 n_i`` residual components, its own noise level ``s_i^2 = S_i / d_i``.  The
camera's pixel noise is estimated robustly from its images, ``sigma^2 = median_i s_i^2``: an
image whose corners are off (a mislabelled grid, shifted corners) cannot inflate it, as it
would inflate a pooled estimate (the refinements estimate each image's own noise, so that
such an image merely weighs less there and is kept silently).

An image is an outlier when both

    S_i / sigma^2  >  chi2_{d_i}^{-1}(1 - p),    p = OUTLIER_PROBABILITY (1e-4),
    s_i^2 / sigma^2  >  F = max(FAR^2, exp(SPREAD_SIGMAS * 1.4826 MAD_i(log s_i^2))):

the chi-square test of its residuals against the camera's noise (beyond what chance gives),
and a noise level beyond the allowance ``F`` (beyond what images differ by among
themselves: blur, distance, the corner detector's errors correlated within an image; a test
on the sum alone flagged a third of the images of a clean rendered rig,
:func:`multieye.pipeline.overlap._rig_warnings`), never less than :data:`FAR` times (RMS)
the camera's median image (clean rendered images reach 3 times).  ``d_i = 2 n_i`` counts
no degree of freedom for the image's pose, which makes the first test lenient.

The floor: a camera keeps at least ``max(MIN_KEPT, ceil((1 - MAX_SHARE) n))`` of its ``n``
images; when more fail, the worst (largest :attr:`ImageOutliers.ratio`) are
left out and the rest kept, and the caller says so (that many outliers point at the lens
model or the target, not at single images).

Synopsis
--------
>>> found = image_outliers(sq_sums, points)                       # doctest: +SKIP
>>> found.left_out, found.over_floor                               # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import chdtri

from multieye.estimate.refine_images import OUTLIER_PROBABILITY

__all__ = ["ImageOutliers", "image_outliers", "FAR", "SPREAD_SIGMAS", "MAX_SHARE", "MIN_KEPT"]

#: An image is never an outlier for a noise level less than this many times (RMS) its
#: camera's (the median image's): clean rendered images reach 3 times (a pinhole camera of
#: bench_wide_render's mixed rig, 0.11 against 0.04 px).
FAR = 5.0
#: The allowance for the spread of the images' noise levels: this many robust standard
#: deviations of ``log s_i^2``.
SPREAD_SIGMAS = 4.0
#: At most this share of a camera's images is left out.
MAX_SHARE = 0.25
#: A camera keeps at least this many images (the hand-eye solvers' minimum).
MIN_KEPT = 3


@dataclass(frozen=True)
class ImageOutliers:
    """The test of one camera's images (:func:`image_outliers`).

    Attributes
    ----------
    left_out : ndarray of int
        The images left out (indices into the camera's images), worst first.
    over_floor : ndarray of int
        Images that fail the test but are kept by the floor.
    ratio : ndarray, shape (n,)
        Per image the smaller of ``S_i / sigma^2`` over its chi-square quantile and
        ``s_i^2 / (sigma^2 F)`` (> 1: fails both tests, an outlier).
    rms_px : ndarray, shape (n,)
        Per image its residuals' RMS per point, pixels (``sqrt(S_i / n_i)``).
    sigma_px : float
        The camera's robust pixel noise per coordinate ``sigma``, pixels.
    """

    left_out: NDArray[np.int64]
    over_floor: NDArray[np.int64]
    ratio: NDArray[np.float64]
    rms_px: NDArray[np.float64]
    sigma_px: float


def image_outliers(sq_sums: ArrayLike, points: ArrayLike, *,
                   probability: float = OUTLIER_PROBABILITY) -> ImageOutliers:
    """The outliers among one camera's images (module docstring).

    Parameters
    ----------
    sq_sums : array_like, shape (n,)
        Per image the sum of its points' squared pixel residuals at the optimum, pixels^2.
    points : array_like of int, shape (n,)
        Per image its number of target points (each two residual components).
    probability : float
        The test's tail probability.

    Returns
    -------
    ImageOutliers
    """
    S = np.asarray(sq_sums, dtype=np.float64).reshape(-1)
    n_pts = np.asarray(points, dtype=np.int64).reshape(-1)
    n = S.size
    none = np.zeros(0, dtype=np.int64)
    dof = 2 * np.maximum(n_pts, 1)
    s2 = S / dof
    rms = np.sqrt(S / np.maximum(n_pts, 1))
    finite = np.isfinite(s2) & (s2 > 0)
    if n < MIN_KEPT + 1 or finite.sum() < MIN_KEPT:
        return ImageOutliers(none, none, np.zeros(n), rms, float("nan"))
    sigma2 = float(np.median(s2[finite]))
    log_s2 = np.log(s2[finite])
    mad = 1.4826 * float(np.median(np.abs(log_s2 - np.median(log_s2))))
    allowance = max(FAR ** 2, float(np.exp(SPREAD_SIGMAS * mad)))
    ratio = np.where(finite, np.minimum(S / sigma2 / chdtri(dof, probability),
                                        s2 / (sigma2 * allowance)), 0.0)
    failed = np.flatnonzero(ratio > 1.0)
    failed = failed[np.argsort(-ratio[failed], kind="stable")]
    room = n - max(MIN_KEPT, int(np.ceil((1.0 - MAX_SHARE) * n)))
    room = max(room, 0)
    return ImageOutliers(failed[:room].astype(np.int64), failed[room:].astype(np.int64),
                         ratio, rms, float(np.sqrt(sigma2)))
