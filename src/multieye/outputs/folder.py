"""The output folder as one set: a lock, a staging folder beside it, a swap, and recovery.

A calibration replaces its output folder ``OUT`` as a whole (docs/outputs.md, section 1):

1. **Lock.** ``OUT.multieye-lock`` beside ``OUT`` holds the process id and command line of
   the run that holds ``OUT``, locked with ``flock`` (Windows: ``msvcrt.locking``); created
   with ``O_EXCL``, or, left by a run that ended, opened with ``O_NOFOLLOW`` and used only
   when it is a plain file with one name (never written through a link).  The
   kernel drops the lock when that process ends, however it ends, so a lock left by a
   killed run is simply taken over; a second run into a held folder stops with one line
   naming the folder and the holder.  The holder removes the file when it lets go.
2. **Recovery** (holding the lock, so nothing beside ``OUT`` belongs to a running process):
   ``OUT.multieye-tmp-<pid>-<hex>`` and ``OUT.multieye-old-<pid>-<hex>`` left by a killed
   run are removed, after the newest ``old`` folder is renamed back to ``OUT`` when ``OUT``
   is missing (a run killed between the two renames of step 5); a link of such a name is
   neither followed, removed nor renamed.
3. **Check**: ``OUT`` is not a symbolic link and holds none (the folders above it are
   resolved once, :func:`~multieye.outputs.folder_names.resolved_output`, and may be links); it is missing, an empty folder, or
   holds only files multieye writes
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
import errno
import json
import os
import re
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
from multieye.io.atomic import confined_to, write_problem
from multieye.outputs.folder_names import checked_output, lock_path, sibling

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
    "figures/rig.png", "figures/rig_3d.png", "figures/rig_top.png",
    "figures/residual_histograms.png", "figures/residuals_over_time.png",
    "figures/image_rms.png", "figures/residuals_by_radius.png",
    "export/camchain.yaml", "export/extrinsics.yaml", "export/cameras.urdf",
    "export/static_transforms.sh", "export/calibration.json",
})
_KNOWN_FOLDERS = frozenset({"figures", "export", "export/camera_info", "export/mrcal"})
#: Files multieye writes under names of the cameras: the report's per-camera figures and
#: drawn images (``multieye report`` on a folder whose manifest predates them writes them too),
#: and ``multieye export --format camera-info`` and ``mrcal``'s files, named after the cameras.
_KNOWN_PATTERN = re.compile(r"figures/camera_[A-Za-z0-9._-]+\.png"
                            r"|figures/image_[A-Za-z0-9._-]+_\d+\.jpg"
                            r"|export/camera_info/[^/]+\.yaml"
                            r"|export/mrcal/[^/]+\.cameramodel")
#: Left by file managers, anywhere: never a reason to refuse a folder.
_DISPOSABLE = frozenset({".DS_Store", "Thumbs.db", "desktop.ini"})
#: The temporary file of an interrupted atomic write (multieye.io.atomic).
_ATOMIC_TMP = re.compile(r"\..+\.[0-9a-f]{32}\.tmp")

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_WINDOWS_LOCK_OFFSET = 1 << 30      # msvcrt locks bytes: lock one far beyond the text


# --------------------------------------------------------------------------- names


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
        if m and entry.is_dir(follow_symlinks=False):       # never a link of that name
            (tmp if m.group(1) == "tmp" else old).append(Path(entry.path))
    return tmp, old


def _remove(path: Path) -> None:
    if not path.is_symlink() and path.is_dir():
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


def _try_lock(fd: int, path: Path) -> bool:
    """Lock ``fd`` without waiting; False when another process holds it; DatasetError when
    the file system cannot lock (``ENOLCK``: some network file systems), not another run."""
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        else:                                            # pragma: no cover - Windows
            import msvcrt  # noqa: PLC0415 (Windows only)

            os.lseek(fd, _WINDOWS_LOCK_OFFSET, os.SEEK_SET)
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except OSError as exc:
        if fcntl is None or exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            return False
        if _same_file(fd, path) and not os.fstat(fd).st_size:     # ours, just created
            os.unlink(path)
        os.close(fd)
        raise DatasetError(f"cannot lock the lock file ({exc.strerror}): the file system of "
                           "the output folder does not lock files; choose an output folder "
                           "on a local disk", path=path) from exc
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
    path = lock_path(out)
    for _ in range(20):
        fd = _open_lock(path)
        if fd is None:
            continue                # removed between our two opens: try again
        if not _try_lock(fd, path):
            os.close(fd)
            raise _busy(out, _holder(path))
        if _same_file(fd, path):    # a holder that ended may have removed it: retry
            break
        os.close(fd)
    else:                                                # pragma: no cover - a storm
        raise _busy(out, "processes taking and releasing it")
    command = " ".join(["multieye", *sys.argv[1:]] if sys.argv and
                       Path(sys.argv[0]).stem in ("multieye", "__main__") else sys.argv)
    try:
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        # "replace": a path given as bytes that are not UTF-8 (surrogateescape) shows as '?'
        os.write(fd, f"{os.getpid()}\n{' '.join(command.split())}\n".encode("utf-8",
                                                                             "replace"))
    except BaseException as exc:        # the file-size limit, a full disk, Ctrl-C: let go
        _drop_lock(fd, path)
        if isinstance(exc, OSError):
            raise DatasetError(f"cannot write the lock file: {write_problem(exc)}",
                               path=path) from exc
        raise
    with _HELD_GUARD:
        _HELD[out] = _Held(fd, path, threading.get_ident())
    return True


def _open_lock(path: Path) -> int | None:
    """Open the lock file: created exclusively, or an existing one (left by a run that
    ended) opened without following a link; None when it went away between the two.

    Raises
    ------
    DatasetError
        The name is a link, a folder, a device or a file with several names (hard links):
        multieye writes its process id only into a file of its own.
    """
    flags = os.O_RDWR | _NOFOLLOW | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags | os.O_CREAT | os.O_EXCL, 0o666)
    except FileExistsError:
        try:
            fd = os.open(path, flags)
        except FileNotFoundError:
            return None
        except OSError as exc:
            if os.path.islink(path):
                raise DatasetError("the lock file is a symbolic link; multieye does not write "
                                   "through links: remove it", path=path) from exc
            raise DatasetError(f"cannot open the lock file: {exc.strerror}", path=path) from exc
    except OSError as exc:
        raise DatasetError(f"cannot create the lock file beside the output folder: "
                           f"{write_problem(exc)}", path=path) from exc
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_nlink != 1:
        os.close(fd)
        what = "has other names (hard links)" if stat.S_ISREG(st.st_mode) else "is not a file"
        raise DatasetError(f"the lock file {what}; multieye writes its process id only into a "
                           "file of its own: remove it", path=path)
    return fd


def _same_file(fd: int, path: Path) -> bool:
    try:
        return os.path.samestat(os.fstat(fd), os.lstat(path))
    except OSError:
        return False


def _drop_lock(fd: int, path: Path) -> None:
    """Remove the lock file (when it is still ours) while locked, then close it."""
    if _same_file(fd, path):
        try:
            os.unlink(path)         # while still locked: nobody takes a file about to go
        except OSError:
            os.close(fd)            # Windows cannot remove an open file
            if _same_file_path(path):
                with contextlib.suppress(OSError):
                    os.unlink(path)
            return
    os.close(fd)


def _same_file_path(path: Path) -> bool:       # pragma: no cover - Windows
    return os.path.isfile(path) and not os.path.islink(path)


def _release(out: Path) -> None:
    with _HELD_GUARD:
        held = _HELD[out]
        held.count -= 1
        if held.count:
            return
        del _HELD[out]
    _drop_lock(held.fd, held.path)


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


def _links_inside(out: Path) -> list[str]:
    """Symbolic links in ``out`` (relative, sorted), not followed."""
    links = []
    for root, dirs, files in os.walk(out):
        for name in dirs + files:
            if os.path.islink(os.path.join(root, name)):
                links.append(Path(root, name).relative_to(out).as_posix())
    return sorted(links)


def _check_real_folder(out: Path) -> None:
    """``out`` is missing or a real folder with no symbolic link in it (one line if not)."""
    if os.path.islink(out):
        raise DatasetError(f"is a symbolic link (to {os.readlink(out)}); multieye writes only "
                           "into a real folder: name the folder itself", path=out)
    if not os.path.lexists(out):
        return
    if not out.is_dir():
        raise DatasetError("exists and is not a folder", path=out)
    links = _links_inside(out)
    if links:
        shown = ", ".join(links[:3]) + (f" and {len(links) - 3} more" if len(links) > 3
                                        else "")
        raise DatasetError(f"holds symbolic links ({shown}); multieye does not write or "
                           "delete through links in an output folder: remove them", path=out)


def _check_replaceable(out: Path, inputs: Iterable) -> None:
    for item in inputs:
        p = Path(item).expanduser().resolve()
        if p.exists() and (p == out or out in p.parents):
            raise DatasetError(f"the input {p} is inside the output folder, which a "
                               "calibration replaces as a whole: choose another output folder",
                               path=out)
    _check_real_folder(out)
    if not os.path.lexists(out):
        return
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
        newest = max(old, key=lambda p: p.lstat().st_mtime_ns)
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
        The output folder, absolute, the folders above it resolved (``OUT`` itself is never
        a link: refused).

    Raises
    ------
    DatasetError
        Another run holds the folder, the folder or the lock file is a link (or holds one),
        or it cannot be replaced (one line saying why); its path or a name beside or inside
        it would be too long (:func:`~multieye.outputs.folder_names.output_path_problem`,
        before anything is written).
    """
    out = checked_output(out_dir, staged=replace)     # before anything is written or run
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
            else:
                _check_real_folder(out)
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
    fd = os.open(folder / MANIFEST, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o666)
    with open(fd, "w", encoding="utf-8", newline="\n") as f:
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
        if os.path.lexists(backup):     # a fresh random name: never over something there
            raise FileExistsError(errno.EEXIST, "the backup name is taken", str(backup))
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
        folder, backup = sibling(out, "tmp"), sibling(out, "old")
        try:
            folder.mkdir()
        except OSError as exc:
            raise DatasetError(f"cannot write beside the output folder: "
                               f"{write_problem(exc)}", path=folder) from exc
        swapped = False
        try:
            try:
                with confined_to(folder):
                    yield Stage(folder=folder, out=out)
            except DatasetError as exc:         # name the file where it was to end up
                if exc.path is None or not Path(exc.path).is_relative_to(folder):
                    raise
                final = out / Path(exc.path).relative_to(folder)
                raise DatasetError(exc.reason, path=final, line=exc.line,
                                   camera=exc.camera) from exc
            _check_replaceable(out, inputs)     # again: files may have appeared meanwhile
            try:
                _swap(folder, out, backup)
            except OSError as exc:
                raise DatasetError(f"cannot replace the output folder: {write_problem(exc)}",
                                   path=out) from exc
            swapped = True
        finally:
            if not swapped and os.path.lexists(backup) and not os.path.lexists(out):
                with contextlib.suppress(OSError):
                    os.rename(backup, out)      # interrupted between the two renames
            _remove(folder)
            if swapped:
                _remove(backup)                 # else a later run removes it (step 2)
