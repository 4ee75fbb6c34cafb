"""Side-by-side stereo recordings (one file per instant holding both sensors' images, as USB
stereo cameras and ZED-like devices write them): each camera's ``crop:`` of the files.  The
rig equals the one from the same pixels saved one file per camera, to the last digit; a crop
the images do not hold, crops that share pixels, and a crop without images are refused.
Before, the files had to be split by the user (``crop`` was an unknown key)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

import multieye
from multieye.cli import main
from multieye.core.errors import DatasetError
from multieye.pipeline.detection import cropped_frames
from multieye.sim.overlap import OverlapSpec, render_overlap_dataset

W, H = 640, 480


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> Path:
    """Two overlapping cameras, lenses estimated, 8 instants, no jitter: ``camN/<k>.png``
    (renamed by instant) and ``sbs/<k>.png`` (cam0 | cam1 side by side)."""
    root = tmp_path_factory.mktemp("sbs")
    render_overlap_dataset(root / "raw", OverlapSpec(n_cameras=2, angle_deg=10, n_instants=8,
                                                     width=W, height=H, jitter_s=0.0),
                           seed=7, models=True)
    ds = root / "ds"
    (ds / "sbs").mkdir(parents=True)
    for j in range(2):
        (ds / f"cam{j}").mkdir()
        for k, f in enumerate(sorted((root / "raw" / f"cam{j}").glob("*.png"),
                                     key=lambda p: float(p.stem))):
            shutil.copy(f, ds / f"cam{j}" / f"{k:02d}.png")
    for f in sorted((ds / "cam0").glob("*.png")):
        left = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
        right = cv2.imread(str(ds / "cam1" / f.name), cv2.IMREAD_UNCHANGED)
        assert left.shape[:2] == (H, W)
        cv2.imwrite(str(ds / "sbs" / f.name), np.concatenate([left, right], axis=1))
    text = (root / "raw" / "rig.yaml").read_text()
    head = text[:text.index("cameras:")]
    (ds / "split.yaml").write_text(
        "sync: name\n" + head + "cameras:\n"
        "  cam0: {model: pinhole-radtan, images: cam0/}\n"
        "  cam1: {model: pinhole-radtan, images: cam1/}\n")
    _side_by_side(ds, f"[0, 0, {W}, {H}]", f"[{W}, 0, {W}, {H}]")
    return ds


def _side_by_side(ds: Path, left: str, right: str) -> None:
    text = (ds / "split.yaml").read_text()
    (ds / "rig.yaml").write_text(text.replace(
        "images: cam0/}", f"images: sbs/, crop: {left}}}").replace(
        "images: cam1/}", f"images: sbs/, crop: {right}}}"))


def test_each_cameras_half_of_the_files_gives_the_rig_of_split_files(pair, tmp_path):
    split = tmp_path / "split"
    shutil.copytree(pair, split)
    (split / "rig.yaml").write_text((pair / "split.yaml").read_text())
    a, b = multieye.calibrate(split, processes=1), multieye.calibrate(pair, processes=1)
    np.testing.assert_array_equal(a.T_ref_cam["cam1"], b.T_ref_cam["cam1"])
    for cam in ("cam0", "cam1"):
        np.testing.assert_array_equal(a.intrinsics[cam].params, b.intrinsics[cam].params)
        assert (b.intrinsics[cam].width, b.intrinsics[cam].height) == (W, H)
    assert len(b.cameras["cam1"].observations) == 8


def test_the_report_draws_each_camera_on_its_half(pair, tmp_path):
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["calibrate", str(pair), "-o", str(out), "--processes", "1"])
    assert res.exit_code in (0, 3), res.output
    assert (out / "figures" / "image_cam1_1.jpg").is_file()
    assert "sbs/00.png" in res.output or "sbs/" not in res.output   # notes name real paths


@pytest.mark.parametrize("left, right, message", [
    (f"[0, 0, {W}, {H}]", f"[{W}, 0, {W + 1}, {H}]",
     r"camera cam1: .*crop \[640, 0, 641, 480\] reaches beyond the 1280 x 480 image"),
    (f"[0, 0, {W}, {H}]", f"[{W - 8}, 0, {W}, {H}]",
     r"cameras cam0 and cam1 read the same image files \(00\.png and 7 more\)"),
    (f"[0, 0, {W}, {H}]", "[640, 0, 16, 480]", r"cameras\.cam1\.crop: expected x, y >= 0 and "
                                              r"width, height >= 32 pixels"),
    (f"[0, 0, {W}, {H}]", "[640, 0, 640]", r"expected \[x, y, width, height\]"),
])
def test_crops_that_do_not_fit_exit_2_in_one_line(pair, tmp_path, left, right, message):
    ds = tmp_path / "ds"
    shutil.copytree(pair, ds)
    _side_by_side(ds, left, right)
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1"])
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert res.exit_code == 2 and len(lines) == 1, res.output
    assert re.search(message, lines[0]), lines[0]
    assert not out.exists()


def test_a_frame_that_does_not_hold_the_crop_is_a_bad_input():
    frames = [("v.mp4#0", np.zeros((480, 1280), np.uint8)), ("v.mp4#1", np.zeros((480, 600)))]
    it = cropped_frames(iter(frames), (640, 0, 640, 480))
    assert next(it)[1].shape == (480, 640)
    with pytest.raises(DatasetError, match=r"v\.mp4#1: the camera's crop \[640, 0, 640, 480\] "
                                           r"reaches beyond the 600 x 480 image"):
        next(it)


def test_a_thumbnail_shows_only_the_cameras_half(tmp_path):
    """Points near the seam: the drawing of the right camera's half shows none of the left
    half (black here; 96 after the report's lightening), which the box around the points
    reaches without ``region``."""
    from multieye.imaging.thumbnails import residual_thumbnail

    image = np.zeros((H, 2 * W), np.uint8)
    image[:, W:] = 255
    cv2.imwrite(str(tmp_path / "f.png"), image)
    uv = np.array([[W + 10.0 + 20 * k, 100.0 + 15 * k] for k in range(6)])
    res = np.zeros_like(uv)
    pictures = [cv2.imdecode(np.frombuffer(residual_thumbnail(
        tmp_path / "f.png", uv, res, magnify=1.0, region=region), np.uint8), cv2.IMREAD_COLOR)
        for region in (None, (W, 0, W, H))]
    dark = [int(np.sum(np.all(np.abs(p.astype(int) - 96) < 12, axis=2))) for p in pictures]
    assert dark[0] > 100 and dark[1] == 0, dark
