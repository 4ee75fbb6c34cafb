"""Calibrate many datasets at once: an end-of-line station, a fleet of vehicles.

Each dataset is one whole calibration (:func:`multieye.pipeline.calibrate`, then
:func:`multieye.outputs.write.write_outputs`) written to its own folder ``OUT_ROOT/<name>``
(the dataset folder's name) under the usual rules: the folder replaced as one set, a failed
run leaving it as it was, a folder held by a running calibration refused.  The calibrations
run as independent tasks of an engine (:mod:`multieye.imaging.engines`): worker processes of
this machine by default, or Dask distributed (a local cluster, or a scheduler whose workers
see the same paths), each calibration detecting in its own process.

A dataset that fails is that dataset's outcome (status 2 with its one line), never the end
of the others; the status of the whole is the worst of them (2, then 3, then 0).

Synopsis
--------
>>> import multieye
>>> many = multieye.calibrate_many(["rig_a", "rig_b"], "out", engine="dask")  # doctest: +SKIP
>>> many.status, [(o.dataset, o.status) for o in many.outcomes]              # doctest: +SKIP
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from multieye.core.errors import CalibrationError, InputError
from multieye.imaging.engines import open_engine
from multieye.outputs.folder import claim_output
from multieye.outputs.folder_names import checked_output
from multieye.outputs.summary import headline
from multieye.outputs.write import write_outputs
from multieye.pipeline import calibrate
from multieye.pipeline.options import Options

__all__ = ["DatasetOutcome", "ManyOutcome", "calibrate_many", "worst_status"]

#: Exit statuses from best to worst (docs/conventions.md: 0 success, 3 doubted, 2 failed).
_ORDER = (0, 3, 2)


def worst_status(statuses: Sequence[int]) -> int:
    """The worst of exit statuses: 2 (failed) over 3 (written but doubted) over 0."""
    return max(statuses, key=_ORDER.index, default=0)


@dataclass(frozen=True)
class DatasetOutcome:
    """How one dataset's calibration ended.

    Attributes
    ----------
    dataset : str
    out : str
        Its output folder.
    status : int
        0 written; 3 written but doubted; 2 failed, nothing written.
    message : str
        ``"ok"``, the doubts, or the error's one line.
    seconds : float
        Wall time of the calibration and its writing.
    headline : str
        The first line of calibrate's summary (:func:`multieye.outputs.summary.headline`:
        the figures that say how good the result is for the setup); empty when it failed.
    """

    dataset: str
    out: str
    status: int
    message: str
    seconds: float
    headline: str = ""


@dataclass(frozen=True)
class ManyOutcome:
    """Every dataset's outcome, in the order given, and the worst status."""

    outcomes: tuple[DatasetOutcome, ...]
    engine: str

    @property
    def status(self) -> int:
        return worst_status([o.status for o in self.outcomes])


def _calibrate_one(dataset: str, out: str, options: Options) -> DatasetOutcome:
    """One whole calibration in a worker (detection in this process only: a worker of a pool
    or of Dask starts no pool of its own)."""
    start = time.perf_counter()
    try:
        with claim_output(out, inputs=[dataset]):
            run = calibrate(dataset, options, processes=1, progress=False)
            write_outputs(run, out, processes=1)     # figures drawn here too
    except CalibrationError as exc:
        return DatasetOutcome(dataset, out, 2, str(exc), time.perf_counter() - start)
    except OSError as exc:
        name = getattr(exc, "filename", None)
        where = f"{os.fsdecode(name)}: " if isinstance(name, (str, bytes)) and name else ""
        return DatasetOutcome(dataset, out, 2, f"{where}{exc.strerror or exc}",
                              time.perf_counter() - start)
    doubts = "; ".join(d.message for d in run.doubts)
    return DatasetOutcome(dataset, out, 3 if run.doubts else 0, doubts or "ok",
                          time.perf_counter() - start, headline(run.record)[0])


def _out_folders(datasets: Sequence[Path], out_root: Path) -> list[Path]:
    """``out_root/<dataset folder name>`` per dataset; InputError when two share a name."""
    names = [(d.parent if d.name == "rig.yaml" else d).resolve().name for d in datasets]
    seen: dict[str, Path] = {}
    for d, n in zip(datasets, names):
        if n in seen:
            raise InputError(f"datasets {seen[n]} and {d} have the same folder name {n!r}, so "
                             f"their outputs would share {out_root / n}; rename one")
        seen[n] = d
    return [out_root / n for n in names]


def calibrate_many(datasets: Sequence[str | os.PathLike], out_root: str | os.PathLike,
                   options: Options = Options(), *, engine: str = "local",
                   scheduler: str | None = None, workers: int | None = None,
                   on_done: Callable[[DatasetOutcome], None] | None = None) -> ManyOutcome:
    """Calibrate every dataset into ``out_root/<its folder name>``, each a task of ``engine``
    ("local" or "dask": a local cluster of ``workers``, or the ``scheduler`` at an address);
    ``on_done(outcome)`` as each finishes; a :class:`ManyOutcome` (module docstring).
    """
    paths = [Path(os.fspath(d)) for d in datasets]
    if not paths:
        raise InputError("no dataset given")
    root = Path(os.fspath(out_root))
    outs = _out_folders(paths, root)
    for o in outs:                  # a name too long refused before anything runs
        checked_output(o)
    root.mkdir(parents=True, exist_ok=True)
    jobs = [(str(d), str(o), options) for d, o in zip(paths, outs)]
    found: dict[int, DatasetOutcome] = {}
    with open_engine(engine, processes=workers, scheduler=scheduler, workers=workers) as eng:
        if engine == "dask":
            done = eng.submit_each(_calibrate_one, jobs, star=True)
        else:
            done = enumerate(eng.map(_calibrate_one, jobs, star=True, chunksize=1))
        for k, outcome in done:
            found[k] = outcome
            if on_done is not None:
                on_done(outcome)
    return ManyOutcome(outcomes=tuple(found[k] for k in range(len(jobs))), engine=engine)
