"""PnP through the wide-angle lens models: IPPE on the rays in front of the camera, the
refinement through every point the model places, rays beyond 90 degrees included."""

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, projectable
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import estimate_pose, estimate_poses, refit_pose, refit_poses

LENSES = [
    Intrinsics(K=[[560.0, 0, 321], [0, 559, 238], [0, 0, 1]],
               dist=[1.2, -0.05, 0.01, 0.0005, -0.0003], model="unified"),
    Intrinsics(K=[[250.0, 0, 318], [0, 251, 241], [0, 0, 1]], dist=[0.3, 0.6],
               model="double-sphere"),
    Intrinsics(K=[[300.0, 0, 320], [0, 300, 240], [0, 0, 1]], dist=[0.6, 1.1], model="eucm"),
]
BOARD = np.array([[x, y, 0.0] for y in np.arange(6) * 0.05 for x in np.arange(9) * 0.05])


def _side_view():
    """A board beside the camera, reaching behind its image plane (corners up to 114 degrees
    off the axis, a third of them at z < 0)."""
    return g.transform_from_rotvec([0.0, 1.05, 0.0], [0.25, -0.12, 0.15])


def _detection(uv):
    return Detection(np.arange(len(BOARD)), uv, BOARD)


@pytest.mark.parametrize("lens", LENSES, ids=lambda c: c.model)
def test_pose_through_rays_beyond_90_degrees(lens):
    T = _side_view()
    P = BOARD @ T[:3, :3].T + T[:3, 3]
    assert np.all(projectable(P, lens)) and np.mean(P[:, 2] < 0) > 0.25
    uv = project_points(P, lens)
    pose = estimate_pose(_detection(uv), lens)
    assert pose.n_points == len(BOARD)                  # the rays behind the plane kept
    assert pose.rms_px < 1e-8
    np.testing.assert_allclose(pose.T_cam_target, T, atol=1e-9)
    # refitting from a nearby pose, alone and batched, through the same model
    T0 = T @ g.transform_from_rotvec([0.01, -0.02, 0.015], [0.003, -0.002, 0.004])
    np.testing.assert_allclose(refit_pose(T0, BOARD, uv, lens).T_cam_target, T, atol=1e-9)
    batch = refit_poses(np.stack([T0, T0]), [BOARD, BOARD], [uv, uv], lens)
    np.testing.assert_allclose(batch[1].T_cam_target, T, atol=1e-9)
    assert estimate_poses([_detection(uv)], lens)[0].rms_px < 1e-8


@pytest.mark.parametrize("lens", LENSES, ids=lambda c: c.model)
def test_pose_with_noise_is_the_least_squares_pose(lens):
    rng = np.random.default_rng(4)
    T = g.transform_from_rotvec([0.3, -0.2, 0.1], [-0.1, -0.1, 0.5])
    uv = project_points(BOARD @ T[:3, :3].T + T[:3, 3], lens) + rng.normal(0, 0.2, (54, 2))
    pose = estimate_pose(_detection(uv), lens)
    assert 0.1 < pose.rms_px < 0.3
    # the least-squares pose: the one the refinement reaches from the true pose
    best = refit_pose(T, BOARD, uv, lens)
    np.testing.assert_allclose(pose.T_cam_target, best.T_cam_target, atol=1e-8)
    assert abs(pose.rms_px - best.rms_px) < 1e-10
