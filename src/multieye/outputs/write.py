"""Write the files of a calibration run into its output folder.

Synopsis
--------
>>> from multieye.outputs.write import write_outputs
>>> write_outputs(run, "out")                              # doctest: +SKIP
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

from multieye.core.names import file_stems
from multieye.io import write_calibration, write_camchain, write_opencv_intrinsics
from multieye.io.atomic import confined_to, make_folder
from multieye.io.run_details import RunDetails, StageTimings, write_details
from multieye.outputs.details import camera_overlaps, camera_topic, write_run_details
from multieye.outputs.export import kalibr_chain
from multieye.outputs.folder import staged_output
from multieye.outputs.report import write_report
from multieye.outputs.report_images import image_folders
from multieye.pipeline import CalibrationRun

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
                  diagnostics: dict | None = None) -> WrittenOutputs:
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

    The time spent writing is the ``outputs`` stage of the run's timings
    (:class:`~multieye.io.run_details.StageTimings`); ``details.json`` is written again with
    it once everything else is written (the report reads the first version), so the file
    holds the final numbers.

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
    with staged_output(out_dir, inputs=inputs) as stage:
        names, notes, timings = write_output_files(run, stage.folder, final=stage.out,
                                                   report=report, diagnostics=diagnostics,
                                                   start=start)
    return WrittenOutputs(paths=[stage.out / n for n in names], notes=notes, timings=timings)


def write_output_files(run: CalibrationRun, folder: Path, *, final: Path, report: bool = True,
                       diagnostics: dict | None = None, start: float | None = None
                       ) -> tuple[list[str], list[str], StageTimings]:
    """Write the files of :func:`write_outputs` into ``folder`` (a staging folder).

    ``final`` is the folder they will be moved to (named on the report); ``start``, a
    ``time.perf_counter()`` value, where the ``outputs`` stage began (default: now).
    Returns the names written, the notes and the timings written into ``details.json``.
    """
    start = time.perf_counter() if start is None else start
    with confined_to(folder):           # nothing written through a link (docs/outputs.md)
        names, notes, details = _write_all(run, folder, report=report,
                                           diagnostics=diagnostics, final=final)
        seconds = time.perf_counter() - start
        timings = replace(run.timings, outputs=seconds, total=run.timings.total + seconds)
        write_details(folder / "details.json", replace(details, timings=timings))
    return [n for n in names if (folder / n).exists()], notes, timings


def _write_all(run: CalibrationRun, folder: Path, *, report: bool, diagnostics: dict | None,
               final: Path) -> tuple[list[str], list[str], RunDetails]:
    """Write every output into ``folder``; returns the names written, notes, the details.

    With the report, a figure worker (:func:`~multieye.outputs.report_draw.figure_worker`)
    is started first: it imports matplotlib while this process writes the other files."""
    from multieye.outputs.report_draw import figure_worker  # noqa: PLC0415 (heavy: matplotlib's modules, only with the report)

    with figure_worker(len(run.record.cameras) if report else 0) as worker:
        return _write_files(run, folder, report=report, diagnostics=diagnostics, final=final,
                            worker=worker)


def _write_files(run: CalibrationRun, folder: Path, *, report: bool, diagnostics: dict | None,
                 final: Path, worker) -> tuple[list[str], list[str], RunDetails]:
    """:func:`_write_all` with the figure worker (or None)."""
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
            write_opencv_intrinsics(folder / "intrinsics" / f"{stems[cam.name]}.yaml",
                                    cam.intrinsics.intrinsics)
        names.append("intrinsics")
    details = write_run_details(folder / "details.json", run, diagnostics=diagnostics)
    names.append("details.json")
    if report:
        write_report(folder, shown_as=final.resolve(), images=image_folders(run),
                     worker=worker)
        names += ["report.html", "figures"]
    return names, notes, details


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
