"""Image folders whose names are frame numbers, with the stamps in a file beside them
(``stamps:`` with ``images:``), as KITTI (``timestamps.txt``, ``times.txt``), EuRoC
(``data.csv``) and TUM (``rgb.txt``) lay them out: the same rig as the same images named by
their stamps, and every misfit of the file refused in one line (exit 2, nothing written).
Before, ``stamps`` went with ``video`` only and such folders had to be renamed."""

from __future__ import annotations

import shutil
from datetime import datetime, UTC
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import multieye
from multieye.cli import main
from multieye.io.frame_stamps import read_image_stamps, stamp_text
from multieye.io.image_folder import stamp_from_name

from small_dataset import render_small


@pytest.fixture(scope="module")
def stamped(tmp_path_factory) -> Path:
    """2 cameras x 8 images named by their stamps, motion capture in time."""
    ds = tmp_path_factory.mktemp("stamped") / "ds"
    render_small(ds)
    return ds


def _kitti(ns: int) -> str:
    when = datetime.fromtimestamp(ns // 1_000_000_000, tz=UTC)
    return f"{when:%Y-%m-%d %H:%M:%S}.{ns % 1_000_000_000:09d}"


#: The stamps file of images ``frames`` (file names, time order) with stamps ``ns``.
WRITERS = {
    "one per line, ns": lambda frames, ns: "".join(f"{t}\n" for t in ns),
    "one per line, KITTI date": lambda frames, ns: "".join(f"{_kitti(t)}\n" for t in ns),
    "EuRoC data.csv": lambda frames, ns: "#timestamp [ns],filename\n" + "".join(
        f"{t},{f}\n" for f, t in zip(frames, ns)),
    "TUM rgb.txt": lambda frames, ns: "# color images\n" + "".join(
        f"{t / 1e9:.9f} data/{f}\n" for f, t in zip(frames, ns)),
    "name then stamp, header": lambda frames, ns: "filename;timestamp\n" + "".join(
        f"{f}; {t}\n" for f, t in zip(frames, ns)),
}


def _renamed(stamped: Path, out: Path, write) -> Path:
    """``stamped`` with each camera's images renamed ``cam0/data/000000.png`` ... in time
    order and the stamps written by ``write`` beside them (rig.yaml's ``stamps:``)."""
    shutil.copytree(stamped, out, ignore=shutil.ignore_patterns("*.png"))
    text = (stamped / "rig.yaml").read_text()
    for cam in ("cam0", "cam1"):
        files = sorted((stamped / cam).glob("*.png"), key=lambda p: float(p.stem))
        ns = [stamp_from_name(p.stem) for p in files]
        (out / cam / "data").mkdir(parents=True)
        frames = [f"{k:06d}.png" for k in range(len(files))]
        for f, name in zip(files, frames):
            shutil.copy(f, out / cam / "data" / name)
        (out / cam / "stamps.txt").write_text(write(frames, ns))
        text = text.replace(f"    images: {cam}/\n",
                            f"    images: {cam}/data\n    stamps: {cam}/stamps.txt\n")
    (out / "rig.yaml").write_text(text)
    return out


@pytest.mark.parametrize("layout", list(WRITERS))
def test_stamps_beside_the_images_give_the_rig_of_stamped_names(stamped, tmp_path, layout):
    ds = _renamed(stamped, tmp_path / "ds", WRITERS[layout])
    a, b = multieye.calibrate(stamped, processes=1), multieye.calibrate(ds, processes=1)
    for cam in ("cam0", "cam1"):
        np.testing.assert_allclose(b.T_ref_cam[cam], a.T_ref_cam[cam], rtol=0, atol=1e-12)
    assert len(b.cameras["cam1"].observations) == len(a.cameras["cam1"].observations) == 8


def test_stamp_forms():
    assert stamp_text("1.036896e-01") == 103_689_600
    assert stamp_text("2011-09-26 13:02:25.594360375") == 1_317_042_145_594_360_375
    assert stamp_text("1700000000.5") == 1_700_000_000_500_000_000
    with pytest.raises(ValueError, match="exponent form"):
        stamp_text("13:02:25")


def test_stamps_by_name_may_list_more_images_than_the_folder_keeps(tmp_path):
    (tmp_path / "a.png").write_bytes(b"")
    (tmp_path / "stamps.csv").write_text("a.png,1700000000.5\nb.png,1700000001.5\n")
    assert read_image_stamps(tmp_path / "stamps.csv", [tmp_path / "a.png"], tmp_path) == [
        1_700_000_000_500_000_000]


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.rsplit("\n", 2)[0] + "\n", r"stamps\.txt: camera cam1: 7 stamps for 8 images"),
    (lambda t: t.replace("000003.png", "000033.png"), r"stamps\.txt: camera cam1: no stamp for image 000003\.png"),
    (lambda t: t + "000003.png,1\n", r"a second stamp for 000003\.png"),
    (lambda t: t.replace("000002.png", "000002.png,x"), r"stamps\.txt:4: camera cam1: expected "
                                                        r"an image's name and its time stamp"),
])
def test_a_stamps_file_that_does_not_fit_exits_2_in_one_line(stamped, tmp_path, edit, message):
    ds = _renamed(stamped, tmp_path / "ds", WRITERS["EuRoC data.csv"])
    if "7 stamps" in message:
        ds = _renamed(stamped, tmp_path / "ds1", WRITERS["one per line, ns"])
    f = ds / "cam1" / "stamps.txt"
    f.write_text(edit(f.read_text()))
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1"])
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert res.exit_code == 2 and len(lines) == 1, res.output
    assert __import__("re").search(message, lines[0]), lines[0]
    assert not out.exists()


@pytest.mark.parametrize("camera, message", [
    ("{images: cam0/, model: fisheye, start_time: 5}", "'start_time' goes with 'video'"),
    ("{poses: poses.txt, stamps: s.txt}", "'stamps' goes with 'video' or 'images'"),
])
def test_stamps_keys_refused_where_they_mean_nothing(tmp_path, camera, message):
    (tmp_path / "cam0").mkdir()
    (tmp_path / "s.txt").write_text("1\n")
    (tmp_path / "m.txt").write_text("1 0 0 0 0 0 0 1\n")
    (tmp_path / "poses.txt").write_text("1 0 0 0 0 0 0 1\n")
    (tmp_path / "rig.yaml").write_text(
        "setup: eye-to-base\ntarget: {type: chessboard, rows: 6, cols: 9, spacing: 0.05}\n"
        f"mocap: {{file: m.txt, pose: T_world_marker}}\ncameras:\n  cam0: {camera}\n")
    res = CliRunner().invoke(main, ["check", str(tmp_path)])
    assert res.exit_code == 2 and message in res.output, res.output


def test_stamps_with_sync_by_name_is_refused(tmp_path):
    (tmp_path / "cam0").mkdir()
    (tmp_path / "s.txt").write_text("1\n")
    (tmp_path / "rig.yaml").write_text(
        "sync: number\ntarget: {type: chessboard, rows: 6, cols: 9, spacing: 0.05}\n"
        "cameras:\n  cam0: {images: cam0/, stamps: s.txt, model: fisheye}\n")
    res = CliRunner().invoke(main, ["check", str(tmp_path)])
    assert res.exit_code == 2 and "camera cam0 has 'stamps'" in res.output, res.output
