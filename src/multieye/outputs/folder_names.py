"""The names a run writes beside and inside its output folder, checked before anything runs.

A run writes ``OUT.multieye-lock``, a staging folder ``OUT.multieye-tmp-<pid>-<hex>`` and,
while swapping, ``OUT.multieye-old-<pid>-<hex>`` beside ``OUT`` (:mod:`multieye.outputs.folder`),
and its files inside the staging folder. A name over the file system's ``NAME_MAX`` (255 bytes)
or a path over its ``PATH_MAX`` (4096 bytes) failed only when the staging folder was made,
after the calibration had run. :func:`output_path_problem` says up front what would not fit;
:func:`checked_output` (OUT resolved as the lock and the names beside it see it,
:func:`resolved_output`) refuses it in every command that writes a folder
(:func:`multieye.outputs.folder.claim_output`, ``calibrate-many`` for each of its folders).
"""

from __future__ import annotations

import os
from pathlib import Path

from multieye.core.errors import DatasetError

__all__ = ["INSIDE_BYTES", "LOCK_BYTES", "SIBLING_BYTES", "checked_output", "lock_path", "output_path_problem",
           "resolved_output", "sibling"]

#: Digits of the longest process id a name beside OUT may hold (Linux: 7; Windows: 10).
_PID_DIGITS = 10

#: Bytes the longest name beside OUT adds to OUT's name: ``.multieye-old-<pid>-<8 hex>``.
SIBLING_BYTES = len(".multieye-old-") + _PID_DIGITS + 1 + 8

#: Bytes the lock file's name adds to OUT's name (all a command that writes into OUT without
#: replacing it, ``report``, ``export``, ``experiment``, puts beside it).
LOCK_BYTES = len(".multieye-lock")

#: Bytes of the longest path a run writes inside OUT, with its separator: a camera's lens
#: file while it is written, ``/intrinsics/.<name>.yaml.<32 hex>.tmp``, camera names being at
#: most :data:`~multieye.core.names.MAX_NAME_BYTES` (200) bytes.
INSIDE_BYTES = 256

_NAME_MAX, _PATH_MAX = 255, 4096        # POSIX's usual values, where pathconf cannot say


def resolved_output(out: str | os.PathLike) -> Path:
    """``out`` made absolute, the folders above it resolved (once, here) as the file system
    does (``link/../out`` lies beside the link's target: the folder read, whose lock it is),
    ``out`` itself not: a link there is refused later (:func:`multieye.outputs.folder.claim_output`)."""
    raw = os.path.join(os.getcwd(), os.path.expanduser(os.fspath(out)))
    head, name = os.path.split(raw.rstrip(os.sep) or os.sep)
    while name == "." and head.rstrip(os.sep):          # out/. names out itself
        head, name = os.path.split(head.rstrip(os.sep))
    path = (Path(os.path.realpath(raw)) if name in ("", "..")
            else Path(os.path.realpath(head or os.sep)) / name)
    if path.parent == path:
        raise DatasetError("cannot use the root of a file system as the output folder",
                           path=path)
    return path


def checked_output(out_dir: str | os.PathLike, *, staged: bool = True) -> Path:
    """``out_dir`` resolved (:func:`resolved_output`); DatasetError naming it as typed when
    :func:`output_path_problem` finds a name too long (``staged``: OUT is written in a
    staging folder beside it and swapped in; else only its lock file is beside it)."""
    out = resolved_output(out_dir)
    problem = output_path_problem(out, SIBLING_BYTES if staged else LOCK_BYTES)
    if problem is not None:
        raise DatasetError(problem, path=out_dir)
    return out


def lock_path(out: Path) -> Path:
    """The lock file beside ``out``."""
    return out.parent / f"{out.name}.multieye-lock"


def sibling(out: Path, kind: str) -> Path:
    """A fresh staging (``tmp``) or backup (``old``) folder name beside ``out``."""
    return out.parent / f"{out.name}.multieye-{kind}-{os.getpid()}-{os.urandom(4).hex()}"


def _limit(path: Path, name: str, default: int) -> int:
    """``pathconf(name)`` of the nearest folder of ``path`` that exists, else ``default``."""
    for folder in (path, *path.parents):
        try:
            if folder.is_dir():
                return int(os.pathconf(folder, name))
        except (OSError, ValueError, AttributeError):     # no pathconf (Windows), no limit
            return default
    return default


def output_path_problem(out: Path, beside: int = SIBLING_BYTES) -> str | None:
    """What in the output folder's path is too long for the file system, or None.

    Parameters
    ----------
    out : Path
        The output folder, absolute, the folders above it resolved.
    beside : int
        Bytes the longest name written beside OUT adds to its name (:data:`SIBLING_BYTES`
        with a staging folder, :data:`LOCK_BYTES` without).

    Returns
    -------
    str or None
        One sentence saying what was found and what was expected: a folder of the path
        over ``NAME_MAX`` bytes, OUT's name too long for the names beside it
        (``NAME_MAX - beside``), or the whole path too long for the files inside
        (``PATH_MAX - 1 - beside - INSIDE_BYTES``); bytes of the file-system encoding.
    """
    name_max = _limit(out.parent, "PC_NAME_MAX", _NAME_MAX)
    path_max = _limit(out.parent, "PC_PATH_MAX", _PATH_MAX)
    for part in out.parts[1:-1]:
        if len(os.fsencode(part)) > name_max:
            return (f"a folder name above the output folder is {len(os.fsencode(part))} bytes "
                    f"long; expected at most {name_max} bytes (the file system's NAME_MAX)")
    what = ("the staging and lock names beside it, <name>.multieye-tmp-<pid>-<hex>"
            if beside > LOCK_BYTES else "the lock file beside it, <name>.multieye-lock")
    size, most = len(os.fsencode(out.name)), name_max - beside
    if size > most:
        return (f"the output folder's name is {size} bytes long; expected at most {most} bytes "
                f"(NAME_MAX {name_max} less {beside} for {what})")
    size, most = len(os.fsencode(str(out))), path_max - 1 - beside - INSIDE_BYTES
    if size > most:
        return (f"the output folder's path is {size} bytes long; expected at most {most} bytes "
                f"(PATH_MAX {path_max} less {beside} for {what.split(',')[0]} and "
                f"{INSIDE_BYTES} for the files inside)")
    return None
