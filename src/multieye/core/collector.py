"""Fewer runs of Python's cyclic garbage collector in the processes multieye owns.

Python collects its youngest generation of container objects every 700 allocations
(``gc.get_threshold()[0]``), and every tenth and hundredth such run looks at older
generations too, up to every object alive.  A command allocates hundreds of thousands of
containers while it imports numpy, OpenCV, SciPy and its own modules (each then looked at
again by every full collection) and while it builds its result: in ``multieye calibrate``
the collector took 0.05-0.06 CPU-s of the main process's 0.5-0.8 without the report and
0.14 with it, and freed next to nothing (``gc.callbacks`` on the 4-camera renders of
``benchmarks/bench_peers.py``, docs/results/peers.md).  Collecting the youngest generation
every :data:`YOUNG_THRESHOLD` allocations instead takes 0.01-0.03 CPU-s.  The collector
still runs, so reference cycles are still freed, only later; a few tens of thousands of
young objects are a few megabytes at most.  Nothing a run computes depends on when the
collector runs.

For the command line's process and the report's figure workers, not a library user's
process, whose settings it would change.

Synopsis
--------
>>> from multieye.core.collector import fewer_collections
>>> fewer_collections()                                                 # doctest: +SKIP
"""

from __future__ import annotations

import gc

__all__ = ["fewer_collections", "YOUNG_THRESHOLD"]

#: Allocations of container objects between two collections of the youngest generation
#: (Python's default: 700).
YOUNG_THRESHOLD = 50_000


def fewer_collections(young: int = YOUNG_THRESHOLD) -> tuple[int, int, int]:
    """Collect the youngest generation every ``young`` allocations (never more often than
    Python's default), the older ones as Python does after it; returns the thresholds set."""
    first, second, third = gc.get_threshold()
    if first and young > first:         # 0: the collector is off, left so
        gc.set_threshold(young, second, third)
    return gc.get_threshold()
