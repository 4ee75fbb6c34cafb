"""TUM trajectory text files: ``t tx ty tz qx qy qz qw`` per line.

Format (as the TUM RGB-D benchmark defines it): one pose per line, time stamp in seconds
(or, as image names may be, integer nanoseconds of 16 to 19 digits: the first row decides),
translation, then the unit quaternion in the order ``qx qy qz qw`` (scalar last).  The pose of
each line is ``T_parent_child`` (for motion capture ``T_world_marker``, for precomputed camera
poses ``T_cam_target``, docs/rig-yaml.md).  Accepted here as well: commas instead of (or
mixed with) spaces, ``#`` comments anywhere on a line, blank lines.

Choices
-------
- Quaternions whose norm differs from 1 by more than
  :data:`multieye.io.poserows.QUATERNION_TOLERANCE` (1e-3) are rejected
  (a file that is not what it claims); smaller deviations (rounding in the writer) are
  normalised.
- Stamps must be strictly increasing; a duplicate or a step back names both lines
  (``duplicates="drop"`` keeps the first of equal stamps instead).
- ``unit="mm"`` (or ``"cm"``) converts translations to metres on reading and from metres on
  writing.
- A line with ``nan`` or ``inf``, a translation beyond 1e4 m or a stamp beyond 1e10 s is left
  out and listed in ``Trajectory.skipped`` with its line; the other lines are read
  (:func:`multieye.io.poserows.screen_rows`).

>>> from multieye.io.tum import read_tum
>>> traj = read_tum("mocap.txt", parent="world", child="marker")   # doctest: +SKIP
"""

from __future__ import annotations

import os

from multieye.core import geometry
from multieye.io.atomic import atomic_output
from multieye.core.errors import DatasetError
from multieye.io.poserows import QuaternionRows
from multieye.io.textfile import (NumberTable, count_lines, is_nanoseconds, length_scale,
                                  line_blocks, split_fields)
from multieye.io.trajectory import Trajectory

__all__ = ["read_tum", "write_tum", "TUM_COLUMNS"]

TUM_COLUMNS = ("t", "tx", "ty", "tz", "qx", "qy", "qz", "qw")
#: What a row of another count may hold, and the rig.yaml keys that read it (docs/rig-yaml.md,
#: section 4).
_COUNT_HINTS = {
    7: "t x y z and three rotation numbers? give rotation: rotvec (radians) or "
       "euler-<axes>-deg under mocap in rig.yaml (values: [...] for another order)",
    13: "t and the top three rows of a 4x4 pose? give rotation: matrix under mocap in rig.yaml",
    17: "t and a 4x4 pose, row-major? give rotation: matrix under mocap in rig.yaml",
}
#: Rows parsed into numbers before they become poses: the file is read line by line and never
#: held whole (a 5-million-row file, 180 MB, reads within 1 GB of memory).
_BLOCK = 1 << 14


def read_tum(path: str | os.PathLike, *, unit: str = "m", parent: str = "world",
             child: str = "marker", duplicates: str = "error") -> Trajectory:
    """Read a TUM trajectory file.

    Parameters
    ----------
    path : path-like
    unit : {"m", "cm", "mm"}
        Unit of the translations in the file; converted to metres.
    parent, child : str
        Frame names of the poses: each line is ``T_parent_child``.
    duplicates : {"error", "drop"}
        A line with the same stamp as the line before is an error, or (``"drop"``) is skipped:
        some recorders print stamps with too few digits for their rate.

    Returns
    -------
    Trajectory
        Stamps in seconds as written, poses in metres.

    Raises
    ------
    DatasetError
        With the file and 1-based line: a row without 8 entries, a cell that is not a
        number, a non-unit quaternion, stamps that repeat or go back, an empty file, or no
        usable row at all.  Rows with non-finite or absurd values are left out and listed in
        ``skipped`` of the result.
    """
    scale = length_scale(unit, path=path)
    rows = QuaternionRows(path, TUM_COLUMNS, scale,
                          capacity=count_lines(path, what="trajectory file"))
    nanoseconds = None
    for contents, numbers in line_blocks(path, what="trajectory file", size=_BLOCK):
        table = NumberTable(len(TUM_COLUMNS))
        table.add_block(contents, numbers, TUM_COLUMNS, files="TUM trajectory files",
                        path=path, finite=False, hints=_COUNT_HINTS)
        data, lines = table.arrays()
        if nanoseconds is None and contents:     # the file's first row decides, as names do
            nanoseconds = is_nanoseconds(split_fields(contents[0])[0])
        if nanoseconds:
            data[:, 0] *= 1e-9
        rows.add(data, lines)
    if not rows.screened:
        raise DatasetError(f"no rows: expected lines '{' '.join(TUM_COLUMNS)}'", path=path)
    return rows.trajectory(parent=parent, child=child, duplicates=duplicates)


def _stamp_text(seconds: float, ns: int | None) -> str:
    if ns is not None:
        sign, ns = ("-", -int(ns)) if ns < 0 else ("", int(ns))
        return f"{sign}{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}"
    return repr(float(seconds))


def write_tum(path: str | os.PathLike, traj: Trajectory, *, unit: str = "m") -> None:
    """Write a TUM file atomically (round-trips exactly with :func:`read_tum`).

    Numbers are written with ``repr`` (shortest exact decimal); stamps from integer
    nanoseconds are written as exact decimals.  A comment line names the frames.

    Parameters
    ----------
    path : path-like
    traj : Trajectory
    unit : {"m", "cm", "mm"}
        Unit of the translations in the file.
    """
    scale = length_scale(unit)
    q = geometry.quat_from_transform(traj.T)
    t = traj.T[:, :3, 3] / scale
    ns = traj.stamps_ns
    with atomic_output(path) as out:
        out.write(f"# {traj.name}: t tx ty tz qx qy qz qw (seconds, {unit})\n")
        for i in range(len(traj)):
            values = [*t[i], *q[i]]
            stamp = _stamp_text(traj.stamps[i], None if ns is None else ns[i])
            out.write(" ".join([stamp, *(repr(float(v)) for v in values)]) + "\n")
