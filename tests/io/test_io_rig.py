"""rig.yaml loading and checking, and time-stamped image folders."""

from __future__ import annotations

import re
import textwrap

import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.io.image_folder import list_images
from multieye.io.rig import load_rig, read_camera_intrinsics

INTRINSICS = "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n"

RIG = """\
setup: eye-to-base
target:
  type: chessboard
  rows: 7
  cols: 8
  spacing: 0.033
mocap:
  file: mocap.txt
  pose: T_world_marker
  time_tolerance: 0.02
cameras:
  cam0:
    intrinsics: cam0.yaml
    images: cam0/
  cam1:
    intrinsics: {file: camchain.yaml, camera: cam1}
    poses: cam1_target.txt
    time_offset: -0.25
    mocap: cam1_mocap.txt
"""

CAMCHAIN = """\
cam0:
  camera_model: pinhole
  intrinsics: [400.0, 400.0, 320.0, 240.0]
  distortion_model: radtan
  distortion_coeffs: [0, 0, 0, 0]
cam1:
  camera_model: pinhole
  intrinsics: [600.0, 600.0, 320.0, 240.0]
  distortion_model: equidistant
  distortion_coeffs: [0.1, 0, 0, 0]
  T_cn_cnm1: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
"""


@pytest.fixture
def dataset(tmp_path):
    (tmp_path / "cam0").mkdir()
    (tmp_path / "cam0" / "1700000000.5.png").write_bytes(b"")
    (tmp_path / "cam0.yaml").write_text(INTRINSICS)
    (tmp_path / "camchain.yaml").write_text(CAMCHAIN)
    for name in ("mocap.txt", "cam1_target.txt", "cam1_mocap.txt"):
        (tmp_path / name).write_text("0 0 0 0 0 0 0 1\n")
    (tmp_path / "rig.yaml").write_text(RIG)
    return tmp_path


def _edit(dataset, old, new):
    text = (dataset / "rig.yaml").read_text()
    assert old in text
    (dataset / "rig.yaml").write_text(text.replace(old, new, 1))
    return dataset / "rig.yaml"


def test_loads_the_design_example(dataset):
    rig = load_rig(dataset)  # the folder works as well as the file
    assert rig.path == (dataset / "rig.yaml").resolve()
    assert rig.setup == "eye-to-base" and list(rig.cameras) == ["cam0", "cam1"]
    assert rig.target.as_dict() == {"type": "chessboard", "rows": 7, "cols": 8,
                                    "spacing": 0.033}
    assert rig.mocap.file == (dataset / "mocap.txt").resolve()
    assert (rig.mocap.pose, rig.mocap.time_tolerance, rig.mocap.format) == (
        "T_world_marker", 0.02, "tum")
    cam0, cam1 = rig.cameras["cam0"], rig.cameras["cam1"]
    assert cam0.source == "images" and cam0.images == (dataset / "cam0").resolve()
    assert cam0.time_offset == 0.0 and rig.mocap_for("cam0") is rig.mocap
    assert cam1.source == "poses" and cam1.time_offset == -0.25
    assert cam1.intrinsics_camera == "cam1"
    own = rig.mocap_for("cam1")  # own file, other keys inherited
    assert own.file == (dataset / "cam1_mocap.txt").resolve() and own.time_tolerance == 0.02
    assert read_camera_intrinsics(cam1).model == "fisheye"
    assert read_camera_intrinsics(cam0).K[0, 0] == 500.0
    with pytest.raises(TypeError):
        rig.cameras["cam2"] = cam0  # read-only


@pytest.mark.parametrize("old, new, line, message", [
    ("  spacing: 0.033\n", "  spacing: 0.033\n  colour: red\n", 7,
     "target.colour: unknown key; expected one of type, rows, cols, spacing"),
    ("setup: eye-to-base", "setup: eye-in-hand", 1,
     "setup: expected one of eye-to-base, eye-on-hand, got 'eye-in-hand'"),
    ("type: chessboard", "type: checkerboard", 3, "target.type: expected one of chessboard,"),
    ("rows: 7", "rows: 7.5", 4, "target.rows: expected a positive integer of at most 200, "
     "got 7.5"),
    ("rows: 7", "rows: 100000", 4, "target.rows: expected a positive integer of at most 200"),
    ("spacing: 0.033", "spacing: 1.0e+300", 6,
     "target.spacing: expected a positive number of at most 10 metres, got 1e+300"),
    ("spacing: 0.033", "spacing: .nan", 6, "target.spacing: expected a positive number of at "
     "most 10 metres, got nan"),
    ("spacing: 0.033", "spacing: -.inf", 6, "got -inf"),
    ("time_tolerance: 0.02", "time_tolerance: 3600", 10,
     "mocap.time_tolerance: expected a positive number of at most 10 seconds, got 3600"),
    ("  pose: T_world_marker\n", "  pose: T_world_marker\n  rotation_noise_deg: 90\n", 10,
     "mocap.rotation_noise_deg: expected a positive number of at most 30 degrees, got 90"),
    ("  pose: T_world_marker\n", "  pose: T_world_marker\n  translation_noise_m: .inf\n", 10,
     "mocap.translation_noise_m: expected a positive number of at most 1 metres, got inf"),
    ("    time_offset: -0.25", "    time_offset: -1.0e+20", 18,
     "cameras.cam1.time_offset: expected a number between -1e+10 and 1e+10 seconds, got -1e+20"),
    ("cam1:\n", "\"cam\\n1\":\n", 15, "cameras.'cam\\n1': camera name 'cam\\n1' holds '\\n'"),
    ("cam1:\n", "\"../../x\":\n", 15, "cameras.../../x: camera name '../../x' holds '/'"),
    ("cam1:\n", "\".hidden\":\n", 15, "camera name '.hidden' starts with '.'"),
    ("cam1:\n", "CAM0:\n", 15, "camera name 'CAM0' would be one file with camera 'cam0'"),
    ("cam1:\n", "c" * 101 + ":\n", 15, "is 101 characters long; a camera name is 1 to 100"),
    ("spacing: 0.033", "spacing: '3cm'", 6, "target.spacing: expected a positive number"),
    ("  cols: 8\n", "", 2, "target: missing key 'cols'"),
    ("time_tolerance: 0.02", "time_tolerance: -1", 10, "mocap.time_tolerance: expected a "
     "positive number"),
    ("pose: T_world_marker", "pose: T_world_body", 9,
     "mocap.pose: expected T_world_marker (or T_marker_world) for eye-to-base"),
    ("file: mocap.txt", "file: missing.txt", 8, "mocap.file: file or bag not found: "),
    ("images: cam0/", "images: nowhere/", 14, "cameras.cam0.images: folder not found"),
    ("images: cam0/", "images: mocap.txt", 14, "expected a folder, found a file"),
    ("    images: cam0/\n", "", 12, "cameras.cam0: expected exactly one of images, poses, "
     "rosbag, video, got none"),
    ("    poses: cam1_target.txt\n", "    poses: cam1_target.txt\n    images: cam0/\n", 15,
     "got images, poses"),
    ("intrinsics: cam0.yaml", "intrinsic: cam0.yaml", 13, "cameras.cam0.intrinsic: unknown key"),
    ("    time_offset: -0.25", "    time_offset: soon", 18,
     "cameras.cam1.time_offset: expected a number between -1e+10 and 1e+10 seconds, "
     "got 'soon'"),
    ("camera: cam1}", "camera: cam1, name: x}", 16, "cameras.cam1.intrinsics.name: unknown key"),
    ("mocap: cam1_mocap.txt", "mocap: {file: cam1_mocap.txt, topic: /x}", 19,
     "cameras.cam1.mocap.topic: applies to rosbag sources only (this one is tum)"),
    ("  pose: T_world_marker\n", "  pose: T_world_marker\n  unit: inch\n", 10,
     "mocap.unit: expected one of m, cm, mm, got 'inch'"),
    ("  pose: T_world_marker\n", "  pose: T_world_marker\n  duplicates: average\n", 10,
     "mocap.duplicates: expected one of error, drop, got 'average'"),
])
def test_bad_rig_files_name_line_and_expectation(dataset, old, new, line, message):
    path = _edit(dataset, old, new)
    with pytest.raises(DatasetError, match=re.escape(message)) as info:
        load_rig(path)
    assert info.value.path == str(path.resolve())
    assert info.value.line == line


@pytest.mark.parametrize("old, new, message", [
    ("spacing: 0.033", "spaceing: 0.033", "target.spaceing: unknown key (did you mean "
     "'spacing'?); expected one of type, rows"),
    ("type: chessboard", "type: Chessboard", "target.type: expected one of chessboard, circles, "
     "asymmetric-circles, charuco, aprilgrid, aruco, aruco-grid, got 'Chessboard' (did you "
     "mean 'chessboard'?)"),
    ("time_tolerance: 0.02", "time_tolerence: 0.02", "mocap.time_tolerence: unknown key (did "
     "you mean 'time_tolerance'?)"),
    ("intrinsics: cam0.yaml", "intrinsic: cam0.yaml", "cameras.cam0.intrinsic: unknown key "
     "(did you mean 'intrinsics'?)"),
    ("setup: eye-to-base", "setup: eye_to_base", "got 'eye_to_base' (did you mean "
     "'eye-to-base'?)"),
])
def test_typos_get_a_did_you_mean(dataset, old, new, message):
    with pytest.raises(DatasetError, match=re.escape(message)):
        load_rig(_edit(dataset, old, new))


def test_unrelated_keys_get_no_guess(dataset):
    with pytest.raises(DatasetError) as info:
        load_rig(_edit(dataset, "spacing: 0.033", "colour: 0.033"))
    assert "unknown key; expected one of" in str(info.value)


def test_paths_in_messages_are_as_typed(dataset, monkeypatch):
    """Not resolved: the rig.yaml as given on the command line, a file as rig.yaml says it."""
    path = _edit(dataset, "images: cam0/", "images: ../elsewhere/cam0/")
    monkeypatch.chdir(dataset.parent)
    with pytest.raises(DatasetError) as info:
        load_rig(dataset.name)
    assert str(info.value) == (f"{dataset.name}/rig.yaml:14: cameras.cam0.images: folder not "
                               "found: ../elsewhere/cam0/ (relative to rig.yaml's folder)")
    assert str(dataset.parent) not in str(info.value)
    # the dataset loaded from a relative path still gives absolute paths to work with
    _edit(dataset, "images: ../elsewhere/cam0/", "images: cam0/")
    rig = load_rig(dataset.name)
    assert rig.path == path.resolve() and rig.cameras["cam0"].images.is_absolute()


def test_duplicate_keys_and_yaml_syntax(dataset):
    path = _edit(dataset, "  rows: 7\n", "  rows: 7\n  rows: 6\n")
    with pytest.raises(DatasetError, match="duplicate key 'rows' \\(first on line 4\\)") as info:
        load_rig(path)
    assert info.value.line == 5
    (dataset / "rig.yaml").write_text("setup: [eye-to-base\ncameras: {}\n")
    with pytest.raises(DatasetError, match="invalid YAML") as info:
        load_rig(dataset)
    assert info.value.line == 2
    with pytest.raises(DatasetError, match="rig description \\(rig.yaml\\) not found"):
        load_rig(dataset / "nowhere")


def test_target_types_need_their_keys(dataset):
    path = _edit(dataset, "type: chessboard", "type: charuco")
    with pytest.raises(DatasetError, match="target: missing key 'marker_size' \\(required for "
                       "charuco targets\\)"):
        load_rig(path)
    _edit(dataset, "  spacing: 0.033\n",
          "  spacing: 0.033\n  marker_size: 0.025\n  dictionary: DICT_5X5_100\n")
    target = load_rig(path).target
    assert (target.type, target.marker_size, target.dictionary) == ("charuco", 0.025,
                                                                     "DICT_5X5_100")
    _edit(dataset, "type: charuco", "type: aprilgrid")
    with pytest.raises(DatasetError, match="target.marker_size: applies to charuco, aruco, "
                       "aruco-grid targets only \\(this target is aprilgrid\\)"):
        load_rig(path)


_TARGET = "  type: chessboard\n  rows: 7\n  cols: 8\n  spacing: 0.033\n"


def test_aruco_targets(dataset):
    from multieye.imaging.targets import ArucoGrid, ArucoMarker, target_from_spec

    path = _edit(dataset, _TARGET, "  type: aruco\n  marker_size: 0.053\n"
                 "  dictionary: DICT_6X6_250\n  id: 0\n")
    target = load_rig(path).target
    assert (target.type, target.rows, target.cols, target.spacing, target.id) == (
        "aruco", 1, 1, 0.053, 0)
    assert target.as_dict() == {"type": "aruco", "marker_size": 0.053,
                                "dictionary": "DICT_6X6_250", "id": 0}
    assert isinstance(target_from_spec(target.as_dict()), ArucoMarker)
    (dataset / "rig.yaml").write_text(RIG)
    _edit(dataset, _TARGET, "  type: aruco-grid\n  rows: 5\n  cols: 7\n  marker_size: 0.04\n"
          "  marker_separation: 0.01\n  dictionary: DICT_6X6_250\n")
    target = load_rig(path).target
    assert (target.rows, target.cols, target.spacing, target.marker_separation,
            target.first_id) == (5, 7, 0.04, 0.01, None)
    grid = target_from_spec(target.as_dict())
    assert isinstance(grid, ArucoGrid) and grid.first_id == 0


@pytest.mark.parametrize("body, message", [
    ("type: aruco\n  marker_size: 0.05\n  dictionary: DICT_6X6_250",
     "target: missing key 'id' \\(required for aruco targets\\)"),
    ("type: aruco\n  marker_size: 0.05\n  dictionary: DICT_6X6_250\n  id: -1",
     "target.id: expected a marker id \\(an integer >= 0\\), got -1"),
    ("type: aruco\n  marker_size: 0.05\n  dictionary: DICT_6X6_250\n  id: 0\n  rows: 2",
     "target.rows: a single marker has no rows and cols"),
    ("type: aruco\n  spacing: 0.05\n  marker_size: 0.05\n  dictionary: DICT_6X6_250\n  id: 0",
     "target.spacing: aruco targets give the marker side as 'marker_size'"),
    ("type: aruco-grid\n  rows: 2\n  cols: 2\n  marker_size: 0.05\n  dictionary: DICT_6X6_250",
     "target: missing key 'marker_separation' \\(required for aruco-grid targets\\)"),
    ("type: aruco-grid\n  cols: 2\n  marker_size: 0.05\n  marker_separation: 0.01\n"
     "  dictionary: DICT_6X6_250", "target: missing key 'rows'"),
    ("type: aruco-grid\n  rows: 2\n  cols: 2\n  marker_size: 0.05\n  marker_separation: 0.01\n"
     "  dictionary: DICT_6X6_250\n  id: 3", "target.id: applies to aruco targets only"),
    ("type: chessboard\n  rows: 7\n  cols: 8\n  spacing: 0.03\n  first_id: 3",
     "target.first_id: applies to charuco, aprilgrid, aruco-grid targets only"),
])
def test_bad_aruco_targets(dataset, body, message):
    path = _edit(dataset, _TARGET, "  " + body + "\n")
    with pytest.raises(DatasetError, match=message):
        load_rig(path)


def test_target_only_needed_with_images(dataset):
    text = RIG.split("mocap:")[1]
    text = "setup: eye-to-base\nmocap:" + text.replace("    images: cam0/",
                                                        "    poses: cam1_target.txt")
    (dataset / "rig.yaml").write_text(text)
    assert load_rig(dataset).target is None
    (dataset / "rig.yaml").write_text(text.replace("    poses: cam1_target.txt\n  cam1",
                                                   "    images: cam0/\n  cam1", 1))
    with pytest.raises(DatasetError, match="missing key 'target': cameras with images \\(cam0\\)"):
        load_rig(dataset)


def test_per_camera_mocap_inherits_format_keys_of_the_same_format(dataset):
    path = _edit(dataset, "  pose: T_world_marker\n",
                 "  pose: T_world_marker\n  unit: mm\n  duplicates: drop\n")
    own = load_rig(path).mocap_for("cam1")
    assert (own.unit, own.duplicates) == ("mm", "drop")


def test_per_camera_mocap_without_top_level(dataset):
    (dataset / "rig.yaml").write_text(textwrap.dedent("""\
        setup: eye-on-hand
        cameras:
          left:
            intrinsics: cam0.yaml
            poses: cam1_target.txt
            mocap: {file: cam1_mocap.txt, time_tolerance: 0.5}
          right:
            intrinsics: cam0.yaml
            poses: cam1_target.txt
        """))
    with pytest.raises(DatasetError, match="cameras.right: no motion capture") as info:
        load_rig(dataset)
    assert info.value.line == 7
    (dataset / "rig.yaml").write_text((dataset / "rig.yaml").read_text() + "    mocap: mocap.txt\n")
    rig = load_rig(dataset)
    assert rig.mocap is None
    assert rig.mocap_for("left").time_tolerance == 0.5
    assert rig.mocap_for("right").pose == "T_world_body"  # default for eye-on-hand
    assert rig.mocap_for("right").time_tolerance == 0.03


def test_rosbag_sources(dataset):
    (dataset / "run.bag").write_bytes(b"")
    path = _edit(dataset, "  file: mocap.txt\n", "  file: run.bag\n  topic: /vicon/pose\n"
                 "  parent_frame: world\n")
    path = _edit(dataset, "    images: cam0/", "    rosbag: run.bag\n    topic: /cam0/image_raw")
    rig = load_rig(path)
    assert (rig.mocap.format, rig.mocap.topic, rig.mocap.parent_frame) == (
        "rosbag", "/vicon/pose", "world")
    cam0 = rig.cameras["cam0"]
    assert (cam0.source, cam0.topic) == ("rosbag", "/cam0/image_raw")
    own = rig.mocap_for("cam1")  # a TUM file: the bag's topic and frames are not inherited
    assert (own.format, own.topic, own.parent_frame, own.time_tolerance) == ("tum", None,
                                                                             None, 0.02)
    _edit(dataset, "  topic: /vicon/pose\n", "")
    with pytest.raises(DatasetError, match="mocap: missing key 'topic' \\(required for a rosbag"):
        load_rig(path)


# --------------------------------------------------------------------------- images


def test_list_images_seconds_and_nanoseconds(tmp_path):
    names = ["1700000000.5.png", "1700000000.000000001.JPG", "1700000001.png",
             "1700000002123456789.png", "notes.txt", ".hidden"]
    for name in names:
        (tmp_path / name).write_bytes(b"")
    out = list_images(tmp_path)
    assert [p.name for _, _, p in out] == [names[1], names[0], names[2], names[3]]
    assert [ns for _, ns, _ in out] == [1700000000000000001, 1700000000500000000,
                                        1700000001000000000, 1700000002123456789]
    assert np.allclose([s for s, _, _ in out], [1700000000.000000001, 1700000000.5,
                                                1700000001.0, 1700000002.123456789],
                       rtol=0, atol=1e-6)


def test_list_images_seconds_underscore_nanoseconds(tmp_path):
    """ROS's sec and nsec as some recorders name frames: ``1700000000_000000001``."""
    names = ["1700000000_500000000.png", "1700000000_000000001.png", "1700000001_000000000.png"]
    for name in names:
        (tmp_path / name).write_bytes(b"")
    out = list_images(tmp_path)
    assert [ns for _, ns, _ in out] == [1700000000000000001, 1700000000500000000,
                                        1700000001000000000]


def test_list_images_stamps_after_a_recorders_prefix(tmp_path):
    """``frame_<ns>``, ``rgb-<s.us>``, ``cam0_<sec>_<nsec>``: the stamp after a prefix that
    ends in a non-digit, as ROS image savers name frames; a short number after a prefix
    (``left0001``, ``12-00-00.123``) is still no stamp."""
    names = ["frame_1700000000500000000.png", "rgb-1700000000.25.png",
             "cam0_1700000001_000000007.png", "IMG1700000002.5.jpg"]
    for name in names:
        (tmp_path / name).write_bytes(b"")
    out = list_images(tmp_path)
    assert [ns for _, ns, _ in out] == [1700000000250000000, 1700000000500000000,
                                        1700000001000000007, 1700000002500000000]
    for bad in ("left0001.png", "12-00-00.123.png", "frame_1700000000500.png"):
        folder = tmp_path / bad.replace(".", "_")
        folder.mkdir()
        (folder / bad).write_bytes(b"")
        with pytest.raises(DatasetError, match="not a time stamp.*stamps:"):
            list_images(folder)


@pytest.mark.parametrize("name, message", [
    ("frame_001.png", "expected a time stamp"),
    ("1700000000123.png", "13 digits is ambiguous"),
    ("-5.png", "expected a time stamp"),
    ("1700000000_12345.png", "or seconds_nanoseconds"),        # nanoseconds: exactly 9 digits
    ("0001_000000001_cam0.png", "expected a time stamp"),
])
def test_list_images_rejects_names_that_are_not_stamps(tmp_path, name, message):
    (tmp_path / "1700000000.png").write_bytes(b"")
    (tmp_path / name).write_bytes(b"")
    with pytest.raises(DatasetError, match=message) as info:
        list_images(tmp_path)
    assert info.value.path == str(tmp_path / name)


def test_entries_are_files_as_path_is_file_says(tmp_path):
    """list_images takes an entry's type from the folder's listing (no stat of each image):
    every kind of entry is a file or not as ``Path.is_file`` says, links followed."""
    import os

    from multieye.io.image_folder import is_file_entry, sorted_entries

    (tmp_path / "1.png").write_bytes(b"")
    (tmp_path / "dir.png").mkdir()
    os.mkfifo(tmp_path / "fifo.png")
    (tmp_path / "2.png").symlink_to(tmp_path / "1.png")
    (tmp_path / "3.png").symlink_to(tmp_path / "dir.png")
    (tmp_path / "4.png").symlink_to(tmp_path / "gone.png")
    (tmp_path / "5.png").symlink_to(tmp_path / "6.png")
    (tmp_path / "6.png").symlink_to(tmp_path / "5.png")          # a loop
    entries = sorted_entries(tmp_path)
    assert [e.name for e in entries] == [p.name for p in sorted(tmp_path.iterdir())]
    assert {e.name: is_file_entry(e) for e in entries} == {
        p.name: p.is_file() for p in tmp_path.iterdir()}
    assert [p.name for _, _, p in list_images(tmp_path)] == ["1.png", "2.png"]
    (tmp_path / "..png").write_bytes(b"")       # ".png" its suffix, as Path says: hidden
    assert [p.name for _, _, p in list_images(tmp_path)] == ["1.png", "2.png"]
    (tmp_path / "x.png").write_bytes(b"")
    with pytest.raises(DatasetError, match="expected a time stamp"):
        list_images(tmp_path)


def test_list_images_duplicates_and_empty(tmp_path):
    (tmp_path / "1700000000.5.png").write_bytes(b"")
    (tmp_path / "1700000000.500.jpg").write_bytes(b"")
    with pytest.raises(DatasetError, match="same time stamp as 1700000000.5.png"):
        list_images(tmp_path)
    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetError, match="no images"):
        list_images(tmp_path / "empty")
    with pytest.raises(DatasetError, match="image folder not found"):
        list_images(tmp_path / "none")


@pytest.mark.parametrize("pose, frames, moving, role_pose, names", [
    ("T_world_marker", None, "marker", "T_world_marker", ("world", "marker")),
    ("T_marker_world", None, "marker", "T_marker_world", ("world", "marker")),
    ("T_base_tool0", None, "body", "T_world_body", ("base", "tool0")),       # parent fixed
    ("T_world_tool0", None, "body", "T_world_body", ("world", "tool0")),     # world is fixed
    ("T_tool0_world", None, "body", "T_body_world", ("world", "tool0")),
    ("T_body_base", None, "body", "T_body_world", ("base", "body")),         # body is tracked
    ("T_mocap_board", None, "marker", "T_world_marker", ("mocap", "board")),
    ("T_world_base_link", None, "body", "T_world_body", ("world", "base_link")),  # one reading names world
    (None, ("base_link", "tool0"), "body", "T_world_body", ("base_link", "tool0")),
    ("T_base_link_tool0", ("base_link", "tool0"), "body", "T_world_body", ("base_link", "tool0")),
])
def test_pose_names_give_the_roles_and_the_users_frame_names(pose, frames, moving, role_pose,
                                                             names):
    from multieye.io.mocap import named_pose

    assert named_pose(pose, moving, frames) == (role_pose, names)


@pytest.mark.parametrize("pose, fixed, moving, role_pose, names", [
    ("T_tool0_base", "base", "body", "T_body_world", ("base", "tool0")),    # the inverse file
    ("T_base_tool0", "base", "body", "T_world_body", ("base", "tool0")),
    ("T_board_mocap", "mocap", "marker", "T_marker_world", ("mocap", "board")),
    ("T_world_tool0", "world", "body", "T_world_body", ("world", "tool0")),
])
def test_fixed_frame_says_which_name_is_fixed(pose, fixed, moving, role_pose, names):
    from multieye.io.mocap import named_pose

    assert named_pose(pose, moving, None, fixed) == (role_pose, names)


@pytest.mark.parametrize("pose, fixed, message", [
    ("T_tool0_base", "flange", "is not one of the frames of the pose, tool0 and base"),
    ("T_world_tool0", "tool0", "contradicts the role names"),
    ("T_base_body", "body", "contradicts the role names"),
])
def test_fixed_frame_that_cannot_be_is_refused(pose, fixed, message):
    from multieye.io.mocap import named_pose

    with pytest.raises(ValueError, match=re.escape(message)):
        named_pose(pose, "body", None, fixed)


@pytest.mark.parametrize("pose, moving", [("T_tool0_base", "body"), ("T_flange_base_link", "body"),
                                          ("T_ee_map", "marker"), ("T_tcp_mocap", "marker")])
def test_a_tool_over_a_base_without_fixed_frame_is_refused(pose, moving):
    """``T_tool0_base`` alone made the tool the fixed frame (the parent) and printed the
    camera's pose in the tool as ``T_base_cam``; a name of a moving frame over one of a fixed
    frame now asks which is meant, naming both fixes; ``fixed_frame`` settles it."""
    from multieye.io.mocap import named_pose

    parent, child = pose[2:].split("_", 1)
    with pytest.raises(ValueError, match=re.escape(f"write pose: T_{child}_{parent}")) as info:
        named_pose(pose, moving, (parent, child))
    assert f"add fixed_frame: {child}" in str(info.value)
    assert named_pose(pose, moving, (parent, child), child)[1] == (child, parent)
    assert named_pose(f"T_{child}_{parent}", moving, (child, parent))[1] == (child, parent)


def test_fixed_frame_is_read_from_rig_yaml_and_its_line_named(dataset):
    _edit(dataset, "  pose: T_world_marker\n", "  pose: T_board_mocap\n  fixed_frame: mocap\n")
    rig = load_rig(dataset)
    assert rig.mocap.pose == "T_marker_world" and rig.mocap.frames == ("mocap", "board")
    assert rig.frames == {"world": "mocap", "marker": "board"}
    (dataset / "rig.yaml").write_text((dataset / "rig.yaml").read_text().replace(
        "fixed_frame: mocap", "fixed_frame: base"))
    with pytest.raises(DatasetError, match=r"rig\.yaml:\d+: mocap\.fixed_frame: fixed_frame "
                                           r"'base' is not one of"):
        load_rig(dataset)


@pytest.mark.parametrize("pose, frames, moving, message", [
    ("T_world_marker", None, "body", "expected T_world_body (or T_body_world) for eye-on-hand"),
    ("T_base_marker", None, "body", "expected T_world_body"),
    ("T_base_link_tool0", None, "body", "can be read as [base, link_tool0] or [base_link, tool0]"),
    ("T_base_tool0", ("base", "flange"), "body", "does not match frames [base, flange]"),
    ("T_base_base", None, "body", "frames of T_base_base are the same"),
    (None, ("tool0", "tool0"), "body", "frames of T_tool0_tool0 are the same"),
    ("T_world_target", None, "marker", "'target' names a frame multieye's outputs already"),
    ("T_base_cam", None, "body", "'cam' names a frame"),
    ("T_ref_tool0", None, "body", "'ref' names a frame"),
    ("base_tool0", None, "body", "T_<parent>_<child>"),
    (None, ("base link", "tool0"), "body", "letters, digits and '_'"),
])
def test_bad_pose_names_are_refused(pose, frames, moving, message):
    from multieye.io.mocap import named_pose

    with pytest.raises(ValueError, match=re.escape(message)):
        named_pose(pose, moving, frames)


def test_cameras_naming_the_frames_differently_are_refused_at_the_camera(dataset):
    _edit(dataset, "    mocap: cam1_mocap.txt\n",
          "    mocap: {file: cam1_mocap.txt, pose: T_base_board}\n")
    with pytest.raises(DatasetError, match=r"cameras\.cam1: camera cam1 names the motion "
                                           r"capture's frames \['base', 'board'\]"):
        load_rig(dataset)


def test_a_rig_without_motion_capture_is_accepted_and_its_keys_checked(tmp_path):
    """Issue 23: mocap optional (setup then optional), sync_tolerance checked where it is,
    motion capture for every camera or for none, and no camera given by poses."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "cam.yaml").write_text("%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n"
                                       "   rows: 3\n   cols: 3\n   dt: d\n"
                                       "   data: [500., 0., 320., 0., 500., 240., 0., 0., 1.]\n")
    target = "target: {type: chessboard, rows: 6, cols: 9, spacing: 0.05}\n"
    cams = "cameras:\n  a: {intrinsics: cam.yaml, images: a/}\n  b: {model: fisheye, images: b/}\n"
    (tmp_path / "rig.yaml").write_text(target + "sync_tolerance: 0.004\n" + cams)
    rig = load_rig(tmp_path)
    assert not rig.has_mocap and rig.mocap is None and rig.sync_tolerance == 0.004
    for bad, where in (("sync_tolerance: -1\n", ":2:"), ("sync_tolerance: 11\n", ":2:")):
        (tmp_path / "rig.yaml").write_text(target + bad + cams)
        with pytest.raises(DatasetError, match=f"{where}.*sync_tolerance"):
            load_rig(tmp_path)
    (tmp_path / "m.txt").write_text("0 0 0 0 0 0 0 1\n")
    (tmp_path / "rig.yaml").write_text(target + cams.replace("images: a/}", "images: a/, "
                                                             "mocap: m.txt}"))
    with pytest.raises(DatasetError, match="missing key 'setup'"):
        load_rig(tmp_path)
    (tmp_path / "rig.yaml").write_text("setup: eye-to-base\n" + target + cams.replace(
        "images: a/}", "images: a/, mocap: m.txt}"))
    with pytest.raises(DatasetError, match="cameras.b.*for every camera, or none"):
        load_rig(tmp_path)
    (tmp_path / "p.txt").write_text("0 0 0 1 0 0 0 1\n")
    (tmp_path / "rig.yaml").write_text(target + cams + "  c: {poses: p.txt}\n")
    with pytest.raises(DatasetError, match="cameras.c.*'poses' has none"):
        load_rig(tmp_path)


def test_a_folder_with_rig_yml_says_so(tmp_path):
    (tmp_path / "rig.yml").write_text("cameras: {}\n")
    with pytest.raises(DatasetError, match="no rig.yaml in the folder, but rig.yml: name it "
                       "rig.yaml, or give the file itself"):
        load_rig(tmp_path)
    with pytest.raises(DatasetError, match="rig.yml:1: cameras: expected a mapping"):
        load_rig(tmp_path / "rig.yml")


def test_hidden_files_beside_images_are_left_out_and_listed(tmp_path):
    """macOS writes ._left01.jpg beside left01.jpg on copied volumes: it stopped the run as a
    second image numbered 1 (sync: number) or as a name that is not a time stamp."""
    from multieye.io.image_folder import list_image_files, skipped_entries

    (tmp_path / "t").mkdir()
    (tmp_path / "n").mkdir()
    for name in ("t/1700000000.5.png", "t/._1700000000.5.png", "n/left01.jpg", "n/._left01.jpg"):
        (tmp_path / name).write_bytes(b"x")
    assert [p.name for _, _, p in list_images(tmp_path / "t")] == ["1700000000.5.png"]
    assert [p.name for _, _, p in list_images(tmp_path / "n", sync="number")] == ["left01.jpg"]
    assert [p.name for p in list_image_files(tmp_path / "n")] == ["left01.jpg"]
    assert [n for n, why in skipped_entries(tmp_path / "t") if "a hidden file" in why] == [
        "._1700000000.5.png"]


def test_a_tab_indent_says_yaml_indents_with_spaces(tmp_path):
    (tmp_path / "rig.yaml").write_text("mocap:\n\tfile: m.txt\ncameras: {c: {poses: p.txt}}\n")
    with pytest.raises(DatasetError, match=r"rig.yaml:2: invalid YAML: found character '\\t' "
                       r"that cannot start any token \(YAML indents with spaces, not tabs\)"):
        load_rig(tmp_path)


def test_poses_may_say_which_direction_the_file_holds(dataset):
    """``poses: {file, pose}``: a file of ``T_target_cam`` (what the inverted-poses doubt
    suggests) is read as such; ``pose`` defaults to ``T_cam_target``, and anything else is
    refused naming the key."""
    assert not load_rig(dataset).cameras["cam1"].poses_inverted
    _edit(dataset, "poses: cam1_target.txt", "poses: {file: cam1_target.txt, pose: T_target_cam}")
    cam1 = load_rig(dataset).cameras["cam1"]
    assert cam1.poses_inverted and cam1.poses == (dataset / "cam1_target.txt").resolve()
    _edit(dataset, "pose: T_target_cam}", "pose: T_cam_target}")
    assert not load_rig(dataset).cameras["cam1"].poses_inverted
    for bad, message in (("pose: T_cam_target}", "cameras.cam1.poses.pose: expected one of "
                          "T_cam_target, T_target_cam, got 'T_target_camera'"),
                         ("file: cam1_target.txt, ", "cameras.cam1.poses: missing key 'file'")):
        text = (dataset / "rig.yaml").read_text()
        _edit(dataset, bad, "pose: T_target_camera}" if bad.startswith("pose") else "")
        with pytest.raises(DatasetError, match=re.escape(message)):
            load_rig(dataset)
        (dataset / "rig.yaml").write_text(text)


@pytest.mark.parametrize("given, ours", [
    ("pinhole", "pinhole-radtan4 (Kalibr's pinhole with radtan"), ("ds", "double-sphere"),
    ("omni", "unified"), ("equidistant", "fisheye"), ("Kannala_Brandt", "fisheye"),
    ("plumb_bob", "pinhole-radtan"), ("rational_polynomial", "pinhole-rational"),
])
def test_another_tools_lens_name_is_refused_naming_multieyes(tmp_path, given, ours):
    """Kalibr's, ROS's and Basalt's names for a lens (``model: pinhole``, ``ds``) are refused
    at their line with multieye's name for that lens, not only the list of names."""
    (tmp_path / "cam0").mkdir()
    (tmp_path / "rig.yaml").write_text(
        "target: {type: chessboard, rows: 6, cols: 9, spacing: 0.05}\n"
        f"cameras:\n  cam0: {{images: cam0/, model: {given}}}\n")
    with pytest.raises(DatasetError) as err:
        load_rig(tmp_path / "rig.yaml")
    assert err.value.line == 3 and f"another tool's name: multieye's is {ours}" in str(err.value)
