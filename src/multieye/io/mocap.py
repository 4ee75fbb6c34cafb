"""One entry point for motion-capture files: :class:`MocapSpec` -> :class:`Trajectory`.

``rig.yaml``'s ``mocap:`` section (docs/rig-yaml.md, section 4) becomes a :class:`MocapSpec`;
:func:`read_mocap` dispatches to the reader of its format and returns the poses with
``world`` as the parent frame, whichever direction the file stores them in.

Format recognition (:func:`sniff_mocap_format`), when the spec does not name one:
a ROS 2 bag folder or a ``.bag`` / ``.db3`` / ``.mcap`` file is ``rosbag``; a ``.csv`` file is
``optitrack`` if it starts with ``Format Version``, ``vicon`` if it starts with a Nexus section
line (``Segments``, ``Trajectories``...), else ``csv``; anything else is ``tum``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from multieye.core.arguments import as_path
from multieye.core.errors import DatasetError, InputError
from multieye.io.mocap_csv import read_pose_csv
from multieye.io.mocap_exports import (csv_flavour, read_optitrack_csv, read_vicon_csv,
                                      refuse_qualisys)
from multieye.io.pose_files import STEM, PoseFormat
from multieye.io.stamped_table import read_stamped_table
from multieye.io.rosbag import read_bag_trajectory
from multieye.io.trajectory import Trajectory
from multieye.io.tum import read_tum

__all__ = ["MOCAP_FORMATS", "MocapSpec", "read_mocap", "sniff_mocap_format", "pose_frames",
           "named_pose", "ROLE_FRAMES", "RESERVED_FRAMES"]

MOCAP_FORMATS = ("tum", "csv", "optitrack", "vicon", "rosbag")
_POSE = re.compile(r"^T_([A-Za-z0-9]+)_([A-Za-z0-9]+)$")


def pose_frames(pose: str) -> tuple[str, str]:
    """``"T_world_marker"`` -> ``("world", "marker")``; ValueError for other shapes."""
    m = _POSE.match(pose)
    if not m:
        raise ValueError(f"expected a transform name T_<parent>_<child>, got {pose!r}")
    return m.group(1), m.group(2)


#: The frames docs/conventions.md names: the motion capture's fixed frame, and the tracked
#: frame of each setup (``marker`` eye-to-base, ``body`` eye-on-hand).
ROLE_FRAMES = ("world", "marker", "body")
_FRAME_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_]*$")
#: Frame names the outputs use for frames other than the motion capture's (``T_world_target``,
#: ``T_body_cam``, ``T_ref_cam``): refused as names of the motion capture's frames.
RESERVED_FRAMES = ("target", "cam", "ref")


def _check_frame_name(name) -> str:
    if not isinstance(name, str) or not _FRAME_NAME.match(name):
        raise ValueError(f"a frame name is letters, digits and '_' (starting with a letter or "
                         f"digit), got {name!r}")
    return name


#: Name starts of frames that move (a robot's flange or tool) and of frames that stay (its
#: base, a map): ``T_tool0_base`` without ``fixed_frame`` would make the tool the fixed one.
_MOVING_LIKE = ("tool", "flange", "tcp", "ee", "end", "gripper", "wrist", "hand")
_FIXED_LIKE = ("base", "map", "odom", "mocap", "vicon", "optitrack")


def _parent_fixed(parent: str, child: str) -> str:
    """``parent``, the fixed frame by default; ValueError naming both readings when its name
    is a moving frame's and the child's a fixed one's (``T_tool0_base``)."""
    if parent.lower().startswith(_MOVING_LIKE) and child.lower().startswith(_FIXED_LIKE):
        raise ValueError(
            f"T_{parent}_{child} reads as the pose of {child} in {parent}, with {parent} "
            f"fixed (the parent is the fixed frame), but {child} names a fixed frame and "
            f"{parent} a moving one: if the rows hold {parent} in {child}, write pose: "
            f"T_{child}_{parent}; if they hold {child} in {parent}, add fixed_frame: "
            f"{child} (they are then inverted)")
    return parent


def named_pose(pose: str | None, moving: str, frames: tuple[str, str] | None = None,
               fixed: str | None = None) -> tuple[str, tuple[str, str]]:
    """Read rig.yaml's ``pose: T_<parent>_<child>`` with the user's own frame names.

    The file holds the pose of ``child`` in ``parent``.  Which of the two is the fixed frame
    (the role docs/conventions.md calls ``world``) and which the tracked one (``moving``:
    ``marker`` eye-to-base, ``body`` eye-on-hand):

    - a frame named ``world`` is the fixed one; a frame named ``moving`` is the tracked one;
    - otherwise the parent is fixed and the child tracked (``T_base_tool0``: a robot's
      base and its flange); a moving frame's name over a fixed one's (``T_tool0_base``) is
      refused as ambiguous (:func:`_parent_fixed`);
    - ``fixed`` overrides all of these: a file holding the inverse, the base in the flange,
      is ``T_tool0_base`` with ``fixed="base"``.

    Parameters
    ----------
    pose : str or None
        ``T_<parent>_<child>``.  With more than one ``_`` the split is ambiguous unless one
        reading names ``world`` or ``moving``; ``frames`` then gives the two names.  None:
        ``T_<frames[0]>_<frames[1]>`` (``frames`` required).
    moving : {"marker", "body"}
        The tracked frame's role in the setup.
    frames : (str, str), optional
        ``(parent, child)`` spelled out (names may hold ``_``); must agree with ``pose``.
    fixed : str, optional
        Which of the two is the fixed frame (rig.yaml's ``fixed_frame``).

    Returns
    -------
    pose : str
        The role form the readers use: ``T_world_<moving>``, or ``T_<moving>_world`` for a file
        holding the inverse.
    names : (str, str)
        The user's names of the fixed and of the tracked frame.

    Raises
    ------
    ValueError
        A malformed or ambiguous name, equal names, or the other setup's role name
        (``T_world_marker`` for eye-on-hand).

    Examples
    --------
    >>> named_pose("T_base_tool0", "body")
    ('T_world_body', ('base', 'tool0'))
    >>> named_pose("T_marker_world", "marker")
    ('T_marker_world', ('world', 'marker'))
    >>> named_pose("T_base_link_tool0", "body", ("base_link", "tool0"))
    ('T_world_body', ('base_link', 'tool0'))
    """
    roles = ("world", moving)
    if frames is not None:
        parent, child = (_check_frame_name(f) for f in frames)
        if pose is not None and pose != f"T_{parent}_{child}":
            raise ValueError(f"pose {pose!r} does not match frames [{parent}, {child}] "
                             f"(expected T_{parent}_{child})")
    else:
        if not isinstance(pose, str) or not pose.startswith("T_"):
            raise ValueError(f"expected a transform name T_<parent>_<child>, got {pose!r}")
        parts = pose[2:].split("_")
        splits = [("_".join(parts[:k]), "_".join(parts[k:])) for k in range(1, len(parts))]
        splits = [s for s in splits if all(_FRAME_NAME.match(f) for f in s)]
        if len(splits) > 1:
            splits = [s for s in splits if s[0] in roles or s[1] in roles] or splits
        if not splits:
            raise ValueError(f"expected a transform name T_<parent>_<child>, got {pose!r}")
        if len(splits) > 1:
            readings = " or ".join(f"[{a}, {b}]" for a, b in splits)
            raise ValueError(f"{pose!r} can be read as {readings}: give the two names as "
                             f"frames: [parent, child]")
        parent, child = splits[0]
    if parent == child:
        raise ValueError(f"the parent and child frames of T_{parent}_{child} are the same")
    for name in (parent, child):
        if name in RESERVED_FRAMES:
            raise ValueError(f"{name!r} names a frame multieye's outputs already have (target "
                             "board, cameras, the reference camera): name the tracked frame "
                             "e.g. board, flange or tool0, the fixed one e.g. base or mocap")
    others = [f for f in ROLE_FRAMES if f not in roles]
    if fixed is not None:
        if fixed not in (parent, child):
            raise ValueError(f"fixed_frame {fixed!r} is not one of the frames of the pose, "
                             f"{parent} and {child}")
        if moving == fixed or (fixed != "world" and "world" in (parent, child)):
            raise ValueError(f"fixed_frame {fixed!r} contradicts the role names: 'world' is "
                             f"fixed and {moving!r} is tracked")
    elif "world" in (parent, child):
        fixed = "world"
    elif moving in (parent, child):
        fixed = child if parent == moving else parent
    else:
        fixed = _parent_fixed(parent, child)
    tracked = child if fixed == parent else parent
    if tracked in others or fixed in others:
        setup = "eye-to-base" if moving == "marker" else "eye-on-hand"
        raise ValueError(f"expected T_world_{moving} (or T_{moving}_world) for {setup}, got "
                         f"{pose or f'T_{parent}_{child}'!r}; your own frame names also do: "
                         f"T_<fixed>_<tracked>, e.g. T_base_tool0")
    return (f"T_world_{moving}" if fixed == parent else f"T_{moving}_world"), (fixed, tracked)


@dataclass(frozen=True)
class MocapSpec:
    """Where and how to read motion-capture poses.

    Attributes
    ----------
    file : Path
        File (or ROS 2 bag folder), absolute or relative to the working folder.
    pose : str
        What each sample is: ``T_world_marker`` / ``T_world_body`` (or their inverses
        ``T_marker_world`` / ``T_body_world``).
    time_tolerance : float
        Seconds allowed between an image and its motion-capture sample.
    format : {"tum", "csv", "optitrack", "vicon", "rosbag"}
    topic : str or None
        Pose topic (``rosbag``).
    unit : {"m", "cm", "mm"} or None
        Translation unit for ``tum``, ``csv`` and ``rosbag`` (OptiTrack and Vicon exports state
        their own).  None: metres (or a ``csv`` header's unit suffix).
    rigid_body : str or None
        OptiTrack rigid body or Vicon segment name (needed when the export has several).
    parent_frame, child_frame : str or None
        ROS frame ids selecting a transform of a ``/tf`` or TransformStamped topic.
    columns : mapping or None
        ``csv`` header names per role (``t tx ty tz qx qy qz qw``).
    duplicates : {"error", "drop"}
        ``tum`` and ``csv``: a sample with the previous sample's stamp is an error, or dropped.
    key, values, rotation :
        ``pose-files`` (``file`` is a pattern with ``{stem}``, relative to each camera's image
        folder): the JSON key of the pose, the order of plain numbers and the rotation
        convention (:mod:`multieye.io.pose_files`); ``values`` and ``rotation`` also for
        ``pose-table`` and ``tum`` (then ``values`` include ``t``).
    match : {"time", "image", "order"}
        ``image``: ``file`` is a table whose ``image`` column names the image of each pose;
        ``order``: a table whose rows follow the images sorted by name (both ``pose-table``);
        ``values``, ``rotation`` and ``unit`` read its numbers.
    frames : (str, str) or None
        The user's names of the fixed and of the tracked frame (rig.yaml's ``pose:``,
        :func:`named_pose`); None: ``world`` and the role name in ``pose``.
    sensor : {"motion-capture", "robot"} or None
        What measures the poses (rig.yaml's ``sensor``); None: not stated (inferred from the
        source by :func:`multieye.estimate.sensor.sensor_bounds`).
    noise_bounds : (float, float) or None
        The largest plausible noise per pose of this sensor, rotation (radians) and
        translation (metres) (rig.yaml's ``noise_bounds``); None for either: the sensor's.
    """

    file: Path
    pose: str = "T_world_marker"
    time_tolerance: float = 0.03
    format: str = "tum"
    topic: str | None = None
    unit: str | None = None
    rigid_body: str | None = None
    parent_frame: str | None = None
    child_frame: str | None = None
    columns: Mapping[str, str] | None = None
    rot_sigma_rad: float | None = None
    trans_sigma_m: float | None = None
    duplicates: str = "error"
    key: str | None = None
    values: tuple[str, ...] | None = None
    rotation: str = "quaternion-xyzw"
    match: str = "time"
    frames: tuple[str, str] | None = None
    sensor: str | None = None
    noise_bounds: tuple[float | None, float | None] | None = None

    @property
    def by_name(self) -> bool:
        """Paired with the images by name: one pose file beside each image (``file`` holds
        ``{stem}``), or a table with an ``image`` column or in image order (``match``);
        :mod:`multieye.io.pose_files` reads them, not :func:`read_mocap`."""
        return STEM in str(self.file) or self.match in ("image", "order")

    @property
    def moving_frame(self) -> str:
        """The frame tracked relative to ``world`` (``marker`` or ``body``)."""
        a, b = pose_frames(self.pose)
        return b if a == "world" else a

    @property
    def frame_names(self) -> tuple[str, str]:
        """The names outputs give the fixed and the tracked frame (``frames``, or ``world``
        and :attr:`moving_frame`)."""
        return self.frames if self.frames is not None else ("world", self.moving_frame)


def sniff_mocap_format(path: str | os.PathLike) -> str:
    """The format of a motion-capture file from its name and first line (module docstring)."""
    p = as_path(path, "motion-capture file")
    if not p.exists():
        raise DatasetError("motion-capture file not found", path=p)
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "rosbag"
        raise DatasetError("expected a motion-capture file or a ROS 2 bag folder "
                           "(with metadata.yaml), found a folder", path=p)
    suffix = p.suffix.lower()
    if suffix in (".bag", ".db3", ".mcap"):
        return "rosbag"
    if suffix == ".csv":
        return csv_flavour(p)
    return "tum"


def read_mocap(spec: MocapSpec) -> Trajectory:
    """Read the poses a spec describes, as ``T_world_<moving frame>``.

    Returns
    -------
    Trajectory
        ``parent == "world"``; rows stored as ``T_<moving>_world`` are inverted.

    Raises
    ------
    DatasetError
        From the format's reader (file, line and what was expected), or a spec whose options do
        not fit its format.
    """
    if not isinstance(spec, MocapSpec):
        raise InputError(f"read_mocap takes a MocapSpec, got {type(spec).__name__}")
    try:
        parent, child = pose_frames(spec.pose)
    except (TypeError, ValueError) as exc:
        raise InputError(f"MocapSpec.pose: {exc}") from None
    fmt = spec.format
    if spec.by_name:
        raise InputError("read_mocap reads poses stamped in time; poses matched by image name "
                         "are read by multieye.io.pose_files")
    if fmt not in MOCAP_FORMATS:
        raise DatasetError(f"motion-capture format must be one of {', '.join(MOCAP_FORMATS)}, "
                           f"got {fmt!r}", path=spec.file)
    try:
        traj = _read_format(spec, fmt, parent, child)
    except DatasetError as exc:
        if not (exc.reason.startswith("duplicate time stamp") and spec.duplicates == "error"
                and fmt != "rosbag"):   # rig.yaml's duplicates is not for bags: not advised
            raise
        raise DatasetError(f"{exc.reason}; give duplicates: drop under mocap in rig.yaml to keep "
                           "the first of equal stamps", path=exc.path, line=exc.line) from None
    return traj if traj.parent == "world" else traj.inverted()


def _read_format(spec: MocapSpec, fmt: str, parent: str, child: str) -> Trajectory:
    """The trajectory of ``spec``'s file in its format ``fmt``, under its own frames."""
    if fmt == "tum":
        refuse_qualisys(spec.file)
    if fmt == "tum" and (spec.values is not None or spec.rotation != "quaternion-xyzw"):
        traj = read_stamped_table(spec.file, PoseFormat(spec.rotation, spec.values, None,
                                                        spec.unit or "m"),
                                  parent=parent, child=child, duplicates=spec.duplicates)
    elif fmt == "tum":
        traj = read_tum(spec.file, unit=spec.unit or "m", parent=parent, child=child,
                        duplicates=spec.duplicates)
    elif fmt == "csv":
        traj = read_pose_csv(spec.file, columns=spec.columns, unit=spec.unit, parent=parent,
                             child=child, duplicates=spec.duplicates)
    elif fmt == "optitrack":
        traj = read_optitrack_csv(spec.file, spec.rigid_body, parent=parent, child=child,
                                  duplicates=spec.duplicates)
    elif fmt == "vicon":
        traj = read_vicon_csv(spec.file, spec.rigid_body, parent=parent, child=child,
                              duplicates=spec.duplicates)
    else:
        if not spec.topic:
            raise DatasetError("a rosbag motion-capture source needs a topic", path=spec.file)
        traj = read_bag_trajectory(spec.file, spec.topic, parent_frame=spec.parent_frame,
                                   child_frame=spec.child_frame, unit=spec.unit or "m",
                                   parent=parent, child=child)
    return traj
