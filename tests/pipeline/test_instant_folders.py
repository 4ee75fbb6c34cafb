"""Recordings with one folder per instant (``frames/0001/left.png``, ``frames/0001/right.png``),
as several stereo and multi-camera recorders write them: ``images: frames/*/left.png``
calibrates them as they are, under every ``sync``, to the same rig as the same images laid
out one folder per camera, and the notes name paths the user can open.  Before, a pattern
with a folder part was refused (rig.yaml's ``images:``) and such recordings had to be renamed.
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import multieye
from multieye.cli import main
from multieye.io import list_images, load_rig, skipped_entries
from multieye.io.image_folder import image_name, label_stem
from multieye.sim.overlap import OverlapSpec, render_overlap_dataset


@pytest.fixture(scope="module")
def flat(tmp_path_factory) -> Path:
    """Two overlapping cameras, lenses given, 8 instants: ``camN/<stamp>.png``."""
    ds = tmp_path_factory.mktemp("flat") / "ds"
    render_overlap_dataset(ds, OverlapSpec(n_cameras=2, angle_deg=10, n_instants=8, width=640,
                                           height=480), seed=3)
    return ds


def _instants(flat: Path) -> list[list[Path]]:
    """Per camera, its images in time order (every camera sees every instant here)."""
    cams = sorted(p for p in flat.iterdir() if p.is_dir())
    per = [sorted(c.glob("*.png"), key=lambda p: float(p.stem)) for c in cams]
    assert len({len(p) for p in per}) == 1
    return per


def _rig_text(flat: Path, images: dict[str, str], sync: str) -> str:
    """``flat``'s rig.yaml with each camera's ``images:`` replaced and ``sync:`` added."""
    text = (flat / "rig.yaml").read_text()
    for cam, pattern in images.items():
        text = re.sub(rf"(\n  {cam}:\n(?:    .*\n)*?    images: )\S+", rf"\g<1>'{pattern}'", text)
    return f"sync: {sync}\n" + text


def _copy_layout(flat: Path, out: Path, place, sync: str) -> Path:
    """``flat``'s images copied to ``place(camera index, k, image)`` below ``out``, its
    intrinsics files beside them, rig.yaml naming the pattern ``place`` gives for ``*``."""
    out.mkdir(parents=True)
    for f in flat.glob("cam*.yaml"):
        shutil.copy(f, out / f.name)
    per = _instants(flat)
    images = {}
    for j, files in enumerate(per):
        for k, f in enumerate(files):
            dest = out / place(j, k, f)
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(f, dest)
        images[f"cam{j}"] = place(j, "*", None)
    (out / "rig.yaml").write_text(_rig_text(flat, images, sync))
    return out


def _stamp(f: Path | None) -> str:
    return "*" if f is None else f.stem


@pytest.mark.parametrize("sync", ["name", "number", "order", "time"])
def test_one_folder_per_instant_gives_the_rig_of_one_folder_per_camera(flat, tmp_path, sync):
    """The same images, per camera (``camN/0003.png``) and per instant
    (``frames/0003/camN.png``): the same lenses, poses and sigmas to the last digit."""
    if sync == "time":      # folders named by the instant's stamp (camera 0's), files by camera
        per = _instants(flat)
        stamp_of = {k: per[0][k].stem for k in range(len(per[0]))}
        flat_place = lambda j, k, f: f"cam{j}/{'*' if k == '*' else stamp_of[k]}.png"  # noqa: E731
        nested_place = lambda j, k, f: (f"frames/{'*' if k == '*' else stamp_of[k]}"  # noqa: E731
                                        f"/cam{j}.png")
    else:
        flat_place = lambda j, k, f: f"cam{j}/{k if k == '*' else f'{k + 1:04d}'}.png"  # noqa: E731
        nested_place = lambda j, k, f: (f"frames/{k if k == '*' else f'{k + 1:04d}'}"  # noqa: E731
                                        f"/cam{j}.png")
    a = _copy_layout(flat, tmp_path / "per_camera", flat_place, sync)
    b = _copy_layout(flat, tmp_path / "per_instant", nested_place, sync)
    rig = load_rig(b)
    assert rig.cameras["cam1"].images == (b / "frames").resolve()
    assert rig.cameras["cam1"].images_pattern == "*/cam1.png"
    ra, rb = (multieye.calibrate(d, processes=1) for d in (a, b))
    for cam in ("cam0", "cam1"):
        np.testing.assert_array_equal(ra.T_ref_cam[cam], rb.T_ref_cam[cam])
        np.testing.assert_array_equal(ra.T_ref_cam_std[cam], rb.T_ref_cam_std[cam])
    assert len(rb.cameras["cam1"].observations) == len(_instants(flat)[1])


def test_a_time_stamp_may_name_the_instant_folder(tmp_path):
    (tmp_path / "1700000000.5").mkdir()
    (tmp_path / "1700000000.5" / "left.png").write_bytes(b"")
    (tmp_path / "1700000001.25").mkdir()
    (tmp_path / "1700000001.25" / "left.png").write_bytes(b"")
    listed = list_images(tmp_path, "*/left.png")
    assert [ns for _, ns, _ in listed] == [1_700_000_000_500_000_000, 1_700_000_001_250_000_000]
    assert image_name(listed[0][2], tmp_path) == "1700000000.5/left"
    assert label_stem("1700000000.5/left.png") == "1700000000.5/left"
    assert label_stem("left01.png") == "left01"


def test_links_to_folders_are_listed_as_skipped_never_followed(tmp_path):
    """A folder part of the pattern never leads through a link (to elsewhere on the disk):
    the link is named among the skipped entries with the reason."""
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "left.png").write_bytes(b"")
    root = tmp_path / "frames"
    (root / "0001").mkdir(parents=True)
    (root / "0001" / "left.png").write_bytes(b"")
    os.symlink(outside, root / "0002")
    assert [p.name for _, _, p in list_images(root, "*/left.png", "name")] == ["left.png"]
    assert skipped_entries(root, "*/left.png") == [
        ("0002", "skipped: a symbolic link to a folder, not followed (give the folder itself)")]


def test_notes_name_paths_below_the_dataset_folder(tmp_path):
    """Every image a note names (here the symmetric board's note, on every image) is a path
    from rig.yaml's folder that exists: ``frames/0001/cam0.png``, not ``cam0/cam0.png``."""
    board = {"type": "chessboard", "rows": 6, "cols": 8, "spacing": 0.03}   # half-turn symmetric
    render_overlap_dataset(tmp_path / "flat", OverlapSpec(n_cameras=2, angle_deg=10, n_instants=6,
                                                          width=640, height=480, target=board),
                           seed=4)
    ds = _copy_layout(tmp_path / "flat", tmp_path / "ds", lambda j, k, f: (
        f"frames/{k if k == '*' else f'{k + 1:04d}'}/cam{j}.png"), "number")
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(tmp_path / "out"),
                                    "--no-report", "--processes", "1"])
    assert res.exit_code in (0, 3), res.output
    named = re.findall(r"\b(frames/\d{4}/cam\d\.png)", res.output)
    assert named, res.output
    assert all((ds / n).is_file() for n in named), named
    assert "cam0/cam0.png" not in res.output and "cam1/cam1.png" not in res.output


def test_the_report_draws_images_of_sub_folders_and_nothing_a_name_leads_out_to(tmp_path):
    """details.json's image names (a file that may have been edited) are drawn only where
    they are files of the camera's folder or of its real sub-folders."""
    from multieye.outputs.report_images import _below

    (tmp_path / "cam" / "0001").mkdir(parents=True)
    (tmp_path / "elsewhere").mkdir()
    os.symlink(tmp_path / "elsewhere", tmp_path / "cam" / "0002")
    folder = tmp_path / "cam"
    assert _below(folder, "0001/left.png") and _below(folder, "left.png")
    for name in ("../elsewhere/left.png", "0001/../../x.png", "/etc/passwd", "0002/left.png",
                 "", ".", "a//b.png", "a/b/c/d/e.png"):
        assert not _below(folder, name), name
