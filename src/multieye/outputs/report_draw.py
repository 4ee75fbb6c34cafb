"""Drawing the report's figures, in worker processes where there are two cores.

matplotlib takes most of the time of the report: its import (about 0.45 CPU-s) and about a
CPU second of drawing for four cameras.  Where two cores may be used, every figure is drawn
by worker processes (:class:`FigureWorkers`; :func:`multieye.imaging.workers.worker_pool`:
they end with this process) and this process never imports matplotlib: it makes the details,
writes the other files and the page meanwhile.  ``multieye calibrate`` starts the workers
when the detection is done (:func:`figure_workers`, :meth:`FigureWorkers.start`), so that
they import matplotlib while the refinement runs on one core; they are forked from the
detection's fork server (numpy and OpenCV already imported).  Two workers when a core is
free (the 1-minute load average below the cores plus a half), else one, so that the figures
cost no more CPU than drawing them here; none with one core, ``processes=1``, or a main
script that a worker would run again: then this process draws them.

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

import contextlib
import multiprocessing
import os
from collections.abc import Callable, Iterator

from multieye.io.calibration_json import CalibrationRecord
from multieye.io.run_details import RunDetails
from multieye.outputs.report_cameras import camera_figure_names
from multieye.outputs import figures as f
from multieye.outputs.figures_rig import rig_pngs, warm_up
from multieye.imaging.batch import main_reimport_problem
from multieye.imaging.workers import worker_pool

__all__ = ["draw_figures", "figure_jobs", "figure_workers", "submit_figures", "FigureWorkers",
           "worker_count"]

#: Rough CPU seconds of the rig's pictures, and per camera (what orders the tasks).
_RIG_S, _RIG_PER_CAMERA_S = 0.15, 0.01
#: Rough CPU seconds of a camera's figure on a figure reused, and of making that figure.
_CAMERA_S, _CAMERA_FIGURE_S = 0.08, 0.05


def _lane_costs(m: int) -> dict[str, float]:
    """Rough CPU-s of the all-camera figures for ``m`` cameras (measured, 2.4 GHz core)."""
    return {"residual_histograms.png": 0.10 + 0.022 * m,
            "residuals_over_time.png": 0.07 + 0.008 * m,
            "image_rms.png": 0.05 + 0.006 * m,
            "residuals_by_radius.png": 0.06 + 0.003 * m}


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
    """forkserver where there is one (the detection's, already running in a calibration;
    when it is not, started with the figures module preloaded), spawn elsewhere: never a plain
    fork of a process with OpenCV's and OpenBLAS's threads."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([warm_up.__module__])
    return ctx


def _free_core() -> bool:
    """Whether another core is free for a second worker: the load average (1 minute) below
    the cores this process may use plus a half.  On a machine busy with other work a second
    worker only adds its imports (about 0.45 CPU-s) to what the cores must do."""
    try:
        return os.getloadavg()[0] < _cores() + 0.5
    except OSError:                 # no load average on this system
        return True


def worker_count(processes: int | None = None) -> int:
    """Figure workers to use: 2 with two cores (``processes`` unset or 2 and more) and one
    of them free, 1 with two cores busy, 0 (this process draws) with one core,
    ``processes=1`` or a main script that a worker would run again
    (:func:`~multieye.imaging.batch.main_reimport_problem`)."""
    allowed = min(2, _cores()) if processes is None else max(1, min(int(processes), 2))
    if allowed < 2 or main_reimport_problem() is not None:
        return 0
    return 2 if _free_core() else 1


class FigureWorkers:
    """The worker processes that draw the report's figures (:func:`figure_workers`).

    Attributes
    ----------
    count : int
        Workers to start (:func:`worker_count`); 0: this process draws.
    pool : ProcessPoolExecutor or None
        Once :meth:`start` has started them.
    """

    def __init__(self, count: int, stack: contextlib.ExitStack):
        self.count = count
        self.pool = None
        self._stack = stack

    def start(self) -> None:
        """Start the workers now (once; nothing with ``count`` 0): each imports matplotlib
        and the figure modules (:func:`multieye.outputs.figures_rig.warm_up`) while this process
        goes on.  Called by a calibration when its detection is done."""
        if self.pool is None and self.count:
            self.pool = self._stack.enter_context(
                worker_pool(self.count, mp_context=_context(), initializer=warm_up))
            first = self.pool.submit(os.getpid)     # a task: the pool starts a process now
            if self.count > 1:          # the next once the first has imported: one core each
                first.add_done_callback(self._another)

    def _another(self, _) -> None:
        """Start one more worker (called by the pool's thread when a worker is ready)."""
        with contextlib.suppress(RuntimeError):     # the pool was shut down meanwhile
            self.pool.submit(os.getpid)


@contextlib.contextmanager
def figure_workers(processes: int | None = None) -> Iterator[FigureWorkers]:
    """Figure workers (:class:`FigureWorkers`, not started yet) that end with the block: at
    once on an exception (``KeyboardInterrupt`` included), after their work otherwise."""
    with contextlib.ExitStack() as stack:
        yield FigureWorkers(worker_count(processes), stack)


def _tasks(rec: CalibrationRecord, details: RunDetails | None, batches: int
           ) -> list[tuple[float, Callable, tuple]]:
    """The figures as ``(rough CPU-s, function, arguments)`` tasks, costliest first: the
    rig's pictures, each all-camera figure, the cameras' figures in ``batches`` batches."""
    jobs = figure_jobs(rec, details)
    cameras = [job for job in jobs if job[1] is f.camera_png]
    tasks = [(_RIG_S + _RIG_PER_CAMERA_S * len(rec.cameras), rig_pngs, (rec, details))]
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
    order = [name for name, *_ in figure_jobs(rec, details)]
    if workers is None or not workers.count:
        def here():
            rig = rig_pngs(rec, details)
            return {**rig.pngs, **f.draw_jobs(figure_jobs(rec, details))}, rig.legend
        return here
    workers.start()
    pending = [workers.pool.submit(func, *args)
               for _, func, args in _tasks(rec, details, workers.count)]

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
