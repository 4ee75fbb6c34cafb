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


RADTAN4 = Intrinsics(K=[[705.0, 0, 635.0], [0, 703.0, 482.0], [0, 0, 1]],
                     dist=[-0.11, 0.025, 4e-4, 2e-4], width=1280, height=960)


@pytest.mark.parametrize("lens", [RADTAN, RADTAN4, RATIONAL, default_intrinsics("fisheye")],
                         ids=["radtan", "radtan4", "rational", "fisheye"])
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


def test_fisheye_from_four_point_views_starts_from_the_pinhole_calibration():
    """One ArUco marker gives 4 corners per view, on which OpenCV's fisheye calibration fails
    (an assertion inside it); the start then comes from its pinhole calibration, with the
    radial distortion carried over, close enough for the joint refinement."""
    lens = default_intrinsics("fisheye")
    sc = simulate_images(5, n_cameras=1, images=30, intrinsics=[lens], pixel_sigma=0.0,
                         mocap_rot_sigma_rad=0.0, mocap_trans_sigma_m=0.0)
    x, y = sc.object_points[:, 0], sc.object_points[:, 1]
    corners = [np.argmin(x + y), np.argmax(x + y), np.argmin(x - y), np.argmax(x - y)]
    views = [(sc.object_points[corners], u[corners]) for u in sc.image_points[0]]
    cv2 = pytest.importorskip("cv2")
    with pytest.raises(cv2.error):      # what the fallback is for
        cv2.fisheye.calibrate([o.reshape(-1, 1, 3) for o, _ in views],
                              [u.reshape(-1, 1, 2) for _, u in views], (1280, 960),
                              np.eye(3), np.zeros(4), flags=cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC)
    start = initial_intrinsics(views, (1280, 960), "fisheye", name="cam0")
    assert start.intrinsics.model == "fisheye" and start.intrinsics.dist.size == 4
    assert abs(start.intrinsics.K[0, 0] / lens.K[0, 0] - 1) < 0.1
    # the start reprojects the views to a few pixels: a start, not the answer
    err = [np.abs(project_points(o @ T[:3, :3].T + T[:3, 3], start.intrinsics) - u).max()
           for (o, u), T in zip(views, start.T_cam_target)]
    assert np.median(err) < 5.0


def test_equidistant_coefficients_bend_rays_as_the_radial_pinhole_does():
    from multieye.imaging.calibrate import _equidistant_from_radial

    K = np.array([[500.0, 0, 640], [0, 500.0, 480], [0, 0, 1]])
    uv = np.array([[640.0, 480.0], [640 + 500 * 1.2, 480.0]])     # up to r = 1.2 (50 deg)
    for dist in (np.zeros(5), np.array([-0.2, 0.04, 0, 0, -0.003])):
        c = _equidistant_from_radial(dist, K, [(None, uv)])
        t = np.linspace(0.01, 1.2, 50)
        r_pin = t * (1 + dist[0] * t ** 2 + dist[1] * t ** 4 + dist[4] * t ** 6)
        th = np.arctan(t)
        r_fish = th * (1 + c[0] * th ** 2 + c[1] * th ** 4 + c[2] * th ** 6 + c[3] * th ** 8)
        assert np.abs(r_fish - r_pin).max() < 2e-3 * r_pin.max()
    # no distortion: tan(theta) = theta + theta^3 / 3 + 2 theta^5 / 15 + ...
    c = _equidistant_from_radial(np.zeros(5), K, [(None, np.array([[640 + 50.0, 480.0]]))])
    assert abs(c[0] - 1 / 3) < 0.01


def test_the_start_is_the_same_to_the_last_digit_run_after_run():
    """OpenCV's calibrateCamera sums its normal equations on its own threads, in an order
    that changes from call to call: the lens (and with it every result) moved in its last
    digits between identical runs (752 numbers of calibration.json, up to 2e-7 relative, on
    a rendered wall rig). Run alone on one thread it is the same every time."""
    import cv2  # noqa: PLC0415 (this test only: the threads OpenCV would use)

    sc = simulate_images(3, n_cameras=1, images=25, intrinsics=[RADTAN], pixel_sigma=0.3,
                         mocap_rot_sigma_rad=0.0, mocap_trans_sigma_m=0.0)
    views = [(sc.object_points, u) for u in sc.image_points[0]]
    threads = cv2.getNumThreads()
    cv2.setNumThreads(max(threads, 4))          # as on a machine with cores to spare
    try:
        runs = [initial_intrinsics(views, (1280, 960), "pinhole-radtan").intrinsics
                for _ in range(6)]
    finally:
        cv2.setNumThreads(threads)
    assert all(np.array_equal(r.K, runs[0].K) and np.array_equal(r.dist, runs[0].dist)
               for r in runs[1:])
