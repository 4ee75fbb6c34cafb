"""calibration.json: the keys of docs/outputs.md, exact round trips, validation on read."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multieye.core import geometry
from multieye.core.errors import DatasetError, InputError
from multieye.io.calibration_json import (
    CalibrationRecord,
    FORMAT_VERSION,
    CameraRecord,
    RejectedItem,
    Residuals,
    read_calibration,
    write_calibration,
)


def _record(rng, setup="eye-to-base", m=3, full=True):
    X = geometry.random_transforms(rng, m)
    cams = []
    for j in range(m):
        extra = {}
        if full and j:
            A = rng.normal(size=(6, 6))
            extra = dict(residuals=Residuals(0.01 * j, 1e-4 * j, 0.05, 3e-4, 0.21),
                         time_offset_s=-0.0123, std_rot_deg=0.02, std_trans_m=4e-4,
                         covariance=A @ A.T * 1e-8,
                         rejected=(RejectedItem("1700000000.5.png", "no target detected"),
                                   RejectedItem("1700000001.png", "reprojection RMS 3.2 px")))
        cams.append(CameraRecord(f"cam{j}", X[j], geometry.inv(X[0]) @ X[j], 40 + j, **extra))
    return CalibrationRecord(setup, "joint", "cam0", geometry.random_transforms(rng), cams,
                             Residuals(0.012, 2.5e-4), ("cam2: rotations span only 12 deg",))


@pytest.mark.parametrize("setup, y_key, x_key", [("eye-to-base", "T_marker_target", "T_world_cam"),
                                                 ("eye-on-hand", "T_world_target", "T_body_cam")])
def test_keys_follow_the_design(tmp_path, rng, setup, y_key, x_key):
    rec = _record(rng, setup)
    write_calibration(tmp_path / "calibration.json", rec)
    data = json.loads((tmp_path / "calibration.json").read_text())
    assert list(data) == ["format_version", "setup", "method", "reference_camera", y_key,
                          "cameras", "residuals", "warnings", "plausibility"]
    assert data["format_version"] == 2 and FORMAT_VERSION == 3   # 3: only with a wide lens
    assert data["plausibility"] == []
    assert data["setup"] == setup and data["reference_camera"] == "cam0"
    assert np.array_equal(np.array(data[y_key]), rec.Y)
    cam0, cam1 = data["cameras"]["cam0"], data["cameras"]["cam1"]
    assert set(cam0) == {x_key, "T_ref_cam", "measurements_used"}
    assert set(cam1) == {x_key, "T_ref_cam", "measurements_used", "residuals", "time_offset_s",
                         "std_rot_deg", "std_trans_m", "covariance", "rejected"}
    assert cam1["rejected"][0] == {"item": "1700000000.5.png", "reason": "no target detected"}
    assert np.array(cam1["covariance"]).shape == (6, 6)
    assert data["residuals"] == {"e_R_deg": 0.012, "e_t_m": 2.5e-4}
    assert cam1["residuals"]["reprojection_rms_px"] == 0.21


def test_plausibility_doubts_round_trip_and_older_files_have_none(tmp_path, rng):
    from dataclasses import replace

    from multieye.io import PlausibilityItem

    doubts = (PlausibilityItem("scale", "scale: the target spacing looks off by x1.25"),
              PlausibilityItem("time-offset", "time offset: cam1 fits 0.1 s later", "cam1"))
    rec = replace(_record(rng, "eye-to-base"), plausibility=doubts)
    path = tmp_path / "calibration.json"
    write_calibration(path, rec)
    data = json.loads(path.read_text())
    assert data["plausibility"] == [
        {"cause": "scale", "message": "scale: the target spacing looks off by x1.25"},
        {"cause": "time-offset", "message": "time offset: cam1 fits 0.1 s later",
         "camera": "cam1"}]
    assert read_calibration(path).plausibility == doubts
    del data["plausibility"]                           # written by an earlier version
    path.write_text(json.dumps(data))
    assert read_calibration(path).plausibility == ()
    for bad in ([{"cause": "scale"}], {"cause": "scale", "message": "m"},
                [{"cause": "scale", "message": "m", "camera": 3}]):
        path.write_text(json.dumps(data | {"plausibility": bad}))
        with pytest.raises(DatasetError, match="plausibility must be a list"):
            read_calibration(path)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(1, 6),
       setup=st.sampled_from(["eye-to-base", "eye-on-hand"]), full=st.booleans())
def test_round_trip_is_exact(tmp_path_factory, seed, m, setup, full):
    rec = _record(np.random.default_rng(seed), setup, m, full)
    path = tmp_path_factory.mktemp("cal") / "calibration.json"
    write_calibration(path, rec)
    back = read_calibration(path)
    assert (back.setup, back.method, back.reference_camera) == (setup, "joint", "cam0")
    assert np.array_equal(back.Y, rec.Y)
    assert back.residuals == rec.residuals and back.warnings == rec.warnings
    for a, b in zip(rec.cameras, back.cameras, strict=True):
        assert a.name == b.name and a.measurements_used == b.measurements_used
        assert np.array_equal(a.X, b.X) and np.array_equal(a.T_ref_cam, b.T_ref_cam)
        assert (a.residuals, a.time_offset_s, a.std_rot_deg, a.std_trans_m, a.rejected) == (
            b.residuals, b.time_offset_s, b.std_rot_deg, b.std_trans_m, b.rejected)
        assert (a.covariance is None and b.covariance is None) or np.array_equal(
            a.covariance, b.covariance)
    assert back.camera("cam0").name == "cam0"


def _write_json(path, data):
    path.write_text(json.dumps(data, indent=1))
    return path


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.pop("T_marker_target"), "missing key 'T_marker_target' in the top level"),
    (lambda d: d["cameras"]["cam1"].pop("T_world_cam"),
     "camera cam1: missing key 'T_world_cam'$"),
    (lambda d: d["cameras"]["cam0"].pop("measurements_used"), "missing key 'measurements_used'"),
    (lambda d: d.update(setup="eye-in-hand"), "setup must be one of eye-to-base, eye-on-hand"),
    (lambda d: d["cameras"]["cam1"]["T_ref_cam"][0].__setitem__(0, 1.5),
     ": camera cam1: T_ref_cam is not a rigid transform$"),
    (lambda d: d.__setitem__("T_marker_target", [[1, 0], [0, 1]]),
     "T_marker_target must be a finite 4x4 transform, got shape \\(2, 2\\)"),
    (lambda d: d["cameras"]["cam1"].__setitem__("covariance", [[0.0] * 6] * 5),
     "covariance must be a finite 6x6 matrix"),
    (lambda d: d["cameras"]["cam1"].__setitem__("std_rot_deg", "small"),
     "std_rot_deg must be a finite number, got 'small'"),
    (lambda d: d.update(reference_camera="cam9"), "reference camera 'cam9' is not one of"),
    (lambda d: d["residuals"].pop("e_t_m"), "missing key 'e_t_m' in residuals"),
    (lambda d: d["cameras"]["cam1"].__setitem__("rejected", [{"item": "x"}]),
     "rejected must be a list of"),
    (lambda d: d["cameras"]["cam0"].__setitem__("measurements_used", -1),
     "measurements_used must be a non-negative integer"),
])
def test_validation_on_read(tmp_path, rng, edit, message):
    write_calibration(tmp_path / "ok.json", _record(rng))
    data = json.loads((tmp_path / "ok.json").read_text())
    edit(data)
    path = _write_json(tmp_path / "bad.json", data)
    with pytest.raises(DatasetError, match=message) as info:
        read_calibration(path)
    assert info.value.path == str(path)


def test_unknown_keys_are_ignored_and_bad_json_names_the_line(tmp_path, rng):
    write_calibration(tmp_path / "ok.json", _record(rng))
    data = json.loads((tmp_path / "ok.json").read_text())
    data["multieye_version"] = "0.1.0"
    data["cameras"]["cam0"]["notes"] = "front bumper"
    assert read_calibration(_write_json(tmp_path / "extra.json", data)).method == "joint"
    (tmp_path / "broken.json").write_text('{\n  "setup": "eye-to-base",\n  "method": joint\n}')
    with pytest.raises(DatasetError, match="invalid JSON") as info:
        read_calibration(tmp_path / "broken.json")
    assert info.value.line == 3


def test_records_check_their_input(rng):
    T = geometry.random_transforms(rng)
    cam = CameraRecord("a", T, np.eye(4), 3)
    with pytest.raises(InputError, match="reference camera 'b' is not one of \\['a'\\]"):
        CalibrationRecord("eye-to-base", "joint", "b", T, (cam,), Residuals(0, 0))
    with pytest.raises(InputError, match="camera names must be unique"):
        CalibrationRecord("eye-to-base", "joint", "a", T, (cam, cam), Residuals(0, 0))
    bad = T.copy()
    bad[:3, :3] *= 2
    with pytest.raises(InputError, match="camera a: X is not a rigid transform"):
        CameraRecord("a", bad, np.eye(4), 3)


def test_nan_residual_is_not_written(tmp_path, rng):
    rec = _record(rng)
    bad = CalibrationRecord(rec.setup, rec.method, rec.reference_camera, rec.Y, rec.cameras,
                            Residuals(float("nan"), 0.0))
    with pytest.raises(ValueError):
        write_calibration(tmp_path / "calibration.json", bad)
    assert not (tmp_path / "calibration.json").exists()


def test_intrinsics_and_uncertainty_round_trip_exactly(tmp_path):
    from multieye.core.intrinsics import Intrinsics
    from multieye.io import IntrinsicsRecord, PoseUncertainty

    rng = np.random.default_rng(3)
    rec = _record(rng, "eye-on-hand")
    A = rng.normal(size=(6, 6))
    unc = PoseUncertainty(0.03, 5e-4, A @ A.T * 1e-8)
    lens = Intrinsics(K=[[700.5, 0, 640.25], [0, 701.0, 480.5], [0, 0, 1]],
                      dist=[0.02, -0.01, 0.003, -0.001], model="fisheye", width=1280,
                      height=960)
    B = rng.normal(size=(8, 8))
    cams = tuple(replace(c, intrinsics=IntrinsicsRecord(lens, j == 0, B @ B.T if j == 0 else
                                                         None, (0.12, 0.4) if j == 0 else None),
                         uncertainty={"T_body_cam": unc, "T_ref_cam": unc})
                 for j, c in enumerate(rec.cameras))
    rec = replace(rec, cameras=cams, uncertainty={"T_world_target": unc})
    write_calibration(tmp_path / "c.json", rec)
    back = read_calibration(tmp_path / "c.json")
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["cameras"][cams[0].name]["intrinsics"]["model"] == "fisheye"
    assert data["cameras"][cams[0].name]["intrinsics"]["image_size"] == [1280, 960]
    for a, b in zip(back.cameras, cams):
        np.testing.assert_array_equal(a.intrinsics.intrinsics.K, b.intrinsics.intrinsics.K)
        np.testing.assert_array_equal(a.intrinsics.intrinsics.dist, b.intrinsics.intrinsics.dist)
        assert a.intrinsics.estimated == b.intrinsics.estimated
        assert a.intrinsics.projection_std_px == b.intrinsics.projection_std_px
        if b.intrinsics.covariance is None:
            assert a.intrinsics.covariance is None
        else:
            np.testing.assert_array_equal(a.intrinsics.covariance, b.intrinsics.covariance)
        np.testing.assert_array_equal(a.uncertainty["T_body_cam"].covariance, unc.covariance)
    assert back.uncertainty["T_world_target"].std_rot_deg == 0.03
    # a wrong key for the setup is refused
    data["uncertainty"] = {"T_marker_target": data["uncertainty"]["T_world_target"]}
    (tmp_path / "bad.json").write_text(json.dumps(data))
    with pytest.raises(DatasetError, match="uncertainty must be an object with keys among "
                                           "T_world_target"):
        read_calibration(tmp_path / "bad.json")


def test_format_version_absent_is_read_as_the_first_and_a_newer_one_is_refused(tmp_path, rng):
    rec = _record(rng)
    path = tmp_path / "calibration.json"
    write_calibration(path, rec)
    data = json.loads(path.read_text())
    del data["format_version"]                  # as files of earlier versions
    path.write_text(json.dumps(data))
    np.testing.assert_array_equal(read_calibration(path).Y, rec.Y)
    for bad in (FORMAT_VERSION + 1, "1", 0, True):
        path.write_text(json.dumps(data | {"format_version": bad}))
        with pytest.raises(DatasetError, match="format_version must be an integer from 1") as e:
            read_calibration(path)
        assert str(path) in str(e.value) and "\n" not in str(e.value)


def test_a_rig_without_motion_capture_has_no_x_and_no_y_and_round_trips(tmp_path, rng):
    """Issue 23: setup overlap, T_ref_cam with its covariance, links per camera."""
    from multieye.io.calibration_json import CameraLinks
    T = geometry.random_transforms(rng, 3)
    T[0] = np.eye(4)
    A = rng.normal(size=(6, 6))
    cams = [CameraRecord(f"cam{j}", None, T[j], 30, covariance=A @ A.T * 1e-8 * (j > 0),
                         links=CameraLinks({f"cam{k}": 10 + j + k for k in range(3) if k != j}))
            for j in range(3)]
    rec = CalibrationRecord("overlap", "covisibility", "cam0", None, cams, Residuals(0.01, 1e-4))
    path = tmp_path / "calibration.json"
    write_calibration(path, rec)
    data = json.loads(path.read_text())
    assert data["format_version"] == 2 and data["setup"] == "overlap"
    assert "T_marker_target" not in data and "T_world_target" not in data
    assert set(data["cameras"]["cam1"]) >= {"T_ref_cam", "links", "covariance"}
    assert "T_world_cam" not in data["cameras"]["cam1"]
    assert data["cameras"]["cam1"]["links"] == {"overlap": {"cam0": 11, "cam2": 13},
                                                "mocap": False}
    back = read_calibration(path)
    assert back.Y is None and not back.mocap
    assert back.camera("cam2").links == cams[2].links
    assert np.array_equal(back.camera("cam2").T_ref_cam, T[2])
    assert cams[1].links.describe() == "overlap with cam0 (11 instants), cam2 (13)"
    # a version-1 file cannot say overlap; X or Y where they cannot be are refused
    path.write_text(json.dumps(data | {"format_version": 1}))
    with pytest.raises(DatasetError, match="setup must be one of"):
        read_calibration(path)
    with pytest.raises(InputError, match="no Y and no X"):
        CalibrationRecord("overlap", "covisibility", "cam0", np.eye(4), cams,
                          Residuals(0.0, 0.0))
    with pytest.raises(InputError, match="Y and every camera's X are needed"):
        CalibrationRecord("eye-to-base", "joint", "cam0", np.eye(4), cams, Residuals(0.0, 0.0))


def test_a_lens_curve_round_trips_and_files_without_it_still_read(tmp_path):
    """``intrinsics.lens_curve`` (a wide lens' radii at three rays and their covariance,
    docs/outputs.md) is written exactly, read back, optional (a file without it reads with
    None: no new format_version) and checked where it is read."""
    from multieye.core.intrinsics import Intrinsics
    from multieye.core.lens_curve import RadialCurve
    from multieye.io.calibration_record import IntrinsicsRecord

    rng = np.random.default_rng(5)
    lens = Intrinsics(K=[[260.0, 0, 511.5], [0, 260.5, 511.0], [0, 0, 1]],
                      dist=[1.1, -0.08, 0.01, 1e-4, -2e-4], model="unified", width=1024,
                      height=1024)
    B = rng.normal(size=(9, 9))
    A = rng.normal(size=(3, 3))
    curve = RadialCurve(np.array([28.5, 57.0, 85.5]), np.array([121.3, 233.9, 331.2]),
                        A @ A.T * 0.01)
    rec = _record(rng)
    cams = tuple(replace(c, intrinsics=IntrinsicsRecord(lens, True, B @ B.T, (0.05, 0.1),
                                                         curve if j == 1 else None))
                 for j, c in enumerate(rec.cameras))
    write_calibration(tmp_path / "c.json", replace(rec, cameras=cams))
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["format_version"] == 3                       # the unified lens's, as before
    assert "lens_curve" not in data["cameras"]["cam0"]["intrinsics"]
    assert set(data["cameras"]["cam1"]["intrinsics"]["lens_curve"]) == {
        "angles_deg", "radii_px", "covariance"}
    back = read_calibration(tmp_path / "c.json")
    assert back.cameras[0].intrinsics.lens_curve is None
    got = back.cameras[1].intrinsics.lens_curve
    for name in ("angles_deg", "radii_px", "covariance"):
        np.testing.assert_array_equal(getattr(got, name), getattr(curve, name))
    for bad in ([[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.5, 0], [0, 1, 0], [0, 0, 1]], "big"):
        data["cameras"]["cam1"]["intrinsics"]["lens_curve"]["covariance"] = bad
        with pytest.raises(DatasetError, match="camera cam1: intrinsics.lens_curve must be"):
            read_calibration(_write_json(tmp_path / "bad.json", data))
    data["cameras"]["cam1"]["intrinsics"]["lens_curve"] = {"radii_px": [1.0]}
    with pytest.raises(DatasetError, match="intrinsics.lens_curve must be"):
        read_calibration(_write_json(tmp_path / "bad.json", data))


def test_a_dataset_folder_given_for_the_output_says_so(tmp_path):
    """multieye report / export DATASET (the folder with rig.yaml, not -o OUT): 'calibration
    file not found' alone did not say which folder was meant."""
    from multieye.io.calibration_json import read_calibration

    (tmp_path / "rig.yaml").write_text("cameras: {}\n")
    with pytest.raises(DatasetError, match="this folder holds rig.yaml, a dataset; give the "
                       "output folder of multieye calibrate"):
        read_calibration(tmp_path / "calibration.json")
    (tmp_path / "rig.yaml").unlink()
    with pytest.raises(DatasetError, match=r"calibration file not found$"):
        read_calibration(tmp_path / "calibration.json")
