"""The embedded main job: render a synthetic surround-view rig, calibrate it, check it.

``multieye demo -o OUT`` renders ``OUT/dataset`` (:mod:`multieye.sim.dataset`:
4 cameras with lens distortion, a chessboard on a motion-captured marker body, blur and sensor
noise, motion capture at 120 Hz against 4 Hz images), runs the full pipeline on it exactly as
on a user's dataset (consensus, ``joint`` closed form, maximum-likelihood refinement with
uncertainty), compares the result and the closed forms ``joint``, ``wang2022``, ``shah`` and
``li`` on the same measurements against the ground truth, and writes ``OUT/calibration.json``,
``camchain.yaml``, ``details.json`` and ``report.html``.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import numpy as np

from multieye.sim.dataset import DatasetSpec, GroundTruth, render_dataset
from multieye.core.metrics import extrinsic_errors
from multieye.outputs.folder import staged_output
from multieye.outputs.write import write_output_files
from multieye.pipeline import CalibrationRun, calibrate, calibrate_rig
from multieye.outputs.summary import calibration_table, comparison_table

__all__ = ["DemoResult", "run_demo", "COMPARED_METHODS"]

COMPARED_METHODS = ("joint", "wang2022", "shah", "li")


@dataclass(frozen=True)
class DemoResult:
    """What the demo did.

    Attributes
    ----------
    run : CalibrationRun
        The ``joint`` calibration (written to ``calibration.json``).  It was computed from
        the dataset in the staging folder, so the file paths it holds (``run.rig.path``)
        name that folder, which is ``OUT`` now.
    truth : GroundTruth
    errors : dict of str to (ndarray, ndarray)
        Per method: rotation (degrees) and translation (metres) error of every ``T_ref_cam``.
    timings : dict of str to float
        Seconds for rendering and calibration.
    outputs : list of Path
    text : str
        The printed report.
    """

    run: CalibrationRun
    truth: GroundTruth
    errors: dict
    timings: dict
    outputs: list
    text: str


def run_demo(out_dir: str | os.PathLike, *, seed: int = 0, spec: DatasetSpec = DatasetSpec(),
             progress: bool = False) -> DemoResult:
    """Render, calibrate and compare (see module docstring)."""
    # OUT as one set (multieye.outputs.folder): the dataset and the outputs are written into a
    # staging folder beside OUT, which replaces OUT when everything succeeded
    with staged_output(out_dir) as stage:
        out = stage.out
        t0 = time.perf_counter()
        truth = render_dataset(stage.folder / "dataset", spec, seed=seed)
        t1 = time.perf_counter()
        run = calibrate(stage.folder / "dataset", method="joint", progress=progress)
        t2 = time.perf_counter()
        results = {"joint + refinement": np.stack([c.T_ref_cam for c in run.record.cameras])}
        for method in COMPARED_METHODS:
            other = calibrate_rig(run.rig, run.cameras, method=method, refine=False)
            results[method] = np.stack([c.T_ref_cam for c in other.record.cameras])
        t3 = time.perf_counter()
        names, notes, _ = write_output_files(run, stage.folder, final=out)
    outputs = [out / n for n in names]
    t4 = time.perf_counter()
    errors = {m: extrinsic_errors(T, truth.T_ref_cam) for m, T in results.items()}
    timings = {"render_s": t1 - t0, "calibrate_s": t2 - t1, "closed_forms_s": t3 - t2,
               "write_and_report_s": t4 - t3}
    text = "\n\n".join([
        f"Rendered {sum(truth.images_written)} images of {len(truth.names)} cameras into "
        f"{out / 'dataset'} in {timings['render_s']:.1f} s; calibrated (detection, consensus, "
        f"closed form, refinement) in {timings['calibrate_s']:.1f} s; report in "
        f"{timings['write_and_report_s']:.1f} s.",
        calibration_table(run.record),
        "Error of T_ref_cam against ground truth (rotation deg / translation mm); the closed "
        "forms on the same measurements below the final result:\n"
        + comparison_table(results, dict(zip(truth.names, truth.T_ref_cam))),
        "Wrote " + ", ".join(str(p) for p in outputs),
        *notes,
    ])
    return DemoResult(run=run, truth=truth, errors=errors, timings=timings, outputs=outputs,
                      text=text)
