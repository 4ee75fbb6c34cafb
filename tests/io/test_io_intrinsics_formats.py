"""Intrinsics files read whole (issues 19, 20, 24): the JSON and YAML layouts of common toolkits
and mrcal's .cameramodel read to the same numbers as OpenCV's own YAML; every key used, ignored
on purpose (the list in docs/rig-yaml.md) or refused naming it; skew and absurd numbers
refused with one line."""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import Intrinsics
from multieye.io.cameramodel import cameramodel_text
from multieye.io.intrinsics_files import IGNORED_KEYS, read_intrinsics

K = np.array([[1052.25, 0.0, 641.75], [0.0, 1049.5, 362.125], [0.0, 0.0, 1.0]])
DIST = np.array([-0.118, 0.179, 1.25e-3, -6.5e-4, -0.0625, 0.0312, 0.0188, -0.0041])
SIZE = (1280, 720)
MRCAL_DATA = Path(__file__).parent / "data" / "mrcal"
DOC = Path(__file__).resolve().parents[2] / "docs" / "rig-yaml.md"
NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")


def _opencv_yaml(path: Path, dist=DIST) -> Path:
    """The reference: OpenCV's own FileStorage YAML, written by cv2."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", SIZE[0])
    fs.write("image_height", SIZE[1])
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", np.asarray(dist, dtype=np.float64).reshape(1, -1))
    fs.release()
    return path


LAYOUTS = {
    "json K/dist (issue 20)": lambda: json.dumps(
        {"K": K.tolist(), "dist": [DIST.tolist()], "width": SIZE[0], "height": SIZE[1]}),
    "json camera_matrix/dist_coeffs": lambda: json.dumps(
        {"camera_matrix": K.tolist(), "dist_coeffs": DIST.tolist(),
         "image_width": SIZE[0], "image_height": SIZE[1], "rms": 0.21}),
    "json mtx/dist (OpenCV tutorial)": lambda: json.dumps(
        {"mtx": K.reshape(-1).tolist(), "dist": [DIST.tolist()], "resolution": list(SIZE),
         "rvecs": [[0.1, 0.2, 0.3]], "tvecs": [[0.0, 0.0, 1.0]]}),
    "json flat fx fy cx cy k1 ...": lambda: json.dumps(
        {"fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2],
         **dict(zip(NAMES, DIST.tolist())), "width": SIZE[0], "height": SIZE[1]}),
    "json ROS 1 CameraInfo message": lambda: json.dumps(
        {"header": {"seq": 3, "stamp": {"secs": 1, "nsecs": 0}, "frame_id": "cam"},
         "height": SIZE[1], "width": SIZE[0], "distortion_model": "rational_polynomial",
         "D": DIST.tolist(), "K": K.reshape(-1).tolist(), "R": np.eye(3).reshape(-1).tolist(),
         "P": np.hstack([K, np.zeros((3, 1))]).reshape(-1).tolist(), "binning_x": 0,
         "binning_y": 0, "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0,
                                 "do_rectify": False}}),
    "yaml ROS 2 CameraInfo message": lambda: (
        "header:\n  stamp: {sec: 1, nanosec: 0}\n  frame_id: cam\n"
        f"height: {SIZE[1]}\nwidth: {SIZE[0]}\ndistortion_model: rational_polynomial\n"
        f"d: {DIST.tolist()}\nk: {K.reshape(-1).tolist()}\nr: {np.eye(3).reshape(-1).tolist()}\n"
        f"p: {np.hstack([K, np.zeros((3, 1))]).reshape(-1).tolist()}\nbinning_x: 1\n"
        "binning_y: 1\nroi: {x_offset: 0, y_offset: 0, height: 720, width: 1280, "
        "do_rectify: false}\n"),
    "yaml ROS camera_info": lambda: (
        f"image_width: {SIZE[0]}\nimage_height: {SIZE[1]}\ncamera_name: front\n"
        f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: {K.reshape(-1).tolist()}\n"
        "distortion_model: rational_polynomial\n"
        f"distortion_coefficients:\n  rows: 1\n  cols: 8\n  data: {DIST.tolist()}\n"
        "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
        "projection_matrix:\n  rows: 3\n  cols: 4\n  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]\n"),
    "yaml ros2 topic echo --once (ends with ---)": lambda: (
        "header:\n  stamp:\n    sec: 1\n    nanosec: 0\n  frame_id: cam\n"
        f"height: {SIZE[1]}\nwidth: {SIZE[0]}\ndistortion_model: rational_polynomial\n"
        "d:\n" + "".join(f"- {v!r}\n" for v in DIST.tolist()) +
        "k:\n" + "".join(f"- {v!r}\n" for v in K.reshape(-1).tolist()) + "---\n"),
    "yaml FileStorage without its %YAML:1.0 line": lambda: (
        f"image_width: {SIZE[0]}\nimage_height: {SIZE[1]}\ncamera_matrix: !!opencv-matrix\n"
        f"   rows: 3\n   cols: 3\n   dt: d\n   data: {K.reshape(-1).tolist()}\n"
        "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 8\n   dt: d\n"
        f"   data: {DIST.tolist()}\n"),
    "json cameraMatrix with image_size [w, h] (calibrateCamera's results)": lambda: json.dumps(
        {"cameraMatrix": K.tolist(), "distCoeffs": [DIST.tolist()], "image_size": list(SIZE)}),
    "mrcal .cameramodel (multieye's)": lambda: cameramodel_text(
        Intrinsics(K, DIST, "pinhole", *SIZE)),
}


@pytest.mark.parametrize("layout", list(LAYOUTS))
def test_every_layout_reads_like_opencv_yaml(tmp_path, layout):
    ref = read_intrinsics(_opencv_yaml(tmp_path / "ref.yaml"))
    suffix = ".cameramodel" if "mrcal" in layout else ".json" if "json" in layout else ".yaml"
    path = tmp_path / f"cam{suffix}"
    path.write_text(LAYOUTS[layout]())
    intr = read_intrinsics(path)
    np.testing.assert_array_equal(intr.K, ref.K)
    np.testing.assert_array_equal(intr.dist, ref.dist)
    assert (intr.model, intr.width, intr.height) == (ref.model, *SIZE)


@pytest.mark.parametrize("suffix", [".json", ".xml"])
def test_opencv_json_and_xml_filestorage_read_like_its_yaml(tmp_path, suffix):
    ref = read_intrinsics(_opencv_yaml(tmp_path / "ref.yaml"))
    intr = read_intrinsics(_opencv_yaml(tmp_path / f"cam{suffix}"))
    if suffix == ".json":
        assert '"type_id": "opencv-matrix"' in (tmp_path / "cam.json").read_text()
    np.testing.assert_array_equal(intr.K, ref.K)
    np.testing.assert_array_equal(intr.dist, ref.dist)


def test_issue_20_json_dist_is_used_and_other_names_are_refused(tmp_path):
    """The issue's case: JSON with K and dist; dist was dropped (0.89 deg / 37 mm wrong)."""
    path = tmp_path / "cam.json"
    path.write_text(json.dumps({"K": K.tolist(), "dist": [-0.118, 0.179, 0.0, 0.0, 0.0]}))
    assert read_intrinsics(path).dist.tolist() == [-0.118, 0.179, 0.0, 0.0, 0.0]
    for name in ("distortion", "dist_coef", "distortions", "coeffs"):
        path.write_text(json.dumps({"K": K.tolist(), name: [-0.118, 0.179, 0.0, 0.0]}))
        with pytest.raises(DatasetError, match=rf"cam\.json:1: {name}: not a key multieye "
                                               "reads or ignores") as info:
            read_intrinsics(path)
        assert "\n" not in str(info.value)


def test_flat_keys_fill_opencv_order_and_fisheye(tmp_path):
    path = tmp_path / "flat.json"
    path.write_text(json.dumps({"fx": 500.0, "fy": 501.0, "cx": 320.0, "cy": 240.0, "k1": 0.1,
                                "k3": 0.01}))
    assert read_intrinsics(path).dist.tolist() == [0.1, 0.0, 0.0, 0.0, 0.01]
    path.write_text(json.dumps({"fx": 500.0, "fy": 501.0, "cx": 320.0, "cy": 240.0, "k1": 0.1,
                                "k6": 0.02}))
    assert read_intrinsics(path).dist.tolist() == [0.1, 0, 0, 0, 0, 0, 0, 0.02]
    path.write_text(json.dumps({"fx": 300.0, "fy": 300.0, "cx": 320.0, "cy": 240.0,
                                "distortion_model": "equidistant", "k1": 0.1, "k4": -0.01}))
    intr = read_intrinsics(path)
    assert intr.model == "fisheye" and intr.dist.tolist() == [0.1, 0.0, 0.0, -0.01]
    path.write_text(json.dumps({"fx": 300.0, "fy": 300.0, "cx": 320.0, "cy": 240.0,
                                "distortion_model": "fisheye", "k1": 0.1, "p1": 0.01}))
    with pytest.raises(DatasetError, match="p1: the fisheye model has k1 k2 k3 k4 only"):
        read_intrinsics(path)
    path.write_text(json.dumps({"fx": 300.0, "fy": 300.0, "cx": 320.0}))
    with pytest.raises(DatasetError, match="cy missing: flat intrinsics need fx, fy, cx and cy"):
        read_intrinsics(path)


def test_opencv_fisheye_model_flag_is_used(tmp_path):
    """OpenCV's calibration sample writes fisheye_model: 1 for a fisheye lens."""
    path = _opencv_yaml(tmp_path / "fish.yaml", DIST[:4])
    path.write_text(path.read_text() + "fisheye_model: 1\n")
    assert read_intrinsics(path).model == "fisheye"
    path.write_text(path.read_text() + "distortion_model: plumb_bob\n")
    with pytest.raises(DatasetError, match="fisheye_model: expected 0 or 1 agreeing with "
                                           "distortion_model"):
        read_intrinsics(path)


# --------------------------------------------------------------------------- refused keys

_KALIBR = ("cam0:\n  camera_model: pinhole\n  intrinsics: [500.0, 501.0, 320.0, 240.0]\n"
           "  distortion_model: radtan\n  distortion_coeffs: [0.1, -0.2, 0.001, -0.002]\n"
           "  resolution: [640, 480]\n")


_ASLAM = ("type: pinhole\nimage_width: 640\nimage_height: 480\nline-delay-nanoseconds: 0\n"
          "intrinsics: {rows: 4, cols: 1, data: [500.0, 501.0, 320.0, 240.0]}\n"
          "distortion:\n  type: radial-tangential\n"
          "  parameters: {rows: 4, cols: 1, data: [0.1, -0.2, 0.001, -0.002]}\n")


@pytest.mark.parametrize("name, text, key, line", [
    ("a.json", json.dumps({"K": K.tolist(), "D": [0.1, 0, 0, 0], "tangential": [0.01, 0.02]},
                          indent=1), "tangential", 25),
    ("b.yaml", "K: [500, 0, 320, 0, 500, 240, 0, 0, 1]\nk_1: 0.1\n", "k_1", 2),
    ("c.yaml", "fx: 500\nfy: 500\ncx: 320\ncy: 240\nk1: 0.1\nq1: 0.2\n", "q1", 6),
    ("d.yaml", "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
               "   dt: d\n   data: [500., 0., 320., 0., 500., 240., 0., 0., 1.]\n"
               "M2: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
               "   data: [1., 0., 0., 0., 1., 0., 0., 0., 1.]\n", "M2", 8),
    ("e.yaml", _KALIBR + "  line_delay: 30.0e-6\n", "cam0.line_delay", 7),
    ("f.cameramodel", "{'lensmodel': 'LENSMODEL_OPENCV4', 'intrinsics': [500, 500, 320, 240, "
                      "0.1, 0, 0, 0], 'imagersize': [640, 480], 'k1_fix': 0}\n", "k1_fix", None),
    ("g.yaml", "camera_matrix: {rows: 3, cols: 3, step: 24, data: [500, 0, 320, 0, 500, 240, 0,"
               " 0, 1]}\n", "camera_matrix.step", 1),
    ("i.yaml", _ASLAM + "T_B_C: [1, 0]\n", "T_B_C", 9),
    ("j.yaml", _ASLAM.replace("  type: radial", "  k1: 0.1\n  type: radial"), "distortion.k1",
     7),
    ("h.json", json.dumps({"K": K.tolist(), "roi": {"x_offset": 0, "y_offset": 0, "height": 0,
                                                    "width": 0, "scale": 2}}), "roi.scale", 1),
])
def test_unknown_keys_are_refused_naming_them(tmp_path, name, text, key, line):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(DatasetError) as info:
        read_intrinsics(path)
    message = str(info.value)
    assert f": {key}: not a key multieye reads or ignores" in message, message
    assert message.startswith(str(path)) and "\n" not in message
    assert info.value.line == line


@pytest.mark.parametrize("text, message", [
    ('{"K": %s, "camera_matrix": %s}' % (K.tolist(), K.tolist()),
     "camera_matrix and K both give the camera matrix; keep one"),
    ('{"K": %s, "fx": 500}' % K.tolist(), "K and fx both give the camera matrix"),
    ('{"K": %s, "D": [0.1, 0, 0, 0], "dist": [0.1, 0, 0, 0]}' % K.tolist(),
     "D and dist both give the distortion"),
    ('{"K": %s, "dist": [0.1, 0, 0, 0], "k1": 0.1}' % K.tolist(),
     "dist and k1 both give the distortion"),
    ('{"K": %s, "K": %s}' % (K.tolist(), K.tolist()), "duplicate key 'K'"),
    ('{"K": %s, "width": 1280, "image_height": 720}' % K.tolist(),
     "width with image_height: write image_width and image_height, or width and height"),
    ('{"K": %s, "binning_x": 2}' % K.tolist(), "binning 2 is not supported"),
    ('{"K": %s, "width": 1280, "height": 720, "roi": {"x_offset": 100, "y_offset": 0, '
     '"height": 400, "width": 600}}' % K.tolist(), "a region of interest"),
    ('{"K": %s,\n "dist": [0.1, 0, 0, 0],,}' % K.tolist(), "cam.json:2: invalid JSON"),
    ('{"K": %s, "dist": {"rows": 1, "cols": 3, "data": [0.1, 0, 0, 0]}}' % K.tolist(),
     "rows x cols (1 x 3) does not match the 4 numbers of data"),
])
def test_ambiguous_or_unusable_keys_are_refused(tmp_path, text, message):
    path = tmp_path / "cam.json"
    path.write_text(text)
    with pytest.raises(DatasetError) as info:
        read_intrinsics(path)
    assert message in str(info.value) and "\n" not in str(info.value), str(info.value)


def _documented_ignored() -> dict[str, tuple[str, ...]]:
    """The per-format lists of ignored metadata keys in docs/rig-yaml.md."""
    text = DOC.read_text()
    rows = re.findall(r"^\| (.+?) \| ((?:`[^`]+`(?:, )?)+) \|$",
                      text.split("Metadata keys ignored on purpose", 1)[1].split("\n\n", 2)[1],
                      re.M)
    return {fmt: tuple(re.findall(r"`([^`]+)`", keys)) for fmt, keys in rows}


def test_ignored_keys_are_the_documented_ones():
    assert _documented_ignored() == IGNORED_KEYS


IGNORED_FILES = {
    "OpenCV FileStorage (OpenCV's calibration samples)": ("cam.yaml", lambda p: _opencv_yaml(p)),
    "ROS camera_info YAML": ("cam.yaml", lambda p: p.write_text(LAYOUTS["yaml ROS camera_info"]())),
    "ROS CameraInfo message (YAML or JSON)": (
        "cam.json", lambda p: p.write_text(LAYOUTS["json ROS 1 CameraInfo message"]())),
    "JSON and YAML layouts": ("cam.json",
                              lambda p: p.write_text(LAYOUTS["json K/dist (issue 20)"]())),
    "Kalibr camchain entry": ("chain.yaml", lambda p: p.write_text(_KALIBR)),
    "aslam_cv camera (ETH Zurich)": ("cam.yaml", lambda p: p.write_text(_ASLAM)),
    "mrcal .cameramodel": ("cam.cameramodel", lambda p: p.write_text(
        LAYOUTS["mrcal .cameramodel (multieye's)"]())),
}


@pytest.mark.parametrize("fmt", list(IGNORED_KEYS))
def test_every_ignored_key_changes_nothing(tmp_path, fmt):
    """A file with every ignored key of its format (odd values of odd types) reads the same."""
    name, make = IGNORED_FILES[fmt]
    path = tmp_path / name
    make(path)
    before = read_intrinsics(path)
    text = path.read_text()
    values = ["[[1, 2], [3, 4]]", "'text'", "7", "{a: 1}", "[0.5]"]
    if name.endswith(".json"):
        extra = {k: [[1, 2], "x", {"a": 1}] for k in IGNORED_KEYS[fmt]}
        data = json.loads(text)
        data.update({k: v for k, v in extra.items() if k not in data})
        path.write_text(json.dumps(data))
    elif name.endswith(".cameramodel"):
        extra = ", ".join(f"'{k}': {values[i % 5]!r}" for i, k in enumerate(IGNORED_KEYS[fmt])
                          if f"'{k}'" not in text)
        path.write_text(text.rstrip().rstrip("}") + extra + "}\n")
    else:
        indent = "  " if fmt.startswith("Kalibr") else ""
        lines = [f"{indent}{k}: {values[i % 5]}" for i, k in enumerate(IGNORED_KEYS[fmt])
                 if f"\n{indent}{k}:" not in "\n" + text]
        path.write_text(text.rstrip("\n") + "\n" + "\n".join(lines) + "\n")
    after = read_intrinsics(path)
    np.testing.assert_array_equal(after.K, before.K)
    np.testing.assert_array_equal(after.dist, before.dist)
    assert (after.model, after.width, after.height) == (before.model, before.width, before.height)


# --------------------------------------------------------------------------- numbers


@pytest.mark.parametrize("change, message", [
    ({"K": [[1052.25, 999999.0, 641.75], [0, 1049.5, 362.125], [0, 0, 1]]},
     "K: camera matrix has skew 999999 px (row 1, column 2); the lens models have no skew"),
    ({"K": [[1052.25, 0.5, 641.75], [0, 1049.5, 362.125], [0, 0, 1]]}, "has skew 0.5 px"),
    ({"fx": 1052.25, "fy": 1049.5, "cx": 641.75, "cy": 362.125, "skew": 3.0}, "has skew 3 px"),
    ({"dist": [1e6, 0.1, 0, 0, 0]}, "dist: distortion coefficient k1 = 1e+06 is beyond any real "
                                    "lens (a radial coefficient's magnitude is at most 10000)"),
    ({"dist": [0.1, 0.1, 5.0, 0, 0]}, "distortion coefficient p1 = 5 is beyond any real lens"),
    ({"dist": [0.1, 0.1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2.0, 0]}, "taux = 2"),
    ({"dist": [0.1, float("nan"), 0, 0]}, "distortion coefficients must be finite"),
    ({"dist": [0.1, float("inf"), 0, 0]}, "distortion coefficients must be finite"),
    ({"K": [[4.0, 0, 641.75], [0, 4.0, 362.125], [0, 0, 1]]},
     "focal length fx = 4 px is below 0.02 x the 1280x720 image's larger side (25.6 px)"),
    ({"K": [[-1052.25, 0, 641.75], [0, 1049.5, 362.125], [0, 0, 1]]},
     "focal lengths must be positive"),
    ({"K": [[1052.25, 0, 6417.5], [0, 1049.5, 362.125], [0, 0, 1]]},
     "principal point cx = 6417.5 px is far outside the 1280x720 image (accepted: -1280 to "
     "2560 px)"),
    ({"K": [[1052.25, 0, 641.75], [0, 1049.5, -900], [0, 0, 1]]}, "principal point cy = -900"),
])
def test_skew_and_absurd_numbers_are_refused_with_one_line(tmp_path, change, message):
    data = {"K": K.tolist(), "dist": DIST[:5].tolist(), "width": SIZE[0], "height": SIZE[1]}
    if "fx" in change:
        del data["K"]
    data.update(change)
    path = tmp_path / "cam.json"
    path.write_text(json.dumps(data))
    with pytest.raises(DatasetError) as info:
        read_intrinsics(path)
    assert message in str(info.value) and "\n" not in str(info.value), str(info.value)
    assert str(info.value).startswith(f"{path}:1: ")


def test_a_rounding_skew_is_accepted_and_skew_is_refused_in_every_format(tmp_path):
    K_skew = K.copy()
    K_skew[0, 1] = 1e-9
    path = tmp_path / "cam.json"
    path.write_text(json.dumps({"K": K_skew.tolist()}))
    assert read_intrinsics(path).K[0, 1] == 1e-9
    K_skew[0, 1] = 999999.0
    with pytest.raises(InputError, match="skew 999999 px"):
        Intrinsics(K_skew)
    fs = cv2.FileStorage(str(tmp_path / "cv.yaml"), cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", K_skew)
    fs.release()
    with pytest.raises(DatasetError, match=r"cv\.yaml:3: camera_matrix: camera matrix has skew"):
        read_intrinsics(tmp_path / "cv.yaml")


def test_kalibr_and_mrcal_absurd_distortion_is_refused(tmp_path):
    (tmp_path / "chain.yaml").write_text(_KALIBR.replace("[0.1, -0.2,", "[1.0e+9, -0.2,"))
    with pytest.raises(DatasetError, match=r"chain\.yaml:5: cam0\.distortion_coeffs: distortion "
                                           "coefficient k1 = 1e\\+09"):
        read_intrinsics(tmp_path / "chain.yaml")
    (tmp_path / "m.cameramodel").write_text(
        "{'lensmodel': 'LENSMODEL_OPENCV4', 'intrinsics': [500, 500, 320, 240, 0.1, 0, 1e12, 0],"
        " 'imagersize': [640, 480]}")
    with pytest.raises(DatasetError, match="p1 = 1e\\+12 is beyond any real lens"):
        read_intrinsics(tmp_path / "m.cameramodel")


# --------------------------------------------------------------------------- mrcal


def test_mrcal_written_fixtures_are_read():
    """Files written by mrcal 2.5.2 (tests/io/data/mrcal/README.md says how)."""
    m = read_intrinsics(MRCAL_DATA / "opencv8.cameramodel")
    np.testing.assert_array_equal(m.K, K)
    np.testing.assert_array_equal(m.dist, DIST)
    assert (m.model, m.width, m.height) == ("pinhole", 1280, 720)
    p = read_intrinsics(MRCAL_DATA / "pinhole.cameramodel")
    assert p.dist.size == 0 and p.K[0, 0] == 500.0 and p.K[1, 2] == 239.25
    # a calibration by mrcal itself, with its optimization_inputs (ignored on purpose)
    c = read_intrinsics(MRCAL_DATA / "calibrated.cameramodel")
    assert "'optimization_inputs': b'" in (MRCAL_DATA / "calibrated.cameramodel").read_text()
    np.testing.assert_array_equal(c.params, [800.0935519, 801.0828919, 639.2933556, 359.0692084,
                                             -0.0971947973, 0.04480220162, 0.0006805356497,
                                             -0.0007316282817])
    with pytest.raises(DatasetError, match="lensmodel: LENSMODEL_CAHVOR has no OpenCV "
                                           "equivalent; multieye reads LENSMODEL_PINHOLE"):
        read_intrinsics(MRCAL_DATA / "cahvor.cameramodel")


@pytest.mark.parametrize("text, message", [
    ("{'lensmodel': 'LENSMODEL_OPENCV5', 'intrinsics': [500, 500, 320, 240, 0.1],"
     " 'imagersize': [640, 480]}", "intrinsics: expected 9 numbers"),
    ("{'lensmodel': 'LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=30_Ny=18_fov_x_deg=150', "
     "'intrinsics': [1, 2, 3, 4], 'imagersize': [640, 480]}", "has no OpenCV equivalent"),
    ("{'lensmodel': 'LENSMODEL_OPENCV4', 'intrinsics': [500, 500, 320, 240, 0, 0, 0, 0],"
     " 'imagersize': [640.5, 480]}", "imagersize: expected [width, height]"),
    ("{'lensmodel': 'LENSMODEL_OPENCV4', 'intrinsics': [500, 500, 320, 240, 0, 0, 0, 0],"
     " 'imagersize': [640, 480], 'lens_model': 'LENSMODEL_OPENCV4'}", "exactly one of lensmodel"),
    ("{'lensmodel': __import__('os').system('true')}", "not a Python dictionary literal"),
    ("[" * 300 + "]" * 300, "not a Python dictionary literal"),
])
def test_bad_cameramodels_are_refused(tmp_path, text, message):
    path = tmp_path / "x.cameramodel"
    path.write_text(text)
    with pytest.raises(DatasetError, match=re.escape(message)) as info:
        read_intrinsics(path)
    assert "\n" not in str(info.value)


def test_mrcal_older_names_are_read(tmp_path):
    path = tmp_path / "old.cameramodel"
    path.write_text("{'distortion_model': 'DISTORTION_OPENCV4', 'intrinsics': [500, 501, 320, "
                    "240, 0.1, -0.05, 0.001, 0.002], 'extrinsics': [0, 0, 0, 0, 0, 0], "
                    "'imagersize': [640, 480]}\n")
    assert read_intrinsics(path).dist.tolist() == [0.1, -0.05, 0.001, 0.002]


@pytest.mark.parametrize("dist", [[], DIST[:4], DIST[:5], DIST, np.r_[DIST, 1e-3, 2e-3, 0, 0]],
                         ids=["pinhole", "opencv4", "opencv5", "opencv8", "opencv12"])
def test_cameramodel_round_trip_is_exact(tmp_path, dist):
    intr = Intrinsics(K, np.asarray(dist, dtype=float), "pinhole", *SIZE)
    path = tmp_path / "c.cameramodel"
    path.write_text(cameramodel_text(intr, note="a\nb"))
    back = read_intrinsics(path)
    np.testing.assert_array_equal(back.K, intr.K)
    np.testing.assert_array_equal(back.dist, intr.dist)
    assert (back.width, back.height) == SIZE


def test_cameramodel_writer_refuses_what_mrcal_cannot_hold():
    with pytest.raises(InputError, match="mrcal has no lens model for OpenCV's fisheye"):
        cameramodel_text(Intrinsics(K, DIST[:4], "fisheye", *SIZE))
    with pytest.raises(InputError, match="tilted sensor"):
        cameramodel_text(Intrinsics(K, np.full(14, 1e-3), "pinhole", *SIZE))
    with pytest.raises(InputError, match="needs the image size"):
        cameramodel_text(Intrinsics(K, DIST))


_MRCAL_CHECK = """
import sys, numpy as np, mrcal
for path in sys.argv[1:]:
    m = mrcal.cameramodel(path)
    lensmodel, values = m.intrinsics()
    print(lensmodel, repr(values.tolist()), m.imagersize().tolist(), m.rt_cam_ref().tolist())
"""


def _mrcal_reads(paths: list[Path]) -> list[str]:
    """mrcal's own reading of ``paths``: in this interpreter when mrcal imports, else in the
    interpreter $MULTIEYE_MRCAL_PYTHON names (mrcal installs on Python 3.12), else skip."""
    try:
        import mrcal  # noqa: F401
        python = None
    except ImportError:
        python = os.environ.get("MULTIEYE_MRCAL_PYTHON")
        if not python:
            pytest.skip("mrcal is not importable and MULTIEYE_MRCAL_PYTHON (a Python with "
                        "mrcal, e.g. 3.12 with pip install --no-deps mrcal numpy numpysane "
                        "scipy gnuplotlib) is not set")
    import sys

    out = subprocess.run([python or sys.executable, "-c", _MRCAL_CHECK, *map(str, paths)],
                         capture_output=True, text=True, timeout=120, check=True)
    return out.stdout.splitlines()


def test_mrcal_reads_what_multieye_writes(tmp_path):
    from multieye.core import geometry

    T_cam_ref = geometry.transform_from_rotvec([0.01, -0.02, 0.03], [-0.2, 0.005, 0.01])
    paths = []
    for n in (0, 4, 5, 8):
        paths.append(tmp_path / f"c{n}.cameramodel")
        paths[-1].write_text(cameramodel_text(Intrinsics(K, DIST[:n], "pinhole", *SIZE),
                                              T_cam_ref))
    for n, line in zip((0, 4, 5, 8), _mrcal_reads(paths)):
        name, values, size, rt = line.split(" ", 1)[0], *re.findall(r"\[[^\]]*\]", line)
        assert name == ("LENSMODEL_PINHOLE" if n == 0 else f"LENSMODEL_OPENCV{n}")
        assert json.loads(values) == [K[0, 0], K[1, 1], K[0, 2], K[1, 2], *DIST[:n]]
        assert json.loads(size) == list(SIZE)
        np.testing.assert_allclose(json.loads(rt), [0.01, -0.02, 0.03, -0.2, 0.005, 0.01],
                                   atol=1e-15)


def test_every_documented_example_reads_to_the_same_camera(tmp_path):
    """docs/rig-yaml.md's complete example files, one per format, each read as written."""
    text = DOC.read_text().split("Complete examples, one per format", 1)[1]
    text = text.split("Image names:", 1)[0]
    blocks = re.findall(r"```(yaml|json|python)\n(.*?)```", text, re.S)
    assert [b[0] for b in blocks] == ["yaml", "yaml", "json", "json", "json", "yaml", "yaml",
                                      "python"]
    for i, (lang, body) in enumerate(blocks):
        path = tmp_path / f"ex{i}.{ {'python': 'cameramodel'}.get(lang, lang)}"
        path.write_text(body)
        intr = read_intrinsics(path)
        np.testing.assert_array_equal(intr.K, K, err_msg=str(i))
        np.testing.assert_array_equal(intr.dist, DIST[:4 if i in (5, 6) else 5])
        assert (intr.model, intr.width, intr.height) == ("pinhole", *SIZE)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.sampled_from([0, 4, 5, 8, 12]))
def test_random_lenses_read_back_exactly_from_every_writable_layout(tmp_path_factory, seed, n):
    rng = np.random.default_rng(seed)
    w, h = int(rng.integers(64, 4000)), int(rng.integers(64, 4000))
    f = rng.uniform(0.3, 3.0) * max(w, h)
    Km = np.array([[f, 0.0, rng.uniform(0, w)], [0.0, f * rng.uniform(0.9, 1.1),
                                                 rng.uniform(0, h)], [0.0, 0.0, 1.0]])
    dist = rng.normal(scale=0.05, size=n)
    intr = Intrinsics(Km, dist, "pinhole", w, h)
    folder = tmp_path_factory.mktemp("rt")
    texts = {"a.json": json.dumps({"K": Km.tolist(), "dist": dist.tolist(), "width": w,
                                   "height": h}),
             "b.json": json.dumps({"fx": Km[0, 0], "fy": Km[1, 1], "cx": Km[0, 2],
                                   "cy": Km[1, 2], **dict(zip(NAMES + ("s1", "s2", "s3", "s4"),
                                                              dist.tolist())),
                                   "width": w, "height": h}),
             "c.cameramodel": cameramodel_text(intr)}
    for name, text in texts.items():
        (folder / name).write_text(text)
        back = read_intrinsics(folder / name)
        np.testing.assert_array_equal(back.K, Km)
        np.testing.assert_array_equal(back.dist, dist)
        assert (back.width, back.height) == (w, h)


def test_aslam_camera_yaml_reads_and_refuses_what_opencv_has_not(tmp_path):
    path = tmp_path / "cam.yaml"
    path.write_text(_ASLAM)
    intr = read_intrinsics(path)
    np.testing.assert_array_equal(intr.K, [[500.0, 0, 320.0], [0, 501.0, 240.0], [0, 0, 1]])
    assert intr.dist.tolist() == [0.1, -0.2, 0.001, -0.002] and (intr.width, intr.height) == (
        640, 480)
    for old, new, message in [
            ("type: radial-tangential", "type: fisheye", "aslam's fisheye is the FOV model"),
            ("line-delay-nanoseconds: 0", "line-delay-nanoseconds: 30000",
             "line-delay-nanoseconds: a rolling shutter (30000 ns per line) is not modelled"),
            ("type: pinhole", "type: unified-projection", "camera type 'unified-projection'"),
            ("{rows: 4, cols: 1, data: [0.1, -0.2, 0.001, -0.002]}",
             "{rows: 2, cols: 1, data: [0.1, -0.2]}",
             "expected 4 parameters for radial-tangential, got 2")]:
        path.write_text(_ASLAM.replace(old, new))
        with pytest.raises(DatasetError, match=re.escape(message)):
            read_intrinsics(path)


def test_eth_zurich_published_camera_files_are_read_whole(shared_data):
    """Every camera file of ethz_handeye/hand_eye_calibration/calib, as published."""
    import yaml

    files = sorted((shared_data / "ethz_handeye" / "hand_eye_calibration" / "calib").glob(
        "*.yaml"))
    cameras = [f for f in files if not f.name.startswith("target_")]
    assert len(cameras) == 7
    for f in cameras:
        raw = yaml.safe_load(f.read_text())
        intr = read_intrinsics(f)
        fu, fv, cu, cv = raw["intrinsics"]["data"]
        np.testing.assert_array_equal(intr.K, [[fu, 0, cu], [0, fv, cv], [0, 0, 1]])
        np.testing.assert_array_equal(intr.dist, raw["distortion"]["parameters"]["data"])
        assert intr.model == ("fisheye" if raw["distortion"]["type"] == "equidistant"
                              else "pinhole"), f.name
        assert (intr.width, intr.height) == (raw["image_width"], raw["image_height"])


@pytest.mark.parametrize("name, text, message", [
    ("a.json", '{"K": [[%s, 0, 1], [0, 1, 1], [0, 0, 1]]}' % ("9" * 400),
     "a.json:1: K: camera matrix must be finite"),
    ("b.json", '{"K": [[%s, 0, 1], [0, 1, 1], [0, 0, 1]]}' % ("9" * 5000), "b.json: invalid JSON"),
    ("c.json", '{"K": [1e400, 0, 1, 0, 1, 1, 0, 0, 1]}', "camera matrix must be finite"),
    ("d.json", '{"K": [NaN, 0, 1, 0, 1, 1, 0, 0, 1]}', "camera matrix must be finite"),
    ("e.json", '{"K": [[[500]], 0, 1, 0, 1, 1, 0, 0, 1]}', "K: expected numbers"),
    ("f.json", '{"K": ' + "[" * 40 + "]" * 40 + "}", "nested deeper than 32"),
    ("g.cameramodel", "{'lensmodel': 'LENSMODEL_PINHOLE', 'intrinsics': [%s, 1, 1, 1], "
                      "'imagersize': [640, 480]}" % ("9" * 400), "intrinsics: "),
    ("h.yaml", "fx: [500, 501]\nfy: 500\ncx: 320\ncy: 240\n", "expected one number each"),
])
def test_hostile_numbers_are_one_line_never_a_traceback(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(DatasetError) as info:
        read_intrinsics(path)
    assert message in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_a_yaml_flow_mapping_with_quotes_is_not_taken_for_json(tmp_path):
    path = tmp_path / "flow.yaml"
    path.write_text('{K: [500, 0, 320, 0, 500, 240, 0, 0, 1], camera_name: "front"}\n')
    assert read_intrinsics(path).K[0, 0] == 500.0


SLAM_CONFIGS = {
    "euroc sensor.yaml": ("""# General sensor definitions.
sensor_type: camera
comment: VI-Sensor cam0 (MT9M034)
T_BS:
  cols: 4
  rows: 4
  data: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
rate_hz: 20
resolution: [752, 480]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375] #fu, fv, cu, cv
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
""", None, "pinhole", [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]),
    "camodocal PINHOLE (VINS)": ("""%YAML:1.0
---
model_type: PINHOLE
camera_name: camera
image_width: 752
image_height: 480
distortion_parameters:
   k1: -2.917e-01
   k2: 8.228e-02
   p1: 5.333e-05
   p2: -1.578e-04
projection_parameters:
   fx: 458.654
   fy: 457.296
   cx: 367.215
   cy: 248.375
""", None, "pinhole", [-2.917e-01, 8.228e-02, 5.333e-05, -1.578e-04]),
    "camodocal MEI (VINS)": ("""%YAML:1.0
---
model_type: MEI
camera_name: camera
image_width: 752
image_height: 480
mirror_parameters:
   xi: 1.8
distortion_parameters:
   k1: -0.2
   k2: 0.1
   p1: 0.0001
   p2: -0.0002
projection_parameters:
   gamma1: 458.654
   gamma2: 457.296
   u0: 367.215
   v0: 248.375
""", None, "unified", [1.8, -0.2, 0.1, 0.0001, -0.0002]),
    "camodocal KANNALA_BRANDT (VINS)": ("""%YAML:1.0
---
model_type: KANNALA_BRANDT
camera_name: camera
image_width: 752
image_height: 480
projection_parameters:
   k2: 0.1
   k3: 0.01
   k4: 0.001
   k5: 0.0001
   mu: 458.654
   mv: 457.296
   u0: 367.215
   v0: 248.375
""", None, "fisheye", [0.1, 0.01, 0.001, 0.0001]),
    "ORB-SLAM2 settings": ("""%YAML:1.0

Camera.fx: 458.654
Camera.fy: 457.296
Camera.cx: 367.215
Camera.cy: 248.375
Camera.k1: -0.28340811
Camera.k2: 0.07395907
Camera.p1: 0.00019359
Camera.p2: 1.76187114e-05
Camera.width: 752
Camera.height: 480
Camera.fps: 20.0
Camera.RGB: 1
ORBextractor.nFeatures: 1000
Viewer.KeyFrameSize: 0.05
""", None, "pinhole", [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.0]),
    "ORB-SLAM3 stereo fisheye settings, right camera": ("""%YAML:1.0
File.version: "1.0"
Camera.type: "KannalaBrandt8"
Camera1.fx: 190.97
Camera1.fy: 190.97
Camera1.cx: 254.93
Camera1.cy: 256.89
Camera1.k1: 0.0034
Camera1.k2: 0.0007
Camera1.k3: -0.0020
Camera1.k4: 0.0002
Camera2.fx: 458.654
Camera2.fy: 457.296
Camera2.cx: 367.215
Camera2.cy: 248.375
Camera2.k1: 0.1
Camera2.k2: 0.01
Camera2.k3: 0.001
Camera2.k4: 0.0001
Camera.width: 752
Camera.height: 480
Stereo.ThDepth: 40.0
""", "Camera2", "fisheye", [0.1, 0.01, 0.001, 0.0001]),
}


@pytest.mark.parametrize("name", list(SLAM_CONFIGS))
def test_slam_tools_camera_settings_are_read(tmp_path, name):
    """EuRoC's sensor.yaml, camodocal's (VINS-Mono/Fusion) and ORB-SLAM's camera settings,
    as those tools ship them: read whole (before: refused, 'sensor_type: not a key ...' or
    'no camera_matrix (or K)'). MEI is the unified model and KANNALA_BRANDT's k2..k5 are
    OpenCV's fisheye k1..k4: the same lens as Kalibr's omni-radtan and pinhole-equidistant."""
    text, camera, model, dist = SLAM_CONFIGS[name]
    (tmp_path / "cam.yaml").write_text(text)
    intr = read_intrinsics(tmp_path / "cam.yaml", camera)
    K = [[458.654, 0, 367.215], [0, 457.296, 248.375], [0, 0, 1]]
    np.testing.assert_array_equal(intr.K, K)
    np.testing.assert_array_equal(intr.dist, dist)
    assert (intr.model, intr.width, intr.height) == (model, 752, 480)
    kalibr = {"unified": ("omni", [dist[0], *np.ravel(K)[[0, 4, 2, 5]]], "radtan", dist[1:]),
              "fisheye": ("pinhole", np.ravel(K)[[0, 4, 2, 5]], "equidistant", dist)}
    if model in kalibr:
        cm, ki, dm, dc = kalibr[model]
        (tmp_path / "k.yaml").write_text(
            f"cam0:\n  camera_model: {cm}\n  intrinsics: {[float(v) for v in ki]}\n"
            f"  distortion_model: {dm}\n  distortion_coeffs: {[float(v) for v in dc]}\n"
            "  resolution: [752, 480]\n")
        same = read_intrinsics(tmp_path / "k.yaml")
        assert same.model == intr.model
        np.testing.assert_array_equal(same.dist, intr.dist)


@pytest.mark.parametrize("change, message", [
    (("ORB-SLAM3 stereo fisheye settings, right camera", None),
     r"holds cameras Camera1, Camera2; choose one with intrinsics: \{file: cam.yaml, "
     r"camera: Camera1\}"),
    (("ORB-SLAM2 settings", "Camera.k1: -0.28340811\n", "Camera.k1: -0.28340811\nCamera.k5: 1\n"),
     r"cam.yaml:8: Camera.k5: not a key multieye reads"),
    (("camodocal MEI (VINS)", "model_type: MEI", "model_type: SCARAMUZZA"),
     r"camodocal model_type 'SCARAMUZZA' is not supported"),
    (("euroc sensor.yaml", "radial-tangential", "fov"), r"distortion_model 'fov' is not "),
])
def test_slam_tools_camera_settings_refused_with_one_line(tmp_path, change, message):
    name, *edit = change
    text, camera, _, _ = SLAM_CONFIGS[name]
    if len(edit) == 2:
        text = text.replace(*edit)
    (tmp_path / "cam.yaml").write_text(text)
    with pytest.raises(DatasetError, match=message) as info:
        read_intrinsics(tmp_path / "cam.yaml")
    assert "\n" not in str(info.value)


def test_an_earlier_runs_calibration_json_gives_a_cameras_lens(tmp_path):
    """docs/rig-yaml.md names multieye's own calibration.json as a source of lenses (the
    wide models too): intrinsics: {file: calibration.json, camera: cam1} reads cam1's lens,
    a rig camera of the same name needs no camera:, and a file of several cameras without
    one is one line naming them (before: 'not an intrinsics file')."""
    from multieye.io.calibration_json import write_calibration
    from multieye.io.calibration_record import (CalibrationRecord, CameraRecord,
                                                IntrinsicsRecord, Residuals)

    lenses = {"cam0": Intrinsics(K, DIST[:5], "pinhole", *SIZE),
              "cam1": Intrinsics(K, np.array([0.9, -0.1, 0.02, 1e-3, -1e-3]), "unified", *SIZE)}
    cams = tuple(CameraRecord(n, np.eye(4), np.eye(4), 10, intrinsics=IntrinsicsRecord(i))
                 for n, i in lenses.items())
    write_calibration(tmp_path / "calibration.json", CalibrationRecord(
        "eye-to-base", "joint", "cam0", np.eye(4), cams, Residuals(0, 0)))
    got = read_intrinsics(tmp_path / "calibration.json", "cam1")
    assert got.model == "unified" and np.array_equal(got.dist, lenses["cam1"].dist)
    assert read_intrinsics(tmp_path / "calibration.json", prefer="cam0").model == "pinhole"
    with pytest.raises(DatasetError, match=r"choose a camera \(cameras with a lens: cam0, cam1\)"
                                           r"; give intrinsics: \{file: calibration.json"):
        read_intrinsics(tmp_path / "calibration.json")


def test_opencv_2s_capitalised_filestorage_names_are_read(tmp_path):
    """OpenCV 2's calibration sample (and the OpenCV book) wrote Camera_Matrix and
    Distortion_Coefficients, with Calibrate_Accuracy: read as camera_matrix and
    distortion_coefficients (before: 'no camera_matrix (or K)')."""
    fs = cv2.FileStorage(str(tmp_path / "out_camera_data.xml"), cv2.FILE_STORAGE_WRITE)
    fs.write("Calibrate_Accuracy", 0.4)
    fs.write("Camera_Matrix", K)
    fs.write("Distortion_Coefficients", DIST[:5].reshape(-1, 1))
    fs.release()
    intr = read_intrinsics(tmp_path / "out_camera_data.xml")
    np.testing.assert_array_equal(intr.K, K)
    np.testing.assert_array_equal(intr.dist, DIST[:5])
