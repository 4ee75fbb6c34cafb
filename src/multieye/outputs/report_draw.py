"""Drawing the report's figures, on two processes when there is enough to draw.

matplotlib takes most of the time of the report (its import alone about 0.3 CPU-s).  With
several cameras, and a core free for it, the figures are shared with one worker process
(:func:`multieye.imaging.workers.worker_pool`: it ends with this process).
:func:`figure_worker` starts it before the other outputs are written, so that it imports
matplotlib while this process writes ``calibration.json`` and ``details.json``; then
:func:`draw_figures` hands it part of the figures while this process imports matplotlib too,
draws the rig and the rest.  The figures are shared so that both sides finish together (by a
rough cost of each figure, measured on 4- and 16-camera rigs), and the cameras' figures of one
process are drawn on one figure reused (:func:`multieye.outputs.figures.camera_pngs`).  The
figures are the same bytes either way: only where they are drawn changes.

Synopsis
--------
>>> from multieye.outputs.report_draw import draw_figures, figure_worker
>>> with figure_worker(4) as worker:                                 # doctest: +SKIP
...     pngs, legend, _ = draw_figures(rec, details, worker=worker)
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from multieye.io.calibration_json import CalibrationRecord
from multieye.io.run_details import RunDetails
from multieye.outputs.report_cameras import camera_figure_names
from multieye.outputs import figures as f
from multieye.outputs.figures_rig import rig_pngs
from multieye.imaging.batch import main_reimport_problem
from multieye.imaging.workers import worker_pool

__all__ = ["draw_figures", "figure_jobs", "figure_worker", "figures_cost", "FigureWorker",
           "PARALLEL_FROM_S"]

#: Rough CPU seconds of a worker's imports (matplotlib 0.3, multieye.io for the details it
#: is sent 0.08): what a worker costs before drawing (measured in a worker of the fork
#: server that a calibration starts).
_IMPORT_S = 0.4
#: Rough CPU seconds of matplotlib's import in this process.
_MAIN_IMPORT_S = 0.3
#: Share the figures with a worker when they would take this many CPU seconds or more.
PARALLEL_FROM_S = 0.6
#: Rough CPU seconds of the rig's pictures in this process, and per camera.
_RIG_S, _RIG_PER_CAMERA_S = 0.15, 0.01
#: Rough CPU seconds of a camera's figure on a figure reused, and of making that figure.
_CAMERA_S, _CAMERA_FIGURE_S = 0.08, 0.05


def _lane_costs(m: int) -> dict[str, float]:
    """Rough CPU-s of the all-camera figures for ``m`` cameras (measured, 2.4 GHz core)."""
    return {"residual_histograms.png": 0.10 + 0.022 * m,
            "residuals_over_time.png": 0.07 + 0.008 * m,
            "image_rms.png": 0.05 + 0.006 * m,
            "residuals_by_radius.png": 0.06 + 0.003 * m}


def figures_cost(n_cameras: int) -> float:
    """Rough CPU seconds of every figure besides the rig's for ``n_cameras`` cameras with
    target points (what :func:`figure_worker` decides by before the details are known)."""
    return sum(_lane_costs(n_cameras).values()) + _CAMERA_S * n_cameras + _CAMERA_FIGURE_S


def figure_jobs(rec: CalibrationRecord, details: RunDetails | None
                ) -> list[tuple[str, Callable, tuple, float]]:
    """The figures besides the rig's: ``(file name, function, arguments, rough CPU-s)``."""

    if details is None:
        return []
    m = len(details.cameras)
    cost = _lane_costs(m)
    names = ["residual_histograms.png", "residuals_over_time.png"]
    if any(c.points is not None for c in details.cameras):
        names += ["image_rms.png", "residuals_by_radius.png"]
    funcs = {"residual_histograms.png": f.residual_histograms_png,
             "residuals_over_time.png": f.residuals_over_time_png,
             "image_rms.png": f.image_rms_png, "residuals_by_radius.png": f.radial_png}
    jobs = [(name, funcs[name], (details,), cost[name]) for name in names]
    files = camera_figure_names(rec.cameras)
    colours = f.camera_colours(len(rec.cameras))
    for j, c in enumerate(rec.cameras):
        cam = details.camera(c.name)
        if cam.points is not None:
            jobs.append((files[c.name], f.camera_png, (cam, colours[j]), _CAMERA_S))
    return jobs


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:          # not on Linux
        return os.cpu_count() or 1


def _context():
    """forkserver where there is one (the detection's, already running after a calibration;
    when it is not, started with the figures module preloaded), spawn elsewhere: never a plain fork
    of a process with OpenCV's and OpenBLAS's threads."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([f.__name__])
    return ctx


def _free_core() -> bool:
    """Whether another core is free for a worker: the load average (1 minute) below the
    cores this process may use plus a half.  This run's own detection counts in it (at most
    one per core); on a machine busy with other work, a worker only adds its imports (about
    0.4 CPU-s) to what the cores must do, and the report takes longer (measured under load:
    docs/results/report_speed.md)."""
    try:
        return os.getloadavg()[0] < _cores() + 0.5
    except OSError:                 # no load average on this system
        return True


def _shared(cost: float, processes: int | None) -> bool:
    """Whether figures of ``cost`` CPU-s are worth a worker (two cores, one of them free,
    and a main script that a worker would not run again)."""
    allowed = min(2, _cores()) if processes is None else max(1, min(int(processes), 2))
    return (allowed >= 2 and cost >= PARALLEL_FROM_S and _free_core()
            and main_reimport_problem() is None)


@dataclass(frozen=True)
class FigureWorker:
    """A worker process drawing figures, and when it started (``time.perf_counter()``)."""

    pool: Any
    started: float


@contextmanager
def figure_worker(n_cameras: int, *, processes: int | None = None
                  ) -> Iterator[FigureWorker | None]:
    """A worker process for :func:`draw_figures`, started now: it imports matplotlib while
    this process goes on (writing the other outputs).  None when one process is better (one
    core or no free core, ``processes=1``, fewer figures than :data:`PARALLEL_FROM_S` CPU
    seconds for ``n_cameras`` cameras, or a main script that a worker would run again).  The
    worker ends with the block."""
    if not _shared(figures_cost(n_cameras), processes):
        yield None
        return
    with worker_pool(1, mp_context=_context()) as pool:
        pool.submit(f.warm_up)
        yield FigureWorker(pool, time.perf_counter())


def draw_figures(rec: CalibrationRecord, details: RunDetails | None, *,
                 processes: int | None = None, also: Callable[[], Any] | None = None,
                 worker: FigureWorker | None = None
                 ) -> tuple[dict[str, bytes], tuple[str, ...], Any]:
    """Every figure of the report as PNG bytes by file name, the rig's legend, and what
    ``also`` returns (run in this process while a worker draws; None without it).

    Parameters
    ----------
    rec, details
        ``calibration.json`` and ``details.json`` (None without it).
    processes : int, optional
        At most this many processes draw (1: this one only); default two where two cores are
        available and one is free.  Without ``worker``, one is started only when the figures
        besides the rig would take about :data:`PARALLEL_FROM_S` CPU seconds or more.
    also : callable, optional
        More work for this process (the report's images: about 25 ms per camera).
    worker : FigureWorker, optional
        The worker of :func:`figure_worker` (already importing), used when given.
    """
    jobs = figure_jobs(rec, details)
    if worker is None and _shared(sum(cost for *_, cost in jobs), processes):
        with worker_pool(1, mp_context=_context()) as pool:
            pool.submit(f.warm_up)
            return draw_figures(rec, details, also=also,
                                worker=FigureWorker(pool, time.perf_counter()))
    if worker is None:
        rig = rig_pngs(rec, details)
        figures = {**rig.pngs, **f.draw_jobs(jobs)}
        return figures, rig.legend, None if also is None else also()

    # share so that both end together: the worker may still be importing (it started
    # `elapsed` seconds ago); this process may import matplotlib, draws the rig and `also`
    mine, theirs = [], []
    here = (_RIG_S + (0.035 if also is not None else _RIG_PER_CAMERA_S) * len(rec.cameras)
            + (0.0 if "matplotlib.figure" in sys.modules else _MAIN_IMPORT_S))
    there = max(0.0, _IMPORT_S - (time.perf_counter() - worker.started))
    for job in sorted(jobs, key=lambda j: -j[3]):     # each side makes one camera figure
        if here <= there:
            here += job[3] + (_CAMERA_FIGURE_S if _first_camera(job, mine) else 0.0)
            mine.append(job)
        else:
            there += job[3] + (_CAMERA_FIGURE_S if _first_camera(job, theirs) else 0.0)
            theirs.append(job)
    pending = worker.pool.submit(f.draw_jobs, theirs) if theirs else None
    rig = rig_pngs(rec, details)
    result = None if also is None else also()
    figures = {**rig.pngs, **f.draw_jobs(mine)}
    if pending is not None:
        figures.update(pending.result())
    order = list(rig.pngs) + [name for name, *_ in jobs]
    return {n: figures[n] for n in order}, rig.legend, result


def _first_camera(job, side: list) -> bool:
    """Whether ``job`` is the first camera figure of a side (which makes the figure)."""
    return job[1] is f.camera_png and not any(j[1] is f.camera_png for j in side)
