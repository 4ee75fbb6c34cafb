"""Intrinsics readers (OpenCV FileStorage, Kalibr, ROS camera_info), the OpenCV writer and
Kalibr camchain round trips."""

from __future__ import annotations

import re
from dataclasses import replace

import cv2
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from multieye.core import geometry
from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import Intrinsics
from multieye.io.intrinsics_files import (
    read_camera_info,
    read_intrinsics,
    read_kalibr_intrinsics,
    read_opencv_intrinsics,
    write_opencv_intrinsics,
)
from multieye.io.kalibr import CamchainEntry, read_camchain, write_camchain

K = np.array([[610.5, 0.0, 641.25], [0.0, 611.0, 365.5], [0.0, 0.0, 1.0]])


def _opencv_file(path, dist, *, model=None, size=(1280, 720),
                 keys=("camera_matrix", "distortion_coefficients")):
    """Written by OpenCV itself."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    if size:
        fs.write("image_width", size[0])
        fs.write("image_height", size[1])
    fs.write(keys[0], K)
    if dist is not None:
        fs.write(keys[1], np.asarray(dist, dtype=np.float64).reshape(1, -1))
    if model:
        fs.write("distortion_model", model)
    fs.release()
    return path


@pytest.mark.parametrize("n", [4, 5, 8, 12, 14])
@pytest.mark.parametrize("xml", [False, True], ids=["yaml", "xml"])
def test_opencv_filestorage_all_coefficient_counts(tmp_path, rng, n, xml):
    dist = rng.normal(scale=0.1, size=n)
    path = _opencv_file(tmp_path / ("cam.xml" if xml else "cam.yaml"), dist)
    intr = read_intrinsics(path)
    assert intr.model == "pinhole" and (intr.width, intr.height) == (1280, 720)
    assert np.array_equal(intr.K, K) and np.array_equal(intr.dist, dist)
    assert np.array_equal(read_opencv_intrinsics(path).dist, dist)


def test_opencv_k_d_keys_fisheye_and_no_size(tmp_path):
    path = _opencv_file(tmp_path / "k.yaml", [0.1, -0.01, 0.002, 0.0003], model="fisheye",
                        size=None, keys=("K", "D"))
    intr = read_intrinsics(path)
    assert intr.model == "fisheye" and intr.width is None
    assert intr.dist.tolist() == [0.1, -0.01, 0.002, 0.0003]


def test_opencv_errors_name_the_file(tmp_path):
    path = _opencv_file(tmp_path / "bad.yaml", [0.1, 0.2, 0.3])
    with pytest.raises(DatasetError, match="pinhole distortion must have 0, 4, 5, 8, 12 or 14 "
                       "coefficients, got 3") as info:
        read_intrinsics(path)
    assert info.value.path == str(path)
    (tmp_path / "nok.yaml").write_text("%YAML:1.0\n---\nfoo: 1\n")
    with pytest.raises(DatasetError, match="no camera_matrix \\(or K\\); keys present: foo"):
        read_intrinsics(tmp_path / "nok.yaml")
    (tmp_path / "broken.yaml").write_text("%YAML:1.0\n---\ncamera_matrix: [1, 2\n")
    with pytest.raises(DatasetError, match="OpenCV cannot parse") as info:
        read_intrinsics(tmp_path / "broken.yaml")
    assert info.value.path == str(tmp_path / "broken.yaml")
    with pytest.raises(DatasetError, match="intrinsics file not found"):
        read_intrinsics(tmp_path / "none.yaml")


@pytest.mark.parametrize("intr", [
    Intrinsics(K, np.array([0.1, -0.2, 1e-5, -2e-4, 0.03]), "pinhole", 1280, 720),
    Intrinsics(K, np.arange(1, 15) * 1e-3, "pinhole", None, None),
    Intrinsics(K, np.array([0.01, -0.002, 3e-4, -4e-5]), "fisheye", 640, 480),
    Intrinsics(K),
], ids=["5", "14-no-size", "fisheye", "no-distortion"])
def test_opencv_writer_round_trip_through_cv2(tmp_path, intr):
    path = tmp_path / "out.yaml"
    write_opencv_intrinsics(path, intr)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)  # OpenCV itself reads it
    assert np.array_equal(fs.getNode("camera_matrix").mat(), intr.K)
    fs.release()
    back = read_intrinsics(path)
    assert back.model == intr.model and (back.width, back.height) == (intr.width, intr.height)
    assert np.array_equal(back.K, intr.K) and np.array_equal(back.dist, intr.dist)


# --------------------------------------------------------------------------- camera_info


CAMERA_INFO = """\
image_width: 1280
image_height: 720
camera_name: front
camera_matrix:
  rows: 3
  cols: 3
  data: [610.5, 0, 641.25, 0, 611, 365.5, 0, 0, 1]
distortion_model: {model}
distortion_coefficients:
  rows: 1
  cols: {n}
  data: [{coeffs}]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
"""


@pytest.mark.parametrize("model, n, kind", [("plumb_bob", 5, "pinhole"),
                                            ("rational_polynomial", 8, "pinhole"),
                                            ("equidistant", 4, "fisheye")])
def test_ros_camera_info(tmp_path, model, n, kind):
    coeffs = [round(0.01 * (i + 1), 3) for i in range(n)]
    (tmp_path / "ci.yaml").write_text(CAMERA_INFO.format(model=model, n=n,
                                                         coeffs=", ".join(map(str, coeffs))))
    intr = read_intrinsics(tmp_path / "ci.yaml")
    assert intr.model == kind and intr.dist.tolist() == coeffs
    assert np.array_equal(intr.K, K) and (intr.width, intr.height) == (1280, 720)
    assert read_camera_info(tmp_path / "ci.yaml").model == kind


def test_camera_info_errors_give_the_line(tmp_path):
    (tmp_path / "a.yaml").write_text(CAMERA_INFO.format(model="plumb_bob", n=3,
                                                        coeffs="0.1, 0.2, 0.3"))
    with pytest.raises(DatasetError, match="got 3") as info:
        read_intrinsics(tmp_path / "a.yaml")
    assert info.value.line == 9
    (tmp_path / "b.yaml").write_text(CAMERA_INFO.format(model="unified", n=4,
                                                        coeffs="0, 0, 0, 0"))
    with pytest.raises(DatasetError, match="distortion_model: 'unified' is not a supported "
                       "distortion model") as info:
        read_intrinsics(tmp_path / "b.yaml")
    assert info.value.line == 8
    (tmp_path / "c.yaml").write_text("width: 3\n")
    with pytest.raises(DatasetError, match="not an intrinsics file: expected OpenCV"):
        read_intrinsics(tmp_path / "c.yaml")
    (tmp_path / "d.yaml").write_text("K: [1, 0, 0, 0, 1, 0, 0, 0]\n")
    with pytest.raises(DatasetError, match="K: expected 9 numbers, got 8") as info:
        read_intrinsics(tmp_path / "d.yaml")
    assert info.value.line == 1


def test_plain_yaml_k_d_nested_lists(tmp_path):
    (tmp_path / "kd.yaml").write_text("K: [[610.5, 0, 641.25], [0, 611, 365.5], [0, 0, 1]]\n"
                                      "D: [0.1, 0.2, 0.0, 0.0]\n")
    intr = read_intrinsics(tmp_path / "kd.yaml")
    assert np.array_equal(intr.K, K) and intr.dist.tolist() == [0.1, 0.2, 0.0, 0.0]


# --------------------------------------------------------------------------- Kalibr


CAMCHAIN = """\
cam0:
  camera_model: pinhole
  intrinsics: [610.5, 611.0, 641.25, 365.5]
  distortion_model: radtan
  distortion_coeffs: [0.1, -0.2, 0.001, -0.002]
  resolution: [1280, 720]
  rostopic: /cam0/image_raw
cam1:
  camera_model: pinhole
  intrinsics: [300.0, 301.0, 320.0, 240.0]
  distortion_model: equidistant
  distortion_coeffs: [0.01, 0.02, 0.03, 0.04]
  resolution: [640, 480]
  T_cn_cnm1:
  - [1.0, 0.0, 0.0, 0.1]
  - [0.0, 1.0, 0.0, 0.0]
  - [0.0, 0.0, 1.0, 0.0]
  - [0.0, 0.0, 0.0, 1.0]
"""


def test_kalibr_camchain_entries(tmp_path):
    (tmp_path / "camchain.yaml").write_text(CAMCHAIN)
    cam0 = read_intrinsics(tmp_path / "camchain.yaml", "cam0")
    cam1 = read_kalibr_intrinsics(tmp_path / "camchain.yaml", "cam1")
    assert cam0.model == "pinhole" and cam0.dist.tolist() == [0.1, -0.2, 0.001, -0.002]
    assert np.array_equal(cam0.K, K) and (cam0.width, cam0.height) == (1280, 720)
    assert cam1.model == "fisheye" and cam1.K[0, 0] == 300.0 and cam1.K[1, 2] == 240.0
    assert read_intrinsics(tmp_path / "camchain.yaml", prefer="cam1").model == "fisheye"
    with pytest.raises(DatasetError, match=r"the camchain has 2 cameras \(cam0, cam1\); choose "
                                           r"one with intrinsics: \{file: camchain.yaml, "
                                           r"camera: cam0\} in rig.yaml"):   # the key to write
        read_intrinsics(tmp_path / "camchain.yaml")
    with pytest.raises(DatasetError, match="camera 'cam7' not in the camchain; it has cam0, cam1"):
        read_intrinsics(tmp_path / "camchain.yaml", "cam7")
    # a single entry (the cam0 block without its key) is read too
    single = "\n".join(line[2:] for line in CAMCHAIN.splitlines()[1:7])
    (tmp_path / "single.yaml").write_text(single + "\n")
    assert np.array_equal(read_intrinsics(tmp_path / "single.yaml").K, K)


def test_kalibr_errors_give_the_line(tmp_path):
    (tmp_path / "fov.yaml").write_text(CAMCHAIN.replace("model: pinhole", "model: fov", 1))
    with pytest.raises(DatasetError, match="cam0.camera_model: camera_model 'fov' is not "
                       "supported") as info:
        read_intrinsics(tmp_path / "fov.yaml", "cam0")
    assert info.value.line == 2
    (tmp_path / "omni.yaml").write_text(CAMCHAIN.replace("model: pinhole", "model: omni", 1))
    with pytest.raises(DatasetError, match=r"intrinsics \[xi, fu, fv, pu, pv\] must be 5 "):
        read_intrinsics(tmp_path / "omni.yaml", "cam0")
    (tmp_path / "short.yaml").write_text(CAMCHAIN.replace("[0.01, 0.02, 0.03, 0.04]", "[0.01]"))
    with pytest.raises(DatasetError, match="distortion_coeffs must be 4 finite numbers") as info:
        read_intrinsics(tmp_path / "short.yaml", "cam1")
    assert info.value.line == 12
    (tmp_path / "skew.yaml").write_text(CAMCHAIN.replace("[1.0, 0.0, 0.0, 0.1]",
                                                         "[2.0, 0.0, 0.0, 0.1]"))
    with pytest.raises(DatasetError, match="T_cn_cnm1 is not a rigid transform") as info:
        read_camchain(tmp_path / "skew.yaml")
    assert info.value.line == 14


def _entries(rng, m):
    cams = []
    for j in range(m):
        if j % 2:
            intr = Intrinsics(K * [[1.1], [1.1], [1]], rng.normal(scale=0.01, size=4), "fisheye",
                              640, 480)
        else:
            intr = Intrinsics(K, np.r_[rng.normal(scale=0.1, size=4), 0.0], "pinhole", 1280, 720)
        T = geometry.random_transforms(rng, translation_scale=0.5) if j else np.eye(4)
        name = ["front", "yes", "0", "left: wide", "rear", "x"][j]  # YAML-special names too
        cams.append(CamchainEntry(name, intr, T, f"/cam{j}/image" if j else None))
    return cams


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(1, 5))
def test_camchain_round_trip(tmp_path_factory, seed, m):
    rng = np.random.default_rng(seed)
    cams = _entries(rng, m)
    path = tmp_path_factory.mktemp("kalibr") / "camchain.yaml"
    write_camchain(path, cams)
    back = read_camchain(path)
    assert [c.name for c in back] == [c.name for c in cams]
    assert [c.rostopic for c in back] == [c.rostopic for c in cams]
    for a, b in zip(cams, back):
        assert np.abs(a.T_ref_cam - b.T_ref_cam).max() < 1e-12
        assert np.array_equal(a.intrinsics.K, b.intrinsics.K)
        assert np.array_equal(a.intrinsics.dist[:4], b.intrinsics.dist)
        assert (a.intrinsics.model, a.intrinsics.width) == (b.intrinsics.model, b.intrinsics.width)


def test_camchain_T_cn_cnm1_direction(tmp_path):
    """cam1 one metre along cam0's x axis: T_c1_c0 maps cam0's origin to x = -1 in cam1."""
    T_ref_c1 = geometry.make_transform(np.eye(3), [1.0, 0.0, 0.0])
    write_camchain(tmp_path / "c.yaml", [CamchainEntry("a", Intrinsics(K), np.eye(4)),
                                         CamchainEntry("b", Intrinsics(K), T_ref_c1)])
    T_cn_cnm1 = np.array(yaml.safe_load((tmp_path / "c.yaml").read_text())["cam1"]["T_cn_cnm1"])
    assert np.array_equal(T_cn_cnm1 @ [0, 0, 0, 1], [-1.0, 0.0, 0.0, 1.0])


def test_camchain_reference_is_the_first_camera(tmp_path, rng):
    cams = _entries(rng, 3)
    shift = geometry.random_transforms(rng)
    moved = [replace(c, T_ref_cam=shift @ c.T_ref_cam) for c in cams]
    write_camchain(tmp_path / "c.yaml", moved)
    back = read_camchain(tmp_path / "c.yaml")
    for a, b in zip(cams, back):
        assert np.abs(a.T_ref_cam - b.T_ref_cam).max() < 1e-12


def test_camchain_writer_rejects_what_kalibr_cannot_hold(tmp_path):
    rational = Intrinsics(K, np.arange(1, 9) * 0.01)
    with pytest.raises(InputError, match="Kalibr radtan holds k1 k2 p1 p2 only"):
        write_camchain(tmp_path / "c.yaml", [CamchainEntry("a", rational, np.eye(4))])
    assert not (tmp_path / "c.yaml").exists()


OPENCV_TEXT = """%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0]
"""


@pytest.mark.parametrize("old, new, expected", [
    ("image_width: 640", "image_width: -640", "cam.yaml:3: image_width: expected a positive "
                                              "integer, got -640"),
    ("image_width: 640", "image_width: 640.5", "image_width: expected a positive integer, got "
                                               "640.5"),
    ("image_width: 640", "image_width: wide", "image_width: expected a positive integer, got "
                                              "'wide'"),
    ("image_height: 480", "image_height: 1e30", "cam.yaml:4: image_height: expected a positive "
                                                "integer"),
    ("image_width: 640", "image_width: 1000000", "image width must be a positive integer of "
                                                 "at most 100000 pixels"),
    ("data: [500.0", "data: [.Nan", "camera matrix must be finite"),
    ("data: [500.0", "data: [-500.0", "focal lengths must be positive"),
    ("data: [500.0", "data: [1e300", "focal lengths must be positive and at most 1e+06 px"),
    ("0.0, 0.0, 1.0]", "0.0, 0.0, 2.0]", "camera matrix must be [[fx, s, cx], [0, fy, cy], "
                                         "[0, 0, 1]]"),
    ("rows: 3", "rows: 300000000", "camera_matrix: OpenCV cannot read this matrix"),
    ("data: [500.0", "data: [.nan, 500.0", "camera_matrix: OpenCV cannot read this matrix"),
    ("camera_matrix: !!opencv-matrix", "camera_matrix: !!opencv-matrix\n   rows: [1\n",
     "OpenCV cannot parse this FileStorage file"),
])
def test_opencv_values_are_range_checked(tmp_path, old, new, expected):
    path = tmp_path / "cam.yaml"
    assert old in OPENCV_TEXT
    path.write_text(OPENCV_TEXT.replace(old, new, 1))
    with pytest.raises(DatasetError) as info:
        read_intrinsics(path)
    assert expected in str(info.value) and str(info.value).startswith(str(path))
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("text, expected", [
    ("camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n"
     "image_width: -640\nimage_height: 480\n",
     "info.yaml:2: image_width: expected a positive integer, got -640"),
    ("camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n"
     "image_width: 640\n", "info.yaml:2: image_width: without image_height: give both"),
    ("camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, .inf]}\n",
     "camera matrix must be finite"),
    ("camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500]}\n",
     "info.yaml:1: camera_matrix: rows x cols (3 x 3) does not match the 5 numbers of data"),
    ("camera_matrix: {rows: 1, cols: 5, data: [500, 0, 320, 0, 500]}\n",
     "info.yaml:1: camera_matrix: expected 9 numbers, got 5"),
    ("cam0: {camera_model: pinhole, intrinsics: [500, 500, 320, 240], distortion_model: none,"
     " resolution: [-640, 480]}\n", "info.yaml:1: cam0.resolution: resolution [width, height] "
                                    "must be positive integers, got [-640.0, 480.0]"),
    ("cam0: {camera_model: pinhole, intrinsics: [500, 500, 320, 240], distortion_model: none,"
     " resolution: [.nan, 480]}\n", "cam0.resolution: resolution [width, height] must be 2 "
                                    "finite numbers"),
    ("cam0: {camera_model: pinhole, intrinsics: [500, .nan, 320, 240], distortion_model: none}\n",
     "cam0.intrinsics: intrinsics [fu, fv, pu, pv] must be 4 finite numbers"),
])
def test_yaml_intrinsics_are_range_checked(tmp_path, text, expected):
    path = tmp_path / "info.yaml"
    path.write_text(text)
    with pytest.raises(DatasetError) as info:
        read_intrinsics(path)
    assert expected in str(info.value), str(info.value)


@pytest.mark.parametrize("kw, expected", [
    ({"width": 0, "height": 480}, "image width must be a positive integer"),
    ({"width": 640, "height": 480.0}, "image height must be a positive integer"),
    ({"width": True, "height": 480}, "image width must be a positive integer"),
    ({"K": np.full((3, 3), np.nan)}, "camera matrix must be finite"),
    ({"K": np.eye(4)}, "camera matrix must be a 3x3 array, got shape (4, 4)"),
    ({"K": K + 1e-3j}, "camera matrix must be real, got complex numbers"),
    ({"K": None}, "camera matrix is None; expected a 3x3 array"),
    ({"dist": ["k1"]}, "distortion coefficients must be an array of real numbers"),
])
def test_intrinsics_object_checks(kw, expected):
    args = {"K": K, **kw}
    with pytest.raises(InputError, match=re.escape(expected)):
        Intrinsics(**args)


@pytest.mark.parametrize("model, n, name", [
    ("pinhole", 0, "plumb_bob"), ("pinhole", 4, "plumb_bob"), ("pinhole", 5, "plumb_bob"),
    ("pinhole", 8, "rational_polynomial"), ("pinhole", 12, "thin_prism"),
    ("pinhole", 14, "tilted"), ("fisheye", 4, "equidistant")])
def test_distortion_model_name_is_the_true_name_and_reads_back(tmp_path, model, n, name):
    from multieye.io.intrinsics_files import DISTORTION_MODELS, distortion_model_name

    dist = np.linspace(-0.1, 0.05, n) * (0.1 if n > 8 else 1)
    intr = Intrinsics(np.array([[400.0, 0, 320], [0, 401, 240], [0, 0, 1]]), dist, model,
                      640, 480)
    assert distortion_model_name(intr) == name
    assert DISTORTION_MODELS[name] == model


@pytest.mark.parametrize("model, dist, ros, written", [
    ("pinhole", [0.1, -0.02, 1e-3, 2e-3], "plumb_bob", [0.1, -0.02, 1e-3, 2e-3, 0.0]),
    ("pinhole", [], "plumb_bob", [0.0] * 5),
    ("pinhole", [0.1, -0.02, 1e-3, 2e-3, 0.01, 0.2, 0.01, 0.001], "rational_polynomial",
     [0.1, -0.02, 1e-3, 2e-3, 0.01, 0.2, 0.01, 0.001]),
    ("fisheye", [0.1, -0.02, 1e-3, 2e-4], "equidistant", [0.1, -0.02, 1e-3, 2e-4])])
def test_camera_info_text_round_trips(tmp_path, model, dist, ros, written):
    from multieye.io.intrinsics_files import camera_info_text, read_camera_info

    K = np.array([[400.5, 0, 320.25], [0, 401.0, 239.75], [0, 0, 1]])
    intr = Intrinsics(K, np.array(dist, dtype=float), model, 640, 480)
    path = tmp_path / "cam.yaml"
    path.write_text(camera_info_text(intr, "front: left"))
    data = yaml.safe_load(path.read_text())
    assert data["camera_name"] == "front: left" and data["distortion_model"] == ros
    assert data["distortion_coefficients"]["data"] == written
    back = read_camera_info(path)
    np.testing.assert_array_equal(back.K, K)
    np.testing.assert_array_equal(back.dist, written)
    assert (back.model, back.width, back.height) == (model, 640, 480)


def test_camera_info_text_names_what_ros_cannot_hold():
    from multieye.io.intrinsics_files import camera_info_text

    K = np.array([[400.0, 0, 320], [0, 401, 240], [0, 0, 1]])
    with pytest.raises(InputError, match="12 coefficients.*thin-prism"):
        camera_info_text(Intrinsics(K, np.full(12, 1e-3), "pinhole", 640, 480), "c")
    with pytest.raises(InputError, match="image size"):
        camera_info_text(Intrinsics(K, np.zeros(5), "pinhole"), "c")


def test_overlaps_in_time_pairs_cameras_within_the_smaller_tolerance():
    from multieye.io.kalibr import overlaps_in_time

    stamps = [np.array([1.0, 2.0]), np.array([9.0, 2.005]), np.array([5.0]), np.array([]),
              np.array([5.02])]
    tol = [0.01, 0.01, 0.05, 0.01, 0.01]
    assert overlaps_in_time(stamps, tol) == [[1], [0], [], [], []]
    tol[4] = 0.05
    assert overlaps_in_time(stamps, tol) == [[1], [0], [4], [], [2]]


def test_camchain_cam_overlaps_round_trip_and_are_checked(tmp_path):
    K = np.array([[400.0, 0, 320], [0, 401, 240], [0, 0, 1]])
    intr = Intrinsics(K, np.zeros(4), "pinhole", 640, 480)
    path = tmp_path / "camchain.yaml"
    write_camchain(path, [CamchainEntry("a", intr, np.eye(4), "/a/image_raw", (1,)),
                          CamchainEntry("b", intr, np.eye(4), None, (0,))])
    back = read_camchain(path)
    assert [(e.rostopic, e.cam_overlaps) for e in back] == [("/a/image_raw", (1,)), (None, (0,))]
    path.write_text(path.read_text().replace("cam_overlaps: [1]", "cam_overlaps: [x]"))
    with pytest.raises(DatasetError, match="cam_overlaps must be a list of camera indices"):
        read_camchain(path)
