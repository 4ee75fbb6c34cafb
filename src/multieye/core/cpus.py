"""The processors this process may use, and the BLAS threads of the command line (issue 21).

numpy's and SciPy's OpenBLAS start a pool of threads when they load, one per processor, and
those threads spin for a while after each call before they sleep: 0.06-0.13 CPU-s per
process that imports numpy, and again after each BLAS call, for work whose matrices here
are small (a 6 x 6 block per board pose; the refinement's reduced system has a few hundred
unknowns).  The command line therefore starts with one BLAS thread per process
(:func:`one_blas_thread`, before numpy is imported; its worker processes inherit it), unless
the user chose a number; :mod:`multieye.optimize.threads` raises it for the problems large
enough to gain from more.
"""

from __future__ import annotations

import os
import time

__all__ = ["available_cores", "one_blas_thread", "blas_threads_chosen", "BLAS_THREAD_VARIABLES",
           "runnable_elsewhere"]

#: The environment variables by which OpenBLAS is told its number of threads (the first set wins).
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")
#: Set beside ``OPENBLAS_NUM_THREADS`` by :func:`one_blas_thread`: the one thread is multieye's
#: choice, not the user's (inherited by the worker processes, as the variable is).
_OURS = "MULTIEYE_ONE_BLAS_THREAD"


def available_cores() -> int:
    """The CPUs this process may use (``os.sched_getaffinity``; the CPU count elsewhere)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:          # not on Linux
        return os.cpu_count() or 1


def runnable_elsewhere(samples: int = 5, pause_s: float = 0.002, *,
                       stat: str = "/proc/stat") -> float | None:
    """Tasks ready to run on this process's cores now, besides the calling thread.

    The median of ``samples`` readings, ``pause_s`` apart, of the kernel's count of runnable
    tasks (``procs_running`` of ``/proc/stat``, which counts the caller), less one, scaled by
    the share of the machine's processors this process may use (a container pinned to 2 of a
    host's 64 sees the host's count).  Unlike the load average, which follows the last
    minute, this sees the machine as it is: right after multieye's own detection workers
    have kept both cores busy for seconds, the one-minute load average is near 2 on an
    otherwise idle 2-core machine.

    Returns
    -------
    float or None
        None where the count cannot be read (not Linux).
    """
    counts = []
    for k in range(samples):
        if k:
            time.sleep(pause_s)
        try:
            with open(stat, "rb") as f:
                line = next((ln for ln in f if ln.startswith(b"procs_running ")), None)
        except OSError:
            return None
        if line is None:
            return None
        counts.append(int(line.split()[1]))
    machine = os.cpu_count() or 1
    return max(_median(counts) - 1.0, 0.0) * min(available_cores() / machine, 1.0)


def _median(values: list[int]) -> float:
    """``statistics.median`` (the same value), without importing :mod:`statistics` at the
    command's start, before its fork server starts (it imports ``fractions``, ``decimal``
    and ``random``: about 4 ms)."""
    s, n = sorted(values), len(values)
    return s[n // 2] if n % 2 else (s[n // 2 - 1] + s[n // 2]) / 2


def one_blas_thread() -> bool:
    """Have OpenBLAS start with one thread in this process and the processes it starts,
    unless one of :data:`BLAS_THREAD_VARIABLES` is set already (the user's choice stands).
    Takes effect only where numpy is imported afterwards.  Returns whether it was set."""
    if any(os.environ.get(name) for name in BLAS_THREAD_VARIABLES):
        return False
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    os.environ[_OURS] = "1"
    return True


def blas_threads_chosen() -> bool:
    """Whether the user chose the BLAS threads (one of :data:`BLAS_THREAD_VARIABLES` set, not
    by :func:`one_blas_thread`)."""
    if os.environ.get(_OURS) == "1" and os.environ.get("OPENBLAS_NUM_THREADS") == "1":
        return False
    return any(os.environ.get(name) for name in BLAS_THREAD_VARIABLES)
