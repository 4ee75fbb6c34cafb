"""The command's entry point (`multieye`, `python -m multieye`): after the command, a quick exit
that keeps the status and every byte written to the standard streams."""

from __future__ import annotations

import subprocess
import sys

from click.testing import CliRunner

from multieye.cli import main


def _cli(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "multieye", *args], capture_output=True,
                          timeout=120, **kwargs)


def test_the_status_and_the_whole_output_survive_the_quick_exit(tmp_path):
    page = CliRunner().invoke(main, ["docs", "rig-yaml"]).output.encode()
    assert len(page) > 10_000                          # more than a pipe's first write
    done = _cli("docs", "rig-yaml")
    assert done.returncode == 0 and done.stdout == page and done.stderr == b""
    bad = _cli("calibrate", str(tmp_path / "missing"), "-o", str(tmp_path / "out"))
    assert bad.returncode == 2 and bad.stdout == b""
    assert bad.stderr.decode().count("\n") == 1 and "rig.yaml" in bad.stderr.decode()
    assert not (tmp_path / "out").exists()
    usage = _cli("demo", "--rig", "ring")
    assert usage.returncode == 2 and b"ring" in usage.stderr


class _Exited(Exception):
    def __init__(self, code):
        super().__init__(code)
        self.code = code


class _GoneReader:
    """A standard stream whose reader has gone: flushing fails as on a closed pipe."""

    def write(self, text):
        return len(text)

    def flush(self):
        raise BrokenPipeError(32, "Broken pipe")


def _run(monkeypatch, status, stdout=None):
    """cli.run() with the command ending in ``status``; what os._exit got (or the usual
    SystemExit's code) and whether the exit functions ran."""
    import atexit

    from multieye import cli

    ran = []
    monkeypatch.setattr(cli, "main", lambda: sys.exit(status))
    monkeypatch.setattr(atexit, "_run_exitfuncs", lambda: ran.append(True))
    monkeypatch.setattr(cli.os, "_exit", lambda code: (_ for _ in ()).throw(_Exited(code)))
    if stdout is not None:
        monkeypatch.setattr(sys, "stdout", stdout)
    try:
        cli.run()
    except _Exited as exc:
        return ("quick", exc.code, bool(ran))
    except SystemExit as exc:
        return ("usual", exc.code, bool(ran))
    raise AssertionError("run() returned")


def test_the_quick_exit_keeps_the_status_and_runs_the_exit_functions_first(monkeypatch):
    assert _run(monkeypatch, 0) == ("quick", 0, True)
    assert _run(monkeypatch, 3) == ("quick", 3, True)
    # a reader gone: no traceback, Python's own status for a failed flush
    assert _run(monkeypatch, 0, stdout=_GoneReader()) == ("quick", 120, True)
    assert _run(monkeypatch, 2, stdout=_GoneReader()) == ("quick", 2, True)
    # a message instead of a status: the interpreter prints it and exits as usual
    assert _run(monkeypatch, "bad") == ("usual", "bad", False)


def test_a_running_thread_is_waited_for_as_usual(monkeypatch):
    import threading

    release = threading.Event()
    worker = threading.Thread(target=release.wait, daemon=False)
    worker.start()
    try:
        assert _run(monkeypatch, 0) == ("usual", 0, False)
    finally:
        release.set()
        worker.join()
