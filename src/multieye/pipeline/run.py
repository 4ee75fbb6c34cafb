"""From a dataset folder to rig extrinsics: the paper's Fig. 3 pipeline.

``rig.yaml`` -> per camera: images -> detection -> PnP (or precomputed ``T_cam_target``) ->
pairing with motion capture in time -> ``A``, ``B`` (:mod:`multieye.pipeline.camera_data`) ->
clock offsets, consensus, :func:`multieye.solve`, plausibility checks, refinement ->
:class:`~multieye.io.CalibrationRecord` and the files written from it.

Synopsis
--------
>>> from multieye.pipeline import calibrate
>>> from multieye.outputs.write import write_outputs
>>> run = calibrate("dataset/rig.yaml", method="joint")   # doctest: +SKIP
>>> write_outputs(run, "out")                              # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field, replace

import numpy as np

from multieye.pipeline.camera_data import (CameraData, Observation, PairedCamera, check_options,
                                           load_camera_data, pair_camera, updated_options)
from multieye.core.arguments import as_path
from multieye.core.errors import CalibrationError, DatasetError, InputError, TooFewMeasurementsError
from multieye.io import CalibrationRecord, PlausibilityItem, RejectedItem, Rig, load_rig
from multieye.pipeline.sources import outside_reads
from multieye.io.run_details import StageTimings
from multieye.solvers import Solution, solve
from multieye.solvers.checks import Measurements, check_measurements
from multieye.pipeline.record import build_record
from multieye.pipeline import ambiguity   # single markers: the rig chooses each image's pose

__all__ = [
    "Observation",
    "CameraData",
    "PairedCamera",
    "CalibrationRun",
    "Options",
    "Refinement",
    "StageTimings",
    "load_camera_data",
    "pair_camera",
    "calibrate",
    "calibrate_rig",
]


@dataclass(frozen=True)
class Refinement:
    """What the maximum-likelihood refinement after the closed form gave.

    Attributes
    ----------
    kind : {"images", "poses"}
        On the target points and motion-capture poses, or on the pose residuals.
    X : ndarray, shape (m, 4, 4)
    Y : ndarray, shape (4, 4)
    covariance : ndarray, shape (6(m+1), 6(m+1)), or None
        Of the perturbations of X^1..X^m then Y (rotation vector, translation; radians,
        metres).
    reprojection_rms_px : dict of str to float
        Per camera, from the refined rig (image refinement only).
    warnings : tuple of str
    result : RefinementResult or Solution
        The refinement's own result: :class:`multieye.estimate.refine_images.RefinementResult`
        on images, a refined :class:`~multieye.solvers.Solution` on poses.
    intrinsics : dict of str to Intrinsics
        Per camera whose intrinsics were estimated: the refined lens (image refinement only).
    intrinsics_covariance : dict of str to ndarray
        Their covariance over ``Intrinsics.params`` (fx fy cx cy, then the distortion).
    """

    kind: str
    X: np.ndarray
    Y: np.ndarray
    covariance: np.ndarray | None
    reprojection_rms_px: dict[str, float]
    warnings: tuple[str, ...]
    result: object
    intrinsics: dict = field(default_factory=dict)
    intrinsics_covariance: dict = field(default_factory=dict)


@dataclass(frozen=True)
class CalibrationRun:
    """Everything a calibration produced, for writers, reports and Python users.

    The final result (refined when the refinement ran, else the closed form) is ``X``,
    ``Y``, ``T_ref_cam`` and ``covariance``; the closed form stays on ``closed_form``.

    Attributes
    ----------
    rig : Rig
    record : CalibrationRecord
        The final result as written to ``calibration.json``.
    closed_form : Solution
        The closed form on the measurements kept (``closed_form.X``, ``closed_form.Y``).
    cameras : dict of str to CameraData
    paired : dict of str to PairedCamera
        The measurements kept, per camera.
    refinement : Refinement or None
        The refinement, when it ran and succeeded; its own result (a
        :class:`multieye.estimate.refine_images.RefinementResult` on images, a refined
        :class:`~multieye.solvers.Solution` on poses) is ``refinement.result``.
    timings : StageTimings
        Seconds per stage; ``reading`` and ``detection`` are 0 when the cameras were loaded
        outside :func:`calibrate`; ``outputs`` is 0: writing the files adds it to the
        timings written into ``details.json`` (``multieye.outputs.write.write_outputs``).
    plausibility : Plausibility or None
        The plausibility checks after the solve
        (:func:`multieye.estimate.plausibility.check_plausibility`); ``doubts`` lists its
        findings.
    doubts : tuple of Finding
        What the plausibility checks doubt, each with its cause and message (also in
        ``record.warnings`` and ``record.plausibility``); empty when nothing is doubted.  The
        command line exits with status 3 when it is not empty.
    X : ndarray, shape (m, 4, 4)
        Final ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand), cameras in the
        order of ``record.cameras``.
    Y : ndarray, shape (4, 4)
        Final ``T_marker_target`` (eye-to-base) or ``T_world_target`` (eye-on-hand).
    T_ref_cam : dict of str to ndarray, shape (4, 4)
        Final extrinsics relative to the reference camera, by camera name.
    covariance : ndarray, shape (6(m+1), 6(m+1)), or None
        Of the final X^1..X^m then Y (:attr:`Refinement.covariance`); None without
        refinement.  Per camera, the 6x6 covariance of ``T_ref_cam`` is
        ``record.cameras[j].covariance``.
    """

    rig: Rig
    record: CalibrationRecord
    closed_form: Solution
    cameras: dict[str, CameraData]
    paired: dict[str, PairedCamera]
    refinement: Refinement | None = None
    timings: StageTimings = field(default_factory=StageTimings)
    plausibility: object | None = None

    @property
    def doubts(self) -> tuple:
        return () if self.plausibility is None else self.plausibility.findings

    @property
    def X(self) -> np.ndarray:
        return np.stack([c.X for c in self.record.cameras])

    @property
    def Y(self) -> np.ndarray:
        return self.record.Y

    @property
    def T_ref_cam(self) -> dict[str, np.ndarray]:
        return {c.name: c.T_ref_cam for c in self.record.cameras}

    @property
    def covariance(self) -> np.ndarray | None:
        return None if self.refinement is None else self.refinement.covariance


@dataclass(frozen=True)
class Options:
    """How :func:`calibrate_rig` goes from measurements to the result.

    Attributes
    ----------
    method : str
        Closed-form solver (:data:`multieye.METHODS`).
    reference : str or None
        Reference camera; default the first.
    refine : bool
        Follow the closed form with the maximum-likelihood refinement: on the target points
        and motion-capture poses when every camera has images (:func:`multieye.estimate.refine_images.
        refine_images`), else on the pose residuals (:mod:`multieye.solvers.refine_poses`).  Fills the
        uncertainty.
    robust : bool
        Consensus over measurements before solving (:func:`multieye.estimate.consensus.consensus`);
        rejected measurements are listed with the reason.
    time_offset : "rig", "auto" or float
        ``"rig"``: each camera's ``time_offset`` from rig.yaml; ``"auto"``: estimated per
        camera (:func:`multieye.estimate.clock.estimate_offset`); a number: seconds for every camera.
    max_time_offset : float
        With ``time_offset="auto"``: offsets from ``-max_time_offset`` to ``+max_time_offset``
        seconds are searched (an optimum at the edge of that range is refused).
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float or None
        Motion-capture noise for the refinement; None: rig.yaml's ``rotation_noise_deg`` /
        ``translation_noise_m``, else the defaults of :mod:`multieye.estimate.refine_images`.
    """

    method: str = "joint"
    reference: str | None = None
    refine: bool = True
    robust: bool = True
    time_offset: str | float = "rig"
    max_time_offset: float = 0.5
    mocap_rot_sigma_rad: float | None = None
    mocap_trans_sigma_m: float | None = None

    def __post_init__(self):
        check_options(self)


#: An estimated motion-capture noise below this (radians, metres) is one the recording could
#: not resolve (its variance component went to zero).
_UNRESOLVED_NOISE = 1e-6

#: Smallest angular-speed correlation at which an automatic clock offset is trusted.
CLOCK_MIN_SCORE = 0.5


def _offsets(rig: Rig, cameras: dict[str, CameraData], opts: Options) -> dict[str, float]:
    if opts.time_offset == "rig":   # cameras paired by name have no clock offset
        return {n: 0.0 if d.by_name else d.time_offset for n, d in cameras.items()}
    if opts.time_offset != "auto":
        return {n: 0.0 if d.by_name else float(opts.time_offset) for n, d in cameras.items()}
    from multieye.estimate.clock import estimate_offset

    out = {}
    for name, d in cameras.items():
        if d.by_name:            # paired by name: no clock to estimate
            out[name] = 0.0
            continue
        stamps = np.array([o.stamp for o in d.observations])
        T = np.stack([o.T_cam_target for o in d.observations])
        if not (math.isfinite(opts.max_time_offset) and opts.max_time_offset > 0):
            raise InputError(f"max_time_offset must be a positive number of seconds, got "
                             f"{opts.max_time_offset!r}")
        search = (-opts.max_time_offset, opts.max_time_offset)
        try:
            est = estimate_offset(stamps, T, d.mocap.stamps, d.mocap.T, setup=rig.setup,
                                  search_s=search)
        except CalibrationError as exc:
            raise CalibrationError(f"camera {name}: clock offset could not be estimated: {exc}; "
                                   "give --time-offset SECONDS or time_offset in rig.yaml") from None
        edge = 0.02 * (search[1] - search[0])
        if not est.score >= CLOCK_MIN_SCORE:
            raise CalibrationError(
                f"camera {name}: the clock offset cannot be estimated (angular speeds of camera "
                f"and motion capture correlate at {est.score:.2f}, below {CLOCK_MIN_SCORE}): move "
                "the target faster and less uniformly, or give --time-offset SECONDS")
        if (min(est.coarse_offset_s, est.offset_s) < search[0] + edge
                or max(est.coarse_offset_s, est.offset_s) > search[1] - edge):
            raise CalibrationError(
                f"camera {name}: the best clock offset ({est.offset_s:+.3f} s) is at the edge of "
                f"the search range {search[0]:+.3g}..{search[1]:+.3g} s, so the true one is "
                "probably outside it; widen the search (--max-time-offset SECONDS) or give "
                "--time-offset SECONDS (or time_offset in rig.yaml)")
        out[name] = float(est.offset_s)
    return out


#: Inlier thresholds of the consensus (loop rotation residual, target position residual),
#: then the wider ones tried when too few measurements of a camera agree with the first.
CONSENSUS_THRESHOLDS = ((5.0, 0.05), (15.0, 0.15))


def _consensus(meas: Measurements, warnings: list[str], labels=None, alternatives=None):
    """RANSAC over measurements with fixed thresholds (never thresholds taken from a fit
    that the outliers themselves pulled); wider ones once if the data are noisier."""
    from multieye.estimate.consensus import consensus

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


def _plausibility(rig: Rig, cameras: dict[str, CameraData], paired: dict[str, PairedCamera],
                  offsets: dict[str, float], opts: Options):
    """The plausibility checks on every paired measurement (the consensus outliers too: the
    checks trim their own), with the motion-capture noise rig.yaml states."""
    from multieye.estimate.plausibility import CameraEvidence, Declared, check_plausibility

    evidence = []
    for name, p in paired.items():
        d = cameras[name]
        obs = p.observations
        points = (d.intrinsics is not None and bool(obs)
                  and all(o.image_points is not None and o.object_points is not None
                          and o.rms_px is not None for o in obs))
        evidence.append(CameraEvidence(
            name=name, A=p.A, B=p.B, T_world_mocap=p.T_world_mocap,
            stamps=None if d.by_name else np.array([o.stamp for o in obs]),
            intrinsics=d.intrinsics,
            object_points=tuple(o.object_points for o in obs) if points else None,
            image_points=tuple(o.image_points for o in obs) if points else None,
            rms_px=np.array([o.rms_px for o in obs]) if points else None,
            mocap_stamps=d.mocap.stamps, mocap_T=d.mocap.T, time_offset=offsets[name],
            intrinsics_estimated=d.intrinsics_estimated))
    spec, rot, trans = _mocap_noise(rig, paired, opts)
    declared = Declared(spacing_m=None if rig.target is None else rig.target.spacing, mocap=spec,
                        target_kind=None if rig.target is None else rig.target.type,
                        mocap_unit=(spec.unit if spec is not None else None) or "m",
                        mocap_pose=None if spec is None else spec.pose,
                        mocap_frames=None if spec is None else spec.frames,
                        mocap_format="tum" if spec is None else spec.format)
    return check_plausibility(rig.setup, evidence, declared=declared, mocap_rot_sigma_rad=rot,
                              mocap_trans_sigma_m=trans, clock=opts.time_offset != "auto",
                              max_time_offset_s=opts.max_time_offset)


def _failed(exc: CalibrationError, check) -> CalibrationError:
    """``exc`` (no result) with the likely cause the plausibility checks find first, if any."""
    found = check()
    if not found.findings:
        return exc
    return type(exc)(f"{'; '.join(found.messages)} (so the calibration failed: {exc})")


def _keep(p: PairedCamera, mask: np.ndarray, reasons: dict[int, str]) -> PairedCamera:
    rejected = p.rejected + tuple(RejectedItem(p.observations[i].name, reasons[i])
                                  for i in sorted(reasons))
    idx = np.flatnonzero(mask)
    return PairedCamera(name=p.name, A=p.A[idx], B=p.B[idx], T_world_mocap=p.T_world_mocap[idx],
                        observations=tuple(p.observations[i] for i in idx), rejected=rejected)


def calibrate_rig(rig: Rig, cameras: dict[str, CameraData], options: Options = Options(), **kw
                  ) -> CalibrationRun:
    """Pair, check, solve, refine and summarise already loaded camera data.

    Parameters
    ----------
    rig : Rig
    cameras : dict of str to CameraData
        From :func:`load_camera_data`.
    options : Options
        Or its fields as keyword arguments (``method="shah", refine=False``).
    """
    from multieye.estimate.diagnostics import motion_diagnostics
    from multieye.estimate.plausibility import check_noise

    start = time.perf_counter()
    opts = updated_options(options, kw)
    names = list(cameras)
    reference = opts.reference or names[0]
    if reference not in cameras:
        raise DatasetError(f"reference camera {reference!r} is not in rig.yaml (cameras: "
                           f"{', '.join(names)})", path=rig.path)
    offsets = _offsets(rig, cameras, opts)
    paired = {n: pair_camera(rig.setup, d, time_offset=offsets[n]) for n, d in cameras.items()}
    warnings = [w for data in cameras.values() for w in data.warnings]
    # Validated here, once: consensus, the diagnostics and the solve take them as they are.
    meas = check_measurements([p.A for p in paired.values()], [p.B for p in paired.values()],
                              names=names, per_camera_motion=False)
    def check(used=paired):      # every measurement when the consensus fails, else the kept
        return _plausibility(rig, cameras, used, offsets, opts)

    if opts.robust:
        try:
            cons = _consensus(meas, warnings,
                              [[o.name for o in p.observations] for p in paired.values()],
                              ambiguity.alternatives(paired.values()))
        except TooFewMeasurementsError as exc:   # almost nothing agrees: say why, if known
            raise _failed(exc, check) from None
        by_cam: dict[str, dict[int, str]] = {n: {} for n in names}
        for r in cons.rejected:
            by_cam[r.camera][r.index] = r.reason
        paired = {n: _keep(ambiguity.with_choice(p, cons.alternative[j]), cons.inliers[j],
                           by_cam[n]) for j, (n, p) in enumerate(paired.items())}
        meas = ambiguity.kept_measurements(meas, cons, paired)
    else:
        paired, meas = ambiguity.closed_form_choice(paired, meas, opts.method)

    motion = motion_diagnostics(meas, setup=rig.setup)
    warnings.extend(motion.warnings)
    paired_at = time.perf_counter()
    try:
        sol = solve(meas, method=opts.method)
    except CalibrationError as exc:
        raise _failed(exc, check) from None
    plausibility = check(paired)
    warnings.extend(plausibility.messages)
    solved_at = time.perf_counter()
    refinement, uncertainty = None, None
    if opts.refine:
        try:
            refinement = _refine(rig, cameras, paired, sol, opts, offsets)
        except CalibrationError as exc:
            warnings.append(f"refinement failed, the result is the closed form without "
                            f"uncertainty: {exc}")
        else:
            warnings.extend(refinement.warnings)
            plausibility = check_noise(plausibility, refinement.result,   # issue 20
                                       _mocap_noise(rig, paired, opts)[0])
            warnings.extend(m for m in plausibility.messages if m not in warnings)
            if refinement.covariance is not None:
                from multieye.estimate.uncertainty import relative_covariance

                uncertainty = relative_covariance(refinement.X, refinement.covariance,
                                                  reference=names.index(reference))
    refined_at = time.perf_counter()
    offset_std = {}
    joint = getattr(getattr(refinement, "result", None), "time_offsets", ())
    for j, name in enumerate(paired if joint else ()):
        if joint[j] is not None:      # estimated in the joint problem: that estimate
            offsets[name] = joint[j]
            offset_std[name] = refinement.result.time_offset_std_s[j]
    unrefined = [n for n, d in cameras.items() if d.intrinsics_estimated
                 and not (refinement is not None and n in refinement.intrinsics)]
    if unrefined:
        warnings.append(f"{', '.join(unrefined)}: the intrinsics are OpenCV's per-camera "
                        "calibration only, since the joint image-level refinement did not run "
                        "(it needs refinement and target points in every camera)")
    if refinement is not None and refinement.intrinsics:
        # estimated lenses: the target poses of the final result are those of the final lens
        from multieye.pipeline.intrinsics import refit_paired

        paired = {n: refit_paired(p, refinement.intrinsics[n])
                  if cameras[n].intrinsics_estimated and n in refinement.intrinsics else p
                  for n, p in paired.items()}
    shown = offsets if opts.time_offset != "rig" else {n: o for n, o in offsets.items() if o}
    record = build_record(rig, paired, sol, refinement, uncertainty, method=opts.method,
                     reference=reference, warnings=warnings, time_offsets=shown,
                     motion=motion.as_dict()["cameras"],
                     doubts=tuple(PlausibilityItem(f.cause, f.message, f.camera)
                                  for f in plausibility.findings), cameras=cameras,
                     time_offset_std=offset_std)
    timings = StageTimings(pairing=paired_at - start, closed_form=solved_at - paired_at,
                           refinement=refined_at - solved_at,
                           total=time.perf_counter() - start)
    if refinement is not None and refinement.intrinsics:
        # estimated lenses: the refined ones are the cameras' intrinsics from here on
        cameras = {n: replace(d, intrinsics=refinement.intrinsics.get(n, d.intrinsics))
                   for n, d in cameras.items()}
    return CalibrationRun(rig=rig, record=record, closed_form=sol, cameras=cameras,
                          paired=paired, refinement=refinement, timings=timings,
                          plausibility=plausibility)


def _mocap_noise(rig: Rig, paired: dict[str, PairedCamera], opts: Options):
    """The motion capture of the first paired camera and its noise per axis (radians, metres):
    the options' where given, else rig.yaml's, else None (to be estimated)."""
    first = next(iter(paired))
    spec = rig.mocap_for(first) if first in rig.cameras else rig.mocap
    rot, trans = opts.mocap_rot_sigma_rad, opts.mocap_trans_sigma_m
    if spec is not None:
        rot = spec.rot_sigma_rad if rot is None else rot
        trans = spec.trans_sigma_m if trans is None else trans
    return spec, rot, trans


def _refine(rig: Rig, cameras: dict[str, CameraData], paired: dict[str, PairedCamera],
            sol: Solution, opts: Options, offsets: dict[str, float]) -> Refinement:
    """Image-level refinement when every camera has target points, else pose-level; with
    ``time_offset="auto"`` the clock offsets (starting at ``offsets``) are unknowns of the
    image-level problem (:mod:`multieye.estimate.clock_residuals`)."""
    _, rot, trans = _mocap_noise(rig, paired, opts)
    sigmas = {k: v for k, v in (("mocap_rot_sigma_rad", rot), ("mocap_trans_sigma_m", trans))
              if v is not None}
    have_points = all(cameras[n].intrinsics is not None and p.observations
                      and all(o.image_points is not None for o in p.observations)
                      for n, p in paired.items())
    warnings = []
    if have_points:
        from multieye.estimate.refine_images import refine_images

        obs = [[(o.object_points, o.image_points, T) for o, T in zip(p.observations, p.T_world_mocap)]
               for p in paired.values()]
        intr = [cameras[n].intrinsics for n in paired]
        # Motion-capture noise not stated: refine_images estimates it, like the pixel noise,
        # from how far the refinement moves the measured poses.
        # (one of the two stated: the other takes refine_images' default)
        given = sigmas or {"mocap_rot_sigma_rad": None, "mocap_trans_sigma_m": None}
        free = [cameras[n].intrinsics_estimated for n in paired]
        views = [[(o.object_points, o.image_points, o.T_cam_target)
                  for o in cameras[n].intrinsics_views] for n in paired]
        clocks = None
        if opts.time_offset == "auto":
            from multieye.estimate.clock_residuals import ClockData, LocalTrajectory

            clocks = []
            for n, p in paired.items():
                try:
                    clock = None if cameras[n].by_name else ClockData(
                        [o.stamp for o in p.observations], cameras[n].mocap.stamps,
                        cameras[n].mocap.T, offset=offsets[n])
                    if clock is not None:
                        LocalTrajectory(clock)         # every image inside the motion capture
                except InputError as exc:
                    warnings.append(f"{n}: clock offset kept at the estimate before the solve "
                                    f"({offsets[n]:+.4f} s), not refined with the rig: {exc}")
                    clock = None
                clocks.append(clock)
            clocks = _share_clocks(list(paired), clocks, warnings)
        res = refine_images(rig.setup, obs, intr, sol.X, sol.Y, names=list(paired),
                            free_intrinsics=free, clocks=clocks,
                            intrinsics_observations=views if any(views) else None, **given)
        for family in res.undetermined:
            what = (f"{family[2:]}: the intrinsics" if family.startswith("K:")
                    else f"the {family} estimate")
            warnings.append(f"{what} include a combination of parameters this recording does "
                            "not determine (their uncertainty covers the other directions "
                            "only); add views with more tilt and nearer the image corners, or "
                            "use a lens model with fewer coefficients")
        if res.mocap_sigma_estimated:
            unresolved = [what for what, v in (("rotation", res.mocap_rot_sigma_rad),
                                               ("position", res.mocap_trans_sigma_m))
                          if v < _UNRESOLVED_NOISE]
            warnings.append(
                f"motion-capture noise estimated from the data: "
                f"{np.degrees(res.mocap_rot_sigma_rad):.3g} deg, "
                f"{res.mocap_trans_sigma_m * 1e3:.3g} mm per pose (state rotation_noise_deg and "
                "translation_noise_m under mocap in rig.yaml to fix it)"
                + (f"; in {' and '.join(unresolved)} it is too small for this recording to "
                   "tell apart from the pixel noise, which then carries it in the uncertainty"
                   if unresolved else ""))
        if not res.converged:
            warnings.append(f"refinement did not converge ({res.message}); the result may be "
                            "short of the best the data allow")
        for j, name in enumerate(paired):
            bad = np.flatnonzero(res.image_outliers[j])
            if bad.size:
                warnings.append(f"{name}: {bad.size} image(s) fit the refined rig poorly: "
                                + ", ".join(paired[name].observations[i].name for i in bad[:5])
                                + (" ..." if bad.size > 5 else ""))
        reproj = {n: float(res.camera_rms_px[j]) for j, n in enumerate(paired)}
        estimated = {n: j for j, n in enumerate(paired) if free[j]}
        return Refinement(kind="images", X=res.X, Y=res.Y, covariance=res.covariance,
                          reprojection_rms_px=reproj, warnings=tuple(warnings), result=res,
                          intrinsics={n: res.intrinsics[j] for n, j in estimated.items()},
                          intrinsics_covariance={n: res.intrinsics_covariance[j]
                                                 for n, j in estimated.items()})
    from multieye.solvers.refine_poses import refine_solution

    ref = refine_solution(sol)
    return Refinement(kind="poses", X=ref.X, Y=ref.Y, covariance=ref.covariance,
                      reprojection_rms_px={}, warnings=(), result=ref)


def _share_clocks(names: list[str], clocks: list, warnings: list[str]) -> list:
    """Cameras triggered together (equal stamps for at least half of each one's images,
    :func:`multieye.estimate.clock_residuals.shared_clocks`) on one motion capture are
    stamped by one clock: one offset for them, started at the mean of their estimates."""
    from multieye.estimate.clock_residuals import shared_clocks

    timed = [j for j, c in enumerate(clocks) if c is not None]
    for group in shared_clocks([clocks[j].image_stamps for j in timed]):
        js = [timed[k] for k in group]
        c0 = clocks[js[0]]
        if not all(np.array_equal(clocks[j].mocap_stamps, c0.mocap_stamps)
                   and np.array_equal(clocks[j].mocap_T, c0.mocap_T) for j in js):
            continue
        start = float(np.mean([clocks[j].offset for j in js]))
        for j in js:
            clocks[j] = replace(clocks[j], offset=start, shared=names[js[0]])
        warnings.append(f"{', '.join(names[j] for j in js)}: image stamps equal (triggered "
                        "together), so one clock: one time offset estimated for them")
    return clocks


def calibrate(dataset: str | os.PathLike, options: Options = Options(), *,
              processes: int | None = None, progress: bool = False, **kw) -> CalibrationRun:
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

    Returns
    -------
    CalibrationRun
        The final result as ``run.X``, ``run.Y``, ``run.T_ref_cam``, ``run.covariance``; the
        closed form as ``run.closed_form``; seconds per stage as ``run.timings``; what the
        plausibility checks doubt as ``run.doubts`` (empty when nothing).
    """
    start = time.perf_counter()
    path = as_path(dataset, "dataset (a folder with rig.yaml, or the rig.yaml)")
    if path.is_dir():
        path = path / "rig.yaml"
    rig = load_rig(path)
    cameras = load_camera_data(rig, processes=processes, progress=progress)
    loaded = time.perf_counter() - start
    run = calibrate_rig(rig, cameras, options, **kw)
    detection = sum(d.detection_s for d in cameras.values())
    timings = replace(run.timings, reading=max(loaded - detection, 0.0), detection=detection,
                      total=time.perf_counter() - start)
    record = replace(run.record, warnings=outside_reads(rig, path) + tuple(run.record.warnings))
    return replace(run, timings=timings, record=record)
