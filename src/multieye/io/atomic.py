"""Atomic file writes: a reader sees the old file or the complete new one, never a part.

Every writer goes through :func:`atomic_output` (docs/outputs.md, section 1): the content
is written to a temporary file in the destination's folder (same file system, so the final
rename is atomic), flushed and fsync'ed, then moved over the destination with
:func:`os.replace`.  If anything fails before the rename, the temporary file is removed and the
destination is untouched.

>>> from multieye.io.atomic import write_text_atomic
>>> write_text_atomic("calibration.json", "{}\\n")   # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from multieye.core.errors import DatasetError

__all__ = ["atomic_output", "write_text_atomic", "write_bytes_atomic"]


def _fsync_folder(folder: Path) -> None:
    """Make the rename durable (best effort: not every platform can open a folder)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike, *, binary: bool = False,
                  encoding: str = "utf-8") -> Iterator[IO]:
    """Context manager yielding a file whose content replaces ``path`` on success.

    Parameters
    ----------
    path : path-like
        Destination.  Its folder must exist.
    binary : bool
        Yield a binary file instead of a text file.
    encoding : str
        Text encoding (text mode only); newlines are written as ``\\n``.

    Raises
    ------
    DatasetError
        The folder is missing or not writable, or the write fails; ``path`` is unchanged and
        no temporary file is left behind.  Exceptions raised by the caller inside the block
        propagate unchanged, with the same clean-up.
    """
    dest = Path(path)
    folder = dest.parent if str(dest.parent) else Path(".")
    if not folder.is_dir():
        raise DatasetError("cannot write: the output folder does not exist", path=dest)
    tmp = folder / f".{dest.name}.{uuid.uuid4().hex}.tmp"
    try:
        # O_EXCL: never clobber; mode 0o666 so that the umask applies as for a normal file.
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                     0o666)
    except OSError as exc:
        raise DatasetError(f"cannot write: {exc.strerror}", path=dest) from exc
    try:
        mode = "wb" if binary else "w"
        kwargs = {} if binary else {"encoding": encoding, "newline": "\n"}
        with os.fdopen(fd, mode, **kwargs) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, dest)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise DatasetError(f"cannot write: {exc.strerror or exc}", path=dest) from exc
        raise
    _fsync_folder(folder)


def write_text_atomic(path: str | os.PathLike, text: str, *, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; returns the path."""
    with atomic_output(path, encoding=encoding) as handle:
        handle.write(text)
    return Path(path)


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns the path."""
    with atomic_output(path, binary=True) as handle:
        handle.write(data)
    return Path(path)
