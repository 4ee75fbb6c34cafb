"""Every lens model through every file multieye writes, read back through rig.yaml's
``intrinsics:`` (issue 33, item 1): the same lens to the last digit (parameters equal, the
projection of the same rays within 1e-9 px, the model's name and the image size kept), or a
refusal naming the format; and the hostile inputs a tester would try on the readers (other
tools' conventions, booleans and strings for numbers, nested lists, ambiguous camera
choices, BoofCV's plain pinhole and Kannala-Brandt files)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import Intrinsics, lens_model
from multieye.core.lens import project_points
from multieye.io import read_intrinsics, write_calibration, write_camchain
from multieye.io.calibration_json import (CalibrationRecord, CameraRecord, IntrinsicsRecord,
                                          Residuals)
from multieye.io.cameramodel import cameramodel_text
from multieye.io.intrinsics_files import camera_info_text, write_intrinsics_file
from multieye.io.kalibr import CamchainEntry
from multieye.io.rig import load_rig, read_camera_intrinsics


def _K(fx, fy, cx, cy):
    return [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]


#: Lenses with the odd values a tester picks: fx != fy, odd image sizes, principal points
#: outside the image, the models' bounds (alpha 0 and 1, beta near 0, xi 0, negative and > 1),
#: numbers at the ends of the double range, no image size.
LENSES = {
    "pinhole-0": Intrinsics(_K(500.123456789, 480.987654321, 321.1, 239.7), [], "pinhole",
                            641, 479),
    "radtan4": Intrinsics(_K(500.1, 499.3, 320.3, 240.9), [-0.2, 0.05, 1e-3, -2e-4],
                          "pinhole", 640, 480),
    "radtan5": Intrinsics(_K(500.1, 499.3, 320.3, 240.9), [-0.2, 0.05, 1e-3, -2e-4, 0.01],
                          "pinhole", 640, 480),
    "rational": Intrinsics(_K(500.1, 499.3, 320.3, 240.9),
                           [-0.2, 0.05, 1e-3, -2e-4, 0.01, 0.1, 0.02, 0.003], "pinhole",
                           640, 480),
    "thin-prism": Intrinsics(_K(500.1, 499.3, 320.3, 240.9),
                             [-0.2, 0.05, 1e-3, -2e-4, 0.01, 0.1, 0.02, 0.003, 1e-3, 2e-4,
                              -1e-3, 3e-4], "pinhole", 640, 480),
    "tilted": Intrinsics(_K(500.1, 499.3, 320.3, 240.9),
                         [-0.2, 0.05, 1e-3, -2e-4, 0.01, 0.1, 0.02, 0.003, 1e-3, 2e-4, -1e-3,
                          3e-4, 1e-3, -2e-3], "pinhole", 640, 480),
    "tiny-numbers": Intrinsics(_K(500.1, 499.3, 320.3, 240.9),
                               [1e-300, -3.3e-17, 1e-20, 5e-324], "pinhole", 640, 480),
    "fisheye": Intrinsics(_K(300.5, 301.25, 639.5, 359.5), [0.01, -0.002, 3e-4, -1e-5],
                          "fisheye", 1279, 719),
    "unified": Intrinsics(_K(560.25, 559.75, 321.5, 238.125),
                          [0.9, -0.05, 0.01, 0.0005, -0.0003], "unified", 640, 480),
    "unified-xi0": Intrinsics(_K(560.25, 559.75, 321.5, 238.125),
                              [0.0, -0.05, 0.01, 0.0005, -0.0003], "unified", 640, 480),
    "unified-xi>1": Intrinsics(_K(960.25, 959.75, 321.5, 238.125), [2.1, 0, 0, 0, 0],
                               "unified", 641, 481),
    "ds": Intrinsics(_K(158.28, 158.27, 254.96, 256.88), [-0.172, 0.593], "double-sphere",
                     512, 512),
    "ds-alpha0": Intrinsics(_K(158.28, 158.27, 254.96, 256.88), [-0.172, 0.0],
                            "double-sphere", 511, 513),
    "ds-alpha1": Intrinsics(_K(158.28, 158.27, 254.96, 256.88), [0.3, 1.0], "double-sphere",
                            512, 512),
    "eucm-no-size": Intrinsics(_K(300.5, 300.25, 320, 240), [0.6, 1.1], "eucm"),
    "eucm-alpha0": Intrinsics(_K(300.5, 300.25, 320, 240), [0.0, 1.1], "eucm", 640, 480),
    "eucm-alpha1": Intrinsics(_K(300.5, 300.25, 320, 240), [1.0, 1.1], "eucm", 640, 480),
    "eucm-beta-tiny": Intrinsics(_K(300.5, 300.25, 320, 240), [0.6, 1e-12], "eucm", 640, 480),
    "eucm-pp-outside": Intrinsics(_K(300.5, 300.25, -200.3, 700.7), [0.6, 1.1], "eucm", 640,
                                  480),
    # a skew small enough for Intrinsics to take (the models ignore it, as OpenCV does)
    "radtan4-skew": Intrinsics([[500.1, 1e-5, 320.3], [0.0, 499.3, 240.9], [0.0, 0.0, 1.0]],
                               [-0.2, 0.05, 1e-3, -2e-4], "pinhole", 640, 480),
}


def _record(lens):
    cam = CameraRecord("cam0", X=np.eye(4), T_ref_cam=np.eye(4), measurements_used=3,
                       intrinsics=IntrinsicsRecord(lens, True))
    return CalibrationRecord("eye-to-base", "joint", "cam0", np.eye(4), (cam,),
                             Residuals(0.01, 1e-4))


#: Each file multieye writes a lens in: name -> (file name, writer).
WRITERS = {
    "OUT/intrinsics": ("lens.yaml", write_intrinsics_file),
    "camchain": ("camchain.yaml",
                 lambda p, lens: write_camchain(p, [CamchainEntry("cam0", lens, np.eye(4))])),
    "calibration.json": ("calibration.json", lambda p, lens: write_calibration(p, _record(lens))),
    "camera_info": ("camera_info.yaml", lambda p, lens: p.write_text(camera_info_text(lens, "c"))),
    "mrcal": ("lens.cameramodel", lambda p, lens: p.write_text(cameramodel_text(lens))),
}
#: (format, lens) -> the refusal expected: what the format cannot hold.
REFUSED = {
    **{("camchain", k): "Kalibr radtan holds k1 k2 p1 p2 only"
       for k in ("radtan5", "rational", "thin-prism", "tilted")},
    **{("camera_info", k): "ROS camera_info names plumb_bob, rational_polynomial"
       for k in ("thin-prism", "tilted")},
    **{("camera_info", k): f"ROS camera_info has no {LENSES[k].model} lens model"
       for k in LENSES if LENSES[k].model in ("unified", "double-sphere", "eucm")
       and LENSES[k].width},
    ("camera_info", "eucm-no-size"): "ROS camera_info has no eucm lens model",
    ("mrcal", "tilted"): "mrcal has no lens model for a tilted sensor",
    ("mrcal", "radtan4-skew"): "mrcal's lens models have no skew; camera matrix has skew 1e-05",
    ("camchain", "radtan4-skew"): "Kalibr's camera models have no skew",
    ("mrcal", "fisheye"): "mrcal has no lens model for OpenCV's fisheye",
    **{("mrcal", k): f"mrcal has no lens model for the {LENSES[k].model} lens"
       for k in LENSES if LENSES[k].model in ("unified", "double-sphere", "eucm")},
}
#: (format, lens) -> the same lens in the form the format states it: ROS's plumb_bob has 5
#: coefficients (k3 = 0 added), Kalibr's radtan 4.
SAME_LENS_OTHER_FORM = {
    ("camera_info", "pinhole-0"): np.zeros(5),
    ("camera_info", "radtan4"): [-0.2, 0.05, 1e-3, -2e-4, 0.0],
    ("camera_info", "tiny-numbers"): [1e-300, -3.3e-17, 1e-20, 5e-324, 0.0],
    ("camera_info", "radtan4-skew"): [-0.2, 0.05, 1e-3, -2e-4, 0.0],
}


def _rays(n=500, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1)[:, None]


def _through_rig(tmp_path: Path, file: str, camera: str | None = None) -> Intrinsics:
    """The lens rig.yaml's ``intrinsics:`` gives a camera named ``front`` from ``file``."""
    spec = file if camera is None else f"{{file: {file}, camera: {camera}}}"
    (tmp_path / "imgs").mkdir(exist_ok=True)
    (tmp_path / "m.csv").touch()
    (tmp_path / "rig.yaml").write_text(
        "setup: eye-to-base\ntarget: {type: chessboard, cols: 9, rows: 6, spacing: 0.02}\n"
        f"mocap: {{file: m.csv}}\ncameras:\n  front:\n    intrinsics: {spec}\n"
        "    images: imgs\n")
    return read_camera_intrinsics(load_rig(tmp_path / "rig.yaml").cameras["front"])


@pytest.mark.parametrize("fmt", WRITERS)
@pytest.mark.parametrize("name", LENSES)
def test_every_lens_through_every_format_and_rig_yaml(tmp_path, fmt, name):
    lens = LENSES[name]
    file, write = WRITERS[fmt]
    needs_size = fmt in ("camera_info", "mrcal") and lens.width is None
    expected = REFUSED.get((fmt, name), "needs the image size" if needs_size else None)
    if expected is not None:
        with pytest.raises(InputError, match=expected):
            write(tmp_path / file, lens)
        assert not (tmp_path / file).exists()
        return
    write(tmp_path / file, lens)
    back = _through_rig(tmp_path, file, "cam0" if fmt == "calibration.json" else None)
    dist = np.asarray(SAME_LENS_OTHER_FORM.get((fmt, name), lens.dist), dtype=float)
    assert back.model == lens.model
    if (fmt, name) not in SAME_LENS_OTHER_FORM:
        assert lens_model(back) == lens_model(lens)
    assert (back.width, back.height) == (lens.width, lens.height)
    np.testing.assert_array_equal(back.K, lens.K)
    np.testing.assert_array_equal(back.dist, dist)
    rays = _rays()
    a, b = project_points(rays, lens), project_points(rays, back)
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-9)



def test_camera_info_says_which_camera_s_model_it_cannot_name_and_rig_yaml_keeps_it(tmp_path):
    """ROS's plumb_bob holds five coefficients: a pinhole-radtan4 lens (k1 k2 p1 p2) is
    written with k3 = 0, the same projection, and read back alone it is pinhole-radtan (k3
    freed when refined). The file's first line names the camera and says so; with rig.yaml's
    ``model: pinhole-radtan4`` it reads back as that model, the same numbers."""
    from multieye.pipeline.rig_model import build_rig_model

    (tmp_path / "ci.yaml").write_text(camera_info_text(LENSES["radtan4"], "front left"))
    assert (tmp_path / "ci.yaml").read_text().splitlines()[0] == (
        '# "front left": pinhole-radtan4 lens written as ROS\'s plumb_bob with k3 = 0 (the '
        "same projection); read back it is pinhole-radtan, pinhole-radtan4 with rig.yaml's "
        "model: pinhole-radtan4")
    assert lens_model(_through_rig(tmp_path, "ci.yaml")) == "pinhole-radtan"
    rig = tmp_path / "rig.yaml"
    rig.write_text(rig.read_text().replace("    images: imgs", "    model: pinhole-radtan4\n"
                                           "    images: imgs"))
    back = build_rig_model(load_rig(rig)).lenses["front"]
    assert lens_model(back) == "pinhole-radtan4"
    np.testing.assert_array_equal(back.params, LENSES["radtan4"].params)
    for name in ("pinhole-0", "radtan5", "rational", "fisheye"):     # named as they are
        assert not camera_info_text(LENSES[name], "c").startswith("#")


# --------------------------------------------------------------------------- Kalibr

OMNI = """cam0:
  camera_model: omni
  intrinsics: {intrinsics}
  distortion_model: radtan
  distortion_coeffs: {coeffs}
  resolution: {resolution}
"""


@pytest.mark.parametrize("intrinsics, coeffs, resolution, message", [
    # YAML 1.1 reads yes / true as booleans: not a mirror offset of 1, not a 1-pixel image
    ("[yes, 461.6, 460.3, 366.3, 249.2]", "[0, 0, 0, 0]", "[752, 480]",
     r"cam0.intrinsics: intrinsics \[xi, fu, fv, pu, pv\] must be numbers, got True"),
    ("[1.2, 461.6, 460.3, 366.3, 249.2]", "[0, false, 0, 0]", "[752, 480]",
     "cam0.distortion_coeffs: distortion_coeffs must be numbers, got False"),
    ("[1.2, 461.6, 460.3, 366.3, 249.2]", "[0, 0, 0, 0]", "[true, 480]",
     r"cam0.resolution: resolution \[width, height\] must be numbers, got True"),
    # five numbers nested: refused with the line, not a traceback
    ("[[1.2, 461.6], [460.3, 366.3, 249.2]]", "[0, 0, 0, 0]", "[752, 480]",
     r"cam0.intrinsics: intrinsics \[xi, fu, fv, pu, pv\] must be a flat list"),
    ("[[1.2, 461.6, 460.3, 366.3, 249.2]]", "[0, 0, 0, 0]", "[752, 480]",
     r"cam0.intrinsics: intrinsics \[xi, fu, fv, pu, pv\] must be a flat list"),
])
def test_kalibr_refuses_booleans_and_nested_lists_for_numbers(tmp_path, intrinsics, coeffs,
                                                              resolution, message):
    (tmp_path / "c.yaml").write_text(OMNI.format(intrinsics=intrinsics, coeffs=coeffs,
                                                 resolution=resolution))
    with pytest.raises(DatasetError, match=message):
        read_intrinsics(tmp_path / "c.yaml")


def test_kalibr_numbers_in_any_yaml_spelling_read_as_the_numbers(tmp_path):
    """Scientific notation without a dot (a string to YAML 1.1), quoted numbers, integers."""
    (tmp_path / "c.yaml").write_text(OMNI.format(
        intrinsics="[1, 461, '460.3', 3.663e2, 249.2]", coeffs="[-1e-2, 2E-3, '1e-4', -2e-4]",
        resolution="[752, 480]"))
    lens = read_intrinsics(tmp_path / "c.yaml")
    np.testing.assert_array_equal(lens.params, [461, 460.3, 366.3, 249.2, 1, -1e-2, 2e-3, 1e-4,
                                                -2e-4])


@pytest.mark.parametrize("dmodel", ["radtan", "equidistant"])
def test_kalibr_distortion_named_without_its_coefficients_is_refused(tmp_path, dmodel):
    """Kalibr itself needs distortion_coeffs with radtan or equidistant; without them the
    lens is not silently undistorted."""
    (tmp_path / "c.yaml").write_text(f"cam0:\n  camera_model: pinhole\n  intrinsics: [461, 460, "
                                     f"366, 249]\n  distortion_model: {dmodel}\n")
    with pytest.raises(DatasetError, match=f"cam0: missing key 'distortion_coeffs' \\(the 4 "
                                           f"coefficients of {dmodel}\\)"):
        read_intrinsics(tmp_path / "c.yaml")


SWAPPED = """cam0:
  camera_name: cam1
  camera_model: ds
  intrinsics: [-0.2, 0.6, 350, 351, 320, 240]
  distortion_model: none
cam1:
  camera_name: cam0
  camera_model: eucm
  intrinsics: [0.6, 1.1, 300, 301, 320, 240]
  distortion_model: none
  T_cn_cnm1: [[1, 0, 0, 0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
"""


def test_camchain_choice_that_is_one_entry_s_key_and_another_s_name_is_refused(tmp_path):
    """multieye writes a rig whose cameras are named cam1, cam0 (in that order) as keys cam0,
    cam1 with the names swapped: ``camera: cam1`` could mean either; not silently one."""
    (tmp_path / "chain.yaml").write_text(SWAPPED)
    for choice in ("cam0", "cam1"):
        with pytest.raises(DatasetError, match=f"camera {choice!r} is ambiguous in this "
                                               "camchain"):
            read_intrinsics(tmp_path / "chain.yaml", choice)
    with pytest.raises(DatasetError, match="'cam1' is ambiguous"):
        _through_rig(tmp_path, "chain.yaml", "cam1")


def test_camchain_camera_chosen_by_name_or_key_with_anchors_and_extra_chain_keys(tmp_path):
    (tmp_path / "chain.yaml").write_text("""cam0: &base
  camera_name: left
  camera_model: omni
  intrinsics: [0.9, 461.5, 460.5, 366.5, 249.5]
  distortion_model: radtan
  distortion_coeffs: [-0.1, 0.01, 1.0e-4, -2.0e-4]
  resolution: [753, 481]
  T_cam_imu: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
  timeshift_cam_imu: 0.001
  cam_overlaps: [1]
  rostopic: /left/image_raw
cam1:
  <<: *base
  camera_name: right
  intrinsics: [1.1, 462.5, 461.5, 367.5, 250.5]
  T_cn_cnm1: [[1, 0, 0, -0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
""")
    for choice, xi in (("left", 0.9), ("cam0", 0.9), ("right", 1.1), ("cam1", 1.1)):
        lens = _through_rig(tmp_path, "chain.yaml", choice)
        assert lens.model == "unified" and lens.dist[0] == xi
        assert (lens.width, lens.height) == (753, 481)
        np.testing.assert_array_equal(lens.dist[1:], [-0.1, 0.01, 1e-4, -2e-4])


def test_rig_camera_takes_the_camchain_entry_of_its_own_name_first(tmp_path):
    """Without ``camera:``, a rig camera named cam1 takes the entry multieye wrote for it
    (``camera_name: cam1``, key cam0), not the entry keyed cam1 of the camera named cam0."""
    (tmp_path / "chain.yaml").write_text(SWAPPED)
    (tmp_path / "imgs").mkdir()
    (tmp_path / "m.csv").touch()
    (tmp_path / "rig.yaml").write_text(
        "setup: eye-to-base\ntarget: {type: chessboard, cols: 9, rows: 6, spacing: 0.02}\n"
        "mocap: {file: m.csv}\ncameras:\n"
        "  cam1: {intrinsics: chain.yaml, images: imgs}\n"
        "  cam0: {intrinsics: chain.yaml, images: imgs}\n")
    rig = load_rig(tmp_path / "rig.yaml")
    assert read_camera_intrinsics(rig.cameras["cam1"]).model == "double-sphere"
    assert read_camera_intrinsics(rig.cameras["cam0"]).model == "eucm"


# --------------------------------------------------------------------------- camodocal, EuRoC

MEI = """model_type: MEI
camera_name: camera
image_width: 752
image_height: 480
mirror_parameters:
   xi: {xi}
distortion_parameters:
   k1: -0.1
   k2: 0.02
   p1: 1e-4
   p2: -2.0e-4
projection_parameters:
   gamma1: 900.5
   gamma2: 899.5
   u0: 376.5
   v0: 240.5
"""


@pytest.mark.parametrize("xi, expected", [
    ("1.5", 1.5), ("1", 1.0), ("'1.5'", 1.5), ("1.5e0", 1.5),
    ("true", "mirror_parameters.xi: expected 1 finite numbers, got True"),
])
def test_camodocal_mei_numbers_and_booleans(tmp_path, xi, expected):
    for header in ("", "%YAML:1.0\n---\n"):       # PyYAML and OpenCV's FileStorage
        if header and xi in ("'1.5'", "true"):
            continue                               # FileStorage: a string, not a number
        (tmp_path / "c.yaml").write_text(header + MEI.format(xi=xi))
        if isinstance(expected, str):
            with pytest.raises(DatasetError, match=expected):
                read_intrinsics(tmp_path / "c.yaml")
            continue
        lens = read_intrinsics(tmp_path / "c.yaml")
        assert lens.model == "unified" and (lens.width, lens.height) == (752, 480)
        np.testing.assert_array_equal(lens.params, [900.5, 899.5, 376.5, 240.5, expected, -0.1,
                                                    0.02, 1e-4, -2e-4])


def test_euroc_sensor_yaml_refuses_a_boolean_for_a_number(tmp_path):
    (tmp_path / "sensor.yaml").write_text(
        "sensor_type: camera\ncamera_model: pinhole\nintrinsics: [458.6, 457.3, 367.2, yes]\n"
        "distortion_model: radial-tangential\ndistortion_coefficients: [-0.28, 0.07, 2e-4, "
        "1.8e-05]\nresolution: [752, 480]\n")
    with pytest.raises(DatasetError, match="sensor.yaml:3: intrinsics: expected 4 finite "
                                           "numbers, got"):
        read_intrinsics(tmp_path / "sensor.yaml")


# --------------------------------------------------------------------------- BoofCV

BOOF_PINHOLE = """pinhole:
  fx: 398.77
  fy: 398.76
  cx: 319.17
  cy: 319.71
  width: 640
  height: 720
  skew: 0.0
"""


def _boofcv_kb(x, symmetric, radial=(), tangent=(), skew=0.0):
    """BoofCV's CameraKannalaBrandt projection (KannalaBrandtStoP_F64, written from its
    documented model): theta from the optical axis, r = sum symmetric[i] theta^(2i+1),
    asymmetric terms zero here."""
    theta = np.arccos(x[:, 2] / np.linalg.norm(x, axis=1))
    r = sum(c * theta ** (2 * i + 1) for i, c in enumerate(symmetric))
    phi = np.arctan2(x[:, 1], x[:, 0])
    dx, dy = r * np.cos(phi), r * np.sin(phi)
    return np.stack([398.77 * dx + skew * dy + 319.17, 398.76 * dy + 319.71], axis=1)


@pytest.mark.parametrize("symmetric", [[1.0, 0.01, -0.002, 0.0003, -1.0e-5], [1.0, 0.4],
                                       [0.98, 0.01, -0.002, 0.0003, -1.0e-5, 0.0]])
def test_boofcv_symmetric_kannala_brandt_is_the_fisheye_model(tmp_path, symmetric):
    """BoofCV's kannala_brandt without asymmetric terms projects as OpenCV's fisheye with
    fx, fy times symmetric[0] and k_i = symmetric[i] / symmetric[0]."""
    (tmp_path / "kb.yaml").write_text(BOOF_PINHOLE + "model: kannala_brandt\n"
                                      f"symmetric: {symmetric}\nradial: []\nradial_trig: []\n"
                                      "tangent: [0.0, 0.0]\ntangent_trig: [0.1, 0.2, 0.3, 0.4]\n"
                                      "version: 0\n")
    lens = read_intrinsics(tmp_path / "kb.yaml")
    assert lens.model == "fisheye" and (lens.width, lens.height) == (640, 720)
    rays = _rays()
    rays = rays[rays[:, 2] > 0.2]
    np.testing.assert_allclose(project_points(rays, lens), _boofcv_kb(rays, symmetric),
                               rtol=0, atol=1e-9)


@pytest.mark.parametrize("extra, message", [
    ("symmetric: [1.0, 0.4]\nradial: [0.001]\nradial_trig: [0.1, 0.2, 0.3, 0.4]\n",
     "radial: BoofCV's asymmetric Kannala-Brandt terms"),
    ("symmetric: [1.0, 0.4]\ntangent: [0.0, 0.002]\ntangent_trig: [0.1, 0.2, 0.3, 0.4]\n",
     "tangent: BoofCV's asymmetric Kannala-Brandt terms"),
    ("symmetric: [1.0, 0.1, 0.1, 0.1, 0.1, 0.01]\n", "symmetric: 6 symmetric coefficients"),
    ("symmetric: [0.0, 0.4]\n", "symmetric: the first symmetric coefficient"),
    ("symmetric: []\n", "symmetric: the first symmetric coefficient"),
    ("symmetric: [1.0, 0.4]\nradial_tangential: {t1: 0.0}\n",
     "radial_tangential: radial_tangential belongs to pinhole_radial_tangential"),
    ("symmetric: [1.0, 0.4]\nmirror_offset: 1.0\n",
     "mirror_offset: mirror_offset belongs to omnidirectional_universal, not kannala_brandt"),
])
def test_boofcv_kannala_brandt_multieye_cannot_hold_is_refused_by_name(tmp_path, extra,
                                                                        message):
    (tmp_path / "kb.yaml").write_text(BOOF_PINHOLE + "model: kannala_brandt\n" + extra)
    with pytest.raises(DatasetError, match=message):
        read_intrinsics(tmp_path / "kb.yaml")


def test_boofcv_plain_pinhole_is_a_pinhole_without_distortion(tmp_path):
    (tmp_path / "p.yaml").write_text(BOOF_PINHOLE + "model: pinhole\nversion: 0\n")
    lens = read_intrinsics(tmp_path / "p.yaml")
    assert lens.model == "pinhole" and lens.dist.size == 0
    np.testing.assert_array_equal(lens.params, [398.77, 398.76, 319.17, 319.71])
    (tmp_path / "p.yaml").write_text(BOOF_PINHOLE + "model: pinhole\nradial_tangential: "
                                     "{radial: [0.1]}\n")
    with pytest.raises(DatasetError, match="radial_tangential belongs to pinhole_radial_tang"):
        read_intrinsics(tmp_path / "p.yaml")


def test_boofcv_numbers_written_as_text_read_as_numbers(tmp_path):
    """YAML 1.1 (PyYAML) reads -2e-1 (an exponent without a dot) as text."""
    (tmp_path / "o.yaml").write_text(
        BOOF_PINHOLE.replace("398.77", "3.9877e2") + "model: omnidirectional_universal\n"
        "mirror_offset: '1.13'\nradial_tangential:\n  radial: [-2e-1, 1e-2]\n  t1: 1e-4\n"
        "  t2: 0\n")
    lens = read_intrinsics(tmp_path / "o.yaml")
    np.testing.assert_array_equal(lens.params, [398.77, 398.76, 319.17, 319.71, 1.13, -0.2,
                                                0.01, 1e-4, 0.0])
    (tmp_path / "o.yaml").write_text(BOOF_PINHOLE + "model: omnidirectional_universal\n"
                                     "mirror_offset: 'big'\n")
    with pytest.raises(DatasetError, match="mirror_offset: expected a finite number, got 'big'"):
        read_intrinsics(tmp_path / "o.yaml")


# --------------------------------------------------------------------------- calibration.json


@pytest.mark.parametrize("change, message", [
    ({"model": "pinhole-radtan4", "distortion": [0.1] * 8},
     "intrinsics.model pinhole-radtan4 does not match its 8 distortion numbers"),
    ({"model": "fisheye", "distortion": [0.1] * 8},
     "intrinsics.model fisheye does not match its 8 distortion numbers"),
    ({"model": "bogus", "distortion": [0.1] * 4},
     "intrinsics.model 'bogus' is not one of pinhole-radtan, pinhole-radtan4"),
    ({"distortion": [True, -0.05, 0.01, 0.0005, -0.0003]},
     "intrinsics.distortion must be numbers, got True"),
    ({"K": [[560.25, False, 321.5], [0, 559.75, 238.125], [0, 0, 1]]},
     "intrinsics.K must be numbers, got False"),
    ({"image_size": [640, None]}, r"intrinsics.image_size must be \[width, height\] or null"),
])
def test_calibration_json_lens_whose_model_or_numbers_do_not_hold_is_refused(tmp_path, change,
                                                                             message):
    write_calibration(tmp_path / "calibration.json", _record(LENSES["unified"]))
    data = json.loads((tmp_path / "calibration.json").read_text())
    data["cameras"]["cam0"]["intrinsics"].update(change)
    (tmp_path / "calibration.json").write_text(json.dumps(data))
    with pytest.raises(DatasetError, match=message):
        read_intrinsics(tmp_path / "calibration.json", "cam0")


# --------------------------------------------------------------------------- what Kalibr loads


def test_camchain_leaves_out_by_name_the_lenses_kalibr_refuses_to_load(tmp_path):
    """Kalibr's CameraParameters (kalibr_common/ConfigReader.py) refuses a camchain entry
    without resolution, with a principal point below 0, or with ds / eucm alpha = 1 (it needs
    0 <= alpha < 1): such a camera is named in the note, not written for Kalibr to fail on."""
    from multieye.outputs.export import kalibr_chain

    names = ["eucm-no-size", "eucm-pp-outside", "ds-alpha1", "eucm-alpha1", "ds", "unified",
             "fisheye", "radtan4"]
    cams = tuple(CameraRecord(n, X=np.eye(4), T_ref_cam=np.eye(4), measurements_used=3,
                              intrinsics=IntrinsicsRecord(LENSES[n], True)) for n in names)
    rec = CalibrationRecord("eye-to-base", "joint", names[0], np.eye(4), cams,
                            Residuals(0.01, 1e-4))
    kept, left = kalibr_chain(rec, {n: LENSES[n] for n in names}, {}, None)
    assert [e.name for e in kept] == ["ds", "unified", "fisheye", "radtan4"]
    assert left == [
        "eucm-no-size (Kalibr's camchain needs the image size (resolution), which these "
        "intrinsics do not know)",
        "eucm-pp-outside (Kalibr refuses a principal point below 0: cx = -200.3)",
        "ds-alpha1, eucm-alpha1 (Kalibr's ds and eucm need alpha < 1, this lens has alpha = 1)"]


def test_intrinsics_file_of_a_lens_kalibr_refuses_says_so_and_reads_back(tmp_path):
    """OUT/intrinsics holds every estimated lens: one Kalibr would refuse is still written
    (multieye reads it back, the same lens) with a comment saying why Kalibr refuses it."""
    write_intrinsics_file(tmp_path / "c.yaml", LENSES["ds-alpha1"])
    text = (tmp_path / "c.yaml").read_text()
    assert "# Kalibr refuses this file: Kalibr's ds and eucm need alpha < 1" in text
    np.testing.assert_array_equal(read_intrinsics(tmp_path / "c.yaml").params,
                                  LENSES["ds-alpha1"].params)


# --------------------------------------------------------------------------- OpenCV omnidir

OMNIDIR = """%YAML:1.0
---
calibration_time: "Sun Nov 29 12:00:00 2026"
nFrames: 20
flags: 1
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 7.2e+02, {skew}, 6.4e+02, 0., 7.1e+02, 3.6e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 4
   dt: d
   data: [ -0.25, 0.07, 1.0e-4, -2.0e-4 ]
xi: 1.3
used_imgs:
   - "img1.jpg"
   - "img2.jpg"
rms: 0.3
"""


def _mei(x, f, c, xi, k1, k2, p1, p2):
    """Mei and Rives' unified projection as OpenCV's omnidir documents it (point on the unit
    sphere seen from (0, 0, -xi), then k1 k2 p1 p2 as OpenCV's pinhole distortion)."""
    s = x / np.linalg.norm(x, axis=1)[:, None]
    m = s[:, :2] / (s[:, 2:] + xi)
    r2 = (m ** 2).sum(axis=1)
    radial = 1 + k1 * r2 + k2 * r2 ** 2
    mx = m[:, 0] * radial + 2 * p1 * m[:, 0] * m[:, 1] + p2 * (r2 + 2 * m[:, 0] ** 2)
    my = m[:, 1] * radial + p1 * (r2 + 2 * m[:, 1] ** 2) + 2 * p2 * m[:, 0] * m[:, 1]
    return np.stack([f[0] * mx + c[0], f[1] * my + c[1]], axis=1)


def test_opencv_omnidir_file_is_the_unified_model(tmp_path):
    """OpenCV's omnidir calibration sample (opencv_contrib ccalib) writes camera_matrix,
    distortion_coefficients (k1 k2 p1 p2) and xi: Mei's unified model, not a pinhole whose
    xi is dropped; its skew, when estimated, is refused by name."""
    (tmp_path / "omni.yaml").write_text(OMNIDIR.format(skew="0."))
    lens = read_intrinsics(tmp_path / "omni.yaml")
    assert lens.model == "unified"
    np.testing.assert_array_equal(lens.dist, [1.3, -0.25, 0.07, 1e-4, -2e-4])
    rays = _rays()
    rays = rays[rays[:, 2] > -0.5]
    np.testing.assert_allclose(project_points(rays, lens),
                               _mei(rays, (720, 710), (640, 360), 1.3, -0.25, 0.07, 1e-4, -2e-4),
                               rtol=0, atol=1e-9)
    (tmp_path / "omni.yaml").write_text(OMNIDIR.format(skew="0.8"))
    with pytest.raises(DatasetError, match="camera matrix has skew 0.8 px"):
        read_intrinsics(tmp_path / "omni.yaml")


@pytest.mark.parametrize("extra, message", [
    ('"distortion_model": "fisheye", ', "xi: xi \\(the unified model's mirror offset\\) "
                                        "with a fisheye lens"),
    ('"k3": 0.01, ', "xi: the unified model has k1 k2 p1 p2 only"),
])
def test_xi_in_a_mapping_layout_that_cannot_be_unified_is_refused(tmp_path, extra, message):
    (tmp_path / "c.json").write_text('{"fx": 500, "fy": 500, "cx": 320, "cy": 240, ' + extra
                                     + '"k1": 0.1, "xi": 0.9}')
    with pytest.raises(DatasetError, match=message):
        read_intrinsics(tmp_path / "c.json")
    (tmp_path / "c.json").write_text('{"fx": 500, "fy": 500, "cx": 320, "cy": 240, '
                                     '"k1": 0.1, "xi": 0.9}')
    np.testing.assert_array_equal(read_intrinsics(tmp_path / "c.json").dist,
                                  [0.9, 0.1, 0, 0, 0])


# --------------------------------------------------------------------------- Kalibr's formulas

CHAIN = """cam0:
  camera_model: omni
  intrinsics: [1.3, 720.5, 710.25, 640.5, 360.75]
  distortion_model: radtan
  distortion_coeffs: [-0.25, 0.07, 1.0e-4, -2.0e-4]
  resolution: [1280, 720]
cam1:
  camera_model: ds
  intrinsics: [-0.17, 0.59, 350.5, 351.25, 640.5, 360.75]
  distortion_model: none
  distortion_coeffs: []
  resolution: [1280, 720]
  T_cn_cnm1: [[1, 0, 0, 0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
cam2:
  camera_model: eucm
  intrinsics: [0.62, 1.08, 300.5, 301.25, 640.5, 360.75]
  distortion_model: none
  distortion_coeffs: []
  resolution: [1280, 720]
  T_cn_cnm1: [[1, 0, 0, 0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
"""


def test_camchain_lenses_project_as_kalibr_does(tmp_path):
    """Kalibr's aslam_cv projections (OmniProjection + RadialTangentialDistortion,
    DoubleSphereProjection, ExtendedUnifiedProjection: euclideanToKeypoint), written from
    their formulas, against each camchain entry read by multieye, on rays inside each model's
    valid region."""
    (tmp_path / "chain.yaml").write_text(CHAIN)
    rays = _rays(2000)
    rays = rays[rays[:, 2] > 0.0]
    x, y, z = rays.T
    omni = read_intrinsics(tmp_path / "chain.yaml", "cam0")
    np.testing.assert_allclose(project_points(rays, omni), _mei(
        rays, (720.5, 710.25), (640.5, 360.75), 1.3, -0.25, 0.07, 1e-4, -2e-4), rtol=0, atol=1e-9)
    ds = read_intrinsics(tmp_path / "chain.yaml", "cam1")
    d1 = np.sqrt(x * x + y * y + z * z)
    k = -0.17 * d1 + z
    norm = 0.59 * np.sqrt(x * x + y * y + k * k) + 0.41 * k
    np.testing.assert_allclose(project_points(rays, ds), np.stack(
        [350.5 * x / norm + 640.5, 351.25 * y / norm + 360.75], axis=1), rtol=0, atol=1e-9)
    eucm = read_intrinsics(tmp_path / "chain.yaml", "cam2")
    norm = 0.62 * np.sqrt(1.08 * (x * x + y * y) + z * z) + 0.38 * z
    np.testing.assert_allclose(project_points(rays, eucm), np.stack(
        [300.5 * x / norm + 640.5, 301.25 * y / norm + 360.75], axis=1), rtol=0, atol=1e-9)


def test_rig_yaml_camera_given_as_an_index_chooses_basalt_s_camera(tmp_path):
    """docs/rig-yaml.md: Basalt's camera by ``cam1`` or its index ``1``; YAML reads an
    unquoted 1 as an integer, which was refused as not a string."""
    (tmp_path / "calib.json").write_text(json.dumps({"value0": {
        "intrinsics": [{"camera_type": "ds", "intrinsics": {
                            "fx": 349.7, "fy": 349.6, "cx": 365.1, "cy": 252.6, "xi": -0.2,
                            "alpha": 0.56}},
                       {"camera_type": "eucm", "intrinsics": {
                            "fx": 300.5, "fy": 300.25, "cx": 320.0, "cy": 240.0, "alpha": 0.6,
                            "beta": 1.1}}],
        "resolution": [[752, 480], [640, 481]]}}))
    lens = _through_rig(tmp_path, "calib.json", "1")
    assert lens.model == "eucm" and (lens.width, lens.height) == (640, 481)
    assert _through_rig(tmp_path, "calib.json", "0").model == "double-sphere"
    with pytest.raises(DatasetError, match="intrinsics.camera: expected a camera name or "
                                           "index, got True"):
        _through_rig(tmp_path, "calib.json", "true")


def test_boofcv_width_without_height_is_refused(tmp_path):
    """BoofCV writes both; one alone was read as a lens of half an image size."""
    (tmp_path / "p.yaml").write_text(BOOF_PINHOLE.replace("  height: 720\n", "")
                                     + "model: pinhole\n")
    with pytest.raises(DatasetError, match="pinhole: width without height: give both"):
        read_intrinsics(tmp_path / "p.yaml")

