"""The simulated rig: exact hand-eye loops, plausible geometry, noise at the requested level."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from multieye.core import geometry as g
from multieye.sim import rigs as sim
from multieye.core.errors import InputError


def _loop_error(scenario: sim.RigScenario) -> float:
    """Largest entry of A X - Y B over all cameras and measurements."""
    return max(float(np.abs(A @ scenario.X[j] - scenario.Y @ B).max())
               for j, (A, B) in enumerate(zip(scenario.A, scenario.B)))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), setup=st.sampled_from(sim.SETUPS),
       counts=st.lists(st.integers(1, 40), min_size=1, max_size=8))
def test_noise_free_measurements_close_the_loop(seed, setup, counts):
    scenario = sim.simulate_rig(seed, n_cameras=len(counts), measurements=counts, setup=setup)
    assert scenario.counts == tuple(counts)
    assert scenario.n_cameras == len(counts)
    assert _loop_error(scenario) < 1e-12


def test_measurements_follow_the_design_table():
    """A and B are the documented functions of the measured poses, for each setup."""
    e2b = sim.simulate_rig(3, setup="eye-to-base", measurements=5)
    np.testing.assert_allclose(e2b.A[1], g.inv(e2b.mocap[1]), atol=1e-15)
    np.testing.assert_allclose(e2b.B[1], g.inv(e2b.T_cam_target[1]), atol=1e-15)
    # the rig stands still: X = T_world_body @ T_body_cam with one T_world_body for all cameras
    T_world_body = e2b.X @ g.inv(e2b.T_body_cam)
    np.testing.assert_allclose(T_world_body, np.broadcast_to(T_world_body[0], (4, 4, 4)),
                               atol=1e-12)
    # T_world_marker @ T_marker_target == T_world_cam @ T_cam_target
    np.testing.assert_allclose(e2b.mocap[2] @ e2b.Y, e2b.X[2] @ e2b.T_cam_target[2], atol=1e-12)

    eoh = sim.simulate_rig(3, setup="eye-on-hand", measurements=5)
    np.testing.assert_array_equal(eoh.A[0], eoh.mocap[0])
    np.testing.assert_array_equal(eoh.X, eoh.T_body_cam)
    # T_world_body @ T_body_cam == T_world_target @ T_target_cam
    np.testing.assert_allclose(eoh.mocap[0] @ eoh.X[0], eoh.Y @ g.inv(eoh.T_cam_target[0]),
                               atol=1e-12)
    # relative extrinsics agree with the rig in both setups
    for s in (e2b, eoh):
        np.testing.assert_allclose(s.T_ref_cam, g.inv(s.T_body_cam[0]) @ s.T_body_cam,
                                   atol=1e-12)
        np.testing.assert_allclose(s.T_ref_cam[0], np.eye(4), atol=1e-15)


def test_rig_is_an_outward_facing_horizontal_ring():
    spec = sim.ScenarioSpec()
    rig = sim.surround_rig(np.random.default_rng(5), 4, spec=spec)
    position = rig[:, :3, 3]
    radius = np.linalg.norm(position, axis=1)
    assert np.all((radius >= 0.4) & (radius <= 0.65))
    np.testing.assert_array_equal(position[:, 2], 0.0)
    outward = position / radius[:, None]
    optical_axis = rig[:, :3, 2]
    angle = np.arccos(np.clip(np.einsum("ki,ki->k", outward, optical_axis), -1, 1))
    assert np.all(angle <= spec.camera_tilt_rad + 1e-12)
    # the four headings cover the ring: consecutive cameras 90 deg +- twice the jitter apart
    heading = np.sort(np.arctan2(position[:, 1], position[:, 0]))
    gaps = np.diff(np.append(heading, heading[0] + 2 * np.pi))
    assert np.all(np.abs(gaps - np.pi / 2) <= 2 * spec.yaw_jitter_rad + 1e-12)
    np.testing.assert_allclose(rig[:, :3, :3] @ np.swapaxes(rig[:, :3, :3], 1, 2),
                               np.broadcast_to(np.eye(3), (4, 3, 3)), atol=1e-12)


def test_board_poses_are_physically_plausible():
    spec = sim.ScenarioSpec()
    P = sim.sample_target_poses(np.random.default_rng(11), 2000, spec=spec)
    assert P.shape == (2000, 4, 4)
    w, h = spec.board_size_m
    corners = np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]], dtype=float)
    centre = P[:, :3, :3] @ corners.mean(axis=0) + P[:, :3, 3]
    assert np.all((centre[:, 2] >= 0.5) & (centre[:, 2] <= 2.0))
    ray = centre / np.linalg.norm(centre, axis=1, keepdims=True)
    # target z points into the board: facing the camera means z along the line of sight
    facing = np.arccos(np.clip(np.einsum("ki,ki->k", ray, P[:, :3, 2]), -1, 1))
    assert facing.max() <= np.deg2rad(45.0) + 1e-9
    assert facing.max() > np.deg2rad(40.0)  # the whole cone is used
    p = np.einsum("kij,cj->kci", P[:, :3, :3], corners) + P[:, None, :3, 3]
    assert np.all(p[..., 2] > 0)
    assert np.all(np.abs(p[..., 0] / p[..., 2]) <= np.tan(spec.half_fov_rad[0]) + 1e-12)
    assert np.all(np.abs(p[..., 1] / p[..., 2]) <= np.tan(spec.half_fov_rad[1]) + 1e-12)
    # rotations about varied axes: relative rotations do not share one axis
    axes = g.rotvec_from_transform(g.inv(P[:-1]) @ P[1:])
    s = np.linalg.svd(axes / np.linalg.norm(axes, axis=1, keepdims=True), compute_uv=False)
    assert s[-1] / s[0] > 0.3


def test_same_seed_same_scenario_and_arrays_are_read_only():
    a = sim.simulate_rig(42, n_cameras=3, measurements=[4, 5, 6])
    b = sim.simulate_rig(np.random.default_rng(42), n_cameras=3, measurements=[4, 5, 6])
    np.testing.assert_array_equal(a.X, b.X)
    for x, y in zip(a.B, b.B):
        np.testing.assert_array_equal(x, y)
    with pytest.raises(ValueError):
        a.X[0, 0, 0] = 2.0
    with pytest.raises(ValueError):
        a.A[0][0, 0, 0] = 2.0


def _var_log_uniform_factor(f: float) -> float:
    """Var(log(1 + u)) for u ~ U(-f, f), by quadrature."""
    m1 = integrate.quad(lambda u: np.log1p(u), -f, f)[0] / (2 * f)
    m2 = integrate.quad(lambda u: np.log1p(u) ** 2, -f, f)[0] / (2 * f)
    return m2 - m1 ** 2


@pytest.mark.parametrize("f", [0.05, 0.3])
def test_multiplicative_noise_matches_the_paper_model(f):
    n = 20000
    q = np.array([0.5, -0.5, 0.5, 0.5])  # every component well away from zero
    t = np.array([1.0, -2.0, 0.5])
    T = np.broadcast_to(g.transform_from_quat(q, t), (n, 4, 4))
    noisy = sim.MultiplicativeNoise(f).perturb(T, np.random.default_rng(7))
    # translation: each coordinate times 1 + U(-f, f)
    factor = noisy[:, :3, 3] / t
    assert factor.min() >= 1 - f and factor.max() <= 1 + f
    assert factor.min() < 1 - 0.99 * f and factor.max() > 1 + 0.99 * f
    np.testing.assert_allclose(factor.mean(axis=0), 1.0, atol=4 * f / np.sqrt(3 * n))
    np.testing.assert_allclose(factor.std(axis=0), f / np.sqrt(3), rtol=0.03)
    # quaternion: components times independent 1 + U(-f, f), then renormalised, so the ratio
    # of two components' factors is (1 + u_k) / (1 + u_l) whatever the normalisation
    q_noisy = g.quat_from_transform(noisy)
    q_noisy *= np.sign(q_noisy @ q)[:, None]
    np.testing.assert_allclose(np.linalg.norm(q_noisy, axis=1), 1.0, atol=1e-12)
    r = q_noisy / q
    log_ratio = np.log(r[:, 0] / r[:, 1])
    bound = np.log((1 + f) / (1 - f))
    assert np.abs(log_ratio).max() <= bound + 1e-9
    np.testing.assert_allclose(np.var(log_ratio), 2 * _var_log_uniform_factor(f), rtol=0.05)
    assert abs(np.corrcoef(np.log(r[:, 0] / r[:, 1]), np.log(r[:, 2] / r[:, 3]))[0, 1]) < 0.03


def test_multiplicative_noise_zero_is_exact():
    T = g.random_transforms(np.random.default_rng(0), 10)
    np.testing.assert_array_equal(sim.MultiplicativeNoise(0.0).perturb(T, np.random.default_rng(1)), T)


def test_gaussian_noise_matches_requested_standard_deviations():
    n = 20000
    rot_std, trans_std = np.deg2rad(0.5), 0.002
    T = np.broadcast_to(g.random_transforms(np.random.default_rng(3)), (n, 4, 4))
    noisy = sim.GaussianNoise(rot_std, trans_std).perturb(T, np.random.default_rng(4))
    w = g.rotvec_from_transform(g.inv(T) @ noisy)  # perturbation in the pose's own frame
    np.testing.assert_allclose(w.std(axis=0), rot_std, rtol=0.03)
    np.testing.assert_allclose(w.mean(axis=0), 0.0, atol=4 * rot_std / np.sqrt(n))
    dt = noisy[:, :3, 3] - T[:, :3, 3]
    np.testing.assert_allclose(dt.std(axis=0), trans_std, rtol=0.03)
    np.testing.assert_allclose(np.cov(np.hstack([w, dt]).T / np.repeat([rot_std, trans_std], 3)[:, None]),
                               np.eye(6), atol=0.05)


@pytest.mark.parametrize("noise", [sim.MultiplicativeNoise(0.05), sim.GaussianNoise(0.01, 0.005)])
def test_add_noise_perturbs_both_streams_and_keeps_the_truth(noise):
    clean = sim.simulate_rig(9, n_cameras=2, measurements=[6, 4])
    noisy = sim.add_noise(clean, noise, np.random.default_rng(2))
    np.testing.assert_array_equal(noisy.X, clean.X)
    np.testing.assert_array_equal(noisy.Y, clean.Y)
    assert noisy.counts == clean.counts
    for j in range(2):
        assert np.all(g.rotation_angle_between(noisy.mocap[j], clean.mocap[j]) > 0)
        assert np.all(g.rotation_angle_between(noisy.T_cam_target[j], clean.T_cam_target[j]) > 0)
        np.testing.assert_allclose(noisy.A[j], g.inv(noisy.mocap[j]), atol=1e-15)
        np.testing.assert_allclose(noisy.B[j], g.inv(noisy.T_cam_target[j]), atol=1e-15)
    assert _loop_error(noisy) > 1e-3


def test_bad_parameters_raise_input_errors():
    with pytest.raises(InputError, match="one count per camera"):
        sim.simulate_rig(0, n_cameras=3, measurements=[4, 5])
    with pytest.raises(InputError, match="at least one measurement"):
        sim.simulate_rig(0, n_cameras=2, measurements=[4, 0])
    with pytest.raises(InputError, match="setup must be one of"):
        sim.simulate_rig(0, setup="eye-in-hand")
    with pytest.raises(InputError, match="at least one camera"):
        sim.simulate_rig(0, n_cameras=0)
    with pytest.raises(InputError, match=r"\[0, 1\)"):
        sim.MultiplicativeNoise(1.5)
    with pytest.raises(InputError, match=">= 0"):
        sim.GaussianNoise(-0.1, 0.0)
