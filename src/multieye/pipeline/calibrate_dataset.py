"""The pipeline from a dataset folder (:func:`calibrate`), light to import: rig.yaml read, the
images listed and detection started before the later stages are imported.

The later stages (:mod:`multieye.pipeline.run`: pairing, consensus, the solvers, the
refinement) import SciPy's spatial, sparse and dense linear algebra: 0.3-0.4 CPU-s.
Imported before the detection starts, as they were, they held back the first image by as
much while the detection's fork server, done with its own imports, waited.  Here the
images go to the workers first, and this process imports those stages on a thread while
the workers detect (issue 21; ``tests/pipeline/test_detection_first.py`` checks the order,
``tests/test_start_up_imports.py`` what is imported before).

Synopsis
--------
>>> from multieye.pipeline import calibrate
>>> run = calibrate("dataset/rig.yaml", method="joint")   # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from importlib import import_module
from typing import TYPE_CHECKING

from multieye.imaging.engines import open_engine
from multieye.imaging.workers import Alongside
from multieye.io import load_rig
from multieye.pipeline.camera_data import load_camera_data
from multieye.pipeline.options import Options, updated_options
from multieye.pipeline.rig_model import build_rig_model
from multieye.pipeline.sources import outside_reads

if TYPE_CHECKING:                 # the result's module imports the later stages' types
    from multieye.pipeline.result import CalibrationRun

__all__ = ["calibrate", "Hooks"]

#: What the pipeline imports while the images are detected: the later stages.
LATER_STAGES = ("multieye.pipeline.run",)


def _import_later_stages(then: Callable[[], object] | None = None) -> None:
    """Import :data:`LATER_STAGES`, then run ``then`` (on the detection's thread)."""
    for name in LATER_STAGES:
        import_module(name)
    if then is not None:
        then()


@dataclass(frozen=True)
class Hooks:
    """The caller's work at two moments of :func:`calibrate`.

    Attributes
    ----------
    meanwhile : callable or None
        Run on a thread while the workers detect, after the later stages' imports.
    on_detected : callable or None
        Called once the detection is done (``multieye calibrate``: the figure workers start).
    """

    meanwhile: Callable[[], object] | None = None
    on_detected: Callable[[], object] | None = None


def calibrate(dataset: str | os.PathLike, options: Options = Options(), *,
              processes: int | None = None, progress: bool = False, engine: str = "local",
              scheduler: str | None = None, hooks: Hooks = Hooks(), **kw) -> CalibrationRun:
    """Calibrate the rig described by a dataset folder (or its ``rig.yaml``).

    Parameters
    ----------
    dataset : path-like
        Folder holding ``rig.yaml``, or the file itself.
    options : Options
        Or its fields as keyword arguments: ``method`` (solver name, :data:`multieye.METHODS`),
        ``reference`` (camera whose frame is ``ref``; default the first of ``rig.yaml``),
        ``refine``, ``robust``, ``time_offset``, ``max_time_offset``.
    processes : int, optional
        Worker processes for detection; default one per core.  Threads of this process
        instead, with a warning, when the calling script runs this at its top level, outside
        ``if __name__ == "__main__":`` (:func:`multieye.imaging.batch.main_reimport_problem`).
    progress : bool
        Show a progress bar (only sensible on a terminal).
    engine, scheduler : {"local", "dask"}, str or None
        Detection on Dask: at a scheduler's address, or a local cluster (docs/recordings.md).
    hooks : Hooks
        The caller's work while the workers detect, and once they are done.

    Returns
    -------
    CalibrationRun
        The final result per camera name as ``run.X``, ``run.T_ref_cam`` (with their
        ``_std`` and ``_covariance``), ``run.Y``; the closed form as ``run.closed_form``;
        ``run.warnings``; seconds per stage as ``run.timings``; what the plausibility
        checks doubt as ``run.doubts`` (empty when nothing).
    """
    start = time.perf_counter()
    rig = load_rig(dataset)                 # a folder or its rig.yaml, checked where it enters
    model = build_rig_model(rig)            # its targets and given lenses, built once
    options = updated_options(options, kw)
    # the later stages imported on a thread once the first images are sent (at the end of
    # the block when none are: poses only, an engine), waited for after the detection
    with Alongside(partial(_import_later_stages, hooks.meanwhile)) as aside, \
            contextlib.ExitStack() as stack:
        eng = None if engine == "local" and scheduler is None else stack.enter_context(
            open_engine(engine, scheduler=scheduler, workers=processes))
        cameras = load_camera_data(rig, processes=processes, progress=progress,
                                   select=options.select, time_offset=options.time_offset,
                                   engine=eng, on_sent=aside.start, model=model)
        loaded = time.perf_counter() - start
    if hooks.on_detected is not None:
        hooks.on_detected()
    from multieye.pipeline.run import calibrate_rig  # noqa: PLC0415 (heavy: SciPy and the solvers, imported while the images are detected, _import_later_stages)

    run = calibrate_rig(rig, cameras, options, model=model)
    detection = sum(d.detection_s for d in cameras.values())
    timings = replace(run.timings, reading=max(loaded - detection, 0.0), detection=detection,
                      total=time.perf_counter() - start)
    # files read from outside the dataset folder named, first among the warnings
    record = replace(run.record, warnings=outside_reads(rig, dataset) + tuple(run.record.warnings))
    return replace(run, timings=timings, record=record)
