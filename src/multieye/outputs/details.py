"""``details.json`` from a calibration run: the evidence behind ``calibration.json``.

The format, its frames and its reader live in :mod:`multieye.io.run_details`; this module
collects the details from a :class:`~multieye.pipeline.CalibrationRun`: per camera also the
target points of the used images with their reprojection residuals (:func:`image_points`) and,
for estimated intrinsics, their covariance and the projection's uncertainty over the image
(:func:`projection_std_grid`).

Synopsis
--------
>>> from multieye.outputs.details import write_run_details
>>> write_run_details("out/details.json", run)          # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, unproject_points
from multieye.estimate.uncertainty import projection_std_at
from multieye.core.metrics import loop_residuals
from multieye.io.kalibr import overlaps_in_time
from multieye.io.pixel_details import MAX_POINTS, ImagePoints, ProjectionStd
from multieye.io.run_details import (
    TRAJECTORY_MARGIN_S,
    CameraDetails,
    RunDetails,
    TrajectoryDetails,
    json_value,
    write_details,
)
from multieye.pipeline import CalibrationRun

__all__ = ["run_details", "write_run_details", "image_points", "projection_std_grid"]

#: Cells across the image of the projection-uncertainty grid.
GRID_COLUMNS = 32


def _camera_index(run: CalibrationRun, name: str) -> int:
    return list(run.paired).index(name)


def image_points(run: CalibrationRun, name: str, *, max_points: int = MAX_POINTS
                 ) -> ImagePoints | None:
    """The target points of camera ``name``'s used images and their reprojection residuals.

    After the image-level refinement the residuals are the refined rig's: the points
    projected through ``inv(X) @ M_i @ Y`` (eye-to-base; ``inv(X) @ inv(M_i) @ Y`` eye-on-hand)
    with the refined motion-capture pose ``M_i`` of the image and the camera's final
    intrinsics, minus the detected pixels (the residuals the refinement minimised, in
    pixels).  Without it they are each image's PnP residuals.  Points are evenly subsampled
    to at most ``max_points`` over the camera (the per-image RMS counts every point).

    Returns None for a camera without target points (given by poses, or without intrinsics).
    """
    paired, data = run.paired[name], run.cameras[name]
    obs = paired.observations
    if (data.intrinsics is None or not obs
            or any(o.object_points is None or o.image_points is None for o in obs)):
        return None
    ref = run.refinement
    if ref is not None and ref.kind == "images":
        j = _camera_index(run, name)
        res = ref.result
        intr, X, Y, M = res.intrinsics[j], res.X[j], res.Y, res.T_world_mocap[j]
        eye_to_base = run.record.setup != "eye-on-hand"     # overlap: as eye-to-base
        X_inv = g.inv(X)
        poses = [X_inv @ (M[i] if eye_to_base else g.inv(M[i])) @ Y for i in range(len(obs))]
        source = "refined"
    else:
        intr, poses, source = data.intrinsics, [o.T_cam_target for o in obs], "pnp"
    uv, points = [], []
    for o, T in zip(obs, poses):
        P = np.asarray(o.object_points, dtype=np.float64)
        u = np.asarray(o.image_points, dtype=np.float64).reshape(-1, 2)
        ok = np.all(np.isfinite(P), axis=1) & np.all(np.isfinite(u), axis=1)
        uv.append(u[ok])
        points.append(P[ok] @ T[:3, :3].T + T[:3, 3])
    counts = np.array([len(u) for u in uv])
    # every image's points projected at once (point by point: the same numbers as image by
    # image, in a tenth of the time)
    resid = np.split(project_points(np.concatenate(points), intr) - np.concatenate(uv),
                     np.cumsum(counts)[:-1]) if counts.sum() else [np.zeros((0, 2))] * len(obs)
    rms = np.full(len(obs), np.nan)
    for i, r in enumerate(resid):
        d2 = np.sum(r ** 2, axis=1)
        if np.any(np.isfinite(d2)):
            rms[i] = float(np.sqrt(np.nanmean(d2)))
    total = int(counts.sum())
    if total > max_points:
        keep = np.unique(np.linspace(0, total - 1, max_points).round().astype(int))
        starts = np.concatenate([[0], np.cumsum(counts)])
        idx = [keep[(keep >= a) & (keep < b)] - a for a, b in zip(starts[:-1], starts[1:])]
        uv = [u[k] for u, k in zip(uv, idx)]
        resid = [r[k] for r, k in zip(resid, idx)]
    size = (intr.width, intr.height) if intr.width and intr.height else None
    return ImagePoints(source=source, image_size=size, n_points=total, uv=tuple(uv),
                       residual_px=tuple(resid), rms_px=rms)


def projection_std_grid(intrinsics: Intrinsics, covariance, *, columns: int = GRID_COLUMNS
                        ) -> ProjectionStd:
    """Standard deviation of the projection at the centres of a grid of cells over the image.

    For the camera-frame ray that a cell centre sees under ``intrinsics`` (held fixed),
    ``J = d uv / d params`` (:func:`multieye.core.lens.project_with_jacobian`, params fx fy cx
    cy then the distortion) and the value is ``sqrt(trace(J covariance J^T) / 2)``: the RMS of
    the standard deviations of u and v, pixels.  It counts the lens' uncertainty only (the
    camera's pose held fixed).  ``columns`` cells across, rows from the aspect ratio; the
    image is ``width x height`` (``2 cx + 1`` by ``2 cy + 1`` when the intrinsics do not say).
    NaN where the lens cannot be inverted.
    """
    K = intrinsics.K
    w = intrinsics.width or max(int(round(2 * K[0, 2] + 1)), 2)
    h = intrinsics.height or max(int(round(2 * K[1, 2] + 1)), 2)
    nu, nv = int(columns), max(int(round(columns * h / w)), 2)
    u = (np.arange(nu) + 0.5) * w / nu - 0.5
    v = (np.arange(nv) + 0.5) * h / nv - 0.5
    uu, vv = np.meshgrid(u, v)
    # unit rays (a wide lens's beyond 90 degrees too); NaN rows project to NaN
    rays = unproject_points(np.column_stack([uu.ravel(), vv.ravel()]), intrinsics)
    std = projection_std_at(intrinsics, covariance, rays)
    return ProjectionStd(u=u, v=v, std_px=std.reshape(nv, nu))


def _lens(run: CalibrationRun, name: str):
    """Whether camera ``name``'s intrinsics were estimated, their covariance and the
    projection grid (None, None when not estimated by the joint refinement)."""
    data = run.cameras[name]
    if data.intrinsics is None:
        return None, None, None
    ref = run.refinement
    cov = None if ref is None else ref.intrinsics_covariance.get(name)
    if cov is None:
        return bool(data.intrinsics_estimated), None, None
    return True, cov, projection_std_grid(data.intrinsics, cov)


def _span_indices(stamps: np.ndarray, lo: float, hi: float, max_points: int) -> np.ndarray:
    """Indices of the samples in ``[lo, hi]``, evenly thinned to at most ``max_points``."""
    idx = np.flatnonzero((stamps >= lo) & (stamps <= hi))
    if idx.size == 0:
        idx = np.arange(stamps.size)
    if idx.size > max_points:
        idx = idx[np.unique(np.linspace(0, idx.size - 1, max_points).round().astype(int))]
    return idx


def run_details(run: CalibrationRun, *, diagnostics: Mapping[str, Mapping[str, Any]] | None = None,
                max_trajectory_points: int = 3000, max_points: int = MAX_POINTS) -> RunDetails:
    """Collect the details of a calibration run (see module docstring for the frames).

    Parameters
    ----------
    run : multieye.pipeline.CalibrationRun
    diagnostics : mapping of camera name to mapping, optional
        Free-form, JSON-compatible per-camera diagnostics (numpy values are converted; NaN
        and inf become null).
    max_trajectory_points : int
        Most positions kept per trajectory.
    max_points : int
        Most target points kept per camera (:func:`image_points`).

    Raises
    ------
    InputError
        Diagnostics for a camera that is not in the run, or values that JSON cannot hold.
    """
    rec = run.record
    setup = rec.setup
    diagnostics = dict(diagnostics or {})
    unknown = sorted(set(diagnostics) - {c.name for c in rec.cameras})
    if unknown:
        raise InputError(f"diagnostics given for cameras not in the run: {', '.join(unknown)}")
    T_shown = None
    if setup == "eye-on-hand":
        ref = run.paired[rec.reference_camera].T_world_mocap
        T_shown = ref[len(ref) // 2]
    rig = None if rec.mocap else _rig_path(run)     # a rig linked by its motion: its poses
    if rig is not None:
        T_shown = rig.T[len(rig.T) // 2]
    # one entry per distinct motion-capture trajectory (cameras share the object when they
    # share the file), with the span of the used images in the motion-capture clock
    traj_index: dict[int, int] = {}
    sources, spans = [], []
    cams = []
    # without motion capture: world = ref, X = T_ref_cam, Y = I, "mocap" = T_ref_target
    # (multieye.pipeline.overlap_run), drawn as eye-to-base
    Y = rec.Y if rec.mocap else np.eye(4)
    for cam in rec.cameras:
        data, paired = run.cameras[cam.name], run.paired[cam.name]
        key = id(data.mocap)
        if key not in traj_index:
            traj_index[key] = len(sources)
            sources.append(data.mocap)
            spans.append([math.inf, -math.inf])
        k = traj_index[key]
        stamps = np.array([o.stamp for o in paired.observations], dtype=np.float64)
        offset = data.time_offset if cam.time_offset_s is None else cam.time_offset_s
        spans[k] = [min(spans[k][0], stamps.min() + offset), max(spans[k][1], stamps.max() + offset)]
        X = cam.T_ref_cam if cam.X is None else cam.X
        rot, trans = loop_residuals(paired.A, paired.B, X, Y)
        if rig is not None:          # T_world_rig(t_i) @ T_ref_cam @ T_cam_target[i]
            sol = run.refinement.result.solution
            T_world_target = sol.result.T_world_rig[sol.instants[cam.name]] @ X @ np.stack(
                [o.T_cam_target for o in paired.observations])
            T_world_cam = T_shown @ X
        elif setup != "eye-on-hand":   # T_world_marker[i] @ T_marker_target
            T_world_target = paired.T_world_mocap @ Y
            T_world_cam = X
        else:                        # T_world_body[i] @ T_body_cam @ T_cam_target[i]
            T_cam_target = np.stack([o.T_cam_target for o in paired.observations])
            T_world_target = paired.T_world_mocap @ cam.X @ T_cam_target
            T_world_cam = T_shown @ cam.X
        rms = np.array([np.nan if o.rms_px is None else o.rms_px for o in paired.observations],
                       dtype=np.float64)
        estimated, intr_cov, grid = _lens(run, cam.name)
        cams.append(CameraDetails(
            name=cam.name, T_world_cam=T_world_cam, intrinsics=data.intrinsics, trajectory=k,
            names=tuple(o.name for o in paired.observations), stamps=stamps, rot_deg=rot,
            trans_m=trans, rms_px=rms, T_world_target=T_world_target,
            diagnostics=json_value(diagnostics.get(cam.name, {}),
                                    f"diagnostics of camera {cam.name}"),
            points=image_points(run, cam.name, max_points=max_points),
            intrinsics_estimated=estimated, intrinsics_covariance=intr_cov,
            projection_std=grid, topic=camera_topic(run, cam.name),
            selection=None if data.selection is None else data.selection.as_dict()))
    overlaps = camera_overlaps(run)
    cams = [replace(c, overlaps=overlaps[c.name]) for c in cams]
    default = "T_world_marker" if setup == "eye-to-base" else "T_world_body"
    trajectories = [] if rec.mocap else [rig or _target_path(run)]
    for traj, (lo, hi) in zip(sources if rec.mocap else (), spans):
        inside = (traj.stamps >= lo - TRAJECTORY_MARGIN_S) & (traj.stamps <= hi + TRAJECTORY_MARGIN_S)
        idx = _span_indices(traj.stamps, lo - TRAJECTORY_MARGIN_S, hi + TRAJECTORY_MARGIN_S,
                            max_trajectory_points)
        pose = (f"T_world_{traj.child}" if traj.parent == "world"
                and traj.child in ("marker", "body") else default)
        trajectories.append(TrajectoryDetails(pose=pose, stamps=traj.stamps[idx].copy(),
                                              positions=traj.T[idx, :3, 3].copy(),
                                              n_samples=int(inside.sum()) or len(traj.stamps)))
    return RunDetails(setup=setup, reference_camera=rec.reference_camera, cameras=tuple(cams),
                      trajectories=tuple(trajectories), T_world_body_shown=T_shown,
                      timings=run.timings, warnings=tuple(rec.warnings),
                      frame=None if rig is None else run.refinement.result.solution.world)


def _instant_stamps(run: CalibrationRun) -> tuple[np.ndarray, np.ndarray]:
    """The mean stamp of each instant's used images, and the instants that have one (not
    those of the lenses' own images), in time order."""
    sol = run.refinement.result.solution
    K = len(sol.result.T_ref_target)
    sums, counts = np.zeros(K), np.zeros(K)
    for n in sol.names:
        d = run.cameras[n]
        np.add.at(sums, sol.instants[n], [o.stamp + d.time_offset for o in sol.used[n]])
        np.add.at(counts, sol.instants[n], 1)
    seen = np.flatnonzero(counts)
    order = seen[np.argsort(sums[seen] / counts[seen], kind="stable")]
    return sums[order] / counts[order], order


def _target_path(run: CalibrationRun) -> TrajectoryDetails:
    """A rig without motion capture: the target's origin at every instant, in ``ref``, at
    the mean stamp of the instant's images (``pose`` ``T_ref_target``)."""
    T = run.refinement.result.solution.result.T_ref_target
    stamps, order = _instant_stamps(run)
    return TrajectoryDetails(pose="T_ref_target", stamps=stamps,
                             positions=T[order, :3, 3].copy(), n_samples=len(order))


def _rig_path(run: CalibrationRun) -> TrajectoryDetails | None:
    """A rig linked by its motion before several boards (no motion capture): the rig's
    (reference camera's) pose at every instant in the first board's frame, at the mean stamp
    of the instant's images (``pose`` ``T_<board>_rig``); None for any other run."""
    if run.record.method != "motion-links" or run.refinement is None:
        return None
    sol = run.refinement.result.solution
    stamps, order = _instant_stamps(run)
    T = sol.result.T_world_rig[order]
    return TrajectoryDetails(pose=f"T_{sol.world}_rig", stamps=stamps,
                             positions=T[:, :3, 3].copy(), n_samples=len(order), T=T.copy())


def write_run_details(path: str | os.PathLike, run: CalibrationRun, *,
                      diagnostics: Mapping[str, Mapping[str, Any]] | None = None,
                      max_trajectory_points: int = 3000) -> RunDetails:
    """Write ``details.json`` of a run atomically and return what was written.

    Parameters
    ----------
    path : path-like
        Usually ``OUT/details.json`` beside ``calibration.json``.
    run : multieye.pipeline.CalibrationRun
    diagnostics, max_trajectory_points
        See :func:`run_details`.
    """
    details = run_details(run, diagnostics=diagnostics,
                          max_trajectory_points=max_trajectory_points)
    write_details(path, details)
    return details


def camera_overlaps(run: CalibrationRun) -> dict[str, tuple[str, ...]]:
    """Per camera, the others that saw the target at the same time: those its ``links`` name
    (images at one instant, docs/rig-yaml.md, section 2); for a record without links, a used
    image of each within the smaller of their time tolerances, stamps in the motion-capture
    clock."""
    if all(c.links is not None for c in run.record.cameras):
        return {c.name: tuple(c.links.overlap) for c in run.record.cameras}
    names, stamps, tols = [], [], []
    for cam in run.record.cameras:
        data, paired = run.cameras[cam.name], run.paired[cam.name]
        offset = data.time_offset if cam.time_offset_s is None else cam.time_offset_s
        names.append(cam.name)
        stamps.append(np.array([o.stamp for o in paired.observations], dtype=np.float64) + offset)
        tols.append(data.time_tolerance)
    found = overlaps_in_time(stamps, tols)
    return {n: tuple(names[k] for k in found[j]) for j, n in enumerate(names)}


def camera_topic(run: CalibrationRun, name: str) -> str | None:
    """The camera's image topic in rig.yaml, if it has one."""
    spec = run.rig.cameras.get(name) if run.rig is not None else None
    return getattr(spec, "topic", None)
