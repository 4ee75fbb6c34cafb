"""``details.json`` from a calibration run: the evidence behind ``calibration.json``.

The format, its frames and its reader live in :mod:`multieye.io.run_details`; this module
collects the details from a :class:`~multieye.pipeline.CalibrationRun`.

Synopsis
--------
>>> from multieye.outputs.details import write_run_details
>>> write_run_details("out/details.json", run)          # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from multieye.core.errors import InputError
from multieye.core.metrics import loop_residuals
from multieye.io.run_details import (
    TRAJECTORY_MARGIN_S,
    CameraDetails,
    RunDetails,
    TrajectoryDetails,
    json_value,
    write_details,
)
from multieye.pipeline import CalibrationRun

__all__ = ["run_details", "write_run_details"]


def _span_indices(stamps: np.ndarray, lo: float, hi: float, max_points: int) -> np.ndarray:
    """Indices of the samples in ``[lo, hi]``, evenly thinned to at most ``max_points``."""
    idx = np.flatnonzero((stamps >= lo) & (stamps <= hi))
    if idx.size == 0:
        idx = np.arange(stamps.size)
    if idx.size > max_points:
        idx = idx[np.unique(np.linspace(0, idx.size - 1, max_points).round().astype(int))]
    return idx


def run_details(run: CalibrationRun, *, diagnostics: Mapping[str, Mapping[str, Any]] | None = None,
                max_trajectory_points: int = 3000) -> RunDetails:
    """Collect the details of a calibration run (see module docstring for the frames).

    Parameters
    ----------
    run : multieye.pipeline.CalibrationRun
    diagnostics : mapping of camera name to mapping, optional
        Free-form, JSON-compatible per-camera diagnostics (numpy values are converted; NaN
        and inf become null).
    max_trajectory_points : int
        Most positions kept per trajectory.

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
    # one entry per distinct motion-capture trajectory (cameras share the object when they
    # share the file), with the span of the used images in the motion-capture clock
    traj_index: dict[int, int] = {}
    sources, spans = [], []
    cams = []
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
        rot, trans = loop_residuals(paired.A, paired.B, cam.X, rec.Y)
        if setup == "eye-to-base":   # T_world_marker[i] @ T_marker_target
            T_world_target = paired.T_world_mocap @ rec.Y
            T_world_cam = cam.X
        else:                        # T_world_body[i] @ T_body_cam @ T_cam_target[i]
            T_cam_target = np.stack([o.T_cam_target for o in paired.observations])
            T_world_target = paired.T_world_mocap @ cam.X @ T_cam_target
            T_world_cam = T_shown @ cam.X
        rms = np.array([np.nan if o.rms_px is None else o.rms_px for o in paired.observations],
                       dtype=np.float64)
        cams.append(CameraDetails(
            name=cam.name, T_world_cam=T_world_cam, intrinsics=data.intrinsics, trajectory=k,
            names=tuple(o.name for o in paired.observations), stamps=stamps, rot_deg=rot,
            trans_m=trans, rms_px=rms, T_world_target=T_world_target,
            diagnostics=json_value(diagnostics.get(cam.name, {}),
                                    f"diagnostics of camera {cam.name}")))
    pose = "T_world_marker" if setup == "eye-to-base" else "T_world_body"
    trajectories = []
    for traj, (lo, hi) in zip(sources, spans):
        inside = (traj.stamps >= lo - TRAJECTORY_MARGIN_S) & (traj.stamps <= hi + TRAJECTORY_MARGIN_S)
        idx = _span_indices(traj.stamps, lo - TRAJECTORY_MARGIN_S, hi + TRAJECTORY_MARGIN_S,
                            max_trajectory_points)
        trajectories.append(TrajectoryDetails(pose=pose, stamps=traj.stamps[idx].copy(),
                                              positions=traj.T[idx, :3, 3].copy(),
                                              n_samples=int(inside.sum()) or len(traj.stamps)))
    return RunDetails(setup=setup, reference_camera=rec.reference_camera, cameras=tuple(cams),
                      trajectories=tuple(trajectories), T_world_body_shown=T_shown,
                      timings=run.timings)


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
