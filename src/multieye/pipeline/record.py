"""The result of a calibration as calibration.json states it (:class:`CalibrationRecord`).

The final transforms (the refinement's when it ran, else the closed form's), the loop and
reprojection residuals, per camera the uncertainty of ``X`` and of ``T_ref_cam``, its
intrinsics (estimated or given, with their uncertainty), and the uncertainty of ``Y``.
"""

from __future__ import annotations

import numpy as np

from multieye.core.metrics import camera_residual, relative_extrinsics
from multieye.estimate.uncertainty import pose_std, projection_std
from multieye.io import (
    CalibrationRecord,
    CameraRecord,
    IntrinsicsRecord,
    PlausibilityItem,
    PoseUncertainty,
    Residuals,
    Rig,
)
from multieye.io.calibration_json import SETUP_KEYS
from multieye.pipeline.camera_data import CameraData, PairedCamera
from multieye.solvers import Solution

__all__ = ["build_record"]


def build_record(rig: Rig, paired: dict[str, PairedCamera], sol: Solution,
            refinement, unc, *, method: str, reference: str,
            warnings: list[str], time_offsets: dict[str, float], motion: dict,
            doubts: tuple[PlausibilityItem, ...] = (),
            cameras: dict[str, CameraData] | None = None,
            time_offset_std: dict[str, float] | None = None) -> CalibrationRecord:
    """The record of the final result: the refinement's when it ran, else the closed form.

    ``unc`` is the :class:`~multieye.estimate.uncertainty.RelativeUncertainty` of the
    refinement, or None; ``time_offset_std`` the standard deviation of each clock offset
    estimated in the joint problem.
    """
    final = sol if refinement is None else refinement
    X, Y = final.X, final.Y
    reproj = {} if refinement is None else refinement.reprojection_rms_px
    names = list(paired)
    T_ref_cam = relative_extrinsics(X, reference=names.index(reference))
    cams, rot_all, trans_all = [], [], []
    for j, name in enumerate(names):
        p = paired[name]
        r = camera_residual(p.A, p.B, X[j], Y)
        rot_all.append(r.e_R_deg * r.n)
        trans_all.append(r.e_t_m * r.n)
        rms = [o.rms_px for o in p.observations if o.rms_px is not None]
        reproj_px = reproj.get(name, float(np.sqrt(np.mean(np.square(rms)))) if rms else None)
        cams.append(CameraRecord(
            name=name, X=X[j], T_ref_cam=T_ref_cam[j], measurements_used=r.n,
            residuals=Residuals(e_R_deg=r.e_R_deg, e_t_m=r.e_t_m, max_R_deg=r.max_R_deg,
                                max_t_m=r.max_t_m, reprojection_rms_px=reproj_px),
            time_offset_s=time_offsets.get(name),
            time_offset_std_s=(time_offset_std or {}).get(name),
            std_rot_deg=None if unc is None else float(unc.std_rot_deg[j]),
            std_trans_m=None if unc is None else float(unc.std_trans_m[j]),
            covariance=None if unc is None else unc.covariance[j],
            rejected=p.rejected,
            intrinsics=_intrinsics_record(name, p, cameras, refinement),
            uncertainty=None if unc is None else {
                SETUP_KEYS[rig.setup][1]: _pose_uncertainty(
                    refinement.covariance[6 * j:6 * j + 6, 6 * j:6 * j + 6]),
                "T_ref_cam": _pose_uncertainty(unc.covariance[j])}))
    n = sum(c.measurements_used for c in cams)
    return CalibrationRecord(setup=rig.setup, method=method, reference_camera=reference, Y=Y,
                             cameras=tuple(cams),
                             residuals=Residuals(e_R_deg=sum(rot_all) / n, e_t_m=sum(trans_all) / n),
                             warnings=tuple(warnings),
                             refinement=None if refinement is None else refinement.kind,
                             motion_diagnostics=motion, plausibility=doubts,
                             uncertainty=None if unc is None else {
                                 SETUP_KEYS[rig.setup][0]: _pose_uncertainty(
                                     refinement.covariance[-6:, -6:])},
                             frames=rig.frames)


def _pose_uncertainty(cov: np.ndarray) -> PoseUncertainty:
    rot, trans = pose_std(cov)
    return PoseUncertainty(float(rot), float(trans), cov)


def _intrinsics_record(name: str, paired: PairedCamera, cameras, refinement
                       ) -> IntrinsicsRecord | None:
    """The camera's final intrinsics, whether they were estimated, and their uncertainty."""
    data = None if cameras is None else cameras.get(name)
    if data is None or data.intrinsics is None:
        return None
    refined = {} if refinement is None else refinement.intrinsics
    intr = refined.get(name, data.intrinsics)
    cov = None if refinement is None else refinement.intrinsics_covariance.get(name)
    proj = None
    if cov is not None:
        pts = [o.object_points @ o.T_cam_target[:3, :3].T + o.T_cam_target[:3, 3]
               for o in paired.observations if o.object_points is not None]
        if pts:
            proj = projection_std(intr, cov, np.concatenate(pts))
    return IntrinsicsRecord(intr, data.intrinsics_estimated, cov, proj)
