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
