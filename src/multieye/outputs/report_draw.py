"""Drawing the report's figures, in worker processes where there are two cores.

matplotlib takes most of the time of the report: its import (about 0.45 CPU-s) and about a
CPU second of drawing for four cameras.  Where two cores may be used and one is free, every
figure is drawn by the workers of :mod:`multieye.outputs.figure_workers` (started when the
detection is done, or with the outputs) and this process never imports matplotlib: it
makes the details, writes the other files and the page meanwhile.  Otherwise (one core,
``processes=1``, a busy machine) this process draws them.

The figures are handed out as tasks, the costliest first (:func:`submit_figures`): the rig's
pictures, the all-camera figures, and the cameras' figures in one batch per worker (drawn on
one figure reused, :func:`multieye.outputs.figures.camera_pngs`); a worker takes the next
task when it is done with one, so both end together.  The figures are the same bytes
whichever process draws them.

Synopsis
--------
>>> from multieye.outputs.report_draw import figure_workers, submit_figures
>>> with figure_workers() as workers:                                  # doctest: +SKIP
...     workers.start()
...     wait = submit_figures(rec, details, workers)
...     pngs, legend = wait()
"""

from __future__ import annotations

from collections.abc import Callable

from multieye.io.calibration_json import CalibrationRecord
from multieye.io.run_details import RunDetails
from multieye.outputs.report_cameras import camera_figure_names
from multieye.outputs import figures as f
from multieye.outputs.figures_rig import record_rig_pngs
from multieye.outputs.figure_workers import FigureWorkers, figure_workers, worker_count

__all__ = ["draw_figures", "figure_jobs", "figure_workers", "submit_figures", "FigureWorkers",
           "worker_count"]     # the last three from multieye.outputs.figure_workers

#: Rough CPU seconds of the rig's pictures, and per camera (what orders the tasks).
_RIG_S, _RIG_PER_CAMERA_S = 0.08, 0.007
#: Rough CPU seconds of a camera's figure on a figure reused, and of making that figure.
_CAMERA_S, _CAMERA_FIGURE_S = 0.045, 0.025


def _lane_costs(m: int) -> dict[str, float]:
    """Rough CPU-s of the all-camera figures for ``m`` cameras (measured on 4 and 16 cameras,
    ``benchmarks/bench_report.py --figures``, docs/results/report_speed.md)."""
    return {"residual_histograms.png": 0.05 + 0.011 * m,
            "residuals_over_time.png": 0.045 + 0.0045 * m,
            "image_rms.png": 0.027 + 0.004 * m,
            "residuals_by_radius.png": 0.04 + 0.002 * m}


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


def _tasks(rec: CalibrationRecord, details: RunDetails | None, jobs: list, batches: int
           ) -> list[tuple[float, Callable, tuple]]:
    """The figures as ``(rough CPU-s, function, arguments)`` tasks, costliest first: the
    rig's pictures, each all-camera figure of ``jobs`` (:func:`figure_jobs`), the cameras'
    figures in ``batches`` batches."""
    cameras = [job for job in jobs if job[1] is f.camera_png]
    tasks = [(_RIG_S + _RIG_PER_CAMERA_S * len(rec.cameras), record_rig_pngs, (rec, details))]
    tasks += [(job[3], f.draw_jobs, ([job],)) for job in jobs if job[1] is not f.camera_png]
    for k in range(min(batches, len(cameras))):
        batch = cameras[k::batches]
        tasks.append((_CAMERA_FIGURE_S + sum(job[3] for job in batch), f.draw_jobs, (batch,)))
    return sorted(tasks, key=lambda t: -t[0])


def submit_figures(rec: CalibrationRecord, details: RunDetails | None,
                   workers: FigureWorkers | None = None
                   ) -> Callable[[], tuple[dict[str, bytes], tuple[str, ...]]]:
    """Hand every figure of the report to the workers now (started here if they were not);
    returns the function that waits for them: PNG bytes by file name in page order (the
    rig's, then :func:`figure_jobs`'), and the rig's legend.  Without workers (None, or
    ``count`` 0) that function draws them in this process.

    Parameters
    ----------
    rec, details
        ``calibration.json`` and ``details.json`` (None without it), as the files hold them.
    workers : FigureWorkers, optional
    """
    jobs = figure_jobs(rec, details)
    if workers is not None:
        workers.start()
    if workers is None or not workers.size:
        def here():
            rig = record_rig_pngs(rec, details)
            return {**rig.pngs, **f.draw_jobs(jobs)}, rig.legend
        return here
    order = [name for name, *_ in jobs]
    pending = [workers.pool.submit(func, *args)
               for _, func, args in _tasks(rec, details, jobs, workers.size)]

    def wait():
        drawn: dict[str, bytes] = {}
        rig = None
        for future in pending:
            result = future.result()
            if isinstance(result, dict):
                drawn.update(result)
            else:
                rig = result
        return {**rig.pngs, **{name: drawn[name] for name in order}}, rig.legend
    return wait


def draw_figures(rec: CalibrationRecord, details: RunDetails | None, *,
                 processes: int | None = None
                 ) -> tuple[dict[str, bytes], tuple[str, ...]]:
    """Every figure of the report as PNG bytes by file name, and the rig's legend: drawn by
    workers of :func:`figure_workers` (``processes``: see :func:`worker_count`), or here."""
    with figure_workers(processes) as workers:
        return submit_figures(rec, details, workers)()
