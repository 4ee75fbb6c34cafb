"""``--time-offset auto`` on a rig with motion capture moved before several still boards
(issue 34, item 1 with the clock of the one-board path): each camera's offset is estimated
from the board it sees most and held, the images are paired at it, and the record states
it with the search's standard deviation.  Until now this path refused ``auto``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import CalibrationError
from multieye.core.lie import log_so3
from multieye.io import Rig
from multieye.io.trajectory import Trajectory
from multieye.pipeline.run import calibrate_rig
from multieye.sim.wall_boards import WallSpec, simulate_walls

from wall_camera_data import wall_camera_data

SIGMA = 0.3
OFFSET = 0.137             # motion-capture clock minus camera clock, seconds
IMAGE_DT = 0.2             # seconds between the rig's images


def body_pose(t):
    """A smooth 6-DoF path of the rig's body at time ``t`` (camera clock), turning about every
    axis at once (what a clock search needs)."""
    yaw = 0.5 * np.sin(2 * np.pi * t / 9.0) + 0.35 * np.sin(2 * np.pi * t / 2.9)
    roll, pitch = 0.18 * np.sin(2 * np.pi * t / 2.3), 0.18 * np.sin(2 * np.pi * t / 3.7 + 1.0)
    R = g.transform_from_rotvec([0.0, 0.0, yaw], [0, 0, 0])[:3, :3] @ \
        g.transform_from_rotvec([roll, pitch, 0.0], [0, 0, 0])[:3, :3]
    p = [0.4 * np.sin(2 * np.pi * t / 5.0), 0.4 * np.sin(2 * np.pi * t / 6.3 + 0.5),
         1.2 + 0.12 * np.sin(2 * np.pi * t / 4.1)]
    return g.make_transform(R, p)


def _rig_and_cameras(offset=OFFSET, seed=0, n_images=100, camera_clocks=None):
    """The rig, its 4 cameras' data (cam3 sees a board in 3 images only) and the truth;
    ``camera_clocks``: each camera's clock ahead of the first's by this many seconds (its
    stamps shifted; default all on one clock, stamps equal)."""
    times = IMAGE_DT * np.arange(n_images)
    T_wb = np.stack([body_pose(t) for t in times])
    sc = simulate_walls(np.random.default_rng(seed), WallSpec(), T_world_body=T_wb)
    rng = np.random.default_rng(seed + 1)
    mocap_t = np.arange(-1.0, times[-1] + 1.0, 1 / 120)
    mocap = Trajectory(mocap_t + offset, np.stack([body_pose(t) for t in mocap_t]),
                       parent="world", child="body")
    cams = wall_camera_data(
        sc, SIGMA, rng, start_noise=(0.003, 0.002), mocap=mocap, time_tolerance=0.01,
        stamp=lambda i, j: times[i] + (0 if camera_clocks is None else camera_clocks[j]))
    rig = Rig(path=Path("rig.yaml"), setup="eye-on-hand", cameras={},
              targets={n: {k: v for k, v in s.items() if k != "cameras"}
                       for n, s in sc.targets.items()})
    return sc, rig, cams


@pytest.fixture(scope="module")
def auto_run():
    sc, rig, cams = _rig_and_cameras()
    return sc, calibrate_rig(rig, cams, time_offset="auto")


def test_one_clock_gets_one_offset_recorded_with_its_deviation(auto_run):
    """The cameras are triggered together (equal stamps): one offset for all, within 2 ms of
    the truth; cam3, whose 3 views cannot be timed, takes it too; the warnings say so."""
    _, run = auto_run
    offsets = {cam.time_offset_s for cam in run.record.cameras}
    assert len(offsets) == 1 and offsets.pop() == pytest.approx(OFFSET, abs=2e-3)
    assert all(0 < cam.time_offset_std_s < 2e-3 for cam in run.record.cameras)
    assert any(w.startswith("cam0, cam1, cam2: image stamps equal (triggered together)")
               for w in run.record.warnings)
    assert any(w.startswith("camera cam3: too few views to time its clock") and
               "its image stamps are cam0's" in w for w in run.record.warnings)


def test_cameras_on_clocks_of_their_own_get_their_own_offsets():
    """Each camera stamps with its own clock (10 ms apart): each offset is estimated from its
    own views; cam3, on a clock of its own with 3 views, cannot be timed: refused, named."""
    shifts = [0.0, 0.01, 0.02, 0.03]
    _, rig, cams = _rig_and_cameras(camera_clocks=shifts)
    with pytest.raises(CalibrationError, match="camera cam3: clock offset could not be estimated"):
        calibrate_rig(rig, cams, time_offset="auto")
    del cams["cam3"]
    run = calibrate_rig(rig, cams, time_offset="auto")
    for j, cam in enumerate(run.record.cameras):
        assert cam.time_offset_s == pytest.approx(OFFSET - shifts[j], abs=2e-3), cam.name
    assert not any("triggered together" in w for w in run.record.warnings)


def test_the_rig_is_calibrated_at_the_estimated_offsets(auto_run):
    """``T_ref_cam`` within its covariance of the truth: the images were paired with the
    motion capture at the estimated clock (at offset 0 the poses would be 0.137 s of a
    turning rig apart)."""
    sc, run = auto_run
    assert run.record.method == "motion-links" and run.record.setup == "eye-on-hand"
    for j, cam in enumerate(run.record.cameras):
        if cam.name == run.record.reference_camera:
            continue
        T = cam.T_ref_cam
        e = np.concatenate([log_so3(T[:3, :3] @ sc.T_ref_cam[j, :3, :3].T),
                            T[:3, 3] - sc.T_ref_cam[j, :3, 3]])
        assert float(e @ np.linalg.solve(cam.covariance, e)) < 30, cam.name      # chi2(6)


def test_a_given_offset_is_recorded_without_a_deviation():
    _, rig, cams = _rig_and_cameras(n_images=30)
    run = calibrate_rig(rig, cams, time_offset=OFFSET)
    for cam in run.record.cameras:
        assert cam.time_offset_s == OFFSET and cam.time_offset_std_s is None


def test_a_search_range_that_misses_the_offset_is_refused_naming_the_camera():
    _, rig, cams = _rig_and_cameras(offset=0.45, n_images=30)
    with pytest.raises(CalibrationError, match=r"camera cam\d: the best clock offset .* edge"):
        calibrate_rig(rig, cams, time_offset="auto", max_time_offset=0.2)
