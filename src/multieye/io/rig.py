"""``rig.yaml``: the description of a dataset (docs/rig-yaml.md), loaded and checked.

:func:`load_rig` returns a frozen :class:`Rig`.  Every problem is a :class:`DatasetError`
naming ``rig.yaml``, the line of the key concerned, the dotted key path and what was
expected: unknown keys, wrong types, missing required keys, unknown setup or target type,
files or folders that do not exist.  Paths are resolved relative to the folder of
``rig.yaml``.

Schema (keys not listed are rejected; :data:`TOP_LEVEL_KEYS` and the other ``*_KEYS``
constants hold them, docs/rig-yaml.md documents each)::

    setup: eye-to-base | eye-on-hand                         # required
    target:                                                  # required when a camera has images
      type: chessboard | circles | asymmetric-circles | charuco | aprilgrid | aruco | aruco-grid
      rows: int > 0                                          # at most 200
      cols: int > 0                                          # at most 200
      spacing: number > 0                                    # metres, at most 10
      marker_size: number > 0                                # charuco only (required)
      dictionary: DICT_...                                   # charuco only (required)
      tag_spacing: 0 < number <= 1                           # aprilgrid only (required)
      # aruco: marker_size, dictionary, id (no rows, cols, spacing)
      # aruco-grid: rows, cols, marker_size, marker_separation, dictionary, first_id (0)
    targets:                                                 # instead of target: several
      - {name: north, type: charuco, ..., first_id: 0}       #   boards, each named, told apart
      - {name: door, type: chessboard, ..., cameras: [cam1]} #   by ids or cameras; optional
                                                             #   pose: (io/rig_targets.py)
    mocap:                                                   # optional if every camera has one
      file: path                                             # required
      pose: T_world_marker                                   # default: T_world_marker
                                                             #   (T_world_body for eye-on-hand);
                                                             #   the inverse name is allowed
      time_tolerance: 0.03                                   # 0 < seconds <= 10, default 0.03
      rotation_noise_deg: 0.03                               # 0 < degrees <= 30; default:
                                                             #   estimated
      translation_noise_m: 0.0001                            # 0 < metres <= 1; default:
                                                             #   estimated
      format: tum | csv | optitrack | vicon | rosbag         # default: from the file
      topic: /vicon/rig/pose                                 # rosbag only (required)
      unit: m | cm | mm                                      # tum, csv, rosbag only
      rigid_body: name                                       # optitrack, vicon only
      parent_frame: world                                    # rosbag only
      child_frame: rig                                       # rosbag only
      columns: {t: time, tx: x, ...}                         # csv only
      duplicates: error | drop             # tum, csv, optitrack, vicon only; default error
      # file: "{stem}.json": one pose file beside each image (format pose-files), or in a
      # folder of the dataset: "poses/{stem}.yaml"; with
      # key: end2base, values: [x, y, z, qx, qy, qz, qw], rotation: quaternion-xyzw | ...
      match: time | image | order    # pose-table: by an image column or rows in name order
      sensor: motion-capture | robot                         # default: from the source
      noise_bounds: {rotation_deg: 0.1, translation_m: 0.001}   # default: the sensor's
    sync: time | name | number | order                       # default time
    cameras:                                                 # required, at least one
      cam0:
        intrinsics: cam0.yaml          # or {file: camchain.yaml, camera: cam0}
        images: cam0/                  # exactly one of images, poses, rosbag, video;
                                       #   images also a pattern: "left*.jpg",
                                       #   "frames/*/left.jpg"; stamps: FILE when the
                                       #   names are not stamps
        poses: cam0_target.txt         #   precomputed T_cam_target, TUM format
        rosbag: run.bag                #   image topic of a bag ...
        topic: /cam0/image_raw         #   ... given here (rosbag only)
        video: cam0.mp4                #   a video file; stamps: FILE or start_time: SECONDS
        mocap: cam0_mocap.txt          # optional: own file, or a mapping overriding mocap
                                       #   keys; pose, time_tolerance, the noise keys, sensor
                                       #   and noise_bounds are inherited, the format's keys
                                       #   only if the format is the same
        time_offset: 0.0               # seconds, motion-capture clock minus camera clock,
                                       #   |x| <= 1e10

:func:`read_camera_intrinsics` reads a camera's intrinsics; a Kalibr camchain with several
cameras and no ``camera`` key selects the entry named like the rig's camera.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import NamedTuple
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

from multieye.core.arguments import as_path
from multieye.core.errors import DatasetError
from multieye.core.intrinsics import LENS_MODELS, Intrinsics
from multieye.core.limits import (MAX_ROTATION_NOISE_DEG, MAX_TIME_OFFSET_S, MAX_TIME_TOLERANCE_S,
                                  MAX_TRANSLATION_NOISE_M)
from multieye.core.names import NAME_RULE, camera_name_problem
from multieye.core.target_spec import TARGET_KEYS as SPEC_KEYS
from multieye.core.target_spec import TARGET_TYPES, TargetSpec
from multieye.io.intrinsics_files import read_intrinsics
from multieye.io.mocap import MOCAP_FORMATS, MocapSpec, named_pose, sniff_mocap_format
from multieye.io.mocap_csv import DEFAULT_COLUMNS
from multieye.io.rig_checks import crop_key, model_key, video_keys
from multieye.io.pose_files import STEM, check_rotation, check_values
from multieye.io import rig_checks as _c
from multieye.io.rig_checks import camera_link, links_keys, no_link_loop, Checker as _Checker
from multieye.io.rig_checks import images_key, stem_pattern, sync_keys
from multieye.io.rig_targets import read_target as _target, read_targets
from multieye.io.textfile import LENGTH_UNITS
from multieye.io.yamlfile import load_yaml, shown

__all__ = ["SETUPS", "TARGET_TYPES", "TOP_LEVEL_KEYS", "TARGET_KEYS", "MOCAP_KEYS",
           "MOCAP_COLUMN_KEYS", "CAMERA_KEYS", "CAMERA_INTRINSICS_KEYS", "TargetSpec",
           "CameraSpec", "Rig", "load_rig", "read_camera_intrinsics"]

#: The keys ``target:`` takes: the board's, and ``file`` (another tool's board file,
#: :mod:`multieye.io.target_files`).
TARGET_KEYS = (*SPEC_KEYS, "file")

#: setup -> the frame motion capture tracks.
SETUPS = {"eye-to-base": "marker", "eye-on-hand": "body"}
_MOCAP_ONLY = {"topic": ("rosbag",), "unit": ("tum", "csv", "rosbag", "pose-files", "pose-table"),
               "rigid_body": ("optitrack", "vicon"), "parent_frame": ("rosbag",),
               "child_frame": ("rosbag",), "columns": ("csv",), "duplicates": ("tum", "csv", "optitrack", "vicon"),
               "key": ("pose-files",), "values": ("pose-files", "pose-table", "tum"),
               "rotation": ("pose-files", "pose-table", "tum")}
_SOURCES = ("images", "poses", "rosbag", "video")

#: The keys each mapping of rig.yaml accepts, in the order error messages list them; any other
#: key is rejected at its line.  docs/rig-yaml.md documents every one (tests/test_docs.py).
TOP_LEVEL_KEYS = ("setup", "target", "targets", "mocap", "cameras", "refine_intrinsics",
                  "sync_tolerance", "sync")
MOCAP_KEYS = ("file", "pose", "frames", "fixed_frame", "time_tolerance", "format",
              "rotation_noise_deg", "translation_noise_m", "match", "sensor",
              "noise_bounds") + tuple(_MOCAP_ONLY)
#: Roles of ``mocap.columns`` (csv sources).
MOCAP_COLUMN_KEYS = tuple(DEFAULT_COLUMNS)
#: Keys of each ``cameras.<name>`` mapping, and of its ``intrinsics`` when that is a mapping.
CAMERA_KEYS = ("intrinsics", "model", "images", "poses", "rosbag", "topic", "video", "stamps",
               "start_time", "mocap", "time_offset", "intrinsics_images", "intrinsics_target",
               "refine_intrinsics", "crop")
CAMERA_INTRINSICS_KEYS = ("file", "camera")
#: Keys of ``cameras.<name>.poses`` when that is a mapping, and what its ``pose`` may say.
CAMERA_POSES_KEYS = ("file", "pose")
CAMERA_POSES_FRAMES = ("T_cam_target", "T_target_cam")


@dataclass(frozen=True)
class CameraSpec:
    """One camera of ``rig.yaml``; paths are absolute.

    Attributes
    ----------
    name : str
    intrinsics : Path or None
        None only for a camera given by precomputed ``poses``.
    intrinsics_camera : str or None
        Entry of a Kalibr camchain (``cam1``) when the intrinsics file holds several.
    images, poses, rosbag, video : Path or None
        Exactly one is set: a folder of time-stamped images, a TUM file of ``T_cam_target``
        (of ``T_target_cam`` with ``poses_inverted``), a bag whose ``topic`` holds the
        images, or a video file.
    poses_inverted : bool
        The ``poses`` file holds ``T_target_cam`` (rig.yaml ``poses: {file, pose:
        T_target_cam}``): each pose is inverted where it is read.
    topic, stamps, start_time : str or None, Path or None, float
        A bag's image topic; a video's or an image folder's frame stamps file
        (:mod:`multieye.io.frame_stamps`), or else a video's first frame's stamp (seconds,
        the others at its frame rate).
    mocap : MocapSpec or None
        This camera's own motion capture (otherwise the rig's).
    time_offset : float
        Seconds, motion-capture clock minus camera clock.
    model : str or None
        Lens model whose intrinsics are estimated from the recording (``pinhole-radtan``,
        ``pinhole-rational``, ``fisheye``); with ``intrinsics`` too, the model they must have.
    estimate_intrinsics : bool
        Whether the intrinsics are estimated: ``model`` without ``intrinsics``, or
        ``refine_intrinsics: true`` (the camera's, else the rig's).
    intrinsics_images : Path or None
        A folder of images without motion capture that only inform the intrinsics.
    intrinsics_target : TargetSpec or None
        Their board, when it is not the rig's ``target``.
    images_pattern : str or None
        Only the images of ``images`` whose names fit this pattern (``left*.jpg``; through
        sub-folders: ``*/left.jpg``).
    crop : (x, y, width, height) or None
        The camera's region of each recorded image (and of its ``intrinsics_images``):
        one half of a side-by-side stereo frame; its lens and detections are in its pixels.
    """

    name: str
    intrinsics: Path | None
    intrinsics_camera: str | None = None
    images: Path | None = None
    poses: Path | None = None
    poses_inverted: bool = False
    rosbag: Path | None = None
    topic: str | None = None
    video: Path | None = None
    stamps: Path | None = None
    start_time: float = 0.0
    mocap: MocapSpec | None = None
    time_offset: float = 0.0
    model: str | None = None
    estimate_intrinsics: bool = False
    intrinsics_images: Path | None = None
    intrinsics_target: TargetSpec | None = None
    images_pattern: str | None = None
    crop: tuple[int, int, int, int] | None = None

    @property
    def source(self) -> str:
        """``"images"``, ``"poses"``, ``"rosbag"`` or ``"video"``."""
        return next(s for s in _SOURCES if getattr(self, s) is not None)


@dataclass(frozen=True)
class Rig:
    """A loaded ``rig.yaml``.

    Attributes
    ----------
    path : Path
        The ``rig.yaml`` file (absolute).
    setup : {"eye-to-base", "eye-on-hand"}
    cameras : mapping of str to CameraSpec
        In file order (read-only).
    target : TargetSpec or None
        The first (or only) board; None when no camera has images.
    mocap : MocapSpec or None
        None when every camera has its own, or when the rig has no motion capture.
    sync_tolerance : float or None
        Seconds within which images of different cameras are one instant (None: default).
    sync : {"time", "name", "number", "order"}
        What makes images of different cameras one instant (docs/recordings.md): their stamps
        (within ``sync_tolerance``; or, for cameras paired by name, today's rule), or their
        names (equal stems, the last integer in the stem, the place in name order).
    targets : mapping of str to TargetSpec
        Every board by name, in file order (read-only): ``targets:``, or ``target:`` as the
        one board named ``"target"`` (:mod:`multieye.io.rig_targets`).  Left out, it is
        ``{"target": target}`` (empty without a target).
    """

    path: Path
    setup: str
    cameras: Mapping[str, CameraSpec]
    target: TargetSpec | None = None
    mocap: MocapSpec | None = field(default=None)
    sync_tolerance: float | None = None
    sync: str = "time"
    targets: Mapping[str, TargetSpec] | None = None

    def __post_init__(self):
        if self.targets is None:
            one = {} if self.target is None else {self.target.name: self.target}
            object.__setattr__(self, "targets", MappingProxyType(one))

    @property
    def has_mocap(self) -> bool:      # else the views the cameras share link the rig
        return self.mocap is not None or any(c.mocap is not None for c in self.cameras.values())

    @property
    def folder(self) -> Path:
        return self.path.parent

    def mocap_for(self, camera: str) -> MocapSpec:
        """The motion capture of a camera: its own, else the rig's."""
        own = self.cameras[camera].mocap
        return own if own is not None else self.mocap

    @property
    def frames(self) -> dict[str, str]:
        """The user's frame names by role: ``{"world": fixed, "marker" | "body": tracked}``
        (rig.yaml's ``pose:``; :func:`multieye.io.mocap.named_pose`)."""
        specs = [self.mocap_for(n) for n in self.cameras] + [self.mocap]
        names = next((m.frame_names for m in specs if m is not None),
                     ("world", SETUPS[self.setup]))
        return {"world": names[0], SETUPS[self.setup]: names[1]}


class _RigWide(NamedTuple):
    """What the reading of one rig.yaml knows beyond the mapping at hand: its checker (the
    document, for messages), the setup, the top-level ``mocap`` (``(raw mapping,
    MocapSpec)``, or ``({}, None)``) and the top-level ``refine_intrinsics``."""

    checker: _Checker
    setup: str
    top: tuple = ({}, None)
    refine_all: bool = False


def _mocap(rw: _RigWide, raw: Mapping, origin: Mapping[str, tuple], where: tuple) -> MocapSpec:
    """Build a MocapSpec from ``raw`` (written at ``where``); ``origin[key]`` is the key path
    of the mapping each key came from (a camera's own or the top-level ``mocap``)."""
    c = rw.checker

    def at(key):
        return origin[key] + (key,)

    if "file" not in raw:
        raise c.error("missing key 'file'", where)
    moving = SETUPS[rw.setup]
    names = None
    if "frames" in raw:
        names = raw["frames"]
        if not isinstance(names, list) or len(names) != 2:
            raise c.error(f"expected the two frame names [parent, child] of 'pose', got "
                          f"{names!r}", at("frames"))
        names = tuple(c.string(n, at("frames")) for n in names)
    pose = (c.string(raw["pose"], at("pose")) if "pose" in raw
            else None if names is not None else f"T_world_{moving}")
    fixed = c.string(raw["fixed_frame"], at("fixed_frame")) if "fixed_frame" in raw else None
    try:
        pose, frame_names = named_pose(pose, moving, names, fixed)
    except ValueError as exc:
        key = ("fixed_frame" if "fixed_frame" in str(exc) and fixed is not None
               else "pose" if "pose" in raw else "frames")
        raise c.error(str(exc), at(key)) from None
    fmt = raw.get("format")
    if fmt is not None:
        c.choice(fmt, at("format"), MOCAP_FORMATS)
    if STEM in str(raw["file"]):
        if fmt is not None:
            raise c.error("a file name with {stem} is one pose file beside each image; leave "
                          "out 'format'", at("format"))
        fmt, file = "pose-files", stem_pattern(c, c.string(raw["file"], at("file")),
                                               at("file"))
    match = c.choice(raw.get("match", "time"), at("match") if "match" in raw else where,
                     ("time", "image", "order"))
    if match != "time":
        if fmt is not None:
            table = "with an 'image' column" if match == "image" else "in image-name order"
            raise c.error(f"match: {match} reads a table {table}; leave out "
                          f"'format'{' and {stem}' if fmt == 'pose-files' else ''}", at("match"))
        fmt, file = "pose-table", c.path(raw["file"], at("file"), "file")
    elif fmt == "pose-files":
        pass
    elif fmt == "rosbag" or fmt is None:
        file = c.path(raw["file"], at("file"), "file or bag")
    else:
        file = c.path(raw["file"], at("file"), "file")
    if fmt is None:
        fmt = sniff_mocap_format(file)
    kw = {"match": match} if fmt == "pose-table" else {}
    for key, formats in _MOCAP_ONLY.items():
        if key in raw and fmt not in formats:
            raise c.error(f"applies to {', '.join(formats)} sources only (this one is {fmt})",
                          at(key))
    if fmt == "rosbag" and "topic" not in raw:
        raise c.error("missing key 'topic' (required for a rosbag source)", where)
    for key in ("topic", "rigid_body", "parent_frame", "child_frame"):
        if key in raw:
            kw[key] = c.string(raw[key], at(key))
    if "unit" in raw:
        kw["unit"] = c.choice(raw["unit"], at("unit"), tuple(LENGTH_UNITS))
    if "duplicates" in raw:
        kw["duplicates"] = c.choice(raw["duplicates"], at("duplicates"), ("error", "drop"))
    if "rotation" in raw:
        try:
            kw["rotation"] = check_rotation(raw["rotation"])
        except ValueError as exc:
            raise c.error(str(exc), at("rotation")) from None
    if "values" in raw:
        try:
            kw["values"] = check_values(raw["values"], kw.get("rotation", "quaternion-xyzw"),
                                        stamped=fmt == "tum")
        except ValueError as exc:
            raise c.error(str(exc), at("values")) from None
    if "key" in raw:
        kw["key"] = c.string(raw["key"], at("key"))
    if "columns" in raw:
        cols = c.mapping(raw["columns"], at("columns"), MOCAP_COLUMN_KEYS)
        kw["columns"] = MappingProxyType({k: c.string(v, at("columns") + (k,))
                                          for k, v in cols.items()})
    tol = 0.03
    if "time_tolerance" in raw:
        tol = c.number(raw["time_tolerance"], at("time_tolerance"), positive=True,
                       maximum=MAX_TIME_TOLERANCE_S, unit="seconds")
    if "rotation_noise_deg" in raw:
        kw["rot_sigma_rad"] = math.radians(c.number(
            raw["rotation_noise_deg"], at("rotation_noise_deg"), positive=True,
            maximum=MAX_ROTATION_NOISE_DEG, unit="degrees"))
    if "translation_noise_m" in raw:
        kw["trans_sigma_m"] = c.number(raw["translation_noise_m"], at("translation_noise_m"),
                                       positive=True, maximum=MAX_TRANSLATION_NOISE_M,
                                       unit="metres")
    kw.update(_c.sensor_keys(c, raw, at))
    if frame_names != ("world", moving):
        kw["frames"] = frame_names
    return MocapSpec(file, pose, tol, fmt, **kw)


def _camera_mocap(rw: _RigWide, own, where: tuple) -> MocapSpec:
    """A camera's own motion capture, completed from the top-level section ``rw.top``:
    ``pose``, ``frames``, ``fixed_frame``,
    ``time_tolerance`` and the noise keys are always inherited; the format-specific keys only
    when the camera's file has the top-level file's format (a camera with a TUM file under a
    rosbag rig does not inherit ``topic``)."""
    c = rw.checker
    if isinstance(own, Mapping):
        c.mapping(own, where, MOCAP_KEYS)
    else:
        own = {"file": c.string(own, where)}
    top_raw, top_spec = rw.top
    inherit = [k for k in top_raw if k not in own]
    if "file" in own and top_spec is not None:
        fmt = own.get("format")
        if STEM in str(own["file"]):
            fmt = "pose-files"
        elif own.get("match", top_raw.get("match")) in ("image", "order"):   # a table
            fmt = "pose-table"
        elif fmt is None:
            fmt = sniff_mocap_format(c.path(own["file"], where + ("file",), "file or bag"))
        if fmt != top_spec.format:
            inherit = [k for k in inherit if k in ("pose", "frames", "fixed_frame",
                                                   "time_tolerance", "rotation_noise_deg",
                                                   "translation_noise_m", "sensor",
                                                   "noise_bounds")]
    merged = {**{k: top_raw[k] for k in inherit}, **own}
    origin = {**{k: ("mocap",) for k in inherit}, **{k: where for k in own}}
    return _mocap(rw, merged, origin, where)


def _camera(rw: _RigWide, name, raw) -> CameraSpec:
    c, keys = rw.checker, ("cameras", name)
    c.mapping(raw, keys, CAMERA_KEYS)
    sources = [s for s in _SOURCES if s in raw]
    if len(sources) != 1:
        raise c.error(f"expected exactly one of {', '.join(_SOURCES)}, got "
                      f"{', '.join(sources) or 'none'}", keys)
    if ("topic" in raw) != ("rosbag" in raw):
        raise c.error("'topic' goes with 'rosbag' (the image topic of the bag)", keys)
    lens = _lens(c, raw, keys, sources[0], rw.refine_all)
    if "intrinsics" not in raw and "model" not in raw and sources[0] != "poses":
        raise c.error("missing key 'intrinsics' or 'model' (intrinsics to find the target in "
                      "the images, or the lens model to estimate them in; only a camera "
                      "given by precomputed 'poses' may go without)", keys)
    intr = raw.get("intrinsics")
    camera = None
    if intr is None:
        intr_path = None
    elif isinstance(intr, Mapping):
        c.mapping(intr, keys + ("intrinsics",), CAMERA_INTRINSICS_KEYS, ("file",))
        if "camera" in intr:            # a name, or an index (Basalt's 1: YAML's integer)
            given = intr["camera"]
            if isinstance(given, bool) or not isinstance(given, (str, int)):
                raise c.error(f"expected a camera name or index, got {shown(given)}",
                              keys + ("intrinsics", "camera"))
            camera = c.string(str(given), keys + ("intrinsics", "camera"))
        intr_path = c.path(intr["file"], keys + ("intrinsics", "file"), "file")
    else:
        intr_path = c.path(intr, keys + ("intrinsics",), "file")
    kw = {"intrinsics_camera": camera}
    source = sources[0]
    kind = "folder" if source == "images" else "file or bag" if source == "rosbag" else "file"
    if source == "images":
        kw["images"], kw["images_pattern"] = images_key(c, raw["images"], keys + ("images",))
    elif source == "poses" and isinstance(raw["poses"], Mapping):
        at = keys + ("poses",)
        c.mapping(raw["poses"], at, CAMERA_POSES_KEYS, ("file",))
        kw["poses"] = c.path(raw["poses"]["file"], at + ("file",), "file")
        pose = c.choice(raw["poses"].get("pose", "T_cam_target"), at + ("pose",),
                        CAMERA_POSES_FRAMES)
        kw["poses_inverted"] = pose == "T_target_cam"
    else:
        kw[source] = c.path(raw[source], keys + (source,), kind)
    if "topic" in raw:
        kw["topic"] = c.string(raw["topic"], keys + ("topic",))
    kw.update(video_keys(c, raw, keys))
    kw.update(crop_key(c, raw, keys))
    if "time_offset" in raw:
        kw["time_offset"] = c.number(raw["time_offset"], keys + ("time_offset",),
                                     maximum=MAX_TIME_OFFSET_S, unit="seconds")
    if "mocap" in raw:
        kw["mocap"] = _camera_mocap(rw, raw["mocap"], keys + ("mocap",))
    return CameraSpec(str(name), intr_path, **kw, **lens)


def _lens(c: _Checker, raw, keys, source: str, refine_all: bool) -> dict:
    """The keys that decide whether a camera's intrinsics are estimated, checked together."""
    out: dict = {}
    if "model" in raw:
        out["model"] = model_key(c, raw["model"], keys + ("model",), tuple(LENS_MODELS))
        if source == "poses":
            raise c.error("a camera given by precomputed 'poses' has no images to estimate "
                          "its intrinsics from; leave out 'model'", keys + ("model",))
    refine = None
    if "refine_intrinsics" in raw:
        refine = c.boolean(raw["refine_intrinsics"], keys + ("refine_intrinsics",))
        if refine is False and "intrinsics" not in raw and "model" in raw:
            raise c.error("'refine_intrinsics: false' but no 'intrinsics' to hold fixed: a "
                          "camera with only a 'model' has its intrinsics estimated",
                          keys + ("refine_intrinsics",))
        if refine and source == "poses":
            raise c.error("a camera given by precomputed 'poses' has no images to refine "
                          "its intrinsics with", keys + ("refine_intrinsics",))
    estimate = ("model" in raw and "intrinsics" not in raw) or (
        source != "poses" and (refine if refine is not None else refine_all))
    out["estimate_intrinsics"] = bool(estimate)
    if "intrinsics_images" in raw:
        if not estimate:
            raise c.error("images for the intrinsics only, but this camera's intrinsics are "
                          "held fixed: give 'model' instead of 'intrinsics', or "
                          "'refine_intrinsics: true'", keys + ("intrinsics_images",))
        out["intrinsics_images"] = c.path(raw["intrinsics_images"],
                                          keys + ("intrinsics_images",), "folder")
    if "intrinsics_target" in raw:
        if "intrinsics_images" not in raw:
            raise c.error("'intrinsics_target' describes the board of 'intrinsics_images', "
                          "which this camera does not have", keys + ("intrinsics_target",))
        out["intrinsics_target"] = _target(c, raw["intrinsics_target"],
                                           keys + ("intrinsics_target",))
    return out


def load_rig(path: str | os.PathLike) -> Rig:
    """Load and check ``rig.yaml`` (or the ``rig.yaml`` of a dataset folder).

    Raises
    ------
    DatasetError
        The first problem found, naming the file, the line of the key and what was expected.
    """
    p = as_path(path, "dataset (a folder with rig.yaml, or the rig.yaml)")
    if p.is_dir():
        others = [] if (p / "rig.yaml").exists() else [
            n for n in ("rig.yml", "Rig.yaml", "RIG.yaml", "rig.yaml.txt") if (p / n).is_file()]
        if others:
            raise DatasetError(f"no rig.yaml in the folder, but {others[0]}: name it rig.yaml, "
                               f"or give the file itself ({p / others[0]})", path=p)
        p = p / "rig.yaml"
    no_link_loop(p)     # a rig.yaml that is a link: its paths are relative to the real file
    doc = load_yaml(p.resolve() if p.is_symlink() else p,    # else named as typed
                    what="rig description (rig.yaml)")
    c = _Checker(doc)
    raw = c.mapping(doc.data if doc.data is not None else {}, (), TOP_LEVEL_KEYS, ("cameras",))
    setup, sync, any_mocap = links_keys(c, raw, tuple(SETUPS))
    cams_raw = raw["cameras"]
    if not isinstance(cams_raw, Mapping) or not cams_raw:
        raise c.error("expected a mapping of camera name -> camera, with at least one camera",
                      ("cameras",))
    mocap = None
    if "mocap" in raw:
        c.mapping(raw["mocap"], ("mocap",), MOCAP_KEYS, ("file",))
        mocap = _mocap(_RigWide(c, setup), raw["mocap"], {k: ("mocap",) for k in raw["mocap"]},
                       ("mocap",))
    rw = _RigWide(c, setup, (dict(raw["mocap"]) if mocap is not None else {}, mocap),
                  c.boolean(raw["refine_intrinsics"], ("refine_intrinsics",))
                  if "refine_intrinsics" in raw else False)
    cameras, taken = {}, {}
    for name, cam_raw in cams_raw.items():
        problem = camera_name_problem(name, taken)      # names become file names (outputs)
        if problem is not None:
            raise c.error(f"camera name {shown(name)} {problem}; a camera name is {NAME_RULE}",
                          ("cameras", name))
        cam = _camera(rw, name, cam_raw)
        camera_link(c, name, cam.mocap or mocap, cam.source, any_mocap)
        if any_mocap and (cam.mocap or mocap).by_name and cam.source != "images":
            raise c.error("poses matched by image name ({stem}, match: image or order) need "
                          "a folder of 'images'", ("cameras", name))
        cameras[cam.name] = cam
    named = {n: (cs.mocap or mocap).frame_names for n, cs in cameras.items() if any_mocap}
    if len(set(named.values())) > 1:
        first, other = next(iter(named)), next(n for n in named
                                                if named[n] != next(iter(named.values())))
        raise c.error(f"camera {other} names the motion capture's frames "
                      f"{list(named[other])}, camera {first} {list(named[first])}: one rig has "
                      "one fixed and one tracked frame; give every camera the same 'pose'",
                      ("cameras", other))
    targets = read_targets(c, raw, cameras)
    if not targets and any(cam.source != "poses" for cam in cameras.values()):
        needing = [n for n, cam in cameras.items() if cam.source != "poses"]
        raise DatasetError(f"missing key 'target': cameras with images ({', '.join(needing)}) "
                           "need the calibration board described", path=doc.path, line=1)
    target = next(iter(targets.values()), None)
    return Rig(doc.path.resolve(), setup, MappingProxyType(cameras), target, mocap, sync,
               sync_keys(c, raw, cameras, mocap), MappingProxyType(targets))


def read_camera_intrinsics(camera: CameraSpec) -> Intrinsics:
    """Intrinsics of a rig camera (its camchain entry: ``intrinsics_camera``, else the only
    one, else the one named like the camera).  DatasetErrors name the camera."""
    try:
        return read_intrinsics(camera.intrinsics, camera.intrinsics_camera, prefer=camera.name)
    except DatasetError as exc:
        raise DatasetError(exc.reason, path=exc.path, line=exc.line, camera=camera.name) from None
