"""Where a run's input files really are: every file read from outside the dataset folder.

A dataset may link to files elsewhere (the shared robot recordings do: images and motion
capture are symbolic links into a common folder), and multieye follows such links to regular
files (:mod:`multieye.core.regular_files`).  So that a result never silently rests on another
dataset's files, :func:`outside_reads` lists every file read from outside the folder named on
the command line (that folder itself is resolved once: a dataset folder that is a link is
fine), the run puts the list in its warnings (on screen, and in ``details.json`` and
``calibration.json``), and a ``rig.yaml`` that is itself a link names the real file, whose
folder its paths are relative to.
"""

from __future__ import annotations

import fnmatch
import os
from pathlib import Path

from multieye.core.errors import DatasetError
from multieye.io import Rig, list_image_files
from multieye.io.image_folder import IMAGE_EXTENSIONS, is_file_entry, sorted_entries

__all__ = ["outside_reads"]


def _inside(path: Path, root: Path) -> bool:
    return path == root or root in path.parents


def _real_images(folder: Path, pattern: str | None = None) -> list[str]:
    """The real path of each image file of ``folder`` (whose name fits ``pattern`` if
    given), in name order: the folder's own real
    path and the name, for an entry that is not a link (what ``os.path.realpath`` of its
    path gives, without resolving the folder's path again for each of them: 17 of the
    23 ms this module took on a 4 x 100 rig)."""
    try:
        if pattern is not None and "/" in pattern:     # sub-folders (real ones, no links)
            return [os.path.realpath(p) for p in list_image_files(folder, pattern)]
        entries = sorted_entries(folder)
        real = os.path.realpath(folder)
        return [os.path.realpath(e.path) if e.is_symlink() else os.path.join(real, e.name)
                for e in entries
                if Path(e.name).suffix.lower() in IMAGE_EXTENSIONS and is_file_entry(e)
                and (pattern is None or fnmatch.fnmatchcase(e.name, pattern))]
    except (OSError, DatasetError):
        return []


def outside_reads(rig: Rig, named: str | os.PathLike) -> tuple[str, ...]:
    """Notes naming each file a run of ``rig`` reads from outside the dataset folder.

    Parameters
    ----------
    rig : Rig
        As loaded (its paths are absolute and resolved).
    named : path-like
        The dataset as named on the command line: its folder (holding ``rig.yaml``) or the
        ``rig.yaml`` (whose folder is the dataset folder).

    Returns
    -------
    tuple of str
        One note for a ``rig.yaml`` that is a link out of the folder, then one per file read
        from outside it (intrinsics, motion capture, poses, bag), and one per camera listing
        its images read from outside it.
    """
    named = Path(os.path.abspath(named))
    named = named / "rig.yaml" if named.is_dir() else named
    root = Path(os.path.realpath(named.parent))
    where = f"outside the dataset folder {root}"
    notes = []
    real_rig = Path(os.path.realpath(named))
    if not _inside(real_rig, root):
        notes.append(f"{named.name} is a symbolic link to {real_rig}, {where}: the rig "
                     f"described there is calibrated, its paths relative to {real_rig.parent}")
    seen: set[Path] = set()

    def note(kind: str, path: Path | None) -> None:
        if path is None:
            return
        real = Path(os.path.realpath(path))
        if real in seen or _inside(real, root):
            return
        seen.add(real)
        notes.append(f"{kind} read from {where}: {real}")

    for name, cam in rig.cameras.items():
        spec = rig.mocap_for(name)
        note("intrinsics", cam.intrinsics)
        note("precomputed poses", cam.poses)
        note("bag", cam.rosbag)
        note("video", cam.video)
        note("frame stamps", cam.stamps)
        if spec is not None and "{stem}" not in str(spec.file):
            note("motion capture", spec.file)
        for kind, folder, pattern in (("images", cam.images, cam.images_pattern),
                                      ("intrinsics images", cam.intrinsics_images, None)):
            if folder is None:
                continue
            inside = str(root).rstrip(os.sep) + os.sep
            away = [Path(p) for p in _real_images(folder, pattern) if not p.startswith(inside)]
            away = [p for p in away if not _inside(p, root) and p not in seen]
            seen.update(away)
            if away:
                notes.append(f"camera {name}: {len(away)} {kind} read from {where}: "
                             + _listed(away))
    return tuple(notes)


#: At most this many files are named one by one in a note of :func:`outside_reads`.
NAMED_FILES = 5


def _listed(paths: list[Path]) -> str:
    """``paths`` named for a note: each, up to :data:`NAMED_FILES`; beyond, their one folder
    (``all in FOLDER``) or the first few and how many more (a camera whose image folder is a
    link to another disk named its thousands of images one by one, on the terminal and in
    the report)."""
    if len(paths) <= NAMED_FILES:
        return ", ".join(str(p) for p in paths)
    folders = {p.parent for p in paths}
    if len(folders) == 1:
        return f"all in {folders.pop()} ({paths[0].name} ... {paths[-1].name})"
    return (", ".join(str(p) for p in paths[:NAMED_FILES])
            + f" and {len(paths) - NAMED_FILES} more")
