"""Motion-capture poses from CSV files: a generic CSV with a header; the layouts of OptiTrack
Motive and Vicon Nexus exports, read by :mod:`multieye.io.mocap_exports`.  Every reader
returns a :class:`Trajectory` of ``T_world_<child>`` in metres and seconds.

Generic CSV (:func:`read_pose_csv`)
    One header row, then one pose per row.  Columns are found by name (case-insensitive,
    a leading ``#`` and a unit suffix such as ``[mm]`` or ``(s)`` are allowed), with defaults
    :data:`DEFAULT_COLUMNS` or an explicit ``columns`` mapping.  Separator: comma, else
    semicolon, else whitespace.

OptiTrack Motive CSV export (:func:`read_optitrack_csv`)
    Facts from the Motive documentation and exported files: line 1 holds ``key,value`` pairs
    (``Format Version``, ``Rotation Type``, ``Length Units`` = ``Meters``/``Millimeters``/
    ``Centimeters``, ...); then header rows whose second cell is ``Type`` (``Rigid Body``,
    ``Marker``, ``Rigid Body Marker``...), ``Name``, ``ID`` (newer versions add ``Parent``),
    a row naming the quantity (``Rotation``/``Position``/``Mean Marker Error``) and a row
    starting ``Frame,Time (Seconds)`` naming the axes.  Rigid-body rotation is a quaternion
    in the column order ``X Y Z W``.  Occluded frames have blank cells.
    Choices: only ``Rotation Type`` = ``Quaternion`` is accepted (Euler exports are
    ambiguous about the axis order's meaning, so they are rejected with a message); frames
    with any blank pose cell are skipped; the stamp is the ``Time (Seconds)`` column.

Vicon Nexus CSV export (:func:`read_vicon_csv`)
    Facts from exported files: sections start with a line holding the section name
    (``Segments``, ``Trajectories``, ``Model Outputs``, ``Joints``, ``Devices``), then the
    frame rate in Hz, a row with each subject/segment name above its first column, the
    labels ``Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,...`` and a units row (``deg`` or ``rad``,
    ``mm``); a blank line ends a section.  ``RX RY RZ`` of a segment is its global
    orientation as a helical (rotation-vector) angle: axis times angle.
    Choices: the pose is ``T_world_segment = [exp(RX RY RZ), (TX TY TZ)]``; the stamp is
    ``Frame / rate`` seconds on the Vicon clock (``Sub Frame``, used by devices sampled
    faster than the cameras, is ignored; segment rows have one row per frame); frames with a
    blank pose cell (segment not reconstructed) are skipped.  ``Trajectories`` holds marker
    positions only, so a file without a ``Segments`` section is rejected with that reason.

Every file is read line by line (never held whole), each line split with :mod:`csv` and its
numbers gathered in flat arrays; generic CSV (stamps in seconds, milliseconds or
microseconds) and OptiTrack rows are turned into poses 16 384 rows at a time
(:class:`~multieye.io.poserows.QuaternionRows`, as TUM files), so only the usable rows' stamps,
poses and lines stay (about 140 bytes a row): a 5-million-row CSV calibrates within 1 GB.
Errors name the file and the 1-based line as before.
"""

from __future__ import annotations

import csv
import os
import re
from array import array
from collections.abc import Iterable, Iterator, Mapping, Sequence

import numpy as np

from multieye.core.errors import DatasetError
from multieye.core.limits import MAX_TABLE_BYTES
from multieye.io.poserows import QuaternionRows, RowPlace, usable_rows
from multieye.io.textfile import (LENGTH_UNITS, count_lines, is_nanoseconds, parse_float,
                                  physical_lines)
from multieye.io.trajectory import Trajectory

__all__ = [
    "DEFAULT_COLUMNS",
    "read_pose_csv",
]

#: Header names tried for each quantity of a generic CSV (after lower-casing and removing
#: a leading ``#`` and a unit suffix).
DEFAULT_COLUMNS: dict[str, tuple[str, ...]] = {
    "t": ("t", "time", "timestamp", "stamp", "time_s", "times", "header_stamp"),
    "tx": ("tx", "x", "px", "pos_x", "position_x", "p_x", "t_x", "translation_x"),
    "ty": ("ty", "y", "py", "pos_y", "position_y", "p_y", "t_y", "translation_y"),
    "tz": ("tz", "z", "pz", "pos_z", "position_z", "p_z", "t_z", "translation_z"),
    "qx": ("qx", "q_x", "quat_x", "orientation_x", "rot_x", "rotation_x"),
    "qy": ("qy", "q_y", "quat_y", "orientation_y", "rot_y", "rotation_y"),
    "qz": ("qz", "q_z", "quat_z", "orientation_z", "rot_z", "rotation_z"),
    "qw": ("qw", "q_w", "quat_w", "orientation_w", "rot_w", "rotation_w"),
}

_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_UNIT_SUFFIX = re.compile(r"^(.*?)\s*[\[(]\s*([a-zA-Z]*)\s*[\])]$")
#: EuRoC/ASL names: ``p_<frames>_x`` (position of one frame in another, as
#: ``p_RS_R_x``) and ``q_<frames>_w`` (EuRoC writes the quaternion w first), used when no
#: name of :data:`DEFAULT_COLUMNS` is in the header; ``v_...``, ``b_w_...`` and other
#: columns are not poses and are left alone.
_EUROC_NAME = re.compile(r"^(p|q)_[a-z0-9]+(?:_[a-z0-9]+)*_([xyzw])$")


#: Rows turned into poses at a time (:class:`~multieye.io.poserows.QuaternionRows`): the
#: table of numbers is never held whole.
_BLOCK = 1 << 14


def _lines(path, what: str) -> Iterator[tuple[int, str]]:
    """Every physical line of the export, one at a time (the file is never held whole: a
    5-million-row export stays within a few hundred MB), within
    :data:`~multieye.core.limits.MAX_TABLE_BYTES` (:func:`multieye.io.textfile.physical_lines`)."""
    return physical_lines(path, what=what, max_bytes=MAX_TABLE_BYTES)


def _rows(lines: Iterable[tuple[int, str]], delimiter: str | None = ",",
          ) -> Iterator[tuple[int, list[str]]]:
    """``(line, cells)`` of each line: one physical line per row (exports never quote
    newlines), split with :mod:`csv` (``delimiter`` None: on white space)."""
    for number, line in lines:
        if delimiter is None:
            yield number, line.split()
        else:
            yield number, next(csv.reader([line], delimiter=delimiter), [])


def _numbers(cells: Sequence[str], columns: Sequence[str], path, line: int) -> list[float]:
    try:
        return [float(c) for c in cells]
    except ValueError:
        return [parse_float(c, path=path, line=line, name=n, finite=False)
                for c, n in zip(cells, columns)]


def _blank(row: Sequence[str]) -> bool:
    return all(not c.strip() for c in row)


def _complete_rows(rows: Iterable[tuple[int, list[str]]], columns: Sequence[int],
                   headers: Sequence[str], path, *, section_ends_at_blank: bool, missing: str,
                   sink: QuaternionRows | None = None):
    """Numbers of ``columns`` (named ``headers`` in messages) in ``rows`` (``(line, cells)``,
    read one at a time), skipping
    rows with a blank cell (an occluded sample); returns ``(array (N, len(columns)),
    1-based lines)``, gathered in flat arrays (8 bytes a number).  With ``sink``, each block
    of :data:`_BLOCK` rows goes to ``sink.add`` instead (turned into poses at once) and the
    result is ``(None, None)``."""
    values, lines, seen = array("d"), array("q"), 0
    for number, row in rows:
        if _blank(row):
            if section_ends_at_blank:
                break
            continue
        cells = [row[j].strip() if j < len(row) else "" for j in columns]
        if not all(cells):
            continue
        values.extend(_numbers(cells, headers, path, number))
        lines.append(number)
        seen += 1
        if sink is not None and len(lines) == _BLOCK:
            sink.add(*_block(values, lines, len(columns)))
            values, lines = array("d"), array("q")
    if not seen:
        raise DatasetError(missing, path=path)
    if sink is not None:
        if lines:
            sink.add(*_block(values, lines, len(columns)))
        return None, None
    return _block(values, lines, len(columns))


def _block(values: array, lines: array, n_columns: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat arrays as ``(data (N, n_columns), lines (N,))`` without copying."""
    return (np.frombuffer(values, dtype=np.float64).reshape(-1, n_columns),
            np.frombuffer(lines, dtype=np.int64))


def _screened(stamps, t, rotation, columns, path, lines, max_rotation=None):
    """:func:`usable_rows` on the converted numbers: ``(keep, skipped, kept lines)``."""
    return usable_rows(stamps, t, rotation, where=RowPlace(path, lines), columns=columns,
                       max_rotation=max_rotation)


def _refuse_tracker(first: str, path, line: int | None) -> None:
    """A Vicon Tracker export (first line ``Objects``) is refused with what to do: its
    ``RX RY RZ`` are a helical angle or Euler XYZ angles by a Tracker setting the file does
    not record, so no reading of them is safe."""
    if first == "Objects":
        raise DatasetError("a Vicon Tracker export (first line 'Objects'): its RX RY RZ are "
                           "helical or Euler XYZ angles by a Tracker setting the file does not "
                           "record, so multieye does not guess; export from Nexus (Segments), "
                           "or convert the object's poses to a TUM file (t x y z qx qy qz qw) "
                           "or to rows read with format: tum, values and rotation (rotvec or "
                           "euler-xyz-deg; docs/rig-yaml.md, section 4)", path=path, line=line)


# --------------------------------------------------------------------------- generic CSV


def _header_name(cell: str) -> tuple[str, str | None]:
    """A header cell's name, lower case, and its unit suffix: ``Pos X [mm]`` is ``pos_x``
    and ``mm``; a dotted ROS field path keeps its last two parts (``rostopic echo -p``'s
    ``field.pose.position.x`` is ``position_x``, ``field.header.stamp`` is
    ``header_stamp``)."""
    name = cell.strip().lstrip("#").strip()
    m = _UNIT_SUFFIX.match(name)
    unit = None
    if m:
        name, unit = m.group(1), m.group(2).lower() or None     # '[]': EuRoC's unitless
    name = re.sub(r"\s+", "_", name.strip().lower())
    return "_".join(name.split(".")[-2:]), unit


def _euroc_role(name: str) -> str | None:
    """The role of an EuRoC/ASL header name (``p_RS_R_x`` is ``tx``, ``q_RS_w`` is ``qw``;
    :data:`_EUROC_NAME`), or None."""
    m = _EUROC_NAME.match(name)
    if m is None or (m.group(1) == "p" and m.group(2) == "w"):
        return None
    return ("t" if m.group(1) == "p" else "q") + m.group(2)


def _no_header(header: list[str]) -> str:
    """What to do when the first line of a .csv holds numbers only (no header)."""
    try:
        [float(c) for c in header]
    except ValueError:
        return ""
    return ("; this line holds numbers, not a header: a .csv file is read by its header's "
            "names; for rows of t x y z qx qy qz qw without a header give format: tum under "
            "mocap (with values: [...] for another order)")


#: Header names of rotations other than a quaternion (Euler angles, rotation vectors, matrix
#: entries), which a generic CSV does not read: the message says how to read them.
_OTHER_ROTATION = re.compile(r"^(roll|pitch|yaw|rx|ry|rz|rot_?vec.*|euler.*|a[123]|"
                             r"[rm]_?[0-4]{2}|rotation_?[xyz]|angle.*)$")


def _other_rotation(cells: list[str]) -> str:
    """What to do with a CSV whose rotation is not a quaternion (empty when its header cells
    name none of :data:`_OTHER_ROTATION`)."""
    if not any(_OTHER_ROTATION.match(n) for n in cells):
        return ""
    return ("; this header looks like a rotation other than a quaternion: read the file with "
            "format: tum, values: [t, x, y, z, ...] (one name per column, in order) and "
            "rotation: rotvec, euler-<axes>-deg or matrix under mocap in rig.yaml "
            "(docs/rig-yaml.md, section 4); its header row is then skipped")


def _find_columns(header: list[str], columns: Mapping[str, str] | None, path, line):
    headers = [_header_name(c) for c in header]
    found = {}
    for role, candidates in DEFAULT_COLUMNS.items():
        wanted = ((_header_name(columns[role])[0],) if columns and role in columns else
                  candidates)
        hits = [j for j, (n, _) in enumerate(headers) if n in wanted]
        if not hits and role != "t" and not (columns and role in columns):
            hits = [j for j, (n, _) in enumerate(headers) if _euroc_role(n) == role]
            wanted = wanted + (f"EuRoC's {'p' if role[0] == 't' else 'q'}_<frames>_{role[1]}",)
        if len(hits) != 1:
            have = ", ".join(repr(c.strip()) for c in header)
            problem = "no column" if not hits else "several columns"
            other = _other_rotation([n for n, _ in headers]) if role != "t" else ""
            raise DatasetError(f"{problem} for {role} (looked for {' or '.join(wanted)}); "
                               f"header has {have}{_no_header(header)}{other}", path=path,
                               line=line)
        found[role] = hits[0]
    if columns:
        unknown = set(columns) - set(DEFAULT_COLUMNS)
        if unknown:
            raise DatasetError(f"unknown column roles {sorted(unknown)}; roles are "
                               f"{', '.join(DEFAULT_COLUMNS)}", path=path)
    return found, headers


def _unit_from_header(headers, found, roles, default, known, path, line):
    units = {headers[found[r]][1] for r in roles} - {None}
    if len(units) > 1:
        raise DatasetError(f"columns {', '.join(roles)} have different units {sorted(units)}",
                           path=path, line=line)
    unit = units.pop() if units else None
    if unit is not None and unit not in known:
        raise DatasetError(f"unknown unit {unit!r} in the header; expected one of "
                           f"{', '.join(known)}", path=path, line=line)
    if unit is not None and default is not None and unit != default:
        raise DatasetError(f"the header says {unit!r} but {default!r} was requested",
                           path=path, line=line)
    return unit or default


def read_pose_csv(path: str | os.PathLike, *, columns: Mapping[str, str] | None = None,
                  unit: str | None = None, time_unit: str | None = None,
                  parent: str = "world", child: str = "marker",
                  duplicates: str = "error") -> Trajectory:
    """Read poses from a CSV file with a header row.

    Parameters
    ----------
    path : path-like
    columns : mapping, optional
        Header name for any of the roles ``t tx ty tz qx qy qz qw`` (others use
        :data:`DEFAULT_COLUMNS`).
    unit : {"m", "cm", "mm"}, optional
        Translation unit; default: the header's unit suffix, else metres.
    time_unit : {"s", "ms", "us", "ns"}, optional
        Time unit; default: the header's suffix, else integer nanoseconds when the first
        row's stamp has 16 to 19 digits (as image names), else seconds.  With ``"ns"`` the
        stamps are read as exact integers and kept in ``stamps_ns``.
    parent, child : str
        Each row is ``T_parent_child``.
    duplicates : {"error", "drop"}
        A row with the same stamp as the row before: error, or skipped.

    Raises
    ------
    DatasetError
        Missing or ambiguous columns (listing the header), a row with too few cells, a cell that
        is not a number, a non-unit quaternion, stamps not strictly increasing.  Rows with a
        blank pose cell are skipped (an occluded sample).
    """
    lines_in = _lines(path, "CSV file")
    first, header_line = next(((i, line) for i, line in lines_in if line.strip()), (None, ""))
    if first is None:
        raise DatasetError("empty CSV file: expected a header row", path=path)
    delimiter = "," if "," in header_line else ";" if ";" in header_line else None
    (_, header), = _rows([(first, header_line)], delimiter)
    _refuse_tracker(header[0].strip(), path, first)
    found, names = _find_columns(header, columns, path, first)
    unit = _unit_from_header(names, found, ("tx", "ty", "tz"), unit, LENGTH_UNITS, path,
                             first) or "m"
    time_unit = _unit_from_header(names, found, ("t",), time_unit, _TIME_UNITS, path, first)
    order = [found[r] for r in DEFAULT_COLUMNS]
    values, stamps_ns, lines = array("d"), array("q"), array("q")
    seconds = None if time_unit is None else _TIME_UNITS[time_unit]
    sink = QuaternionRows(path, tuple(DEFAULT_COLUMNS), LENGTH_UNITS[unit],
                          capacity=count_lines(path, what="CSV file"))

    def flush():
        data, numbers = _block(values, lines, len(DEFAULT_COLUMNS))
        if time_unit == "ns":
            ns = np.frombuffer(stamps_ns, dtype=np.int64)
            data[:, 0] = ns / 1e9
            sink.add(data, numbers, ns)
        else:
            sink.add(*_seconds((data, numbers), seconds))

    for number, row in _rows(lines_in, delimiter):
        if _blank(row) or row[0].lstrip().startswith("#"):
            continue
        if len(row) <= max(order):
            raise DatasetError(f"row has {len(row)} cells, the header has {len(header)}",
                               path=path, line=number)
        cells = [row[j].strip() for j in order]
        if not all(cells):
            continue
        if time_unit is None:      # no unit stated: the first row decides, as image names do
            time_unit = "ns" if is_nanoseconds(cells[0]) else "s"
            seconds = _TIME_UNITS[time_unit]
        if time_unit == "ns":
            try:
                ns_value = int(cells[0])
            except ValueError:
                raise DatasetError(f"expected integer nanoseconds for t, got {cells[0]!r}",
                                   path=path, line=number) from None
            if abs(ns_value) >= 2 ** 63:
                raise DatasetError(f"time stamp {ns_value} ns does not fit 64 bits", path=path,
                                   line=number)
            stamps_ns.append(ns_value)
            cells[0] = "0"
        values.extend(_numbers(cells, DEFAULT_COLUMNS, path, number))
        lines.append(number)
        if len(lines) == _BLOCK:
            flush()
            values, stamps_ns, lines = array("d"), array("q"), array("q")
    if lines:
        flush()
    if not sink.screened:
        raise DatasetError("no poses found below the header", path=path)
    return sink.trajectory(parent=parent, child=child, duplicates=duplicates)


def _seconds(block: tuple[np.ndarray, np.ndarray], seconds: float):
    """A block with its stamps (column 0) converted to seconds, in place."""
    data, lines = block
    if seconds != 1.0:
        with np.errstate(over="ignore", invalid="ignore"):
            data[:, 0] *= seconds
    return data, lines
