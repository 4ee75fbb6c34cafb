"""From a dataset folder to rig extrinsics: the paper's Fig. 3 pipeline, as a list of stages.

Each stage is a function from typed input to typed output, keyed by camera name:

1. read: ``rig.yaml`` (docs/rig-yaml.md) -> :class:`~multieye.io.Rig`; detect: per camera,
   images -> target detection -> PnP (or precomputed ``T_cam_target`` poses) ->
   :class:`CameraData` (:mod:`multieye.pipeline.camera_data`); together a
   :class:`~multieye.pipeline.problem.Problem`.
2. pair: clock offsets, pairing with the motion capture in time -> ``A``, ``B``
   (docs/conventions.md, section 2) -> :class:`~multieye.pipeline.problem.Pairing`.
3. consensus: the measurements that agree, and each single marker's pose of the two PnP
   gives (:mod:`multieye.pipeline.ambiguity`) -> a smaller ``Pairing``.
4. closed form: :func:`multieye.solve` -> :class:`ClosedForm`.
5. plausibility: :func:`multieye.estimate.plausibility.check_plausibility` on the kept
   measurements.
6. refine: :func:`multieye.pipeline.refine.refine` -> ``Refined``; then the noise it
   estimated checked against the sensor (:func:`multieye.estimate.plausibility.check_noise`).
7. summarise: :func:`multieye.pipeline.record.build_record` -> :class:`CalibrationRun`,
   which ``multieye.outputs.write.write_outputs`` writes.

Synopsis
--------
>>> from multieye.pipeline import calibrate
>>> from multieye.outputs.write import write_outputs
>>> run = calibrate("dataset/rig.yaml", method="joint")   # doctest: +SKIP
>>> write_outputs(run, "out")                              # doctest: +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from multieye.core.errors import CalibrationError, TooFewMeasurementsError
from multieye.estimate.consensus import DEFAULT_THRESHOLDS, consensus
from multieye.estimate.diagnostics import MotionDiagnostics, motion_diagnostics
from multieye.estimate.plausibility import (
    CameraEvidence,
    Declared,
    Plausibility,
    check_determined,
    check_noise,
    check_plausibility,
)
from multieye.estimate.uncertainty import pose_std
from multieye.io import RejectedItem, Rig
from multieye.io.calibration_json import SETUP_KEYS
from multieye.io.run_details import StageTimings
from multieye.pipeline import ambiguity  # single markers: the rig chooses each image's pose
from multieye.pipeline import half_turns  # symmetric boards: the rig chooses each view's order
from multieye.pipeline.camera_data import (
    CameraData,
    Observation,
    PairedCamera,
    load_camera_data,
    pair_camera,
)
from multieye.pipeline.estimated_lens import refit_paired
from multieye.pipeline.image_acceptance import camera_data_now
from multieye.pipeline.options import Options, updated_options
from multieye.estimate.refine_images import (
    DEFAULT_MOCAP_ROT_SIGMA_RAD,
    DEFAULT_MOCAP_TRANS_SIGMA_M,
    RefinementResult,
)
from multieye.pipeline.overlap import paired_instants, share_instants
from multieye.pipeline.recordings import camera_warnings, no_copied_images
from multieye.pipeline.overlap_run import calibrate_overlap, check_overlap_options
from multieye.pipeline.clock_offsets import estimated_offset, with_clock_offsets
from multieye.pipeline.overlap_mocap import check_mocap_options, refuse_eye_to_base, with_clocks
from multieye.pipeline.problem import Pairing, Problem, make_problem
from multieye.pipeline.record import build_record
from multieye.pipeline.rig_model import RigModel
from multieye.pipeline.refine import Refined, mocap_noise, refine
from multieye.pipeline.result import CalibrationRun, Refinement
from multieye.pipeline.selection import merged, select_paired
from multieye.solvers import Solution, solve
from multieye.solvers.checks import check_measurements
from multieye.solvers.measurements import Measurements

__all__ = [
    "Observation",
    "CameraData",
    "PairedCamera",
    "CalibrationRun",
    "ClosedForm",
    "Options",
    "Refinement",
    "StageTimings",
    "load_camera_data",
    "pair_camera",
    "calibrate_rig",
]

#: Inlier thresholds of the consensus (loop rotation residual, target position residual),
#: then the wider ones tried when too few measurements of a camera agree with the first.
CONSENSUS_THRESHOLDS = (DEFAULT_THRESHOLDS, (15.0, 0.15))


@dataclass(frozen=True)
class Checks:
    """What the plausibility checks doubt: after the closed form, and at the end (with the
    motion-capture noise the refinement estimated checked against the sensor)."""

    solved: Plausibility
    final: Plausibility


@dataclass(frozen=True)
class ClosedForm:
    """The closed-form stage: the solution and the motion diagnostics of the measurements
    it solved (their warnings name weak motion)."""

    solution: Solution
    motion: MotionDiagnostics


def calibrate_rig(rig: Rig, cameras: dict[str, CameraData], options: Options = Options(), *,
                  model: RigModel | None = None, **kw) -> CalibrationRun:
    """Pair, check, solve, refine and summarise already loaded camera data.

    Parameters
    ----------
    rig : Rig
    cameras : dict of str to CameraData
        From :func:`load_camera_data`.
    options : Options
        Or its fields as keyword arguments (``method="shah", refine=False``).
    model : RigModel, optional
        The targets and given lenses the cameras were loaded with (built when not given).
    """
    clock = [time.perf_counter()]
    no_copied_images(cameras, rig.path)
    problem = make_problem(rig, cameras, updated_options(options, kw), model)
    if all(d.mocap is None for d in cameras.values()):   # linked by shared views (issue 23)
        run = calibrate_overlap(check_overlap_options(problem))      # and by motion (34)
        return replace(run, timings=StageTimings(refinement=time.perf_counter() - clock[0],
                                                 total=time.perf_counter() - clock[0]))
    if len(rig.targets) > 1:             # with motion capture: the rig's motion too (34)
        refuse_eye_to_base(rig)
        problem, clocks, notes = with_clock_offsets(check_mocap_options(problem))
        run = calibrate_overlap(problem)
        run = replace(run, record=with_clocks(run.record, problem, clocks, notes))
        return replace(run, timings=StageTimings(refinement=time.perf_counter() - clock[0],
                                                 total=time.perf_counter() - clock[0]))
    every = pair(problem)

    def check() -> Plausibility:      # every measurement: why a failing stage failed
        return check_pairing(problem, every)

    if problem.options.robust:
        kept = keep_consensus(problem, every, check)
    else:
        kept = choose_without_consensus(problem, every)
    clock.append(time.perf_counter())
    closed = solve_closed_form(problem, kept, check)
    solved = check_pairing(problem, kept)
    clock.append(time.perf_counter())
    refined = refine(problem, kept, closed.solution)
    kept = refined.pairing or kept          # images taken back or left out on the refined lens
    clock.append(time.perf_counter())
    checks = Checks(solved=solved, final=check_refined(problem, kept, solved, refined))
    run = summarise(problem, kept, closed, checks, refined)
    return replace(run, timings=StageTimings(
        pairing=clock[1] - clock[0], closed_form=clock[2] - clock[1],
        refinement=clock[3] - clock[2], total=time.perf_counter() - clock[0]))


def pair(problem: Problem) -> Pairing:
    """Each camera's images paired with the motion capture at its clock offset, and the
    measurements validated here, once: consensus, diagnostics and solve take them as they are."""
    offsets = _offsets(problem)
    paired = {n: pair_camera(problem.setup, d, time_offset=offsets[n])
              for n, d in problem.cameras.items()}
    selection = {}
    if problem.options.select:      # the images of cameras still over their budget, chosen
        images = {n: p for n, p in paired.items() if problem.cameras[n].intrinsics is not None
                  and p.observations[0].object_points is not None}
        chosen, selection = select_paired(images, problem.cameras, problem.options.select,
                                          problem.rig.sync_tolerance, offsets)
        paired.update({n: _keep(paired[n], mask, reasons)
                       for n, (mask, reasons) in chosen.items()})
    if problem.options.time_offset != "auto":    # cameras that see the target together
        instants, _ = paired_instants(paired, problem.cameras, offsets,
                                      problem.rig.sync_tolerance)
        _, rot, trans = mocap_noise(problem.rig, paired, problem.options)
        paired = share_instants(problem.rig, paired, instants, (
            DEFAULT_MOCAP_ROT_SIGMA_RAD if rot is None else rot,
            DEFAULT_MOCAP_TRANS_SIGMA_M if trans is None else trans))
    meas = check_measurements([p.A for p in paired.values()], [p.B for p in paired.values()],
                              names=list(paired), per_camera_motion=False)
    return Pairing(offsets=offsets, paired=paired, measurements=meas,
                   warnings=camera_warnings(problem.cameras),
                   selection=selection)


def _offsets(problem: Problem) -> dict[str, float]:
    """Per camera, the clock offset to pair with: rig.yaml's, the options' number, or
    estimated (``time_offset="auto"``); 0 for cameras paired by name (no clock)."""
    opts, cameras = problem.options, problem.cameras
    if opts.time_offset == "rig":
        return {n: 0.0 if d.by_name else d.time_offset for n, d in cameras.items()}
    if opts.time_offset != "auto":
        return {n: 0.0 if d.by_name else float(opts.time_offset) for n, d in cameras.items()}
    return {n: 0.0 if d.by_name else float(estimated_offset(problem, d).offset_s)
            for n, d in cameras.items()}


def keep_consensus(problem: Problem, pairing: Pairing, check: Callable[[], Plausibility]
                   ) -> Pairing:
    """The measurements the consensus keeps, each camera's outliers added to its rejected
    items; when almost nothing agrees, the error says why, if the plausibility checks know."""
    warnings: list[str] = []
    try:
        cons = _consensus(pairing.measurements, warnings,
                          [[o.name for o in p.observations] for p in pairing.paired.values()],
                          ambiguity.alternatives(pairing.paired.values()))
    except TooFewMeasurementsError as exc:
        raise _failed(exc, check) from None
    by_cam: dict[str, dict[int, str]] = {n: {} for n in pairing.paired}
    for r in cons.rejected:
        by_cam[r.camera][r.index] = r.reason
    choices = half_turns.fewest_turns([p.observations for p in pairing.paired.values()],
                                      cons.alternative, cons.inliers)
    paired = {n: _keep(ambiguity.with_choice(p, choices[j]), cons.inliers[j], by_cam[n])
              for j, (n, p) in enumerate(pairing.paired.items())}
    warnings += half_turns.turn_warning(
        {n: p.observations for n, p in paired.items()},
        {n: choices[j][cons.inliers[j]] for j, n in enumerate(paired)},
        "the consensus with the motion capture")
    return replace(pairing, paired=paired,
                   measurements=ambiguity.kept_measurements(pairing.measurements, cons, paired,
                                                            choices),
                   warnings=pairing.warnings + tuple(warnings))


def choose_without_consensus(problem: Problem, pairing: Pairing) -> Pairing:
    """Every measurement kept; a single marker's pose of the two PnP gives chosen by the
    closed form (:func:`multieye.pipeline.ambiguity.closed_form_choice`)."""
    paired, meas, turns = ambiguity.closed_form_choice(pairing.paired, pairing.measurements,
                                                       problem.options.method)
    warnings = half_turns.turn_warning({n: p.observations for n, p in paired.items()}, turns,
                                       "the closed form with the motion capture")
    return replace(pairing, paired=paired, measurements=meas,
                   warnings=pairing.warnings + warnings)


def _consensus(meas: Measurements, warnings: list[str], labels=None, alternatives=None):
    """RANSAC over measurements with fixed thresholds (never thresholds taken from a fit
    that the outliers themselves pulled); wider ones once if the data are noisier."""
    for k, (rot, trans) in enumerate(CONSENSUS_THRESHOLDS):
        try:
            return consensus(meas, threshold_rot_deg=rot, threshold_trans_m=trans, labels=labels,
                             B_alternative=alternatives)
        except TooFewMeasurementsError as exc:
            if k + 1 == len(CONSENSUS_THRESHOLDS):
                raise TooFewMeasurementsError(
                    f"{exc} (consensus thresholds up to {rot:g} deg / {trans:g} m); if the data "
                    "are this noisy, run with --no-robust and check the residuals") from None
            warnings.append(f"consensus: {exc}; retried with {CONSENSUS_THRESHOLDS[k + 1][0]:g} "
                            f"deg / {CONSENSUS_THRESHOLDS[k + 1][1]:g} m")


def _keep(p: PairedCamera, mask: np.ndarray, reasons: dict[int, str]) -> PairedCamera:
    rejected = p.rejected + tuple(RejectedItem(p.observations[i].name, reasons[i])
                                  for i in sorted(reasons))
    idx = np.flatnonzero(mask)
    scale = None if p.mocap_noise_scale is None else p.mocap_noise_scale[idx]
    return PairedCamera(name=p.name, A=p.A[idx], B=p.B[idx], T_world_mocap=p.T_world_mocap[idx],
                        observations=tuple(p.observations[i] for i in idx), rejected=rejected,
                        mocap_noise_scale=scale)


def solve_closed_form(problem: Problem, pairing: Pairing, check: Callable[[], Plausibility]
                      ) -> ClosedForm:
    """The closed form on the measurements kept, and their motion diagnostics; a failing
    solve says the likely cause the plausibility checks find, if any."""
    motion = motion_diagnostics(pairing.measurements, setup=problem.setup)
    try:
        sol = solve(pairing.measurements, method=problem.options.method)
    except CalibrationError as exc:
        raise _failed(exc, check) from None
    return ClosedForm(solution=sol, motion=motion)


def check_pairing(problem: Problem, pairing: Pairing) -> Plausibility:
    """The plausibility checks on the pairing's measurements (the kept ones; every one when
    a stage failed), with the motion-capture noise rig.yaml states."""
    rig, opts = problem.rig, problem.options
    evidence = [_evidence(problem.cameras[n], p, pairing.offsets[n])
                for n, p in pairing.paired.items()]
    spec, rot, trans = mocap_noise(rig, pairing.paired, opts)
    declared = Declared(setup=rig.setup,
                        spacing_m=None if rig.target is None else rig.target.spacing, mocap=spec,
                        target_kind=None if rig.target is None else rig.target.type,
                        mocap_unit=(spec.unit if spec is not None else None) or "m",
                        mocap_pose=None if spec is None else spec.pose,
                        mocap_frames=None if spec is None else spec.frames,
                        mocap_format="tum" if spec is None else spec.format)
    return check_plausibility(evidence, declared=declared, mocap_rot_sigma_rad=rot,
                              mocap_trans_sigma_m=trans, clock=opts.time_offset != "auto",
                              max_time_offset_s=opts.max_time_offset)


def _evidence(d: CameraData, p: PairedCamera, offset: float) -> CameraEvidence:
    obs = p.observations
    points = (d.intrinsics is not None and bool(obs)
              and all(o.image_points is not None and o.object_points is not None
                      and o.rms_px is not None for o in obs))
    return CameraEvidence(
        name=p.name, A=p.A, B=p.B, T_world_mocap=p.T_world_mocap,
        stamps=None if d.by_name else np.array([o.stamp for o in obs]),
        intrinsics=d.intrinsics,
        object_points=tuple(o.object_points for o in obs) if points else None,
        image_points=tuple(o.image_points for o in obs) if points else None,
        rms_px=np.array([o.rms_px for o in obs]) if points else None,
        mocap_stamps=d.mocap.stamps, mocap_T=d.mocap.T, time_offset=offset,
        intrinsics_estimated=d.intrinsics_estimated)


def check_refined(problem: Problem, pairing: Pairing, solved: Plausibility, refined: Refined
                  ) -> Plausibility:
    """``solved`` with the motion-capture noise the refinement estimated checked against what
    the sensor has (issue 20); ``solved`` itself without a refinement."""
    if refined.refinement is None:
        return solved
    solved = check_determined(solved, _pose_spread(problem, pairing, refined.refinement),
                              SETUP_KEYS[problem.setup][1])
    if not isinstance(refined.refinement.result, RefinementResult):
        return solved               # only the image-level refinement estimates the noise
    return check_noise(solved, refined.refinement.result,
                       mocap_noise(problem.rig, pairing.paired, problem.options)[0])


def _pose_spread(problem: Problem, pairing: Pairing, refinement: Refinement):
    """Per camera (name, std_rot_deg, std_trans_m, median distance to the target in metres,
    measurements) of its refined pose X, for :func:`check_determined`."""
    out = []
    if refinement.covariance is None:
        return out
    for j, (name, p) in enumerate(pairing.paired.items()):
        rot, trans = pose_std(refinement.covariance[6 * j:6 * j + 6, 6 * j:6 * j + 6])
        dist = float(np.median(np.linalg.norm(np.asarray(p.B)[:, :3, 3], axis=1)))
        out.append((name, float(rot), float(trans), dist, len(p.B)))
    return out


def _failed(exc: CalibrationError, check: Callable[[], Plausibility]) -> CalibrationError:
    """``exc`` (no result) with the likely cause the plausibility checks find first, if any."""
    found = check()
    if not found.findings:
        return exc
    return type(exc)(f"{'; '.join(found.messages)} (so the calibration failed: {exc})")


def summarise(problem: Problem, pairing: Pairing, closed: ClosedForm, checks: Checks,
              refined: Refined) -> CalibrationRun:
    """The run: the record of the final result (refined when the refinement ran), the
    warnings of every stage in their order, and, for estimated lenses, the refined lenses
    and the target poses refitted with them."""
    refinement = refined.refinement
    estimated = {} if refinement is None else refinement.intrinsics
    cameras = problem.cameras
    warnings = [*pairing.warnings, *closed.motion.warnings, *checks.solved.messages,
                *refined.warnings]
    warnings.extend(m for m in checks.final.messages if m not in warnings)
    unrefined = [n for n, d in cameras.items() if d.intrinsics_estimated and n not in estimated]
    if unrefined:
        warnings.append(f"{', '.join(unrefined)}: the intrinsics are OpenCV's per-camera "
                        "calibration only, since the joint image-level refinement did not run "
                        "(it needs refinement and target points in every camera)")
    # estimated lenses: the target poses of the final result are those of the final lens
    final = replace(pairing, paired={
        n: refit_paired(p, estimated[n]) if cameras[n].intrinsics_estimated and n in estimated
        else p for n, p in pairing.paired.items()})
    record = build_record(problem, final, closed, checks.final, refined, warnings)
    cameras = {n: replace(d, selection=merged(d.selection, pairing.selection[n]))
               if n in pairing.selection else d for n, d in cameras.items()}
    cameras = {n: camera_data_now(d, final.paired[n].observations) if n in final.paired
               and d.bad_fits else d for n, d in cameras.items()}     # bad fits taken back
    return CalibrationRun(rig=problem.rig, record=record, closed_form=closed.solution,
                          cameras={n: replace(d, intrinsics=estimated.get(n, d.intrinsics))
                                   for n, d in cameras.items()} if estimated else cameras,
                          paired=final.paired, refinement=refinement,
                          plausibility=checks.final)
