"""The worker processes that draw the report's figures, and when they start.

Light to import (no numpy, OpenCV or matplotlib: the command line creates them before the
detection, :func:`figure_workers`); what they draw is :mod:`multieye.outputs.report_draw`'s.
Two workers where two cores may be used and one is free (the 1-minute load average below
the cores); ``multieye calibrate`` starts them when the detection is done
(:meth:`FigureWorkers.start_early`), so that matplotlib is imported while the refinement
runs on one core: once, by the detection's fork server, which then forks both workers
ready to draw (it imported this module first, :data:`PRELOAD`, and does that when asked,
:mod:`multieye.imaging.forkserver_later`); else by each worker, the second once the first
has imported.  Otherwise they start with the outputs (:meth:`FigureWorkers.start`).  They
are forked from the detection's fork server (numpy and OpenCV already imported) and end
with this process (:func:`multieye.imaging.workers.worker_pool`).  None with one core,
``processes=1``, a main script that a worker would run again, or on a busy machine (no core
free), where workers slowed the refinement or the outputs down
(docs/results/report_speed.md): the main process draws then.

Synopsis
--------
>>> from multieye.outputs.figure_workers import figure_workers
>>> with figure_workers() as workers:                                  # doctest: +SKIP
...     workers.start_early()
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import threading
from collections.abc import Iterator

from multieye.imaging.forkserver_later import when_asked
from multieye.imaging.main_script import main_reimport_problem
from multieye.core.cpus import runnable_elsewhere
from multieye.imaging.workers import ask_fork_server, available_cores, worker_pool

__all__ = ["FigureWorkers", "figure_workers", "worker_count", "FIGURE_MODULE", "PRELOAD"]

#: The module a figure worker imports first (:func:`multieye.outputs.figures_rig.warm_up`).
FIGURE_MODULE = "multieye.outputs.figures_rig"
#: This module, for the detection's fork server to import first
#: (:func:`multieye.imaging.workers.prestart_workers`): it then imports the figure modules
#: once the detection is done, when asked (:meth:`FigureWorkers.start_early`).
PRELOAD = __name__

_READY: list[bool] = []


def _warm_up() -> None:
    """A figure worker's first work: :func:`multieye.outputs.figures_rig.warm_up`, unless
    the process it was forked from did it already."""
    if _READY:
        return
    from multieye.outputs.figures_rig import warm_up  # noqa: PLC0415 (heavy: matplotlib, in the worker only)

    warm_up()
    _READY.append(True)


# In the detection's fork server (imported with its preload): the figure modules imported
# when the command asks, for every figure worker it forks afterwards.
when_asked(_warm_up)


def _context():
    """forkserver where there is one (the detection's, already running in a calibration;
    when it is not, started with the figure modules preloaded), spawn elsewhere: never a
    plain fork of a process with OpenCV's and OpenBLAS's threads."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([FIGURE_MODULE])
    return ctx


def _free_core() -> bool:
    """Whether a core is free now for workers beside this process: fewer tasks ready to run
    elsewhere than the cores this process may use, less its own
    (:func:`~multieye.core.cpus.runnable_elsewhere`; where that count cannot be read, the
    one-minute load average below the cores, this process being one of the runnable ones it
    counts).  On a busy machine workers started during the refinement take a share of its
    core instead (measured at a load of 3.5-4 on 2 cores: the refinement 2.2 s instead of 1.0,
    docs/results/report_speed.md).  The load average alone followed the last minute: after the
    detection's own workers it was near 2 on an idle 2-core machine, and the figures were drawn
    here, one after the other (outputs 1.0-1.1 s instead of 0.5)."""
    others = runnable_elsewhere()
    if others is not None:
        return others < available_cores() - 1
    try:
        return os.getloadavg()[0] < available_cores()
    except OSError:                 # no load average on this system
        return True


def worker_count(processes: int | None = None) -> int:
    """Figure workers to use: 2 where two cores may be used (``processes`` unset, or 2 and
    more), else 0 (this process draws: one core, ``processes=1``, or a main script that a
    worker would run again, :func:`~multieye.imaging.main_script.main_reimport_problem`)."""
    allowed = min(2, available_cores()) if processes is None else max(1, min(int(processes), 2))
    return 2 if allowed >= 2 and main_reimport_problem() is None else 0


class FigureWorkers:
    """The worker processes that draw the report's figures (:func:`figure_workers`).

    Attributes
    ----------
    count : int
        At most this many workers (:func:`worker_count`); 0: this process draws.
    pool : ProcessPoolExecutor or None
        Once :meth:`start_early` or :meth:`start` has started them.
    size : int
        Workers started: ``count`` with a core free when they started, else none.
    """

    def __init__(self, count: int, stack: contextlib.ExitStack):
        self.count = count
        self.pool = None
        self.size = 0
        self._stack = stack
        self._starter: threading.Thread | None = None
        self._failed: list[BaseException] = []
        self._busy = False          # start_early found no core free: this process draws

    def start_early(self) -> None:
        """Start the workers now if a core is free (a calibration calls this when its
        detection is done).  Matplotlib and the figure modules
        (:func:`multieye.outputs.figures_rig.warm_up`) are imported on the core the
        refinement leaves free: once, by the detection's fork server, where it imported this
        module first (:data:`PRELOAD`), and both workers are forked from it ready to draw
        (requested from a thread: a fork request waits for the server, which answers once it
        has imported, and this process goes on meanwhile); otherwise by the first worker,
        and the second starts once the first is ready, so that the two imports take that
        core in turn.  On a busy machine they would take a share of the refinement's core
        instead, and this process draws (:meth:`start` then starts none)."""
        if not self.count:
            return
        if not _free_core():
            self._busy = True
            return
        if ask_fork_server(PRELOAD):
            # a fork request waits for the server's answer, which comes once it has imported
            # (about half a second): requested from a thread, while this process refines
            self._starter = threading.Thread(target=self._start_aside, daemon=True,
                                             name="multieye-figure-workers")
            self._starter.start()
        else:
            self._start(self.count, one_at_a_time=True)

    def start(self) -> None:
        """Start the workers now, both at once, if a core is free (once; nothing with
        ``count`` 0; a start begun by :meth:`start_early` is waited for, and its error
        raised).  On a busy machine this process draws: one worker drawing while it waits
        made the outputs 0.6 s longer at a load of 3.3-3.8 on 2 cores (medians of 6,
        docs/results/report_speed.md).  Nor after :meth:`start_early` found no core free:
        workers started now would each import matplotlib (0.35-0.45 CPU-s apiece) beside
        this process's writing, where the detection's fork server would have imported it
        once, and a momentary load at either moment would otherwise decide."""
        self.join()
        if self._failed:
            raise self._failed[0]
        self._start(self.count if not self._busy and _free_core() else 0, one_at_a_time=False)

    def begin(self) -> None:
        """:meth:`start`, unless a start begun by :meth:`start_early` is under way: that one
        is waited for when the figures are handed over (:meth:`start` again), and this
        process meanwhile makes what they are drawn from instead of waiting (0.03-0.13 s
        on the 4 x 100 rig with the lenses known, where the fork server's imports outlast
        the refinement)."""
        if self._starter is None:
            self.start()

    def join(self) -> None:
        """Wait for a start begun by :meth:`start_early` on its thread (none: nothing)."""
        if self._starter is not None:
            self._starter.join()
            self._starter = None

    def _start_aside(self) -> None:
        try:
            self._start(self.count, one_at_a_time=False)
        except BaseException as exc:    # noqa: BLE001 - raised in the caller's thread, start()
            self._failed.append(exc)

    def _start(self, size: int, *, one_at_a_time: bool) -> None:
        if self.pool is not None or not size:
            return
        self.size = size
        self.pool = self._stack.enter_context(
            worker_pool(size, mp_context=_context(), initializer=_warm_up))
        first = self.pool.submit(os.getpid)         # a task: the pool starts a process now
        for _ in range(size - 1):
            if one_at_a_time:
                first.add_done_callback(self._another)
            else:
                self.pool.submit(os.getpid)

    def _another(self, _) -> None:
        """Start one more worker (called by the pool's thread when a worker is ready)."""
        with contextlib.suppress(RuntimeError):     # the pool was shut down meanwhile
            self.pool.submit(os.getpid)


@contextlib.contextmanager
def figure_workers(processes: int | None = None) -> Iterator[FigureWorkers]:
    """Figure workers (:class:`FigureWorkers`, not started yet) that end with the block: at
    once on an exception (``KeyboardInterrupt`` included), after their work otherwise."""
    with contextlib.ExitStack() as stack:
        workers = FigureWorkers(worker_count(processes), stack)
        try:
            yield workers
        finally:
            workers.join()          # a start under way ends before the workers are ended
