"""Recordings as users lay them out (issue 34, item 4): rig.yaml's ``sync``, ``images:`` as a
file-name pattern, ``{stem}`` pose files in a folder of the dataset, and pose files whose
numbers are named (YAML or JSON), each with its bad input refused in one line."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from multieye.core.errors import DatasetError
from multieye.io.image_folder import (check_pattern, list_image_files, list_images,
                                      number_in_name, numbers_in_names, sync_key)
from multieye.io.pose_files import PoseFormat, poses_by_name, read_pose_file
from multieye.io.rig import load_rig

HEAD = "target: {type: chessboard, rows: 6, cols: 4, spacing: 0.03}\n"


def _touch(folder, *names):
    folder.mkdir(parents=True, exist_ok=True)
    for n in names:
        (folder / n).write_bytes(b"")


def test_number_and_name_keys():
    assert number_in_name("left01") == 1 and number_in_name("frame_000123") == 123
    assert number_in_name("img_123") == 123 and number_in_name("cam2_frame7") == 7
    assert number_in_name("left") is None
    assert sync_key("left01", "number", 5) == sync_key("right1", "number", 0) == "1"
    assert sync_key("a", "name", 0) == "a" and sync_key("a", "order", 4) == "4"


def test_number_is_the_integer_that_differs_between_a_cameras_images(tmp_path):
    """``0001_cam0.png`` ... ``0016_cam0.png``: the last integer (0) names the camera, and
    sync: number refused the camera as 16 images of number 0; the number is the last integer
    that differs between the camera's images."""
    assert numbers_in_names(["0001_cam0", "0002_cam0", "0010_cam0"]) == [1, 2, 10]
    assert numbers_in_names(["frame0001_cam1", "frame0002_cam1"]) == [1, 2]
    assert numbers_in_names(["cam0_frame1_v2", "cam0_frame2_v2"]) == [1, 2]
    assert numbers_in_names(["left01", "left2", "left10"]) == [1, 2, 10]
    assert numbers_in_names(["0005_cam1"]) == [1]             # nothing differs: the last
    assert numbers_in_names(["a1_b2", "a3", "x"]) == [2, 3, None]   # counts differ: the last
    _touch(tmp_path, *(f"{k:04d}_cam{j}.png" for k in range(1, 4) for j in range(2)))
    for j in range(2):
        listed = list_images(tmp_path, f"*_cam{j}.png", "number")
        assert [p.name for _, _, p in listed] == [f"{k:04d}_cam{j}.png" for k in range(1, 4)]


def test_pattern_lists_matching_images_in_natural_order(tmp_path):
    _touch(tmp_path, "left2.jpg", "left10.jpg", "left1.jpg", "right1.jpg", "left3.txt")
    listed = list_images(tmp_path, "left*.jpg", "number")
    assert [p.name for _, _, p in listed] == ["left1.jpg", "left2.jpg", "left10.jpg"]
    assert [s for s, _, _ in listed] == [0.0, 1.0, 2.0]
    assert [p.name for p in list_image_files(tmp_path, "right*")] == ["right1.jpg"]
    with pytest.raises(DatasetError, match="no image .* named up\\*.jpg"):
        list_images(tmp_path, "up*.jpg", "number")


def test_default_sync_keeps_names_as_stamps(tmp_path):
    _touch(tmp_path, "left01.jpg")
    with pytest.raises(DatasetError, match="not a time stamp.*sync: name \\| number \\| order"):
        list_images(tmp_path)


def test_same_number_twice_names_both_files(tmp_path):
    _touch(tmp_path, "left01.jpg", "left1.png")
    with pytest.raises(DatasetError) as err:
        list_images(tmp_path, None, "number")
    assert "left01.jpg" in str(err.value) and "left1.png" in str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("bad", ["../x*.jpg", "a/../b*.jpg", "a//b*.jpg", "./b*.jpg", "", "..",
                                 "a\\b*", "**/left.jpg", "a/*/*/*/left*.jpg"])
def test_a_pattern_is_a_file_name(bad):
    with pytest.raises(ValueError, match="file-name pattern"):
        check_pattern(bad)


@pytest.mark.parametrize("good", ["left*.jpg", "*/left.jpg", "run_*/cam?/*.png"])
def test_a_pattern_may_name_sub_folders(good):
    assert check_pattern(good) == good


def _rig(tmp_path, body: str):
    (tmp_path / "rig.yaml").write_text(HEAD + body)
    return load_rig(tmp_path)


def test_rig_yaml_sync_and_pattern(tmp_path):
    _touch(tmp_path, "left01.jpg", "right01.jpg")
    rig = _rig(tmp_path, "sync: number\ncameras:\n  left: {model: fisheye, images: 'left*.jpg'}\n"
               "  right: {model: fisheye, images: right*.jpg}\n")
    assert rig.sync == "number"
    assert rig.cameras["left"].images == tmp_path.resolve()
    assert rig.cameras["left"].images_pattern == "left*.jpg"
    _touch(tmp_path / "raw", "a1.png")
    rig = _rig(tmp_path, "cameras:\n  a: {model: fisheye, images: 'raw/a*.png'}\n")
    assert rig.sync == "time" and rig.cameras["a"].images == (tmp_path / "raw").resolve()
    assert rig.cameras["a"].images_pattern == "a*.png"


@pytest.mark.parametrize("images, message", [
    ("'../*.jpg'", "folder of the dataset"),
    ("'/tmp/*.jpg'", "folder of the dataset"),
    ("'r*/../x.jpg'", "no '..'"),
    ("'raw/**/x.jpg'", "no '[*][*]'"),
    ("'nowhere/*.jpg'", "folder not found"),
])
def test_bad_patterns_refused_at_their_line(tmp_path, images, message):
    _touch(tmp_path, "left01.jpg")
    with pytest.raises(DatasetError, match=message) as err:
        _rig(tmp_path, f"cameras:\n  a: {{model: fisheye, images: {images}}}\n")
    assert err.value.line == 3 and "\n" not in str(err.value)


def test_pattern_folder_linked_out_of_the_dataset_is_refused(tmp_path):
    _touch(tmp_path / "elsewhere", "a1.jpg")
    (tmp_path / "ds").mkdir()
    os.symlink(tmp_path / "elsewhere", tmp_path / "ds" / "raw")
    with pytest.raises(DatasetError, match="leads out of the dataset folder"):
        _rig(tmp_path / "ds", "cameras:\n  a: {model: fisheye, images: 'raw/a*.jpg'}\n")


@pytest.mark.parametrize("body, message", [
    ("sync: stamps\ncameras:\n  a: {model: fisheye, images: a/}\n", "expected one of time, name"),
    ("sync: number\nsetup: eye-to-base\nmocap: {file: m.txt}\n"
     "cameras:\n  a: {model: fisheye, images: a/}\n", "pairs with motion capture in time"),
    ("sync: order\ncameras:\n  a: {model: fisheye, video: v.mp4, start_time: 0}\n",
     "camera a has video, not images"),
])
def test_sync_refused_where_names_cannot_pair(tmp_path, body, message):
    _touch(tmp_path / "a", "1.png")
    (tmp_path / "m.txt").write_text("0 0 0 0 0 0 0 1\n")
    (tmp_path / "v.mp4").write_bytes(b"")
    with pytest.raises(DatasetError, match=message):
        _rig(tmp_path, body)


def _pose(T):
    q = Rotation.from_matrix(T[:3, :3]).as_quat()
    return T[:3, 3].tolist(), q.tolist()


@pytest.fixture
def T():
    R = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = R, [0.4, -0.1, 1.2]
    return out


def test_yaml_named_keys_as_ros_industrial_stores_them(tmp_path, T):
    t, q = _pose(T)
    (tmp_path / "3.yaml").write_text(
        f"x: {t[0]!r}\ny: {t[1]!r}\nz: {t[2]!r}\nqx: {q[0]!r}\nqy: {q[1]!r}\nqz: {q[2]!r}\n"
        f"qw: {q[3]!r}\n")
    np.testing.assert_allclose(read_pose_file(tmp_path / "3.yaml", PoseFormat()), T, atol=1e-12)


def test_named_forms(tmp_path, T):
    t, q = _pose(T)
    rv = Rotation.from_matrix(T[:3, :3]).as_rotvec().tolist()
    forms = {
        "wfirst.json": json.dumps({"qw": q[3], "qx": q[0], "qy": q[1], "qz": q[2],
                                   "x": t[0], "y": t[1], "z": t[2]}),
        "rvec.yaml": f"rx: {rv[0]!r}\nry: {rv[1]!r}\nrz: {rv[2]!r}\nx: {t[0]!r}\ny: {t[1]!r}\n"
                     f"z: {t[2]!r}\n",
        "ros.yaml": f"position: {{x: {t[0]!r}, y: {t[1]!r}, z: {t[2]!r}}}\n"
                    f"orientation: {{x: {q[0]!r}, y: {q[1]!r}, z: {q[2]!r}, w: {q[3]!r}}}\n",
    }
    for name, text in forms.items():
        (tmp_path / name).write_text(text)
        np.testing.assert_allclose(read_pose_file(tmp_path / name, PoseFormat()), T,
                                   atol=1e-12, err_msg=name)
    (tmp_path / "m.yaml").write_text(f"stamp: 3\npose: {T.tolist()}\n")
    np.testing.assert_allclose(read_pose_file(tmp_path / "m.yaml", PoseFormat(key="pose")), T,
                               atol=1e-12)


@pytest.mark.parametrize("name, text, fmt, message", [
    ("mixed.yaml", "x: 0\ny: 0\nz: 0\nqx: 0\nqy: 0\nqz: 0\nqw: 1\nrx: 0\nry: 0\nrz: 0\n",
     PoseFormat(), "keys qx, qy, qz, qw, rx, ry, rz: both a quaternion and a rotation vector"),
    ("extra.yaml", "x: 0\ny: 0\nz: 0\nqx: 0\nqy: 0\nqz: 0\nqw: 1\nroll: 0\n", PoseFormat(),
     "key 'roll': not one of the pose's numbers"),
    ("half.yaml", "x: 0\ny: 0\nz: 0\nqx: 0\nqw: 1\n", PoseFormat(), "missing qy, qz"),
    ("norm.yaml", "x: 0\ny: 0\nz: 0\nqx: 0\nqy: 0\nqz: 0\nqw: 1.1\n", PoseFormat(),
     "unit norm"),
    ("text.yaml", "x: 0\ny: 0\nz: zero\nqx: 0\nqy: 0\nqz: 0\nqw: 1\n", PoseFormat(),
     "key 'z': expected a number"),
    ("skew.yaml", "pose: [[1, 0.1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n",
     PoseFormat(key="pose"), "expected a rotation matrix"),
    ("nokey.yaml", "pose: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n",
     PoseFormat(), "give mocap.key"),
    ("ros.yaml", "position: {x: 0, y: 0}\norientation: {x: 0, y: 0, z: 0, w: 1}\n",
     PoseFormat(), "key 'position': expected the numbers x, y, z"),
])
def test_bad_named_pose_files_name_file_and_key(tmp_path, name, text, fmt, message):
    (tmp_path / name).write_text(text)
    with pytest.raises(DatasetError, match=message) as err:
        read_pose_file(tmp_path / name, fmt)
    assert str(err.value).startswith(str(tmp_path / name)) and "\n" not in str(err.value)


def test_stem_pattern_in_a_folder_of_the_dataset(tmp_path, T):
    _touch(tmp_path / "images", "1.png", "2.png", "3.png")
    (tmp_path / "poses").mkdir()
    t, q = _pose(T)
    text = (f"x: {t[0]!r}\ny: {t[1]!r}\nz: {t[2]!r}\nqx: {q[0]!r}\nqy: {q[1]!r}\nqz: {q[2]!r}\n"
            f"qw: {q[3]!r}\n")
    for k in (1, 2, 4):
        (tmp_path / "poses" / f"{k}.yaml").write_text(text)
    rig = _rig(tmp_path, "setup: eye-on-hand\nmocap: {file: 'poses/{stem}.yaml', pose: "
               "T_base_tool0}\ncameras:\n  cam: {model: fisheye, images: images/}\n")
    spec = rig.mocap
    assert spec.by_name and spec.file == (tmp_path / "poses").resolve() / "{stem}.yaml"
    images = list_image_files(tmp_path / "images")
    matched, unmatched = poses_by_name(images, str(spec.file), PoseFormat())
    assert [p.name for p, _ in matched] == ["1.png", "2.png"]
    assert unmatched == [("3.png", "no pose file 3.yaml"),
                         ("4.yaml", "pose file without an image 4.*")]
    with pytest.raises(DatasetError, match="folder of the dataset"):
        _rig(tmp_path, "setup: eye-on-hand\nmocap: {file: '../poses/{stem}.yaml'}\n"
             "cameras:\n  cam: {model: fisheye, images: images/}\n")


def test_folder_entries_are_bounded(tmp_path, monkeypatch):
    import multieye.io.image_folder as image_folder

    _touch(tmp_path, "a1.png", "a2.png", "a3.png")
    monkeypatch.setattr(image_folder, "MAX_FOLDER_ENTRIES", 2)
    with pytest.raises(DatasetError, match="3 entries, more than 2 in one image folder"):
        list_images(tmp_path, "a*", "number")


def test_pattern_skips_entries_that_are_not_regular_files(tmp_path):
    _touch(tmp_path, "a1.png")
    (tmp_path / "a2.png").mkdir()
    os.symlink(tmp_path / "nowhere.png", tmp_path / "a3.png")
    assert [p.name for _, _, p in list_images(tmp_path, "a*.png", "number")] == ["a1.png"]
