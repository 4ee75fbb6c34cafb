"""OpenCV's per-camera calibration as the start of the joint problem: exact on noise-free
views for the three lens models, poses consistent with the views, clear refusals."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics, lens_model
from multieye.core.lens import project_points
from multieye.imaging.calibrate import initial_intrinsics
from multieye.sim.images import default_intrinsics, simulate_images

RATIONAL = Intrinsics(K=[[700.0, 0, 640.5], [0, 702.0, 478.0], [0, 0, 1]],
                      dist=[-0.12, 0.03, 1e-3, -5e-4, -0.004, 0.02, -0.004, 0.002],
                      width=1280, height=960)
RADTAN = Intrinsics(K=[[705.0, 0, 635.0], [0, 703.0, 482.0], [0, 0, 1]],
                    dist=[-0.11, 0.025, 4e-4, 2e-4, -0.003], width=1280, height=960)


@pytest.mark.parametrize("lens", [RADTAN, RATIONAL, default_intrinsics("fisheye")],
                         ids=["radtan", "rational", "fisheye"])
def test_noise_free_views_give_the_lens_back(lens):
    sc = simulate_images(2, n_cameras=1, images=25, intrinsics=[lens], pixel_sigma=0.0,
                         mocap_rot_sigma_rad=0.0, mocap_trans_sigma_m=0.0)
    views = [(sc.object_points, u) for u in sc.image_points[0]]
    start = initial_intrinsics(views, (1280, 960), lens_model(lens), name="cam0")
    assert start.rms_px < 1e-3
    assert start.intrinsics.model == lens.model
    assert start.intrinsics.dist.size == lens.dist.size
    rays = np.concatenate([sc.object_points @ T[:3, :3].T + T[:3, 3]
                           for T in sc.truth.T_cam_target[0]])
    err = np.linalg.norm(project_points(rays, start.intrinsics) - project_points(rays, lens),
                         axis=1)
    assert err.max() < 1e-2
    # the poses it returns reproject the views
    for (obj, uv), T in zip(views, start.T_cam_target):
        pc = obj @ T[:3, :3].T + T[:3, 3]
        assert np.abs(project_points(pc, start.intrinsics) - uv).max() < 1e-2


def test_refusals_name_the_camera_and_what_to_add():
    sc = simulate_images(2, n_cameras=1, images=5)
    views = [(sc.object_points, u) for u in sc.image_points[0]]
    with pytest.raises(InputError, match="camera front: unknown lens model 'kannala'"):
        initial_intrinsics(views, (1280, 960), "kannala", name="front")
    with pytest.raises(InputError, match=r"camera front: 2 image\(s\) with the target, at "
                                         r"least 3 .*add images of the target"):
        initial_intrinsics(views[:2], (1280, 960), "pinhole-radtan", name="front")
