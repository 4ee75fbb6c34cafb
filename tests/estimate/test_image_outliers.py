"""The outlier test of a camera's images on their residuals in a joint refinement (issue 33,
item 2): robust to the outlier's own noise, tolerant of the spread clean images show, and a
floor that keeps three quarters of a camera's images."""

from __future__ import annotations

import numpy as np

from multieye.estimate.image_outliers import FAR, MIN_KEPT, image_outliers


def _sums(rng, n_images=20, points=54, sigma=0.3, scales=None):
    scales = np.ones(n_images) if scales is None else np.asarray(scales)
    return np.array([np.sum((rng.normal(scale=sigma * s, size=(points, 2))) ** 2)
                     for s in scales]), np.full(n_images, points)


def test_gaussian_images_are_never_outliers():
    rng = np.random.default_rng(0)
    flagged = 0
    for _ in range(200):
        S, n = _sums(rng)
        flagged += image_outliers(S, n).left_out.size
    assert flagged == 0


def test_an_image_far_beyond_the_noise_is_found_though_it_would_inflate_a_pooled_noise():
    rng = np.random.default_rng(1)
    S, n = _sums(rng, n_images=6)
    S[2] = np.sum(rng.normal(scale=0.3 * 8, size=(54, 2)) ** 2)      # eight times the noise
    found = image_outliers(S, n)
    assert list(found.left_out) == [2]
    assert abs(found.sigma_px - 0.3) < 0.05                  # the median, not pulled by it
    # a pooled noise (the mean) would be inflated by it: 8 x over 3.4 x is not 5 x
    pooled = np.sqrt(np.sum(S) / np.sum(2 * n))
    assert np.sqrt(S[2] / (2 * n[2])) / pooled < FAR


def test_images_whose_noise_differs_among_themselves_are_kept():
    """Clean images differ (blur, distance): noise levels spread over a factor of three (as
    rendered corners do) leave nothing out, while one ten times the median's is."""
    rng = np.random.default_rng(2)
    scales = np.exp(rng.uniform(np.log(0.6), np.log(1.8), size=30))
    S, n = _sums(rng, n_images=30, scales=scales)
    assert image_outliers(S, n).left_out.size == 0
    S[7] = np.sum(rng.normal(scale=0.3 * 10, size=(54, 2)) ** 2)
    assert list(image_outliers(S, n).left_out) == [7]


def test_the_floor_keeps_three_quarters_of_the_images_worst_left_out_first():
    rng = np.random.default_rng(3)
    S, n = _sums(rng, n_images=10)
    bad = [1, 3, 4, 6]                       # four of ten images: only two may go
    for k, i in enumerate(bad):
        S[i] = np.sum(rng.normal(scale=0.3 * (8 + 4 * k), size=(54, 2)) ** 2)
    found = image_outliers(S, n)
    assert list(found.left_out) == [6, 4] and sorted(found.over_floor) == [1, 3]
    few = image_outliers(S[:MIN_KEPT], n[:MIN_KEPT])          # too few to judge
    assert few.left_out.size == 0 and few.over_floor.size == 0
