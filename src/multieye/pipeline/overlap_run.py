"""A rig without motion capture, from the problem to the run the writers take (issue 23).

:func:`calibrate_overlap` runs :func:`multieye.pipeline.overlap.solve_overlap` on the problem
and states the result as every run is stated (:class:`~multieye.pipeline.result.CalibrationRun`
with its :class:`~multieye.io.CalibrationRecord`, setup ``overlap``: docs/outputs.md,
section 2).  The evidence is laid out as the writers already read it, in the reference
camera's frame: per camera ``X = T_ref_cam``, ``Y`` the identity, and per image the "motion
capture" ``M_i = T_ref_target`` of its instant, so that ``A_i = inv(M_i)``, ``B_i =
inv(T_cam_target_i)`` and the loop ``A_i X = Y B_i`` is each image's PnP pose against the
solution's ``inv(T_ref_cam) @ T_ref_target``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import DatasetError
from multieye.core.metrics import camera_residual
from multieye.estimate.findings import Plausibility
from multieye.estimate.plausibility import CameraEvidence, given_lens_findings, target_size_findings
from multieye.estimate.uncertainty import pose_std, projection_std
from multieye.core.lens_curve import observed_curve
from multieye.io import (
    BoardRecord,
    CalibrationRecord,
    CameraRecord,
    IntrinsicsRecord,
    PlausibilityItem,
    PoseUncertainty,
    Residuals,
)
from multieye.io.calibration_json import OVERLAP, CameraLinks
from multieye.imaging.targets import target_from_spec
from multieye.pipeline.camera_data import PairedCamera
from multieye.pipeline.image_acceptance import camera_data_now
from multieye.pipeline.overlap import OverlapSolution, solve_overlap
from multieye.pipeline.overlap_mocap import (eye_on_hand_layout, has_mocap, rig_mocap,
                                           with_mocap)
from multieye.pipeline.overlap_motion import MotionSolution, board_order, solve_motion
from multieye.pipeline.record import lens_parameter_warnings, lens_view_points
from multieye.pipeline.recordings import camera_warnings
from multieye.pipeline.problem import Problem
from multieye.pipeline.result import CalibrationRun, Refinement

__all__ = ["calibrate_overlap", "check_overlap_options", "OverlapImages", "METHOD",
           "MOTION_METHOD"]

#: ``method`` of a rig without motion capture: the start from the co-visibility graph.
METHOD = "covisibility"
#: ... with several boards: the start from the loops the views close and the joint hand-eye
#: problem with the rig's own motion (:mod:`multieye.estimate.motion_links`).
MOTION_METHOD = "motion-links"


@dataclass(frozen=True)
class OverlapImages:
    """The refined rig in the per-camera layout the image-level writers read
    (:func:`multieye.outputs.details.image_points`): ``X[j] = T_ref_cam``, ``Y`` the identity,
    ``T_world_mocap[j][i] = T_ref_target`` of image i's instant, the final lenses; and the
    solution itself."""

    X: np.ndarray
    Y: np.ndarray
    T_world_mocap: tuple
    intrinsics: tuple
    solution: OverlapSolution


def check_overlap_options(problem: Problem) -> Problem:
    """The problem, once its options are checked against a rig without motion capture.

    Raises
    ------
    DatasetError
        Options that need motion capture (``time_offset="auto"``, a closed-form ``method``
        other than the default) or the refinement turned off (it is the solve here).
    """
    opts, where = problem.options, problem.rig.path
    if opts.time_offset == "auto":
        raise DatasetError("--time-offset auto estimates each camera's clock against the "
                           "motion capture, which this rig has none of; give each camera's "
                           "time_offset in rig.yaml", path=where)
    if not opts.refine:
        raise DatasetError("--no-refine: a rig without motion capture has no closed form; it "
                           "is solved by the refinement on the views its cameras share",
                           path=where)
    if opts.method != "joint":
        raise DatasetError(f"--method {opts.method}: the hand-eye solvers need motion "
                           "capture; a rig without it is started from the views its cameras "
                           "share", path=where)
    return problem


def calibrate_overlap(problem: Problem) -> CalibrationRun:
    """Calibrate a rig without motion capture (module docstring).

    Raises
    ------
    DatasetError, DisconnectedError
        As :func:`multieye.pipeline.overlap.solve_overlap`.
    """
    declared = tuple(getattr(problem.rig, "targets", None) or ())
    mocap = has_mocap(problem)          # the rig's motion capture too (issue 34, item 1)
    if len(board_order(problem.cameras, declared)) > 1:      # linked by motion too (issue 34)
        sol = solve_motion(problem.cameras, problem.reference,
                           sync_tolerance=problem.rig.sync_tolerance, sync=problem.rig.sync,
                           robust=problem.options.robust, boards=declared,
                           mocap=(lambda inst: rig_mocap(problem, inst)) if mocap else None,
                           poses=given_poses(problem.rig))
        M = tuple(sol.T_ref_target(n) for n in sol.names)
    else:
        sol = solve_overlap(problem.cameras, problem.reference,
                            sync_tolerance=problem.rig.sync_tolerance, sync=problem.rig.sync,
                            robust=problem.options.robust)
        M = tuple(sol.result.T_ref_target[sol.instants[n]] for n in sol.names)
    res = sol.result
    names = sol.names
    paired = {n: PairedCamera(
        name=n, A=g.inv(M[j]), T_world_mocap=M[j],
        B=g.inv(np.stack([o.T_cam_target for o in sol.used[n]])),
        observations=tuple(sol.used[n]),
        rejected=getattr(sol, "rejected", {}).get(n, problem.cameras[n].rejected))
        for j, n in enumerate(names)}
    lens = given_lens_findings([_evidence(problem.cameras[n], paired[n]) for n in names
                                if not problem.cameras[n].intrinsics_estimated],
                               alone=len(names) == 1 and not mocap)
    # the scale reaches the result through the cameras' translations only: one camera's
    # lens does not depend on it (boofcv_fisheye's squares are "1 unit")
    size = () if len(names) < 2 or any(d.mocap is not None for d in problem.cameras.values()) \
        else target_size_findings(_spacings(problem.rig))
    sol = replace(sol, findings=tuple(sol.findings) + lens + size)
    estimated = {n: res.intrinsics[j] for j, n in enumerate(names)
                 if problem.cameras[n].intrinsics_estimated}
    rms = _camera_rms(sol)
    refinement = Refinement(
        kind="images", X=res.T_ref_cam, Y=np.eye(4), covariance=None,
        reprojection_rms_px=rms, warnings=(),
        result=OverlapImages(res.T_ref_cam, np.eye(4), M, res.intrinsics, sol),
        intrinsics=estimated,
        intrinsics_covariance={n: res.intrinsics_covariance[j] for j, n in enumerate(names)
                               if problem.cameras[n].intrinsics_estimated})
    plaus = Plausibility(findings=sol.findings, cost=float("nan"), camera_cost={},
                         tested=("fit", "intrinsics", "scale")
                         + (("observability",) if _by_motion(sol) else ())
                         + (("given-pose",) if getattr(sol, "given", ()) else ()))
    warnings = camera_warnings(problem.cameras)
    warnings += sol.warnings + tuple(f.message for f in sol.findings)
    record = _record(problem, sol, paired, rms, warnings)
    if mocap:
        if not _by_motion(sol):
            raise DatasetError("motion capture with several targets: the images show only "
                               "one of them; give that one as rig.yaml's target:",
                               path=problem.rig.path)
        record = with_mocap(record, sol, problem)
        paired, refinement = eye_on_hand_layout(paired, refinement, sol)
    judged = getattr(sol, "rejected", {})            # images judged on the refined lens
    cameras = {n: replace(camera_data_now(d, sol.used[n], judged[n]) if n in judged else d,
                          intrinsics=estimated.get(n, d.intrinsics))
               for n, d in problem.cameras.items()}
    return CalibrationRun(rig=problem.rig, record=record, closed_form=None, cameras=cameras,
                          paired=paired, refinement=refinement, plausibility=plaus)


def _spacings(rig) -> dict[str, float]:
    """Each board's square (or marker) side, metres, by name (rig.yaml's ``targets``, or its
    one ``target``; specs or their mappings)."""
    boards = getattr(rig, "targets", None) or {"target": getattr(rig, "target", None)}
    out = {}
    for name, spec in boards.items():
        if isinstance(spec, dict):
            side = spec.get("spacing", spec.get("marker_size"))
        else:
            side = getattr(spec, "spacing", None)
        if side is not None:
            out[name] = float(side)
    return out


def given_poses(rig) -> dict[str, np.ndarray]:
    """rig.yaml's given board poses (``targets: ... pose:``, in the first board's frame) by
    board name."""
    return {name: np.array(spec.pose, dtype=np.float64)
            for name, spec in (getattr(rig, "targets", None) or {}).items()
            if getattr(spec, "pose", None) is not None}


def _evidence(data, p: PairedCamera) -> CameraEvidence:
    """A camera's views as the lens check reads them (:func:`multieye.estimate.plausibility.
    given_lens_findings`): its points and PnP RMS with the given lens."""
    obs = p.observations
    points = all(o.image_points is not None and o.object_points is not None
                 and o.rms_px is not None for o in obs)
    return CameraEvidence(
        name=p.name, A=p.A, B=p.B, T_world_mocap=p.T_world_mocap, intrinsics=data.intrinsics,
        object_points=tuple(o.object_points for o in obs) if points else None,
        image_points=tuple(o.image_points for o in obs) if points else None,
        rms_px=np.array([o.rms_px for o in obs]) if points else None,
        intrinsics_estimated=data.intrinsics_estimated)


def _by_motion(sol) -> bool:
    return isinstance(sol, MotionSolution)


def _targets(sol, problem: Problem) -> dict | None:
    """Every board's pose in the world (the first board) with its uncertainty, views and
    pattern's outline, by name (docs/outputs.md, several boards)."""
    if not _by_motion(sol):
        return None
    res = sol.result
    out = {}
    for k, b in enumerate(sol.boards):
        per = {n: int(np.sum(sol.board[n] == k)) for n in sol.names}
        per = {n: v for n, v in per.items() if v}
        # the targets built once (RigModel); a rig given from Python may not describe the board
        board = (problem.model.targets.get(b) if problem.model is not None else None)
        if board is None and b in (problem.rig.targets or {}):
            board = target_from_spec(problem.rig.targets[b])
        given = b in sol.given                  # held at rig.yaml's pose: no covariance
        out[b] = BoardRecord(res.T_world_board[k], given, sum(per.values()), per,
                             None if given else _pose_uncertainty(res.board_covariance[k]),
                             None if board is None else board.bounds(),
                             True if board is None else bool(board.z_into_board))
    return out


def _camera_rms(sol: OverlapSolution) -> dict[str, float]:
    res = sol.result
    return {n: float(res.camera_rms_px[j]) for j, n in enumerate(sol.names)}


def _pose_uncertainty(cov: np.ndarray) -> PoseUncertainty:
    rot, trans = pose_std(cov)
    return PoseUncertainty(float(rot), float(trans), cov)


def _record(problem: Problem, sol: OverlapSolution, paired: dict, rms: dict,
            warnings: tuple[str, ...]) -> CalibrationRecord:
    res = sol.result
    cams, rot_all, trans_all = [], [], []
    for j, n in enumerate(sol.names):
        p = paired[n]
        r = camera_residual(p.A, p.B, res.T_ref_cam[j], np.eye(4))
        rot_all.append(r.e_R_deg * r.n)
        trans_all.append(r.e_t_m * r.n)
        unc = _pose_uncertainty(res.covariance[j])
        cams.append(CameraRecord(
            name=n, X=None, T_ref_cam=res.T_ref_cam[j], measurements_used=r.n,
            residuals=Residuals(e_R_deg=r.e_R_deg, e_t_m=r.e_t_m, max_R_deg=r.max_R_deg,
                                max_t_m=r.max_t_m, reprojection_rms_px=rms[n]),
            std_rot_deg=unc.std_rot_deg, std_trans_m=unc.std_trans_m,
            covariance=res.covariance[j], rejected=p.rejected,
            intrinsics=_intrinsics_record(problem, sol, j, p),
            uncertainty={"T_ref_cam": unc},
            links=CameraLinks(dict(sol.links[n].overlap), False, sol.links[n].motion,
                              sol.links[n].boards)))
    used = sum(c.measurements_used for c in cams)
    return CalibrationRecord(
        setup=OVERLAP, method=MOTION_METHOD if _by_motion(sol) else METHOD,
        reference_camera=problem.reference, Y=None, targets=_targets(sol, problem),
        cameras=tuple(cams),
        residuals=Residuals(e_R_deg=sum(rot_all) / used, e_t_m=sum(trans_all) / used),
        warnings=warnings + lens_parameter_warnings(cams), refinement="images",
        plausibility=tuple(PlausibilityItem(f.cause, f.message, f.camera)
                           for f in sol.findings))


def _intrinsics_record(problem: Problem, sol: OverlapSolution, j: int, p: PairedCamera
                       ) -> IntrinsicsRecord:
    """The camera's final lens, whether it was estimated, its covariance and the projection's
    standard deviation over the target points (in the solution's target poses)."""
    res, name = sol.result, sol.names[j]
    data = problem.cameras[name]
    intr = res.intrinsics[j]
    cov = res.intrinsics_covariance[j]
    proj = curve = None
    if cov is not None:
        T = g.inv(res.T_ref_cam[j]) @ p.T_world_mocap
        pts = np.concatenate([o.object_points @ Tc[:3, :3].T + Tc[:3, 3]
                              for o, Tc in zip(p.observations, T)])
        proj = projection_std(intr, cov, pts)
        curve = observed_curve(intr, cov, np.concatenate([pts, *lens_view_points(data)]))
    return IntrinsicsRecord(intr, data.intrinsics_estimated, cov, proj, curve)
