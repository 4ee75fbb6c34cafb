"""Image folders whose file names are time stamps (docs/rig-yaml.md, section 5).

Rule for a file name's stem (the name without its extension):

- digits, a decimal point, digits (``1700000000.123456``): seconds;
- only digits, at most 10 of them (``1700000000``): whole seconds (10 digits reach the year
  2286);
- only digits, 16 to 19 of them (``1700000000123456789``): integer nanoseconds (16 digits
  are 1970-01-12 to 1970-04-26, or 12 to 116 days after a clock's start; microseconds of
  today's dates have 16 digits too: such images are 1000 times too early, which pairing
  with a motion capture names as clocks 1000 times apart; 19 fit in int64);
- whole seconds (at most 10 digits), an underscore, exactly 9 digits of nanoseconds
  (``1700000000_123456789``: ROS's ``sec`` and ``nsec`` as some recorders name frames);
- any of the last three forms with at least 9 digits of whole seconds (``1700000000.123456``,
  ``1700000000_123456789``, ``1700000000123456789``) after a prefix that ends in a character
  other than a digit or ``.`` (``frame_1700000000123456789``, ``rgb-1700000000.123456``,
  ``cam0_1700000000_123456789``: a recorder's prefix before the stamp; image folders only);
- anything else, including 11 to 15 digits (milliseconds or microseconds could not be told
  apart from the others), is an error naming the file.

Only files with an image extension (:data:`IMAGE_EXTENSIONS`, any case) are considered; other
files (notes, hidden files) and sub-folders are ignored.  An entry with an image extension
that is not a regular file (a folder, a device, a FIFO, a socket), and a symbolic link of any
name that does not lead to a regular file (dangling, a loop, to a device), is skipped and
listed by :func:`skipped_entries` with the reason.  Links to regular files elsewhere are
followed (datasets link to shared recordings).  Stamps are also returned as exact integer
nanoseconds (seconds with more than 9 decimals are rounded to the nearest nanosecond).

Recordings as users lay them out (rig.yaml's ``sync:``, docs/recordings.md): with ``sync``
other than ``time`` the names need not be stamps.  The images are then in natural name order
(``left2`` before ``left10``) and their stamps are their places in it (0, 1, 2, ... seconds);
what pairs them across cameras is their key (:func:`sync_keys`): the stem (``name``), the
number in the stem (``number``: ``left01`` and ``right1`` have the key ``1``; the last
integer that differs between the camera's images, :func:`numbers_in_names`) or the place
(``order``).  ``images:`` may be a pattern (:func:`check_pattern`: ``left*.jpg``) matched
against the names of the one folder's entries, never a path.
"""

from __future__ import annotations

import errno
import fnmatch
import os
import re
import stat
from decimal import ROUND_HALF_EVEN, Decimal
from collections.abc import Sequence
from pathlib import Path

from multieye.core.arguments import as_path
from multieye.core.errors import DatasetError
from multieye.core.limits import MAX_FOLDER_ENTRIES
from multieye.core.regular_files import file_kind

__all__ = ["IMAGE_EXTENSIONS", "SYNC_MODES", "list_images", "list_image_files",
           "stamp_from_name", "skipped_entries", "sorted_entries", "is_file_entry",
           "MAX_PATTERN_LEVELS", "check_pattern", "image_name", "label_stem", "natural_key",
           "number_in_name", "numbers_in_names", "sync_key", "sync_keys"]

#: Levels (sub-folders, then files) that an ``images:`` pattern may span.
MAX_PATTERN_LEVELS = 4

#: How images of different cameras are taken to be of one instant (rig.yaml's ``sync``).
SYNC_MODES = ("time", "name", "number", "order")
_NUMBER = re.compile(r"(\d+)(?!.*\d)")

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp")

_SECONDS = re.compile(r"^\d+\.\d+$")
_SEC_NSEC = re.compile(r"^(\d{1,10})_(\d{9})$")
_DIGITS = re.compile(r"^\d+$")
#: A stamp after a recorder's prefix (module docstring): the prefix ends in a character that
#: is neither a digit nor ``.``; only the unambiguous forms of an epoch stamp follow it.
_PREFIXED = re.compile(r"^.*[^0-9.](\d{9,10}\.\d+|\d{9,10}_\d{9}|\d{16,19})$")


def stamp_from_name(stem: str) -> int:
    """Integer nanoseconds of a file name stem, by the rule of the module docstring.

    Raises
    ------
    ValueError
        The stem is not a time stamp (the message says what is accepted).
    """
    if _SECONDS.match(stem):
        ns = (Decimal(stem) * 1_000_000_000).quantize(Decimal(1), rounding=ROUND_HALF_EVEN)
        return int(ns)
    sec_nsec = _SEC_NSEC.match(stem)
    if sec_nsec:
        return int(sec_nsec.group(1)) * 1_000_000_000 + int(sec_nsec.group(2))
    if _DIGITS.match(stem):
        if len(stem) <= 10:
            return int(stem) * 1_000_000_000
        if 16 <= len(stem) <= 19:
            return int(stem)
        raise ValueError(f"{len(stem)} digits is ambiguous (milliseconds? microseconds?); "
                         "name images by seconds with a decimal point (1700000000.123456) or by "
                         "integer nanoseconds (16 to 19 digits)")
    raise ValueError("expected a time stamp: seconds (1700000000.123456), integer "
                     "nanoseconds (1700000000123456789) or seconds_nanoseconds "
                     "(1700000000_123456789)")


def check_pattern(pattern: str) -> str:
    """``pattern`` if it is a file-name pattern (``fnmatch``: ``*``, ``?``, ``[...]``) for the
    entries of one folder (``left*.jpg``), or such patterns for sub-folders and then files,
    joined by ``/`` (``*/left.jpg``: one folder per instant, as some recorders write), at
    most :data:`MAX_PATTERN_LEVELS` of them; ValueError saying what was expected (``..``,
    ``.``, an empty part, ``**``, a backslash)."""
    parts = pattern.split("/") if isinstance(pattern, str) else []
    if (not parts or any(p in ("", ".", "..") for p in parts) or "\\" in pattern
            or "\0" in pattern or "**" in pattern or len(parts) > MAX_PATTERN_LEVELS):
        raise ValueError(f"expected a file-name pattern such as 'left*.jpg', or sub-folder "
                         f"patterns then a file-name pattern such as '*/left.jpg' (at most "
                         f"{MAX_PATTERN_LEVELS} levels; no '..', no '**'), got {pattern!r}")
    return pattern


def image_name(path: str | os.PathLike, folder: str | os.PathLike) -> str:
    """The name of an image of a camera's ``folder`` that time stamps and sync keys are read
    from: its path below ``folder`` without the extension, ``/`` between folders
    (``left01``; ``0001/left`` for ``0001/left.png`` matched by ``*/left.png``)."""
    return Path(path).relative_to(folder).with_suffix("").as_posix()


def label_stem(label: str) -> str:
    """:func:`image_name` of an image's label (its path below the camera's folder, as
    detection names it): the stem of a plain file name, the path without the extension of an
    image in a sub-folder."""
    return Path(label).stem if "/" not in label else Path(label).with_suffix("").as_posix()


def _stamp_of(name: str) -> int:
    """:func:`stamp_from_name` of an image's :func:`image_name`: its stem, else the name of
    the nearest of its sub-folders that is a stamp (``1700000000.5/left``)."""
    parts = name.split("/")
    try:
        return stamp_from_name(parts[-1])
    except ValueError:
        prefixed = _PREFIXED.match(parts[-1])
        if prefixed:
            return stamp_from_name(prefixed.group(1))
        for part in reversed(parts[:-1]):
            try:
                return stamp_from_name(part)
            except ValueError:
                continue
        raise


def natural_key(name: str) -> tuple:
    """Sort key of a file name in natural order: ``left2`` before ``left10``."""
    return tuple((0, int(t), "") if t.isdigit() else (1, 0, t)
                 for t in re.split(r"(\d+)", name) if t)


def number_in_name(stem: str) -> int | None:
    """The last integer in a file name's stem (``left01`` -> 1, ``frame_000123`` -> 123), or
    None when it has no digit."""
    m = _NUMBER.search(stem)
    return int(m.group(1)) if m else None


def numbers_in_names(stems: Sequence[str]) -> list[int | None]:
    """The number ``sync: number`` pairs each of one camera's images by (stems in natural
    order): when every stem holds as many integers, the last of them that is not the same in
    all (``0001_cam0`` ... ``0016_cam0`` -> 1 ... 16, ``cam0_frame2_v2`` -> 2: an integer
    every image of the camera shares names the camera, not the instant); otherwise, or when
    no integer differs (one image), the last integer (:func:`number_in_name`); None for a
    stem without a digit."""
    runs = [[int(d) for d in re.findall(r"\d+", s)] for s in stems]
    field = -1
    if len({len(r) for r in runs}) == 1 and len(runs[0]) > 1:
        varying = [i for i in range(len(runs[0])) if len({r[i] for r in runs}) > 1]
        field = varying[-1] if varying else -1
    return [r[field] if r else None for r in runs]


def sync_keys(stems: Sequence[str], sync: str) -> list[str]:
    """The instant keys of one camera's images under ``sync`` (not ``time``), stems in
    natural name order: the stem (``name``; for images in sub-folders the parts that vary,
    :func:`_varying_parts`), the number of :func:`numbers_in_names` (``number``) or the
    place (``order``)."""
    if sync == "number":
        return [str(n) for n in numbers_in_names(stems)]
    if sync == "name" and any("/" in s for s in stems):
        return _varying_parts(stems)
    return [sync_key(s, sync, k) for k, s in enumerate(stems)]


def _varying_parts(stems: Sequence[str]) -> list[str]:
    """``sync: name`` keys of images in sub-folders (:func:`image_name`): the parts of their
    names that are not the same in all of the camera's images (``0001/left`` ... ``0016/left``
    -> ``0001`` ... ``0016``: the folder names the instant, the file the camera), each whole
    name where the names do not all have as many parts or none differs."""
    split = [n.split("/") for n in stems]
    if len({len(p) for p in split}) != 1:
        return list(stems)
    varying = [i for i in range(len(split[0])) if len({p[i] for p in split}) > 1]
    if not varying:
        return list(stems)
    return ["/".join(p[i] for i in varying) for p in split]


def sync_key(stem: str, sync: str, place: int) -> str:
    """The key images of different cameras taken at one instant share under ``sync`` (not
    ``time``): the stem, its last integer, or the image's ``place`` in its camera's natural
    name order."""
    if sync == "name":
        return stem
    if sync == "number":
        return str(number_in_name(stem))
    return str(place)


def _entries(folder: Path) -> list[os.DirEntry]:
    """:func:`sorted_entries`, at most :data:`MAX_FOLDER_ENTRIES` of them."""
    entries = sorted_entries(folder)
    if len(entries) > MAX_FOLDER_ENTRIES:
        raise DatasetError(f"{len(entries)} entries, more than {MAX_FOLDER_ENTRIES} in one image "
                           "folder", path=folder)
    return entries


def _pattern_folders(root: Path, pattern: str | None) -> tuple[list[Path], str | None]:
    """The folders whose files a pattern's last part is matched against (``root`` alone for a
    file-name pattern; the sub-folders matched level by level for ``*/left.jpg``: real
    folders only, never a link, no hidden ones) and that last part."""
    if pattern is None or "/" not in pattern:
        return [root], pattern
    *levels, last = pattern.split("/")
    folders = [root]
    for level in levels:
        folders = [f / e.name for f in folders for e in _entries(f)
                   if not e.name.startswith(".") and fnmatch.fnmatchcase(e.name, level)
                   and e.is_dir(follow_symlinks=False)]
        if len(folders) > MAX_FOLDER_ENTRIES:
            raise DatasetError(f"more than {MAX_FOLDER_ENTRIES} folders match {pattern}",
                               path=root)
    return folders, last


def _matching(root: Path, pattern: str | None) -> list[Path]:
    """The regular files (links to them followed) with an image extension whose names fit
    ``pattern`` (its sub-folders too, :func:`_pattern_folders`), in name order; at most
    :data:`MAX_FOLDER_ENTRIES` entries per folder."""
    folders, last = _pattern_folders(root, pattern)
    return [f / e.name for f in folders for e in _entries(f)
            if Path(e.name).suffix.lower() in IMAGE_EXTENSIONS and not e.name.startswith(".")
            and (last is None or fnmatch.fnmatchcase(e.name, last)) and is_file_entry(e)]


def list_images(folder: str | os.PathLike, pattern: str | None = None, sync: str = "time"
                ) -> list[tuple[float, int, Path]]:
    """Images of a folder sorted by the time stamp in their names (``sync`` ``time``), else in
    natural name order with their places as stamps.

    Parameters
    ----------
    folder : path-like
    pattern : str, optional
        Only the entries whose names fit this file-name pattern (:func:`check_pattern`).
    sync : {"time", "name", "number", "order"}

    Returns
    -------
    list of (stamp_s, stamp_ns, path)
        ``stamp_s`` float seconds, ``stamp_ns`` exact int nanoseconds, sorted by time.

    Raises
    ------
    DatasetError
        Missing folder, no images, a name that is not a time stamp, two images with the same
        stamp (or, with ``sync: number``, the same number; naming both).
    """
    root = as_path(folder, "image folder")
    if not root.is_dir():
        raise DatasetError("image folder not found", path=root)
    paths = _matching(root, pattern)
    if not paths:
        raise DatasetError(_none_found(root, pattern), path=root)
    if sync != "time":
        paths = sorted(paths, key=lambda p: natural_key(image_name(p, root)))
        if sync in ("number", "name"):
            _unique_keys(paths, sync, root)
        return [(float(k), k * 1_000_000_000, p) for k, p in enumerate(paths)]
    found: dict[int, Path] = {}
    for p in paths:
        try:
            ns = _stamp_of(image_name(p, root))
        except ValueError as exc:
            raise DatasetError(f"image name is not a time stamp: {exc}; give the camera "
                               "'stamps:', a file of the images' stamps (one per line in name "
                               "order, or name and stamp per line: EuRoC's data.csv, TUM's "
                               "rgb.txt), or rig.yaml's 'sync: name | number | order' to pair "
                               "images by name", path=p) from None
        if ns in found:
            raise DatasetError(f"same time stamp as {found[ns].relative_to(root)}", path=p)
        found[ns] = p
    return [(ns / 1e9, ns, found[ns]) for ns in sorted(found)]


def _unique_keys(paths: list[Path], sync: str, root: Path) -> None:
    """Refuse two images of one camera with one key under ``sync`` (name or number)."""
    seen: dict[str, Path] = {}
    for p, key in zip(paths, sync_keys([image_name(p, root) for p in paths], sync)):
        if sync == "number" and key == "None":
            raise DatasetError("sync: number pairs images by the number in their names; "
                               "this name has none", path=p)
        if key in seen:
            what = f"number {key}" if sync == "number" else f"name {key}"
            raise DatasetError(f"same {what} as {seen[key].relative_to(root)} in this camera's "
                               f"images (sync: {sync} pairs one image per camera and {what}; sync: "
                               "order pairs the k-th image of each camera)", path=p)
        seen[key] = p


#: What ``Path.is_file`` takes for "not a file" rather than an error.
_NOT_THERE = (errno.ENOENT, errno.ENOTDIR, errno.EBADF, errno.ELOOP)


def sorted_entries(folder: str | os.PathLike) -> list[os.DirEntry]:
    """The entries of a folder (``os.scandir``) in name order, as ``sorted(Path.iterdir())``
    gives them."""
    with os.scandir(folder) as it:
        return sorted(it, key=lambda e: e.name)


def is_file_entry(entry: os.DirEntry) -> bool:
    """``Path.is_file`` of a folder's entry (links followed; a dangling link or a loop is
    not a file), from the type the listing gave where it is not a link: no ``stat`` of
    each image (a third of listing a 100-image folder)."""
    try:
        return entry.is_file()
    except OSError as exc:
        if exc.errno in _NOT_THERE:
            return False
        raise


def list_image_files(folder: str | os.PathLike, pattern: str | None = None) -> list[Path]:
    """Every image of a folder (whose name fits ``pattern`` if given), sorted by name,
    whatever the names (images that carry no time, e.g. ``intrinsics_images``).

    Raises
    ------
    DatasetError
        Missing folder or no images.
    """
    root = as_path(folder, "image folder")
    if not root.is_dir():
        raise DatasetError("image folder not found", path=root)
    found = _matching(root, pattern)
    if not found:
        raise DatasetError(_none_found(root, pattern), path=root)
    return found


def _none_found(root: Path, pattern: str | None = None) -> str:
    skipped = skipped_entries(root, pattern)
    first = f"; {len(skipped)} skipped, first {skipped[0][0]}: {skipped[0][1]}" if skipped else ""
    if pattern is not None:
        return f"no image ({', '.join(IMAGE_EXTENSIONS)}) named {pattern} in the folder{first}"
    return f"no images ({', '.join(IMAGE_EXTENSIONS)}) in the folder{first}{_in_sub_folders(root)}"


def _in_sub_folders(root: Path, most: int = 20) -> str:
    """Where the images are when a folder has none of its own but a sub-folder has (EuRoC's
    ``cam0/data/``): the first of its first ``most`` sub-folders holding images, for the
    message; empty when none does."""
    try:
        subs = [e for e in sorted_entries(root) if e.is_dir()][:most]
        for sub in subs:
            count = sum(1 for e in sorted_entries(sub.path)
                        if Path(e.name).suffix.lower() in IMAGE_EXTENSIONS)
            if count:
                return (f"; its sub-folder {sub.name}/ holds {count} images (sub-folders are "
                        f"not searched): give that folder as the camera's images: in rig.yaml")
    except OSError:
        pass
    return ""


def _entry_problem(p: Path) -> str | None:
    """Why an entry is not a regular file (following links), or None when it is one."""
    try:
        st = os.stat(p)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "a symbolic link loop"
        if exc.errno == errno.ENOENT and os.path.islink(p):
            return f"a dangling symbolic link (to {os.readlink(p)})"
        return f"cannot be read: {exc.strerror or exc}"
    if stat.S_ISREG(st.st_mode):
        return None
    kind = file_kind(st.st_mode)
    if os.path.islink(p):
        return f"a symbolic link to {kind}, not to a regular file ({os.path.realpath(p)})"
    return f"{kind}, not a regular file"


def skipped_entries(folder: str | os.PathLike, pattern: str | None = None
                    ) -> list[tuple[str, str]]:
    """Entries of an image folder (whose names fit ``pattern`` if given) that are skipped, as
    ``(name, reason)`` sorted by name.

    An entry named like an image (:data:`IMAGE_EXTENSIONS`) that is not a regular file or
    whose name starts with ``.`` (a hidden file: macOS's ``._`` files beside copied ones),
    and any symbolic link that does not lead to a regular file: a dangling link, a link
    loop, a folder, a device, a FIFO or a socket.  Sub-folders and other files are not images and are
    not listed.
    """
    root = Path(folder)
    if pattern is not None and "/" in pattern:
        return _skipped_below(root, pattern)
    out = []
    try:
        entries = sorted(root.iterdir())
    except OSError:
        return []
    for p in entries:
        if p.suffix.lower() not in IMAGE_EXTENSIONS and not p.is_symlink():
            continue
        if pattern is not None and not fnmatch.fnmatchcase(p.name, pattern):
            continue
        if p.name.startswith("."):
            out.append((p.name, "skipped: a hidden file (such as the ._ files macOS writes "
                                "beside copied files)"))
            continue
        problem = _entry_problem(p)
        if problem is not None:
            out.append((p.name, f"skipped: {problem}"))
    return out


def _skipped_below(root: Path, pattern: str) -> list[tuple[str, str]]:
    """:func:`skipped_entries` of a pattern with sub-folders (``*/left.jpg``): in every folder
    it matches, named by their paths below ``root``; and the links that a folder part of the
    pattern matches, which are not followed (a folder of the dataset is read, never one a
    link leads to)."""
    out = []
    levels = pattern.split("/")[:-1]
    try:
        for depth in range(len(levels)):
            above, _ = _pattern_folders(root, "/".join(levels[:depth] + ["x"]))
            out += [((f / e.name).relative_to(root).as_posix(), "skipped: a symbolic link "
                     "to a folder, not followed (give the folder itself)")
                    for f in above for e in _entries(f)
                    if fnmatch.fnmatchcase(e.name, levels[depth]) and e.is_symlink()]
        folders, last = _pattern_folders(root, pattern)
    except (OSError, DatasetError):
        return out
    for f in folders:
        out += [(f"{f.relative_to(root).as_posix()}/{name}", why)
                for name, why in skipped_entries(f, last)]
    return sorted(out)
