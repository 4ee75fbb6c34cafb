"""Write the files of a calibration run into its output folder.

Synopsis
--------
>>> from multieye.outputs.write import write_outputs
>>> write_outputs(run, "out")                              # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from multieye.core.names import file_stems
from multieye.io import write_calibration, write_camchain, write_intrinsics_file
from multieye.io.atomic import confined_to, make_folder, synced_together
from multieye.io.run_details import (StageTimings, details_head, run_details_from_dict,
                                     run_details_to_dict, write_details_text)
from multieye.outputs.details import camera_overlaps, camera_topic, run_details
from multieye.outputs.export import kalibr_chain
from multieye.outputs.folder import staged_output
from multieye.outputs.report import write_report_from
from multieye.outputs.report_images import image_crops, image_folders
from multieye.pipeline import CalibrationRun

if TYPE_CHECKING:
    from multieye.outputs.report_draw import FigureWorkers

__all__ = ["WrittenOutputs", "write_outputs", "write_output_files"]


@dataclass(frozen=True)
class WrittenOutputs:
    """What :func:`write_outputs` wrote.

    Attributes
    ----------
    paths : list of Path
        Files (and the ``figures`` folder) written.
    notes : list of str
        Why an output was not written (e.g. intrinsics that Kalibr's models cannot hold).
    timings : StageTimings
        The run's timings with ``outputs`` measured and added to ``total``, as written
        into ``details.json``.
    """

    paths: list[Path]
    notes: list[str]
    timings: StageTimings


def write_outputs(run: CalibrationRun, out_dir: str | os.PathLike, *, report: bool = True,
                  diagnostics: dict | None = None, processes: int | None = None,
                  workers: FigureWorkers | None = None) -> WrittenOutputs:
    """Write the results of a run as the new content of ``out_dir``, all or nothing.

    ``calibration.json`` (docs/outputs.md), Kalibr ``camchain.yaml``, ``intrinsics/<camera>.yaml``
    for every camera whose intrinsics were estimated (the camera's name as a file name,
    :func:`multieye.core.names.file_stem`), ``details.json``
    (per-image residuals, target poses, trajectory; :mod:`multieye.io.run_details`) and,
    with ``report=True``, ``report.html`` with ``figures/`` (:mod:`multieye.outputs.report`).
    Everything is written into a staging folder beside ``out_dir``, which then replaces
    ``out_dir`` as a whole (:func:`multieye.outputs.folder.staged_output`): files of an
    earlier run that this one does not write are gone, and a run that fails at any point
    leaves ``out_dir`` exactly as it was.  ``out_dir`` must be missing, empty or hold only
    files multieye wrote, and no other run may hold it.

    The figures are drawn by worker processes while this process writes the rest
    (:mod:`multieye.outputs.report_draw`): ``workers`` when given (a calibration's, already
    started), else workers started here (``processes``: at most this many processes draw;
    1: this one).  The report is made from the record and the details as the files hold
    them, not read back.  The time spent writing is the ``outputs`` stage of the run's
    timings (:class:`~multieye.io.run_details.StageTimings`), measured before
    ``details.json``, which holds it, is written last.

    Returns
    -------
    WrittenOutputs

    Raises
    ------
    DatasetError
        ``out_dir`` is held by another run, holds files multieye did not write, or cannot be
        written; ``out_dir`` is unchanged.
    """
    start = time.perf_counter()
    rig = getattr(run, "rig", None)
    inputs = [rig.path] if getattr(rig, "path", None) is not None else []
    # the staging folder's files synced to disk together once written, before it replaces
    # out_dir (not one by one, each sync waiting for the last: io.atomic.synced_together)
    with staged_output(out_dir, inputs=inputs) as stage, synced_together(stage.folder):
        names, notes, timings = write_output_files(run, stage.folder, final=stage.out,
                                                   report=report, diagnostics=diagnostics,
                                                   start=start, processes=processes,
                                                   workers=workers)
    return WrittenOutputs(paths=[stage.out / n for n in names], notes=notes, timings=timings)


def write_output_files(run: CalibrationRun, folder: Path, *, final: Path, report: bool = True,
                       diagnostics: dict | None = None, start: float | None = None,
                       processes: int | None = None, workers: FigureWorkers | None = None
                       ) -> tuple[list[str], list[str], StageTimings]:
    """Write the files of :func:`write_outputs` into ``folder`` (a staging folder).

    ``final`` is the folder they will be moved to (named on the report); ``start``, a
    ``time.perf_counter()`` value, where the ``outputs`` stage began (default: now).
    Returns the names written, the notes and the timings written into ``details.json``.
    """
    from multieye.outputs.figure_workers import figure_workers  # noqa: PLC0415 (light: the figure modules are imported where the report is drawn)

    start = time.perf_counter() if start is None else start
    with confined_to(folder):           # nothing written through a link (docs/outputs.md)
        with (contextlib.nullcontext(workers) if workers is not None or not report
              else figure_workers(processes)) as drawing:
            if report and drawing is not None:   # importing while the details are made
                drawing.begin()
            names, notes, head = _write_files(run, folder, report=report,
                                              diagnostics=diagnostics, final=final,
                                              workers=drawing)
        seconds = time.perf_counter() - start
        timings = replace(run.timings, outputs=seconds, total=run.timings.total + seconds)
        write_details_text(folder / "details.json", head, timings)
    return [n for n in names if (folder / n).exists()], notes, timings


def _write_files(run: CalibrationRun, folder: Path, *, report: bool, diagnostics: dict | None,
                 final: Path, workers: FigureWorkers | None) -> tuple[list[str], list[str], str]:
    """Every output but ``details.json``, whose text but the timings is returned
    (:func:`~multieye.io.run_details.details_head`): the figures handed to the workers
    first, the other files written while they draw."""
    data = run_details_to_dict(run_details(run, diagnostics=diagnostics))
    if report:      # the details as details.json holds them (rounded): what the report shows
        from multieye.outputs.report_draw import submit_figures  # noqa: PLC0415 (heavy: the figure modules and OpenCV, only with the report)

        shown = run_details_from_dict(data)
        figures = submit_figures(run.record, shown, workers)
    write_calibration(folder / "calibration.json", run.record)
    names, notes = ["calibration.json"], []
    written, camchain_notes = _camchain(run, folder)
    names += ["camchain.yaml"] if written else []
    notes += camchain_notes
    estimated = [c for c in run.record.cameras
                 if c.intrinsics is not None and c.intrinsics.estimated]
    if estimated:
        stems = file_stems(estimated, what="file intrinsics/<camera>.yaml")
        make_folder(folder / "intrinsics")
        for cam in estimated:
            write_intrinsics_file(folder / "intrinsics" / f"{stems[cam.name]}.yaml",
                                    cam.intrinsics.intrinsics)
        names.append("intrinsics")
    head = details_head(data)
    names.append("details.json")
    if report:
        write_report_from(folder, run.record, shown, figures, shown_as=final.resolve(),
                          images=image_folders(run), crops=image_crops(run))
        names += ["report.html", "figures"]
    return names, notes, head


def _camchain(run: CalibrationRun, folder: Path) -> tuple[bool, list[str]]:
    """Kalibr's camchain with every camera it can hold; a camera it cannot (no intrinsics, or
    a lens Kalibr's models do not have) is named with the reason, in a note and in a comment
    at the top of the file, never dropped silently.  Returns whether it was written, and
    the notes."""
    cams = [c.name for c in run.record.cameras]
    kept, left = kalibr_chain(run.record, {n: run.cameras[n].intrinsics for n in cams},
                              {n: camera_topic(run, n) for n in cams}, camera_overlaps(run))
    if not kept:
        return False, [f"camchain.yaml not written: Kalibr cannot hold any camera: "
                       f"{'; '.join(left)}"]
    comments = ([f"left out of this camchain: {c}" for c in left] if left else [])
    write_camchain(folder / "camchain.yaml", kept, comments=comments)
    if not left:
        return True, []
    return True, [f"camchain.yaml holds {', '.join(e.name for e in kept)} only; left out: "
                  + "; ".join(left)]
