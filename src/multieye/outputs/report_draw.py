"""Drawing the report's figures, on two processes when there is enough to draw.

matplotlib takes most of the time of the report (its import alone about 0.4 CPU-s).  With
several cameras :func:`draw_figures` hands part of the figures to one worker process
(:func:`multieye.imaging.workers.worker_pool`: it ends with this process), which imports
matplotlib while this process imports it too and draws the rig; the figures are shared so
that both sides finish together (by a rough cost of each figure, measured on 4- and
16-camera rigs).  The figures are the same bytes either way: only where they are drawn
changes.

Synopsis
--------
>>> from multieye.outputs.report_draw import draw_figures
>>> pngs, legend, _ = draw_figures(rec, details)       # doctest: +SKIP
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable
from typing import Any

from multieye.io.calibration_json import CalibrationRecord
from multieye.io.run_details import RunDetails
from multieye.outputs.report_cameras import camera_figure_names
from multieye.outputs import figures as f
from multieye.outputs.figures_rig import rig_pngs
from multieye.imaging.batch import main_reimport_problem
from multieye.imaging.workers import worker_pool

__all__ = ["draw_figures", "figure_jobs", "PARALLEL_FROM_S"]

#: Rough CPU seconds of matplotlib's import in a worker: what a worker costs before drawing.
_IMPORT_S = 0.45
#: Share the figures with a worker when they would take this many CPU seconds or more.
PARALLEL_FROM_S = 0.6


def figure_jobs(rec: CalibrationRecord, details: RunDetails | None
                ) -> list[tuple[str, Callable, tuple, float]]:
    """The figures besides the rig's: ``(file name, function, arguments, rough CPU-s)``."""

    if details is None:
        return []
    m = len(details.cameras)
    jobs = [("residual_histograms.png", f.residual_histograms_png, (details,), 0.15 + 0.012 * m),
            ("residuals_over_time.png", f.residuals_over_time_png, (details,), 0.09 + 0.008 * m)]
    if any(c.points is not None for c in details.cameras):
        jobs += [("image_rms.png", f.image_rms_png, (details,), 0.08 + 0.006 * m),
                 ("residuals_by_radius.png", f.radial_png, (details,), 0.07 + 0.002 * m)]
    files = camera_figure_names(rec.cameras)
    colours = f.camera_colours(len(rec.cameras))
    for j, c in enumerate(rec.cameras):
        cam = details.camera(c.name)
        if cam.points is not None:
            jobs.append((files[c.name], f.camera_png, (cam, colours[j]), 0.12))
    return jobs


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:          # not on Linux
        return os.cpu_count() or 1


def _context():
    """forkserver where there is one (the detection's, already running after a calibration;
    when it is not, started with this module preloaded), spawn elsewhere: never a plain fork
    of a process with OpenCV's and OpenBLAS's threads."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([__name__])
    return ctx


def draw_figures(rec: CalibrationRecord, details: RunDetails | None, *,
                 processes: int | None = None, also: Callable[[], Any] | None = None
                 ) -> tuple[dict[str, bytes], tuple[str, ...], Any]:
    """Every figure of the report as PNG bytes by file name, the rig's legend, and what
    ``also`` returns (run in this process while a worker draws; None without it).

    Parameters
    ----------
    rec, details
        ``calibration.json`` and ``details.json`` (None without it).
    processes : int, optional
        At most this many processes draw (1: this one only); default two where two cores are
        available.  A worker is used only when the figures besides the rig would take about
        :data:`PARALLEL_FROM_S` CPU seconds or more.
    also : callable, optional
        More work for this process (the report's images: about 25 ms per camera).
    """

    jobs = figure_jobs(rec, details)
    allowed = min(2, _cores()) if processes is None else max(1, min(int(processes), 2))
    total = sum(cost for *_, cost in jobs)

    # a worker imports the main script again: not when that would run the user's script
    if allowed < 2 or total < PARALLEL_FROM_S or main_reimport_problem() is not None:
        rig = rig_pngs(rec, details)
        figures = dict(rig.pngs)
        for name, func, args, _ in jobs:
            figures[name] = func(*args)
        return figures, rig.legend, None if also is None else also()

    # share: the worker pays for its import first; this process draws the rig
    mine, theirs = [], []
    here = 0.3 + (0.035 if also is not None else 0.01) * len(rec.cameras)
    there = _IMPORT_S
    for job in sorted(jobs, key=lambda j: -j[3]):
        if here <= there:
            mine.append(job)
            here += job[3]
        else:
            theirs.append(job)
            there += job[3]
    with worker_pool(1, mp_context=_context()) as pool:
        pending = [(name, pool.submit(func, *args)) for name, func, args, _ in theirs]
        rig = rig_pngs(rec, details)
        figures = dict(rig.pngs)
        extra = None if also is None else also()
        for name, func, args, _ in mine:
            figures[name] = func(*args)
        for name, future in pending:
            figures[name] = future.result()
    order = [n for n in figures if n in rig.pngs] + [name for name, *_ in jobs]
    return {n: figures[n] for n in order}, rig.legend, extra
