"""`multieye calibrate` stopped during detection: no orphans, no leftovers, one run per folder.

The runs are real processes.  Detection is slowed down by a ``sitecustomize`` module on
``PYTHONPATH`` (written here, nothing in the package) that makes ``cv2.imread`` and
``cv2.imdecode`` (image files are read as bytes, then decoded) sleep, so
every run is in detection, with its worker processes, for a few seconds.  The run is started
in its own process group; its workers are found in /proc by that group.
"""

from __future__ import annotations

import os
import signal
import stat
import re
import subprocess
import sys

import pytest
from proc_tree import group_members, group_processes, needs_proc, wait_until
from small_dataset import render_small

pytestmark = needs_proc

SLOW_IMREAD = """
import os
_delay = float(os.environ.get("MULTIEYE_TEST_IMREAD_DELAY_S") or 0)
if _delay > 0:
    import time
    import cv2

    def _slowed(read):
        def slow(*args, **kwargs):
            time.sleep(_delay)
            return read(*args, **kwargs)
        return slow

    cv2.imread = _slowed(cv2.imread)
    cv2.imdecode = _slowed(cv2.imdecode)
"""


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ds") / "ds"
    render_small(folder, images_per_camera=12)
    return folder


@pytest.fixture(scope="module")
def slow_env(tmp_path_factory):
    hook = tmp_path_factory.mktemp("hook")
    (hook / "sitecustomize.py").write_text(SLOW_IMREAD)
    path = os.pathsep.join(filter(None, [str(hook), os.environ.get("PYTHONPATH")]))
    return dict(os.environ, PYTHONPATH=path, MULTIEYE_TEST_IMREAD_DELAY_S="0.4")


def _calibrate(ds, out, env=None, **kw):
    return subprocess.Popen([sys.executable, "-m", "multieye", "calibrate", str(ds), "-o",
                             str(out), "--processes", "2"], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def _in_detection(ds, out, env):
    """A slowed run, in its own process group, once its detection workers run."""
    proc = _calibrate(ds, out, env, start_new_session=True)

    def workers_started():     # a grandchild: a worker forked by the fork server
        members = group_members(proc.pid)
        return any(parent != proc.pid and parent in members for parent in members.values())

    if wait_until(workers_started, timeout=60.0) is None:
        proc.kill()
        pytest.fail("the run never reached detection: " + proc.communicate()[1])
    return proc


def _tree(folder):
    return {p.relative_to(folder).as_posix(): (stat.S_IMODE(p.stat().st_mode),
                                               None if p.is_dir() else p.read_bytes())
            for p in sorted(folder.rglob("*"))}


def _beside(out):
    return sorted(p.name for p in out.parent.iterdir() if p.name != out.name)


def _earlier_output(out):
    out.mkdir(parents=True)
    (out / "calibration.json").write_text('{"an": "earlier run"}\n')
    (out / "camchain.yaml").write_text("cam0: {}\n")
    return _tree(out)


def _stopped_cleanly(proc, signum, out, before, *, collected=True):
    """``collected``: the run's workers and helpers were all collected before it returned
    (a signal while a worker is still being started can leave that worker to end just after
    the main process, collected by init instead)."""
    proc.send_signal(signum)                    # to the main process only
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 128 + signum, (proc.returncode, stderr)
    assert stderr.strip().splitlines()[-1] == f"multieye: stopped by {signum.name}", stderr
    assert "Traceback" not in stderr
    # the command collects its helpers and workers before it returns (waiting up to 2 s for
    # each helper): nothing of its group is left, not even a defunct process. On a loaded
    # machine a helper may outlast that wait and be collected by init instead a moment
    # later, so the check allows 2 s more
    if collected:
        left = wait_until(lambda: group_processes(proc.pid) == {}, timeout=2.0)
        assert left is not None, f"left behind: {group_processes(proc.pid)}"
    took = wait_until(lambda: not group_members(proc.pid), timeout=5.0)
    assert took is not None, f"still running: {group_members(proc.pid)}"
    assert _tree(out) == before
    assert _beside(out) == []                   # no lock, no staging folder


def test_sigterm_ends_workers_removes_temporary_files_and_a_second_run_is_refused(
        dataset, slow_env, tmp_path):
    out = tmp_path / "out"
    before = _earlier_output(out)
    first = _in_detection(dataset, out, slow_env)
    second = _calibrate(dataset, out)
    _, err = second.communicate(timeout=60)
    assert second.returncode == 2, err
    (line,) = err.strip().splitlines()
    assert line.startswith(f"multieye: error: {out}: in use by another multieye run "
                           f"(process {first.pid}: multieye calibrate {dataset} -o {out}")
    _stopped_cleanly(first, signal.SIGTERM, out, before)


def test_sigint_ends_workers_and_removes_temporary_files(dataset, slow_env, tmp_path):
    out = tmp_path / "out"
    before = _earlier_output(out)
    _stopped_cleanly(_in_detection(dataset, out, slow_env), signal.SIGINT, out, before)


def test_after_sigkill_workers_end_within_5_s_and_the_next_run_leaves_no_leftovers(
        dataset, slow_env, tmp_path):
    out = tmp_path / "out"
    before = _earlier_output(out)
    killed = _in_detection(dataset, out, slow_env)
    killed.kill()
    took = wait_until(lambda: not group_members(killed.pid), timeout=5.0)
    killed.communicate()
    assert took is not None, f"still running 5 s after SIGKILL: {group_members(killed.pid)}"
    assert _tree(out) == before
    assert _beside(out) == ["out.multieye-lock"]        # the lock of the dead run
    again = _calibrate(dataset, out)
    stdout, stderr = again.communicate(timeout=120)
    assert again.returncode == 0, stderr
    assert _beside(out) == []
    assert sorted(p.name for p in out.iterdir()) == [
        ".multieye-manifest.json", "calibration.json", "camchain.yaml", "details.json",
        "figures", "report.html"]
    assert (out / "calibration.json").read_bytes() != before["calibration.json"][1]


@pytest.mark.parametrize("how", ["success", "error"])
def test_a_finished_run_leaves_no_process_behind(dataset, tmp_path, how):
    """Once ``multieye calibrate`` has returned, with its results (0) or with an error found
    after detection (2: the target never detected), no process of its group is left, not
    even defunct: the workers, the fork server and the resource tracker were collected."""
    ds = dataset
    if how == "error":
        ds = tmp_path / "ds"
        ds.mkdir()
        for p in dataset.iterdir():
            (ds / p.name).symlink_to(p)
        (ds / "rig.yaml").unlink()
        text = (dataset / "rig.yaml").read_text()
        assert "rows: 6" in text
        (ds / "rig.yaml").write_text(text.replace("rows: 6", "rows: 5"))
    proc = _calibrate(ds, tmp_path / "out", start_new_session=True)
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == (0 if how == "success" else 2), stderr
    if how == "error":
        (line,) = stderr.strip().splitlines()
        # whichever camera's detection fails first is named (the 5 x 9 target is a sub-grid
        # of the 6 x 9 board: no image of either camera should show it)
        assert line.startswith("multieye: error: ") and re.search(r"camera cam[01]\b", line) \
            and "not detected" in line, line
    assert group_processes(proc.pid) == {}


def _busy_loops(n):
    """``n`` processes spinning on the CPU (a ``stress``-like load), to be killed by the test."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


@pytest.mark.parametrize("to_group", [False, True], ids=["main-process", "terminal-group"])
def test_sigint_while_workers_start_never_shows_a_traceback(dataset, slow_env, tmp_path,
                                                            to_group):
    """Ctrl-C at any moment of the pool's start, under CPU load: one line, no traceback.

    A worker still being started by the fork server when the main process ends used to print
    a traceback (FileNotFoundError from SemLock._rebuild) to the shared standard error.  The
    signal goes early (as soon as the first worker exists, while the second may still be
    unpickling its queues), repeatedly, with 3 busy loops competing for the 2 cores; with
    ``to_group`` to the whole process group, as a terminal's Ctrl-C does.
    """
    load = _busy_loops(3)
    try:
        for k in range(4):
            out = tmp_path / f"run{k}" / "out"
            before = _earlier_output(out)
            proc = _in_detection(dataset, out, slow_env)
            if to_group:
                os.killpg(proc.pid, signal.SIGINT)
                stdout, stderr = proc.communicate(timeout=30)
                assert proc.returncode == 128 + signal.SIGINT, (proc.returncode, stderr)
                assert stderr.strip().splitlines()[-1] == "multieye: stopped by SIGINT", stderr
                assert "Traceback" not in stderr and "Error" not in stderr, stderr
                assert wait_until(lambda p=proc: not group_members(p.pid), timeout=5.0) is not None
                assert _tree(out) == before and _beside(out) == []
            else:
                _stopped_cleanly(proc, signal.SIGINT, out, before, collected=False)
    finally:
        for p in load:
            p.kill()
            p.wait()
