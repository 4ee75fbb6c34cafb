"""Cameras triggered together on one clock (ClockData.shared, estimate/clock_residuals.py):
one offset, one motion-capture block and one timed prior per instant; exact recovery without
noise, the Jacobian, a quick look at the NEES (benchmarks/bench_clock_joint.py runs the full
Monte Carlo), the checks and the grouping by stamps."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.estimate.clock_residuals import (ClockData, TimedMocapPriors, offset_family,
                                               shared_clocks)
from multieye.estimate.image_data import ImageProblem, image_data
from multieye.estimate.refine_images import refine_images
from multieye.optimize.gradient_check import numerical_jacobians
from multieye.sim.streams import simulate_rig_stream
from multieye.estimate.uncertainty import pose_error


def _shared(st, start, name="rig"):
    return [ClockData(st.image_stamps[j], st.mocap_stamps, st.T_world_mocap, offset=start[j],
                      shared=name) for j in range(len(st.X))]



def test_cameras_on_one_clock_share_the_offset_the_instants_and_the_priors():
    st = simulate_rig_stream(4, n_cameras=3, duration_s=5.0, time_offsets_s=0.04,
                             interleaved=False)
    assert all(np.array_equal(t, st.image_stamps[0]) for t in st.image_stamps)
    data = image_data(ImageProblem(st.setup, st.observations, st.intrinsics,
                     clocks=_shared(st, [0.041, 0.043, 0.045])))
    n = len(st.image_stamps[0])
    assert data.n_images == 3 * n and data.n_instants == n
    assert all(np.array_equal(data.instant[data.cam_of_image == j], np.arange(n))
               for j in range(3))
    fams = data.families(st.X, st.Y)
    assert [f.name for f in fams if f.name.startswith("dt:")] == ["dt:cam0"]
    assert next(f for f in fams if f.name == "dt:cam0").value[0, 0] == pytest.approx(0.043)
    priors = [gr for gr in data.groups(0.5, 1e-3, 3e-4) if gr.slots[0] == "M"]
    assert len(priors) == 1 and priors[0].index.shape == (n, 2)
    assert len(data.units.trajectories[0].h) == n           # one window fit per instant


def test_a_camera_with_extra_images_shares_the_common_instants():
    """Camera 1 skips every third image of the shared clock and camera 2 keeps its own
    clock: the instants are the union of the shared stamps, camera 2 has its own."""
    st = simulate_rig_stream(5, n_cameras=3, duration_s=5.0, time_offsets_s=0.02,
                             interleaved=False)
    keep = np.arange(len(st.image_stamps[1])) % 3 != 0
    obs = [st.observations[0], [o for o, k in zip(st.observations[1], keep) if k],
           st.observations[2]]
    clocks = [ClockData(st.image_stamps[0], st.mocap_stamps, st.T_world_mocap, 0.02,
                        shared="a"),
              ClockData(st.image_stamps[1][keep], st.mocap_stamps, st.T_world_mocap, 0.02,
                        shared="a"),
              ClockData(st.image_stamps[2], st.mocap_stamps, st.T_world_mocap, 0.02)]
    data = image_data(ImageProblem(st.setup, obs, st.intrinsics, clocks=clocks))
    n = len(st.image_stamps[0])
    assert data.n_instants == 2 * n
    assert np.array_equal(data.instant[data.cam_of_image == 1], np.flatnonzero(keep))
    assert [f.name for f in data.families(st.X, st.Y) if f.name.startswith("dt:")] == \
        ["dt:cam0", "dt:cam2"]


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_shared_offset_and_rig_recovered_exactly_without_noise(setup):
    offset = 0.0613
    st = simulate_rig_stream(11, n_cameras=3, setup=setup, duration_s=10.0,
                             time_offsets_s=offset, pixel_sigma=0.0, mocap_rot_sigma_rad=0.0,
                             mocap_trans_sigma_m=0.0, interleaved=False)
    X0 = np.stack([g.transform_from_rotvec([0.01, -0.01, 0.005], [0.005, 0.0, -0.005]) @ x
                   for x in st.X])
    res = refine_images(setup, st.observations, st.intrinsics, X0, st.Y, pixel_sigma=0.3,
                        mocap_rot_sigma_rad=1e-3, mocap_trans_sigma_m=3e-4, loss="linear",
                        clocks=_shared(st, [offset + 0.03, offset + 0.02, offset + 0.025]),
                        tol=1e-14, max_iter=200)
    np.testing.assert_allclose(res.time_offsets, offset, atol=1e-6)
    assert len(set(res.time_offsets)) == 1 and len(set(res.time_offset_std_s)) == 1
    assert 0 < res.time_offset_std_s[0] < 1e-3
    assert np.abs(res.X - st.X).max() < 1e-6 and np.abs(res.Y - st.Y).max() < 1e-6
    assert [f for f in res.layout.offset if f.startswith("dt:")] == ["dt:cam0"]
    # the images of one instant share one pose
    assert all(np.array_equal(res.T_world_mocap[0], T) for T in res.T_world_mocap[1:])


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_shared_timed_prior_jacobian_matches_central_differences(setup):
    st = simulate_rig_stream(3, n_cameras=3, setup=setup, duration_s=6.0,
                             time_offsets_s=0.03, interleaved=False)
    data = image_data(ImageProblem(setup, st.observations, st.intrinsics,
                     clocks=_shared(st, [0.0313] * 3)))
    rng = np.random.default_rng(0)
    M = g.transform_from_rotvec(rng.normal(scale=0.01, size=(data.n_instants, 3)),
                                rng.normal(scale=0.01, size=(data.n_instants, 3))
                                ) @ data.mocap_start()
    fams = data.families(st.X, st.Y, M)
    groups = [gr for gr in data.groups(0.3, 1e-3, 3e-4) if isinstance(gr, TimedMocapPriors)]
    assert len(groups) == 1
    _, analytic = groups[0].evaluate({f.name: f.value for f in fams}, True)
    for a, n in zip(analytic, numerical_jacobians(fams, groups[0], step=1e-7)):
        assert np.abs(a - n).max() <= 1e-5 * np.abs(n).max()


def test_shared_clock_nees_near_one_quick():
    """Quick version of bench_clock_joint's shared-clock rows: 3 cameras triggered together,
    0.05 px (where the motion capture's error dominates and counting it three times gave a
    mean NEES of X and Y of 1.3), least squares, noise stated.  A loose band."""
    nees, z = [], []
    for seed in range(8):
        rng = np.random.default_rng([seed, 1])
        offset = rng.uniform(-0.1, 0.1)
        st = simulate_rig_stream(seed + 900, n_cameras=3, duration_s=20.0,
                                 time_offsets_s=offset, pixel_sigma=0.05, interleaved=False)
        res = refine_images(st.setup, st.observations, st.intrinsics, st.X, st.Y,
                            pixel_sigma=0.05, mocap_rot_sigma_rad=1e-3,
                            mocap_trans_sigma_m=3e-4, loss="linear",
                            clocks=_shared(st, [offset + 0.002] * 3))
        e = np.concatenate([pose_error(res.X[j], st.X[j]) for j in range(3)] + [pose_error(res.Y, st.Y)])
        nees.append(e @ np.linalg.solve(res.covariance, e) / e.size)
        z.append((res.time_offsets[0] - offset) / res.time_offset_std_s[0])
    assert 0.7 < np.mean(nees) < 1.3
    assert np.mean(np.square(z)) < 4.0


def test_shared_clock_is_checked_and_grouped_by_stamps():
    st = simulate_rig_stream(2, n_cameras=2, duration_s=3.0, interleaved=False)
    other = st.T_world_mocap.copy()
    other[:, 0, 3] += 1e-3
    clocks = [ClockData(st.image_stamps[0], st.mocap_stamps, st.T_world_mocap, shared="a"),
              ClockData(st.image_stamps[1], st.mocap_stamps, other, shared="a")]
    with pytest.raises(InputError, match="share the clock 'a' but not its motion capture"):
        image_data(ImageProblem(st.setup, st.observations, st.intrinsics, clocks=clocks))
    t = np.arange(10.0)
    assert shared_clocks([t, t.copy(), t + 0.5]) == [[0, 1]]
    assert shared_clocks([t, t[:5], t[5:]]) == [[0, 1, 2]]        # transitively, via camera 0
    assert shared_clocks([t, t[:4]]) == []                         # 4 of 10: under half
    assert shared_clocks([t, t + 1e-12]) == []
    # on two motion captures, cameras triggered together are not on one clock; the third
    # camera's motion capture (equal samples, another array) is the first one's
    m = (np.arange(5.0), np.tile(np.eye(4), (5, 1, 1)))
    m2 = (m[0], m[1].copy())
    m2[1][:, 0, 3] += 1e-3
    assert shared_clocks([t, t, t], [m, m2, m]) == [[0, 2]]
    assert shared_clocks([t, t], [m, (m[0].copy(), m[1].copy())]) == [[0, 1]]
    assert offset_family("cam0") == "dt:cam0"
