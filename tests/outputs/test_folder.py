"""The output folder as one set: staging beside OUT, the swap, refusals, the lock, recovery.

A run that fails at any point leaves OUT byte for byte as it was; a run that succeeds leaves
exactly its own files (and nothing beside OUT); what a killed run left is cleaned up by the
next one.
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from multieye.core.errors import DatasetError
from multieye.outputs import folder as folder_mod
from multieye.outputs import report_draw
from multieye.outputs import write as write_mod
from multieye.outputs.export import export
from multieye.outputs import report as report_mod
from multieye.outputs.report import write_report
from multieye.outputs.folder import MANIFEST, claim_output, foreign_files, staged_output
from multieye.outputs.write import write_outputs
from export_runs import make_run


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return make_run(tmp_path_factory.mktemp("run"), "eye-to-base")[0]


def tree(folder: Path) -> dict:
    """Every file and folder under ``folder`` with its bytes (files) and permission bits."""
    items = {}
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).as_posix()
        mode = stat.S_IMODE(p.lstat().st_mode)
        items[rel] = (mode, None if p.is_dir() else p.read_bytes())
    return items


def siblings(out: Path) -> list[str]:
    """What lies beside ``out`` apart from ``out`` itself."""
    return sorted(p.name for p in out.parent.iterdir() if p.name != out.name)


@pytest.fixture(scope="module")
def earlier_template(run, tmp_path_factory):
    out = tmp_path_factory.mktemp("earlier") / "out"
    write_outputs(run, out)
    export(out, "urdf")
    return out


@pytest.fixture
def earlier(earlier_template, tmp_path):
    """An output folder of an earlier run, with an export, alone in its parent."""
    out = tmp_path / "parent" / "out"
    shutil.copytree(earlier_template, out)
    return out


def _quick_report(folder, rec, details, figures, **kwargs):
    """Stands in for the report (whose figures take a second) where it is not the point."""
    assert figures() == ({}, ())
    (Path(folder) / "figures").mkdir()
    (Path(folder) / "figures" / "rig.png").write_bytes(b"png")
    (Path(folder) / "report.html").write_text("<html>")


def _quick(monkeypatch):
    """No figures drawn (no worker started) and :func:`_quick_report` for the report."""
    monkeypatch.setattr(report_draw, "submit_figures", lambda *a, **k: (lambda: ({}, ())))
    monkeypatch.setattr(write_mod, "write_report_from", _quick_report)


def test_a_run_writes_its_set_and_nothing_beside(run, tmp_path):
    out = tmp_path / "new" / "out"
    written = write_outputs(run, out)
    assert [p.name for p in written.paths] == ["calibration.json", "camchain.yaml",
                                               "details.json", "report.html", "figures"]
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["files"] == sorted(
        ["calibration.json", "camchain.yaml", "details.json", "report.html",
         "figures/rig_3d.png", "figures/rig_top.png", "figures/residual_histograms.png",
         "figures/residuals_over_time.png"])
    assert siblings(out) == []
    assert foreign_files(out) == []


def test_files_of_an_earlier_run_that_this_one_does_not_write_are_gone(run, earlier):
    (earlier / "figures" / "old_figure.png").write_bytes(b"x")    # listed in no manifest...
    with pytest.raises(DatasetError, match="figures/old_figure.png"):
        write_outputs(run, earlier)                                # ...so not multieye's
    (earlier / "figures" / "old_figure.png").unlink()
    assert (earlier / "export" / "cameras.urdf").exists()
    write_outputs(run, earlier, report=False)
    assert sorted(p.name for p in earlier.iterdir()) == [MANIFEST, "calibration.json",
                                                         "camchain.yaml", "details.json"]
    assert siblings(earlier) == []


def test_the_folder_keeps_its_permissions(run, earlier):
    os.chmod(earlier, 0o750)
    write_outputs(run, earlier, report=False)
    assert stat.S_IMODE(earlier.stat().st_mode) == 0o750


def _user_notes(out):
    (out / "notes.txt").write_text("mine")


def _file_named_figures(out):
    for p in (out / "figures").iterdir():
        p.unlink()
    (out / "figures").rmdir()
    (out / "figures").write_text("not a folder")


def _failing_report(monkeypatch):
    def broken(*args, **kwargs):
        raise DatasetError("the report failed")
    monkeypatch.setattr(write_mod, "write_report_from", broken)


def _failing_camchain(monkeypatch):
    def broken(path, entries, **kwargs):
        Path(path).write_text("half")
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(write_mod, "write_camchain", broken)


def _interrupted_details(monkeypatch):
    def broken(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(write_mod, "write_details_text", broken)


def _failing_manifest(monkeypatch):
    def broken(folder):
        raise OSError(5, "Input/output error")
    monkeypatch.setattr(folder_mod, "_write_manifest", broken)


def _failing_second_rename(monkeypatch):
    real = os.rename

    def rename(src, dst):
        if ".multieye-tmp-" in str(src):
            raise OSError(13, "Permission denied")
        return real(src, dst)
    monkeypatch.setattr(folder_mod.os, "rename", rename)


def _interrupted_in_the_second_rename(monkeypatch):
    real = os.rename

    def rename(src, dst):
        if ".multieye-tmp-" in str(src):
            raise KeyboardInterrupt
        return real(src, dst)
    monkeypatch.setattr(folder_mod.os, "rename", rename)


def _interrupted_just_after_the_first_rename(monkeypatch):
    real = os.rename

    def rename(src, dst):
        real(src, dst)
        if ".multieye-old-" in str(dst):
            raise KeyboardInterrupt         # a signal handled right after OUT was moved aside
    monkeypatch.setattr(folder_mod.os, "rename", rename)


@pytest.mark.parametrize("inject, error", [
    (_user_notes, DatasetError), (_file_named_figures, DatasetError),
    (_failing_report, DatasetError), (_failing_camchain, OSError),
    (_interrupted_details, KeyboardInterrupt), (_failing_manifest, DatasetError),
    (_failing_second_rename, DatasetError), (_interrupted_in_the_second_rename, KeyboardInterrupt),
    (_interrupted_just_after_the_first_rename, KeyboardInterrupt),
])
def test_a_failed_run_leaves_the_folder_exactly_as_it_was(run, earlier, monkeypatch, inject,
                                                           error):
    if inject is not _failing_report:
        _quick(monkeypatch)
    if inject in (_user_notes, _file_named_figures):
        inject(earlier)
    else:
        inject(monkeypatch)
    before = tree(earlier)
    with pytest.raises(error):
        write_outputs(run, earlier)
    assert tree(earlier) == before
    assert siblings(earlier) == []


def test_refusals_are_one_line_naming_the_folder(run, earlier, tmp_path, monkeypatch):
    _quick(monkeypatch)
    _file_named_figures(earlier)
    with pytest.raises(DatasetError) as info:
        write_outputs(run, earlier)
    text = str(info.value)
    assert text.startswith(f"{earlier}: holds files multieye did not write (figures)")
    assert "\n" not in text
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    with pytest.raises(DatasetError, match="exists and is not a folder"):
        write_outputs(run, a_file)
    assert a_file.read_text() == "x"


def test_an_input_inside_the_output_folder_is_refused(tmp_path):
    dataset = tmp_path / "out" / "dataset"
    dataset.mkdir(parents=True)
    with pytest.raises(DatasetError, match="is inside the output folder"):
        with claim_output(tmp_path / "out", inputs=[dataset]):
            pass
    with pytest.raises(DatasetError, match="is inside the output folder"):
        with claim_output(tmp_path / "out", inputs=[tmp_path / "out"]):
            pass


def test_file_managers_litter_and_old_staging_folders_inside_are_multieyes(run, earlier):
    (earlier / ".DS_Store").write_bytes(b"\0")
    (earlier / ".multieye-abc123").mkdir()          # the staging folder of older versions
    (earlier / ".multieye-abc123" / "calibration.json").write_text("{}")
    (earlier / f".report.html.{'0' * 32}.tmp").write_text("<html")   # an interrupted write
    assert foreign_files(earlier) == []
    write_outputs(run, earlier, report=False)
    assert not (earlier / ".DS_Store").exists()


def test_a_new_folder_and_its_parents_are_not_left_behind_by_a_failure(run, tmp_path,
                                                                        monkeypatch):
    _failing_report(monkeypatch)
    with pytest.raises(DatasetError):
        write_outputs(run, tmp_path / "a" / "b" / "out")
    assert list(tmp_path.iterdir()) == []


def test_a_later_run_puts_back_what_a_run_killed_between_the_renames_moved(run, earlier):
    before = tree(earlier)
    parent = earlier.parent
    dead = 2 ** 22 + 17                            # above the default pid_max: never alive
    old = parent / f"out.multieye-old-{dead}-0badf00d"
    os.rename(earlier, old)                        # killed after the first rename
    (parent / f"out.multieye-tmp-{dead}-0000beef").mkdir()
    (parent / f"out.multieye-tmp-{dead}-0000beef" / "calibration.json").write_text("{")
    (parent / "out.multieye-lock").write_text(f"{dead}\nmultieye calibrate x -o out\n")
    (parent / "out.multieye-tmp-notes").mkdir()     # not a name multieye gives: left alone
    with claim_output(earlier, replace=False) as out:
        assert out == earlier
        assert tree(earlier) == before
        assert siblings(earlier) == ["out.multieye-lock", "out.multieye-tmp-notes"]
    assert siblings(earlier) == ["out.multieye-tmp-notes"]
    (parent / "out.multieye-tmp-notes").rmdir()
    # killed after the second rename: the new set is in place, the old one is removed
    (parent / f"out.multieye-old-{dead}-0badf00d").mkdir()
    write_outputs(run, earlier, report=False)
    assert siblings(earlier) == []


def test_the_lock_is_reentrant_in_a_thread_and_refuses_other_threads(tmp_path):
    out = tmp_path / "out"
    errors = []

    def other():
        try:
            with claim_output(out):
                pass
        except DatasetError as exc:
            errors.append(str(exc))

    with claim_output(out):
        with claim_output(out):
            assert (tmp_path / "out.multieye-lock").read_text().startswith(f"{os.getpid()}\n")
        t = threading.Thread(target=other)
        t.start()
        t.join()
        assert (tmp_path / "out.multieye-lock").exists()
    assert not (tmp_path / "out.multieye-lock").exists()
    assert len(errors) == 1 and "in use by another multieye run" in errors[0]


def test_a_second_process_is_refused_while_the_first_holds_the_folder(tmp_path):
    out = tmp_path / "out"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from multieye.outputs.folder import "
         "claim_output\nwith claim_output(sys.argv[1]):\n print('held', flush=True)\n"
         " sys.stdin.read()", str(out)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        with pytest.raises(DatasetError) as info:
            with staged_output(out):
                pass
        assert str(info.value).startswith(f"{out}: in use by another multieye run "
                                          f"(process {holder.pid}: ")
        assert not out.exists()
    finally:
        holder.communicate("")
    with staged_output(out) as stage:               # free again once the holder ended
        (stage.folder / "calibration.json").write_text("{}")
    assert (out / "calibration.json").read_text() == "{}"
    assert siblings(out) == []


def _holding(out: Path) -> subprocess.Popen:
    """Another process holding ``out`` (as a running calibration does) until its stdin ends."""
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from multieye.outputs.folder import "
         "claim_output\nwith claim_output(sys.argv[1]):\n print('held', flush=True)\n"
         " sys.stdin.read()", str(out)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline() == "held\n"
    return holder


@pytest.mark.parametrize("write", ["export", "report"])
def test_export_and_report_are_refused_while_another_process_holds_the_folder(earlier, write,
                                                                               monkeypatch):
    """Issue 32: ``export`` (and ``write_report``) into a folder a calibration holds wrote
    files that the calibration's swap then removed; they take the folder's lock themselves."""
    _quick(monkeypatch)
    monkeypatch.setattr(report_mod, "write_report_from", _quick_report)
    shutil.rmtree(earlier / "export")
    shutil.rmtree(earlier / "figures")
    before = tree(earlier)
    holder = _holding(earlier)
    try:
        with pytest.raises(DatasetError) as info:
            export(earlier, "json") if write == "export" else write_report(earlier)
        assert str(info.value).startswith(f"{earlier}: in use by another multieye run "
                                          f"(process {holder.pid}: ")
        assert tree(earlier) == before
    finally:
        holder.communicate("")
    export(earlier, "json") if write == "export" else write_report(earlier)   # free again
    assert tree(earlier) != before and siblings(earlier) == []


def test_every_file_written_outside_the_set_has_a_known_name():
    from multieye.outputs.export import FORMATS
    from multieye.outputs.report import FIGURES

    fixed = {f"export/{name}" for name in FORMATS.values() if "<camera>" not in name}
    assert fixed <= folder_mod.KNOWN_FILES
    for name in FORMATS.values():       # one file per camera: known by its pattern
        if "<camera>" in name:
            assert folder_mod._KNOWN_PATTERN.fullmatch(
                "export/" + name.replace("<camera>", "front left"))
    assert {f"figures/{name}" for name in FIGURES} <= folder_mod.KNOWN_FILES


# --------------------------------------------------------------------------- issue 19


def test_the_lock_file_is_never_written_through_a_link(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("mine")
    lock = tmp_path / "out.multieye-lock"
    lock.symlink_to(victim)
    with pytest.raises(DatasetError, match="lock file is a symbolic link"):
        with claim_output(tmp_path / "out"):
            pass
    assert victim.read_text() == "mine" and lock.is_symlink()
    lock.unlink()
    os.link(victim, lock)                   # a hard link: the same file under another name
    with pytest.raises(DatasetError, match="hard links"):
        with claim_output(tmp_path / "out"):
            pass
    assert victim.read_text() == "mine"


def test_a_linked_output_folder_or_a_link_inside_it_is_refused(run, tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "out").symlink_to(real)
    with pytest.raises(DatasetError, match=r"out: is a symbolic link \(to .*real\)"):
        write_outputs(run, tmp_path / "out", report=False)
    assert list(real.iterdir()) == []
    out = tmp_path / "out2"
    write_outputs(run, out, report=False)
    before = tree(out)
    (out / "figures").symlink_to(real)
    for replace in (True, False):
        with pytest.raises(DatasetError, match="holds symbolic links \\(figures\\)"):
            with claim_output(out, replace=replace):
                pass
    assert list(real.iterdir()) == [] and not (tmp_path / "out2.multieye-lock").exists()
    (out / "figures").unlink()
    assert tree(out) == before


def test_folders_above_the_output_folder_may_be_links(run, tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "via").symlink_to(tmp_path / "real")
    written = write_outputs(run, tmp_path / "via" / "out", report=False)
    assert (tmp_path / "real" / "out" / "calibration.json").is_file()
    assert all(p.parent == tmp_path / "real" / "out" for p in written.paths)


def test_leftovers_that_are_links_are_neither_followed_nor_renamed(run, tmp_path):
    keep = tmp_path / "keep"
    keep.mkdir()
    (keep / "data.txt").write_text("mine")
    for kind in ("tmp", "old"):
        (tmp_path / f"out.multieye-{kind}-1-abcd").symlink_to(keep)
    write_outputs(run, tmp_path / "out", report=False)
    assert (keep / "data.txt").read_text() == "mine"
    assert (tmp_path / "out" / "calibration.json").is_file()
    assert all((tmp_path / f"out.multieye-{k}-1-abcd").is_symlink() for k in ("tmp", "old"))


def test_the_lock_is_released_when_writing_it_fails(tmp_path, monkeypatch):
    import errno

    def full(fd, data):
        raise OSError(errno.EFBIG, "File too large")

    monkeypatch.setattr(folder_mod.os, "write", full)
    with pytest.raises(DatasetError, match="out.multieye-lock: cannot write the lock file: "
                                           "File too large .*ulimit -f"):
        with claim_output(tmp_path / "out"):
            pass
    assert list(tmp_path.iterdir()) == [] and not folder_mod._HELD


def test_a_failed_write_in_the_staging_folder_names_the_file_in_out(run, tmp_path,
                                                                    monkeypatch):
    import errno

    from multieye.io import atomic

    real = atomic.os.fdopen
    calls = []

    def fdopen(fd, *args, **kwargs):
        calls.append(1)
        f = real(fd, *args, **kwargs)
        if len(calls) == 2:
            f.close()
            raise OSError(errno.ENOSPC, "No space left on device")
        return f

    monkeypatch.setattr(atomic.os, "fdopen", fdopen)
    with pytest.raises(DatasetError) as info:
        write_outputs(run, tmp_path / "out", report=False)
    assert info.value.path.startswith(str(tmp_path / "out") + os.sep), info.value.path
    assert "No space left on device (the disk is full)" in str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_the_output_folder_is_named_as_typed(tmp_path, monkeypatch):
    """Not resolved: ``-o out`` is ``out`` in the message, not the absolute folder."""
    (tmp_path / "runs" / "out").mkdir(parents=True)
    (tmp_path / "runs" / "out" / "notes.txt").write_text("mine")
    monkeypatch.chdir(tmp_path / "runs")
    with pytest.raises(DatasetError) as info:
        with claim_output("out"):
            pass
    assert str(info.value).startswith("out: holds files multieye did not write (notes.txt)")
    assert str(tmp_path) not in str(info.value)
    with pytest.raises(DatasetError) as info:
        with claim_output(Path("out") / "notes.txt" / "deeper"):
            pass
    assert str(info.value).startswith("out/notes.txt/deeper: cannot create the output folder")


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="paths of descriptors: Linux")
def test_every_file_is_on_disk_before_the_new_set_replaces_the_folder(run, tmp_path,
                                                                      monkeypatch):
    """docs/outputs.md, section 1, step 4: each file is synced to disk before the staging
    folder is renamed to OUT (the files all at once once written: io.atomic.synced_together)."""
    events = []
    real_fsync, real_rename = os.fsync, os.rename
    monkeypatch.setattr(os, "fsync", lambda fd: (
        events.append(("fsync", os.readlink(f"/proc/self/fd/{fd}"))), real_fsync(fd))[1])
    monkeypatch.setattr(folder_mod.os, "rename", lambda a, b: (
        events.append(("rename", os.fspath(b))), real_rename(a, b))[1])
    out = tmp_path / "out"
    write_outputs(run, out)
    swap = events.index(("rename", str(out)))
    # a file synced under its temporary name (.NAME.<hex>.tmp) before its rename counts
    synced = {tuple(re.sub(r"^\.(.+)\.[0-9a-f]{32}\.tmp$", r"\1", part) for part in
                    Path(p).relative_to(tmp_path).parts[1:])
              for kind, p in events[:swap] if kind == "fsync" and Path(p).parent != tmp_path}
    files = {p.relative_to(out).parts for p in out.rglob("*") if p.is_file()}
    assert len(files) >= 6 and files <= synced, files - synced


def test_a_folder_named_through_a_link_and_dot_dot_is_the_one_the_lock_guards(earlier, tmp_path):
    """``via/link/../out`` is ``out`` beside the link's target for the file system (the
    calibration read), but its letters (os.path.abspath) put the lock beside the link: an
    export through that name went on while a calibration held the folder."""
    (tmp_path / "elsewhere").mkdir()
    (earlier.parent / "inner").mkdir()
    (tmp_path / "elsewhere" / "link").symlink_to(earlier.parent / "inner")
    typed = tmp_path / "elsewhere" / "link" / ".." / earlier.name
    assert (typed / "calibration.json").is_file()
    shutil.rmtree(earlier / "export")
    before = tree(earlier)
    holder = _holding(earlier)
    try:
        with pytest.raises(DatasetError, match="in use by another multieye run"):
            export(typed, "json")
    finally:
        holder.communicate("")
    assert tree(earlier) == before and list((tmp_path / "elsewhere").iterdir()) == [
        tmp_path / "elsewhere" / "link"]
    export(typed, "json")                           # free again: written where it was read
    assert (earlier / "export" / "calibration.json").is_file()


def test_a_file_system_that_cannot_lock_is_not_another_run(tmp_path, monkeypatch):
    def no_locks(fd, flags):
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr(folder_mod.fcntl, "flock", no_locks)
    with pytest.raises(DatasetError, match="does not lock files") as info:
        with claim_output(tmp_path / "out"):
            pass
    assert "in use" not in str(info.value)
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.multieye-lock").exists()
