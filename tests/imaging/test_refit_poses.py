"""Many target poses refitted at once (Gauss-Newton over all views in numpy) land where
OpenCV's Levenberg-Marquardt of one view at a time lands, for pinhole and fisheye lenses,
with views of different point counts, and hand a view it cannot fit to that one-view fit;
PnP of many views together gives what PnP of each alone gives."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.lens import project_points
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


@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_many_views_posed_together_as_each_alone(model):
    """estimate_poses: boards together (the pose estimate_pose finds, to 1e-7 where the noise
    moves it by 1e-4), and every view it cannot do together (a single marker whose mirrored
    pose is kept, a circle grid, too few points, points on a line, off the plane) exactly as
    estimate_pose does it, error included."""
    from multieye.imaging.detect import Detection
    from multieye.imaging.pnp import estimate_pose, estimate_poses

    starts, obj, uvs, lens = _views(model, sigma=0.2)
    rng = np.random.default_rng(8)
    dets = [Detection(np.arange(len(o)), u, o) for o, u in zip(obj, uvs)]
    # a 5 cm marker 2 m away: its mirrored pose fits too, and is kept
    square = np.array([[0, 0, 0], [0.05, 0, 0], [0.05, 0.05, 0], [0, 0.05, 0]], dtype=float)
    T = g.transform_from_rotvec([np.radians(25.0), 0, 0], [0, 0, 2.0])
    marker = Detection(np.arange(4), project_points(square @ T[:3, :3].T + T[:3, 3], lens) + rng.normal(0, 0.3, (4, 2)),
                       square)
    circles = replace(dets[2], circle_diameter=0.01)
    line = Detection(np.arange(5), uvs[0][:5] * [1, 0] + [0, 400.0],
                     np.column_stack([np.linspace(0, 0.2, 5), np.zeros(5), np.zeros(5)]))
    bumpy = obj[1].copy()
    bumpy[3, 2] = 0.01
    dets += [marker, circles, line, Detection(np.arange(3), uvs[0][:3], obj[0][:3]),
             Detection(np.arange(len(bumpy)), uvs[1], bumpy)]
    together = estimate_poses(dets, lens)
    assert len(together) == len(dets)
    for det, pose in zip(dets, together):
        try:
            alone = estimate_pose(det, lens)
        except InputError as exc:
            assert isinstance(pose, InputError) and str(pose) == str(exc)
            continue
        assert isinstance(pose, type(alone))
        assert np.abs(pose.T_cam_target - alone.T_cam_target).max() < 1e-7
        assert abs(pose.rms_px - alone.rms_px) < 1e-9
        assert pose.n_points == alone.n_points
        assert (pose.alternative is None) == (alone.alternative is None)
    assert together[30].alternative is not None                 # the marker kept both
    np.testing.assert_array_equal(together[31].T_cam_target,    # the circles: alone
                                  estimate_pose(circles, lens).T_cam_target)
    assert [type(p) for p in together[32:]] == [InputError] * 3
    assert estimate_poses([], lens) == []


def test_many_views_in_parts_as_in_one(monkeypatch):
    """Above a number of views the fit goes in parts (memory bounded): the same poses."""
    from multieye.imaging import pnp

    starts, obj, uvs, lens = _views("pinhole", sigma=0.2)
    whole = refit_poses(starts, obj, uvs, lens)
    monkeypatch.setattr(pnp, "_REFIT_VIEWS", 7)
    parts = refit_poses(starts, obj, uvs, lens)
    assert len(parts) == len(whole) == 30
    for a, b in zip(whole, parts):
        # (the padding to the part's largest view may change the sums' rounding)
        np.testing.assert_allclose(a.T_cam_target, b.T_cam_target, rtol=0, atol=1e-12)
        assert abs(a.rms_px - b.rms_px) < 1e-12
