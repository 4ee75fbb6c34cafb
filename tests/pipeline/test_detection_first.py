"""``multieye calibrate`` sends the images to the detection's workers before it imports the
later stages (issue 21): SciPy, the solvers, the refinement and the output writers are
imported by this process while the workers detect, on a thread, not before the first image
is sent.  Checked by order of events in a real run, not by time."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from multieye.imaging.workers import Alongside

#: Run as the main script: the command line, with the first job submission, the imports of
#: the modules below and the thread that imported them recorded in order.
SPY = textwrap.dedent("""
    import sys, threading
    from concurrent.futures import ProcessPoolExecutor

    LATER = ("scipy", "scipy.sparse", "scipy.spatial", "multieye.pipeline.run",
             "multieye.solvers.registry", "multieye.optimize", "multieye.outputs.write")
    events = []

    class Record:   # first on sys.meta_path: notes which thread imports what, finds nothing

        @staticmethod
        def find_spec(name, path=None, target=None):
            if name in LATER:
                events.append(("import", name, threading.current_thread().name))
            return None

    submit = ProcessPoolExecutor.submit

    def spy(self, fn, *args, **kwargs):
        if not any(e[0] == "submit" for e in events):
            events.append(("submit", " ".join(m for m in LATER if m in sys.modules), ""))
        return submit(self, fn, *args, **kwargs)

    def audit(event, args):     # the motion capture's file opened: by which thread, when
        if (event == "open" and str(args[0]).endswith("mocap.txt")
                and not any(e[0] == "mocap" for e in events)):
            events.append(("mocap", "-", threading.current_thread().name))

    if __name__ == "__main__":
        sys.meta_path.insert(0, Record)
        sys.addaudithook(audit)
        ProcessPoolExecutor.submit = spy
        from multieye.cli import main
        try:
            main(sys.argv[1:], standalone_mode=False)
        finally:
            # numpy's subpackages SciPy's first import would load (multieye.core.numpy_extras)
            events.append(("loaded", " ".join(m for m in (
                "numpy.f2py.f2py2e", "numpy.testing._private.utils") if m in sys.modules), ""))
            events.append(("figures", str("multieye.outputs.figures_rig" in sys.modules), ""))
            for kind, what, thread in events:
                print("event", kind, what.replace(" ", ",") or "-", thread or "-",
                      file=sys.stderr)
""")


def _events(tmp_path, dataset, processes: int, *flags: str) -> list[tuple[str, str, str]]:
    script = tmp_path / "spy.py"
    script.write_text(SPY)
    run = subprocess.run([sys.executable, str(script), "calibrate", str(dataset), "-o",
                          str(tmp_path / f"out{processes}"), "--processes", str(processes),
                          *flags], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    return [tuple(line.split()[1:]) for line in run.stderr.splitlines()
            if line.startswith("event ")]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from small_dataset import render_small

    ds = tmp_path_factory.mktemp("detection_first") / "ds"
    render_small(ds, images_per_camera=6)
    return ds


def test_the_images_are_sent_before_scipy_and_the_later_stages_are_imported(tmp_path, dataset):
    events = _events(tmp_path, dataset, processes=2)
    kinds = [e[0] for e in events]
    assert kinds.count("submit") == 1, events
    first = kinds.index("submit")
    # nothing of the later stages in this process when the first images go to the workers
    assert events[first][1] == "-", f"imported before the first image was sent: {events[first]}"
    imported = {what: thread for kind, what, thread in events if kind == "import"}
    # ... and all of them once the run is done, imported on the thread beside the detection
    # (scipy.spatial not at all: nothing on a calibration's path needs it, since 75729ea)
    assert set(imported) == {"scipy", "scipy.sparse", "multieye.pipeline.run",
                             "multieye.solvers.registry", "multieye.optimize",
                             "multieye.outputs.write"}, events
    assert set(imported.values()) == {"multieye-alongside"}, events


def test_the_command_leaves_numpy_f2py_and_testing_unloaded(tmp_path, dataset):
    """SciPy's first import (any subpackage) would load numpy.f2py and numpy.testing, which
    nothing uses (0.04-0.06 CPU-s): the command makes them lazy first."""
    events = _events(tmp_path, dataset, processes=2)
    assert "scipy" in {what for kind, what, _ in events if kind == "import"}, events
    assert [e for e in events if e[0] == "loaded"] == [("loaded", "-", "-")], events


def test_without_the_report_the_figure_modules_are_not_imported(tmp_path, dataset):
    """--no-report: the writers are imported while the workers detect, the report's figure
    modules not (a few ms of CPU beside the detection for nothing)."""
    events = _events(tmp_path, dataset, 2, "--no-report")
    assert [e for e in events if e[0] == "figures"] == [("figures", "False", "-")], events
    assert "multieye.outputs.write" in {what for kind, what, _ in events if kind == "import"}


def test_the_motion_capture_is_read_once_the_first_images_are_with_the_workers(tmp_path,
                                                                               dataset):
    """Nothing of the detection needs the motion capture here (no camera paired by name, no
    more images than the budget): its 50-90 ms of reading on a 4 x 100 rig no longer hold
    the first images back."""
    (dataset / "rig.yaml").read_text().index("mocap.txt")     # the file the spy watches
    events = _events(tmp_path, dataset, processes=2)
    kinds = [e[0] for e in events]
    assert "mocap" in kinds and kinds.index("submit") < kinds.index("mocap"), events
    assert events[kinds.index("mocap")][2] == "MainThread", events


def test_with_one_process_the_later_stages_are_imported_beside_the_detection(tmp_path, dataset):
    """No worker processes: the imports still run on the thread beside the detection in
    this process (OpenCV lets go of the interpreter while it decodes and detects)."""
    events = _events(tmp_path, dataset, processes=1)
    assert [e for e in events if e[0] == "submit"] == []
    threads = {thread for kind, _, thread in events if kind == "import"}
    assert threads == {"multieye-alongside"}, events


def test_alongside_runs_its_work_once_and_raises_its_error_at_the_end():
    calls = []
    with Alongside(lambda: calls.append(1)) as aside:
        aside.start()
        aside.start()                     # once only
    assert calls == [1]
    with Alongside(lambda: calls.append(2)):
        pass                              # never started: run at the end of the block
    assert calls == [1, 2]

    def fail():
        raise ImportError("no such module")

    with pytest.raises(ImportError, match="no such module"):
        with Alongside(fail) as aside:
            aside.start()
    # the block's own error wins over the work's
    with pytest.raises(KeyError):
        with Alongside(fail) as aside:
            aside.start()
            raise KeyError("the block's")
    with Alongside(None) as aside:        # nothing to run
        aside.start()


def test_alongside_interrupted_inside_start_raises_the_interrupt(monkeypatch):
    """Ctrl-C arriving inside Thread.start() (the thread object made, never started): the
    block's KeyboardInterrupt goes on, not join()'s "cannot join thread before it is
    started" (seen once in test_cli_processes' Ctrl-C under load)."""
    import threading

    def interrupted(self):
        raise KeyboardInterrupt

    monkeypatch.setattr(threading.Thread, "start", interrupted)
    with pytest.raises(KeyboardInterrupt):
        with Alongside(lambda: None) as aside:
            aside.start()


def test_the_lazy_packages_still_give_their_names_and_submodules():
    """pipeline, solvers and imaging import their names on first use (so that the detection
    starts first); a name, or a submodule read as an attribute, is there as it was."""
    code = ("import multieye.pipeline as p, multieye.solvers as s, multieye.imaging as i\n"
            "from multieye.pipeline import Options, calibrate, calibrate_rig, CalibrationRun\n"
            "from multieye.solvers import METHODS, solve\n"
            "from multieye.imaging import target_from_spec, detect_and_estimate\n"
            "assert p.run.calibrate_rig is calibrate_rig and s.registry.solve is solve\n"
            "assert i.batch.detect_and_estimate is detect_and_estimate\n"
            "assert calibrate.__module__ == 'multieye.pipeline.calibrate_dataset'\n"
            "for pkg in (p, s, i):\n"
            "    assert not hasattr(pkg, 'no_such_name') and not hasattr(pkg, '_private')\n"
            "print('ok')")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert run.stdout.split() == ["ok"], run.stderr
