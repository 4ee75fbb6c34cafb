"""Write the files of a calibration run into its output folder.

Synopsis
--------
>>> from multieye.outputs.write import write_outputs
>>> write_outputs(run, "out")                              # doctest: +SKIP
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

from multieye.core.errors import DatasetError, InputError
from multieye.io import CamchainEntry, write_calibration, write_camchain
from multieye.io.run_details import RunDetails, StageTimings, write_details
from multieye.outputs.details import write_run_details
from multieye.outputs.report import write_report
from multieye.pipeline import CalibrationRun

__all__ = ["WrittenOutputs", "write_outputs"]


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
    """Write the results of a run into ``out_dir``, all or nothing.

    ``calibration.json`` (docs/outputs.md), Kalibr ``camchain.yaml``, ``details.json``
    (per-image residuals, target poses, trajectory; :mod:`multieye.io.run_details`) and,
    with ``report=True``, ``report.html`` with ``figures/`` (:mod:`multieye.outputs.report`).
    Everything is first written into a temporary folder inside ``out_dir``; only when all of
    it succeeded are the files moved into place, ``calibration.json`` last, so a failed run
    leaves the previous results as they were.

    The time spent writing is the ``outputs`` stage of the run's timings
    (:class:`~multieye.io.run_details.StageTimings`); ``details.json`` is written again with
    it once everything else is written (the report reads the first version), so the file
    holds the final numbers.

    Returns
    -------
    WrittenOutputs
    """
    start = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".multieye-", dir=out))
    try:
        names, notes, details = _write_all(run, tmp, report=report, diagnostics=diagnostics,
                                           final=out)
        seconds = time.perf_counter() - start
        timings = replace(run.timings, outputs=seconds, total=run.timings.total + seconds)
        write_details(tmp / "details.json", replace(details, timings=timings))
        names = [n for n in names if (tmp / n).exists()]
        for name in names:
            target = out / name
            if target.is_dir() and not (tmp / name).is_dir():
                raise DatasetError("cannot replace a folder with a file", path=target)
        for name in sorted(names, key=lambda n: n == "calibration.json"):
            target = out / name
            if (tmp / name).is_dir():
                if target.exists():
                    shutil.rmtree(target)
            os.replace(tmp / name, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return WrittenOutputs(paths=[out / n for n in names], notes=notes, timings=timings)


def _write_all(run: CalibrationRun, folder: Path, *, report: bool, diagnostics: dict | None,
               final: Path) -> tuple[list[str], list[str], RunDetails]:
    """Write every output into ``folder``; returns the names written, notes, the details."""
    write_calibration(folder / "calibration.json", run.record)
    names, notes = ["calibration.json"], []
    missing = [c.name for c in run.record.cameras if run.cameras[c.name].intrinsics is None]
    if missing:
        notes.append(f"camchain.yaml not written: no intrinsics for {', '.join(missing)}")
    else:
        entries = [CamchainEntry(name=c.name, intrinsics=run.cameras[c.name].intrinsics,
                                 T_ref_cam=c.T_ref_cam) for c in run.record.cameras]
        try:
            write_camchain(folder / "camchain.yaml", entries)
        except InputError as exc:
            notes.append(f"camchain.yaml not written: {exc}")
        else:
            names.append("camchain.yaml")
    details = write_run_details(folder / "details.json", run, diagnostics=diagnostics)
    names.append("details.json")
    if report:
        write_report(folder, shown_as=final.resolve())
        names += ["report.html", "figures"]
    return names, notes, details
