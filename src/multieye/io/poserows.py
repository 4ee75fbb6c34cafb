"""Rows of time-stamped poses read from a text file -> :class:`Trajectory`, with line numbers.

Shared by the TUM, CSV, OptiTrack and Vicon readers so that every format reports a non-unit
quaternion or a repeated time stamp the same way, naming the file and the line.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from multieye.core import geometry
from multieye.core.errors import DatasetError
from multieye.io.trajectory import Trajectory

__all__ = ["QUATERNION_TOLERANCE", "quaternion_poses", "trajectory_from_rows"]

#: Largest accepted ``| ||q|| - 1 |`` before a quaternion is rejected.
QUATERNION_TOLERANCE = 1e-3


def quaternion_poses(t_xyz: np.ndarray, q_xyzw: np.ndarray, *, path: str | os.PathLike,
                     lines: Sequence[int] | None, tolerance: float = QUATERNION_TOLERANCE,
                     what: str = "") -> np.ndarray:
    """Rigid transforms ``(N, 4, 4)`` from translations and ``(qx, qy, qz, qw)`` quaternions.

    Parameters
    ----------
    t_xyz : ndarray, shape (N, 3)
        Translations, metres.
    q_xyzw : ndarray, shape (N, 4)
        Quaternions, scalar last.
    path, lines : the file and the 1-based line of each row, for messages.  Without lines
        (a binary file), the message names the sample's index.
    tolerance : float
        Largest accepted ``| ||q|| - 1 |``; smaller deviations are normalised.
    what : str
        Prefix of the message (e.g. ``"topic /vicon/pose: "``).

    Raises
    ------
    DatasetError
        A quaternion is further than ``tolerance`` from unit norm (the message gives the norm).
    """
    q = np.asarray(q_xyzw, dtype=np.float64).reshape(-1, 4)
    norms = np.linalg.norm(q, axis=1)
    bad = np.abs(norms - 1.0) > tolerance
    if np.any(bad):
        i = int(np.argmax(bad))
        where = what if lines is not None else f"{what}sample {i}: "
        raise DatasetError(f"{where}quaternion (qx qy qz qw) must have unit norm, got norm "
                           f"{norms[i]:.6g} (tolerance {tolerance:g})", path=path,
                           line=None if lines is None else lines[i])
    return geometry.transform_from_quat(q / norms[:, None], t_xyz)


def trajectory_from_rows(stamps: np.ndarray, T: np.ndarray, *, path: str | os.PathLike,
                         lines: Sequence[int], parent: str, child: str,
                         stamps_ns: np.ndarray | None = None,
                         duplicates: str = "error") -> Trajectory:
    """A Trajectory from rows in file order; stamps must be strictly increasing.

    Parameters
    ----------
    stamps : ndarray, shape (N,)
        Seconds.
    T : ndarray, shape (N, 4, 4)
        ``T_parent_child`` of each row, metres.
    path, lines : the file and the 1-based line of each row.
    parent, child : frame names.
    stamps_ns : ndarray, shape (N,), int64, optional
    duplicates : {"error", "drop"}
        What to do with a row whose stamp equals the previous row's: raise, or keep only the
        first row of each run of equal stamps (for files written with too few digits).

    Raises
    ------
    DatasetError
        No rows, a stamp that goes back, or (``duplicates="error"``) a stamp that repeats;
        the message names both lines.
    """
    stamps = np.asarray(stamps, dtype=np.float64)
    if stamps.size == 0:
        raise DatasetError("no poses found", path=path)
    if duplicates not in ("error", "drop"):
        raise ValueError(f"duplicates must be 'error' or 'drop', got {duplicates!r}")
    key = stamps if stamps_ns is None else np.asarray(stamps_ns)
    if duplicates == "drop":
        keep = np.r_[True, np.diff(key) != 0]
        stamps, T, key = stamps[keep], np.asarray(T)[keep], key[keep]
        lines = [line for line, k in zip(lines, keep) if k]
        stamps_ns = None if stamps_ns is None else key
    steps = np.diff(key)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        what = "duplicate time stamp" if steps[i] == 0 else "time stamp goes back"
        raise DatasetError(f"{what}: {float(stamps[i + 1])!r} s after {float(stamps[i])!r} s "
                           f"on line {lines[i]}; stamps must be strictly increasing",
                           path=path, line=lines[i + 1])
    return Trajectory(stamps, T, parent, child, stamps_ns)
