"""``details.json``: what the report needs beyond ``calibration.json``.

``calibration.json`` (docs/outputs.md, section 2) holds the result; this file holds the evidence
behind it, per measurement, so that :mod:`multieye.outputs.report` can draw the rig and the residuals
without the dataset:

- per camera: the used measurements (image name, camera-clock stamp, loop residual of
  ``A_i X = Y B_i`` in rotation and translation from :func:`multieye.core.metrics.loop_residuals`,
  PnP reprojection RMS), the target pose in the world at each of them, the intrinsics (for
  frustums), the pose of the camera in the world, and an optional free-form ``diagnostics``
  mapping (weak-motion diagnostics, filled by whoever computes them);
- the motion-capture trajectories (positions only) over the span of the used images,
  subsampled to at most a few thousand points;
- ``timings_s``: seconds spent per stage of the run (:class:`StageTimings`); files written
  before it existed do not have it;
- ``warnings``: the run's warnings, the same list as in ``calibration.json`` (among them the
  files read from outside the dataset folder); files written before it existed read with
  none;
- per camera, where the target was seen and how well it fits (the target points of every used
  image and their reprojection residuals), the intrinsics' covariance when they were
  estimated and the projection's uncertainty over the image (:mod:`multieye.io.pixel_details`);
  files written before these existed read with them as None.

Frames (docs/conventions.md, section 2), for the world pictures:

============  ==========================================  ===================================
setup         ``T_world_target[i]``                       ``T_world_cam`` drawn
============  ==========================================  ===================================
eye-to-base   ``T_world_marker[i] @ T_marker_target``     ``T_world_cam`` (static)
eye-on-hand   ``T_world_body[i] @ T_body_cam @            ``T_world_body_shown @ T_body_cam``
              T_cam_target[i]``
overlap       ``T_ref_target`` of the image's instant     ``T_ref_cam``
============  ==========================================  ===================================

Without motion capture (setup ``overlap``) the ``world`` of these pictures is the reference
camera's frame, the loop residuals are those of each image's PnP pose against the solution's
``inv(T_ref_cam) @ T_ref_target`` and the one trajectory is the target's origin at every
instant (``pose`` ``T_ref_target``).  A rig linked by its motion is drawn in the first board's
frame (``frame``; docs/outputs.md, section 3): the rig's pose per instant (trajectory ``T``),
the cameras at its middle one, the boards as ``calibration.json``'s ``targets``.

In eye-to-base the target moves and the motion capture says where it was.  In eye-on-hand the
target is static at ``T_world_target`` and every measurement gives one estimate of it through
the camera chain, whose scatter shows the residuals in space; the cameras move with the body
and are drawn at one body pose, ``T_world_body_shown``: the motion-capture pose at the middle
used image of the reference camera.

Synopsis
--------
>>> from multieye.io.run_details import read_run_details
>>> from multieye.outputs.details import write_run_details
>>> write_run_details("out/details.json", run)          # doctest: +SKIP
>>> details = read_run_details("out/details.json")      # doctest: +SKIP
>>> details.camera("cam0").rot_deg                      # doctest: +SKIP
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import Intrinsics, parameter_names
from multieye.io.atomic import write_text_atomic
from multieye.io.calibration_json import OVERLAP, SETUP_KEYS
from multieye.io.pixel_details import (
    ImagePoints,
    plain,
    ProjectionStd,
    points_from_dict,
    points_to_dict,
    projection_from_dict,
    projection_to_dict,
)
from multieye.io.textfile import read_json_as

__all__ = [
    "FORMAT",
    "VERSION",
    "TrajectoryDetails",
    "CameraDetails",
    "ImagePoints",
    "ProjectionStd",
    "RunDetails",
    "StageTimings",
    "TIMING_KEYS",
    "run_details_to_dict",
    "run_details_from_dict",
    "write_details",
    "details_head",
    "write_details_text",
    "json_value",
    "read_run_details",
]

#: Value of the top-level ``format`` key.
FORMAT = "multieye-run-details"
#: Version of the layout; readers reject other versions.
VERSION = 1
#: Seconds of motion capture kept before the first and after the last used image.
TRAJECTORY_MARGIN_S = 2.0


@dataclass(frozen=True)
class TrajectoryDetails:
    """Positions of one motion-capture trajectory, for drawing.

    Attributes
    ----------
    pose : str
        What the poses were, ``"T_world_marker"`` or ``"T_world_body"``.
    stamps : ndarray, shape (k,)
        Motion-capture clock, seconds.
    positions : ndarray, shape (k, 3)
        Origin of the marker (or body) frame in the world, metres.
    n_samples : int
        Samples in the span before subsampling (``>= k``).
    T : ndarray, shape (k, 4, 4), or None
        The full poses (a rig linked by its motion); None for motion capture.
    """

    pose: str
    stamps: np.ndarray
    positions: np.ndarray
    n_samples: int
    T: np.ndarray | None = None


@dataclass(frozen=True)
class CameraDetails:
    """One camera's measurements and drawing data.

    Attributes
    ----------
    name : str
    T_world_cam : ndarray, shape (4, 4)
        Where the camera is drawn (module docstring), metres.
    intrinsics : Intrinsics or None
        None for a camera given by precomputed poses without intrinsics.
    trajectory : int
        Index of its motion capture in :attr:`RunDetails.trajectories`.
    names : tuple of str
        Image file names (or ``"<poses file>:<line>"``) of the used measurements.
    stamps : ndarray, shape (n,)
        Camera clock, seconds.
    rot_deg : ndarray, shape (n,)
        Rotation residual of ``A_i X = Y B_i``, degrees (paper section V-A).
    trans_m : ndarray, shape (n,)
        Translation residual, metres.
    rms_px : ndarray, shape (n,)
        PnP reprojection RMS, pixels; NaN where unknown (precomputed poses).
    T_world_target : ndarray, shape (n, 4, 4)
        The target in the world at each measurement (module docstring).
    diagnostics : mapping
        Free-form, JSON-compatible values (e.g. weak-motion diagnostics); empty when none.
    points : ImagePoints or None
        The target points of the used images and their reprojection residuals; None for a
        camera given by poses, and in files written before it existed.
    intrinsics_estimated : bool or None
        Whether the intrinsics were estimated from the recording; None when the file does
        not say (written before it existed).
    intrinsics_covariance : ndarray, shape (p, p), or None
        Covariance of ``intrinsics.params`` (fx fy cx cy, then the distortion) when they were
        estimated by the joint refinement.
    projection_std : ProjectionStd or None
        Standard deviation of the projection over the image, from that covariance.
    topic : str or None
        The camera's image topic in rig.yaml (a rosbag camera); None otherwise.
    overlaps : tuple of str, or None
        The other cameras that saw the target at the same time (a used image of each within
        the time tolerance, in the motion-capture clock); None in files written before it
        existed.
    selection : dict or None
        What the image selection did (docs/recordings.md, section 1): ``budget``, ``seen``,
        ``kept``, ``stage``, ``without_mocap``, and ``unusable``, ``refilled`` (absent in files
        of earlier versions); None when it did not choose among this camera's images.
    """

    name: str
    T_world_cam: np.ndarray
    intrinsics: Intrinsics | None
    trajectory: int
    names: tuple[str, ...]
    stamps: np.ndarray
    rot_deg: np.ndarray
    trans_m: np.ndarray
    rms_px: np.ndarray
    T_world_target: np.ndarray
    diagnostics: Mapping[str, Any] = field(default_factory=dict)
    points: ImagePoints | None = None
    intrinsics_estimated: bool | None = None
    intrinsics_covariance: np.ndarray | None = None
    projection_std: ProjectionStd | None = None
    topic: str | None = None
    overlaps: tuple[str, ...] | None = None
    selection: Mapping[str, Any] | None = None


#: Keys of a camera's ``selection`` and their types.
SELECTION_KEYS = {"budget": int, "seen": int, "kept": int, "stage": str, "without_mocap": int}
#: ... and those files of earlier versions lack (chosen images that proved unusable, and the
#: images chosen again in their place).
SELECTION_LATER_KEYS = {"unusable": int, "refilled": int}


@dataclass(frozen=True)
class StageTimings:
    """Seconds spent per stage of a calibration (``timings_s`` of ``details.json``).

    Attributes
    ----------
    reading : float
        ``rig.yaml``, intrinsics, motion capture, image listing.
    detection : float
        Target detection and PnP (images read from a ROS bag are streamed into it).
    pairing : float
        Clock offsets, pairing in time, input checks, consensus, motion diagnostics.
    closed_form : float
        The closed-form solve.
    refinement : float
        Maximum-likelihood refinement and the uncertainty of the result.
    outputs : float
        Writing ``calibration.json``, ``camchain.yaml``, ``details.json`` and the report;
        0 until :func:`multieye.outputs.write.write_outputs` has measured it.
    total : float
        The whole run, outputs included once measured; at least the sum of the stages.
    """

    reading: float = 0.0
    detection: float = 0.0
    pairing: float = 0.0
    closed_form: float = 0.0
    refinement: float = 0.0
    outputs: float = 0.0
    total: float = 0.0

    def as_dict(self) -> dict[str, float]:
        """``{"reading": ..., ..., "total": ...}``, seconds."""
        return {k: float(getattr(self, k)) for k in TIMING_KEYS}


#: Keys of ``timings_s``: the stages in the order they run, then the total.
TIMING_KEYS = ("reading", "detection", "pairing", "closed_form", "refinement", "outputs", "total")


@dataclass(frozen=True)
class RunDetails:
    """Everything ``details.json`` holds.

    Attributes
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    reference_camera : str
    cameras : tuple of CameraDetails
        In the order of ``calibration.json``.
    trajectories : tuple of TrajectoryDetails
    T_world_body_shown : ndarray, shape (4, 4), or None
        Eye-on-hand: the body pose at which the cameras are drawn; a rig linked by its motion:
        the rig's pose at its middle instant; None for eye-to-base.
    timings : StageTimings or None
        None when the file has no ``timings_s`` (written before it existed).
    warnings : tuple of str
        The run's warnings, as in ``calibration.json`` (files read from outside the dataset
        folder among them); empty for files written before ``details.json`` had them.
    frame : str or None
        The pictures' world when it is a board (a rig linked by its motion: the first board).
    """

    setup: str
    reference_camera: str
    cameras: tuple[CameraDetails, ...]
    trajectories: tuple[TrajectoryDetails, ...]
    T_world_body_shown: np.ndarray | None = None
    timings: StageTimings | None = None
    warnings: tuple[str, ...] = ()
    frame: str | None = None

    def camera(self, name: str) -> CameraDetails:
        """The details of camera ``name``."""
        for cam in self.cameras:
            if cam.name == name:
                return cam
        raise KeyError(name)


# --------------------------------------------------------------------------- from a run


def json_value(value, where: str):
    """``value`` as plain JSON types (numpy scalars and arrays become numbers and lists)."""
    if isinstance(value, np.ndarray):
        return json_value(value.tolist(), where)
    if isinstance(value, np.generic):
        return json_value(value.item(), where)
    if isinstance(value, Mapping):
        return {str(k): json_value(v, where) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_value(v, where) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise InputError(f"{where}: {type(value).__name__} is not a JSON value")


# --------------------------------------------------------------------------- to / from dict


def _floats(a) -> list:
    """Nested lists of Python floats (NaN -> None), full precision."""
    return plain(a)


def _intrinsics_dict(c: CameraDetails):
    intr = c.intrinsics
    if intr is None:
        return None
    out = {"model": intr.model, "K": _floats(intr.K), "dist": _floats(intr.dist),
           "width": intr.width, "height": intr.height}
    if c.intrinsics_estimated is not None:
        out["estimated"] = bool(c.intrinsics_estimated)
    if c.intrinsics_covariance is not None:
        out["parameters"] = list(parameter_names(intr))
        out["covariance"] = _floats(c.intrinsics_covariance)
    return out


def run_details_to_dict(details: RunDetails) -> dict:
    """The JSON object of :class:`RunDetails` (matrices as nested lists, NaN as null)."""
    cameras = {}
    for c in details.cameras:
        cameras[c.name] = {
            "T_world_cam": _floats(c.T_world_cam),
            "intrinsics": _intrinsics_dict(c),
            "trajectory": c.trajectory,
            "measurements": {
                "name": list(c.names), "stamp": _floats(c.stamps), "rot_deg": _floats(c.rot_deg),
                "trans_m": _floats(c.trans_m), "rms_px": _floats(c.rms_px),
                "T_world_target": _floats(c.T_world_target),
            },
            "diagnostics": json_value(c.diagnostics, f"diagnostics of camera {c.name}"),
        }
        if c.points is not None:
            cameras[c.name]["points"] = points_to_dict(c.points)
        if c.projection_std is not None:
            cameras[c.name]["projection_std"] = projection_to_dict(c.projection_std)
        if c.topic is not None:
            cameras[c.name]["topic"] = c.topic
        if c.overlaps is not None:
            cameras[c.name]["overlaps"] = list(c.overlaps)
        if c.selection is not None:
            cameras[c.name]["selection"] = dict(c.selection)
    out = {
        "format": FORMAT, "version": VERSION, "setup": details.setup,
        "reference_camera": details.reference_camera,
        "T_world_body_shown": (None if details.T_world_body_shown is None
                               else _floats(details.T_world_body_shown)),
        "trajectories": [{"pose": t.pose, "n_samples": t.n_samples, "stamp": _floats(t.stamps),
                          "position": _floats(t.positions)}
                         | ({} if t.T is None else {"T": _floats(t.T)})
                         for t in details.trajectories],
        "cameras": cameras,
        "warnings": list(details.warnings),
    }
    if details.frame is not None:
        out["frame"] = details.frame
    if details.timings is not None:
        out["timings_s"] = details.timings.as_dict()
    return out


class _Reader:
    """Checks values of one ``details.json`` and names the file and camera in errors."""

    def __init__(self, path):
        self.path = path

    def error(self, message: str, camera: str | None = None) -> DatasetError:
        return DatasetError(message, path=self.path, camera=camera)

    def get(self, obj, key: str, where: str, camera: str | None = None):
        if not isinstance(obj, Mapping):
            raise self.error(f"{where} must be an object", camera)
        if key not in obj:
            raise self.error(f"missing key {key!r} in {where}", camera)
        return obj[key]

    def array(self, value, shape: tuple, what: str, camera: str | None = None,
              nan_ok: bool = False) -> np.ndarray:
        """Numbers of the given shape (``-1`` matches any length); null -> NaN if allowed."""
        try:
            a = np.array(value, dtype=np.float64)  # None -> nan
        except (TypeError, ValueError, OverflowError):
            raise self.error(f"{what} must be numbers", camera) from None
        if a.ndim != len(shape) or any(s not in (-1, n) for s, n in zip(shape, a.shape)):
            want = " x ".join("n" if s == -1 else str(s) for s in shape)
            raise self.error(f"{what} must have shape ({want}), got {a.shape}", camera)
        if not nan_ok and not np.all(np.isfinite(a)):
            raise self.error(f"{what} must be finite numbers", camera)
        return a


def _read_intrinsics(r: _Reader, obj, name: str) -> Intrinsics | None:
    if obj is None:
        return None
    K = r.array(r.get(obj, "K", "intrinsics", name), (3, 3), "intrinsics.K", name)
    dist = r.array(r.get(obj, "dist", "intrinsics", name), (-1,), "intrinsics.dist", name)
    size = []
    for key in ("width", "height"):
        v = obj.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v <= 0):
            raise r.error(f"intrinsics.{key} must be a positive integer or null, got {v!r}", name)
        size.append(v)
    try:
        return Intrinsics(K, dist, obj.get("model", "pinhole"), *size)
    except InputError as exc:
        raise r.error(f"intrinsics: {exc}", name) from None


def _read_estimated(r: _Reader, obj, intr: Intrinsics | None, name: str):
    """``intrinsics.estimated`` and ``intrinsics.covariance`` (both optional)."""
    if intr is None:
        return None, None
    estimated = obj.get("estimated")
    if estimated is not None and not isinstance(estimated, bool):
        raise r.error(f"intrinsics.estimated must be true or false, got {estimated!r}", name)
    cov = obj.get("covariance")
    if cov is not None:
        n = intr.params.size
        cov = r.array(cov, (n, n), "intrinsics.covariance", name)
    return estimated, cov


def _read_timings(r: _Reader, obj) -> StageTimings | None:
    """``timings_s``: absent (older files) or every key a finite non-negative number."""
    if obj is None:
        return None
    if not isinstance(obj, Mapping):
        raise r.error("timings_s must be an object of stage -> seconds")
    values = {}
    for key in TIMING_KEYS:
        v = r.get(obj, key, "timings_s")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v)
                                                                          and v >= 0):
            raise r.error(f"timings_s.{key} must be a non-negative number of seconds, got {v!r}")
        values[key] = float(v)
    return StageTimings(**values)


def _read_trajectories(r: _Reader, data) -> list[TrajectoryDetails]:  # checked
    trajectories = []
    raw_trajs = r.get(data, "trajectories", "the top level")
    if not isinstance(raw_trajs, list):
        raise r.error("trajectories must be a list")
    for k, t in enumerate(raw_trajs):
        where = f"trajectories[{k}]"
        stamps = r.array(r.get(t, "stamp", where), (-1,), f"{where}.stamp")
        pos = r.array(r.get(t, "position", where), (stamps.size, 3), f"{where}.position")
        n = r.get(t, "n_samples", where)
        if isinstance(n, bool) or not isinstance(n, int) or n < stamps.size:
            raise r.error(f"{where}.n_samples must be an integer >= {stamps.size}, got {n!r}")
        T = None if t.get("T") is None else r.array(t["T"], (stamps.size, 4, 4), f"{where}.T")
        trajectories.append(TrajectoryDetails(str(r.get(t, "pose", where)), stamps, pos, n, T))
    return trajectories


def run_details_from_dict(data, path: str | os.PathLike | None = None) -> RunDetails:
    """Validate a parsed ``details.json`` object.

    Raises
    ------
    DatasetError
        Another format or version, missing keys, wrong shapes, lengths that disagree between a
        camera's measurement columns, a trajectory index out of range, ``timings_s``
        (optional) without every stage as a non-negative number, or malformed optional
        ``points``, ``projection_std`` or intrinsics covariance.
    """
    r = _Reader(path)
    if not isinstance(data, Mapping) or data.get("format") != FORMAT:
        raise r.error(f"not a multieye details file (expected \"format\": \"{FORMAT}\")")
    if data.get("version") != VERSION:
        raise r.error(f"details version {data.get('version')!r} is not supported; expected "
                      f"{VERSION} (rerun `multieye calibrate`)")
    setup = r.get(data, "setup", "the top level")
    if setup not in SETUP_KEYS and setup != OVERLAP:
        raise r.error(f"setup must be one of {', '.join(SETUP_KEYS)} or {OVERLAP}, got "
                      f"{setup!r}")
    reference = r.get(data, "reference_camera", "the top level")
    shown = data.get("T_world_body_shown")
    shown = None if shown is None else r.array(shown, (4, 4), "T_world_body_shown")
    trajectories = _read_trajectories(r, data)
    cams_raw = r.get(data, "cameras", "the top level")
    if not isinstance(cams_raw, Mapping) or not cams_raw:
        raise r.error("cameras must be a non-empty object of camera name -> details")
    cameras = []
    for name, c in cams_raw.items():
        where = f"camera {name}"
        k = r.get(c, "trajectory", where, name)
        if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < len(trajectories):
            raise r.error(f"trajectory must be an index into trajectories (0..{len(trajectories) - 1}),"
                          f" got {k!r}", name)
        m = r.get(c, "measurements", where, name)
        names = r.get(m, "name", "measurements", name)
        if not isinstance(names, list) or not all(isinstance(s, str) for s in names):
            raise r.error("measurements.name must be a list of strings", name)
        n = len(names)
        cols = {key: r.array(r.get(m, key, "measurements", name), (n,), f"measurements.{key}",
                             name, nan_ok=key == "rms_px")
                for key in ("stamp", "rot_deg", "trans_m", "rms_px")}
        T_wt = r.array(r.get(m, "T_world_target", "measurements", name), (n, 4, 4),
                       "measurements.T_world_target", name)
        if n == 0:
            T_wt = T_wt.reshape(0, 4, 4)
        diagnostics = c.get("diagnostics") or {}
        if not isinstance(diagnostics, Mapping):
            raise r.error("diagnostics must be an object", name)
        intr = _read_intrinsics(r, c.get("intrinsics"), name)
        topic, overlaps = c.get("topic"), c.get("overlaps")
        if topic is not None and not isinstance(topic, str):
            raise r.error(f"topic must be a string, got {topic!r}", name)
        if overlaps is not None and (not isinstance(overlaps, list) or not all(
                isinstance(o, str) and o in cams_raw and o != name for o in overlaps)):
            raise r.error(f"overlaps must be a list of the other cameras' names, got "
                          f"{overlaps!r}", name)
        estimated, intr_cov = _read_estimated(r, c.get("intrinsics"), intr, name)
        selection = c.get("selection")
        types = {**SELECTION_KEYS, **SELECTION_LATER_KEYS}
        if selection is not None and not (
                isinstance(selection, Mapping) and set(SELECTION_KEYS) <= set(selection)
                and set(selection) <= set(types)
                and all(isinstance(v, types[k]) and not isinstance(v, bool)
                        for k, v in selection.items())):
            raise r.error(f"selection must be an object with {', '.join(SELECTION_KEYS)}, got "
                          f"{selection!r}", name)
        cameras.append(CameraDetails(
            name=str(name),
            T_world_cam=r.array(r.get(c, "T_world_cam", where, name), (4, 4), "T_world_cam", name),
            intrinsics=intr, trajectory=k,
            names=tuple(names), stamps=cols["stamp"], rot_deg=cols["rot_deg"],
            trans_m=cols["trans_m"], rms_px=cols["rms_px"], T_world_target=T_wt,
            diagnostics=dict(diagnostics), points=points_from_dict(r, c.get("points"), n, name),
            intrinsics_estimated=estimated, intrinsics_covariance=intr_cov,
            projection_std=projection_from_dict(r, c.get("projection_std"), name),
            topic=topic, overlaps=None if overlaps is None else tuple(overlaps),
            selection=None if selection is None else dict(selection)))
    if reference not in cams_raw:
        raise r.error(f"reference camera {reference!r} is not one of {', '.join(cams_raw)}")
    warnings, frame = data.get("warnings", []), data.get("frame")
    if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings) or not (
            frame is None or isinstance(frame, str)):
        raise r.error("warnings must be a list of strings, frame (optional) a board's name")
    return RunDetails(setup=setup, reference_camera=reference, cameras=tuple(cameras),
                      trajectories=tuple(trajectories), T_world_body_shown=shown,
                      timings=_read_timings(r, data.get("timings_s")),
                      warnings=tuple(warnings), frame=frame)


# --------------------------------------------------------------------------- files


def write_details(path: str | os.PathLike, details: RunDetails) -> None:
    """Write ``details`` as ``details.json`` atomically (:func:`run_details_to_dict`)."""
    write_details_text(path, details_head(run_details_to_dict(details)), details.timings)


def details_head(data: Mapping) -> str:
    """The text of ``details.json`` for ``data`` (:func:`run_details_to_dict`) but its
    ``timings_s``, which ends the object: made while the run is still being written, and
    completed by :func:`write_details_text` once the timings are known."""
    text = json.dumps({k: v for k, v in data.items() if k != "timings_s"}, allow_nan=False,
                      separators=(",", ":"))
    return text[:-1]


def write_details_text(path: str | os.PathLike, head: str, timings: StageTimings | None
                       ) -> None:
    """Write ``details.json`` atomically: :func:`details_head` with ``timings_s`` (the same
    bytes as :func:`write_details` of the details with those timings)."""
    tail = ("" if timings is None else ',"timings_s":' + json.dumps(
        timings.as_dict(), allow_nan=False, separators=(",", ":")))
    write_text_atomic(path, head + tail + "}\n")


def read_run_details(path: str | os.PathLike) -> RunDetails:
    """Read and validate ``details.json``.

    Raises
    ------
    DatasetError
        Missing file, invalid JSON (with the line), or any check of
        :func:`run_details_from_dict`.
    """
    return read_json_as(path, run_details_from_dict, what="details file")
