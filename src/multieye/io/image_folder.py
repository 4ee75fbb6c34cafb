"""Image folders whose file names are time stamps (docs/rig-yaml.md, section 5).

Rule for a file name's stem (the name without its extension):

- digits, a decimal point, digits (``1700000000.123456``): seconds;
- only digits, at most 10 of them (``1700000000``): whole seconds (10 digits reach the year
  2286);
- only digits, 16 to 19 of them (``1700000000123456789``): integer nanoseconds (16 digits
  start at 1970-04-27, 19 fit in int64);
- anything else, including 11 to 15 digits (milliseconds or microseconds could not be told
  apart from the others), is an error naming the file.

Only files with an image extension (:data:`IMAGE_EXTENSIONS`, any case) are considered; other
files (notes, hidden files) and sub-folders are ignored.  An entry with an image extension
that is not a regular file (a folder, a device, a FIFO, a socket), and a symbolic link of any
name that does not lead to a regular file (dangling, a loop, to a device), is skipped and
listed by :func:`skipped_entries` with the reason.  Links to regular files elsewhere are
followed (datasets link to shared recordings).  Stamps are also returned as exact integer
nanoseconds (seconds with more than 9 decimals are rounded to the nearest nanosecond).
"""

from __future__ import annotations

import errno
import os
import re
import stat
from decimal import ROUND_HALF_EVEN, Decimal
from pathlib import Path

from multieye.core.arguments import as_path
from multieye.core.errors import DatasetError
from multieye.core.regular_files import file_kind

__all__ = ["IMAGE_EXTENSIONS", "list_images", "list_image_files", "stamp_from_name",
           "skipped_entries", "sorted_entries", "is_file_entry"]

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp")

_SECONDS = re.compile(r"^\d+\.\d+$")
_DIGITS = re.compile(r"^\d+$")


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
    if _DIGITS.match(stem):
        if len(stem) <= 10:
            return int(stem) * 1_000_000_000
        if 16 <= len(stem) <= 19:
            return int(stem)
        raise ValueError(f"{len(stem)} digits is ambiguous (milliseconds? microseconds?); "
                         "name images by seconds with a decimal point (1700000000.123456) or by "
                         "integer nanoseconds (16 to 19 digits)")
    raise ValueError("expected a time stamp: seconds (1700000000.123456) or integer "
                     "nanoseconds (1700000000123456789)")


def list_images(folder: str | os.PathLike) -> list[tuple[float, int, Path]]:
    """Images of a folder sorted by the time stamp in their names.

    Parameters
    ----------
    folder : path-like

    Returns
    -------
    list of (stamp_s, stamp_ns, path)
        ``stamp_s`` float seconds, ``stamp_ns`` exact int nanoseconds, sorted by time.

    Raises
    ------
    DatasetError
        Missing folder, no images, a name that is not a time stamp, two images with the same
        stamp (naming both).
    """
    root = as_path(folder, "image folder")
    if not root.is_dir():
        raise DatasetError("image folder not found", path=root)
    found: dict[int, Path] = {}
    for entry in sorted_entries(root):
        p = root / entry.name
        if p.suffix.lower() not in IMAGE_EXTENSIONS or not is_file_entry(entry):
            continue
        try:
            ns = stamp_from_name(p.stem)
        except ValueError as exc:
            raise DatasetError(f"image name is not a time stamp: {exc}", path=p) from None
        if ns in found:
            raise DatasetError(f"same time stamp as {found[ns].name}", path=p)
        found[ns] = p
    if not found:
        raise DatasetError(_none_found(root), path=root)
    return [(ns / 1e9, ns, found[ns]) for ns in sorted(found)]


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


def list_image_files(folder: str | os.PathLike) -> list[Path]:
    """Every image of a folder, sorted by name, whatever the names (images that carry no
    time, e.g. ``intrinsics_images``).

    Raises
    ------
    DatasetError
        Missing folder or no images.
    """
    root = as_path(folder, "image folder")
    if not root.is_dir():
        raise DatasetError("image folder not found", path=root)
    found = [p for p in sorted(root.iterdir())
             if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS]
    if not found:
        raise DatasetError(_none_found(root), path=root)
    return found


def _none_found(root: Path) -> str:
    skipped = skipped_entries(root)
    first = f"; {len(skipped)} skipped, first {skipped[0][0]}: {skipped[0][1]}" if skipped else ""
    return f"no images ({', '.join(IMAGE_EXTENSIONS)}) in the folder{first}"


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


def skipped_entries(folder: str | os.PathLike) -> list[tuple[str, str]]:
    """Entries of an image folder that are skipped, as ``(name, reason)`` sorted by name.

    An entry named like an image (:data:`IMAGE_EXTENSIONS`) that is not a regular file, and
    any symbolic link that does not lead to a regular file: a dangling link, a link loop, a
    folder, a device, a FIFO or a socket.  Sub-folders and other files are not images and are
    not listed.
    """
    root = Path(folder)
    out = []
    try:
        entries = sorted(root.iterdir())
    except OSError:
        return []
    for p in entries:
        if p.suffix.lower() not in IMAGE_EXTENSIONS and not p.is_symlink():
            continue
        problem = _entry_problem(p)
        if problem is not None:
            out.append((p.name, f"skipped: {problem}"))
    return out
