"""A job's task split over the detection's workers, so that both take part at its end.

A camera whose lens is estimated gets its lens start from the detection's workers as soon as
its images are detected (:func:`multieye.imaging.batch.detect_jobs_then`).  The last camera's
start ran on one worker while the other had nothing left to do (0.07-0.35 s of a 4 x 100 rig,
the pose of every image by PnP with the lens found taking more than half of it).  A
:class:`SplitTask` is such a task in three steps: ``first`` (the lens) on one worker, then
``each`` (the poses) on parts of the results on every worker at once, then ``join`` here.

Synopsis
--------
>>> task = lens_start_task("pinhole-radtan", "cam0")    # a SplitTask   # doctest: +SKIP
>>> task(results)                       # the same, in this process   # doctest: +SKIP
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

__all__ = ["SplitTask", "OnPool"]


@dataclass(frozen=True)
class SplitTask:
    """A task on a job's results in three steps: ``state = first(results)``; then, unless
    ``state`` is None (the task's result then), ``each(state, part)`` for parts of the
    results in order, each giving a list, one per item of its part; ``join(state, items)``
    of those lists joined is the result.  ``first`` and ``each`` are picklable (they run in
    worker processes); calling the task runs the steps in this process."""

    first: Callable[[Sequence], Any]
    each: Callable[[Any, Sequence], list]
    join: Callable[[Any, list], Any]

    def __call__(self, results: Sequence) -> Any:
        state = self.first(results)
        return None if state is None else self.join(state, self.each(state, list(results)))


def _parts(items: Sequence, n: int) -> list[list]:
    """``items`` cut in ``n`` consecutive parts of sizes within one of each other."""
    k = len(items)
    return [list(items[i * k // n:(i + 1) * k // n]) for i in range(n) if k]


class OnPool:
    """A :class:`SplitTask` on ``pool``: ``first`` submitted now, the parts (one per worker)
    as soon as it is done (from the pool's thread), :meth:`result` waits for all and joins.

    Parameters
    ----------
    pool : concurrent.futures.Executor
    task : SplitTask
    results : sequence
        The job's results.
    workers : int
        Parts to cut the results in.
    """

    def __init__(self, pool, task: SplitTask, results: Sequence, workers: int):
        self._pool, self._task, self._results = pool, task, list(results)
        self._workers = max(int(workers), 1)
        self._parts: list | None = None
        self._spread = threading.Event()
        self._first = pool.submit(task.first, self._results)
        self._first.add_done_callback(self._submit_parts)

    def _submit_parts(self, future) -> None:
        try:
            if future.cancelled() or future.exception() is not None:
                return
            state = future.result()
            if state is not None:
                self._parts = [self._pool.submit(self._task.each, state, part)
                               for part in _parts(self._results, self._workers)]
        except (RuntimeError, BrokenProcessPool):   # the pool shut down or broke meanwhile
            self._parts = None
        finally:
            self._spread.set()

    def result(self) -> Any:
        """The task's result (the exception of a step raised here)."""
        state = self._first.result()
        if state is None:
            return None
        self._spread.wait()
        if self._parts is None:      # the parts could not be submitted: here, then
            return self._task.join(state, self._task.each(state, self._results))
        items = [item for part in self._parts for item in part.result()]
        return self._task.join(state, items)
