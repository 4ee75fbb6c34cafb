"""Many target poses refitted at once (Gauss-Newton over all views in numpy) land where
OpenCV's Levenberg-Marquardt of one view at a time lands, for pinhole and fisheye lenses,
with views of different point counts, and hand a view it cannot fit to that one-view fit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.imaging.pnp import refit_pose, refit_poses
from multieye.sim.images import default_intrinsics, simulate_images


def _views(model: str, sigma: float, seed: int = 3):
    lens = default_intrinsics(model)
    sc = simulate_images(seed, n_cameras=1, images=30, intrinsics=[lens], pixel_sigma=sigma,
                         mocap_rot_sigma_rad=0.0, mocap_trans_sigma_m=0.0)
    rng = np.random.default_rng(seed)
    obj, uvs, starts = [], [], []
    for k, (uv, T) in enumerate(zip(sc.image_points[0], sc.truth.T_cam_target[0])):
        keep = np.arange(len(uv)) if k % 3 else rng.choice(len(uv), 12 + k, replace=False)
        obj.append(sc.object_points[keep])
        uvs.append(uv[keep])
        # the start: the pose a slightly different lens gave (a mm, a few mrad away)
        starts.append(T @ g.transform_from_rotvec(rng.normal(0, 3e-3, 3),
                                                  rng.normal(0, 1e-3, 3)))
    # the lens the poses are refitted with: not the one that made the pixels
    K = lens.K.copy()
    K[0, 0] *= 1.002
    return np.stack(starts), obj, uvs, replace(lens, K=K)


@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_all_views_at_once_land_where_one_view_at_a_time_does(model):
    starts, obj, uvs, lens = _views(model, sigma=0.3)
    together = refit_poses(starts, obj, uvs, lens)
    alone = [refit_pose(T, o, u, lens) for T, o, u in zip(starts, obj, uvs)]
    assert len(together) == len(alone) == len(starts)
    for a, b, o in zip(together, alone, obj):
        # the noise moves a pose by about 1e-4 (rad, m); both fits agree far below it (OpenCV's
        # iteration stops up to 2e-8 short where a view's pose is weakly determined)
        assert np.abs(a.T_cam_target - b.T_cam_target).max() < 1e-7
        assert a.rms_px <= b.rms_px + 1e-12 and abs(a.rms_px - b.rms_px) < 1e-9
        assert abs(a.max_px - b.max_px) < 1e-6
        assert a.n_points == len(o)
        assert np.allclose(a.T_cam_target[3], [0, 0, 0, 1])
        assert np.abs(a.T_cam_target[:3, :3].T @ a.T_cam_target[:3, :3] - np.eye(3)).max() < 1e-12
    # and it is the optimum: fitting again from it stays there
    again = refit_poses(np.stack([p.T_cam_target for p in together]), obj, uvs, lens)
    for a, b in zip(together, again):
        assert np.abs(a.T_cam_target - b.T_cam_target).max() < 1e-11
    # the fit moved the poses from their start, and it reports the residual of the pixels
    assert max(np.abs(a.T_cam_target - T).max() for a, T in zip(together, starts)) > 1e-4
    assert 0.1 < np.median([a.rms_px for a in together]) < 1.0


def test_a_view_the_batch_cannot_fit_is_fitted_alone():
    starts, obj, uvs, lens = _views("pinhole", sigma=0.2)
    # one view's start behind the camera: its points do not project, the batch gives it up
    flipped = starts.copy()
    flipped[4, :3, 3] *= -1
    together = refit_poses(flipped, obj, uvs, lens)
    alone = refit_pose(flipped[4], obj[4], uvs[4], lens)
    np.testing.assert_array_equal(together[4].T_cam_target, alone.T_cam_target)
    assert together[4].rms_px == alone.rms_px
    others = refit_poses(starts, obj, uvs, lens)
    for k in (0, 3, 5, 29):
        assert np.abs(together[k].T_cam_target - others[k].T_cam_target).max() < 1e-12


def test_refusals():
    starts, obj, uvs, lens = _views("pinhole", sigma=0.2)
    assert refit_poses(np.zeros((0, 4, 4)), [], [], lens) == []
    with pytest.raises(InputError, match="at least 4 points, got 3"):
        refit_poses(starts[:2], [obj[0], obj[1][:3]], [uvs[0], uvs[1][:3]], lens)
    with pytest.raises(InputError, match="one of each per view"):
        refit_poses(starts[:2], obj[:3], uvs[:3], lens)
