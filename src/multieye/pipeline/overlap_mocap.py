"""Motion capture of a rig moved in front of several still boards (issue 34, item 1).

A rig.yaml with ``mocap:`` and several ``targets:`` is calibrated as one problem by
:func:`multieye.pipeline.overlap_run.calibrate_overlap`: the image views, the rig's motion
(:mod:`multieye.pipeline.overlap_motion`) and the motion capture of the rig
(:mod:`multieye.estimate.motion_mocap`).  This module holds what the motion capture adds:

- :func:`refuse_eye_to_base`: only eye-on-hand (the marker on the rig).  In eye-to-base the
  motion capture tracks the one moved board while the cameras stand still; boards that stand
  still too are then seen from fixed cameras and add no motion, so the problem this estimates
  (the rig moving before still boards) does not arise: refused, exit status 2.
- :func:`rig_mocap`: the motion capture at each instant, from the existing pairing
  (:func:`multieye.pipeline.camera_data.pair_camera`: interpolated at each image's stamp,
  within the camera's time tolerance and clock offset); an instant keeps the pose of the
  first camera (rig.yaml's order) paired there.  The noise is the options' or rig.yaml's, else
  the defaults of :mod:`multieye.estimate.refine_images` (held fixed, not estimated).
- :func:`with_mocap`: the record stated in the eye-on-hand contract (docs/outputs.md,
  section 2): per camera ``X = T_body_cam = inv(T_ref_body) @ T_ref_cam``, ``Y =
  T_world_target`` of the first board (``T_mocap_world``, the world being the first board),
  every board in the motion capture's frame, each with its covariance from the joint one;
  :func:`eye_on_hand_layout`: the evidence in the eye-on-hand layout the writers read.
- :func:`with_clocks`: each camera's clock offset in the record, as the images were paired
  with it (``--time-offset auto``: estimated per camera from the board it sees most and held,
  :mod:`multieye.pipeline.clock_offsets`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import DatasetError, TooFewMeasurementsError
from multieye.estimate.motion_mocap import RigMocap
from multieye.estimate.refine_images import (
    DEFAULT_MOCAP_ROT_SIGMA_RAD,
    DEFAULT_MOCAP_TRANS_SIGMA_M,
)
from multieye.estimate.uncertainty import pose_std
from multieye.io import CalibrationRecord, PoseUncertainty, Rig
from multieye.pipeline.camera_data import pair_camera
from multieye.pipeline.problem import Problem
from multieye.pipeline.refine import mocap_noise

__all__ = ["refuse_eye_to_base", "check_mocap_options", "rig_mocap", "with_mocap", "with_clocks",
           "has_mocap", "eye_on_hand_layout", "body_cam_jacobians", "board_jacobians"]

EYE_ON_HAND = "eye-on-hand"


def has_mocap(problem: Problem) -> bool:
    """Whether any camera of the problem has motion capture."""
    return any(d.mocap is not None for d in problem.cameras.values())


def refuse_eye_to_base(rig: Rig) -> None:
    """Several boards with motion capture: eye-on-hand only (module docstring).

    Raises
    ------
    DatasetError
        rig.yaml's setup is eye-to-base.
    """
    if rig.setup != EYE_ON_HAND:
        raise DatasetError(
            f"setup: {rig.setup} with {len(rig.targets)} targets: the motion capture tracks "
            "one moved board while the cameras stand still, so still boards add no motion to "
            "calibrate with; give one target (the tracked board), or put the marker on the "
            "rig (setup: eye-on-hand)", path=rig.path)


def check_mocap_options(problem: Problem) -> Problem:
    """The problem, once its options are checked against this path.

    Raises
    ------
    DatasetError
        ``--no-refine`` (the refinement is the solve) or another closed-form ``method`` (the start is the rig's
        motion's, :mod:`multieye.estimate.motion_links`).
    """
    opts, where, n = problem.options, problem.rig.path, len(problem.rig.targets)
    if not opts.refine:
        raise DatasetError(f"--no-refine: with motion capture and {n} targets the rig is "
                           "solved by the refinement on the views and the motion capture",
                           path=where)
    if opts.method != "joint":
        raise DatasetError(f"--method {opts.method}: with motion capture and {n} targets the "
                           "rig is started from its own motion before the boards", path=where)
    return problem


def rig_mocap(problem: Problem, instants: dict) -> RigMocap:
    """The motion capture of the rig at the instants the cameras' images were paired with it.

    Parameters
    ----------
    problem : Problem
    instants : dict of str to ndarray of int
        Per camera the instant of each of its observations (``problem.cameras[n]
        .observations`` order).

    Raises
    ------
    TooFewMeasurementsError
        A camera with fewer than 3 images paired, or fewer than 3 instants paired in all.
    """
    poses: dict[int, np.ndarray] = {}
    for n, d in problem.cameras.items():
        if d.mocap is None:
            continue
        # each camera's clock as :func:`~multieye.pipeline.clock_offsets.with_clock_offsets` set it
        p = pair_camera(problem.setup, d, time_offset=0.0 if d.by_name else d.time_offset)
        where = {id(o): i for i, o in enumerate(d.observations)}
        for o, T in zip(p.observations, p.T_world_mocap):
            poses.setdefault(int(instants[n][where[id(o)]]), T)
    if len(poses) < 3:
        raise TooFewMeasurementsError(f"motion capture: only {len(poses)} instants of the rig "
                                      "have a motion-capture pose; 3 or more are needed")
    _, rot, trans = mocap_noise(problem.rig, {n: None for n in problem.cameras}, problem.options)
    keys = sorted(poses)
    return RigMocap(np.array(keys, dtype=np.int64), np.stack([poses[k] for k in keys]),
                    DEFAULT_MOCAP_ROT_SIGMA_RAD if rot is None else rot,
                    DEFAULT_MOCAP_TRANS_SIGMA_M if trans is None else trans)


def body_cam_jacobians(T_rig_marker: np.ndarray, T_ref_cam: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians of ``X = inv(T_rig_marker) @ T_ref_cam`` with respect to both, (6, 6) each.

    Every pose perturbed as the engine's ``se3-left`` blocks
    (:mod:`multieye.optimize.blocks`): ``R <- Exp(phi) R``, ``t <- t + tau``, rotation then
    translation; X's perturbation likewise.
    """
    Rm, tm = T_rig_marker[:3, :3], T_rig_marker[:3, 3]
    z = np.zeros((3, 3))
    j_c = np.block([[Rm.T, z], [z, Rm.T]])
    j_m = np.block([[-Rm.T, z], [Rm.T @ g.skew(T_ref_cam[:3, 3] - tm), -Rm.T]])
    return j_m, j_c


def board_jacobians(T_mocap_world: np.ndarray, T_world_board: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians of ``T_mocap_world @ T_world_board`` with respect to both, (6, 6) each
    (perturbations as :func:`body_cam_jacobians`)."""
    Ry = T_mocap_world[:3, :3]
    z, eye = np.zeros((3, 3)), np.eye(3)
    j_y = np.block([[eye, z], [-g.skew(Ry @ T_world_board[:3, 3]), eye]])
    return j_y, np.block([[Ry, z], [z, Ry]])


def _propagated(cov: np.ndarray, offsets: dict, parts: list) -> np.ndarray:
    """``sum_a J_a C_ab J_b^T`` over the families' 6-blocks ``parts = [(family, block, J)]``
    (families absent from the covariance, e.g. the gauge's identity, left out)."""
    out = np.zeros((6, 6))
    rows = [(offsets[f] + 6 * b, J) for f, b, J in parts if f in offsets]
    for ia, Ja in rows:
        for ib, Jb in rows:
            out += Ja @ cov[ia:ia + 6, ib:ib + 6] @ Jb.T
    return out


def _uncertainty(cov: np.ndarray) -> PoseUncertainty:
    rot, trans = pose_std(cov)
    return PoseUncertainty(float(rot), float(trans), cov)


def with_mocap(record: CalibrationRecord, sol, problem: Problem) -> CalibrationRecord:
    """The record of :func:`~multieye.pipeline.overlap_run.calibrate_overlap` stated as an
    eye-on-hand calibration (module docstring); ``sol`` its
    :class:`~multieye.pipeline.overlap_motion.MotionSolution` refined with motion capture."""
    res = sol.result
    Xm, Ym = res.T_rig_marker, res.T_mocap_world
    cov, off = res.joint_covariance, res.offsets
    inv_x = g.inv(Xm)
    others = {j: b for b, j in enumerate(sol.views.others)}
    cams = []
    for j, cam in enumerate(record.cameras):
        X = inv_x @ res.T_ref_cam[j]                                  # T_body_cam
        j_m, j_c = body_cam_jacobians(Xm, res.T_ref_cam[j])
        parts = [("Xm", 0, j_m)] + ([("C", others[j], j_c)] if j in others else [])
        unc = dict(cam.uncertainty or {}) | {"T_body_cam": _uncertainty(
            _propagated(cov, off, parts))}
        links = None if cam.links is None else replace(
            cam.links, mocap=problem.cameras[cam.name].mocap is not None)
        cams.append(replace(cam, X=X, uncertainty=unc, links=links))
    targets = {}
    for k, (name, b) in enumerate((record.targets or {}).items()):
        j_y, j_w = board_jacobians(Ym, res.T_world_board[k])
        slot = int(sol.views.board_slot[k])             # -1: held (first or given)
        parts = [("Ym", 0, j_y)] + ([("W", slot, j_w)] if slot >= 0 else [])
        targets[name] = replace(b, T_world_target=Ym @ res.T_world_board[k],
                                uncertainty=_uncertainty(_propagated(cov, off, parts)))
    return replace(record, setup=problem.setup, Y=Ym, cameras=tuple(cams), targets=targets,
                   uncertainty={"T_world_target": _uncertainty(
                       _propagated(cov, off, [("Ym", 0, np.eye(6))]))},
                   frames=problem.rig.frames)


def with_clocks(record: CalibrationRecord, problem: Problem, clocks: dict,
                notes: tuple[str, ...] = ()) -> CalibrationRecord:
    """The record with each camera's clock offset as the images were paired with it
    (:func:`~multieye.pipeline.clock_offsets.with_clock_offsets`; ``clocks`` the estimated
    ones, :class:`~multieye.estimate.clock.ClockOffset` by camera): estimated ones with the
    search's standard deviation, given ones (rig.yaml's when not zero, ``--time-offset
    SECONDS``) without; ``notes`` (a camera that took another's offset) join the warnings."""
    cams = []
    for cam in record.cameras:
        d = problem.cameras[cam.name]
        if cam.name in clocks:
            cam = replace(cam, time_offset_s=float(clocks[cam.name].offset_s),
                          time_offset_std_s=float(clocks[cam.name].std_s))
        elif d.mocap is not None and not d.by_name and (
                d.time_offset or problem.options.time_offset != "rig"):
            cam = replace(cam, time_offset_s=float(d.time_offset))
        cams.append(cam)
    return replace(record, cameras=tuple(cams), warnings=tuple(record.warnings) + tuple(notes))


def eye_on_hand_layout(paired: dict, refinement, sol) -> tuple[dict, object]:
    """The paired cameras and the refinement of the reference camera's layout
    (:mod:`multieye.pipeline.overlap_run`: ``X = T_ref_cam``, ``Y = I``, ``M_i =
    T_ref_target``) in the eye-on-hand one: ``X = T_body_cam``, ``Y = T_world_target`` (the
    first board) and per view ``A_i = M_i = Y @ inv(T_ref_target_i) @ T_ref_body``: for a view
    of the first board the refined motion-capture pose of its instant, for a view of another
    board the body's pose relative to that board placed at the first board's pose, so that
    ``inv(X) @ inv(M_i) @ Y`` is the view's refined board pose (the residuals the refinement
    minimised, docs/outputs.md, section 3)."""
    res = sol.result
    Xm, Y = res.T_rig_marker, res.T_mocap_world
    X = g.inv(Xm)[None] @ res.T_ref_cam
    M = {n: Y @ g.inv(p.T_world_mocap) @ Xm for n, p in paired.items()}
    out = {n: replace(p, A=M[n], T_world_mocap=M[n]) for n, p in paired.items()}
    layout = replace(refinement.result, X=X, Y=Y,
                     T_world_mocap=tuple(M[n] for n in sol.names))
    return out, replace(refinement, X=X, Y=Y, result=layout)
