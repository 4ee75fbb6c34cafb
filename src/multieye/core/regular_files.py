"""Opening the user's files: regular files only, read with a byte bound (docs/rig-yaml.md,
section 1).

Every reader of a file named by a dataset (rig.yaml, intrinsics, motion capture, pose files,
calibration.json, images, bags) opens it here, so that

- a device (``/dev/zero``, ``/dev/urandom``), a FIFO, a socket or a folder is refused with
  one line naming the file and what it is, before a byte is read: the path is checked with
  ``stat`` first, then opened with ``O_NONBLOCK`` (a FIFO never blocks the open) and checked
  again with ``fstat`` on the open descriptor (what is read is what was checked, even if the
  path is swapped in between);
- a size bound holds while reading, not only on the size the file system states (a device
  states 0 bytes): at most ``max_bytes + 1`` bytes are read, and one more than the bound
  refuses the file;
- symbolic links are followed (datasets link to shared recordings), but only to regular files.

>>> from multieye.core.regular_files import read_bounded
>>> data = read_bounded("rig.yaml", what="rig.yaml", max_bytes=1_000_000)   # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
from collections.abc import Iterator
from pathlib import Path

from multieye.core.errors import DatasetError

__all__ = ["file_kind", "check_regular", "open_regular", "read_bounded", "open_bounded_text",
           "BoundedReader"]

_CHUNK = 1 << 20


def file_kind(mode: int) -> str:
    """What a ``st_mode`` is, for a message: ``"a character device"``, ``"a FIFO"``..."""
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    return "not a regular file"


def _refusal(path, what: str, kind: str) -> DatasetError:
    link = ""
    with contextlib.suppress(OSError, ValueError):
        if os.path.islink(path):
            link = f" (a symbolic link to {os.path.realpath(path)})"
    return DatasetError(f"expected a regular file as {what}, found {kind}{link}", path=path)


def _os_error(path, what: str, exc: OSError) -> DatasetError:
    if exc.errno == errno.ENOENT:
        if os.path.islink(path):
            return DatasetError(f"{what} is a dangling symbolic link (to "
                                f"{os.readlink(path)})", path=path)
        return DatasetError(f"{what} not found", path=path)
    if exc.errno == errno.ELOOP:
        return DatasetError(f"{what} is a symbolic link loop", path=path)
    if exc.errno == errno.EFBIG:
        return DatasetError(f"{what} is too large to read", path=path)
    return DatasetError(f"cannot read {what}: {exc.strerror or exc}", path=path)


def check_regular(path: str | os.PathLike, *, what: str = "file",
                  max_bytes: int | None = None) -> int:
    """Size in bytes of a regular file (links followed), or a DatasetError saying what it is.

    For readers that hand a path to a library (bag readers): the file is not opened here.
    """
    try:
        st = os.stat(path)
    except OSError as exc:
        raise _os_error(path, what, exc) from None
    except ValueError as exc:          # a NUL byte in the path
        raise DatasetError(f"invalid path for {what}: {exc}", path=repr(str(path))) from None
    if not stat.S_ISREG(st.st_mode):
        raise _refusal(path, what, file_kind(st.st_mode))
    if max_bytes is not None and st.st_size > max_bytes:
        raise DatasetError(f"{what} is {st.st_size} bytes, more than the {max_bytes} accepted "
                           "for it", path=path)
    return int(st.st_size)


def open_regular(path: str | os.PathLike, *, what: str = "file") -> int:
    """An open, blocking, read-only descriptor of a regular file (links followed).

    Raises
    ------
    DatasetError
        Missing, a dangling link or a link loop, not a regular file (checked before opening and
        again on the open descriptor), or unreadable.
    """
    check_regular(path, what=what)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags | getattr(os, "O_BINARY", 0))
    except OSError as exc:
        raise _os_error(path, what, exc) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise _refusal(path, what, file_kind(st.st_mode))
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd


def read_bounded(path: str | os.PathLike, *, what: str = "file", max_bytes: int) -> bytes:
    """All bytes of a regular file, refusing it once more than ``max_bytes`` have been read.

    Raises
    ------
    DatasetError
        As :func:`open_regular`, or the file holds more than ``max_bytes`` bytes (counted while
        reading: a file growing under the reader, or one whose stated size is wrong, is bound
        as well).
    """
    fd = open_regular(path, what=what)
    try:
        size = os.fstat(fd).st_size
        if size > max_bytes:
            raise DatasetError(f"{what} is {size} bytes, more than the {max_bytes} accepted "
                               "for it", path=path)
        parts, total = [], 0
        while True:
            chunk = os.read(fd, min(_CHUNK, max_bytes + 1 - total))
            if not chunk:
                break
            parts.append(chunk)
            total += len(chunk)
            if total > max_bytes:
                raise DatasetError(f"{what} holds more than the {max_bytes} bytes accepted "
                                   "for it", path=path)
    except OSError as exc:
        raise _os_error(path, what, exc) from None
    finally:
        os.close(fd)
    return b"".join(parts)


class BoundedReader:
    """A binary file object over a regular file that refuses to read past ``max_bytes``.

    Iterating gives its lines (``bytes``), as a file object does; reading past the bound
    raises :class:`DatasetError` naming the file.
    """

    def __init__(self, path, *, what: str, max_bytes: int):
        self.path, self.what, self.max_bytes = path, what, int(max_bytes)
        fd = open_regular(path, what=what)
        size = os.fstat(fd).st_size
        if size > max_bytes:
            os.close(fd)
            raise DatasetError(f"{what} is {size} bytes, more than the {max_bytes} accepted "
                               "for it", path=path)
        self._file = os.fdopen(fd, "rb", buffering=_CHUNK)
        self._read = 0

    def _count(self, n: int) -> None:
        self._read += n
        if self._read > self.max_bytes:
            raise DatasetError(f"{self.what} holds more than the {self.max_bytes} bytes "
                               "accepted for it", path=self.path)

    def __iter__(self) -> Iterator[bytes]:
        while True:
            try:
                line = self._file.readline(self.max_bytes + 1 - self._read + 1)
            except OSError as exc:
                raise _os_error(self.path, self.what, exc) from None
            if not line:
                return
            self._count(len(line))
            yield line

    def blocks(self) -> Iterator[bytes]:
        """The content in blocks of bytes (1 MiB)."""
        while True:
            try:
                block = self._file.read(min(_CHUNK, self.max_bytes + 1 - self._read))
            except OSError as exc:
                raise _os_error(self.path, self.what, exc) from None
            if not block:
                return
            self._count(len(block))
            yield block

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> BoundedReader:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_bounded_text(path, *, what: str, max_bytes: int) -> BoundedReader:
    """:class:`BoundedReader` (binary lines; decode each as UTF-8 where it is used)."""
    return BoundedReader(Path(path), what=what, max_bytes=max_bytes)
