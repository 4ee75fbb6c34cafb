"""multieye's board frame against OpenCV's (issue 24, item 3): per target type, a board found
by OpenCV's own detector and posed by ``cv2.solvePnP`` on OpenCV's own object points gives
multieye's pose once ``T_opencv_target`` (docs/conventions.md, section 5) is applied:
``T_cam_target (multieye) == T_cam_opencv @ T_opencv_target``."""

from __future__ import annotations


import cv2
import numpy as np
import pytest
from board_poses import PINHOLE, facing_pose

from multieye.core.errors import InputError
from multieye.core.geometry import (
    rotation_angle_between, transform_from_rotvec, translation_distance)
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.board_frames import T_opencv_target
from multieye.imaging.detect import detect
from multieye.imaging.pnp import estimate_pose
from multieye.imaging.targets import (
    AprilGrid, ArucoGrid, ArucoMarker, AsymmetricCircleGrid, Charuco, Chessboard, CircleGrid)
from multieye.sim.render import render


CAMERA = Intrinsics(K=PINHOLE.K, dist=np.zeros(5), width=800, height=600)


def _pose_opencv(object_points, image_points, camera) -> np.ndarray:
    ok, rvec, tvec = cv2.solvePnP(np.asarray(object_points, np.float64).reshape(-1, 3),
                                  np.asarray(image_points, np.float64).reshape(-1, 2),
                                  camera.K, camera.dist, flags=cv2.SOLVEPNP_ITERATIVE)
    assert ok
    return transform_from_rotvec(rvec.ravel(), tvec.ravel())


def _agree(target, image, T_cam_opencv, camera, **kw):
    T_multieye = estimate_pose(detect(image, target), camera).T_cam_target
    T = T_cam_opencv @ T_opencv_target(target, **kw)
    assert np.degrees(rotation_angle_between(T_multieye, T)) < 0.05
    assert translation_distance(T_multieye, T) < 2e-4
    return T_multieye


@pytest.mark.parametrize("roll", [0.0, 100.0, 200.0])
def test_chessboard_both_opencv_detectors(roll):
    t = Chessboard(rows=6, cols=9, spacing=0.04)
    T = transform_from_rotvec([0, 0, np.radians(roll)], np.zeros(3)) @ facing_pose(
        t, [0.3, -0.25, 0.0], 0.5)
    image = render(t, CAMERA, T)
    # OpenCV's tutorial: object points (j*s, i*s, 0) in the detector's order
    objp = np.zeros((t.rows * t.cols, 3))
    objp[:, :2] = np.mgrid[0:t.cols, 0:t.rows].T.reshape(-1, 2) * t.spacing
    ok, sb = cv2.findChessboardCornersSB(image, (t.cols, t.rows), flags=0)
    assert ok
    mine = _agree(t, image, _pose_opencv(objp, sb, CAMERA), CAMERA, chessboard_detector="sb")
    ok, classic = cv2.findChessboardCorners(image, (t.cols, t.rows))
    assert ok
    classic = cv2.cornerSubPix(image, classic, (5, 5), (-1, -1),
                               (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3))
    T_classic = _pose_opencv(objp, classic, CAMERA)
    _agree(t, image, T_classic, CAMERA, chessboard_detector="classic")
    # the SB detector's frame is the half turn the issue met (180 deg, origin far away)
    T_sb = _pose_opencv(objp, sb, CAMERA)
    assert abs(np.degrees(rotation_angle_between(T_sb, mine)) - 180) < 0.1


def test_charuco_board_object_is_one_square_in():
    t = Charuco(rows=7, cols=9, spacing=0.04, marker_size=0.028, dictionary="DICT_5X5_100")
    image = render(t, CAMERA, facing_pose(t, [0.35, -0.3, 0.1], 0.5))
    board = t.opencv_board()
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(image)
    obj = board.getChessboardCorners()[ids.ravel()]
    _agree(t, image, _pose_opencv(obj, corners, CAMERA), CAMERA)
    # matchImagePoints, OpenCV's own pairing, gives the same object points
    obj2, img2 = board.matchImagePoints(corners, ids)
    np.testing.assert_allclose(obj2.reshape(-1, 3), obj)


def test_asymmetric_circles_as_opencv_sample_writes_them():
    t = AsymmetricCircleGrid(rows=11, cols=7, spacing=0.04, diameter=0.02)
    image = render(t, CAMERA, facing_pose(t, [0.3, 0.2, 0.0], 0.5))
    ok, centres = cv2.findCirclesGrid(image, (t.cols, t.rows), flags=cv2.CALIB_CB_ASYMMETRIC_GRID)
    assert ok
    s = t.spacing / 2
    objp = np.array([[(2 * j + i % 2) * s, i * s, 0] for i in range(t.rows) for j in range(t.cols)])
    T_cv = _pose_opencv(objp, centres, CAMERA)
    T_multieye = estimate_pose(detect(image, t), CAMERA).T_cam_target
    T = T_cv @ T_opencv_target(t)
    # blob centroids without the diameter correction: a little looser
    assert np.degrees(rotation_angle_between(T_multieye, T)) < 0.1
    assert translation_distance(T_multieye, T) < 1e-3


K_ARUCO = Intrinsics(K=[[500.0, 0, 320], [0, 500, 280], [0, 0, 1]], dist=np.zeros(5))


def _view(printed: np.ndarray, metres_per_px: float, margin: int, rotvec, distance) -> np.ndarray:
    """A pinhole view (K_ARUCO, no distortion) of a printed board image whose pixel
    ``(margin, margin)`` (its centre ``- 0.5``) is the board's origin, tilted by ``rotvec``."""
    h, w = printed.shape
    centre = np.array([w / 2 - margin, h / 2 - margin]) * metres_per_px
    T = transform_from_rotvec(rotvec, [0, 0, 0])
    T[:3, 3] = -T[:3, :2] @ centre + [0, 0, distance]
    A = np.array([[metres_per_px, 0, (0.5 - margin) * metres_per_px],
                  [0, metres_per_px, (0.5 - margin) * metres_per_px], [0, 0, 1]])
    H = K_ARUCO.K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ A
    return cv2.warpPerspective(printed, H, (640, 560), flags=cv2.INTER_LINEAR,
                               borderValue=255)


def test_aruco_grid_board_object_is_the_same_frame():
    t = ArucoGrid(rows=3, cols=4, spacing=0.04, marker_separation=0.01,
                  dictionary="DICT_6X6_250", first_id=3)
    board = t.opencv_board()
    img = board.generateImage((860, 660), marginSize=50)           # 4000 px per metre
    image = _view(img, 1 / 4000, 50, [0.4, -0.3, 0.1], 0.45)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    corners, ids, _ = cv2.aruco.ArucoDetector(board.getDictionary(), params).detectMarkers(image)
    obj, pts = board.matchImagePoints(corners, ids)
    _agree(t, image, _pose_opencv(obj, pts, K_ARUCO), K_ARUCO)
    np.testing.assert_array_equal(T_opencv_target(t), np.eye(4))


def test_single_marker_opencv_points_centre_and_y_up():
    t = ArucoMarker(rows=1, cols=1, spacing=0.053, dictionary="DICT_6X6_250", id=3)
    side, margin = 120, 40
    canvas = np.full((side + 2 * margin,) * 2, 255, np.uint8)
    canvas[margin:margin + side, margin:margin + side] = cv2.aruco.generateImageMarker(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250), 3, side)
    image = _view(canvas, t.spacing / side, margin, [0.5, -0.4, 0.2], 0.25)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    corners, ids, _ = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250), params).detectMarkers(image)
    L = t.spacing
    # the object points of OpenCV's marker tutorial (SOLVEPNP_IPPE_SQUARE)
    objp = np.array([[-L / 2, L / 2, 0], [L / 2, L / 2, 0], [L / 2, -L / 2, 0], [-L / 2, -L / 2, 0]])
    assert ids.ravel().tolist() == [3]
    # a lone square seen with little perspective has two poses that fit (IPPE): OpenCV
    # returns both; the one multieye's own IPPE chose must be one of them, in OpenCV's frame
    n, rvecs, tvecs, _ = cv2.solvePnPGeneric(objp, corners[0].reshape(-1, 2), K_ARUCO.K,
                                             K_ARUCO.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    T_multieye = estimate_pose(detect(image, t), K_ARUCO).T_cam_target
    T_given = T_opencv_target(t)
    errors = [np.degrees(rotation_angle_between(
        T_multieye, transform_from_rotvec(r.ravel(), v.ravel()) @ T_given)) for r, v in
        zip(rvecs, tvecs)]
    k = int(np.argmin(errors))
    T = transform_from_rotvec(rvecs[k].ravel(), tvecs[k].ravel()) @ T_given
    assert errors[k] < 0.05 and translation_distance(T_multieye, T) < 2e-4
    # and point by point: multieye's corner j is OpenCV's corner j
    P = t.object_points()
    np.testing.assert_allclose((P @ T_given[:3, :3].T) + T_given[:3, 3], objp, atol=1e-12)


@pytest.mark.parametrize("target", [
    Chessboard(rows=6, cols=8, spacing=0.04),
    CircleGrid(rows=6, cols=8, spacing=0.04),
    AsymmetricCircleGrid(rows=6, cols=7, spacing=0.04),
    AprilGrid(rows=5, cols=6, spacing=0.04, tag_spacing=0.3),
])
def test_no_fixed_opencv_frame_is_said(target):
    with pytest.raises(InputError, match="no fixed transform|Kalibr"):
        T_opencv_target(target)
