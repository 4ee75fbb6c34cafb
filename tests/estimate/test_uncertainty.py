"""Relative-pose covariance propagation and the Cramér-Rao bound."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.sim.images import simulate_images
from multieye.estimate.image_data import ImageProblem
from multieye.estimate.refine_images import refine_images
from multieye.estimate.uncertainty import cramer_rao_bound, pose_std, relative_covariance


def _random_covariance(rng, n, scale):
    L = rng.normal(size=(n, n)) * scale
    return L @ L.T


def test_relative_covariance_matches_sampling(rng):
    """Perturb X as the refinement's convention says and compare the spread of T_ref_cam."""
    m = 3
    X = g.random_transforms(rng, m, translation_scale=1.0)
    C = _random_covariance(rng, 6 * m + 6, 1e-3)
    rel = relative_covariance(X, C, reference=1)
    samples = rng.multivariate_normal(np.zeros(6 * m + 6), C, size=20000)[:, :6 * m]
    d = samples.reshape(-1, m, 6)
    R = g.transform_from_rotvec(d[..., :3], np.zeros(d.shape[:-1] + (3,)))[..., :3, :3]
    Xs = g.make_transform(R @ X[:, :3, :3], X[:, :3, 3] + d[..., 3:])        # (S, m, 4, 4)
    T_hat = g.inv(X[1]) @ X
    T = g.inv(Xs[:, 1:2]) @ Xs
    dphi = g.rotvec_from_transform(T[..., :3, :3] @ np.swapaxes(T_hat[:, :3, :3], 1, 2))
    dt = T[..., :3, 3] - T_hat[:, :3, 3]
    emp = np.stack([np.cov(np.concatenate([dphi[:, j], dt[:, j]], axis=1).T) for j in range(m)])
    np.testing.assert_allclose(rel.covariance[1], 0.0)
    for j in (0, 2):
        scale = np.sqrt(np.outer(np.diag(emp[j]), np.diag(emp[j])))
        assert np.abs(rel.covariance[j] - emp[j]).max() < 0.05 * scale.max()
    std_rot, std_t = pose_std(rel.covariance)
    np.testing.assert_allclose(rel.std_rot_deg, std_rot)
    np.testing.assert_allclose(rel.std_trans_m, std_t)


def test_pose_std_is_root_of_the_trace():
    C = np.diag([1e-4, 4e-4, 4e-4, 1e-6, 1e-6, 2e-6])
    rot, trans = pose_std(C)
    assert rot == pytest.approx(np.degrees(3e-2))
    assert trans == pytest.approx(2e-3)


def test_relative_covariance_checks_its_input(rng):
    X = g.random_transforms(rng, 2)
    with pytest.raises(InputError, match=r"covariance must be 12x12 \(X\) or 18x18"):
        relative_covariance(X, np.eye(6))
    with pytest.raises(InputError, match="reference camera index 2 out of range for 2 cameras"):
        relative_covariance(X, np.eye(12), reference=2)
    with pytest.raises(InputError, match=r"pose covariances must be 6x6"):
        pose_std(np.eye(5))


def test_crb_equals_the_refinement_covariance_at_the_truth():
    """Noise-free data and linear loss: the refinement stays at the truth and its covariance
    is the inverse Fisher information there."""
    sc = simulate_images(9, n_cameras=3, images=5, setup="eye-on-hand", pixel_sigma=0.0,
                         mocap_rot_sigma_rad=0.0, mocap_trans_sigma_m=0.0)
    kw = dict(pixel_sigma=0.5, mocap_rot_sigma_rad=2e-3, mocap_trans_sigma_m=1e-3)
    res = refine_images(sc.setup, sc.observations, sc.intrinsics, sc.X, sc.Y, loss="linear",
                        **kw)
    problem = ImageProblem(sc.setup, sc.true_observations, sc.intrinsics)
    crb = cramer_rao_bound(problem, sc.X, sc.Y, **kw)
    np.testing.assert_allclose(res.covariance, crb, rtol=1e-6, atol=1e-16)
    # The bound scales with the noise variance.
    crb2 = cramer_rao_bound(problem, sc.X, sc.Y,
                            **{k: 2 * v for k, v in kw.items()})
    np.testing.assert_allclose(crb2, 4 * crb, rtol=1e-9, atol=1e-18)
    with pytest.raises(InputError, match="noise levels must be positive"):
        cramer_rao_bound(problem, sc.X, sc.Y,
                         pixel_sigma=0.0, mocap_rot_sigma_rad=1e-3, mocap_trans_sigma_m=1e-3)


@pytest.mark.parametrize("X, C, reference, message", [
    (None, np.eye(18), 0, "X is None; expected a real array of shape (N, 4, 4)"),
    ("X", None, 0, "covariance is None"),
    ("complex", np.eye(18), 0, "X must be real, got complex"),
    ("X", np.eye(18) + 0j, 0, "covariance must be real, got complex"),
    ("X", np.eye(18) * np.nan, 0, "X and covariance must be finite"),
    ("X", np.eye(7), 0, "covariance must be 12x12 (X) or 18x18 (X and Y) for 2 cameras"),
    ("X", np.eye(18), None, "reference must be a camera index (int), got None"),
    ("X", np.eye(18), "cam0", "reference must be a camera index (int), got 'cam0'"),
    ("X", np.eye(18), 0.5, "reference must be a camera index (int), got 0.5"),
    ("X", np.eye(18), 2, "reference camera index 2 out of range for 2 cameras"),
])
def test_relative_covariance_bad_arguments(X, C, reference, message):
    Xs = g.random_transforms(np.random.default_rng(0), 2)
    X = Xs if isinstance(X, str) and X == "X" else Xs + 0j if X == "complex" else X
    with pytest.raises(InputError) as info:
        relative_covariance(X, C, reference=reference)
    assert message in str(info.value)


def test_pose_error_is_the_left_perturbation_of_the_covariances():
    from multieye.core import geometry as g
    from multieye.estimate.uncertainty import pose_error

    T = g.transform_from_rotvec([0.3, -0.2, 1.1], [0.5, -1.0, 2.0])
    phi, tau = np.array([1e-3, -2e-3, 5e-4]), np.array([1e-3, 2e-3, -3e-3])
    T_est = T.copy()
    T_est[:3, :3] = g.transform_from_rotvec(phi, np.zeros(3))[:3, :3] @ T[:3, :3]
    T_est[:3, 3] += tau
    np.testing.assert_allclose(pose_error(T_est, T), np.concatenate([phi, tau]), atol=1e-15)
