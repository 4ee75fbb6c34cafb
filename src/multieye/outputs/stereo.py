"""Stereo pairs of a calibration and their rectification, for the OpenCV and camera_info exports.

Cameras that saw the target at the same instants (``details.json``'s ``overlaps``) are stereo
pairs.  Each camera is rectified with one partner (ROS ``CameraInfo`` holds one rectification
per camera): in rig order, a camera not yet paired takes its first overlapping partner not yet
paired.  Within a pair the left camera (the one the other sits to the right of, +x of its
frame) comes first, so that the right camera's ``P[0, 3] = -f B`` as ROS expects.  The
rectification itself is OpenCV's (:func:`multieye.imaging.rectify.stereo_rectification`); a
pair OpenCV cannot rectify (a pinhole lens with a fisheye one, unknown image sizes) is named
in a note and left unrectified.

Synopsis
--------
>>> pairs, notes = stereo_pairs(record, intrinsics, overlaps)     # doctest: +SKIP
>>> rectified = per_camera(pairs)                                 # doctest: +SKIP
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.imaging.rectify import Rectification, stereo_rectification
from multieye.io.calibration_json import CalibrationRecord

__all__ = ["StereoPair", "stereo_pairs", "per_camera", "opencv_stereo_lines"]


@dataclass(frozen=True)
class StereoPair:
    """Two cameras rectified together: ``left``, ``right`` and OpenCV's rectification
    (``R_a``, ``P_a`` of ``left``; ``R_b``, ``P_b`` of ``right``)."""

    left: str
    right: str
    rectification: Rectification


def _matching(names: list[str], overlaps: Mapping[str, tuple[str, ...] | None]
              ) -> list[tuple[str, str]]:
    taken: set[str] = set()
    out = []
    for a in names:
        if a in taken:
            continue
        for b in names:
            if b != a and b not in taken and b in (overlaps.get(a) or ()):
                out.append((a, b))
                taken |= {a, b}
                break
    return out


def stereo_pairs(rec: CalibrationRecord, intrinsics: Mapping, overlaps: Mapping | None
                 ) -> tuple[list[StereoPair], list[str]]:
    """The rectified pairs of a calibration (module docstring) and notes on the pairs left
    unrectified.

    Parameters
    ----------
    rec : CalibrationRecord
    intrinsics : mapping of camera name to Intrinsics or None
    overlaps : mapping of camera name to tuple of camera names, or None
        The cameras each one saw the target together with; None: unknown (no pairs).
    """
    if not overlaps:
        return [], []
    T = {c.name: c.T_ref_cam for c in rec.cameras}
    pairs, notes = [], []
    for a, b in _matching([c.name for c in rec.cameras], overlaps):
        T_a_b = g.inv(T[a]) @ T[b]
        if T_a_b[0, 3] < 0:                          # b left of a: a is the right camera
            a, b, T_a_b = b, a, g.inv(T_a_b)
        try:
            if intrinsics.get(a) is None or intrinsics.get(b) is None:
                raise InputError("no intrinsics")
            rect = stereo_rectification(intrinsics[a], intrinsics[b], T_a_b)
        except InputError as exc:
            notes.append(f"no stereo rectification for {a} and {b} ({exc})")
            continue
        pairs.append(StereoPair(a, b, rect))
    return pairs, notes


def per_camera(pairs: list[StereoPair]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Camera name -> (R 3x3, P 3x4) of its rectification, for the cameras in a pair."""
    out = {}
    for p in pairs:
        out[p.left] = (p.rectification.R_a, p.rectification.P_a)
        out[p.right] = (p.rectification.R_b, p.rectification.P_b)
    return out


def opencv_stereo_lines(pairs: list[StereoPair], matrix) -> list[str]:
    """``stereo_pairs:`` of ``extrinsics.yaml``: per pair ``left``, ``right``, ``R1``, ``R2``,
    ``P1``, ``P2``, ``Q`` as OpenCV's ``stereoRectify`` names them; ``matrix(name, M,
    indent)`` writes one ``!!opencv-matrix``."""
    if not pairs:
        return []
    lines, ind = ["stereo_pairs:"], "      "
    for p in pairs:
        r = p.rectification
        lines += ["   -", f"{ind}left: {json.dumps(p.left)}", f"{ind}right: {json.dumps(p.right)}"]
        for name, M in (("R1", r.R_a), ("R2", r.R_b), ("P1", r.P_a), ("P2", r.P_b),
                        ("Q", r.Q)):
            lines += matrix(name, M, ind)
    return lines
