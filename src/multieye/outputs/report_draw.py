"""Drawing the report's figures, in worker processes where there are two cores.

matplotlib takes most of the time of the report: its import (about 0.45 CPU-s) and about a
CPU second of drawing for four cameras.  Where two cores may be used and one is free (the
1-minute load average below the cores), every figure is drawn by worker processes
(:class:`FigureWorkers`; :func:`multieye.imaging.workers.worker_pool`: they end with this
process) and this process never imports matplotlib: it makes the details, writes the other
files and the page meanwhile.  ``multieye calibrate`` starts the workers when the detection
is done (:func:`figure_workers`, :meth:`FigureWorkers.start_early`), so that they import
matplotlib while the refinement runs on one core, the second once the first has imported
(the two imports take the free core in turn); otherwise they start with the outputs
(:meth:`FigureWorkers.start`).  They are forked from the detection's fork server (numpy and
OpenCV already imported).  This process draws everything with one core, ``processes=1``, a
main script that a worker would run again, or on a busy machine (no core free), where
workers slowed the refinement or the outputs down (docs/results/report_speed.md).

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
    """Whether a core is free now: the load average (1 minute) below the cores this process
    may use (this process is one of the runnable ones it counts).  On a busy machine
    workers started during the refinement take a share of its core instead (measured at a
    load of 3.5-4 on 2 cores: the refinement 2.2 s instead of 1.0, docs/results/
    report_speed.md)."""
    try:
        return os.getloadavg()[0] < _cores()
    except OSError:                 # no load average on this system
        return True


def worker_count(processes: int | None = None) -> int:
    """Figure workers to use: 2 where two cores may be used (``processes`` unset, or 2 and
    more), else 0 (this process draws: one core, ``processes=1``, or a main script that a
    worker would run again, :func:`~multieye.imaging.batch.main_reimport_problem`)."""
    allowed = min(2, _cores()) if processes is None else max(1, min(int(processes), 2))
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

    def start_early(self) -> None:
        """Start the workers now if a core is free (a calibration calls this when its
        detection is done): the first imports matplotlib and the figure modules
        (:func:`multieye.outputs.figures_rig.warm_up`) on the core the refinement leaves
        free, the second once the first is ready, so that the two imports take that core in
        turn.  On a busy machine they would take a share of the refinement's core instead,
        and start when the figures are handed to them (:meth:`start`)."""
        if self.count and _free_core():
            self._start(self.count, one_at_a_time=True)

    def start(self) -> None:
        """Start the workers now, both at once, if a core is free (once; nothing with
        ``count`` 0).  On a busy machine this process draws: one worker drawing while it
        waits made the outputs 0.6 s longer at a load of 3.3-3.8 on 2 cores (medians of 6,
        docs/results/report_speed.md)."""
        self._start(self.count if _free_core() else 0, one_at_a_time=False)

    def _start(self, size: int, *, one_at_a_time: bool) -> None:
        if self.pool is not None or not size:
            return
        self.size = size
        self.pool = self._stack.enter_context(
            worker_pool(size, mp_context=_context(), initializer=warm_up))
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
    if workers is not None:
        workers.start()
    if workers is None or not workers.size:
        def here():
            rig = rig_pngs(rec, details)
            return {**rig.pngs, **f.draw_jobs(figure_jobs(rec, details))}, rig.legend
        return here
    pending = [workers.pool.submit(func, *args)
               for _, func, args in _tasks(rec, details, workers.size)]

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
