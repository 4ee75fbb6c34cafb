"""Readers of what :mod:`multieye.outputs.export` writes for ROS: the fixed joints of a URDF and
the ``static_transform_publisher`` lines of a tf-static script, so that tests and users can
check an export against ``calibration.json`` (the writers live in ``export``).
"""

from __future__ import annotations

import os
import shlex
import xml.etree.ElementTree as ET

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import DatasetError
from multieye.io.textfile import read_text
from multieye.core.geometry import rotation_from_rpy

__all__ = ["read_urdf_joints", "read_tf_static"]


def read_urdf_joints(path: str | os.PathLike) -> dict[tuple[str, str], np.ndarray]:
    """The fixed joints of a URDF: ``(parent, child) -> T_parent_child``.

    Raises
    ------
    DatasetError
        Not XML, or a joint without parent, child or a numeric ``origin``.
    """
    text = read_text(path, what="URDF file")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise DatasetError(f"invalid XML: {exc}", path=path, line=exc.position[0]) from None
    joints = {}
    for joint in root.iter("joint"):
        name = joint.get("name", "?")
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None or not parent.get("link") or not child.get("link"):
            raise DatasetError(f"joint {name!r} needs <parent link=...> and <child link=...>",
                               path=path)
        origin = joint.find("origin")
        values = {"xyz": [0.0] * 3, "rpy": [0.0] * 3}
        for key in values:
            text_value = origin.get(key) if origin is not None else None
            if text_value is not None:
                try:
                    values[key] = [float(v) for v in text_value.split()]
                except ValueError:
                    values[key] = []
                if len(values[key]) != 3:
                    raise DatasetError(f"joint {name!r}: origin {key} must be 3 numbers, got "
                                       f"{text_value!r}", path=path)
        joints[(parent.get("link"), child.get("link"))] = g.make_transform(
            rotation_from_rpy(values["rpy"]), values["xyz"])
    return joints


def read_tf_static(path: str | os.PathLike) -> dict[tuple[str, str], np.ndarray]:
    """The ``static_transform_publisher`` lines of a file: ``(frame_id, child) -> T``.

    Accepts the flag form written by :func:`tf_static_text` (``--x ... --child-frame-id``),
    with or without the ``ros2 run tf2_ros`` prefix and a trailing ``&``; other lines
    (comments, ``wait``) are skipped.

    Raises
    ------
    DatasetError
        A publisher line with an unknown flag, a missing value, a non-number or a quaternion
        that is not unit length, with its line number.
    """
    out = {}
    numbers = ("--x", "--y", "--z", "--qx", "--qy", "--qz", "--qw")
    for lineno, line in enumerate(read_text(path, what="tf file").splitlines(), start=1):
        try:
            words = shlex.split(line, comments=True)
        except ValueError as exc:
            raise DatasetError(f"cannot split the line: {exc}", path=path, line=lineno) from None
        if "static_transform_publisher" not in words:
            continue
        words = words[words.index("static_transform_publisher") + 1:]
        if words and words[-1] == "&":
            words = words[:-1]
        if len(words) % 2:
            raise DatasetError("expected --flag value pairs", path=path, line=lineno)
        args = dict(zip(words[::2], words[1::2]))
        unknown = sorted(set(args) - {*numbers, "--frame-id", "--child-frame-id"})
        if unknown or "--frame-id" not in args or "--child-frame-id" not in args:
            raise DatasetError("expected --x --y --z --qx --qy --qz --qw --frame-id "
                               f"--child-frame-id{'; unknown ' + ', '.join(unknown) if unknown else ''}",
                               path=path, line=lineno)
        try:
            v = {k: float(args.get(k, "1" if k == "--qw" else "0")) for k in numbers}
        except ValueError:
            raise DatasetError("translation and quaternion values must be numbers", path=path,
                               line=lineno) from None
        q = np.array([v["--qx"], v["--qy"], v["--qz"], v["--qw"]])
        if abs(np.linalg.norm(q) - 1.0) > 1e-6:
            raise DatasetError(f"quaternion norm is {np.linalg.norm(q):.6g}, expected 1",
                               path=path, line=lineno)
        out[(args["--frame-id"], args["--child-frame-id"])] = g.transform_from_quat(
            q, [v["--x"], v["--y"], v["--z"]])
    return out
