"""Atomic writes: all or nothing, no temporary file left behind."""

from __future__ import annotations

import os

import pytest

from multieye.core.errors import DatasetError
from multieye.io import atomic
from multieye.io.atomic import atomic_output, write_bytes_atomic, write_text_atomic


def test_text_and_bytes_written_completely(tmp_path):
    write_text_atomic(tmp_path / "a.txt", "héllo\nworld\n")
    write_bytes_atomic(tmp_path / "b.bin", bytes(range(256)))
    assert (tmp_path / "a.txt").read_text(encoding="utf-8") == "héllo\nworld\n"
    assert (tmp_path / "b.bin").read_bytes() == bytes(range(256))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.bin"]


def test_failure_inside_block_keeps_old_file_and_leaves_no_temp(tmp_path):
    dest = tmp_path / "calibration.json"
    dest.write_text("old")
    with pytest.raises(RuntimeError, match="solver exploded"):
        with atomic_output(dest) as out:
            out.write("half a result")
            raise RuntimeError("solver exploded")
    assert dest.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["calibration.json"]


def test_failure_without_old_file_leaves_nothing(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with atomic_output(tmp_path / "new.txt") as out:
            out.write("partial")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_failing_rename_is_a_dataset_error_and_cleans_up(tmp_path, monkeypatch):
    dest = tmp_path / "out.txt"
    dest.write_text("old")

    def broken_replace(src, dst, **kw):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(atomic.os, "replace", broken_replace)
    with pytest.raises(DatasetError, match="cannot write: Permission denied") as info:
        write_text_atomic(dest, "new")
    assert info.value.path == str(dest)
    assert dest.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_content_is_fsynced_before_the_rename(tmp_path, monkeypatch):
    events = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: (events.append("fsync"), real_fsync(fd)))
    monkeypatch.setattr(atomic.os, "replace",
                        lambda a, b, **kw: (events.append("replace"), real_replace(a, b, **kw)))
    write_text_atomic(tmp_path / "x.txt", "data")
    assert events.index("fsync") < events.index("replace")


def test_missing_folder_is_reported(tmp_path):
    with pytest.raises(DatasetError, match="output folder does not exist"):
        write_text_atomic(tmp_path / "nope" / "x.txt", "data")


def test_new_file_gets_normal_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        write_text_atomic(tmp_path / "x.txt", "data")
    finally:
        os.umask(old)
    assert (tmp_path / "x.txt").stat().st_mode & 0o777 == 0o644


def _recording_syncs(monkeypatch) -> list:
    """``os.fsync`` (every thread) and ``os.replace`` recorded in order, by path."""
    events = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: (
        events.append(("fsync", os.readlink(f"/proc/self/fd/{fd}"))), real_fsync(fd))[1])
    monkeypatch.setattr(atomic.os, "replace", lambda a, b, **kw: (
        events.append(("replace", os.fspath(b))), real_replace(a, b, **kw))[1])
    return events


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="paths of descriptors: Linux")
def test_files_synced_together_are_synced_once_all_are_written(tmp_path, monkeypatch):
    """Below a folder of ``synced_together`` no file is synced while the files are written
    (each sync waited for the disk, one after the other); every file and every folder they
    were renamed in is synced before the block returns."""
    events = _recording_syncs(monkeypatch)
    (tmp_path / "figures").mkdir()
    names = [tmp_path / "a.json", tmp_path / "figures" / "b.png", tmp_path / "c.yaml"]
    with atomic.synced_together(tmp_path):
        for p in names:
            write_text_atomic(p, f"data of {p.name}")
        assert [e for e in events if e[0] == "fsync"] == []
        assert [os.path.basename(e[1]) for e in events] == [p.name for p in names]  # renamed
    synced = [path for kind, path in events if kind == "fsync"]
    assert set(synced) >= {*map(str, names), str(tmp_path), str(tmp_path / "figures")}
    last_file = max(synced.index(str(p)) for p in names)
    assert synced.index(str(tmp_path / "figures")) > last_file      # folders after the files
    assert [p.read_text() for p in names] == [f"data of {p.name}" for p in names]
    # outside such a block (and once it has ended) each file is synced as it is written
    events.clear()
    write_text_atomic(tmp_path / "d.txt", "data")
    assert [e[0] for e in events] == ["fsync", "replace", "fsync"]


def test_nothing_is_synced_when_the_block_fails(tmp_path, monkeypatch):
    events = _recording_syncs(monkeypatch) if os.path.isdir("/proc/self/fd") else []
    with pytest.raises(RuntimeError, match="made to fail"):
        with atomic.synced_together(tmp_path):
            write_text_atomic(tmp_path / "a.json", "data")
            raise RuntimeError("made to fail")
    assert [e for e in events if e[0] == "fsync"] == []
    with atomic.synced_together(tmp_path):          # the folder may be held again
        with pytest.raises(RuntimeError, match="already synced together"):
            with atomic.synced_together(tmp_path):
                pass


def test_a_file_removed_after_it_was_written_is_not_synced_nor_an_error(tmp_path):
    with atomic.synced_together(tmp_path):
        write_text_atomic(tmp_path / "old.png", "data")
        atomic.remove_file(tmp_path / "old.png")
        write_text_atomic(tmp_path / "new.png", "data")
    assert [p.name for p in tmp_path.iterdir()] == ["new.png"]
