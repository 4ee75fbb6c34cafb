"""The output folder as one set: a lock, a staging folder beside it, a swap, and recovery.

A calibration replaces its output folder ``OUT`` as a whole (docs/outputs.md, section 1):

1. **Lock.** ``OUT.multieye-lock`` beside ``OUT`` holds the process id and command line of
   the run that holds ``OUT``, locked with ``flock`` (Windows: ``msvcrt.locking``).  The
   kernel drops the lock when that process ends, however it ends, so a lock left by a
   killed run is simply taken over; a second run into a held folder stops with one line
   naming the folder and the holder.  The holder removes the file when it lets go.
2. **Recovery** (holding the lock, so nothing beside ``OUT`` belongs to a running process):
   ``OUT.multieye-tmp-<pid>-<hex>`` and ``OUT.multieye-old-<pid>-<hex>`` left by a killed
   run are removed, after the newest ``old`` folder is renamed back to ``OUT`` when ``OUT``
   is missing (a run killed between the two renames of step 5).
3. **Check**: ``OUT`` is missing, an empty folder, or holds only files multieye writes
   (those listed in its ``.multieye-manifest.json`` and the fixed names of section 1 of
   docs/outputs.md); anything else (a user's notes, a dataset, a file named ``figures``)
   stops the run with one line, before any work, and again just before the swap.
4. **Staging**: every file of the run is written into ``OUT.multieye-tmp-<pid>-<hex>``
   (same parent, so the same file system), then ``.multieye-manifest.json`` listing them.
5. **Swap**: rename ``OUT`` to ``OUT.multieye-old-<pid>-<hex>``, rename the staging folder
   to ``OUT``, sync the parent folder, remove the old folder.

Interrupted at any point, ``OUT`` is either the complete old set or the complete new one:
before the first rename it is untouched (the staging folder is removed on the way out, or by
the next run); between the renames ``OUT`` is missing and the old set waits beside it, put
back by the ``finally`` of this process or by the next run; after the second rename the new
set is in place and only the old folder is left to remove.

Synopsis
--------
>>> from multieye.outputs.folder import claim_output, staged_output
>>> with claim_output("out", inputs=["dataset"]):          # doctest: +SKIP
...     run = calibrate("dataset")                         # long work, holding "out"
...     with staged_output("out") as stage:                # doctest: +SKIP
...         (stage.folder / "calibration.json").write_text("{}")
>>> # here "out" is the new set, or unchanged if the block raised
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import shutil
import stat
import sys
import threading
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from multieye.core.errors import DatasetError
from multieye.core.version import __version__

try:
    import fcntl
except ImportError:             # Windows
    fcntl = None

__all__ = ["MANIFEST", "KNOWN_FILES", "Stage", "claim_output", "staged_output",
           "foreign_files"]

#: The list of files a run wrote, inside ``OUT``.
MANIFEST = ".multieye-manifest.json"

#: Files multieye writes under fixed names (docs/outputs.md, section 1), relative to ``OUT``.
KNOWN_FILES = frozenset({
    "calibration.json", "camchain.yaml", "details.json", "report.html",
    "figures/rig.png", "figures/residual_histograms.png", "figures/residuals_over_time.png",
    "export/camchain.yaml", "export/extrinsics.yaml", "export/cameras.urdf",
    "export/static_transforms.sh", "export/calibration.json",
})
_KNOWN_FOLDERS = frozenset({"figures", "export", "export/camera_info"})
#: Files multieye writes under names of the cameras: the report's per-camera figures
#: (``multieye report`` on a folder whose manifest predates them writes them too).
#: and ``multieye export --format camera-info``'s files, named after the cameras.
_KNOWN_PATTERN = re.compile(r"figures/camera_[A-Za-z0-9._-]+\.png|export/camera_info/[^/]+\.yaml")
#: Left by file managers, anywhere: never a reason to refuse a folder.
_DISPOSABLE = frozenset({".DS_Store", "Thumbs.db", "desktop.ini"})
#: The temporary file of an interrupted atomic write (multieye.io.atomic).
_ATOMIC_TMP = re.compile(r"\..+\.[0-9a-f]{32}\.tmp")

_WINDOWS_LOCK_OFFSET = 1 << 30      # msvcrt locks bytes: lock one far beyond the text


# --------------------------------------------------------------------------- names


def _resolve(out: str | os.PathLike) -> Path:
    path = Path(out).expanduser().resolve()
    if path.parent == path:
        raise DatasetError("cannot use the root of a file system as the output folder",
                           path=path)
    return path


def _as_typed(exc: DatasetError, out: Path, typed: str | os.PathLike) -> DatasetError:
    """``exc`` with a path inside the resolved output folder ``out`` named from ``typed``,
    the folder as the user gave it."""
    if exc.path is None:
        return exc
    try:
        inside = Path(exc.path).relative_to(out)
    except ValueError:
        return exc
    shown = Path(typed) if inside == Path(".") else Path(typed) / inside
    return DatasetError(exc.reason, path=shown, line=exc.line, camera=exc.camera)


def _lock_path(out: Path) -> Path:
    return out.parent / f"{out.name}.multieye-lock"


def _sibling(out: Path, kind: str) -> Path:
    return out.parent / f"{out.name}.multieye-{kind}-{os.getpid()}-{secrets.token_hex(4)}"


def _leftovers(out: Path) -> tuple[list[Path], list[Path]]:
    """Staging (``tmp``) and backup (``old``) folders beside ``out``."""
    pattern = re.compile(re.escape(out.name) + r"\.multieye-(tmp|old)-\d+-[0-9a-f]+")
    tmp, old = [], []
    try:
        entries = list(os.scandir(out.parent))
    except OSError:
        return tmp, old
    for entry in entries:
        m = pattern.fullmatch(entry.name)
        if m:
            (tmp if m.group(1) == "tmp" else old).append(Path(entry.path))
    return tmp, old


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink()


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


# --------------------------------------------------------------------------- lock


@dataclass
class _Held:
    fd: int
    path: Path
    thread: int
    count: int = 1


_HELD: dict[Path, _Held] = {}
_HELD_GUARD = threading.Lock()


def _try_lock(fd: int) -> bool:
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        else:                                            # pragma: no cover - Windows
            import msvcrt

            os.lseek(fd, _WINDOWS_LOCK_OFFSET, os.SEEK_SET)
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except OSError:
        return False
    return True


def _holder(path: Path) -> str:
    """Who holds the lock file, for a message: ``process <pid>: <command>``."""
    for _ in range(10):             # the holder writes its pid just after taking the lock
        try:
            text = path.read_text(encoding="utf-8", errors="replace").strip()
        except OSError:
            text = ""
        if text:
            pid, _, command = text.partition("\n")
            return f"process {pid.strip()}" + (f": {command.strip()}" if command.strip() else "")
        time.sleep(0.02)
    return "another process"


def _busy(out: Path, who: str) -> DatasetError:
    return DatasetError(f"in use by another multieye run ({who}); wait for it to end or "
                        "choose another output folder", path=out)


def _acquire(out: Path) -> bool:
    """Take the lock of ``out`` for this thread; False when this thread held it already."""
    with _HELD_GUARD:
        held = _HELD.get(out)
        if held is not None:
            if held.thread != threading.get_ident():
                raise _busy(out, f"process {os.getpid()}, this one, in another thread")
            held.count += 1
            return False
    path = _lock_path(out)
    for _ in range(20):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise DatasetError(f"cannot create the lock file beside the output folder: "
                               f"{exc.strerror}", path=path) from exc
        if not _try_lock(fd):
            os.close(fd)
            raise _busy(out, _holder(path))
        try:            # a holder that ended may have removed the file we opened: retry
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except OSError:
            same = False
        if same:
            break
        os.close(fd)
    else:                                                # pragma: no cover - a storm
        raise _busy(out, "processes taking and releasing it")
    command = " ".join(["multieye", *sys.argv[1:]] if sys.argv and
                       Path(sys.argv[0]).stem in ("multieye", "__main__") else sys.argv)
    os.ftruncate(fd, 0)
    os.lseek(fd, 0, os.SEEK_SET)
    os.write(fd, f"{os.getpid()}\n{' '.join(command.split())}\n".encode())
    with _HELD_GUARD:
        _HELD[out] = _Held(fd, path, threading.get_ident())
    return True


def _release(out: Path) -> None:
    with _HELD_GUARD:
        held = _HELD[out]
        held.count -= 1
        if held.count:
            return
        del _HELD[out]
    try:
        os.unlink(held.path)        # while still locked: nobody takes a file about to go
    except OSError:
        os.close(held.fd)           # Windows cannot remove an open file
        with contextlib.suppress(OSError):
            os.unlink(held.path)
    else:
        os.close(held.fd)


# --------------------------------------------------------------------------- checks


def _manifest_files(out: Path) -> set[str]:
    try:
        data = json.loads((out / MANIFEST).read_text(encoding="utf-8"))
        return {str(f) for f in data["files"]}
    except (OSError, ValueError, KeyError, TypeError):
        return set()


def foreign_files(out: str | os.PathLike) -> list[str]:
    """Files and folders in ``out`` that multieye did not write, relative, sorted.

    Written by multieye: the manifest, the files it lists, the fixed names of
    :data:`KNOWN_FILES` and the folders holding them, the report's per-camera figures
    (``figures/camera_<name>.png``), ``.multieye-*`` staging folders an
    earlier version left inside ``OUT`` and the temporary files of interrupted atomic writes.
    File managers' litter (``.DS_Store``, ``Thumbs.db``, ``desktop.ini``) is not counted.
    Symbolic links are judged by their own name, never followed.
    """
    out = Path(out)
    known = KNOWN_FILES | _manifest_files(out) | {MANIFEST}
    folders = set(_KNOWN_FOLDERS)
    for name in known:
        parts = name.split("/")[:-1]
        folders.update("/".join(parts[:k]) for k in range(1, len(parts) + 1))
    foreign = []
    for root, dirs, files in os.walk(out):
        rel = Path(root).relative_to(out).as_posix()
        prefix = "" if rel == "." else rel + "/"
        if not prefix:
            dirs[:] = [d for d in dirs if not d.startswith(".multieye-")]
        for d in list(dirs):
            if os.path.islink(os.path.join(root, d)):
                dirs.remove(d)          # a link to a folder: not followed, judged as a file
                files.append(d)
            elif prefix + d not in folders:
                dirs.remove(d)
                foreign.append(prefix + d + "/")
        foreign += [prefix + f for f in files if prefix + f not in known
                    and not _KNOWN_PATTERN.fullmatch(prefix + f)
                    and f not in _DISPOSABLE and not _ATOMIC_TMP.fullmatch(f)]
    return sorted(foreign)


def _check_replaceable(out: Path, inputs: Iterable) -> None:
    for item in inputs:
        p = Path(item).expanduser().resolve()
        if p.exists() and (p == out or out in p.parents):
            raise DatasetError(f"the input {p} is inside the output folder, which a "
                               "calibration replaces as a whole: choose another output folder",
                               path=out)
    if not os.path.lexists(out):
        return
    if not out.is_dir():
        raise DatasetError("exists and is not a folder", path=out)
    if os.path.ismount(out):
        raise DatasetError("is a mount point, which cannot be replaced as a whole: use a "
                           "folder inside it", path=out)
    foreign = foreign_files(out)
    if foreign:
        shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3
                                          else "")
        raise DatasetError(f"holds files multieye did not write ({shown}); a calibration "
                           "replaces the whole folder: move them away or choose another "
                           "output folder", path=out)


def _recover(out: Path) -> None:
    """Put back an old set a killed run left beside ``out``, remove the rest (lock held)."""
    tmp, old = _leftovers(out)
    if old and not os.path.lexists(out):
        newest = max(old, key=lambda p: p.stat().st_mtime_ns)
        os.rename(newest, out)
        old.remove(newest)
    for p in tmp + old:
        _remove(p)


# --------------------------------------------------------------------------- API


@contextlib.contextmanager
def claim_output(out_dir: str | os.PathLike, *, inputs: Iterable = (),
                 replace: bool = True) -> Iterator[Path]:
    """Hold the output folder for the duration of the block (re-entrant in one thread).

    Takes the lock (step 1 of the module docstring), removes what killed runs left (step 2)
    and, with ``replace=True``, checks that the folder may be replaced as a whole (step 3).
    The parent folder is created when missing, and removed again if it is still empty when
    the block ends.

    Parameters
    ----------
    out_dir : path-like
    inputs : iterable of path-like
        Inputs of the run (the dataset); none may lie inside the output folder.
    replace : bool
        False for commands that write into the folder without replacing it (``report``,
        ``export``): lock and recovery only.

    Yields
    ------
    Path
        The output folder, absolute, symbolic links resolved.

    Raises
    ------
    DatasetError
        Another run holds the folder, or it cannot be replaced (one line saying why).
    """
    out = _resolve(out_dir)
    created = []
    parent = out.parent
    while not parent.exists():
        created.append(parent)
        parent = parent.parent
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(f"cannot create the output folder: {exc.strerror}",
                           path=out_dir) from exc
    outermost = None
    try:
        try:
            outermost = _acquire(out)
            if outermost:
                _recover(out)
            if replace:
                _check_replaceable(out, inputs)
        except DatasetError as exc:         # the folder named as the user typed it
            raise _as_typed(exc, out, out_dir) from None
        yield out
    finally:
        if outermost is not None:
            _release(out)
        for folder in created:          # innermost first
            with contextlib.suppress(OSError):
                folder.rmdir()


@dataclass(frozen=True)
class Stage:
    """Where a run writes its files (``folder``) and where they end up (``out``)."""

    folder: Path
    out: Path


def _write_manifest(folder: Path) -> None:
    files = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                   if not p.is_dir() and p.name != MANIFEST)
    text = json.dumps({"written_by": f"multieye {__version__}", "files": files}, indent=1)
    with open(folder / MANIFEST, "w", encoding="utf-8", newline="\n") as f:
        f.write(text + "\n")
        f.flush()
        os.fsync(f.fileno())


def _swap(stage: Path, out: Path, backup: Path) -> None:
    """Steps 5 of the module docstring; on an error before the new set is in place, the old
    one is put back (the caller's ``finally`` does the same for interruptions)."""
    _write_manifest(stage)
    _fsync_folder(stage)
    if os.path.lexists(out):
        with contextlib.suppress(OSError):
            os.chmod(stage, stat.S_IMODE(os.stat(out).st_mode))
        os.rename(out, backup)
        try:
            os.rename(stage, out)
        except BaseException:
            os.rename(backup, out)
            raise
    else:
        os.rename(stage, out)
    _fsync_folder(out.parent)


@contextlib.contextmanager
def staged_output(out_dir: str | os.PathLike, *, inputs: Iterable = ()) -> Iterator[Stage]:
    """Write a run's files into a staging folder; swap it in as ``out_dir`` on success.

    The block writes into ``stage.folder``.  When it ends normally, the folder gets its
    manifest and replaces ``out_dir`` as a whole; when it raises, ``out_dir`` is left exactly
    as it was and the staging folder is removed.  Holds the output folder
    (:func:`claim_output`) for the duration.

    Raises
    ------
    DatasetError
        As :func:`claim_output`; or the swap failed (``out_dir`` unchanged).
    """
    with claim_output(out_dir, inputs=inputs) as out:
        folder, backup = _sibling(out, "tmp"), _sibling(out, "old")
        try:
            folder.mkdir()
        except OSError as exc:
            raise DatasetError(f"cannot write beside the output folder: {exc.strerror}",
                               path=folder) from exc
        swapped = False
        try:
            yield Stage(folder=folder, out=out)
            _check_replaceable(out, inputs)     # again: files may have appeared meanwhile
            try:
                _swap(folder, out, backup)
            except OSError as exc:
                raise DatasetError(f"cannot replace the output folder: {exc.strerror or exc}",
                                   path=out) from exc
            swapped = True
        finally:
            if not swapped and os.path.lexists(backup) and not os.path.lexists(out):
                with contextlib.suppress(OSError):
                    os.rename(backup, out)      # interrupted between the two renames
            _remove(folder)
            if swapped:
                _remove(backup)                 # else a later run removes it (step 2)
