"""The embedded main job: render a synthetic surround-view rig, calibrate it, check it.

``multieye demo -o OUT`` renders ``OUT/dataset`` (:mod:`multieye.sim.dataset`:
4 cameras with lens distortion, a chessboard on a motion-captured marker body, blur and sensor
noise, motion capture at 120 Hz against 4 Hz images), runs the full pipeline on it exactly as
on a user's dataset (consensus, ``joint`` closed form, maximum-likelihood refinement with
uncertainty), compares the result and the closed forms ``joint``, ``wang2022``, ``shah`` and
``li`` on the same measurements against the ground truth, and writes ``OUT/calibration.json``,
``camchain.yaml``, ``details.json`` and ``report.html``.

``multieye demo --rig overlap -o OUT`` does the same for what Kalibr and mrcal users calibrate:
three cameras whose views overlap (two radial-tangential lenses and a fisheye, 34 degrees
apart; :mod:`multieye.sim.overlap`), no motion capture, every lens unknown (``model:``): the
rig comes from the views the cameras share alone (:func:`run_overlap_demo`).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, unproject_points
from multieye.core.metrics import extrinsic_errors
from multieye.sim.dataset import DatasetSpec, GroundTruth, render_dataset
from multieye.sim.overlap import OverlapSpec, render_overlap_dataset
from multieye.outputs.folder import staged_output
from multieye.outputs.write import write_output_files
from multieye.pipeline import CalibrationRun, calibrate, calibrate_rig
from multieye.outputs.summary import calibration_table, comparison_table

__all__ = ["DemoResult", "run_demo", "run_overlap_demo", "lens_error_px", "COMPARED_METHODS"]

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
    truth : GroundTruth or OverlapScenario
        What was rendered (:func:`render_dataset`'s or :func:`render_overlap_dataset`'s).
    errors : dict of str to (ndarray, ndarray)
        Per method: rotation (degrees) and translation (metres) error of every ``T_ref_cam``.
        The overlap demo adds ``"lens"``: per camera, the estimated lens's projection error
        over the corners observed, raw and after the best-fitting rotation (pixels,
        :func:`lens_error_px`).
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


def lens_error_px(estimated: Intrinsics, true: Intrinsics, pixels: np.ndarray
                  ) -> tuple[float, float]:
    """RMS distance, pixels, between where the true and the estimated lens put the same rays,
    raw and after the rotation between the two camera frames that fits best.

    Parameters
    ----------
    estimated, true : Intrinsics
    pixels : ndarray, shape (n, 2)
        Where to compare: the true lens's rays through these pixels (unprojected by
        :func:`unproject_points`) are projected by ``estimated``.  Pass the corners that were
        observed: outside them a lens is extrapolated, and no calibration is told about it.

    Returns
    -------
    raw, rotated : float
        ``RMS |pi_est(ray) - pixel|`` and ``min_R RMS |pi_est(R ray) - pixel|``: a principal
        point off by ``d`` pixels is the camera turned by ``d / f`` radians, which the
        extrinsics estimated with that lens absorb (what mrcal's ``projection_diff`` fits).
    """
    pixels = np.asarray(pixels, dtype=float).reshape(-1, 2)
    rays = unproject_points(pixels, true)

    def residuals(rotvec: np.ndarray) -> np.ndarray:
        return (project_points(rays @ Rotation.from_rotvec(rotvec).as_matrix().T, estimated)
                - pixels).ravel()

    raw = float(np.sqrt(2 * np.mean(residuals(np.zeros(3)) ** 2)))
    fit = least_squares(residuals, np.zeros(3), x_scale=1e-3)
    return raw, float(np.sqrt(2 * np.mean(fit.fun ** 2)))


#: The overlap demo's scene: the board moved further than OverlapSpec's default so that every
#: lens is seen over more of its image (the fisheye still sees it in its centre only).
OVERLAP_DEMO = OverlapSpec(board_shift_m=0.45, n_instants=80)


def run_overlap_demo(out_dir: str | os.PathLike, *, seed: int = 0,
                     spec: OverlapSpec = OVERLAP_DEMO, progress: bool = False) -> DemoResult:
    """Render an overlapping rig without motion capture, calibrate it with every lens unknown
    and compare ``T_ref_cam`` and the lenses with the truth (module docstring)."""
    with staged_output(out_dir) as stage:
        out = stage.out
        t0 = time.perf_counter()
        truth = render_overlap_dataset(stage.folder / "dataset", spec, seed=seed, models=True,
                                       processes=2)
        t1 = time.perf_counter()
        run = calibrate(stage.folder / "dataset", progress=progress)
        t2 = time.perf_counter()
        names, notes, _ = write_output_files(run, stage.folder, final=out)
    outputs = [out / n for n in names]
    t3 = time.perf_counter()
    cams = [f"cam{j}" for j in range(spec.n_cameras)]
    T = np.stack([run.T_ref_cam[n] for n in cams])
    observed = {n: np.concatenate([o.image_points for o in run.cameras[n].observations])
                for n in cams}
    lens = np.array([lens_error_px(run.intrinsics[n], truth.intrinsics[j], observed[n])
                     for j, n in enumerate(cams)])          # (m, 2): raw, rotated
    errors = {"covisibility + refinement": extrinsic_errors(T, truth.T_ref_cam),
              "lens": (lens[:, 0], lens[:, 1])}
    timings = {"render_s": t1 - t0, "calibrate_s": t2 - t1, "write_and_report_s": t3 - t2}
    lens_rows = [f"  {n} ({truth.intrinsics[j].model}): {lens[j, 0]:.3f} px, "
                 f"{lens[j, 1]:.3f} px after the best-fitting rotation" for j, n in enumerate(cams)]
    text = "\n\n".join([
        f"Rendered {int(truth.seen.sum())} images of {len(cams)} cameras whose views overlap "
        f"({len(truth.seen)} board poses, {int((truth.seen.sum(axis=1) > 1).sum())} seen by "
        f"more than one camera; no motion capture, every lens unknown) into {out / 'dataset'} "
        f"in {timings['render_s']:.1f} s; calibrated in {timings['calibrate_s']:.1f} s; "
        f"report in {timings['write_and_report_s']:.1f} s.",
        calibration_table(run.record),
        "Error of T_ref_cam against ground truth (rotation deg / translation mm):\n"
        + comparison_table({"covisibility + refinement": T}, dict(zip(cams, truth.T_ref_cam))),
        "Error of each estimated lens against the true one (RMS, over the corners observed, of "
        "where the two put the same rays; then after the rotation between the two camera "
        "frames that fits best, which the extrinsics absorb):\n" + "\n".join(lens_rows),
        "Wrote " + ", ".join(str(p) for p in outputs),
        *notes,
    ])
    return DemoResult(run=run, truth=truth, errors=errors, timings=timings, outputs=outputs,
                      text=text)
