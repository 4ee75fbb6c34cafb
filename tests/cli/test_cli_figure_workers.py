"""`multieye calibrate` draws the report's figures in worker processes (issue 21).

With two cores the figure workers start when the detection is done (they import matplotlib
while the refinement runs) and draw every figure, so the main process never imports
matplotlib; the workers end with the command, whether it succeeds, fails or is stopped; and
the files are the same bytes as when one process draws everything (``--processes 1``).

The runs are real processes, started in their own process group (found in /proc by it).  A
driver (``python -c``, no main script for the workers to import again) runs the command line
as ``python -m multieye`` does, after wrapping what the test needs to see or slow down.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest
from proc_tree import group_members, group_processes, needs_proc, running, wait_until
from small_dataset import render_small

pytestmark = [needs_proc, pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2,
                                             reason="figure workers need two cores")]

#: argv[1]: "plain" (record what the figure workers were), "slow" (the solve after the
#: detection waits 60 s: the figure workers are up meanwhile), or "fail" (it raises a
#: CalibrationError then); the rest: the command's arguments.  The workers start when the
#: detection is done, as on a machine with a free core.
DRIVER = r"""
import contextlib, sys, time
import multieye.outputs.figure_workers as draw
import multieye.pipeline.run as run

mode = sys.argv.pop(1)
draw._free_core = lambda: True          # the workers start when the detection is done
real_pool = draw.worker_pool
pids = []

@contextlib.contextmanager
def recorded_pool(*args, **kwargs):     # the pids of the figure workers, once they are done
    with real_pool(*args, **kwargs) as pool:
        try:
            yield pool
        finally:
            pids.extend(pool._processes)

draw.worker_pool = recorded_pool
real_solve = run.calibrate_rig

def solve(*args, **kwargs):
    print("SOLVING", flush=True)
    if mode == "fail":
        from multieye.core.errors import CalibrationError
        raise CalibrationError("made to fail after the detection")
    if mode == "slow":
        time.sleep(60)
    return real_solve(*args, **kwargs)

run.calibrate_rig = solve
try:
    from multieye.cli import main
    main(sys.argv[1:], standalone_mode=False)
finally:
    print("FIGURE_WORKERS " + " ".join(map(str, pids)), flush=True)
    print("MATPLOTLIB_IN_MAIN " + str("matplotlib" in sys.modules), flush=True)
"""


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ds") / "ds"
    render_small(folder, images_per_camera=10)
    return folder


def _driver(mode, ds, out, processes=2):
    return subprocess.Popen([sys.executable, "-c", DRIVER, mode, "calibrate", str(ds), "-o",
                             str(out), "--processes", str(processes)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _said(stdout: str, key: str) -> list[str]:
    (line,) = [x for x in stdout.splitlines() if x.startswith(key + " ")]
    return line.split()[1:]


def test_figures_are_drawn_by_workers_that_end_with_the_command(dataset, tmp_path):
    proc = _driver("plain", dataset, tmp_path / "out")
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr
    workers = [int(p) for p in _said(stdout, "FIGURE_WORKERS")]
    assert 1 <= len(workers) <= 2, stdout
    assert _said(stdout, "MATPLOTLIB_IN_MAIN") == ["False"]
    figures = sorted(p.name for p in (tmp_path / "out" / "figures").iterdir())
    assert "rig_3d.png" in figures and "camera_cam0.png" in figures, figures
    # nothing of the command is left once it has returned, not even a defunct process
    assert group_processes(proc.pid) == {}
    assert not any(running(p) for p in workers)


@pytest.mark.parametrize("how", ["sigint", "error"])
def test_figure_workers_end_when_the_run_is_stopped_or_fails(dataset, tmp_path, how):
    """The figure workers run from the detection's end: stopped then (Ctrl-C) or failing
    then, the command leaves none of them behind."""
    out = tmp_path / "out"
    proc = _driver("slow" if how == "sigint" else "fail", dataset, out)
    assert proc.stdout.readline().strip() == "SOLVING"

    def figure_workers_up():         # a grandchild: a worker forked by the fork server
        members = group_members(proc.pid)
        return any(parent != proc.pid and parent in members for parent in members.values())

    if how == "sigint":
        assert wait_until(figure_workers_up, timeout=60.0) is not None, "no figure worker"
        proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == (128 + signal.SIGINT if how == "sigint" else 2), stderr
    assert "Traceback" not in stderr
    assert len(_said(stdout, "FIGURE_WORKERS")) >= 1
    # the workers end with the command (allowing a loaded machine 2 s for its helpers)
    took = wait_until(lambda: group_processes(proc.pid) == {}, timeout=2.0)
    assert took is not None, f"left behind: {group_processes(proc.pid)}"
    assert not out.exists()


def _files(out):
    """Every file of an output folder by name: the folder's own name taken out of the page,
    and details.json without its timings (the only bytes that differ between two runs)."""
    files = {}
    for p in sorted(out.rglob("*")):
        if p.is_file():
            data = p.read_bytes()
            if p.name == "report.html":
                data = data.replace(str(out.resolve()).encode(), b"OUT").replace(
                    f"report: {out.name}<".encode(), b"report: OUT<")
            if p.name == "details.json":
                text = json.loads(data)
                assert set(text.pop("timings_s")) >= {"outputs", "total"}
                data = json.dumps(text).encode()
            files[p.relative_to(out).as_posix()] = data
    return files


def test_the_files_are_the_same_drawn_by_one_process_or_by_workers(dataset, tmp_path):
    runs = {}
    for processes in (1, 2):
        out = tmp_path / f"p{processes}"
        proc = _driver("plain", dataset, out, processes)
        stdout, stderr = proc.communicate(timeout=300)
        assert proc.returncode == 0, stderr
        workers = _said(stdout, "FIGURE_WORKERS")
        assert (len(workers) >= 1) == (processes == 2), stdout
        assert _said(stdout, "MATPLOTLIB_IN_MAIN") == [str(processes == 1)]
        runs[processes] = _files(out)
    assert sum(name.endswith(".png") for name in runs[1]) >= 6
    assert runs[1].keys() == runs[2].keys()
    assert [n for n in runs[1] if runs[1][n] != runs[2][n]] == []
