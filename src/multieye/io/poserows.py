"""Rows of time-stamped poses read from a text file -> :class:`Trajectory`, with line numbers.

Shared by the TUM, CSV, OptiTrack, Vicon and bag readers so that every format reports a
non-unit quaternion or a repeated time stamp the same way, naming the file and the line, and
leaves out the same unusable rows (:func:`screen_rows`): a row with a value that is not a
finite number, a translation coordinate beyond :data:`~multieye.core.limits.MAX_POSITION_M`
(after the unit conversion) or a time stamp beyond :data:`~multieye.core.limits.MAX_STAMP_S`
is skipped and listed in :attr:`Trajectory.skipped` with its line and the reason, and the rest
of the file is read; a file with no usable row at all is an error naming the first one.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from multieye.core import geometry
from multieye.core.errors import DatasetError, InputError
from multieye.core.limits import MAX_POSITION_M, MAX_STAMP_S
from multieye.io.trajectory import SkippedRow, Trajectory

__all__ = ["QUATERNION_TOLERANCE", "quaternion_poses", "trajectory_from_rows", "screen_rows",
           "usable_rows", "RowPlace", "QuaternionRows"]

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
    with np.errstate(over="ignore", invalid="ignore"):     # 1e308 cells: norm inf, refused
        norms = np.linalg.norm(q, axis=1)
    bad = ~(np.abs(norms - 1.0) <= tolerance)          # NaN is bad too
    if np.any(bad):
        i = int(np.argmax(bad))
        where = what if lines is not None else f"{what}sample {i}: "
        raise DatasetError(f"{where}quaternion (qx qy qz qw) must have unit norm, got norm "
                           f"{norms[i]:.6g} (tolerance {tolerance:g})", path=path,
                           line=None if lines is None else int(lines[i]))
    return geometry.transform_from_quat(q / norms[:, None], t_xyz)


def screen_rows(stamps: np.ndarray, t_xyz: np.ndarray, rotation: np.ndarray, *,
                columns: Sequence[str], lines: Sequence[int] | None = None,
                labels: Sequence[str] | None = None, max_rotation: float | None = None
                ) -> tuple[np.ndarray, tuple[SkippedRow, ...]]:
    """Which pose rows are usable, and why the others are not.

    Parameters
    ----------
    stamps : ndarray, shape (N,)
        Seconds.
    t_xyz : ndarray, shape (N, 3)
        Translations in metres (after the unit conversion).
    rotation : ndarray, shape (N, k)
        The rotation's numbers as the file gives them (quaternion, rotation vector).
    columns : sequence of str
        Names of the ``1 + 3 + k`` columns, for the reasons (``t tx ty tz qx qy qz qw``).
    lines : sequence of int, optional
        1-based line of each row (text files).
    labels : sequence of str, optional
        How to name each row without lines (``"sample 3"``).
    max_rotation : float, optional
        Largest magnitude of a rotation number (a rotation vector's components, radians).

    Returns
    -------
    keep : ndarray, shape (N,), bool
    skipped : tuple of SkippedRow
        The rows left out: a value that is not a finite number, a translation coordinate
        beyond :data:`MAX_POSITION_M` metres or a stamp beyond :data:`MAX_STAMP_S` seconds.
    """
    stamps = np.asarray(stamps, dtype=np.float64).reshape(-1)
    t_xyz = np.asarray(t_xyz, dtype=np.float64).reshape(-1, 3)
    rotation = np.asarray(rotation, dtype=np.float64).reshape(len(stamps), -1)
    values = np.column_stack([stamps, t_xyz, rotation])
    finite = np.isfinite(values)
    with np.errstate(invalid="ignore", over="ignore"):
        far = ~(np.abs(t_xyz) <= MAX_POSITION_M)
        late = ~(np.abs(stamps) <= MAX_STAMP_S)
        turned = np.zeros_like(far) if max_rotation is None else ~(np.abs(rotation)
                                                                    <= max_rotation)
    bad = ~finite.all(axis=1) | far.any(axis=1) | late | turned.any(axis=1)
    skipped = []
    for i in np.flatnonzero(bad):
        if not finite[i].all():
            j = int(np.argmin(finite[i]))
            reason = f"not a finite number: {columns[j]} = {float(values[i, j])!r}"
        elif late[i]:
            reason = (f"absurd time stamp: {columns[0]} = {stamps[i]:g} s, beyond "
                      f"{MAX_STAMP_S:g} s")
        elif turned[i].any():
            j = int(np.argmax(turned[i]))
            reason = (f"absurd rotation: {columns[4 + j]} = {rotation[i, j]:g} rad, beyond "
                      f"{max_rotation:g} rad")
        else:
            j = int(np.argmax(far[i]))
            reason = (f"absurd position: {columns[1 + j]} = {t_xyz[i, j]:g} m, beyond "
                      f"{MAX_POSITION_M:g} m")
        line = None if lines is None else int(lines[i])
        where = f"line {line}" if line is not None else (
            labels[i] if labels is not None else f"sample {i + 1}")
        skipped.append(SkippedRow(where, reason, line, int(i) + 1))
    return ~bad, tuple(skipped)


@dataclass(frozen=True)
class RowPlace:
    """Where rows of poses come from, for messages: the file, the 1-based line of each row
    (or a label of each row, such as a bag topic and stamp) and what to say before."""

    path: str | os.PathLike
    lines: Sequence[int] | None = None
    labels: Sequence[str] | None = None
    what: str = ""


def usable_rows(stamps: np.ndarray, t_xyz: np.ndarray, rotation: np.ndarray, *,
                where: RowPlace, columns: Sequence[str], max_rotation: float | None = None):
    """:func:`screen_rows`, then the usable rows only (``columns``: their names; ``where``:
    the file and the rows' lines or labels).

    Returns
    -------
    keep : ndarray, shape (N,), bool
    skipped : tuple of SkippedRow
    lines : list of int or None
        The lines of the rows kept.

    Raises
    ------
    DatasetError
        No usable row at all (naming the first row and why).
    """
    path, lines, what = where.path, where.lines, where.what
    keep, skipped = screen_rows(stamps, t_xyz, rotation, columns=columns, lines=lines,
                                labels=where.labels, max_rotation=max_rotation)
    if len(keep) and not keep.any():
        first = skipped[0]
        raise DatasetError(f"{what}no usable pose: all {len(keep)} rows left out; "
                           f"{first.where}: {first.reason}", path=path, line=first.line)
    kept_lines = None if lines is None else np.asarray(lines, dtype=np.int64)[keep]
    return keep, skipped, kept_lines


def trajectory_from_rows(stamps: np.ndarray, T: np.ndarray, *, path: str | os.PathLike,
                         lines: Sequence[int], frames: tuple[str, str],
                         stamps_ns: np.ndarray | None = None,
                         duplicates: str = "error",
                         skipped: tuple[SkippedRow, ...] = ()) -> Trajectory:
    """A Trajectory from rows in file order; stamps must be strictly increasing.

    Parameters
    ----------
    stamps : ndarray, shape (N,)
        Seconds.
    T : ndarray, shape (N, 4, 4)
        ``T_parent_child`` of each row, metres.
    path, lines : the file and the 1-based line of each row.
    frames : (str, str)
        The parent and child frame names.
    stamps_ns : ndarray, shape (N,), int64, optional
    duplicates : {"error", "drop"}
        What to do with a row whose stamp equals the previous row's: raise, or keep only the
        first row of each run of equal stamps (for files written with too few digits).
    skipped : tuple of SkippedRow
        Rows left out before (:func:`screen_rows`), kept on the trajectory.

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
        raise InputError(f"duplicates must be 'error' or 'drop', got {duplicates!r}")
    key = stamps if stamps_ns is None else np.asarray(stamps_ns)
    if duplicates == "drop":
        keep = np.r_[True, np.diff(key) != 0]
        stamps, T, key = stamps[keep], np.asarray(T)[keep], key[keep]
        lines = np.asarray(lines, dtype=np.int64)[keep]
        stamps_ns = None if stamps_ns is None else key
    back = key[1:] <= key[:-1]                  # booleans: no copy of the stamps
    if np.any(back):
        i = int(np.argmax(back))
        what = "duplicate time stamp" if key[i + 1] == key[i] else "time stamp goes back"
        raise DatasetError(f"{what}: {float(stamps[i + 1])!r} s after {float(stamps[i])!r} s "
                           f"on line {int(lines[i])}; stamps must be strictly increasing",
                           path=path, line=int(lines[i + 1]))
    return Trajectory(stamps, T, *frames, stamps_ns, skipped)


class QuaternionRows:
    """Rows ``t tx ty tz qx qy qz qw`` turned into poses block by block, for tables of millions
    of rows: only the usable rows' stamps, poses and lines are kept (about 180 bytes a row),
    never the table of numbers whole.

    Each block goes through :func:`screen_rows` and :func:`quaternion_poses` as a whole file
    would; :meth:`trajectory` then checks the stamps (:func:`trajectory_from_rows`).

    Parameters
    ----------
    path : path-like
        The file, for messages.
    columns : sequence of str
        The 8 column names.
    scale : float
        Metres per unit of the translations.
    capacity : int
        Rows expected at most (the file's line count): the arrays are allocated once; more
        rows grow them (ndarray.resize fills what it adds, so a good bound saves memory).
    """

    def __init__(self, path, columns: Sequence[str], scale: float, capacity: int = 0):
        self.path, self.columns, self.scale = path, tuple(columns), float(scale)
        self._n = 0           # usable rows so far
        self._rows = 0        # rows screened so far
        # np.empty: the pages of rows never written are never resident
        self._stamps = np.empty(capacity)
        self._T = np.empty((capacity, 4, 4))
        self._lines = np.empty(capacity, dtype=np.int32)   # tables are below 2 GiB
        self.skipped: list[SkippedRow] = []
        self._ns: list[np.ndarray] = []      # integer-nanosecond stamps of the usable rows

    @property
    def screened(self) -> int:
        """Rows screened so far, usable or not."""
        return self._rows

    def _grow(self, need: int) -> None:
        cap = len(self._stamps)
        if need <= cap:
            return
        cap = max(need, cap + cap // 4, 1 << 16)
        # ndarray.resize reallocates in place (no second copy of the poses in memory)
        for a, shape in ((self._stamps, (cap,)), (self._T, (cap, 4, 4)),
                         (self._lines, (cap,))):
            a.resize(shape, refcheck=False)

    def add(self, data: np.ndarray, lines: np.ndarray, stamps_ns: np.ndarray | None = None
            ) -> None:
        """Screen and convert one block: ``data`` (k, 8) as the file gives it (stamps in
        seconds), ``lines`` (k,); ``stamps_ns`` (k,) int64, the exact stamps where the file
        gives integer nanoseconds (every block then has them)."""
        with np.errstate(over="ignore", invalid="ignore"):
            t = data[:, 1:4] * self.scale
        keep, skipped = screen_rows(data[:, 0], t, data[:, 4:8], columns=self.columns,
                                    lines=lines)
        self.skipped.extend(replace(r, row=r.row + self._rows) for r in skipped)
        self._rows += len(data)
        kept_lines = lines[keep]
        if stamps_ns is not None:
            self._ns.append(np.asarray(stamps_ns, dtype=np.int64)[keep])
        T = quaternion_poses(t[keep], data[keep, 4:8], path=self.path, lines=kept_lines)
        m = len(T)
        self._grow(self._n + m)
        self._stamps[self._n:self._n + m] = data[keep, 0]
        self._T[self._n:self._n + m] = T
        self._lines[self._n:self._n + m] = kept_lines
        self._n += m

    def trajectory(self, *, parent: str, child: str, duplicates: str = "error") -> Trajectory:
        """The usable rows as a :class:`Trajectory` (DatasetError: no rows, none usable, or
        stamps that repeat or go back)."""
        if self._rows and not self._n:
            first = self.skipped[0]
            unit = ("; every stamp in milliseconds or microseconds? write seconds, or "
                    "nanoseconds of 16 to 19 digits (a CSV header may name the unit: t [ms])"
                    if first.reason.startswith("absurd time stamp") else "")
            raise DatasetError(f"no usable pose: all {self._rows} rows left out; "
                               f"{first.where}: {first.reason}{unit}", path=self.path,
                               line=first.line)
        n = self._n
        for a, shape in ((self._stamps, (n,)), (self._T, (n, 4, 4)), (self._lines, (n,))):
            a.resize(shape, refcheck=False)
        ns = np.concatenate(self._ns) if self._ns else None
        return trajectory_from_rows(self._stamps, self._T, path=self.path, lines=self._lines,
                                    frames=(parent, child), duplicates=duplicates,
                                    skipped=tuple(self.skipped), stamps_ns=ns)
