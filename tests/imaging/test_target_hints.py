"""What the images hold when rig.yaml's target is not found (issue 24, item 3): each mistake
users make, rendered, gives back the complete target mapping that finds the board, in the
terms of its target type."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from board_poses import PINHOLE, facing_pose

from multieye.imaging.detect import detect
from multieye.imaging.target_hints import counting_rule, markers_in, suggest_target
from multieye.imaging.targets import ArucoGrid, target_from_spec
from multieye.sim.render import render


CHARUCO = {"type": "charuco", "rows": 7, "cols": 9, "spacing": 0.04, "marker_size": 0.02,
           "dictionary": "DICT_4X4_50"}


def _images(spec, n=1):
    t = target_from_spec(spec)
    tilts = ([0.35, -0.3, 0.1], [-0.2, 0.3, 0.4])
    return [render(t, PINHOLE, facing_pose(t, tilts[k], 0.5), rng=np.random.default_rng(k))
            for k in range(n)]


@pytest.mark.parametrize("true, wrong, why", [
    (CHARUCO, {"dictionary": "DICT_5X5_100"}, "dictionary DICT_4X4_50 (the images hold ids 0-30)"),
    ({**CHARUCO, "dictionary": "DICT_5X5_100"}, {"rows": 9, "cols": 7}, "rows and cols swapped"),
    ({**CHARUCO, "rows": 6}, {"rows": 5, "cols": 8}, "rows 6 and cols 9 (rows and cols count the squares"),
    (CHARUCO, {"dictionary": "DICT_6X6_250", "marker_size": 0.03},
     "marker_size 0.02 (the markers measure about 0.50 of a square, rig.yaml says 0.75)"),
    ({"type": "chessboard", "rows": 6, "cols": 9, "spacing": 0.04}, {"rows": 7, "cols": 10},
     "6 x 9 inner corners (squares counted instead of inner corners)"),
    ({"type": "chessboard", "rows": 6, "cols": 9, "spacing": 0.04}, {"rows": 5},
     "rows and cols count the inner corners"),
    ({"type": "asymmetric-circles", "rows": 11, "cols": 7, "spacing": 0.04},
     {"rows": 7, "cols": 11}, "rows and cols swapped (cols counts the circles of one row"),
    ({"type": "circles", "rows": 6, "cols": 8, "spacing": 0.04}, {"rows": 7},
     "rows 6 and cols 8 (rows and cols count the circles"),
    ({"type": "circles", "rows": 6, "cols": 8, "spacing": 0.04},
     {"type": "asymmetric-circles"}, "type circles"),
])
def test_each_mistake_gives_the_mapping_that_finds_the_board(true, wrong, why):
    images = _images(true, n=2 if true["type"] == "charuco" and "rows" in wrong else 1)
    spec = {**true, **wrong}
    t_wrong = target_from_spec(spec)
    assert all(detect(im, t_wrong) is None for im in images)        # the mistake is real
    hint = suggest_target(images, spec)
    assert hint is not None and hint.found == hint.tried == len(images)
    assert hint.spec == {**spec, **true}, hint.text
    assert why in hint.why, hint.why
    assert hint.text.endswith("write in rig.yaml " + hint.yaml)
    assert hint.yaml.startswith(f"target: {{type: {true['type']}, ")
    # the mapping is what rig.yaml takes: it finds the board
    target = target_from_spec(hint.spec)
    assert all(detect(im, target) is not None for im in images)
    # the hint speaks of the type's own counting
    if true["type"] != "chessboard":
        assert "inner corners" not in hint.text.replace("(not the inner corners)", "")


def test_texts_fit_the_target_type():
    assert "inner corners" in counting_rule("chessboard")
    for kind in ("circles", "asymmetric-circles", "aprilgrid", "aruco", "aruco-grid"):
        assert "inner corner" not in counting_rule(kind)
    assert "squares (not the inner corners)" in counting_rule("charuco")


def test_single_marker_of_another_dictionary_and_id():
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_25h9)
    canvas = np.full((400, 400), 255, np.uint8)
    canvas[100:300, 100:300] = cv2.aruco.generateImageMarker(dictionary, 12, 200)
    spec = {"type": "aruco", "marker_size": 0.05, "dictionary": "DICT_6X6_250", "id": 3}
    hint = suggest_target([canvas], spec)
    assert hint.spec == {**spec, "dictionary": "DICT_APRILTAG_25h9", "id": 12}, hint.text
    assert "AprilTag" not in hint.why or "25h9" in hint.why


def test_marker_grid_with_another_first_id_and_dictionary():
    board = ArucoGrid(rows=3, cols=4, spacing=0.04, marker_separation=0.01,
                      dictionary="DICT_5X5_100", first_id=20)
    image = board.opencv_board().generateImage((860, 660), marginSize=50)
    spec = {"type": "aruco-grid", "rows": 3, "cols": 4, "marker_size": 0.04,
            "marker_separation": 0.01, "dictionary": "DICT_4X4_50"}
    hint = suggest_target([image], spec)
    assert hint.spec == {**spec, "dictionary": "DICT_5X5_50", "first_id": 20}, hint.text


def test_markers_on_a_board_said_for_a_chessboard():
    images = _images(CHARUCO, n=1)
    sightings = markers_in(images)
    assert sightings[0].dictionary == "DICT_4X4_50" and sightings[0].ids == tuple(range(31))
    hint = suggest_target(images, {"type": "chessboard", "rows": 6, "cols": 8, "spacing": 0.04})
    # OpenCV's chessboard detector may or may not find the ChArUco board's squares (as 8 x 6);
    # either way the markers are named, with the type and the counting they call for
    note = ("hold ArUco markers of DICT_4X4_50 (ids 0-30), not the chessboard of rig.yaml: a "
            "ChArUco board? type: charuco, with dictionary: DICT_4X4_50 (rows and cols count "
            "the squares (not the inner corners)")
    assert note in hint.text, hint.text
    assert hint.spec is None or hint.spec["type"] == "chessboard"


def test_an_aprilgrid_is_named_for_another_target():
    grid = {"type": "aprilgrid", "rows": 5, "cols": 6, "spacing": 0.04, "tag_spacing": 0.3}
    hint = suggest_target(_images(grid, n=1), CHARUCO)
    assert hint.spec is None and "as on Kalibr's AprilGrid" in hint.text
    assert "type: aprilgrid" in hint.text


def test_nothing_recognised_is_none():
    blank = np.full((480, 640), 128, np.uint8)
    assert suggest_target([blank], CHARUCO) is None
    assert suggest_target([Path("/nonexistent.png")], CHARUCO) is None
