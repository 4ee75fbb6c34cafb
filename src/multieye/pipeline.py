"""From a dataset folder to rig extrinsics: the paper's Fig. 3 pipeline.

``rig.yaml`` (DESIGN.md section 4) -> per camera: images -> target detection -> PnP (or
precomputed ``T_cam_target`` poses) -> pairing with motion capture in time -> ``A``, ``B``
(DESIGN.md section 2) -> :func:`multieye.solve` -> :class:`~multieye.io.CalibrationRecord`.

Synopsis
--------
>>> from multieye.pipeline import calibrate, write_outputs
>>> run = calibrate("dataset/rig.yaml", method="joint")   # doctest: +SKIP
>>> write_outputs(run, "out")                              # doctest: +SKIP
"""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import geometry as g
from .errors import DatasetError, InputError, TooFewMeasurementsError
from .intrinsics import Intrinsics
from .io import (
    CalibrationRecord,
    CamchainEntry,
    CameraRecord,
    RejectedItem,
    Residuals,
    Rig,
    Trajectory,
    list_images,
    load_rig,
    read_camera_intrinsics,
    read_mocap,
    read_tum,
    write_calibration,
    write_camchain,
)
from .metrics import relative_extrinsics
from .pairing import pair_in_time
from .solvers import Solution, solve
from .solvers.checks import MIN_MEASUREMENTS

__all__ = [
    "Observation",
    "CameraData",
    "PairedCamera",
    "CalibrationRun",
    "load_camera_data",
    "pair_camera",
    "calibrate",
    "calibrate_rig",
    "write_outputs",
]


@dataclass(frozen=True)
class Observation:
    """The target seen in one image (or one precomputed pose).

    Attributes
    ----------
    name : str
        Image file name, or ``"<poses file>:<line>"``.
    stamp : float
        Camera clock, seconds.
    T_cam_target : ndarray, shape (4, 4)
    rms_px : float or None
        PnP reprojection RMS, pixels (None for precomputed poses).
    object_points : ndarray, shape (n, 3), or None
        Detected target points in the target frame, metres.
    image_points : ndarray, shape (n, 2), or None
        Their pixels.
    """

    name: str
    stamp: float
    T_cam_target: np.ndarray
    rms_px: float | None = None
    object_points: np.ndarray | None = None
    image_points: np.ndarray | None = None


@dataclass(frozen=True)
class CameraData:
    """What one camera contributes before pairing.

    Attributes
    ----------
    name : str
    intrinsics : Intrinsics or None
        None for a camera given by precomputed poses.
    observations : tuple of Observation
        Images with a target pose, in time order.
    rejected : tuple of RejectedItem
        Images left out, and why.
    n_inputs : int
        Images (or pose rows) read.
    mocap : Trajectory
        ``T_world_marker`` (eye-to-base) or ``T_world_body`` (eye-on-hand).
    time_offset : float
        Motion-capture clock minus camera clock, seconds.
    time_tolerance : float
        Seconds.
    warnings : tuple of str
    """

    name: str
    intrinsics: Intrinsics | None
    observations: tuple[Observation, ...]
    rejected: tuple[RejectedItem, ...]
    n_inputs: int
    mocap: Trajectory
    time_offset: float
    time_tolerance: float
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class PairedCamera:
    """One camera's measurements for ``A_i X = Y B_i`` (DESIGN.md section 2).

    Attributes
    ----------
    name : str
    A, B : ndarray, shape (n, 4, 4)
    T_world_mocap : ndarray, shape (n, 4, 4)
        The motion-capture pose at each used image (``T_world_marker`` or ``T_world_body``).
    observations : tuple of Observation
        The used images, one per row of A and B.
    rejected : tuple of RejectedItem
        Everything left out so far (detection and pairing).
    """

    name: str
    A: np.ndarray
    B: np.ndarray
    T_world_mocap: np.ndarray
    observations: tuple[Observation, ...]
    rejected: tuple[RejectedItem, ...]


@dataclass(frozen=True)
class CalibrationRun:
    """Everything a calibration produced, for writers, reports and Python users."""

    rig: Rig
    record: CalibrationRecord
    solution: Solution
    cameras: dict[str, CameraData]
    paired: dict[str, PairedCamera]


def _describe_target(rig: Rig) -> str:
    t = rig.target
    return f"{t.type} {t.rows}x{t.cols}" if t is not None else "target"


def _observations_from_images(name: str, source: Path, rig: Rig, intr: Intrinsics, *,
                              processes, progress, topic: str | None = None):
    """Detection and PnP over a folder of time-stamped images, or a bag's image topic."""
    from .imaging.targets import target_from_spec

    target = target_from_spec(rig.target.as_dict(), path=rig.path)
    if topic is None:
        from .imaging.batch import detect_and_estimate

        images = list_images(source)
        results = detect_and_estimate([p for _, _, p in images], target, intr,
                                      processes=processes, progress=progress)
        stamped = [(stamp, path.name) for stamp, _, path in images]
    else:
        from .imaging.batch import process_array
        from .io import iter_bag_images

        results, stamped = [], []
        for stamp_ns, image in iter_bag_images(source, topic):
            label = f"{topic}@{stamp_ns}"
            results.append(process_array(image, label, target, intr))
            stamped.append((stamp_ns * 1e-9, label))
        if not stamped:
            raise DatasetError(f"image topic {topic} holds no images", path=source, camera=name)
    obs, rejected, warnings = [], [], []
    for (stamp, label), res in zip(stamped, results):
        if res.ok:
            obs.append(Observation(name=label, stamp=stamp, T_cam_target=res.pose.T_cam_target,
                                   rms_px=res.pose.rms_px,
                                   object_points=res.detection.object_points,
                                   image_points=res.detection.image_points))
            warnings.extend(f"{name}/{label}: {w}" for w in res.warnings)
        else:
            rejected.append(RejectedItem(label, res.reason))
    if not obs:
        raise DatasetError(f"the target ({_describe_target(rig)}) was not detected in any of "
                           f"the {len(stamped)} images; check the target section of rig.yaml "
                           "(rows/cols count inner corners for a chessboard) and the images",
                           path=source, camera=name)
    return obs, rejected, len(stamped), tuple(warnings)


def load_camera_data(rig: Rig, *, processes: int | None = None,
                     progress: bool = False) -> dict[str, CameraData]:
    """Read, detect and estimate every camera's target poses and its motion capture.

    Raises
    ------
    DatasetError
        A missing or malformed file, or a camera in which the target is never detected.
    """
    trajectories: dict[tuple, Trajectory] = {}
    out = {}
    for name, cam in rig.cameras.items():
        spec = rig.mocap_for(name)
        key = (str(spec.file), spec.pose, spec.format, spec.topic, spec.rigid_body)
        if key not in trajectories:
            trajectories[key] = read_mocap(spec)
        warnings: tuple[str, ...] = ()
        if cam.source == "poses":
            traj = read_tum(cam.poses, parent="cam", child="target")
            obs = [Observation(name=f"{cam.poses.name}:{i + 1}", stamp=float(t), T_cam_target=T)
                   for i, (t, T) in enumerate(zip(traj.stamps, traj.T))]
            rejected: list[RejectedItem] = []
            n_inputs = len(obs)
            intr = read_camera_intrinsics(cam) if cam.intrinsics is not None else None
        elif cam.source == "images":
            intr = read_camera_intrinsics(cam)
            obs, rejected, n_inputs, warnings = _observations_from_images(
                name, cam.images, rig, intr, processes=processes, progress=progress)
        else:
            intr = read_camera_intrinsics(cam)
            obs, rejected, n_inputs, warnings = _observations_from_images(
                name, cam.rosbag, rig, intr, processes=processes, progress=progress,
                topic=cam.topic)
        out[name] = CameraData(name=name, intrinsics=intr, observations=tuple(obs),
                               rejected=tuple(rejected), n_inputs=n_inputs,
                               mocap=trajectories[key], time_offset=cam.time_offset,
                               time_tolerance=spec.time_tolerance, warnings=warnings)
    return out


def pair_camera(setup: str, data: CameraData, *, time_offset: float | None = None) -> PairedCamera:
    """Pair a camera's observations with motion capture and form its A and B.

    Parameters
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    data : CameraData
    time_offset : float, optional
        Overrides ``data.time_offset`` (seconds, motion-capture minus camera clock).

    Raises
    ------
    TooFewMeasurementsError
        Fewer than 3 images paired; the message counts what was lost where.
    """
    offset = data.time_offset if time_offset is None else time_offset
    stamps = np.array([o.stamp for o in data.observations])
    p = pair_in_time(data.mocap.stamps, data.mocap.T, stamps, tolerance=data.time_tolerance,
                     offset=offset)
    rejected = list(data.rejected)
    rejected.extend(RejectedItem(data.observations[i].name, f"no motion capture: {why}")
                    for i, why in p.unpaired)
    used = tuple(data.observations[i] for i in p.index)
    if len(used) < MIN_MEASUREMENTS:
        raise TooFewMeasurementsError(
            f"camera {data.name}: only {len(used)} of {data.n_inputs} images could be used "
            f"({data.n_inputs - len(data.observations)} without a target pose, "
            f"{len(p.unpaired)} without motion capture within {data.time_tolerance:g} s); "
            f"at least {MIN_MEASUREMENTS} are needed")
    T_cam_target = np.stack([o.T_cam_target for o in used])
    B = g.inv(T_cam_target)                            # T_target_cam
    A = g.inv(p.T) if setup == "eye-to-base" else p.T  # T_marker_world or T_world_body
    return PairedCamera(name=data.name, A=A, B=B, T_world_mocap=p.T, observations=used,
                        rejected=tuple(rejected))


def _record(rig: Rig, method: str, reference: str, sol: Solution,
            paired: dict[str, PairedCamera], warnings: list[str],
            time_offsets: dict[str, float]) -> CalibrationRecord:
    names = list(paired)
    ref = names.index(reference)
    T_ref_cam = relative_extrinsics(sol.X, reference=ref)
    cams = []
    for j, name in enumerate(names):
        r = sol.residuals[j]
        rms = [o.rms_px for o in paired[name].observations if o.rms_px is not None]
        cams.append(CameraRecord(
            name=name, X=sol.X[j], T_ref_cam=T_ref_cam[j], measurements_used=r.n,
            residuals=Residuals(e_R_deg=r.e_R_deg, e_t_m=r.e_t_m, max_R_deg=r.max_R_deg,
                                max_t_m=r.max_t_m,
                                reprojection_rms_px=float(np.sqrt(np.mean(np.square(rms))))
                                if rms else None),
            time_offset_s=time_offsets.get(name),
            rejected=paired[name].rejected))
    return CalibrationRecord(setup=rig.setup, method=method, reference_camera=reference, Y=sol.Y,
                             cameras=tuple(cams),
                             residuals=Residuals(e_R_deg=sol.e_R_deg, e_t_m=sol.e_t_m),
                             warnings=tuple(warnings))


def calibrate_rig(rig: Rig, cameras: dict[str, CameraData], *, method: str = "joint",
                  reference: str | None = None) -> CalibrationRun:
    """Pair, solve and summarise already loaded camera data (see :func:`calibrate`)."""
    names = list(cameras)
    reference = reference or names[0]
    if reference not in cameras:
        raise DatasetError(f"reference camera {reference!r} is not in rig.yaml (cameras: "
                           f"{', '.join(names)})", path=rig.path)
    paired = {name: pair_camera(rig.setup, data) for name, data in cameras.items()}
    sol = solve([p.A for p in paired.values()], [p.B for p in paired.values()], method,
                names=names)
    warnings = [w for data in cameras.values() for w in data.warnings]
    offsets = {name: data.time_offset for name, data in cameras.items() if data.time_offset}
    record = _record(rig, method, reference, sol, paired, warnings, offsets)
    return CalibrationRun(rig=rig, record=record, solution=sol, cameras=cameras, paired=paired)


def calibrate(dataset: str | os.PathLike, *, method: str = "joint", reference: str | None = None,
              processes: int | None = None, progress: bool = False) -> CalibrationRun:
    """Calibrate the rig described by a dataset folder (or its ``rig.yaml``).

    Parameters
    ----------
    dataset : path-like
        Folder holding ``rig.yaml``, or the file itself.
    method : str
        Solver name (:data:`multieye.METHODS`).
    reference : str, optional
        Camera whose frame is ``ref``; default the first camera of ``rig.yaml``.
    processes : int, optional
        Worker processes for detection; default one per core.
    progress : bool
        Show a progress bar (only sensible on a terminal).

    Returns
    -------
    CalibrationRun
    """
    path = Path(dataset)
    if path.is_dir():
        path = path / "rig.yaml"
    rig = load_rig(path)
    cameras = load_camera_data(rig, processes=processes, progress=progress)
    return calibrate_rig(rig, cameras, method=method, reference=reference)


def write_outputs(run: CalibrationRun, out_dir: str | os.PathLike, *, report: bool = True,
                  diagnostics: dict | None = None) -> tuple[list[Path], list[str]]:
    """Write the results of a run into ``out_dir``, all or nothing.

    ``calibration.json`` (DESIGN.md section 4), Kalibr ``camchain.yaml``, ``details.json``
    (per-image residuals, target poses, trajectory; :mod:`multieye.io.run_details`) and,
    with ``report=True``, ``report.html`` with ``figures/`` (:mod:`multieye.report`).
    Everything is first written into a temporary folder inside ``out_dir``; only when all of
    it succeeded are the files moved into place, ``calibration.json`` last, so a failed run
    leaves the previous results as they were.

    Returns
    -------
    paths : list of Path
        Files written.
    notes : list of str
        Why an output was not written (e.g. intrinsics that Kalibr's models cannot hold).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".multieye-", dir=out))
    try:
        names, notes = _write_all(run, tmp, report=report, diagnostics=diagnostics)
        names = [n for n in names if (tmp / n).exists()]
        for name in names:
            target = out / name
            if target.is_dir() and not (tmp / name).is_dir():
                raise DatasetError("cannot replace a folder with a file", path=target)
        for name in sorted(names, key=lambda n: n == "calibration.json"):
            target = out / name
            if (tmp / name).is_dir():
                if target.exists():
                    shutil.rmtree(target)
            os.replace(tmp / name, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return [out / n for n in names], notes


def _write_all(run: CalibrationRun, folder: Path, *, report: bool,
               diagnostics: dict | None) -> tuple[list[str], list[str]]:
    """Write every output into ``folder``; returns the names written and notes."""
    from .io.run_details import write_run_details

    write_calibration(folder / "calibration.json", run.record)
    names, notes = ["calibration.json"], []
    missing = [c.name for c in run.record.cameras if run.cameras[c.name].intrinsics is None]
    if missing:
        notes.append(f"camchain.yaml not written: no intrinsics for {', '.join(missing)}")
    else:
        entries = [CamchainEntry(name=c.name, intrinsics=run.cameras[c.name].intrinsics,
                                 T_ref_cam=c.T_ref_cam) for c in run.record.cameras]
        try:
            write_camchain(folder / "camchain.yaml", entries)
        except InputError as exc:
            notes.append(f"camchain.yaml not written: {exc}")
        else:
            names.append("camchain.yaml")
    write_run_details(folder / "details.json", run, diagnostics=diagnostics)
    names.append("details.json")
    if report:
        from .report import write_report

        write_report(folder)
        names += ["report.html", "figures"]
    return names, notes
