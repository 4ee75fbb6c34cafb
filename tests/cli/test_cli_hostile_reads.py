"""Hostile and unlucky input files (issue 19, items 2 and 3): reads with bounds, images checked
before decoding, links out of the dataset named.

Every case runs ``multieye calibrate`` (or ``check``/``report``) and asserts the outcome the
issue asks for: exit status 2 with exactly one line on stderr naming the file and what it
is, nothing written, no traceback; or exit status 0 with the hostile entry listed among the
rejected items (or the warnings) with its reason.  Cases that would block or exhaust memory
without the bounds (a FIFO, ``/dev/zero``, ``/dev/urandom``) run in a subprocess with a
timeout, so that a regression fails instead of hanging the suite.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from pose_dataset import write_pose_dataset

from multieye.cli import main
from multieye.core import geometry as g
from multieye.sim.dataset import DatasetSpec, render_dataset

TIMEOUT_S = 300


@pytest.fixture(scope="module")
def pose_dataset(tmp_path_factory):
    """Two cameras given by poses (no images): the fastest whole run."""
    return write_pose_dataset(tmp_path_factory.mktemp("poses"))[0]


@pytest.fixture(scope="module")
def image_dataset(tmp_path_factory):
    """Two cameras x 7 rendered images, 320 x 240, rendered once for the module."""
    folder = tmp_path_factory.mktemp("images") / "ds"
    render_dataset(folder, DatasetSpec(n_cameras=2, images_per_camera=7, width=320, height=240,
                                       processes=1), seed=2)
    return folder


def _copy(source: Path, tmp_path: Path) -> Path:
    ds = tmp_path / "ds"
    shutil.copytree(source, ds, symlinks=True)
    return ds


def _calibrate(ds, out, *extra):
    return CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1",
                                     *extra])


def _subprocess(*args):
    """``python -m multieye ARGS`` with a timeout: a read that blocks fails the test."""
    return subprocess.run([sys.executable, "-m", "multieye", *map(str, args)],
                          capture_output=True, text=True, timeout=TIMEOUT_S)


def _one_error(code, stderr, out=None) -> str:
    assert code == 2, stderr
    assert "Traceback" not in stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("multieye: error: "), lines[0]
    if out is not None:
        assert not (out / "calibration.json").exists()
    return lines[0]


def _ok(res, out):
    assert res.exit_code == 0, (res.output, res.exception)
    assert "Traceback" not in res.output
    assert (out / "calibration.json").exists()


def _rejected(out: Path) -> dict[str, str]:
    cal = json.loads((out / "calibration.json").read_text())
    return {r["item"]: r["reason"] for c in cal["cameras"].values() for r in c.get("rejected", [])}


def _warnings(out: Path) -> list[str]:
    return json.loads((out / "calibration.json").read_text()).get("warnings", [])


# --- files that are not regular files --------------------------------------------------------

@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_device_as_intrinsics_refused_in_one_line(pose_dataset, tmp_path, device):
    ds = _copy(pose_dataset, tmp_path)
    rig = ds / "rig.yaml"
    rig.write_text(rig.read_text().replace("cam0: {intrinsics: cam.yaml",
                                           f"cam0: {{intrinsics: {device}"))
    res = _subprocess("calibrate", ds, "-o", tmp_path / "out", "--processes", "1")
    line = _one_error(res.returncode, res.stderr, tmp_path / "out")
    assert device in line and "character device" in line and "regular file" in line


@pytest.mark.parametrize("device", ["/dev/urandom", "/dev/zero"])
def test_device_as_mocap_refused_in_one_line(pose_dataset, tmp_path, device):
    ds = _copy(pose_dataset, tmp_path)
    (ds / "mocap.txt").unlink()
    (ds / "mocap.txt").symlink_to(device)
    res = _subprocess("calibrate", ds, "-o", tmp_path / "out", "--processes", "1")
    line = _one_error(res.returncode, res.stderr, tmp_path / "out")
    assert ("mocap.txt" in line or device in line) and "character device" in line


def test_rig_yaml_linked_to_a_device_refused(pose_dataset, tmp_path):
    ds = _copy(pose_dataset, tmp_path)
    (ds / "rig.yaml").unlink()
    (ds / "rig.yaml").symlink_to("/dev/zero")
    res = _subprocess("calibrate", ds, "-o", tmp_path / "out", "--processes", "1")
    line = _one_error(res.returncode, res.stderr, tmp_path / "out")
    assert "rig.yaml" in line or "/dev/zero" in line
    assert "character device" in line


@pytest.mark.parametrize("which", ["mocap.txt", "cam0.txt", "cam.yaml"])
def test_fifo_refused_without_blocking(pose_dataset, tmp_path, which):
    ds = _copy(pose_dataset, tmp_path)
    (ds / which).unlink()
    os.mkfifo(ds / which)
    res = _subprocess("calibrate", ds, "-o", tmp_path / "out", "--processes", "1")
    line = _one_error(res.returncode, res.stderr, tmp_path / "out")
    assert which in line and "FIFO" in line


def test_fifo_as_rig_yaml_refused_without_blocking(pose_dataset, tmp_path):
    ds = _copy(pose_dataset, tmp_path)
    (ds / "rig.yaml").unlink()
    os.mkfifo(ds / "rig.yaml")
    res = _subprocess("check", ds)
    line = _one_error(res.returncode, res.stderr)
    assert "rig.yaml" in line and "FIFO" in line


def test_socket_and_folder_as_mocap_refused(pose_dataset, tmp_path):
    ds = _copy(pose_dataset, tmp_path)
    (ds / "mocap.txt").unlink()
    sock = socket.socket(socket.AF_UNIX)
    try:
        sock.bind(str(ds / "mocap.txt"))
        res = _calibrate(ds, tmp_path / "out")
        line = _one_error(res.exit_code, res.stderr, tmp_path / "out")
        assert "mocap.txt" in line and "socket" in line
    finally:
        sock.close()
    (ds / "mocap.txt").unlink()
    (ds / "mocap.txt").mkdir()
    res = _calibrate(ds, tmp_path / "out2")
    line = _one_error(res.exit_code, res.stderr, tmp_path / "out2")
    assert "mocap.txt" in line and "folder" in line


@pytest.mark.parametrize("which", ["mocap.txt", "cam.yaml", "rig.yaml"])
def test_symbolic_link_loop_refused_in_one_line(pose_dataset, tmp_path, which):
    ds = _copy(pose_dataset, tmp_path)
    (ds / which).unlink()
    (ds / "a").symlink_to(ds / "b")
    (ds / "b").symlink_to(ds / "a")
    (ds / which).symlink_to(ds / "a")
    res = _calibrate(ds, tmp_path / "out")
    line = _one_error(res.exit_code, res.stderr, tmp_path / "out")
    assert "symbolic link loop" in line and (which in line or "rig.yaml" in line), line


def test_calibration_json_as_device_refused_by_report_and_export(pose_dataset, tmp_path):
    out = tmp_path / "out"
    _ok(_calibrate(_copy(pose_dataset, tmp_path), out), out)
    (out / "calibration.json").unlink()
    (out / "calibration.json").symlink_to("/dev/zero")
    for args in (["report", out], ["export", out, "--format", "json"]):
        res = _subprocess(*args)
        line = _one_error(res.returncode, res.stderr)
        assert "calibration.json" in line or "/dev/zero" in line, line


def test_bag_files_must_be_regular(tmp_path):
    from multieye.core.errors import DatasetError
    from multieye.io.rosbag import bag_topics

    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    os.mkfifo(bag / "bag_0.db3")
    with pytest.raises(DatasetError, match="FIFO"):
        bag_topics(bag)
    (tmp_path / "x.bag").symlink_to("/dev/zero")
    with pytest.raises(DatasetError, match="character device"):
        bag_topics(tmp_path / "x.bag")


# --- limits counted while reading ------------------------------------------------------------

def test_byte_limit_is_counted_while_reading(tmp_path, monkeypatch):
    from multieye.core.errors import DatasetError
    from multieye.core.regular_files import open_bounded_text, read_bounded

    f = tmp_path / "big.txt"
    f.write_bytes(b"0 0 0 0 0 0 0 1\n" * 100)
    assert len(read_bounded(f, what="table", max_bytes=1600)) == 1600
    with pytest.raises(DatasetError, match="1599"):
        read_bounded(f, what="table", max_bytes=1599)
    # a file whose stated size is smaller than its content (as a device's 0): the bound
    # still holds, counted on the bytes read
    real_fstat = os.fstat

    def small_fstat(fd):
        st = real_fstat(fd)
        return os.stat_result((st.st_mode, *st[1:6], 0, *st[7:]))

    monkeypatch.setattr(os, "fstat", small_fstat)
    with pytest.raises(DatasetError, match="more than the 100 bytes"):
        read_bounded(f, what="table", max_bytes=100)
    with pytest.raises(DatasetError, match="more than the 100 bytes"):
        with open_bounded_text(f, what="table", max_bytes=100) as lines:
            list(lines)


def test_mocap_larger_than_the_limit_refused(pose_dataset, tmp_path, monkeypatch):
    import multieye.io.textfile as textfile
    from multieye.core.errors import DatasetError
    from multieye.io.tum import read_tum

    for reader in (textfile.text_lines, textfile.count_lines):
        monkeypatch.setitem(reader.__kwdefaults__, "max_bytes", 500)
    assert (pose_dataset / "mocap.txt").stat().st_size > 500
    with pytest.raises(DatasetError, match="more than the 500"):
        read_tum(pose_dataset / "mocap.txt")


def test_large_tum_table_is_read_into_arrays(tmp_path):
    """Rows are kept as arrays, not one Python object per row: the memory held per row."""
    import tracemalloc

    from multieye.io.tum import read_tum

    n = 300_000
    rng = np.random.default_rng(0)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    rows = np.column_stack([np.arange(n) * 0.001, rng.normal(size=(n, 3)), q])
    path = tmp_path / "big.txt"
    np.savetxt(path, rows, fmt="%.9f")
    tracemalloc.start()
    traj = read_tum(path)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert len(traj) == n
    np.testing.assert_allclose(traj.T[:, :3, 3], rows[:, 1:4], atol=1e-9)
    # the poses alone are 136 bytes a row (stamps and 4 x 4 floats), the line numbers 4 more;
    # a list of rows of Python floats would be over 400 (24 bytes a float, 8 a pointer)
    assert peak / n < 250, peak / n


# --- images ----------------------------------------------------------------------------------

def _png_claiming(width: int, height: int) -> bytes:
    """A tiny real PNG whose IHDR says width x height (CRC fixed: a valid header)."""
    ok, buf = cv2.imencode(".png", np.full((8, 8), 200, np.uint8))
    data = bytearray(buf.tobytes())
    data[16:24] = struct.pack(">II", width, height)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    return bytes(data)


def _jpeg_claiming(width: int, height: int) -> bytes:
    ok, buf = cv2.imencode(".jpg", np.full((16, 16), 200, np.uint8))
    data = bytearray(buf.tobytes())
    pos = 2
    while data[pos + 1] not in (0xC0, 0xC1, 0xC2):
        pos += 2 + struct.unpack(">H", data[pos + 2:pos + 4])[0]
    data[pos + 5:pos + 9] = struct.pack(">HH", height, width)
    return bytes(data)


def _with_exif_orientation(jpeg: bytes, orientation: int) -> bytes:
    """A JPEG with an APP1 Exif segment holding one IFD entry: Orientation (0x0112)."""
    tiff = b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", 1) + struct.pack(
        "<HHIHH", 0x0112, 3, 1, orientation, 0) + struct.pack("<I", 0)
    body = b"Exif\x00\x00" + tiff
    app1 = b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body
    return jpeg[:2] + app1 + jpeg[2:]


def test_header_sizes_read_without_decoding():
    from multieye.imaging.image_file import image_header

    png = _png_claiming(60000, 60000)
    assert len(png) < 400
    assert (image_header(png).width, image_header(png).height) == (60000, 60000)
    jpg = _jpeg_claiming(30000, 30000)
    assert (image_header(jpg).width, image_header(jpg).height) == (30000, 30000)
    assert image_header(_with_exif_orientation(jpg, 3)).orientation == 3
    image = np.zeros((5, 7), np.uint8)
    for ext in (".png", ".jpg", ".bmp", ".tiff", ".pgm", ".webp"):
        ok, buf = cv2.imencode(ext, image)
        h = image_header(buf.tobytes())
        assert h is not None and (h.width, h.height) == (7, 5), ext


@pytest.mark.parametrize("kind", ["png", "jpeg"])
def test_image_claiming_a_huge_size_is_rejected_before_decoding(image_dataset, tmp_path, kind):
    ds = _copy(image_dataset, tmp_path)
    victim = sorted((ds / "cam0").glob("*.png"))[2]
    data = _png_claiming(60000, 60000) if kind == "png" else _jpeg_claiming(30000, 30000)
    victim.write_bytes(data)
    out = tmp_path / "out"
    res = _calibrate(ds, out, "--no-refine")
    _ok(res, out)
    reason = _rejected(out)[victim.name]
    size = "60000 x 60000" if kind == "png" else "30000 x 30000"
    assert size in reason and "not decoded" in reason
    res = CliRunner().invoke(main, ["check", str(ds), "--processes", "2"])
    assert res.exit_code in (0, 2) and "Traceback" not in res.output, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)


def test_exif_orientation_ignored_with_a_note(image_dataset, tmp_path):
    """JPEGs saying "rotate 180 degrees" calibrate as the sensor's pixels: the result matches
    the truth (a decoder that applied the tag would turn the camera 180 degrees)."""
    ds = _copy(image_dataset, tmp_path)
    for png in sorted((ds / "cam1").glob("*.png")):
        ok, buf = cv2.imencode(".jpg", cv2.imread(str(png), cv2.IMREAD_GRAYSCALE),
                               [cv2.IMWRITE_JPEG_QUALITY, 98])
        png.with_suffix(".jpg").write_bytes(_with_exif_orientation(buf.tobytes(), 3))
        png.unlink()
    out = tmp_path / "out"
    res = _calibrate(ds, out, "--no-refine")
    _ok(res, out)
    assert "EXIF orientation 3 ignored" in res.output
    cal = json.loads((out / "calibration.json").read_text())
    truth = json.loads((ds / "ground_truth.json").read_text())
    T = np.array(cal["cameras"]["cam1"]["T_ref_cam"])
    T_true = np.array(truth["cameras"]["cam1"]["T_ref_cam"])
    angle = float(np.degrees(g.rotation_angle_between(T, T_true)))
    assert angle < 1.0, angle


def test_exif_quarter_turn_applied_when_only_the_turned_image_fits(image_dataset, tmp_path):
    """A phone or camera that stores its pixels turned by a quarter, with EXIF orientation 6
    ("turn 90 degrees clockwise to view"), against intrinsics of the viewed image (as
    cv2.imread shows it, the default of OpenCV's tools): turned as the EXIF says, with a
    note, and the result matches the truth (before: every image 'wrong resolution', exit 2).
    The report's thumbnails read the image the same way."""
    from multieye.imaging.image_file import read_gray
    from multieye.imaging.thumbnails import residual_thumbnail

    ds = _copy(image_dataset, tmp_path)
    for png in sorted((ds / "cam1").glob("*.png")):
        turned = cv2.rotate(cv2.imread(str(png), cv2.IMREAD_GRAYSCALE),
                            cv2.ROTATE_90_COUNTERCLOCKWISE)   # stored so; EXIF 6 undoes it
        ok, buf = cv2.imencode(".jpg", turned, [cv2.IMWRITE_JPEG_QUALITY, 98])
        png.with_suffix(".jpg").write_bytes(_with_exif_orientation(buf.tobytes(), 6))
        png.unlink()
    first = sorted((ds / "cam1").glob("*.jpg"))[0]
    h, w = cv2.imread(str(first), cv2.IMREAD_GRAYSCALE | cv2.IMREAD_IGNORE_ORIENTATION).shape
    image, reason, notes = read_gray(first, (h, w))
    assert reason is None and image.shape == (w, h) and "orientation 6 applied" in notes[0]
    assert read_gray(first)[0].shape == (h, w)            # no intrinsics: as stored
    assert read_gray(first, (w, h))[0].shape == (h, w)    # the stored size fits: as stored
    thumb = residual_thumbnail(first, np.zeros((0, 2)), np.zeros((0, 2)), magnify=1.0,
                               image_size=(h, w), crop=False)
    assert thumb is not None
    out = tmp_path / "out"
    res = _calibrate(ds, out, "--no-refine")
    _ok(res, out)
    assert "EXIF orientation 6 applied" in res.output
    cal = json.loads((out / "calibration.json").read_text())
    truth = json.loads((ds / "ground_truth.json").read_text())
    T = np.array(cal["cameras"]["cam1"]["T_ref_cam"])
    T_true = np.array(truth["cameras"]["cam1"]["T_ref_cam"])
    angle = float(np.degrees(g.rotation_angle_between(T, T_true)))
    assert angle < 1.0, angle


def test_hostile_image_entries_listed_with_reasons(image_dataset, tmp_path):
    ds = _copy(image_dataset, tmp_path)
    cam = ds / "cam0"
    (cam / "1700000000.010000.png").symlink_to(cam / "nowhere.png")            # dangling
    (cam / "1700000000.020000.png").symlink_to(cam / "1700000000.030000.png")  # loop
    (cam / "1700000000.030000.png").symlink_to(cam / "1700000000.020000.png")
    (cam / "1700000000.040000.png").symlink_to("/dev/zero")                    # device
    (cam / "1700000000.050000.png").mkdir()                                    # folder
    os.mkfifo(cam / "1700000000.060000.png")                                   # FIFO
    out = tmp_path / "out"
    res = _calibrate(ds, out, "--no-refine")
    _ok(res, out)
    rejected = _rejected(out)
    expected = {"1700000000.010000.png": "dangling symbolic link",
                "1700000000.020000.png": "symbolic link loop",
                "1700000000.030000.png": "symbolic link loop",
                "1700000000.040000.png": "character device",
                "1700000000.050000.png": "folder",
                "1700000000.060000.png": "FIFO"}
    for name, why in expected.items():
        assert name in rejected and why in rejected[name], (name, rejected.get(name))


def test_image_linked_from_outside_the_dataset_is_named(image_dataset, tmp_path):
    ds = _copy(image_dataset, tmp_path)
    elsewhere = tmp_path / "shared"
    elsewhere.mkdir()
    image = sorted((ds / "cam1").glob("*.png"))[0]
    shutil.move(image, elsewhere / image.name)
    image.symlink_to(elsewhere / image.name)
    out = tmp_path / "out"
    res = _calibrate(ds, out, "--no-refine")
    _ok(res, out)
    assert str(elsewhere / image.name) in res.output
    assert any(str(elsewhere / image.name) in w and "outside the dataset folder" in w
               for w in _warnings(out))
    # details.json carries the same warnings (the report and later readers see them too)
    details = json.loads((out / "details.json").read_text())
    assert details["warnings"] == _warnings(out)


def test_rig_yaml_linked_into_another_dataset_is_named(pose_dataset, tmp_path):
    other = _copy(pose_dataset, tmp_path)
    ds = tmp_path / "mine"
    ds.mkdir()
    (ds / "rig.yaml").symlink_to(other / "rig.yaml")
    out = tmp_path / "out"
    res = _calibrate(ds, out)
    _ok(res, out)
    real = str((other / "rig.yaml").resolve())
    assert real in res.output
    notes = _warnings(out)
    assert any(real in w and "symbolic link" in w for w in notes), notes
    assert json.loads((out / "details.json").read_text())["warnings"] == notes
    # and the files it names, all in the other dataset, are listed too
    assert any(str((other / "mocap.txt").resolve()) in w for w in notes), notes
    res = CliRunner().invoke(main, ["check", str(ds)])
    assert res.exit_code == 0 and f"note: rig.yaml is a symbolic link to {real}" in res.output


def test_dataset_folder_that_is_a_link_is_not_outside(pose_dataset, tmp_path):
    ds = _copy(pose_dataset, tmp_path)
    link = tmp_path / "link"
    link.symlink_to(ds)
    out = tmp_path / "out"
    res = _calibrate(link, out)
    _ok(res, out)
    assert not any("outside the dataset folder" in w for w in _warnings(out))


# --- processes and workers -------------------------------------------------------------------

def test_processes_capped_at_the_cpus_with_a_note(pose_dataset, tmp_path):
    from multieye.imaging.batch import worker_count

    cpus = len(os.sched_getaffinity(0))
    assert worker_count(200, 8) == min(cpus, 8)
    assert worker_count(200, 1) == 1
    assert worker_count(None, 1000) == cpus
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["calibrate", str(_copy(pose_dataset, tmp_path)), "-o",
                                    str(out), "--processes", "200"])
    _ok(res, out)
    assert f"note: --processes 200: at most {cpus} detection process" in res.output


def test_failures_inside_a_worker_are_the_image_reason(image_dataset, monkeypatch):
    import multieye.imaging.batch as batch
    from multieye.imaging.targets import target_from_spec

    paths = sorted((image_dataset / "cam0").glob("*.png"))[:2]
    target = target_from_spec({"type": "chessboard", "rows": 6, "cols": 9, "spacing": 0.05})

    def broken(*a, **k):
        raise MemoryError("no memory for this one")

    monkeypatch.setattr(batch, "detect_with_second_look", broken)
    results = batch.detect_and_estimate(paths, target, None, processes=1)
    assert [r.reason for r in results] == ["failed while reading or detecting: MemoryError: "
                                           "no memory for this one"] * 2
    # a worker that dies (a crash) is that item's reason, not the run's end
    crashed = batch._isolated(os._exit, 3, "item", (target, None, 2.0))
    assert crashed.reason.startswith("failed while reading or detecting: the worker process "
                                     "ended abruptly")
