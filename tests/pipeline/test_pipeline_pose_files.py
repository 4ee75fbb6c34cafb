"""Poses matched to images by name (issue 14, item 1): one pose file beside each image, on a
rendered rig against the same data paired in time, on the command line (bad pose files:
one line naming the file, exit 2), and on the published robot data sets as they are."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from multieye.cli import main
from multieye.estimate.pairing import pair_in_time
from multieye.io import list_images, read_tum
from multieye.pipeline import calibrate

from small_dataset import render_small

RIG_HEAD = """setup: eye-to-base
target: {type: chessboard, rows: 6, cols: 9, spacing: 0.05}
"""


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    folder = tmp_path_factory.mktemp("small")
    render_small(folder)
    return folder


def _by_name(rendered: Path, out: Path, mocap: str, write) -> Path:
    """The rendered rig with images named ``img<k>`` and, beside each, its motion-capture
    pose (as the time pairing finds it) written by ``write(path_without_suffix, T)``."""
    out.mkdir()
    traj = read_tum(rendered / "mocap.txt")
    for cam in ("cam0", "cam1"):
        images = list_images(rendered / cam)
        p = pair_in_time(traj.stamps, traj.T, np.array([s for s, _, _ in images]),
                         tolerance=0.0167)
        (out / cam).mkdir()
        for k, i in enumerate(p.index):
            shutil.copy(images[i][2], out / cam / f"img{k}.png")
            write(out / cam / f"img{k}", p.T[k])
        shutil.copy(rendered / f"{cam}.yaml", out / f"{cam}.yaml")
    (out / "rig.yaml").write_text(
        RIG_HEAD + f"mocap: {mocap}\ncameras:\n  cam0: {{intrinsics: cam0.yaml, images: cam0/}}\n"
        "  cam1: {intrinsics: cam1.yaml, images: cam1/}\n")
    return out


def _json(path, T):
    path.with_suffix(".json").write_text(json.dumps({"end2base": T.tolist(), "other": 1}))


def _euler_mm(path, T):
    angles = Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
    path.with_suffix(".txt").write_text(
        "\n".join(f"{v:.10f}" for v in [*angles, *(T[:3, 3] * 1000)]) + "\n")


@pytest.mark.parametrize("mocap, write", [
    ('{file: "{stem}.json", key: end2base}', _json),
    ('{file: "{stem}.txt", values: [rx, ry, rz, x, y, z], rotation: euler-xyz-deg, unit: mm}',
     _euler_mm),
])
def test_by_name_gives_the_time_paired_result(rendered, tmp_path, mocap, write):
    in_time = calibrate(rendered, processes=1)
    by_name = calibrate(_by_name(rendered, tmp_path / "ds", mocap, write), processes=1)
    for a, b in zip(in_time.closed_form.X, by_name.closed_form.X):
        np.testing.assert_allclose(a, b, atol=1e-6)
    assert [c.measurements_used for c in by_name.record.cameras] == [
        c.measurements_used for c in in_time.record.cameras]
    assert all(c.rejected == () for c in by_name.record.cameras)


def test_table_matched_by_image_name(rendered, tmp_path):
    """One table, rows matched by the image column: OptiTrack's w x y z quaternions, mm."""
    rows = []

    def collect(path, T):
        q = Rotation.from_matrix(T[:3, :3]).as_quat()
        rows.append(f"{path.name}.png"
                    f",{q[3]:.12f},{q[0]:.12f},{q[1]:.12f},{q[2]:.12f}"
                    + "".join(f",{v * 1000:.9f}" for v in T[:3, 3]))

    ds = _by_name(rendered, tmp_path / "ds", "{file: cam0/poses.csv, match: image, "
                  "values: [qw, qx, qy, qz, x, y, z], rotation: quaternion-wxyz, unit: mm}",
                  collect)
    n0 = len(list((ds / "cam0").glob("*.png")))
    (ds / "cam0" / "poses.csv").write_text("image,qw,qx,qy,qz,x,y,z\n" + "\n".join(rows[:n0])
                                           + "\n")
    (ds / "cam1" / "poses.csv").write_text("image,qw,qx,qy,qz,x,y,z\n" + "\n".join(rows[n0:])
                                           + "\nimg77.png,1,0,0,0,0,0,0\n")
    text = (ds / "rig.yaml").read_text().replace(
        "images: cam1/}", "images: cam1/, mocap: {file: cam1/poses.csv}}")
    (ds / "rig.yaml").write_text(text)
    in_time = calibrate(rendered, processes=1)
    by_name = calibrate(ds, processes=1)
    for a, b in zip(in_time.closed_form.X, by_name.closed_form.X):
        np.testing.assert_allclose(a, b, atol=1e-6)
    assert by_name.record.cameras[0].rejected == ()
    assert [(r.item, r.reason) for r in by_name.record.cameras[1].rejected] == [
        (f"poses.csv line {len(rows) - n0 + 2}", "pose row without an image: img77.png")]


def test_table_in_image_order_as_kuka_writes_it(rendered, tmp_path):
    """KUKA's RobotPosesVec.txt: no header, no image names, one row per image in the images'
    name order (img2 before img10), 16 numbers of a row-major 4x4 in mm (``match: order``);
    the same rows matched by an image column, and the poses paired in time, give one answer."""
    poses = {}
    ds = _by_name(rendered, tmp_path / "order", "{file: cam0/RobotPosesVec.txt, match: order, "
                  "unit: mm}", lambda path, T: poses.__setitem__(path, T))
    text = (ds / "rig.yaml").read_text().replace(
        "images: cam1/}", "images: cam1/, mocap: {file: cam1/RobotPosesVec.txt}}")
    (ds / "rig.yaml").write_text(text)
    mine = {}
    for cam in ("cam0", "cam1"):           # img0 img5 img10 ...: name order is not the order
        stems = sorted((p for p in poses if p.parent.name == cam), key=lambda p: int(p.name[3:]))
        mine[cam] = [ds / cam / f"img{5 * k}" for k in range(len(stems))]     # of characters
        for k, stem in reversed(list(enumerate(stems))):
            stem.with_suffix(".png").rename(mine[cam][k].with_suffix(".png"))
        mine[cam] = [(p, poses[stem]) for p, stem in zip(mine[cam], stems)]
        assert sorted(p.name for p, _ in mine[cam]) != [p.name for p, _ in mine[cam]]
    by_image = tmp_path / "image"
    shutil.copytree(ds, by_image)
    (by_image / "rig.yaml").write_text(text.replace("RobotPosesVec.txt", "poses.txt").replace(
        "match: order", "match: image"))
    for cam in ("cam0", "cam1"):
        mm = [T.ravel() * np.where(np.isin(np.arange(16), (3, 7, 11)), 1000, 1)
              for _, T in mine[cam]]                                             # t in mm
        (ds / cam / "RobotPosesVec.txt").write_text(
            "".join(" ".join(f"{v:.12g}" for v in row) + "\n" for row in mm))
        (by_image / cam / "poses.txt").write_text(
            "image " + " ".join(f"m{k}" for k in range(16)) + "\n" + "".join(
                f"{p.name}.png " + " ".join(f"{v:.12g}" for v in row) + "\n"
                for (p, _), row in reversed(list(zip(mine[cam], mm)))))
    in_time = calibrate(rendered, processes=1)
    by_order, matched = calibrate(ds, processes=1), calibrate(by_image, processes=1)
    for a, b, c in zip(in_time.closed_form.X, by_order.closed_form.X, matched.closed_form.X):
        np.testing.assert_allclose(b, c, atol=1e-12)
        np.testing.assert_allclose(a, b, atol=1e-6)
    assert [c.measurements_used for c in by_order.record.cameras] == [
        c.measurements_used for c in in_time.record.cameras]
    assert all(c.rejected == () for c in by_order.record.cameras)


def test_stamped_table_in_its_own_order(rendered, tmp_path):
    """Motion capture paired in time, written as t qw qx qy qz x y z in millimetres."""
    ds = tmp_path / "ds"
    shutil.copytree(rendered, ds)
    traj = read_tum(rendered / "mocap.txt")
    q = Rotation.from_matrix(traj.T[:, :3, :3]).as_quat()
    (ds / "mocap.txt").write_text("".join(
        f"{repr(float(t))} {w!r} {x!r} {y!r} {z!r} " + " ".join(repr(float(v) * 1000)
                                                                  for v in T[:3, 3]) + "\n"
        for t, (x, y, z, w), T in zip(traj.stamps, q.tolist(), traj.T)))
    text = (ds / "rig.yaml").read_text().replace(
        "  file: mocap.txt\n", "  file: mocap.txt\n  values: [t, qw, qx, qy, qz, x, y, z]\n"
        "  rotation: quaternion-wxyz\n  unit: mm\n")
    assert "quaternion-wxyz" in text
    (ds / "rig.yaml").write_text(text)
    a, b = calibrate(rendered, processes=1), calibrate(ds, processes=1)
    for Xa, Xb in zip(a.closed_form.X, b.closed_form.X):
        np.testing.assert_allclose(Xa, Xb, atol=1e-6)


def test_missing_and_orphan_pose_files_are_listed(rendered, tmp_path):
    ds = _by_name(rendered, tmp_path / "ds", '{file: "{stem}.json", key: end2base}', _json)
    (ds / "cam0" / "img3.json").unlink()
    (ds / "cam0" / "img99.json").write_text("{}")       # not read: no image img99
    # any names: images need no time stamps, and a clock offset does not apply
    text = (ds / "rig.yaml").read_text().replace("images: cam0/}", "images: cam0/, "
                                                 "time_offset: 5.0}")
    (ds / "rig.yaml").write_text(text)
    run = calibrate(ds, processes=1, time_offset="auto")
    cam = run.record.cameras[0]
    reasons = {r.item: r.reason for r in cam.rejected}
    assert reasons == {"img3.png": "no pose file img3.json",
                       "img99.json": "pose file without an image img99.*"}
    n = len(list((ds / "cam0").glob("*.png")))
    assert cam.measurements_used == n - 1


def _fails(ds, out, *expected):
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out)])
    assert res.exit_code == 2, (res.exit_code, res.stdout, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    for text in expected:
        assert text in lines[0], lines[0]
    assert not (out / "calibration.json").exists()


def _bad_dataset(tmp_path, mocap: str, files: dict) -> Path:
    ds = tmp_path / "bad"
    (ds / "cam0").mkdir(parents=True)
    for k in range(3):
        (ds / "cam0" / f"{k}.png").write_bytes(b"")       # never read: the poses fail first
    for name, content in files.items():
        (ds / "cam0" / name).write_text(content)
    (ds / "cam0.yaml").write_text(
        "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n")
    (ds / "rig.yaml").write_text(RIG_HEAD + f"mocap: {mocap}\n"
                                 "cameras:\n  cam0: {intrinsics: cam0.yaml, images: cam0/}\n")
    return ds


@pytest.mark.parametrize("mocap, content, expected", [
    ('{file: "{stem}.json", key: end2base}', '{"base2end": []}',
     "no key 'end2base' (mocap.key); its keys: base2end"),
    ('{file: "{stem}.txt", values: [rx, ry, rz, x, y, z], rotation: euler-xyz-deg}',
     "1 2 3 4 5\n", "expected 6 numbers (rx ry rz x y z; rotation euler-xyz-deg), got 5"),
    ('{file: "{stem}.json", key: T}', '{"T": [[1,0,0,0],[0,2,0,0],[0,0,1,0],[0,0,0,1]]}',
     "expected a rotation matrix (orthonormal, det 1)"),
    ('{file: "{stem}.txt"}', "0 0 0 0 0 0 3\n", "quaternion (qx qy qz qw) must have"),
])
def test_bad_pose_files_exit_2_naming_the_file(tmp_path, mocap, content, expected):
    suffix = ".json" if ".json" in mocap else ".txt"
    ds = _bad_dataset(tmp_path, mocap, {f"{k}{suffix}": content for k in range(3)})
    _fails(ds, tmp_path / "out", f"{ds / 'cam0' / ('0' + suffix)}: camera cam0: {expected}")


@pytest.mark.parametrize("mocap, expected", [
    ('{file: "{stem}.txt", rotation: euler-xyz}',
     "rig.yaml:3: mocap.rotation: expected one of quaternion-xyzw"),
    ('{file: "{stem}.txt", values: [x, y, z, a, b, c], rotation: rotvec}',
     "rig.yaml:3: mocap.values: expected each of x, y, z, rx, ry, rz once"),
    ('{file: cam0/mocap.txt, key: end2base}',
     "rig.yaml:3: mocap.key: applies to pose-files sources only (this one is tum)"),
    ('{file: "{stem}.txt", format: tum}', "mocap.format: a file name with {stem}"),
    ('{file: cam0/mocap.txt, values: [x, y, z, qx, qy, qz, qw]}',
     "rig.yaml:3: mocap.values: expected each of t, x, y, z, qw, qx, qy, qz once"),
    ('{file: cam0/mocap.txt, format: csv, rotation: rotvec}',
     "mocap.rotation: applies to pose-files, pose-table, tum sources only (this one is csv)"),
    ('{file: cam0/mocap.txt, match: name}',
     "rig.yaml:3: mocap.match: expected one of time, image, order"),
    ('{file: cam0/mocap.txt, match: image, format: tum}',
     "mocap.match: match: image reads a table with an 'image' column; leave out 'format'"),
    ('{file: cam0/mocap.txt, match: image}',
     "cam0/mocap.txt:1: camera cam0: expected a header with a column 'image' (match: image)"),
    ('{file: cam0/mocap.txt, match: order, format: tum}',
     "mocap.match: match: order reads a table in image-name order; leave out 'format'"),
    ('{file: cam0/mocap.txt, match: order}',
     "cam0/mocap.txt:1: camera cam0: expected the numbers x, y, z, qx, qy, qz, qw (rotation "
     "quaternion-xyzw), or 16 (or 12) numbers of a 4x4 matrix, got 8 numbers"),
    ('{file: cam0/mocap.txt, match: order, rotation: matrix}',
     "cam0/mocap.txt:1: camera cam0: expected 16 numbers (a 4x4 pose, row-major) or 12, got 8"),
])
def test_bad_pose_file_keys_exit_2_at_their_line(tmp_path, mocap, expected):
    ds = _bad_dataset(tmp_path, mocap, {"mocap.txt": "0 0 0 0 0 0 0 1\n"})
    _fails(ds, tmp_path / "out", expected)


def test_order_table_with_another_count_of_rows_exit_2_naming_both(tmp_path):
    ds = _bad_dataset(tmp_path, "{file: cam0/RobotPosesVec.txt, match: order}",
                      {"RobotPosesVec.txt": "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n" * 2})
    _fails(ds, tmp_path / "out", "cam0/RobotPosesVec.txt: camera cam0: match: order pairs row "
           "k with image k, but the table has 2 pose rows and cam0/ 3 images")


# --------------------------------------------------------------------------- published data


def _rig(folder: Path, text: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "rig.yaml").write_text(text)
    return folder


def test_open3dv_pose_files_as_published(shared_data, tmp_path):
    """pos<k>.bmp + pos<k>.txt (Rx Ry Rz degrees, X Y Z mm); the published intrinsics
    (param.txt, a bare list of numbers) are the only file the test writes besides rig.yaml."""
    from real_datasets import _param_intrinsics

    from multieye.io import write_opencv_intrinsics

    src = shared_data / "open3dv_eih" / "input_EyeInHand"
    write_opencv_intrinsics(tmp_path / "cam0.yaml", _param_intrinsics(src, 1920, 1200))
    run = calibrate(_rig(tmp_path, (
        "setup: eye-on-hand\n"
        "target: {type: asymmetric-circles, rows: 11, cols: 7, spacing: 0.02}\n"
        'mocap: {file: "{stem}.txt", values: [rx, ry, rz, x, y, z], rotation: euler-xyz-deg, '
        "unit: mm}\n"
        f"cameras:\n  cam0: {{intrinsics: cam0.yaml, images: {src}}}\n")), processes=1)
    cam = run.record.cameras[0]
    assert run.doubts == () and cam.measurements_used == 8
    assert [r.item for r in cam.rejected] == ["param.txt"]      # a .txt without an image
    np.testing.assert_allclose(run.closed_form.X[0][:3, 3] * 1e3, [220.5, 68.4, -177.7], atol=2.0)
    assert run.record.residuals.e_t_m < 1e-3


def test_yizhong_eye_in_hand_json_as_published(shared_data, tmp_path):
    src = shared_data / "yizhong_toolkit" / "sample_data" / "eye_in_hand_test_data"
    run = calibrate(_rig(tmp_path, (
        "setup: eye-on-hand\n"
        "target: {type: chessboard, rows: 8, cols: 11, spacing: 0.02}\n"
        'mocap: {file: "{stem}.json", key: end2base}\n'
        f"cameras:\n  cam0: {{model: pinhole-radtan, images: {src}}}\n")), processes=1)
    cam = run.record.cameras[0]
    assert run.doubts == () and cam.measurements_used == 6
    assert [r.item for r in cam.rejected] == ["chessboard_config.json"]
    assert run.record.residuals.e_R_deg < 0.5 and run.record.residuals.e_t_m < 2e-3
    # the camera in the end effector's frame, as PROVENANCE.md's independent check (m)
    np.testing.assert_allclose(run.closed_form.X[0][:3, 3], [0.100, -0.001, 0.145], atol=0.015)


def test_yizhong_eye_to_hand_single_aruco_marker(shared_data, tmp_path):
    """The marker (id 0, 53 mm, DICT_6X6_250) on the robot, the camera static; the lens from
    the same images and the published ArUco grid views (6 x 4 markers)."""
    data = shared_data / "yizhong_toolkit" / "sample_data"
    run = calibrate(_rig(tmp_path, (
        "setup: eye-to-base\n"
        "target: {type: aruco, marker_size: 0.053, dictionary: DICT_6X6_250, id: 0}\n"
        'mocap: {file: "{stem}.json", pose: T_world_marker, key: end2base}\n'
        "cameras:\n  cam0:\n    model: pinhole-radtan\n"
        f"    images: {data / 'eye_to_hand_test_data'}\n"
        f"    intrinsics_images: {data / 'intrinsic_calib_grid_test_images'}\n"
        "    intrinsics_target: {type: aruco-grid, rows: 4, cols: 6, marker_size: 0.030863157,\n"
        "                        marker_separation: 0.007715789, dictionary: DICT_6X6_250}\n")),
        processes=1)
    cam = run.record.cameras[0]
    assert run.doubts == () and cam.measurements_used == 8          # the marker in every image
    # the 7 grid views start the lens with the 8 marker views: none is rejected as a bad fit
    # of a start from the 8 x 4 marker corners alone (two were, at 11.0 and 7.8 px)
    assert [r.item for r in cam.rejected] == ["chessboard_config.json"]
    # PROVENANCE.md's check with OpenCV's intrinsics: 1.9 deg, 2.0 mm median residual; the
    # loop residuals are those of the final lens, 0.284 deg, 1.77 mm (they took the marker
    # poses of the starting lens before, 0.97 deg, 5.35 mm): docs/results/robot_sets.md
    assert run.record.residuals.e_R_deg < 0.5 and run.record.residuals.e_t_m < 2.5e-3
    lens = run.refinement.intrinsics["cam0"]
    assert abs(lens.K[0, 0] / 988 - 1) < 0.05                        # PROVENANCE.md: ~988


def test_selection_keeps_images_of_one_name_together(rendered, tmp_path):
    """Poses matched by name: images of the same name in several cameras are one instant,
    kept or left out together by the image selection (issue 22)."""
    ds = _by_name(rendered, tmp_path / "ds", '{file: "{stem}.json", key: end2base}', _json)
    run = calibrate(ds, processes=1, select=4)
    kept = {}
    for cam in ("cam0", "cam1"):
        left = {r.item for r in run.cameras[cam].rejected if r.reason.startswith("not selected")}
        kept[cam] = {p.name for p in (ds / cam).glob("*.png")} - left
        assert run.cameras[cam].selection.kept == len(kept[cam]) >= 4
    assert kept["cam0"] == kept["cam1"]
    assert len(kept["cam0"]) < len(list((ds / "cam0").glob("*.png")))


def _euler_rad(path, T):
    angles = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")
    path.with_suffix(".txt").write_text(" ".join(f"{v:.10f}" for v in [*T[:3, 3], *angles]) + "\n")


def test_euler_angles_read_as_a_rotation_vector_point_at_the_rotation_convention(rendered,
                                                                                  tmp_path):
    """Euler angles in files that rig.yaml reads as rotation vectors: no hypothesis models
    it, so the run is doubted (exit 3) and the message names the convention rig.yaml reads
    among what to check."""
    ds = _by_name(rendered, tmp_path / "ds", '{file: "{stem}.txt", rotation: rotvec}', _euler_rad)
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(tmp_path / "out"),
                                    "--processes", "1", "--no-report"])
    assert res.exit_code in (2, 3), res.output
    assert "rotation convention (rig.yaml reads rotation: rotvec: Euler angles read as a " \
           "rotation vector" in res.output, res.output
