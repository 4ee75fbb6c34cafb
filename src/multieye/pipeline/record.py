"""The result of a calibration as calibration.json states it (:class:`CalibrationRecord`).

The final transforms (the refinement's when it ran, else the closed form's), the loop and
reprojection residuals, per camera the uncertainty of ``X`` and of ``T_ref_cam``, its
intrinsics (estimated or given, with their uncertainty), and the uncertainty of ``Y``.
"""

from __future__ import annotations

import numpy as np

from multieye.core.metrics import camera_residual, relative_extrinsics
from multieye.estimate.uncertainty import pose_std, projection_std
from multieye.core.lens_curve import observed_curve, undetermined_parameters
from multieye.io import (
    CalibrationRecord,
    CameraRecord,
    IntrinsicsRecord,
    PlausibilityItem,
    PoseUncertainty,
    Residuals,
)
from multieye.io.calibration_json import SETUP_KEYS
from multieye.pipeline.camera_data import CameraData, PairedCamera
from multieye.pipeline.overlap import paired_instants
from multieye.pipeline.problem import Pairing, Problem
from multieye.pipeline.refine import Refined
from multieye.pipeline.result import Refinement

__all__ = ["build_record", "lens_view_points", "lens_parameter_warnings"]


def build_record(problem: Problem, pairing: Pairing, closed, plausibility, refined: Refined,
                 warnings: list[str]) -> CalibrationRecord:
    """The record of the final result: the refinement's when it ran, else the closed form's.

    ``closed`` is the closed-form stage (:class:`multieye.pipeline.run.ClosedForm`: the
    solution and the motion diagnostics), ``plausibility`` the checks' findings.
    """
    refinement, unc = refined.refinement, refined.uncertainty
    final = closed.solution if refinement is None else refinement
    X, Y = final.X, final.Y
    reproj = {} if refinement is None else refinement.reprojection_rms_px
    names = list(pairing.paired)
    T_ref_cam = relative_extrinsics(X, reference=names.index(problem.reference))
    offsets, offset_std = _time_offsets(problem, pairing, refinement)
    x_key, y_key = SETUP_KEYS[problem.setup][1], SETUP_KEYS[problem.setup][0]
    links = paired_instants(pairing.paired, problem.cameras, pairing.offsets,
                            problem.rig.sync_tolerance)[1]
    cams, rot_all, trans_all = [], [], []
    for j, (name, p) in enumerate(pairing.paired.items()):
        r = camera_residual(p.A, p.B, X[j], Y)
        rot_all.append(r.e_R_deg * r.n)
        trans_all.append(r.e_t_m * r.n)
        rms = [o.rms_px for o in p.observations if o.rms_px is not None]
        reproj_px = reproj.get(name, float(np.sqrt(np.mean(np.square(rms)))) if rms else None)
        cams.append(CameraRecord(
            name=name, X=X[j], T_ref_cam=T_ref_cam[j], measurements_used=r.n,
            residuals=Residuals(e_R_deg=r.e_R_deg, e_t_m=r.e_t_m, max_R_deg=r.max_R_deg,
                                max_t_m=r.max_t_m, reprojection_rms_px=reproj_px),
            time_offset_s=offsets.get(name), time_offset_std_s=offset_std.get(name),
            std_rot_deg=None if unc is None else float(unc.std_rot_deg[j]),
            std_trans_m=None if unc is None else float(unc.std_trans_m[j]),
            covariance=None if unc is None else unc.covariance[j],
            rejected=p.rejected,
            intrinsics=_intrinsics_record(problem.cameras[name], p, refinement),
            uncertainty=None if unc is None else {
                x_key: _pose_uncertainty(refinement.covariance[6 * j:6 * j + 6, 6 * j:6 * j + 6]),
                "T_ref_cam": _pose_uncertainty(unc.covariance[j])},
            links=links[name]))
    n = sum(c.measurements_used for c in cams)
    return CalibrationRecord(
        setup=problem.setup, method=problem.options.method, reference_camera=problem.reference,
        Y=Y, cameras=tuple(cams),
        residuals=Residuals(e_R_deg=sum(rot_all) / n, e_t_m=sum(trans_all) / n),
        warnings=tuple(warnings) + lens_parameter_warnings(cams),
        refinement=None if refinement is None else refinement.kind,
        motion_diagnostics=closed.motion.as_dict()["cameras"],
        plausibility=tuple(PlausibilityItem(f.cause, f.message, f.camera)
                           for f in plausibility.findings),
        uncertainty=None if unc is None else {
            y_key: _pose_uncertainty(refinement.covariance[-6:, -6:])},
        frames=problem.rig.frames)


def _time_offsets(problem: Problem, pairing: Pairing, refinement: Refinement | None
                  ) -> tuple[dict[str, float], dict[str, float]]:
    """Per camera, the clock offset shown (those estimated in the joint refinement replace the
    ones paired with; with ``time_offset="rig"`` only those not zero) and, where estimated
    in the joint refinement, its standard deviation."""
    joint = {} if refinement is None else refinement.time_offsets
    offsets = pairing.offsets | joint
    if problem.options.time_offset == "rig":
        offsets = {n: o for n, o in offsets.items() if o}
    return offsets, {} if refinement is None else dict(refinement.time_offset_std)


def _pose_uncertainty(cov: np.ndarray) -> PoseUncertainty:
    rot, trans = pose_std(cov)
    return PoseUncertainty(float(rot), float(trans), cov)


def lens_view_points(data: CameraData) -> list[np.ndarray]:
    """The target points of the camera's ``intrinsics_images`` in its frame (their starting
    poses), (n, 3) each: with the observations' they set the field the lens' curve is
    stated over (:func:`multieye.core.lens_curve.observed_curve`)."""
    return [o.object_points @ o.T_cam_target[:3, :3].T + o.T_cam_target[:3, 3]
            for o in data.intrinsics_views if o.object_points is not None]


def _intrinsics_record(data: CameraData, paired: PairedCamera, refinement: Refinement | None
                       ) -> IntrinsicsRecord | None:
    """The camera's final intrinsics, whether they were estimated, and their uncertainty."""
    if data.intrinsics is None:
        return None
    refined = {} if refinement is None else refinement.intrinsics
    intr = refined.get(data.name, data.intrinsics)
    cov = None if refinement is None else refinement.intrinsics_covariance.get(data.name)
    proj = curve = None
    if cov is not None:
        pts = [o.object_points @ o.T_cam_target[:3, :3].T + o.T_cam_target[:3, 3]
               for o in paired.observations if o.object_points is not None]
        if pts:
            proj = projection_std(intr, cov, np.concatenate(pts))
            curve = observed_curve(intr, cov, np.concatenate(pts + lens_view_points(data)))
    return IntrinsicsRecord(intr, data.intrinsics_estimated, cov, proj, curve)


def lens_parameter_warnings(cameras) -> tuple[str, ...]:
    """Per camera whose estimated lens has parameters the views do not determine one by one
    (:func:`multieye.core.lens_curve.undetermined_parameters`: a double sphere with ``xi``
    near 0 on ``boofcv_fisheye``, ``fx 189 +- 3.8e+04``), a warning naming them: their
    ``+-`` are true but say nothing of the lens, whose projection is determined (its std,
    and calibration.json's ``lens_curve``)."""
    out = []
    for cam in cameras:
        rec = cam.intrinsics
        if rec is None or not rec.estimated or rec.covariance is None:
            continue
        loose = undetermined_parameters(rec.intrinsics, rec.covariance)
        if not loose:
            continue
        model = rec.intrinsics.model
        listed = ", ".join(f"{n} {v:.4g} +- {s:.2g}" for n, v, s in loose)
        proj = ("" if rec.projection_std_px is None
                else f" (projection std {rec.projection_std_px[0]:.2f} px mean)")
        fix = ("use model: eucm for parameters that compare across calibrations"
               if model in ("unified", "double-sphere") else
               "add views of the board tilted and near the edges and corners of the image")
        out.append(f"{cam.name}: the views do not determine the {model} lens' {listed} one by "
                   f"one (they trade against each other); its projection is determined{proj}, "
                   "and calibration.json's lens_curve states it with its uncertainty; " + fix)
    return tuple(out)
