"""Several boards in one image (multieye.imaging.boards): each found under its own name by
its marker ids, with the pixels of its true pose."""

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.imaging.batch import process_array
from multieye.imaging.boards import Boards
from multieye.imaging.detect import detect
from multieye.imaging.targets import target_from_spec
from multieye.sim.render import render_boards

SPEC = {"type": "charuco", "rows": 5, "cols": 7, "spacing": 0.05, "marker_size": 0.0375,
        "dictionary": "DICT_4X4_100"}
CAM = Intrinsics(K=[[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], dist=np.zeros(5),
                 width=640, height=480)


def _scene():
    """Board 'left' (ids 0-16) left of the centre, 'right' (ids 20-36) to the right, turned a
    little, both 1.2 m away; 'far' (ids 40-56) out of view."""
    boards = {"left": target_from_spec(SPEC), "right": target_from_spec({**SPEC, "first_id": 20}),
              "far": target_from_spec({**SPEC, "first_id": 40})}
    poses = {"left": g.transform_from_rotvec([0.1, 0.25, 0.0], [-0.42, -0.08, 1.2]),
             "right": g.transform_from_rotvec([-0.05, -0.3, 0.05], [0.1, -0.1, 1.25]),
             "far": g.transform_from_rotvec([0, 0, 0], [5.0, 0.0, 1.0])}
    image = render_boards([(boards[n], poses[n]) for n in ("left", "right")], CAM,
                          rng=np.random.default_rng(1), blur_sigma=0.7, noise_sigma=2.0)
    return boards, poses, image


def _pixel_error(detection, pose):
    P = detection.object_points @ pose[:3, :3].T + pose[:3, 3]
    return np.abs(project_points(P, CAM) - detection.image_points).max()


def test_two_boards_in_one_image_each_under_its_name():
    boards, poses, image = _scene()
    result = process_array(image, "two.png", Boards.of(boards), CAM)
    assert result.ok and result.detection is None
    parts = dict(result.parts)
    assert list(parts) == ["left", "right", "far"]
    for name in ("left", "right"):
        part = parts[name]
        assert part.ok, part.reason
        assert len(part.detection) >= 16                    # of 24 inner corners
        assert _pixel_error(part.detection, poses[name]) < 1.0    # the other board: 100s of px
        # the pose PnP finds is the board's own, not the other's
        assert np.linalg.norm(part.pose.T_cam_target[:3, 3] - poses[name][:3, 3]) < 0.01
    assert parts["far"].reason.startswith("target not detected")


def test_a_board_is_not_found_where_only_other_ids_are():
    """The board of ids 40-56 is nowhere in the image: its detector ignores the markers of the
    two boards that are (the ids keep boards apart)."""
    boards, _, image = _scene()
    assert detect(image, boards["far"]) is None
    swapped = Boards((("right", boards["left"]), ("left", boards["right"])))
    parts = dict(process_array(image, "two.png", swapped, CAM).parts)
    _, poses, _ = _scene()
    assert _pixel_error(parts["right"].detection, poses["left"]) < 1.0


def test_no_board_found_names_every_board():
    boards, poses, _ = _scene()
    blank = render_boards([], CAM, rng=np.random.default_rng(2))
    result = process_array(blank, "blank.png", Boards.of(boards), CAM)
    assert not result.ok
    assert result.reason == ("target not detected (charuco 5x7 left, charuco 5x7 right, "
                             "charuco 5x7 far)")


def test_boards_need_distinct_names():
    board = target_from_spec(SPEC)
    with pytest.raises(InputError):
        Boards((("a", board), ("a", board)))
    with pytest.raises(InputError):
        Boards(())


def test_two_aprilgrids_told_apart_by_first_id():
    spec = {"type": "aprilgrid", "rows": 3, "cols": 4, "spacing": 0.05, "tag_spacing": 0.3}
    boards = {"a": target_from_spec(spec), "b": target_from_spec({**spec, "first_id": 12})}
    poses = {"a": g.transform_from_rotvec([np.pi, 0.2, 0.0], [-0.35, 0.1, 1.0]),
             "b": g.transform_from_rotvec([np.pi, -0.2, 0.0], [0.08, 0.1, 1.0])}
    image = render_boards([(boards[n], poses[n]) for n in boards], CAM,
                          rng=np.random.default_rng(3), blur_sigma=0.7, noise_sigma=2.0)
    parts = dict(process_array(image, "april.png", Boards.of(boards), CAM).parts)
    for name in boards:
        assert parts[name].ok, parts[name].reason
        assert len(parts[name].detection) == 48                     # every tag corner
        assert _pixel_error(parts[name].detection, poses[name]) < 1.0
    # a grid of ids 24-35 is not in the image
    assert detect(image, target_from_spec({**spec, "first_id": 24})) is None
