"""ArUco targets (issue 14, item 2): a single marker and OpenCV's GridBoard, their geometry
against OpenCV's and their detection on synthetic images warped by a homography."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.detect import detect
from multieye.imaging.pnp import estimate_pose
from multieye.imaging.targets import ArucoGrid, ArucoMarker, target_from_spec

H = np.array([[0.8, 0.1, 60.0], [0.05, 0.9, 40.0], [2e-4, 1e-4, 1.0]])


def _warp(points: np.ndarray) -> np.ndarray:
    p = np.column_stack([points, np.ones(len(points))]) @ H.T
    return p[:, :2] / p[:, 2:]


def test_single_marker_points_are_its_corners_in_opencv_order():
    t = target_from_spec({"type": "aruco", "marker_size": 0.053, "dictionary": "DICT_6X6_250",
                          "id": 7})
    assert isinstance(t, ArucoMarker) and (t.rows, t.cols, t.id) == (1, 1, 7)
    np.testing.assert_allclose(t.object_points(), [[0, 0, 0], [0.053, 0, 0], [0.053, 0.053, 0],
                                                   [0, 0.053, 0]])
    assert t.marker_size == 0.053 and t.grid_shape() is None


def test_grid_points_match_opencv_gridboard():
    t = target_from_spec({"type": "aruco-grid", "rows": 3, "cols": 4, "marker_size": 0.04,
                          "marker_separation": 0.01, "dictionary": "DICT_4X4_50", "first_id": 5})
    assert isinstance(t, ArucoGrid) and t.first_id == 5
    board = t.opencv_board()
    np.testing.assert_allclose(t.object_points(), np.asarray(board.getObjPoints()).reshape(-1, 3),
                               atol=1e-7)
    assert board.getIds().ravel().tolist() == list(range(5, 17))
    np.testing.assert_allclose(t.bounds(), (0, 0.19, 0, 0.14))
    assert target_from_spec({"type": "aruco-grid", "rows": 1, "cols": 2, "marker_size": 0.04,
                             "marker_separation": 0.01, "dictionary": "DICT_4X4_50"}).first_id == 0


@pytest.mark.parametrize("spec, message", [
    ({"type": "aruco", "marker_size": 0.05, "dictionary": "DICT_4X4_50", "id": 50},
     "needs ids up to 50 but DICT_4X4_50 has ids 0 to 49"),
    ({"type": "aruco", "marker_size": 0.05, "dictionary": "DICT_NOPE", "id": 0},
     "unknown ArUco dictionary"),
    ({"type": "aruco", "marker_size": 0.05, "dictionary": "DICT_4X4_50"}, "needs key 'id'"),
    ({"type": "aruco", "marker_size": 0.05, "dictionary": "DICT_4X4_50", "id": 0, "rows": 2},
     "unknown key 'rows'"),
    ({"type": "aruco-grid", "rows": 8, "cols": 8, "marker_size": 0.04,
      "marker_separation": 0.01, "dictionary": "DICT_4X4_50"}, "needs ids up to 63"),
    ({"type": "aruco-grid", "rows": 2, "cols": 2, "marker_size": 0.04,
      "marker_separation": 0, "dictionary": "DICT_4X4_50"}, "marker_separation"),
    ({"type": "aruco-grid", "rows": 2, "cols": 2, "marker_size": 0.04,
      "marker_separation": 0.01, "dictionary": "DICT_4X4_50", "first_id": -1}, "first_id"),
])
def test_bad_aruco_specs(spec, message):
    with pytest.raises(DatasetError, match=message.replace("(", r"\(")):
        target_from_spec(spec)


def test_single_marker_detected_with_subpixel_corners():
    t = ArucoMarker(rows=1, cols=1, spacing=0.053, dictionary="DICT_6X6_250", id=3)
    side, margin = 240, 80
    marker = cv2.aruco.generateImageMarker(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250), 3, side)
    canvas = np.full((side + 2 * margin, side + 2 * margin), 255, np.uint8)
    canvas[margin:margin + side, margin:margin + side] = marker
    # a stray marker of another id does not count
    other = cv2.aruco.generateImageMarker(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250), 4, 60)
    canvas[5:65, 5:65] = other
    image = cv2.warpPerspective(canvas, H, (640, 560), flags=cv2.INTER_CUBIC, borderValue=255)
    d = detect(image, t)
    assert d is not None and d.ids.tolist() == [0, 1, 2, 3] and not d.warnings
    truth = _warp(margin - 0.5 + t.object_points()[:, :2] * side / t.spacing)
    assert np.abs(d.image_points - truth).max() < 0.3
    np.testing.assert_allclose(d.object_points, t.object_points())
    K = np.array([[500.0, 0, 320], [0, 500, 280], [0, 0, 1]])
    assert estimate_pose(d, Intrinsics(K=K, dist=np.zeros(5))) is not None
    # the wrong id: nothing found; the marker twice: dropped with a warning
    assert detect(image, ArucoMarker(1, 1, 0.053, "DICT_6X6_250", 5)) is None
    twice = np.hstack([canvas, canvas])
    assert detect(twice, t) is None
    twice[5:65, canvas.shape[1] + 5:canvas.shape[1] + 65] = 255     # id 4 once, id 3 twice
    d3 = detect(twice, ArucoGrid(1, 2, 0.053, 0.02, "DICT_6X6_250", first_id=3))
    assert d3 is not None and d3.ids.tolist() == [4, 5, 6, 7]
    assert d3.warnings and "ArUco ids [3] seen more than once" in d3.warnings[0]


def test_grid_detected_whole_and_in_part():
    t = ArucoGrid(rows=3, cols=4, spacing=0.04, marker_separation=0.01,
                  dictionary="DICT_6X6_250", first_id=3)
    scale, margin = 4000.0, 50
    img = t.opencv_board().generateImage((int(0.19 * scale) + 2 * margin,
                                          int(0.14 * scale) + 2 * margin), marginSize=margin)
    image = cv2.warpPerspective(img, H, (1000, 800), flags=cv2.INTER_CUBIC, borderValue=255)
    d = detect(image, t)
    assert d is not None and d.ids.tolist() == list(range(48))
    truth = _warp(margin - 0.5 + t.object_points()[:, :2] * scale)
    # outer corners of black squares (not X-junctions): a few tenths of a pixel at most
    assert np.abs(d.image_points - truth).max() < 0.5
    assert np.sqrt(np.mean((d.image_points - truth) ** 2)) < 0.2
    # the right half covered: the markers still seen give their corners
    part = img.copy()
    part[:, img.shape[1] // 2:] = 255
    d = detect(cv2.warpPerspective(part, H, (1000, 800), borderValue=255), t)
    assert d is not None and 0 < len(d) < 48 and set((d.ids // 4) % 4) == {0, 1}
    # another board's ids (first_id 20) are not this board's
    other = ArucoGrid(3, 4, 0.04, 0.01, "DICT_6X6_250", first_id=20)
    assert detect(image, other) is None


def test_grid_views_give_the_intrinsics():
    """Detections of an aruco-grid in views of a pinhole camera calibrate that camera."""
    from scipy.spatial.transform import Rotation

    from multieye.imaging.calibrate import initial_intrinsics

    t = ArucoGrid(rows=4, cols=5, spacing=0.04, marker_separation=0.01,
                  dictionary="DICT_5X5_100")
    scale, margin = 4000.0, 40
    w_m, h_m = t.bounds()[1], t.bounds()[3]
    board = t.opencv_board().generateImage((int(round(w_m * scale)) + 2 * margin,
                                            int(round(h_m * scale)) + 2 * margin),
                                           marginSize=margin)
    # board pixel -> board metres
    S = np.array([[1 / scale, 0, -(margin - 0.5) / scale], [0, 1 / scale, -(margin - 0.5) / scale],
                  [0, 0, 1]])
    K = np.array([[700.0, 0, 400], [0, 700, 300], [0, 0, 1]])
    rng = np.random.default_rng(3)
    views = []
    for _ in range(8):
        R = Rotation.from_rotvec(rng.uniform(-0.5, 0.5, 3)).as_matrix()
        centre = np.array([w_m / 2, h_m / 2, 0])
        tvec = np.array([0, 0, rng.uniform(0.45, 0.6)]) - R @ centre
        Hm = K @ np.column_stack([R[:, 0], R[:, 1], tvec])
        image = cv2.warpPerspective(board, Hm @ S, (800, 600), flags=cv2.INTER_CUBIC,
                                    borderValue=255)
        d = detect(image, t)
        if d is not None and len(d) >= 40:
            views.append((d.object_points, d.image_points))
    assert len(views) >= 6
    found = initial_intrinsics(views, (800, 600), "pinhole-radtan")
    K_found = np.asarray(found.intrinsics.K)
    assert abs(K_found[0, 0] - 700) < 10 and abs(K_found[0, 2] - 400) < 10
