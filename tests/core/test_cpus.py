"""The processors a run may use, and whether a core is free for the figure workers: from the
tasks ready to run now, not the one-minute load average that multieye's own detection
raised."""

from __future__ import annotations

import os

import pytest

from multieye.core import cpus
from multieye.outputs import figure_workers


def _stat(tmp_path, *counts):
    """Fake /proc/stat files, one per reading: the nth call reads the nth count."""
    paths = []
    for k, n in enumerate(counts):
        p = tmp_path / f"stat{k}"
        p.write_text(f"cpu  1 2 3 4\nctxt 99\nprocs_running {n}\nprocs_blocked 0\n")
        paths.append(p)
    return paths


def test_runnable_elsewhere_is_the_median_less_the_caller(tmp_path, monkeypatch):
    monkeypatch.setattr(cpus, "available_cores", lambda: 2)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    p = _stat(tmp_path, 3)[0]
    assert cpus.runnable_elsewhere(samples=3, pause_s=0.0, stat=str(p)) == 2.0
    p = _stat(tmp_path, 1)[0]
    assert cpus.runnable_elsewhere(samples=1, stat=str(p)) == 0.0
    # a container pinned to 2 of a host's 8 processors: a quarter of the host's count
    monkeypatch.setattr(os, "cpu_count", lambda: 8)
    p = _stat(tmp_path, 9)[0]
    assert cpus.runnable_elsewhere(samples=1, stat=str(p)) == 2.0


def test_runnable_elsewhere_takes_the_median_of_its_readings(tmp_path, monkeypatch):
    monkeypatch.setattr(cpus, "available_cores", lambda: 2)
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    paths = iter(_stat(tmp_path, 1, 7, 1, 2, 1))
    real_open = open

    def reading(path, mode="r", *a, **k):
        return real_open(next(paths), mode, *a, **k) if path == "fake" else real_open(path, mode,
                                                                                         *a, **k)

    monkeypatch.setattr("builtins.open", reading)
    assert cpus.runnable_elsewhere(samples=5, pause_s=0.0, stat="fake") == 0.0   # one spike


def test_runnable_elsewhere_is_none_without_the_count(tmp_path):
    assert cpus.runnable_elsewhere(stat=str(tmp_path / "missing")) is None
    p = tmp_path / "stat"
    p.write_text("cpu  1 2 3 4\n")
    assert cpus.runnable_elsewhere(samples=1, stat=str(p)) is None


@pytest.mark.parametrize(("others", "load", "free"), [
    (0.0, 1.9, True),       # the load average of the detection just done does not count
    (1.0, 0.2, False),      # another task ready to run: this process draws
    (None, 1.5, True),      # no count: the load average decides
    (None, 2.5, False),
])
def test_free_core_counts_the_tasks_ready_now(monkeypatch, others, load, free):
    monkeypatch.setattr(figure_workers, "available_cores", lambda: 2)
    monkeypatch.setattr(figure_workers, "runnable_elsewhere", lambda: others)
    monkeypatch.setattr(os, "getloadavg", lambda: (load, load, load))
    assert figure_workers._free_core() is free


def test_the_median_is_statistics_median():
    import statistics

    from multieye.core.cpus import _median

    for values in ([3], [5, 1], [4, 1, 3], [2, 2, 7, 1], [9, 0, 4, 4, 1], [1, 2, 3, 4, 5, 6]):
        assert _median(values) == statistics.median(values)
        assert type(_median(values)) is type(statistics.median(values))
