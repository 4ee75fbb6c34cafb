"""multieye.outputs.export: every format written from a calibration and read back to 1e-9.

Runs are built in memory (:func:`make_run`: the pipeline's own pairing and solver on exact
measurements from known frames), for both setups and with camera names that need quoting.
"""

from __future__ import annotations

import json
import shlex
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from export_runs import NAMES, make_run

from multieye.core import geometry as g
from multieye.core.errors import DatasetError, InputError
from multieye.outputs.export_readers import read_tf_static, read_urdf_joints
from multieye.outputs.export import (
    BASE_FRAME,
    ros_name,
    FORMATS,
    T_LINK_OPTICAL,
    export,
)
from multieye.core.geometry import rotation_from_rpy, rpy_from_rotation
from multieye.io import read_calibration, read_camchain
from multieye.outputs.details import write_run_details
from multieye.outputs.write import write_outputs



@pytest.fixture(scope="module", params=["eye-to-base", "eye-on-hand"])
def result(request, tmp_path_factory):
    """An output folder as ``multieye calibrate`` leaves it, with details.json."""
    out = tmp_path_factory.mktemp(request.param)
    run, truth = make_run(out, request.param)
    write_outputs(run, out)
    write_run_details(out / "details.json", run)
    return out, run.record, truth


def _near(a, b, tol=1e-9):
    np.testing.assert_allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float), rtol=0,
                               atol=tol)


def test_format_names_are_the_cli_choices():
    from multieye.cli import EXPORT_FORMATS

    assert list(FORMATS) == ["kalibr", "opencv", "urdf", "tf-static", "json", "camera-info",
                             "mrcal"]
    assert list(EXPORT_FORMATS) == list(FORMATS)


def test_json_round_trips_through_read_calibration(result, tmp_path):
    out, rec, _ = result
    (path,) = export(out, "json", dest=tmp_path)
    assert path == tmp_path / "calibration.json"
    assert "\n" not in path.read_text().rstrip("\n")          # compact: one line
    back = read_calibration(path)
    assert (back.setup, back.method, back.reference_camera) == (rec.setup, rec.method,
                                                                rec.reference_camera)
    _near(back.Y, rec.Y, 0)
    assert [c.name for c in back.cameras] == list(NAMES)
    for a, b in zip(back.cameras, rec.cameras):
        _near(a.X, b.X, 0)
        _near(a.T_ref_cam, b.T_ref_cam, 0)
        assert a.rejected == b.rejected and a.measurements_used == b.measurements_used
        assert [r.item for r in a.rejected] == ["blurred.png", "lonely.png"]
    assert back.warnings == rec.warnings


def test_kalibr_round_trips_through_read_camchain(result):
    out, rec, _ = result
    (path,) = export(out, "kalibr")
    assert path == out / "export" / "camchain.yaml"
    chain = read_camchain(path)
    assert [c.name for c in chain] == list(NAMES)
    T0 = rec.cameras[0].T_ref_cam                  # the chain's poses are relative to cam0
    for entry, cam in zip(chain, rec.cameras):
        _near(entry.T_ref_cam, g.inv(T0) @ cam.T_ref_cam)
        assert entry.intrinsics.width == 640 and entry.intrinsics.model == "pinhole"
    _near(chain[1].intrinsics.K, [[510, 0, 319.5], [0, 511, 239.5], [0, 0, 1]], 0)
    _near(chain[2].intrinsics.dist, [-0.2, 0.05, 1e-4, -2e-4], 0)


def test_opencv_filestorage_is_read_by_cv2(result):
    cv2 = pytest.importorskip("cv2")
    out, rec, _ = result
    (path,) = export(out, "opencv")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        assert fs.isOpened()
        y_key, x_key = ("T_marker_target", "T_world_cam") if rec.setup == "eye-to-base" else (
            "T_world_target", "T_body_cam")
        assert fs.getNode("setup").string() == rec.setup
        assert fs.getNode("reference_camera").string() == "cam0"
        assert fs.getNode("base_frame").string() == BASE_FRAME[rec.setup]
        _near(fs.getNode(y_key).mat(), rec.Y)
        cams = fs.getNode("cameras")
        assert cams.size() == len(NAMES)
        for j, cam in enumerate(rec.cameras):
            node = cams.at(j)
            assert node.getNode("name").string() == cam.name
            _near(node.getNode("T_ref_cam").mat(), cam.T_ref_cam)
            _near(node.getNode(x_key).mat(), cam.X)
            _near(node.getNode("camera_matrix").mat(),
                  [[500 + 10 * j, 0, 319.5], [0, 501 + 10 * j, 239.5], [0, 0, 1]])
            _near(node.getNode("distortion_coefficients").mat(), [[-0.2, 0.05, 1e-4, -2e-4]])
            assert node.getNode("distortion_model").string() == "plumb_bob"
            assert node.getNode("camera_model").string() == "pinhole"
            assert (node.getNode("image_width").real(), node.getNode("image_height").real()) == (
                640, 480)
    finally:
        fs.release()


def test_opencv_without_details_has_extrinsics_only(result, tmp_path):
    cv2 = pytest.importorskip("cv2")
    out, rec, _ = result
    (tmp_path / "calibration.json").write_bytes((out / "calibration.json").read_bytes())
    (path,) = export(tmp_path, "opencv")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        node = fs.getNode("cameras").at(1)
        _near(node.getNode("T_ref_cam").mat(), rec.cameras[1].T_ref_cam)
        assert node.getNode("camera_matrix").empty()
    finally:
        fs.release()


def test_urdf_joints_give_back_every_camera_pose(result):
    out, rec, _ = result
    (path,) = export(out, "urdf")
    root = ET.parse(path).getroot()
    assert root.tag == "robot"
    base = BASE_FRAME[rec.setup]
    links = [link.get("name") for link in root.iter("link")]
    assert links[0] == base and len(links) == 1 + 2 * len(NAMES)
    joints = read_urdf_joints(path)
    assert all(j.get("type") == "fixed" for j in root.iter("joint"))
    for cam in rec.cameras:
        link, optical = f"{ros_name(cam.name)}_link", f"{ros_name(cam.name)}_optical_frame"
        assert {link, optical} <= set(links)
        T = joints[(base, link)] @ joints[(link, optical)]
        _near(T, cam.X)                            # T_world_cam (or T_body_cam)
        _near(joints[(link, optical)], T_LINK_OPTICAL)


def test_tf_static_lines_give_back_every_camera_pose(result):
    out, rec, _ = result
    (path,) = export(out, "tf-static")
    lines = [ln for ln in path.read_text().splitlines() if ln.startswith("ros2 ")]
    assert len(lines) == len(NAMES)
    flags = [w for w in shlex.split(lines[0]) if w.startswith("--")]
    assert flags == ["--x", "--y", "--z", "--qx", "--qy", "--qz", "--qw", "--frame-id",
                     "--child-frame-id"]
    assert shlex.split(lines[0])[:4] == ["ros2", "run", "tf2_ros", "static_transform_publisher"]
    transforms = read_tf_static(path)
    base = BASE_FRAME[rec.setup]
    assert set(transforms) == {(base, f"{ros_name(c.name)}_optical_frame") for c in rec.cameras}
    for cam in rec.cameras:
        _near(transforms[(base, f"{ros_name(cam.name)}_optical_frame")], cam.X)


def test_exports_match_the_true_rig_on_exact_data(result):
    """Noise-free measurements: the exported poses are the true ones, not just self-consistent."""
    out, rec, truth = result
    export(out, "tf-static")
    transforms = read_tf_static(out / "export" / "static_transforms.sh")
    base = BASE_FRAME[rec.setup]
    for j, name in enumerate(NAMES):
        _near(transforms[(base, f"{ros_name(name)}_optical_frame")], truth["X"][j], 1e-8)


def test_urdf_rpy_is_fixed_axis_roll_pitch_yaw():
    r, p, y = 0.3, -0.7, 2.1
    R = rotation_from_rpy((r, p, y))
    _near(R, Rotation.from_euler("xyz", [r, p, y]).as_matrix(), 1e-15)  # extrinsic x, y, z
    _near(rotation_from_rpy((0, 0, np.pi / 2)) @ [1, 0, 0], [0, 1, 0], 1e-15)  # yaw about z
    _near(rotation_from_rpy((np.pi / 2, 0, 0)) @ [0, 1, 0], [0, 0, 1], 1e-15)  # roll about x


def test_optical_frame_axes_follow_rep_103():
    R = T_LINK_OPTICAL[:3, :3]       # columns: optical x, y, z in the link frame
    _near(R[:, 2], [1, 0, 0], 1e-15)  # optical z (forward) = link x (forward)
    _near(R[:, 0], [0, -1, 0], 1e-15)  # optical x (right) = link -y
    _near(R[:, 1], [0, 0, -1], 1e-15)  # optical y (down) = link -z


@settings(max_examples=200, deadline=None)
@given(st.floats(-np.pi, np.pi), st.one_of(st.floats(-np.pi / 2, np.pi / 2),
                                             st.sampled_from([np.pi / 2, -np.pi / 2,
                                                              np.pi / 2 - 1e-9])),
       st.floats(-np.pi, np.pi))
def test_rpy_round_trip_including_gimbal_lock(roll, pitch, yaw):
    R = rotation_from_rpy((roll, pitch, yaw))
    _near(rotation_from_rpy(rpy_from_rotation(R)), R, 1e-9)


def test_unknown_format_lists_the_formats(result):
    out, _, _ = result
    with pytest.raises(InputError, match="unknown export format 'ply'; expected one of kalibr, "
                                         "opencv, urdf, tf-static, json"):
        export(out, "ply")


def test_missing_calibration_names_the_file(tmp_path):
    with pytest.raises(DatasetError, match=r"calibration\.json: calibration file not found"):
        export(tmp_path, "urdf")


def test_kalibr_without_details_says_where_the_intrinsics_are(result, tmp_path):
    out, _, _ = result
    (tmp_path / "calibration.json").write_bytes((out / "calibration.json").read_bytes())
    with pytest.raises(DatasetError, match=r"details\.json: the intrinsics are in details\.json"):
        export(tmp_path, "kalibr")
    assert not (tmp_path / "export" / "camchain.yaml").exists()


def test_tf_reader_names_the_line_of_a_bad_value(tmp_path):
    path = tmp_path / "tf.sh"
    path.write_text("# comment\nros2 run tf2_ros static_transform_publisher --x 1 --y oops "
                    "--frame-id a --child-frame-id b\n")
    with pytest.raises(DatasetError, match=r"tf\.sh:2: translation and quaternion values must "
                                           "be numbers"):
        read_tf_static(path)
    path.write_text("static_transform_publisher --x 1 --qw 2 --frame-id a --child-frame-id b\n")
    with pytest.raises(DatasetError, match=r"tf\.sh:1: quaternion norm is 2, expected 1"):
        read_tf_static(path)
    path.write_text("static_transform_publisher --x 1 --frame-id a\n")
    with pytest.raises(DatasetError, match=r"tf\.sh:1: expected --x --y --z"):
        read_tf_static(path)


def test_urdf_reader_rejects_a_short_origin(tmp_path):
    path = tmp_path / "r.urdf"
    path.write_text('<robot name="r"><joint name="j" type="fixed"><parent link="a"/>'
                    '<child link="b"/><origin xyz="1 2" rpy="0 0 0"/></joint></robot>')
    with pytest.raises(DatasetError, match="joint 'j': origin xyz must be 3 numbers, got '1 2'"):
        read_urdf_joints(path)


def test_json_export_is_the_record_not_a_copy_of_the_file(result, tmp_path):
    """The compact export is re-serialised from the validated record (same keys)."""
    out, _, _ = result
    (path,) = export(out, "json", dest=tmp_path)
    assert json.loads(path.read_text()) == json.loads((out / "calibration.json").read_text())


#: The fields of ROS sensor_msgs/CameraInfo YAML as camera_calibration_parsers writes and
#: reads them, with the shape of each matrix.
CAMERA_INFO_SCHEMA = {"image_width": int, "image_height": int, "camera_name": str,
                      "camera_matrix": (3, 3), "distortion_model": str,
                      "distortion_coefficients": (1, None), "rectification_matrix": (3, 3),
                      "projection_matrix": (3, 4)}


def test_camera_info_per_camera_follows_ros_and_reads_back(result):
    yaml = pytest.importorskip("yaml")
    from multieye.io.intrinsics_files import read_camera_info

    out, rec, _ = result
    notes = []
    paths = export(out, "camera-info", notes=notes)
    # k1 k2 p1 p2 lenses: ROS's plumb_bob holds five, so they read back as another model
    assert notes == [f"camera_info of {', '.join(NAMES)}: pinhole-radtan4 lens written as "
                     "ROS's plumb_bob with k3 = 0 (the same projection); read back it is "
                     "pinhole-radtan, pinhole-radtan4 with rig.yaml's model: pinhole-radtan4"]
    # names as file names (docs/outputs.md, section 1): < > " cannot be in a Windows file name
    files = ["cam0.yaml", "front left.yaml", "rear_&__q_.yaml"]
    assert paths == [out / "export" / "camera_info" / f for f in files]
    for j, (path, cam) in enumerate(zip(paths, rec.cameras)):
        data = yaml.safe_load(path.read_text())
        assert set(data) == set(CAMERA_INFO_SCHEMA)
        for key, kind in CAMERA_INFO_SCHEMA.items():
            if isinstance(kind, type):
                assert isinstance(data[key], kind), key
            else:
                m = data[key]
                assert set(m) == {"rows", "cols", "data"}
                assert m["rows"] == kind[0] and (kind[1] is None or m["cols"] == kind[1])
                assert len(m["data"]) == m["rows"] * m["cols"]
        assert data["camera_name"] == cam.name
        assert data["distortion_model"] == "plumb_bob"
        assert data["distortion_coefficients"]["data"] == [-0.2, 0.05, 1e-4, -2e-4, 0.0]
        K = np.reshape(data["camera_matrix"]["data"], (3, 3))
        _near(np.reshape(data["projection_matrix"]["data"], (3, 4)), np.hstack([K, np.zeros((3, 1))]), 0)
        _near(np.reshape(data["rectification_matrix"]["data"], (3, 3)), np.eye(3), 0)
        back = read_camera_info(path)
        _near(back.K, [[500 + 10 * j, 0, 319.5], [0, 501 + 10 * j, 239.5], [0, 0, 1]], 0)
        _near(back.dist, [-0.2, 0.05, 1e-4, -2e-4, 0.0], 0)
        assert (back.width, back.height, back.model) == (640, 480, "pinhole")


def test_camera_info_without_details_says_so(result, tmp_path):
    out, _, _ = result
    (tmp_path / "calibration.json").write_bytes((out / "calibration.json").read_bytes())
    with pytest.raises(DatasetError, match="details.json"):
        export(tmp_path, "camera-info")


def test_camera_info_export_through_the_cli_is_known_to_the_output_folder(result):
    from click.testing import CliRunner

    from multieye.cli import main
    from multieye.outputs.folder import foreign_files

    out, _, _ = result
    res = CliRunner().invoke(main, ["export", str(out), "--format", "camera-info"])
    assert res.exit_code == 0, res.output
    assert len(res.stdout.splitlines()) == len(NAMES)          # the files; the note apart
    assert res.stderr.startswith(f"note: camera_info of {', '.join(NAMES)}: pinhole-radtan4")
    assert foreign_files(out) == []


def test_urdf_loads_in_urdf_parser_py(result):
    urdf = pytest.importorskip("urdf_parser_py.urdf")
    out, rec, _ = result
    (path,) = export(out, "urdf")
    robot = urdf.URDF.from_xml_string(path.read_bytes())
    base = BASE_FRAME[rec.setup]
    assert robot.get_root() == base
    assert {j.type for j in robot.joints} == {"fixed"}
    for cam in rec.cameras:
        chain = robot.get_chain(base, f"{ros_name(cam.name)}_optical_frame", links=False)
        T = np.eye(4)
        for name in chain:
            joint = robot.joint_map[name]
            T = T @ g.make_transform(rotation_from_rpy(joint.origin.rpy), joint.origin.xyz)
        _near(T, cam.X)


def test_frames_overridden_by_parent_and_child_frame(result):
    from click.testing import CliRunner

    from multieye.cli import main

    out, rec, _ = result
    res = CliRunner().invoke(main, ["export", str(out), "--format", "urdf", "--parent-frame",
                                    "base_link", "--child-frame", "rig/{camera}"])
    assert res.exit_code == 0, res.output
    joints = read_urdf_joints(out / "export" / "cameras.urdf")
    (path,) = export(out, "tf-static", parent_frame="base_link", child_frame="rig/{camera}")
    transforms = read_tf_static(path)
    for cam in rec.cameras:
        link, optical = f"rig/{ros_name(cam.name)}_link", f"rig/{ros_name(cam.name)}_optical_frame"
        _near(joints[("base_link", link)] @ joints[(link, optical)], cam.X)
        _near(transforms[("base_link", optical)], cam.X)
    (path,) = export(out, "opencv", parent_frame="base_link")
    assert 'base_frame: "base_link"' in path.read_text()


@pytest.mark.parametrize("parent, child, message", [
    ("", None, "non-empty"), ("a b", None, "white space"), ("/world", None, "leading"),
    (None, "cam", "must contain {camera}"), ("cam0_link", None, "give another --parent-frame")])
def test_bad_frame_names_are_refused_before_writing(result, tmp_path, parent, child, message):
    out, _, _ = result
    with pytest.raises(InputError, match=message):
        export(out, "urdf", dest=tmp_path / "x", parent_frame=parent, child_frame=child)
    assert not (tmp_path / "x" / "cameras.urdf").exists()


def test_the_base_is_the_world_or_the_tracked_frame_of_the_pose(result, tmp_path):
    out, rec, _ = result
    tracked = "marker" if rec.setup == "eye-to-base" else "body"
    assert rec.frames == {"world": "world", tracked: tracked}    # rig.yaml's default pose
    if rec.setup == "eye-to-base":      # static cameras: the world, whatever is tracked
        parents = {p for p, _ in read_tf_static(export(out, "tf-static",
                                                       dest=tmp_path / "e2b")[0])}
        assert "world" in parents and not parents & {"marker", "body"}
        return
    data = json.loads((out / "calibration.json").read_text())
    (tmp_path / "details.json").write_text(
        (out / "details.json").read_text().replace("T_world_body", "T_world_marker"))
    data["frames"] = {"world": "base", "body": "tool0"}        # rig.yaml's pose: T_base_tool0
    (tmp_path / "calibration.json").write_text(json.dumps(data))
    assert {p for p, _ in read_tf_static(export(tmp_path, "tf-static")[0])} == {"tool0"}
    del data["frames"]                  # a calibration.json of an earlier version
    (tmp_path / "calibration.json").write_text(json.dumps(data))
    assert {p for p, _ in read_tf_static(export(tmp_path, "tf-static")[0])} == {"marker"}
    (tmp_path / "details.json").unlink()
    transforms = read_tf_static(export(tmp_path, "tf-static")[0])
    assert {p for p, _ in transforms} == {"body"}


def test_camera_names_become_ros_frame_names():
    assert [ros_name(n) for n in NAMES] == ["cam0", "front_left", "rear____q_"]
    assert ros_name("0") == "cam_0" and ros_name("ü") == "cam__"


def test_cameras_whose_names_clean_to_one_frame_are_refused_where_frames_are_named(result,
                                                                                 tmp_path):
    """'front left' and 'front_left' are both the ROS frame front_left_link: urdf and tf-static are
    refused naming both cameras and what to do; the formats that name no camera frame are
    written (every format was refused, with the list of frames only)."""
    out, rec, _ = result
    data = json.loads((out / "calibration.json").read_text())
    data["cameras"]["front_left"] = data["cameras"]["cam0"]
    (tmp_path / "calibration.json").write_text(json.dumps(data))
    for fmt in ("urdf", "tf-static"):
        with pytest.raises(InputError, match=r"cameras 'front left' and 'front_left' are both the "
                           r"frame front_left_link .*rename one in rig.yaml"):
            export(tmp_path, fmt)
    assert not (tmp_path / "export").exists()
    for fmt in ("json", "opencv"):
        assert export(tmp_path, fmt)


#: Kalibr's camchain keys (kalibr_common.ConfigReader.CameraParameters / CameraChainParameters)
#: and what each holds; camera_name is multieye's own, which Kalibr ignores.
KALIBR_SCHEMA = {"camera_model": str, "intrinsics": list, "distortion_model": str,
                 "distortion_coeffs": list, "resolution": list, "T_cn_cnm1": list,
                 "rostopic": str, "cam_overlaps": list, "camera_name": str}


def _check_kalibr_schema(data: dict) -> None:
    assert list(data) == [f"cam{n}" for n in range(len(data))]
    for n, entry in enumerate(data.values()):
        assert set(entry) <= set(KALIBR_SCHEMA)
        required = {"camera_model", "intrinsics", "distortion_model", "distortion_coeffs",
                    "rostopic", "cam_overlaps"} | ({"T_cn_cnm1"} if n else set())
        assert required <= set(entry)
        for key, kind in KALIBR_SCHEMA.items():
            assert key not in entry or isinstance(entry[key], kind), key
        assert entry["camera_model"] == "pinhole"
        assert entry["distortion_model"] in ("radtan", "equidistant", "none")
        assert len(entry["intrinsics"]) == 4 and len(entry["distortion_coeffs"]) == 4
        assert entry["rostopic"].startswith("/") and " " not in entry["rostopic"]
        assert all(isinstance(k, int) and 0 <= k < len(data) and k != n
                   for k in entry["cam_overlaps"])
        if n:
            assert np.shape(entry["T_cn_cnm1"]) == (4, 4)


def test_kalibr_camchains_follow_kalibrs_schema_with_topics_and_overlaps(result):
    yaml = pytest.importorskip("yaml")
    out, _, _ = result
    (path,) = export(out, "kalibr")
    for chain in (path, out / "camchain.yaml"):     # the export and calibrate's own
        data = yaml.safe_load(chain.read_text())
        _check_kalibr_schema(data)
        assert [e["rostopic"] for e in data.values()] == [
            "/cam0/image_raw", "/front_left/image_raw", "/rear____q_/image_raw"]
        assert [e["cam_overlaps"] for e in data.values()] == [[], [], []]  # one at a time
    assert [e.cam_overlaps for e in read_camchain(path)] == [(), (), ()]


def test_kalibr_takes_topics_and_overlaps_from_details(result, tmp_path):
    yaml = pytest.importorskip("yaml")
    out, _, _ = result
    details = json.loads((out / "details.json").read_text())
    cams = details["cameras"]
    cams["cam0"]["topic"] = "/rig/cam0/image_color"
    cams["cam0"]["overlaps"], cams["front left"]["overlaps"] = ["front left"], ["cam0"]
    (tmp_path / "details.json").write_text(json.dumps(details))
    (tmp_path / "calibration.json").write_bytes((out / "calibration.json").read_bytes())
    (path,) = export(tmp_path, "kalibr")
    data = yaml.safe_load(path.read_text())
    _check_kalibr_schema(data)
    assert data["cam0"]["rostopic"] == "/rig/cam0/image_color"
    assert [e["cam_overlaps"] for e in data.values()] == [[1], [0], []]
    back = read_camchain(path)
    assert [e.rostopic for e in back][0] == "/rig/cam0/image_color"
    assert [e.cam_overlaps for e in back] == [(1,), (0,), ()]


def test_kalibr_export_names_each_camera_it_leaves_out(result, tmp_path):
    out, rec, _ = result
    details = json.loads((out / "details.json").read_text())
    del details["cameras"]["front left"]["intrinsics"]
    details["cameras"]["front left"].pop("points", None)
    (tmp_path / "details.json").write_text(json.dumps(details))
    (tmp_path / "calibration.json").write_bytes((out / "calibration.json").read_bytes())
    notes = []
    (path,) = export(tmp_path, "kalibr", notes=notes)
    assert [e.name for e in read_camchain(path)] == ["cam0", NAMES[2]]
    assert path.read_text().startswith("# left out of this camchain: front left (no intrinsics)")
    assert notes == [f"camchain.yaml holds cam0, {NAMES[2]} only; left out: front left "
                     "(no intrinsics)"]


def test_one_note_per_cause_naming_every_camera_it_holds(result, tmp_path):
    """Two cameras whose lens Kalibr cannot hold and one without intrinsics: one entry per
    cause (not one per camera), in the note and in the file's comment."""
    out, rec, _ = result
    details = json.loads((out / "details.json").read_text())
    del details["cameras"]["front left"]["intrinsics"]
    details["cameras"]["front left"].pop("points", None)
    for name in ("cam0", NAMES[2]):
        intr = details["cameras"][name]["intrinsics"]
        intr["dist"] = [0.01, -0.02, 0.0, 0.0, 0.001, 0.002, 0.0, 0.0]
    (tmp_path / "details.json").write_text(json.dumps(details))
    (tmp_path / "calibration.json").write_bytes((out / "calibration.json").read_bytes())
    with pytest.raises(InputError) as info:
        export(tmp_path, "kalibr")
    text = str(info.value)
    assert text.count("Kalibr radtan holds k1 k2 p1 p2 only") == 1, text
    assert text.startswith(f"Kalibr cannot hold any camera: cam0, {NAMES[2]} (Kalibr radtan "
                           "holds k1 k2 p1 p2 only; these intrinsics have 8 non-trivial "
                           "coefficients"), text
    assert text.endswith("; front left (no intrinsics)"), text
    notes = []
    export(tmp_path, "camera-info", notes=notes)
    assert notes == ["no camera_info for front left (no intrinsics)"]


def test_camera_overlaps_compare_used_images_in_the_mocap_clock():
    from types import SimpleNamespace as NS

    from multieye.outputs.details import camera_overlaps

    def cam(name, stamps, offset, tol):
        return (NS(name=name, time_offset_s=offset, links=None),   # a record of version 1
                NS(time_offset=0.0, time_tolerance=tol),
                NS(observations=[NS(stamp=t) for t in stamps]))

    cams = [cam("a", [1.0, 2.0], 0.0, 0.01), cam("b", [11.995], -10.0, 0.01),
            cam("c", [2.5], None, 0.01)]
    run = NS(record=NS(cameras=[c[0] for c in cams]),
             cameras={c[0].name: c[1] for c in cams}, paired={c[0].name: c[2] for c in cams})
    assert camera_overlaps(run) == {"a": ("b",), "b": ("a",), "c": ()}
