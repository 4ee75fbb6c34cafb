"""Work the detection's fork server does later, when the main process asks (issue 21).

A module the fork server imports with its preload (:data:`multieye.imaging.workers.
FORKSERVER_PRELOAD` and the ``preload`` of :func:`~multieye.imaging.workers.
prestart_workers`) registers work with :func:`when_asked`; the server runs it when the
main process calls :func:`ask`, between two forks, and every worker forked afterwards
starts with its result: a module imported once for all of them.  ``multieye calibrate``
has the report's figure modules (matplotlib: about half a CPU second) imported this way
when the detection is done, while the refinement leaves a core free, so that its two
figure workers start ready to draw instead of each importing matplotlib
(:mod:`multieye.outputs.figure_workers`).

The request is a signal, :data:`SIGNAL` (``SIGURG``, which the system never sends to a
process without sockets of its own and whose default action is to ignore it): a fork
server that has nothing registered, or that was started by someone else, goes on as if
nothing had happened, and the figure workers import what they need themselves.  The work
runs in the server's main thread, from Python's signal handler, never while it forks; a
worker forked with the handler ignores the signal.  Light to import (no numpy, OpenCV or
matplotlib): the work imports what it needs when it runs.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from collections.abc import Callable
from multiprocessing import forkserver

__all__ = ["SIGNAL", "in_fork_server", "when_asked", "ask"]

#: The signal that asks the fork server for its registered work.
SIGNAL = signal.SIGURG


def in_fork_server() -> bool:
    """Whether this runs in a fork server's preload (its ``main`` is on the stack)."""
    frame = sys._getframe()
    while frame is not None:
        if frame.f_code is forkserver.main.__code__:
            return True
        frame = frame.f_back
    return False


#: The fork server's process id when this module was imported by it; None elsewhere.
_SERVER = os.getpid() if in_fork_server() else None
_LATER: list[Callable[[], object]] = []


def when_asked(work: Callable[[], object]) -> bool:
    """Run ``work()`` in this fork server when :func:`ask` is called, once.

    Call it at import time of a preload module.  Nothing happens in any other process.
    An exception of ``work`` is dropped: a worker that needs what ``work`` prepares
    prepares it again itself.

    Returns
    -------
    bool
        Whether ``work`` was registered (this process is a fork server importing its preload).
    """
    if _SERVER is None or os.getpid() != _SERVER:
        return False
    if not _LATER:
        signal.signal(SIGNAL, _run)
    _LATER.append(work)
    return True


def _run(signum, frame) -> None:
    if os.getpid() != _SERVER:          # a worker forked by the server keeps the handler
        return
    while _LATER:
        work = _LATER.pop(0)
        with contextlib.suppress(Exception):
            work()


def ask(pid: int) -> bool:
    """Ask the fork server ``pid`` (one this process started with a preload that registered
    work, :func:`multieye.imaging.workers.preloaded`) for its registered work; False when it
    cannot be asked (ended meanwhile).  The work runs before the server forks again."""
    try:
        os.kill(pid, SIGNAL)
    except OSError:
        return False
    return True
