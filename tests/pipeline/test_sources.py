"""The files a run reads from outside its dataset folder (:func:`multieye.pipeline.sources.
outside_reads`): each image's real path from its folder's real path unless it is a link, the
same notes as resolving every image's path on its own."""

from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace

from multieye.io.image_folder import IMAGE_EXTENSIONS
from multieye.pipeline.sources import outside_reads


def _reference_notes(rig, named: Path) -> tuple[str, ...]:
    """The images' notes as made before: ``os.path.realpath`` of every image's own path."""
    root = Path(os.path.realpath(named.parent))
    notes, seen = [], set()
    for name, cam in rig.cameras.items():
        entries = sorted(cam.images.iterdir())
        real = [Path(os.path.realpath(p)) for p in entries
                if p.suffix.lower() in IMAGE_EXTENSIONS and p.is_file()]
        away = [p for p in real if not (p == root or root in p.parents) and p not in seen]
        seen.update(away)
        if away:
            notes.append(f"camera {name}: {len(away)} images read from outside the dataset "
                         f"folder {root}: " + ", ".join(str(p) for p in away))
    return tuple(notes)


def _camera(folder: Path):
    return SimpleNamespace(images=folder, images_pattern=None, intrinsics=None, poses=None, rosbag=None,
                           video=None, stamps=None, intrinsics_images=None)


def test_images_linked_from_outside_are_named_as_resolving_each_path_gives(tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    for k in range(3):
        (elsewhere / f"{k}.0.png").write_bytes(b"x")
    data = tmp_path / "data"
    own = data / "cam0"
    own.mkdir(parents=True)
    (own / "1.0.png").write_bytes(b"x")                         # a file of its own
    (own / "2.0.png").symlink_to(elsewhere / "0.0.png")           # a link out
    (own / "3.0.PNG").symlink_to(own / "1.0.png")                 # a link inside
    (own / "4.0.png").symlink_to(own / "2.0.png")                 # a link to a link out
    (own / "5.0.png").symlink_to(tmp_path / "nowhere.png")        # broken: not a file
    (own / "6.0.png").mkdir()                                     # a folder named as one
    (own / "notes.txt").write_text("not an image")
    (data / "cam1").symlink_to(elsewhere)                         # the folder is a link out
    (data / "cam2").symlink_to(own)                               # ... or in
    linked = tmp_path / "linked_data"
    linked.symlink_to(data)                                       # the dataset by a link
    rig = SimpleNamespace(cameras={n: _camera(data / n) for n in ("cam0", "cam1", "cam2")},
                          mocap_for=lambda name: None)
    for named in (data, linked):
        (data / "rig.yaml").write_text("")
        notes = outside_reads(rig, named)
        assert notes == _reference_notes(rig, named / "rig.yaml")
        # elsewhere/0.0.png named once, with the camera that read it first
        assert len(notes) == 2 and "cam0: 2 images" in notes[0] and "cam1: 2 images" in notes[1]


def test_many_files_from_outside_are_named_by_their_folder_or_the_first_few(tmp_path):
    """A camera folder linked to another disk: its images named by their one folder, not one by
    one (thousands on the terminal and in the report); spread over folders, the first five
    and how many more. Every file still counted."""
    far, farther = tmp_path / "far", tmp_path / "farther"
    far.mkdir()
    farther.mkdir()
    for k in range(12):
        (far / f"{k:02d}.0.png").write_bytes(b"x")
        (farther / f"{k:02d}.5.png").write_bytes(b"x")
    data = tmp_path / "data"
    (data / "mixed").mkdir(parents=True)
    (data / "cam0").symlink_to(far)
    for k in range(3):
        (data / "mixed" / f"{k}.1.png").symlink_to(far / f"{k:02d}.0.png")
        (data / "mixed" / f"{k}.2.png").symlink_to(farther / f"{k:02d}.5.png")
    (data / "rig.yaml").write_text("")
    rig = SimpleNamespace(cameras={"cam0": _camera(data / "cam0"),
                                   "cam1": _camera(data / "mixed")}, mocap_for=lambda name: None)
    notes = outside_reads(rig, data)
    assert notes[0].endswith(f": all in {far.resolve()} (00.0.png ... 11.0.png)"), notes[0]
    assert "cam0: 12 images" in notes[0]
    # cam1's links into far were read by cam0 already; its three into farther are named
    assert "cam1: 3 images" in notes[1] and notes[1].count(str(farther.resolve())) == 3
    (data / "more").mkdir()
    for k in range(4, 12):
        (data / "more" / f"{k}.1.png").symlink_to(far / f"{k:02d}.0.png")
        (data / "more" / f"{k}.2.png").symlink_to(farther / f"{k:02d}.5.png")
    rig = SimpleNamespace(cameras={"cam2": _camera(data / "more")}, mocap_for=lambda name: None)
    (note,) = outside_reads(rig, data)
    assert "cam2: 16 images" in note and note.endswith(" and 11 more"), note
    assert (note.count(f"{far.resolve()}{os.sep}")
            + note.count(f"{farther.resolve()}{os.sep}")) == 5       # the first five files
