"""Processes from /proc (Linux): which are running, and which belong to a process group."""

from __future__ import annotations

import os
import sys
import time

import pytest

needs_proc = pytest.mark.skipif(not sys.platform.startswith("linux") or not os.path.isdir("/proc"),
                                reason="reads processes from /proc (Linux)")


def _stat(pid: int) -> tuple[str, int, int] | None:
    """(state, parent pid, process group) of ``pid``, or None when it is gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            text = f.read().decode(errors="replace")
    except OSError:
        return None
    fields = text[text.rindex(")") + 2:].split()
    return fields[0], int(fields[1]), int(fields[2])


def running(pid: int) -> bool:
    """True while ``pid`` runs (a zombie, ended but not collected, does not)."""
    st = _stat(pid)
    return st is not None and st[0] not in ("Z", "X")


def group_members(pgid: int) -> dict[int, int]:
    """Running processes of process group ``pgid``: pid -> parent pid."""
    members = {}
    for name in os.listdir("/proc"):
        if name.isdigit():
            st = _stat(int(name))
            if st is not None and st[2] == pgid and st[0] not in ("Z", "X"):
                members[int(name)] = st[1]
    return members


def wait_until(condition, timeout: float, step: float = 0.05) -> float | None:
    """Seconds until ``condition()`` held, or None when it did not within ``timeout``."""
    start = time.monotonic()
    while True:
        if condition():
            return time.monotonic() - start
        if time.monotonic() - start > timeout:
            return None
        time.sleep(step)


def group_processes(pgid: int) -> dict[int, str]:
    """Every process of process group ``pgid``, defunct ones (zombies) included: pid -> state."""
    members = {}
    for name in os.listdir("/proc"):
        if name.isdigit():
            st = _stat(int(name))
            if st is not None and st[2] == pgid:
                members[int(name)] = st[0]
    return members


#: multiprocessing's own helpers, which outlive a pool by design until the interpreter exits:
#: not workers of a pool or a cluster.
MULTIPROCESSING_HELPERS = ("multiprocessing.resource_tracker", "multiprocessing.forkserver")


def working_descendants() -> set[int]:
    """Running descendants of this process (psutil), multiprocessing's own helpers left aside:
    the workers a pool or a local cluster would leave behind."""
    import psutil  # noqa: PLC0415 (only the tests that need it import this; the test extra has it)

    out = set()
    for p in psutil.Process().children(recursive=True):
        try:
            if p.status() != psutil.STATUS_ZOMBIE and not any(
                    h in " ".join(p.cmdline()) for h in MULTIPROCESSING_HELPERS):
                out.add(p.pid)
        except psutil.NoSuchProcess:
            pass
    return out
