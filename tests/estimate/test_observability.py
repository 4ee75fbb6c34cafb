"""What a rig linked by its motion leaves undetermined (issue 34, item 3): a rig driven on a
floor whose cameras each see their own boards has every camera's height undetermined, named
along the axis it turned about; the same rig turned fully (the loops close through the
boards) or moved in 6 DoF has nothing undetermined."""

from __future__ import annotations

import numpy as np
import pytest
from wall_rig import wall_rig

from multieye.estimate.motion_residuals import MotionViews
from multieye.estimate.observability import observability, turn_axis
from multieye.estimate.refine_motion import refine_motion


def _observe(seed, sigma_px, **kw):
    s = wall_rig(seed, **kw)
    mv = MotionViews(s.views(sigma_px, np.random.default_rng(seed)), s.intrinsics)
    res = refine_motion(mv, s.T_cam_board(), pixel_sigma=0.3)
    return s, observability(res, mv)


@pytest.mark.parametrize("sigma_px", [0.0, 0.3])
def test_a_floor_driven_rig_that_turns_a_little_leaves_the_heights_undetermined(sigma_px):
    s, obs = _observe(0, sigma_px, motion="planar", yaw_deg=(-25, 115))
    assert obs.turn_axis is not None and abs(obs.turn_axis[1]) > 0.999   # rig's y: vertical
    assert obs.cameras == ("cam1", "cam2", "cam3")
    for u in obs.undetermined:
        assert u.kind == "translation" and u.along_turn_axis
        assert abs(u.direction_rig[1]) > 0.99
        j = int(u.camera[3:])
        assert np.allclose(u.direction_camera, s.T_ref_cam[j, :3, :3].T @ u.direction_rig,
                           atol=0.05)                   # the estimated camera's frame
        assert (f"{u.camera}: translation along the axis the rig turned about (y of the rig)"
                in u.message)
        assert "tilt the rig" in u.message and "overlap" in u.message
        if sigma_px:
            assert 100 < u.sigma / u.best_sigma and u.sigma > 0.3          # metres
        else:
            assert "not determined at all" in u.message


def test_the_same_rig_turned_fully_closes_the_loops():
    _, obs = _observe(0, 0.3, motion="planar", yaw_deg=(0, 360))
    assert obs.turn_axis is not None and obs.undetermined == ()


def test_a_rig_moved_in_6_dof_has_nothing_undetermined():
    _, obs = _observe(1, 0.3)
    assert obs.turn_axis is None and obs.undetermined == ()


def test_turn_axis_needs_turns_about_one_axis():
    from multieye.core import geometry as g
    k = np.array([0.0, 0.6, 0.8])
    T = np.stack([g.make_transform(g.rotation_from_rotvec(a * k), [0, 0, 0])
                  for a in np.linspace(-2, 2, 9)])
    assert np.allclose(turn_axis(T), k)
    T[3, :3, :3] = T[3, :3, :3] @ g.rotation_from_rotvec([0.2, 0.0, 0.0])
    assert turn_axis(T) is None
