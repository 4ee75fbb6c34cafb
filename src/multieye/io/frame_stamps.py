"""Frame stamps files: one time stamp per frame of a video, or per image of a folder.

Each line holds the stamp of one frame, by the rule of image names
(:func:`multieye.io.image_folder.stamp_from_name`): seconds with a decimal point
(``1700000000.033333``) or integer nanoseconds (16 to 19 digits), or whole seconds of at most
10 digits; also seconds in exponent form (``1.036896e-01``, KITTI's ``times.txt``) and a UTC
date and time (``2011-09-26 13:02:25.594360375``, KITTI's ``timestamps.txt``: taken as UTC;
only differences between stamps matter to a rig without motion capture).  ``#`` starts a
comment, empty lines are skipped.  Stamps must increase, and lie from 1970 to the largest
stamp integer nanoseconds hold (:data:`MAX_STAMP_NS`, the year 2262).

For a folder of images (:func:`read_image_stamps`) a line may instead name its image: a file
name and a stamp in either order, separated by a comma or a semicolon (a name may then hold
spaces) or else white space (EuRoC's ``data.csv``:
``1403636579763555584,1403636579763555584.png``; TUM's ``rgb.txt``: ``stamp rgb/name.png``);
a first line of names (no field a number: ``timestamp,filename``) is a header, any other
line that is not a stamp is refused with its number.  One stamp per line gives the stamps of
the images in natural name order, as many as there are images.

Synopsis
--------
>>> from multieye.io.frame_stamps import read_frame_stamps
>>> ns = read_frame_stamps("cam0_stamps.txt")       # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
import re
import unicodedata
from datetime import datetime, UTC
from pathlib import Path

import numpy as np

from multieye.core.errors import DatasetError
from multieye.core.limits import MAX_STAMP_S
from multieye.io.image_folder import MAX_PATTERN_LEVELS, stamp_from_name
from multieye.io.textfile import text_lines

__all__ = ["MAX_STAMP_NS", "read_frame_stamps", "read_image_stamps", "stamp_text"]

#: Largest stamp of a stamps file, integer nanoseconds: within ``MAX_STAMP_S`` seconds and
#: within int64 (the year 2262), as every stamp is held.
MAX_STAMP_NS = min(int(MAX_STAMP_S) * 1_000_000_000, 2**63 - 1)

_EXPONENT = re.compile(r"^[0-9]+(\.[0-9]*)?[eE][-+]?[0-9]+$")
_DATE_TIME = re.compile(r"^(\d{4})-(\d{2})-(\d{2})[ T](\d{2}):(\d{2}):(\d{2})(?:\.(\d{1,9}))?$")
_SEPARATORS = re.compile(r"[,;]")


def stamp_text(text: str) -> int:
    """Integer nanoseconds of one stamp in a stamps file (module docstring).

    Raises
    ------
    ValueError
        Not a stamp (the message says what is accepted), or one before 1970 or after
        :data:`MAX_STAMP_NS` (``1.0e300``, ``9999-12-31 ...``).
    """
    ns = _stamp_ns(text.strip())
    if not 0 <= ns <= MAX_STAMP_NS:
        raise ValueError(f"a time stamp from 0 (1970) to {MAX_STAMP_NS} nanoseconds (the "
                         f"year 2262), got {text.strip()[:40]!r}")
    return ns


def _stamp_ns(text: str) -> int:
    """:func:`stamp_text` without its bounds (an exponent beyond the float range: -1)."""
    if _EXPONENT.match(text):
        seconds = float(text)
        return int(round(seconds * 1e9)) if math.isfinite(seconds * 1e9) else -1
    when = _DATE_TIME.match(text)
    if when:
        *ymdhms, fraction = when.groups()
        seconds = datetime(*map(int, ymdhms), tzinfo=UTC).timestamp()
        return int(seconds) * 1_000_000_000 + int((fraction or "0").ljust(9, "0"))
    try:
        return stamp_from_name(text)
    except ValueError as exc:
        raise ValueError(f"{exc}, seconds in exponent form (1.036896e-01) or a UTC date and "
                         "time (2011-09-26 13:02:25.594360375)") from None


def read_frame_stamps(path: str | os.PathLike) -> np.ndarray:
    """Integer nanoseconds of every frame, (n,), from a stamps file (module docstring).

    Raises
    ------
    DatasetError
        Missing or unreadable file, a line that is not one time stamp (with its number), a
        stamp not after the one before, no stamp at all.
    """
    out = _increasing(path, text_lines(path, what="frame stamps file"), "frame")
    if not out:
        raise DatasetError("no frame stamp in the file", path=path)
    return np.array(out, dtype=np.int64)


def _increasing(path, lines, what: str) -> list[int]:
    """The stamps of ``(line number, text)`` lines, one each, each after the one before
    (DatasetError naming the line otherwise; ``what``: frame or image)."""
    out: list[int] = []
    for number, text in lines:
        try:
            ns = stamp_text(text)
        except ValueError as exc:
            raise DatasetError(f"expected one time stamp per line: {exc}", path=path,
                               line=number) from None
        if out and ns <= out[-1]:
            raise DatasetError(f"stamps must increase, {what} by {what}", path=path,
                               line=number)
        out.append(ns)
    return out


def read_image_stamps(path: str | os.PathLike, images: list[Path], folder: Path) -> list[int]:
    """Integer nanoseconds of each of ``images`` (natural name order, below ``folder``) from a
    stamps file (module docstring): by name where its lines name images, else one per line.

    Raises
    ------
    DatasetError
        A line that is neither (with its number), stamps not increasing (one per line), a
        count other than the images' (one per line), an image without a stamp or two stamps
        for one image (by name; naming it), no stamp at all.
    """
    rows = [(number, _fields(text)) for number, text in
            text_lines(path, what="image stamps file")]
    if rows and _is_header(rows[0][1]):
        rows = rows[1:]                                 # a header: timestamp,filename
    if not rows:
        raise DatasetError("no stamp in the file", path=path)
    if all(len(fields) == 1 for _, fields in rows):
        return _in_order(path, rows, images)
    return _by_name(path, rows, images, folder)


def _fields(text: str) -> list[str]:
    """A line's fields: split at commas and semicolons where it has one (a name may then
    hold spaces: ``My Frames/0001.png``, a stamp be a date and a time), else at white space;
    a date and a time (``2011-09-26 13:02:25.5``) are one."""
    if _SEPARATORS.search(text):
        return [f.strip() for f in _SEPARATORS.split(text) if f.strip()]
    fields = text.split()
    return [" ".join(fields)] if _DATE_TIME.match(" ".join(fields)) else fields


def _is_header(fields: list[str]) -> bool:
    """Whether a first line's fields are names (``timestamp``, ``filename``): none a stamp
    nor a number nor starting as one (``-0.5``, ``nan``, ``1.0x`` are stamps gone wrong, said
    with their line, never dropped as a header)."""
    def number_like(f: str) -> bool:
        try:
            float(f)
        except ValueError:
            return f[0] in "0123456789+-."
        return True
    return not any(_is_stamp(f) or number_like(f) for f in fields)


def _is_stamp(text: str) -> bool:
    try:
        stamp_text(text)
    except ValueError:
        return False
    return True


def _in_order(path, rows, images: list[Path]) -> list[int]:
    """One stamp per line, for the images in name order."""
    out = _increasing(path, ((number, fields[0]) for number, fields in rows), "image")
    if len(out) != len(images):
        raise DatasetError(f"{len(out)} stamps for {len(images)} images: one stamp per line "
                           "gives the images' stamps in name order, as many as the images "
                           "(or name each image on its line: name,stamp)", path=path)
    return out


def _by_name(path, rows, images: list[Path], folder: Path) -> list[int]:
    """Lines of a file name and a stamp, either order; each image's stamp by its name (its
    path below ``folder``, or the file name alone)."""
    stamps: dict[str, int] = {}
    for number, fields in rows:
        stamp = [f for f in fields if _is_stamp(f)]
        named = [f for f in fields if not _is_stamp(f)]
        if len(fields) != 2 or len(stamp) != 1:
            raise DatasetError(f"expected an image's name and its time stamp, got "
                               f"{' '.join(fields)[:80]!r}", path=path, line=number)
        key = _nfc(named[0].replace("\\", "/"))
        if key in stamps:
            raise DatasetError(f"a second stamp for {key}", path=path, line=number)
        stamps[key] = stamp_text(stamp[0])
    tails = _tails(stamps)
    out = []
    for p in images:
        below = _nfc(p.relative_to(folder).as_posix())
        hit = [k for k in (below, _nfc(p.name)) if k in stamps]
        if not hit:
            hit = tails.get(below, [])
            if len(hit) > 1:
                raise DatasetError(f"two lines name image {below}: {hit[0]} and {hit[1]} "
                                   "(name each image once)", path=path)
        if not hit:
            raise DatasetError(f"no stamp for image {below} (its lines name images: every "
                               "image needs its line)", path=path)
        out.append(stamps[hit[0]])
    return out


def _nfc(name: str) -> str:
    """``name`` in Unicode's composed form: ``é`` typed (NFC) and as macOS's HFS+ stores it
    (NFD, ``e`` and an accent) are one name."""
    return unicodedata.normalize("NFC", name)


def _tails(lines) -> dict[str, list[str]]:
    """The lines' image names by each path of at most :data:`MAX_PATTERN_LEVELS` parts after a
    ``/`` they end in (``a/b/0001/left.png`` under ``0001/left.png``, ``b/0001/left.png``,
    ...): an image's line by its path below the camera's folder in one look-up, not a scan of
    every line per image (quadratic: 7 s for 8,000 images)."""
    out: dict[str, list[str]] = {}
    for line in lines:
        parts = line.rsplit("/", MAX_PATTERN_LEVELS)
        for k in range(1, len(parts)):
            out.setdefault("/".join(parts[k:]), []).append(line)
    return out
