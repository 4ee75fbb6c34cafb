"""BLAS threads chosen for the size of the reduced system.

The refinement's linear algebra is a Schur-complement system (:mod:`normal_equations`): the
eliminated blocks are small (6 x 6 per board pose) and the reduced system ``S`` has ``k``
unknowns, a few hundred for a rig of 16 cameras with free lenses. On problems of that size a
multi-threaded BLAS spends more time starting and synchronising its threads than it saves:
issue 21 measured 8 cameras x 100 images at 1.65 s wall / 2.2 CPU-s with OpenBLAS on 2
threads against 1.12 s / 1.24 CPU-s on one. A dense Cholesky of ``S`` costs ``k^3 / 3``
floating-point operations; threads only pay once that is in the billions.

Rule: one BLAS thread while ``k < PARALLEL_FROM`` (2000 unknowns, about 2.7 GFLOP per
factorisation), otherwise one per core this process may use, or the user's choice where
``OPENBLAS_NUM_THREADS`` (or ``OMP_NUM_THREADS``) states one (left as it is).  The command
line starts every process with one BLAS thread (:func:`multieye.core.cpus.one_blas_thread`). A fixed thread count also
makes reruns give the same digits: a threaded BLAS may sum in a different order from run to
run.

The libraries are looked up once per process (threadpoolctl scans the loaded shared objects,
about 10 ms a time; a refinement limits the threads several times).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from functools import cache

from threadpoolctl import ThreadpoolController

from multieye.core.cpus import available_cores, blas_threads_chosen

PARALLEL_FROM = 2000


@cache
def _controller() -> ThreadpoolController:
    """The BLAS libraries of this process, looked up at the first refinement (module doc)."""
    return ThreadpoolController()


def blas_threads(k: int) -> int | None:
    """BLAS threads for a reduced system of ``k`` unknowns.

    Parameters
    ----------
    k : int
        Unknowns of the reduced (Schur-complement) system.

    Returns
    -------
    int or None
        1 below :data:`PARALLEL_FROM`; from there on the cores this process may use, or
        None (left as it is) where the user chose the BLAS threads
        (:func:`multieye.core.cpus.blas_threads_chosen`).
    """
    if k < PARALLEL_FROM:
        return 1
    return None if blas_threads_chosen() else available_cores()


@contextmanager
def threads_for(k: int) -> Iterator[None]:
    """Limit the BLAS libraries loaded in this process to :func:`blas_threads` ``(k)`` threads
    for the duration of the ``with`` block (restored afterwards)."""
    limit = blas_threads(k)
    if limit is None:
        context = nullcontext()
    else:
        context = _controller().limit(limits=limit, user_api="blas")
    with context:
        yield
