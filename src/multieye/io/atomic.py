"""Atomic file writes: a reader sees the old file or the complete new one, never a part.

Every writer goes through :func:`atomic_output` (docs/outputs.md, section 1): the content
is written to a temporary file in the destination's folder (same file system, so the final
rename is atomic), created exclusively and never through a symbolic link, flushed and
fsync'ed, then moved over the destination with :func:`os.replace`.  If anything fails before
the rename, the temporary file is removed and the destination is untouched.  Below a folder
held with :func:`synced_together` (a staging folder, which nobody reads before it is
complete) the files are synced all at once when its block ends instead of one by one.

Inside a folder held with :func:`confined_to` (an output folder, a staging folder), nothing
is written, created or removed through a symbolic link: the path below that folder is walked
one folder at a time with ``O_NOFOLLOW`` (each step opened relative to the one before, so a
link put in place meanwhile is found too), and a destination, a folder or a file to remove
that is a link is refused with one line (:func:`make_folder`, :func:`remove_file`).

>>> from multieye.io.atomic import write_text_atomic
>>> write_text_atomic("calibration.json", "{}\\n")   # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from multieye.core.errors import DatasetError

__all__ = ["atomic_output", "write_text_atomic", "write_bytes_atomic", "confined_to",
           "make_folder", "remove_file", "write_problem", "synced_together"]

_DIR_FDS = os.open in os.supports_dir_fd and os.replace in os.supports_dir_fd
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_DIRECTORY = getattr(os, "O_DIRECTORY", 0)

_ROOTS: dict[Path, int] = {}
_ROOTS_GUARD = threading.Lock()
#: The files written below each root of :func:`synced_together`, synced when its block ends.
_BATCHES: dict[Path, list[Path]] = {}
#: At most this many files synced at once by :func:`synced_together` (a thread each).
SYNC_THREADS = 8

#: What the usual reasons of a failed write mean, added to the system's words.
_HINTS = {getattr(errno, name): hint for name, hint in (
    ("EFBIG", "over the file-size limit of this process, ulimit -f"),
    ("ENOSPC", "the disk is full"), ("EDQUOT", "the disk quota is used up"))
    if hasattr(errno, name)}


def write_problem(exc: OSError) -> str:
    """The system's words for a failed write, with what they mean for the common causes."""
    words = exc.strerror or str(exc)
    hint = _HINTS.get(exc.errno)
    return f"{words} ({hint})" if hint and hint not in words else words


def _abs(path: str | os.PathLike) -> Path:
    """``path`` made absolute, ``..`` read as the file system reads it: the part up to the
    last ``..`` resolved (``link/..`` is the folder above the link's target, not the folder
    holding the link, as ``os.path.abspath`` has it), the rest by its letters, links kept
    (a link inside a confined folder is found and refused, not followed)."""
    parts = Path(os.path.join(os.getcwd(), os.fspath(path))).parts
    if ".." not in parts:
        return Path(os.path.abspath(os.fspath(path)))
    last = len(parts) - parts[::-1].index("..")
    return Path(os.path.normpath(os.path.join(os.path.realpath(os.path.join(*parts[:last])),
                                              *parts[last:])))


@contextlib.contextmanager
def confined_to(root: str | os.PathLike) -> Iterator[Path]:
    """Within the block, writes below ``root`` never go through a symbolic link.

    ``root`` itself must not be a link; folders above it are not checked.  Nested and
    repeated use is fine; the confinement holds for every thread of the process.
    """
    root = _abs(root)
    with _ROOTS_GUARD:
        _ROOTS[root] = _ROOTS.get(root, 0) + 1
    try:
        yield root
    finally:
        with _ROOTS_GUARD:
            _ROOTS[root] -= 1
            if not _ROOTS[root]:
                del _ROOTS[root]


@contextlib.contextmanager
def synced_together(root: str | os.PathLike) -> Iterator[Path]:
    """Within the block, files written by :func:`atomic_output` below ``root`` are synced to
    disk together when the block ends, instead of one by one as each is written.

    For a folder nobody reads until it is complete, e.g. a run's staging folder, which
    replaces the output folder only after this block (docs/outputs.md, section 1): every
    file and every folder it was renamed in are still synced before the block returns, but
    the files' syncs run at once (:data:`SYNC_THREADS` threads, whose requests the file
    system commits together) after the last write, not two in turn per file: 25 files took
    0.15-0.23 s of syncing one by one on the benchmarks' machine, one journal commit after
    the other, which a calibration's process waited for.  On an exception nothing is synced
    (the folder is to be thrown away).  On Windows each file is synced as it is written.

    Raises
    ------
    DatasetError
        A file could not be synced (a full disk, an I/O error), named with its path.
    """
    root = _abs(root)
    if os.name == "nt":         # pragma: no cover - fsync there needs a file open to write
        yield root              # each file synced as it is written, as elsewhere
        return
    with _ROOTS_GUARD:
        if root in _BATCHES:
            raise RuntimeError(f"{root}: already synced together by an enclosing block")
        _BATCHES[root] = []
    try:
        yield root
        with _ROOTS_GUARD:
            written = list(dict.fromkeys(_BATCHES[root]))
        _sync_all(written)
    finally:
        with _ROOTS_GUARD:
            _BATCHES.pop(root, None)


def _batch_of(folder: Path) -> list[Path] | None:
    """The list of :func:`synced_together` that files written in ``folder`` join, if any."""
    with _ROOTS_GUARD:
        return next((files for r, files in _BATCHES.items()
                     if r == folder or r in folder.parents), None)


def _sync_file(path: Path) -> None:
    try:        # read-only, never through a link, never waiting on a FIFO put there
        fd = os.open(path, os.O_RDONLY | _NOFOLLOW | getattr(os, "O_NONBLOCK", 0))
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except FileNotFoundError:   # removed again after it was written: nothing to sync
        return
    except OSError as exc:
        raise DatasetError(f"cannot write: {write_problem(exc)}", path=path) from exc


def _sync_all(paths: list[Path]) -> None:
    """Sync ``paths`` to disk, :data:`SYNC_THREADS` at a time, then the folders they are in
    (their new names; best effort, as :func:`atomic_output` does)."""
    if not paths:
        return
    from concurrent.futures import ThreadPoolExecutor  # noqa: PLC0415 (only where files are synced together)

    with ThreadPoolExecutor(min(SYNC_THREADS, len(paths)),
                            thread_name_prefix="multieye-sync") as pool:
        list(pool.map(_sync_file, paths))
    for folder in dict.fromkeys(p.parent for p in paths):
        with contextlib.suppress(OSError):
            fd = os.open(folder, os.O_RDONLY | _DIRECTORY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)


def _root_of(folder: Path) -> Path | None:
    with _ROOTS_GUARD:
        roots = list(_ROOTS)
    inside = [r for r in roots if r == folder or r in folder.parents]
    return min(inside, key=lambda r: len(r.parts)) if inside else None     # the outermost


def _link_error(path: Path) -> DatasetError:
    return DatasetError("is a symbolic link; multieye does not write or delete through links "
                        "in an output folder: remove the link", path=path)


def _open_folder(folder: Path) -> int:
    """A file descriptor of ``folder``; below a confined root, walked without following
    links (a link, or a file where a folder should be, is refused)."""
    root = _root_of(folder)
    flags = os.O_RDONLY | _DIRECTORY
    if root is None or not _DIR_FDS:
        if root is not None:                    # pragma: no cover - no dir_fd (Windows)
            for p in [folder, *folder.parents]:
                if (p == root or root in p.parents) and os.path.islink(p):
                    raise _link_error(p)
        try:
            return os.open(folder, flags)
        except OSError as exc:
            raise _walk_error(exc, folder) from exc
    here = root
    try:
        fd = os.open(root, flags | _NOFOLLOW)
    except OSError as exc:
        raise _walk_error(exc, root) from exc
    try:
        for part in folder.relative_to(root).parts:
            here = here / part
            try:
                nxt = os.open(part, flags | _NOFOLLOW, dir_fd=fd)
            except OSError as exc:
                raise _walk_error(exc, here, fd, part) from exc
            os.close(fd)
            fd = nxt
    except BaseException:
        os.close(fd)
        raise
    return fd


def _walk_error(exc: OSError, path: Path, fd: int | None = None,
                name: str | None = None) -> DatasetError:
    try:
        st = (os.stat(name, dir_fd=fd, follow_symlinks=False) if fd is not None
              else os.lstat(path))
    except OSError:
        st = None
    if st is not None and stat.S_ISLNK(st.st_mode):
        return _link_error(path)
    if exc.errno == errno.ENOENT:
        return DatasetError("cannot write: the output folder does not exist", path=path)
    if exc.errno == errno.ENOTDIR:
        return DatasetError("cannot write: expected a folder, found a file", path=path)
    return DatasetError(f"cannot write: {exc.strerror}", path=path)


def _lstat_in(fd: int, name: str, path: Path) -> os.stat_result | None:
    try:
        return (os.stat(name, dir_fd=fd, follow_symlinks=False) if _DIR_FDS
                else os.lstat(path))
    except FileNotFoundError:
        return None


def make_folder(path: str | os.PathLike) -> Path:
    """Create the folder ``path`` (its parent must exist), or accept it when it is already a
    folder; below a :func:`confined_to` root, a link (or a file) there is refused.

    Raises
    ------
    DatasetError
        One line naming the folder.
    """
    path = _abs(path)
    fd = _open_folder(path.parent)
    try:
        try:
            if _DIR_FDS:
                os.mkdir(path.name, dir_fd=fd)
            else:                               # pragma: no cover - Windows
                os.mkdir(path)
            return path
        except FileExistsError:
            pass
        except OSError as exc:
            raise DatasetError(f"cannot create the folder: {write_problem(exc)}",
                               path=path) from exc
        st = _lstat_in(fd, path.name, path)
        if st is not None and stat.S_ISLNK(st.st_mode):
            if _root_of(path.parent) is not None:
                raise _link_error(path)
            if os.path.isdir(path):             # outside output folders: the user's link
                return path
        if st is None or not stat.S_ISDIR(st.st_mode):
            raise DatasetError("cannot create the folder: a file has that name", path=path)
        return path
    finally:
        os.close(fd)


def remove_file(path: str | os.PathLike) -> bool:
    """Remove the regular file ``path``; False when there is none.  Never removes through a
    link: a link below a :func:`confined_to` root is refused, a folder is left alone.

    Raises
    ------
    DatasetError
        The file is a link inside a confined folder, or cannot be removed.
    """
    path = _abs(path)
    fd = _open_folder(path.parent)
    try:
        st = _lstat_in(fd, path.name, path)
        if st is None:
            return False
        if stat.S_ISLNK(st.st_mode) and _root_of(path.parent) is not None:
            raise _link_error(path)
        if stat.S_ISDIR(st.st_mode):
            return False
        try:
            if _DIR_FDS:
                os.unlink(path.name, dir_fd=fd)
            else:                               # pragma: no cover - Windows
                os.unlink(path)
        except FileNotFoundError:
            return False
        except OSError as exc:
            raise DatasetError(f"cannot remove: {exc.strerror}", path=path) from exc
        return True
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
        Text encoding (text mode only); newlines are written as ``\\n``; a character the
        encoding cannot hold (a name read with ``surrogateescape`` from bytes that are not
        UTF-8) is written as ``?``.

    Raises
    ------
    DatasetError
        The folder is missing or not writable, the write fails (a full disk, the file-size
        limit), or, below a :func:`confined_to` root, the destination or a folder on the way
        is a symbolic link; ``path`` is unchanged and no temporary file is left behind.
        Exceptions raised by the caller inside the block propagate unchanged, with the same
        clean-up.
    """
    dest = Path(path)
    full = _abs(dest)
    confined = _root_of(full.parent) is not None
    fd_dir = _open_folder(full.parent)
    batch = _batch_of(full.parent)              # synced later, with the others of its block
    tmp_name = f".{full.name}.{uuid.uuid4().hex}.tmp"
    tmp = full.parent / tmp_name

    def at(name: str):                          # path arguments relative to the folder
        return (name, {"dir_fd": fd_dir}) if _DIR_FDS else (full.parent / name, {})

    try:
        # O_EXCL: never clobber, never through a link; mode 0o666 so that the umask applies.
        name, kw = at(tmp_name)
        try:
            fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW
                         | getattr(os, "O_BINARY", 0), 0o666, **kw)
        except OSError as exc:
            raise DatasetError(f"cannot write: {write_problem(exc)}", path=dest) from exc
        try:
            mode = "wb" if binary else "w"
            kwargs = {} if binary else {"encoding": encoding, "newline": "\n",
                                        "errors": "replace"}
            with os.fdopen(fd, mode, **kwargs) as handle:
                yield handle
                handle.flush()
                if batch is None:
                    os.fsync(handle.fileno())
            if confined:
                st = _lstat_in(fd_dir, full.name, full)
                if st is not None and stat.S_ISLNK(st.st_mode):
                    raise _link_error(dest)
            if _DIR_FDS:
                os.replace(tmp_name, full.name, src_dir_fd=fd_dir, dst_dir_fd=fd_dir)
            else:                               # pragma: no cover - Windows
                os.replace(tmp, full)
        except BaseException as exc:
            with contextlib.suppress(OSError):
                name, kw = at(tmp_name)
                os.unlink(name, **kw)
            if isinstance(exc, OSError):
                raise DatasetError(f"cannot write: {write_problem(exc)}", path=dest) from exc
            raise
        if batch is not None:
            with _ROOTS_GUARD:
                batch.append(full)
        else:
            with contextlib.suppress(OSError):
                os.fsync(fd_dir)                # make the rename durable (best effort)
    finally:
        os.close(fd_dir)


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
