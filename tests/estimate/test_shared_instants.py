"""Cameras triggered together: images paired with the same motion-capture measurement share
one motion-capture block and one prior (the measurement counts once).  Numbering, Jacobians,
exact recovery, per-image results mapped back, and a quick Monte Carlo of the honesty of
X and Y's covariance (the full sweep: benchmarks/bench_shared_instants.py)."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.lens import project_points
from multieye.estimate.clock_residuals import ClockData, TimedMocapPriors
from multieye.estimate.image_data import image_data
from multieye.estimate.image_residuals import MocapPriors
from multieye.estimate.refine_images import refine_images
from multieye.optimize.gradient_check import numerical_jacobians
from multieye.sim.images import default_target_points
from multieye.sim.streams import simulate_rig_stream
from multieye.estimate.uncertainty import pose_error

MOCAP = (1e-3, 0.3e-3)


def _triggered(seed, setup, m, pixel_sigma=0.5, images=40, per_image=False, mocap=MOCAP):
    """``m`` cameras triggered together; every image of an instant gets the same measured
    pose (``per_image``: each camera's copy one ulp apart, so nothing is shared: the
    behaviour before).  Pixels rendered from the true pose at the paired sample."""
    rng = np.random.default_rng([seed, 7])
    st = simulate_rig_stream(seed, n_cameras=m, setup=setup, duration_s=images / 4.0,
                             mocap_rot_sigma_rad=mocap[0], mocap_trans_sigma_m=mocap[1],
                             interleaved=False)
    k = np.searchsorted(st.mocap_stamps, st.image_stamps[0])
    M_true, M_meas = st.T_world_mocap_true[k], st.T_world_mocap[k]
    pts = default_target_points()
    obs = []
    for j in range(m):
        P = g.inv(st.X[j]) @ (M_true if setup == "eye-to-base" else g.inv(M_true)) @ st.Y
        pc = pts @ np.swapaxes(P[:, :3, :3], 1, 2) + P[:, None, :3, 3]
        uv = project_points(pc.reshape(-1, 3), st.intrinsics[j]).reshape(len(P), -1, 2)
        uv = uv + rng.normal(scale=pixel_sigma, size=uv.shape)
        meas = M_meas.copy()
        if per_image and j:
            meas[:, j - 1, 3] = np.nextafter(meas[:, j - 1, 3], np.inf)
        obs.append([(pts, uv[i], meas[i]) for i in range(len(k))])
    return obs, st, M_true



def _nees(res, st):
    e = np.concatenate([pose_error(res.X[j], st.X[j]) for j in range(len(st.X))]
                       + [pose_error(res.Y, st.Y)])
    return float(e @ np.linalg.solve(res.covariance, e)) / e.size


def test_images_with_the_same_pose_share_an_instant_and_one_prior():
    obs, st, _ = _triggered(1, "eye-to-base", 3, images=6)
    data = image_data("eye-to-base", obs, st.intrinsics)
    assert data.n_images == 18 and data.n_instants == 6
    np.testing.assert_array_equal(data.instant, np.tile(np.arange(6), 3))
    np.testing.assert_array_equal(data.instant_image, np.arange(6))
    priors = [gr for gr in data.groups(0.5, *MOCAP) if isinstance(gr, MocapPriors)]
    assert len(priors) == 1 and priors[0].n_rows == 6
    assert data.mocap_start().shape == (6, 4, 4)
    # one camera's repeated pose is one measurement too; anything else stays apart
    obs[0][3] = (obs[0][3][0], obs[0][3][1], obs[0][2][2])
    obs[2][5] = (obs[2][5][0], obs[2][5][1], obs[2][5][2] + np.finfo(float).eps)
    data = image_data("eye-to-base", obs, st.intrinsics)
    assert data.instant[3] == data.instant[2] == 2
    assert data.instant[17] != data.instant[5]
    # no repeated pose: one instant per image, numbered as the images
    obs, st, _ = _triggered(1, "eye-to-base", 3, images=6, per_image=True)
    data = image_data("eye-to-base", obs, st.intrinsics)
    np.testing.assert_array_equal(data.instant, np.arange(18))


def test_a_camera_with_a_clock_keeps_its_own_blocks():
    obs, st, _ = _triggered(2, "eye-on-hand", 3, images=8)
    clocks = [None, ClockData(st.image_stamps[1], st.mocap_stamps, st.T_world_mocap,
                              offset=0.0), None]
    data = image_data("eye-on-hand", obs, st.intrinsics, clocks=clocks)
    assert data.n_instants == 16
    np.testing.assert_array_equal(data.instant[:8], data.instant[16:])
    assert len(set(data.instant[8:16]) | set(data.instant[:8])) == 16
    groups = data.groups(0.5, *MOCAP)
    timed = [gr for gr in groups if isinstance(gr, TimedMocapPriors)]
    np.testing.assert_array_equal(timed[0].index[:, 0], data.instant[8:16])
    plain = [gr for gr in groups if isinstance(gr, MocapPriors)]
    assert plain[0].n_rows == 8
    res = refine_images("eye-on-hand", obs, st.intrinsics, st.X, st.Y, clocks=clocks,
                        pixel_sigma=0.5, mocap_rot_sigma_rad=MOCAP[0],
                        mocap_trans_sigma_m=MOCAP[1])
    assert res.converged and res.time_offset_std_s[1] > 0


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_jacobians_with_shared_instants(setup, rng):
    obs, st, _ = _triggered(3, setup, 3, images=3)
    data = image_data(setup, obs, st.intrinsics, free_intrinsics=[True, False, False])
    M = g.transform_from_rotvec(rng.normal(scale=0.02, size=(data.n_instants, 3)),
                                rng.normal(scale=0.01, size=(data.n_instants, 3))
                                ) @ data.mocap_start()
    X = g.transform_from_rotvec(rng.normal(scale=0.01, size=(3, 3)), np.zeros((3, 3))) @ st.X
    fams = data.families(X, st.Y, M)
    values = {f.name: f.value for f in fams}
    for group in data.groups(0.5, *MOCAP):
        _, analytic = group.evaluate(values, True)
        for a, n in zip(analytic, numerical_jacobians(fams, group)):
            assert np.abs(a - n).max() <= 1e-6 * np.abs(n).max()


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_exact_recovery_with_shared_instants(setup, rng):
    obs, st, M_true = _triggered(4, setup, 3, pixel_sigma=0.0, images=12, mocap=(0.0, 0.0))
    X0 = g.transform_from_rotvec(rng.normal(scale=0.01, size=(3, 3)),
                                 rng.normal(scale=0.01, size=(3, 3))) @ st.X
    res = refine_images(setup, obs, st.intrinsics, X0, st.Y, pixel_sigma=0.5)
    assert res.converged
    np.testing.assert_allclose(res.X, st.X, atol=1e-8)
    np.testing.assert_allclose(res.Y, st.Y, atol=1e-8)
    for M in res.T_world_mocap:                              # per image, the instant's pose
        np.testing.assert_allclose(M, M_true, atol=1e-8)


def test_per_image_results_are_the_instants_mapped_back():
    obs, st, _ = _triggered(5, "eye-to-base", 3, images=10)
    M_bad = g.transform_from_rotvec([0.0, 0.0, 0.0], [0.004, 0.0, 0.0]) @ obs[0][4][2]
    for j in range(3):                                       # a glitch of one measurement
        obs[j][4] = (obs[j][4][0], obs[j][4][1], M_bad)
    res = refine_images("eye-to-base", obs, st.intrinsics, st.X, st.Y)
    for j in range(1, 3):
        np.testing.assert_array_equal(res.T_world_mocap[j], res.T_world_mocap[0])
        np.testing.assert_array_equal(res.mocap_covariance[10 * j:10 * j + 10],
                                      res.mocap_covariance[:10])
    # the glitch's prior residual belongs to every image sharing it
    for j in range(3):
        assert res.image_outliers[j][4] and res.image_outliers[j].sum() == 1


def test_shared_measurement_counts_once_the_covariance_is_honest():
    """Quick Monte Carlo (4 cameras, 40 instants, 0.05 px: the motion capture's error
    dominates).  Per-image priors (the code before) count each measurement 4 times: mean NEES
    per dimension of X and Y 1.4 here; shared: 1.0.  Full sweep:
    docs/results/shared_instants.md."""
    before, after, sig = [], [], []
    for t in range(12):
        setup = ("eye-to-base", "eye-on-hand")[t % 2]
        kw = dict(pixel_sigma=0.05, mocap_rot_sigma_rad=MOCAP[0], mocap_trans_sigma_m=MOCAP[1],
                  loss="linear")
        for per_image, out in ((True, before), (False, after)):
            obs, st, _ = _triggered(100 + t, setup, 4, pixel_sigma=0.05, per_image=per_image)
            out.append(_nees(refine_images(setup, obs, st.intrinsics, st.X, st.Y, **kw), st))
        res = refine_images(setup, obs, st.intrinsics, st.X, st.Y, pixel_sigma=0.05,
                            mocap_rot_sigma_rad=None, mocap_trans_sigma_m=None)
        sig.append((res.mocap_rot_sigma_rad / MOCAP[0], res.mocap_trans_sigma_m / MOCAP[1]))
    print(np.mean(before), np.mean(after), np.mean(sig, axis=0))
    assert 0.75 < np.mean(after) < 1.2
    assert np.mean(before) > 1.2 and np.mean(before) > np.mean(after) + 0.2
    # the measurement's noise estimated from its one prior per instant: unbiased
    assert np.all(np.abs(np.mean(sig, axis=0) - 1.0) < 0.15)


def test_pairing_at_the_same_time_gives_bitwise_equal_poses():
    """What the sharing relies on: two cameras triggered together, with different numbers of
    images (so the same time sits at different positions of the query), are paired with
    bitwise equal poses, interpolated or not."""
    from multieye.estimate.pairing import pair_in_time

    st = simulate_rig_stream(6, n_cameras=1, duration_s=5.0)
    t = np.arange(0.0, 4.0, 0.0371)
    a = pair_in_time(st.mocap_stamps, st.T_world_mocap, t, tolerance=0.01, offset=0.0123)
    b = pair_in_time(st.mocap_stamps, st.T_world_mocap, np.concatenate([t[5:17], t[::3]]),
                     tolerance=0.01, offset=0.0123)
    assert a.interpolated.all()
    np.testing.assert_array_equal(b.T, np.concatenate([a.T[5:17], a.T[::3]]))
    data = image_data("eye-to-base", [[(np.zeros((1, 3)), np.zeros((1, 2)), T) for T in a.T],
                                     [(np.zeros((1, 3)), np.zeros((1, 2)), T) for T in b.T]],
                     st.intrinsics * 2)
    assert data.n_instants == len(t)
