"""Target geometry in the canonical frame, against OpenCV's and Kalibr's definitions."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multieye.core.errors import DatasetError, InputError
from multieye.imaging.targets import (
    AprilGrid,
    AsymmetricCircleGrid,
    Charuco,
    Chessboard,
    CircleGrid,
    target_from_spec,
)


def test_chessboard_points_are_row_major_inner_corners():
    board = Chessboard(rows=3, cols=4, spacing=0.05)
    P = board.object_points()
    assert P.shape == (12, 3)
    np.testing.assert_allclose(P[0], [0, 0, 0])
    np.testing.assert_allclose(P[1], [0.05, 0, 0])       # x along cols
    np.testing.assert_allclose(P[4], [0, 0.05, 0])       # next row: y
    np.testing.assert_allclose(P[-1], [0.15, 0.10, 0])
    np.testing.assert_allclose(board.bounds(), (-0.05, 0.2, -0.05, 0.15))
    assert not board.half_turn_symmetric and Chessboard(3, 5, 0.05).half_turn_symmetric


def test_symmetric_circle_grid_points():
    P = CircleGrid(rows=3, cols=4, spacing=0.02).object_points()
    np.testing.assert_allclose(P[5], [0.02, 0.02, 0])


def test_asymmetric_grid_matches_opencv_sample_and_open3dv():
    """OpenCV's sample: ((2c + r % 2) * s, r * s) with s half the in-row distance; Open3DV:
    x = (c + 0.5 (r % 2)) d, y = r d / 2 for a 7 x 11 grid (PROVENANCE.md)."""
    d = 0.02
    board = AsymmetricCircleGrid(rows=11, cols=7, spacing=d)
    P = board.object_points()
    r, c = np.divmod(np.arange(77), 7)
    np.testing.assert_allclose(P[:, 0], (2 * c + r % 2) * d / 2)
    np.testing.assert_allclose(P[:, 1], r * d / 2)
    # neighbours in a row are d apart, neighbours across rows d / sqrt(2)
    assert np.isclose(np.linalg.norm(P[1] - P[0]), d)
    assert np.isclose(np.linalg.norm(P[7] - P[0]), d / np.sqrt(2))


def test_charuco_points_are_opencv_corners_shifted_to_corner_zero():
    board = Charuco(rows=5, cols=7, spacing=0.04, marker_size=0.03, dictionary="DICT_5X5_100")
    P = board.object_points()
    cv_corners = np.asarray(board.opencv_board().getChessboardCorners())
    np.testing.assert_allclose(P, cv_corners - [0.04, 0.04, 0.0], atol=1e-8)   # OpenCV: float32
    assert board.grid_shape() == (4, 6)


def test_aprilgrid_follows_kalibr_point_ordering():
    """Kalibr: 2R x 2C grid; point (r, c) at ((c // 2) (1 + s) t + (c % 2) t, same for r);
    tag k has corners b, b + 1, b + 2C + 1, b + 2C with b = (k // C) 4C + (k % C) 2."""
    t, s = 0.088, 0.3
    board = AprilGrid(rows=2, cols=3, spacing=t, tag_spacing=s)
    P = board.object_points()
    assert P.shape == (24, 3)
    np.testing.assert_allclose(P[0], [0, 0, 0])
    np.testing.assert_allclose(P[1], [t, 0, 0])
    np.testing.assert_allclose(P[2], [(1 + s) * t, 0, 0])
    np.testing.assert_allclose(P[6], [0, t, 0])            # 2C = 6 points per row
    np.testing.assert_allclose(P[12], [0, (1 + s) * t, 0])
    assert board.tag_corner_ids(0) == (0, 1, 7, 6)
    assert board.tag_corner_ids(4) == (14, 15, 21, 20)     # tag 4: row 1, column 1
    np.testing.assert_allclose(board.tag_corners(4), P[list(board.tag_corner_ids(4)), :2])
    assert not AprilGrid.z_into_board


def kalibr_drawing(code: int) -> np.ndarray:
    """The 6x6 code as kalibr_create_target_pdf draws it (row 0 at the top, 1 = black):
    bit (6 i + j) clear means black at (i, j), then a half turn."""
    bits = np.array([[0 if code & (1 << (6 * i + j)) else 1 for j in range(6)] for i in range(6)])
    return np.rot90(bits, 2)


@pytest.mark.parametrize("tag, code", [(0, 0xD5D628584), (1, 0xD97F18B49), (7, 0x10652E1D4)])
def test_aprilgrid_tags_are_drawn_as_kalibr_prints_them(tag, code):
    """Codes of AprilTag 36h11 ids 0, 1 and 7 as listed in Kalibr's target generator."""
    images = AprilGrid(rows=2, cols=4, spacing=0.05, tag_spacing=0.3).tag_images()
    black = (images[tag] < 0.5).astype(int)
    assert black[:2].all() and black[-2:].all() and black[:, :2].all() and black[:, -2:].all()
    np.testing.assert_array_equal(black[2:8, 2:8], kalibr_drawing(code))


def test_spec_builds_each_type():
    specs = [
        {"type": "chessboard", "rows": 7, "cols": 8, "spacing": 0.033},
        {"type": "circles", "rows": 4, "cols": 5, "spacing": 0.02, "diameter": 0.01},
        {"type": "asymmetric-circles", "rows": 11, "cols": 4, "spacing": 0.04},
        {"type": "charuco", "rows": 5, "cols": 7, "spacing": 0.04, "marker_size": 0.03,
         "dictionary": "DICT_5X5_100"},
        {"type": "aprilgrid", "rows": 6, "cols": 6, "spacing": 0.088, "tag_spacing": 0.3},
    ]
    kinds = [target_from_spec(s).kind for s in specs]
    assert kinds == ["chessboard", "circles", "asymmetric-circles", "charuco", "aprilgrid"]
    assert target_from_spec(specs[0]) == Chessboard(7, 8, 0.033)


@pytest.mark.parametrize("spec, message", [
    ({"type": "checkerboard", "rows": 7, "cols": 8, "spacing": 0.03}, r"unknown type 'checkerboard'"),
    ({"type": "chessboard", "rows": 7, "cols": 8}, r"needs key 'spacing'"),
    ({"type": "chessboard", "rows": 7, "cols": 8, "spacing": 0.03, "colour": "red"},
     r"unknown key 'colour' for type chessboard"),
    ({"type": "chessboard", "rows": "seven", "cols": 8, "spacing": 0.03}, r"rows must be an integer, got 'seven'"),
    ({"type": "chessboard", "rows": True, "cols": 8, "spacing": 0.03}, r"rows must be an integer"),
    ({"type": "chessboard", "rows": 2, "cols": 8, "spacing": 0.03}, r"rows must be at least 3"),
    ({"type": "chessboard", "rows": 7, "cols": 8, "spacing": -0.03}, r"spacing must be a positive"),
    ({"type": "chessboard", "rows": 7, "cols": 8, "spacing": "3cm"}, r"spacing must be a number"),
    ({"type": "charuco", "rows": 5, "cols": 7, "spacing": 0.04, "marker_size": 0.05,
      "dictionary": "DICT_5X5_100"}, r"marker_size 0.05 must be smaller than the square size"),
    ({"type": "charuco", "rows": 5, "cols": 7, "spacing": 0.04, "marker_size": 0.03,
      "dictionary": "DICT_5x5_100"}, r"unknown ArUco dictionary 'DICT_5x5_100'"),
    ({"type": "charuco", "rows": 20, "cols": 20, "spacing": 0.04, "marker_size": 0.03,
      "dictionary": "DICT_4X4_50"}, r"needs 200 markers but DICT_4X4_50 has only 50"),
    ({"type": "aprilgrid", "rows": 6, "cols": 6, "spacing": 0.088, "tag_spacing": 30},
     r"tag_spacing is the gap as a fraction"),
    ({"type": "asymmetric-circles", "rows": 11, "cols": 4, "spacing": 0.04, "diameter": 0.03},
     r"diameter 0.03 must be smaller than the distance between neighbouring centres"),
    (["chessboard", 7, 8], r"expected a mapping"),
])
def test_bad_specs_name_the_problem(spec, message):
    with pytest.raises(DatasetError, match=message) as info:
        target_from_spec(spec, path="rig.yaml", line=3)
    assert str(info.value).startswith("rig.yaml:3: target: ")


def test_dataclass_checks_raise_input_errors():
    with pytest.raises(InputError, match="charuco marker_size"):
        Charuco(rows=5, cols=7, spacing=0.04)
    with pytest.raises(InputError, match="aprilgrid tag_spacing"):
        AprilGrid(rows=2, cols=2, spacing=0.04)


def test_dictionary_sizes_come_from_opencv():
    board = Charuco(rows=10, cols=10, spacing=0.02, marker_size=0.015, dictionary="DICT_4X4_50")
    assert cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50).bytesList.shape[0] == 50
    assert board.n_points == 81


VALUES = st.one_of(st.none(), st.booleans(), st.integers(-5, 40), st.floats(allow_nan=True, allow_infinity=True),
                   st.text(max_size=12), st.sampled_from(["DICT_5X5_100", "DICT_4X4_50", "DICT_APRILTAG_36h11"]))
KEYS = st.sampled_from(["rows", "cols", "spacing", "marker_size", "dictionary", "tag_spacing", "diameter",
                        "legacy", "size", "Rows"])


@settings(max_examples=100, deadline=None)
@given(kind=st.sampled_from(["chessboard", "circles", "asymmetric-circles", "charuco", "aprilgrid", "grid", None, 3]),
       entries=st.dictionaries(KEYS, VALUES, max_size=7))
def test_any_mapping_gives_a_target_or_a_dataset_error(kind, entries):
    spec = {"type": kind, **entries}
    try:
        target = target_from_spec(spec, path="rig.yaml")
    except DatasetError as exc:
        assert str(exc).startswith("rig.yaml: target: ")
        return
    assert target.kind == kind
    P = target.object_points()
    assert P.shape == (target.n_points, 3) and np.all(np.isfinite(P)) and target.spacing > 0
