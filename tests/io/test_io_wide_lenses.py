"""The wide-angle lenses (unified, double-sphere, eucm) in and out of every file lenses travel
in: Kalibr camchains (omni, ds, eucm), BoofCV's camera YAML, calibration.json (format_version
3), OUT/intrinsics; and the formats that cannot hold them refuse them by name."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from multieye.core import geometry
from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import Intrinsics
from multieye.io import (
    CalibrationRecord, CameraRecord, IntrinsicsRecord, Residuals, read_calibration,
    read_camchain, read_intrinsics, write_calibration, write_camchain)
from multieye.io.cameramodel import cameramodel_text
from multieye.io.intrinsics_files import (
    camera_info_text, write_intrinsics_file, write_opencv_intrinsics)
from multieye.io.kalibr import CamchainEntry

LENSES = [
    Intrinsics(K=[[560.25, 0, 321.5], [0, 559.75, 238.125], [0, 0, 1]],
               dist=[0.9, -0.05, 0.01, 0.0005, -0.0003], model="unified", width=640,
               height=480),
    Intrinsics(K=[[158.28, 0, 254.96], [0, 158.27, 256.88], [0, 0, 1]], dist=[-0.172, 0.593],
               model="double-sphere", width=512, height=512),
    Intrinsics(K=[[300.5, 0, 320], [0, 300.25, 240], [0, 0, 1]], dist=[0.6, 1.1],
               model="eucm"),
]


def test_kalibr_camchain_round_trip_of_every_model(tmp_path, rng):
    T = geometry.random_transforms(rng, 3)
    T[0] = np.eye(4)
    write_camchain(tmp_path / "camchain.yaml",
                   [CamchainEntry(f"c{j}", lens, T[j]) for j, lens in enumerate(LENSES)])
    text = (tmp_path / "camchain.yaml").read_text()
    assert "camera_model: omni" in text and "camera_model: ds" in text
    assert "intrinsics: [0.9, 560.25, 559.75, 321.5, 238.125]" in text
    assert "intrinsics: [-0.172, 0.593, 158.28, 158.27, 254.96, 256.88]" in text
    assert "intrinsics: [0.6, 1.1, 300.5, 300.25, 320.0, 240.0]" in text
    chain = read_camchain(tmp_path / "camchain.yaml")
    for entry, lens, T_true in zip(chain, LENSES, T):
        assert entry.intrinsics.model == lens.model
        np.testing.assert_array_equal(entry.intrinsics.params, lens.params)
        assert (entry.intrinsics.width, entry.intrinsics.height) == (lens.width, lens.height)
        np.testing.assert_allclose(entry.T_ref_cam, T_true, atol=1e-12)


KALIBR_OMNI = """cam0:
  camera_model: omni
  intrinsics: [1.2, 461.6, 460.3, 366.3, 249.2]
  distortion_model: {dmodel}
  distortion_coeffs: {coeffs}
  resolution: [752, 480]
"""


@pytest.mark.parametrize("dmodel, coeffs, message", [
    ("radtan", "[-0.01, 0.002, 0.0001, -0.0002]", None),
    ("none", "[]", None),
    ("equidistant", "[0.1, 0, 0, 0]", "distortion_model 'equidistant' is not supported with "
                                      "camera_model omni; expected radtan or none"),
    ("radtan", "[0.1]", "distortion_coeffs must be 4 finite numbers"),
])
def test_kalibr_omni_as_kalibr_writes_it(tmp_path, dmodel, coeffs, message):
    (tmp_path / "c.yaml").write_text(KALIBR_OMNI.format(dmodel=dmodel, coeffs=coeffs))
    if message:
        with pytest.raises(DatasetError, match=message):
            read_intrinsics(tmp_path / "c.yaml")
        return
    lens = read_intrinsics(tmp_path / "c.yaml")
    assert lens.model == "unified" and (lens.width, lens.height) == (752, 480)
    np.testing.assert_array_equal(lens.params[:5], [461.6, 460.3, 366.3, 249.2, 1.2])
    np.testing.assert_array_equal(lens.dist[1:], [-0.01, 0.002, 0.0001, -0.0002]
                                  if dmodel == "radtan" else [0, 0, 0, 0])


@pytest.mark.parametrize("text, message", [
    ("camera_model: ds\nintrinsics: [-0.2, 0.59, 150, 150, 250, 250]\n"
     "distortion_model: radtan\ndistortion_coeffs: [0, 0, 0, 0]\n",
     "distortion_model 'radtan' is not supported with camera_model ds; expected none"),
    ("camera_model: ds\nintrinsics: [0.59, 150, 150, 250, 250]\ndistortion_model: none\n",
     r"intrinsics \[xi, alpha, fu, fv, pu, pv\] must be 6 finite numbers"),
    ("camera_model: ds\nintrinsics: [-0.2, 1.59, 150, 150, 250, 250]\ndistortion_model: none\n",
     "double-sphere alpha must be within"),
    ("camera_model: eucm\nintrinsics: [0.6, -1.0, 150, 150, 250, 250]\n"
     "distortion_model: none\n", "eucm beta must be > 0"),
    ("camera_model: eucm\nintrinsics: [0.6, 500.0, 150, 150, 250, 250]\n"
     "distortion_model: none\n", "beta = 500 is beyond any real lens"),
])
def test_kalibr_ds_and_eucm_refusals_name_the_key(tmp_path, text, message):
    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(DatasetError, match=message) as info:
        read_intrinsics(tmp_path / "c.yaml")
    assert info.value.line is not None


def test_boofcv_fisheye_file_is_the_unified_model_it_states(shared_data):
    lens = read_intrinsics(shared_data / "boofcv_fisheye" / "fisheye.yaml")
    assert lens.model == "unified" and (lens.width, lens.height) == (640, 720)
    np.testing.assert_array_equal(lens.K, [[398.77492706579216, 0, 319.17879590584187],
                                           [0, 398.7685638672075, 319.71743712432686],
                                           [0, 0, 1]])
    np.testing.assert_array_equal(lens.dist, [1.1331346732794045, -0.24972089525362837,
                                              0.009672326567075125, 0.0, 0.0])
    left = read_intrinsics(shared_data / "boofcv_stereo" / "intrinsicLeft.yaml")
    assert left.model == "pinhole" and (left.width, left.height) == (640, 480)
    np.testing.assert_array_equal(left.dist, [-0.36253655570702903, 0.17532743749719257, 0, 0])
    assert left.K[0, 0] == 524.614138540519 and left.K[1, 2] == 247.40160777589855


def test_boofcv_stereo_file_gives_the_camera_chosen(shared_data, tmp_path):
    """BoofCV's stereo calibration as published (model: stereo_camera, left, right,
    rightToLeft): each camera by `camera` or by the rig camera's name; none chosen is one
    line saying how to choose (it was refused as 'not an intrinsics file')."""
    path = shared_data / "boofcv_stereo" / "stereo.yaml"
    left, right = read_intrinsics(path, "left"), read_intrinsics(path, "right")
    assert left.K[0, 0] == 524.6141554796689 and right.K[0, 0] == 526.437309515818
    np.testing.assert_array_equal(left.dist, [-0.3625365821238732, 0.17532754393079863, 0, 0])
    assert (right.width, right.height) == (640, 480)
    assert read_intrinsics(path, prefer="right").K[0, 0] == right.K[0, 0]
    with pytest.raises(DatasetError, match=r"holds two cameras, left and right; choose one "
                       r"with intrinsics: \{file: stereo.yaml, camera: left\}") as info:
        read_intrinsics(path, prefer="cam0")
    assert info.value.line == 18
    (tmp_path / "s.yaml").write_text(path.read_text().replace("    t1: 0.0", "    t9: 0.0", 1))
    with pytest.raises(DatasetError, match="left.radial_tangential.t9"):
        read_intrinsics(tmp_path / "s.yaml", "left")


BOOFCV = """pinhole:
  fx: 400.0
  fy: 401.0
  cx: 320.0
  cy: 240.0
  width: 640
  height: 480
  skew: 0.0
model: {model}
radial_tangential:
  radial: {radial}
  t1: 0.001
  t2: -0.002
version: 0
{extra}"""


@pytest.mark.parametrize("model, radial, extra, expect", [
    ("pinhole_radial_tangential", "[-0.3, 0.1, 0.01]", "", [-0.3, 0.1, 0.001, -0.002, 0.01]),
    ("pinhole_radial_tangential", "[-0.3]", "", [-0.3, 0, 0.001, -0.002]),
    ("omnidirectional_universal", "[-0.2, 0.01]", "mirror_offset: 0.8\n",
     [0.8, -0.2, 0.01, 0.001, -0.002]),
    ("omnidirectional_universal", "[-0.2, 0.01, 0.001]", "mirror_offset: 0.8\n",
     "3 radial coefficients; multieye's unified model holds 2"),
    ("omnidirectional_universal", "[-0.2]", "", "missing key 'mirror_offset'"),
    ("pinhole_radial_tangential", "[-0.2]", "mirror_offset: 0.8\n",
     "mirror_offset belongs to omnidirectional_universal"),
    ("kannala_brandt", "[-0.2]", "symmetric: [1.0]\n",
     "radial_tangential belongs to pinhole_radial_tangential and omnidirectional_universal, "
     "not kannala_brandt"),
    ("fisheye", "[-0.2]", "", "BoofCV model 'fisheye' is not supported"),
    ("omnidirectional_universal", "[-0.2]", "mirror_offset: -0.5\n", "xi .* must be >= 0"),
    ("pinhole_radial_tangential", "[-0.2]", "projection: 1\n", "projection: not a key"),
])
def test_boofcv_layouts_read_or_refused(tmp_path, model, radial, extra, expect):
    (tmp_path / "b.yaml").write_text(BOOFCV.format(model=model, radial=radial, extra=extra))
    if isinstance(expect, str):
        with pytest.raises(DatasetError, match=expect):
            read_intrinsics(tmp_path / "b.yaml")
        return
    lens = read_intrinsics(tmp_path / "b.yaml")
    np.testing.assert_array_equal(lens.dist, expect)
    assert lens.K[1, 1] == 401.0 and (lens.width, lens.height) == (640, 480)


def _record(rng, lenses):
    X = geometry.random_transforms(rng, len(lenses))
    cams = tuple(CameraRecord(f"cam{j}", X[j], geometry.inv(X[0]) @ X[j], 40,
                              intrinsics=IntrinsicsRecord(lens, j == 0))
                 for j, lens in enumerate(lenses))
    return CalibrationRecord("eye-to-base", "joint", "cam0", geometry.random_transforms(rng),
                             cams, Residuals(0.01, 1e-4))


def test_calibration_json_holds_the_models_as_version_3(tmp_path, rng):
    write_calibration(tmp_path / "c.json", _record(rng, LENSES))
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["format_version"] == 3
    assert [c["intrinsics"]["model"] for c in data["cameras"].values()] == [
        "unified", "double-sphere", "eucm"]
    assert data["cameras"]["cam1"]["intrinsics"]["distortion"] == [-0.172, 0.593]
    back = read_calibration(tmp_path / "c.json")
    for cam, lens in zip(back.cameras, LENSES):
        assert cam.intrinsics.intrinsics.model == lens.model
        np.testing.assert_array_equal(cam.intrinsics.intrinsics.params, lens.params)
    # a version-2 file with such a lens is not one this layout defines: refused, not misread
    (tmp_path / "v2.json").write_text(json.dumps(data | {"format_version": 2}))
    with pytest.raises(DatasetError, match="intrinsics.model unified needs format_version 3"):
        read_calibration(tmp_path / "v2.json")
    # without a wide lens the file stays version 2, as before
    pin = [replace(LENSES[0], model="pinhole", dist=np.zeros(5))]
    write_calibration(tmp_path / "p.json", _record(rng, pin))
    assert json.loads((tmp_path / "p.json").read_text())["format_version"] == 2


def test_intrinsics_files_written_for_every_model_read_back(tmp_path):
    for j, lens in enumerate(LENSES):
        write_intrinsics_file(tmp_path / f"c{j}.yaml", lens)
        back = read_intrinsics(tmp_path / f"c{j}.yaml")
        assert back.model == lens.model
        np.testing.assert_array_equal(back.params, lens.params)
        assert (back.width, back.height) == (lens.width, lens.height)
        assert (tmp_path / f"c{j}.yaml").read_text().startswith(f"# {lens.model} lens")


@pytest.mark.parametrize("lens", LENSES, ids=lambda c: c.model)
def test_formats_without_the_models_refuse_them_by_name(tmp_path, lens):
    with pytest.raises(InputError, match=f"OpenCV FileStorage has no {lens.model} lens model"):
        write_opencv_intrinsics(tmp_path / "x.yaml", lens)
    assert not (tmp_path / "x.yaml").exists()
    with pytest.raises(InputError, match=f"ROS camera_info has no {lens.model} lens model"):
        camera_info_text(replace(lens, width=640, height=480), "cam0")
    with pytest.raises(InputError, match=f"mrcal has no lens model for the {lens.model} lens"):
        cameramodel_text(replace(lens, width=640, height=480))
