"""Clock offsets as unknowns of the image-level problem (estimate/clock_residuals.py): the
smoothed trajectory, the Jacobian, exact recovery without noise, and honest uncertainty."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.lie import log_so3
from multieye.estimate.clock_residuals import (ClockData, LocalTrajectory, TimedMocapPriors,
                                               offset_family)
from multieye.estimate.image_data import image_data
from multieye.estimate.refine_images import refine_images
from multieye.optimize.gradient_check import numerical_jacobians
from multieye.sim.streams import simulate_rig_stream
from multieye.estimate.uncertainty import pose_error


def _clocks(st, start, half_window_s=0.05):
    return [ClockData(st.image_stamps[j], st.mocap_stamps, st.T_world_mocap, offset=start[j],
                      half_window_s=half_window_s) for j in range(len(st.X))]



def test_local_fit_reproduces_a_cubic_and_its_velocity():
    """A trajectory that is a cubic in time (rotation in a chart at the first sample,
    translation) is reproduced exactly, with its velocity, anywhere in a window."""
    s = np.arange(0.0, 2.0, 0.005)
    c = np.array([[0.1, -0.2, 0.3], [0.4, 0.1, -0.3], [-0.2, 0.3, 0.1], [0.05, -0.1, 0.2]])
    phi = (s[:, None] ** np.arange(4)) @ c
    T = g.transform_from_rotvec(phi, 0.3 * phi[:, ::-1])
    R0 = T[0, :3, :3]
    T = g.make_transform(np.swapaxes(np.broadcast_to(R0, T[:, :3, :3].shape), 1, 2) @ T[:, :3, :3],
                         T[:, :3, 3])                               # phi in a chart at sample 0
    t = np.array([0.3, 0.9, 1.5])
    traj = LocalTrajectory(ClockData(t, s, T, offset=0.0))
    for delta in (0.0, 0.013, -0.02):
        poses, omega, vel = traj.at(delta)
        tt = t + delta
        phi_t = (tt[:, None] ** np.arange(4)) @ c
        want = g.make_transform(R0.T @ g.transform_from_rotvec(phi_t, 0 * phi_t)[:, :3, :3],
                                0.3 * phi_t[:, ::-1])
        np.testing.assert_allclose(poses, want, atol=1e-10)
        dphi = (np.arange(1, 4) * tt[:, None] ** np.arange(3)) @ c[1:]
        np.testing.assert_allclose(vel, 0.3 * dphi[:, ::-1], atol=1e-9)
        # body-frame angular velocity: R(s)^T dR/ds, by central differences of the model
        h = 1e-6
        Rp, Rm = traj.at(delta + h)[0][:, :3, :3], traj.at(delta - h)[0][:, :3, :3]
        w = log_so3(np.swapaxes(Rm, 1, 2) @ Rp) / (2 * h)
        np.testing.assert_allclose(omega, w, atol=1e-6)
    # the variance factor at the centre: about 2.25 / n_window for a cubic
    h, dh = traj.variance_factor(0.0)
    assert np.allclose(h, traj.h)
    step = 1e-6
    np.testing.assert_allclose(dh, (traj.variance_factor(step)[0]
                                    - traj.variance_factor(-step)[0]) / (2 * step), rtol=1e-5,
                               atol=1e-6)
    assert 1.5 / traj.n_window < traj.h.mean() < 3.0 / traj.n_window


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_timed_prior_jacobian_matches_central_differences(setup):
    st = simulate_rig_stream(3, n_cameras=2, setup=setup, duration_s=6.0,
                             time_offsets_s=[0.03, -0.05])
    data = image_data(setup, st.observations, st.intrinsics,
                     clocks=_clocks(st, [0.0313, -0.0441]))
    rng = np.random.default_rng(0)
    M = g.transform_from_rotvec(rng.normal(scale=0.01, size=(data.n_images, 3)),
                                rng.normal(scale=0.01, size=(data.n_images, 3))) @ data.mocap_start()
    fams = data.families(st.X, st.Y, M)
    groups = [gr for gr in data.groups(0.3, 1e-3, 3e-4) if isinstance(gr, TimedMocapPriors)]
    assert len(groups) == 2
    for group in groups:
        _, analytic = group.evaluate({f.name: f.value for f in fams}, True)
        for a, n in zip(analytic, numerical_jacobians(fams, group, step=1e-7)):
            assert np.abs(a - n).max() <= 1e-5 * np.abs(n).max()


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_offsets_and_rig_recovered_exactly_without_noise(setup):
    """Noise-free pixels and motion capture, the offsets started 30 ms off and the rig
    perturbed: offsets, X and Y come back to rounding (the windows re-centred)."""
    offsets = np.array([0.04, -0.0713])
    st = simulate_rig_stream(1, n_cameras=2, setup=setup, duration_s=10.0,
                             time_offsets_s=offsets, pixel_sigma=0.0, mocap_rot_sigma_rad=0.0,
                             mocap_trans_sigma_m=0.0)
    X0 = np.stack([g.transform_from_rotvec([0.01, -0.01, 0.005], [0.005, 0.0, -0.005]) @ x
                   for x in st.X])
    res = refine_images(setup, st.observations, st.intrinsics, X0, st.Y, pixel_sigma=0.3,
                        mocap_rot_sigma_rad=1e-3, mocap_trans_sigma_m=3e-4, loss="linear",
                        clocks=_clocks(st, offsets + 0.03), tol=1e-14, max_iter=200)
    np.testing.assert_allclose(res.time_offsets, offsets, atol=1e-6)
    assert all(0 < s < 1e-3 for s in res.time_offset_std_s)
    assert np.abs(res.X - st.X).max() < 1e-6 and np.abs(res.Y - st.Y).max() < 1e-6
    k = 6 * 3
    o = [res.layout.offset[offset_family(n)] for n in ("cam0", "cam1")]
    assert res.full_covariance.shape[0] >= k + 2 and np.all(np.diag(res.full_covariance)[o] > 0)


def test_offset_uncertainty_is_honest():
    """Noisy pixels and motion capture (1e-3 rad, 0.3 mm at 200 Hz): over a few rigs the
    offsets' and the rig's errors are consistent with the reported covariance (a loose band;
    benchmarks/bench_clock_joint.py runs the full Monte Carlo)."""
    z, nees = [], []
    for seed in range(6):
        offsets = np.array([0.02, -0.06])
        st = simulate_rig_stream(seed + 40, n_cameras=2, duration_s=15.0,
                                 time_offsets_s=offsets)
        res = refine_images(st.setup, st.observations, st.intrinsics, st.X, st.Y,
                            pixel_sigma=0.5, mocap_rot_sigma_rad=1e-3,
                            mocap_trans_sigma_m=3e-4, clocks=_clocks(st, offsets + 0.002))
        z += list((np.array(res.time_offsets) - offsets) / np.array(res.time_offset_std_s))
        e = np.concatenate([pose_error(res.X[j], st.X[j]) for j in range(2)] + [pose_error(res.Y, st.Y)])
        nees.append(e @ np.linalg.solve(res.covariance, e) / e.size)
    assert 0.25 < np.mean(np.square(z)) < 3.0
    assert 0.5 < np.mean(nees) < 2.0


def test_unstated_mocap_noise_comes_from_the_smoothing_residuals():
    st = simulate_rig_stream(7, n_cameras=1, duration_s=8.0, time_offsets_s=0.05,
                             mocap_rot_sigma_rad=2e-3, mocap_trans_sigma_m=5e-4)
    res = refine_images(st.setup, st.observations, st.intrinsics, st.X, st.Y,
                        pixel_sigma=0.5, mocap_rot_sigma_rad=None, mocap_trans_sigma_m=None,
                        clocks=_clocks(st, [0.05]))
    assert res.mocap_sigma_estimated
    assert res.mocap_rot_sigma_rad == pytest.approx(2e-3, rel=0.1)
    assert res.mocap_trans_sigma_m == pytest.approx(5e-4, rel=0.1)
    assert res.time_offsets[0] == pytest.approx(0.05, abs=5 * res.time_offset_std_s[0])


def test_clock_data_is_checked():
    s = np.arange(20) * 0.01
    T = np.tile(np.eye(4), (20, 1, 1))
    with pytest.raises(InputError, match="strictly increasing stamps"):
        ClockData(np.zeros(3), s[::-1], T)
    with pytest.raises(InputError, match="at least 8 motion-capture samples"):
        ClockData(np.zeros(3), s[:5], T[:5])
    with pytest.raises(InputError, match="outside the motion capture"):
        LocalTrajectory(ClockData(np.array([0.1, 5.0]), s, T))
    st = simulate_rig_stream(2, n_cameras=1, duration_s=3.0)
    short = ClockData(st.image_stamps[0][:-1], st.mocap_stamps, st.T_world_mocap)
    with pytest.raises(InputError, match="image stamps for"):
        image_data(st.setup, st.observations, st.intrinsics, clocks=[short])


def test_prior_is_the_profile_likelihood_of_the_window_away_from_its_centre():
    """The position prior of an image at offset delta, squared and times sigma^2, is the
    rise of the window's residual sum of squares when its cubic is forced through the pose
    M at t_i + delta (constrained least squares, solved here on its own through the KKT
    system). At the window's centre h(0) would do; away from it only h(u) gives this (a
    prior with h held at the centre pulled every offset towards the centre)."""
    rng = np.random.default_rng(3)
    s = np.arange(0.0, 2.0, 0.005)                                  # 200 Hz
    T = np.tile(np.eye(4), (len(s), 1, 1))
    T[:, :3, 3] = np.column_stack([np.sin(3 * s), s ** 2, np.cos(s)]) \
        + rng.normal(scale=3e-4, size=(len(s), 3))
    t = np.array([0.5, 0.9, 1.3])
    lt = LocalTrajectory(ClockData(t, s, T, offset=0.0))
    sigma_t = 3e-4
    prior = TimedMocapPriors("cam0", np.arange(3), lt, 1e-3, sigma_t)
    M = np.tile(np.eye(4), (3, 1, 1))
    M[:, :3, 3] = np.column_stack([np.sin(3 * t), t ** 2, np.cos(t)]) + 1e-3
    for delta in (0.0, 0.017, -0.031):                              # u = 0, 0.34, -0.62
        r, _ = prior.evaluate({"M": M, "dt:cam0": np.array([[delta]])}, False)
        n_w = lt.n_window
        for i in range(3):
            k0 = int(np.clip(np.searchsorted(s, t[i]) - n_w // 2, 0, len(s) - n_w))
            w = slice(k0, k0 + n_w)
            u = (s[w] - lt.c[i]) / lt.a[i]
            A = u[:, None] ** np.arange(4)
            e = ((t[i] + delta - lt.c[i]) / lt.a[i]) ** np.arange(4)
            for c in range(3):
                y = T[w, c, 3] - lt.tc[i, c]
                m = M[i, c, 3] - lt.tc[i, c]
                free = np.linalg.lstsq(A, y, rcond=None)[0]
                kkt = np.block([[A.T @ A, e[:, None]], [e[None, :], np.zeros((1, 1))]])
                forced = np.linalg.solve(kkt, np.concatenate([A.T @ y, [m]]))[:4]
                rise = np.sum((y - A @ forced) ** 2) - np.sum((y - A @ free) ** 2)
                assert (r[i, 3 + c] * sigma_t) ** 2 == pytest.approx(rise, rel=1e-6)
