"""The PnP noise model of the plausibility checks (multieye.estimate.hypotheses)."""

from __future__ import annotations

import numpy as np

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.estimate import hypotheses as h

K = np.array([[600.0, 0.0, 400.0], [0.0, 590.0, 300.0], [0.0, 0.0, 1.0]])
INTR = Intrinsics(K=K, dist=np.zeros(4))


def _pixels(T: np.ndarray, obj: np.ndarray) -> np.ndarray:
    p = obj @ T[:3, :3].T + T[:3, 3]
    return np.column_stack([K[0, 0] * p[:, 0] / p[:, 2] + K[0, 2],
                            K[1, 1] * p[:, 1] / p[:, 2] + K[1, 2]]).ravel()


def _poses(rng, n):
    T = g.random_transforms(rng, n, translation_scale=0.1)
    T[:, :3, 3] += [0.0, 0.0, 1.5]
    return T


def test_pnp_information_is_the_gram_matrix_of_the_pixel_jacobian(rng):
    """J^T J against central differences of the pinhole pixels under T = Exp(xi) T_hat, on
    poses with different numbers of points (padded together)."""
    T = _poses(rng, 3)
    obj = [np.column_stack([rng.uniform(-0.2, 0.2, (k, 2)), np.zeros(k)]) for k in (5, 12, 8)]
    info = h.pnp_information(T, obj, INTR)
    assert info.shape == (3, 6, 6)
    eps = 1e-7
    for i in range(3):
        J = np.empty((2 * len(obj[i]), 6))
        for a in range(6):
            e = np.zeros(6)
            e[a] = eps
            plus = g.transform_from_rotvec(e[:3], e[3:]) @ T[i]
            minus = g.transform_from_rotvec(-e[:3], -e[3:]) @ T[i]
            J[:, a] = (_pixels(plus, obj[i]) - _pixels(minus, obj[i])) / (2 * eps)
        np.testing.assert_allclose(info[i], J.T @ J, rtol=1e-6, atol=1e-3)


def test_noise_with_another_rms_equals_the_camera_with_that_rms(rng):
    """``noise(cam, sigma, rms_px=...)`` (the unit covariance computed once per camera) is
    the noise of the camera whose reprojection RMS is that."""
    from dataclasses import replace  # noqa: PLC0415 (this test only)

    T = _poses(rng, 6)
    obj = tuple(np.column_stack([rng.uniform(-0.2, 0.2, (9, 2)), np.zeros(9)]) for _ in T)
    img = tuple(_pixels(t, o).reshape(-1, 2) for t, o in zip(T, obj))
    cam = h.CameraEvidence("cam0", g.random_transforms(rng, 6), g.inv(T), g.random_transforms(rng, 6),
                           intrinsics=INTR, object_points=obj, image_points=img,
                           rms_px=np.linspace(0.1, 0.3, 6))
    sigma = (1e-3, 2e-4)
    other = np.linspace(0.02, 0.5, 6)
    np.testing.assert_array_equal(h.noise(cam, sigma, rms_px=other),
                                  h.noise(replace(cam, rms_px=other), sigma))
    W = h.noise(cam, sigma)
    assert W.shape == (6, 6, 6) and np.all(np.linalg.eigvalsh(W) > 0)
    # a larger pixel noise weighs a pose less
    assert np.all(np.trace(h.noise(cam, sigma, rms_px=2 * cam.rms_px), axis1=1, axis2=2)
                  < np.trace(W, axis1=1, axis2=2))
