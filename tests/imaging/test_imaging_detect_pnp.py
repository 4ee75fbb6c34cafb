"""Render -> detect -> PnP recovers the pose, for every target type and both camera models;
canonical point order survives a half turn of the image."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from multieye.core.errors import InputError
from multieye.core.geometry import rotation_angle_between, translation_distance
from multieye.core.lens import project_points
from multieye.imaging.detect import Detection, detect
from multieye.imaging.pnp import estimate_pose
from multieye.sim.render import render, visible
from multieye.imaging.targets import AprilGrid, AsymmetricCircleGrid, Charuco, Chessboard, CircleGrid
from multieye.core.intrinsics import Intrinsics
from board_poses import PINHOLE, facing_pose

FISHEYE = Intrinsics(K=[[300, 0, 399.5], [0, 300, 299.5], [0, 0, 1]],
                     dist=[-0.02, 0.005, -0.001, 0.0002], model="fisheye", width=800, height=600)
CAMERAS = {"pinhole": (PINHOLE, 0.5), "fisheye": (FISHEYE, 0.3)}    # camera, board distance (m)

TARGETS = {
    "chessboard": Chessboard(rows=6, cols=9, spacing=0.04),
    "circles": CircleGrid(rows=6, cols=8, spacing=0.04, diameter=0.02),
    "asymmetric-circles": AsymmetricCircleGrid(rows=11, cols=7, spacing=0.04, diameter=0.02),
    "charuco": Charuco(rows=7, cols=9, spacing=0.04, marker_size=0.028, dictionary="DICT_5X5_100"),
    "aprilgrid": AprilGrid(rows=5, cols=6, spacing=0.04, tag_spacing=0.3),
}


def true_pixels(target, camera, T, ids):
    P = target.object_points()[ids]
    return project_points(P @ T[:3, :3].T + T[:3, 3], camera)


@pytest.mark.parametrize("camera_name", sorted(CAMERAS))
@pytest.mark.parametrize("kind", list(TARGETS))
def test_rendered_target_gives_back_its_pose(kind, camera_name):
    target = TARGETS[kind]
    camera, distance = CAMERAS[camera_name]
    T = facing_pose(target, [0.35, -0.3, 0.1], distance, offset=(0.01, -0.01))
    assert visible(target, camera, T)
    image = render(target, camera, T, rng=np.random.default_rng(7))
    det = detect(image, target)
    assert det is not None
    if kind in ("charuco", "aprilgrid"):
        assert len(det) >= 0.9 * target.n_points
    else:
        assert len(det) == target.n_points
    np.testing.assert_array_equal(det.object_points, target.object_points()[det.ids])
    # every point where the camera model puts it, so the order is the canonical one
    err = np.linalg.norm(det.image_points - true_pixels(target, camera, T, det.ids), axis=1)
    assert err.max() < 0.5
    pose = estimate_pose(det, camera)
    assert np.degrees(rotation_angle_between(pose.T_cam_target, T)) < 0.05
    assert translation_distance(pose.T_cam_target, T) < 1e-3
    assert pose.rms_px < 0.3 and pose.n_points == len(det)
    # the symmetric circle grid cannot tell its order: it says so
    assert bool(det.warnings) == (kind == "circles")


def rotate_half_turn(image):
    return np.ascontiguousarray(image[::-1, ::-1])


def test_chessboard_order_survives_a_half_turn():
    """Turning the image by 180 deg is a camera turned about its axis (centred principal
    point, radial distortion only). OpenCV reports the corners from the image's top-left
    either way; the detector must put them back on the board's own first corner."""
    camera = Intrinsics(K=[[600, 0, 399.5], [0, 600, 299.5], [0, 0, 1]], dist=[-0.25, 0.08, 0, 0, -0.01],
                        width=800, height=600)
    board = Chessboard(rows=6, cols=9, spacing=0.04)
    T = facing_pose(board, [0.3, -0.25, 0.15], 0.55)
    T_turned = np.diag([-1.0, -1.0, 1.0, 1.0]) @ T
    image = render(board, camera, T, rng=np.random.default_rng(3))
    turned = rotate_half_turn(image)

    raw = [cv2.findChessboardCornersSB(img, (9, 6))[1].reshape(-1, 2) for img in (image, turned)]
    truth = [true_pixels(board, camera, T, np.arange(54)), true_pixels(board, camera, T_turned, np.arange(54))]
    starts_at_last = [np.linalg.norm(r[0] - t[-1]) < 1.0 for r, t in zip(raw, truth)]
    assert any(starts_at_last), "OpenCV did not flip the order: the test would prove nothing"

    for img, T_true, t in ((image, T, truth[0]), (turned, T_turned, truth[1])):
        det = detect(img, board)
        assert det.warnings == ()
        assert np.linalg.norm(det.image_points - t, axis=1).max() < 0.5
        pose = estimate_pose(det, camera)
        assert np.degrees(rotation_angle_between(pose.T_cam_target, T_true)) < 0.05


def test_symmetric_chessboard_warns_and_keeps_x_to_the_right():
    camera = Intrinsics(K=[[600, 0, 399.5], [0, 600, 299.5], [0, 0, 1]], width=800, height=600)
    board = Chessboard(rows=6, cols=8, spacing=0.04)          # rows + cols even: half-turn symmetric
    T = facing_pose(board, [0.2, -0.25, 0.1], 0.55)
    image = render(board, camera, T)
    upright = true_pixels(board, camera, T, np.arange(48))
    turned = true_pixels(board, camera, np.diag([-1.0, -1, 1, 1]) @ T, np.arange(48))
    # upright, the true order has x to the right; turned, only the order turned back has
    for img, expected in ((image, upright), (rotate_half_turn(image), turned[::-1])):
        det = detect(img, board)
        assert len(det.warnings) == 1 and "looks the same after a turn" in det.warnings[0]
        assert det.image_points[1, 0] > det.image_points[0, 0]
        assert np.linalg.norm(det.image_points - expected, axis=1).max() < 0.5


@pytest.mark.parametrize("board", [Chessboard(rows=6, cols=8, spacing=0.04),
                                   Chessboard(rows=8, cols=6, spacing=0.04)])
def test_symmetric_chessboard_turned_a_quarter_keeps_one_order(board):
    """A half-turn symmetric board whose x axis is near vertical in the image (a portrait
    board, or rows and cols swapped in rig.yaml) turned by 88 and by 92 degrees: two
    cameras of a stereo pair see it so. Both views must take the same corner first, else
    the rig's cameras disagree by a half turn of the board (a garbage stereo calibration)."""
    camera = Intrinsics(K=[[600, 0, 399.5], [0, 600, 299.5], [0, 0, 1]], width=800, height=600)
    chosen = []
    for degrees in (88.0, 92.0, -88.0, -92.0):
        turn = np.eye(4)
        turn[:3, :3] = cv2.Rodrigues(np.array([0.0, 0.0, np.radians(degrees)]))[0]
        T = turn @ facing_pose(board, [0.15, -0.1, 0.0], 0.6)
        det = detect(render(board, camera, T, rng=np.random.default_rng(5)), board)
        assert det is not None and len(det.warnings) == 1
        ids = np.arange(board.n_points)
        as_is = np.linalg.norm(det.image_points - true_pixels(board, camera, T, ids), axis=1)
        turned = np.linalg.norm(det.image_points - true_pixels(board, camera, T, ids[::-1]), axis=1)
        assert min(as_is.max(), turned.max()) < 0.5
        chosen.append(bool(as_is.max() < 0.5))
    assert chosen[0] == chosen[1] and chosen[2] == chosen[3]


def test_light_circles_on_dark_are_found():
    board = AsymmetricCircleGrid(rows=11, cols=7, spacing=0.03)
    T = facing_pose(board, [0.25, 0.2, 0.05], 0.45)
    image = render(board, PINHOLE, T, inverted=True, rng=np.random.default_rng(1))
    det = detect(image, board)
    assert det is not None and len(det) == 77
    assert np.linalg.norm(det.image_points - true_pixels(board, PINHOLE, T, det.ids), axis=1).max() < 0.5


@pytest.mark.parametrize("kind", ["charuco", "aprilgrid"])
def test_partial_views_keep_their_ids(kind):
    target = TARGETS[kind]
    T = facing_pose(target, [0.2, -0.2, 0.05], 0.45, offset=(0.27, 0.0))   # right part outside
    assert not visible(target, PINHOLE, T)
    image = render(target, PINHOLE, T, rng=np.random.default_rng(2))
    det = detect(image, target)
    assert det is not None and 8 <= len(det) < target.n_points
    assert np.linalg.norm(det.image_points - true_pixels(target, PINHOLE, T, det.ids), axis=1).max() < 0.5
    pose = estimate_pose(det, PINHOLE)
    assert np.degrees(rotation_angle_between(pose.T_cam_target, T)) < 0.1


@pytest.mark.parametrize("kind", list(TARGETS))
def test_no_target_no_detection(kind):
    rng = np.random.default_rng(0)
    blank = np.clip(128 + rng.normal(0, 3, (480, 640)), 0, 255).astype(np.uint8)
    assert detect(blank, TARGETS[kind]) is None


def test_colour_and_16_bit_images_are_accepted():
    board = TARGETS["chessboard"]
    T = facing_pose(board, [0.2, 0.1, 0.0], 0.5)
    gray = render(board, PINHOLE, T)
    for image in (cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR), gray.astype(np.uint16) * 257):
        det = detect(image, board)
        assert det is not None and len(det) == 54


def test_pnp_rejects_degenerate_point_sets():
    obj = np.column_stack([np.linspace(0, 0.2, 6), np.zeros(6), np.zeros(6)])
    det = Detection(ids=np.arange(6), image_points=np.column_stack([np.linspace(300, 500, 6), np.full(6, 300.0)]),
                    object_points=obj)
    with pytest.raises(InputError, match="lie on one line"):
        estimate_pose(det, PINHOLE)
    with pytest.raises(InputError, match="at least 4 points, got 3"):
        estimate_pose(Detection(np.arange(3), det.image_points[:3], obj[:3]), PINHOLE)
    bumpy = obj.copy()
    bumpy[:, 1] = [0, 0.1, 0, 0.1, 0, 0.1]
    bumpy[0, 2] = 0.05
    with pytest.raises(InputError, match="z = 0"):
        estimate_pose(Detection(np.arange(6), det.image_points, bumpy), PINHOLE)


def test_pnp_is_exact_on_exact_points(rng):
    """No image, no noise: the exact projections give back the pose to numerical precision,
    for both models (the fisheye refinement included)."""
    board = Chessboard(rows=5, cols=7, spacing=0.05)
    for camera in (PINHOLE, FISHEYE):
        T = facing_pose(board, rng.normal(0, 0.3, 3), 0.6)
        pts = true_pixels(board, camera, T, np.arange(35))
        pose = estimate_pose(Detection(np.arange(35), pts, board.object_points()), camera)
        np.testing.assert_allclose(pose.T_cam_target, T, atol=1e-8)
        assert pose.rms_px < 1e-6 and pose.max_px < 1e-5


def test_pnp_pixel_errors_are_the_reprojection_residuals(rng):
    """estimate_pose scores its candidates and reports its RMS with cv2.projectPoints at the
    pose (pnp._pixel_errors, issue 21: less Python per image); it must give
    reprojection_residuals' figures, inf for a point behind the camera included."""
    from multieye.imaging import pnp
    from multieye.imaging.pnp import reprojection_residuals

    board = Chessboard(rows=5, cols=7, spacing=0.05)
    obj = board.object_points()
    for camera in (PINHOLE, FISHEYE):
        T = facing_pose(board, rng.normal(0, 0.3, 3), 0.6)
        pts = true_pixels(board, camera, T, np.arange(35)) + rng.normal(0, 0.3, (35, 2))
        rvec, tvec = cv2.Rodrigues(T[:3, :3])[0].ravel(), T[:3, 3].copy()
        fast = pnp._pixel_errors(obj, pts, camera, rvec, tvec)
        assert np.allclose(fast, reprojection_residuals(T, obj, pts, camera), rtol=1e-9, atol=1e-9)
        pose = estimate_pose(Detection(np.arange(35), pts, obj), camera)
        slow = reprojection_residuals(pose.T_cam_target, obj, pts, camera)
        assert abs(pose.rms_px - np.sqrt(np.mean(slow ** 2))) < 1e-9
        assert abs(pose.max_px - slow.max()) < 1e-9
        behind = T.copy()
        behind[2, 3] = -0.05                 # the board through the camera's plane
        slow = reprojection_residuals(behind, obj, pts, camera)
        fast = pnp._pixel_errors(obj, pts, camera, rvec, behind[:3, 3])
        assert np.isinf(slow).any() and np.array_equal(np.isinf(fast), np.isinf(slow))
        assert np.allclose(fast[np.isfinite(slow)], slow[np.isfinite(slow)], atol=1e-9)
