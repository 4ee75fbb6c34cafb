"""Motion-capture exports of OptiTrack Motive and Vicon Nexus (moved out of
:mod:`multieye.io.mocap_csv`, whose docstring describes both layouts and the choices made), and
:func:`csv_flavour`, which tells them from a generic CSV.

Each body's columns are found by their labels under its name; a label met twice under one
name (a names row shifted by a column, or two bodies exported under one name) is refused with
both columns, never read from the wrong column.
"""

from __future__ import annotations

import itertools
import os

import numpy as np

from multieye.core import geometry
from multieye.core.errors import DatasetError
from multieye.io.mocap_csv import (_blank, _complete_rows, _lines, _refuse_tracker, _rows,
                                   _screened)
from multieye.io.poserows import QuaternionRows, trajectory_from_rows
from multieye.io.textfile import LENGTH_UNITS, count_lines, parse_float, text_lines
from multieye.io.trajectory import Trajectory

__all__ = ["read_optitrack_csv", "read_vicon_csv", "csv_flavour", "refuse_qualisys"]

_OPTITRACK_UNITS = {"meters": "m", "millimeters": "mm", "centimeters": "cm"}
_VICON_SECTIONS = ("Segments", "Trajectories", "Model Outputs", "Joints", "Devices")
#: Largest rotation-vector component accepted from a Vicon export, radians (beyond it a row is
#: left out as absurd: no exporter writes it, and it has lost every digit of the angle).
_MAX_ROTVEC_RAD = 1e3
#: Most lines above the first data row of an OptiTrack export that are kept (Motive writes 7).
_MAX_HEADER_ROWS = 1000

# --------------------------------------------------------------------------- OptiTrack


def _label_row(rows: list[list[str]], label: str, start: int, stop: int) -> int | None:
    for i in range(start, stop):
        if len(rows[i]) > 1 and rows[i][1].strip() == label and not rows[i][0].strip():
            return i
    return None


def _choose(name: str | None, available: list[str], what: str, path) -> str:
    if name is None:
        if len(available) == 1:
            return available[0]
        if not available:
            raise DatasetError(f"no {what} in the file: export the {what} whose pose is "
                               "wanted (markers alone have no orientation)", path=path)
        raise DatasetError(f"{len(available)} {what}s in the file ({', '.join(available)}); "
                           f"choose one with rigid_body: <name> under mocap in rig.yaml",
                           path=path)
    if name in available:
        return name
    short = [a for a in available if a.split(":")[-1] == name]
    if len(short) == 1:
        return short[0]
    raise DatasetError(f"{what} {name!r} not found; the file has {', '.join(available) or 'none'}",
                       path=path)


def _columns_once(labelled, wanted, what: str, path, line: int) -> dict:
    """``{label: column}`` of ``labelled`` (``(label, 0-based column)`` pairs under one body's
    name); a label of ``wanted`` met twice is refused naming both columns (1-based): reading
    either would take another body's numbers or a shifted names row's."""
    cols = {}
    for label, j in labelled:
        if label in wanted and label in cols:
            shown = " ".join(label) if isinstance(label, tuple) else label
            raise DatasetError(f"{what} has two {shown} columns ({cols[label] + 1} and {j + 1}): "
                               "its name stands over another's columns (a names row shifted, or "
                               "two bodies of one name); expected each once", path=path, line=line)
        cols[label] = j
    return cols


def read_optitrack_csv(path: str | os.PathLike, rigid_body: str | None = None, *,
                       parent: str = "world", child: str = "marker",
                       duplicates: str = "error") -> Trajectory:
    """Read one rigid body's poses from an OptiTrack Motive CSV export.

    Parameters
    ----------
    path : path-like
    rigid_body : str, optional
        Name of the rigid body (as in the ``Name`` row); needed when the file has several.
    parent, child : str
        Frame names: the poses are ``T_parent_child`` (the rigid body in Motive's world).
    duplicates : {"error", "drop"}
        A frame whose stamp repeats the previous one's: an error, or left out (the first kept).

    Returns
    -------
    Trajectory
        Stamps from ``Time (Seconds)``, translations converted from ``Length Units``.

    Raises
    ------
    DatasetError
        Not a Motive export, Euler rotations, unknown length unit, rigid body missing (listing
        those present), malformed cells (with the line).
    """
    stream = _rows(_lines(path, "OptiTrack CSV export"))
    rows = []       # the header rows, up to the 'Frame' row; the data rows are read one by one
    for _, row in stream:
        rows.append(row)
        if (row and row[0].strip() == "Frame") or len(rows) >= _MAX_HEADER_ROWS:
            break
    if not rows or rows[0][0].strip() != "Format Version":
        raise DatasetError("not an OptiTrack Motive CSV export: the first cell should be "
                           "'Format Version' (export with header information)", path=path, line=1)
    meta = {k.strip(): v.strip() for k, v in zip(rows[0][0::2], rows[0][1::2])}
    rotation = meta.get("Rotation Type", "Quaternion")
    if rotation != "Quaternion":
        raise DatasetError(f"Rotation Type is {rotation!r}; export rigid bodies with Rotation "
                           "Type 'Quaternion'", path=path, line=1)
    units = meta.get("Length Units")
    if units is None or units.lower() not in _OPTITRACK_UNITS:
        raise DatasetError(f"Length Units must be Meters, Millimeters or Centimeters, got "
                           f"{units!r}", path=path, line=1)
    scale = LENGTH_UNITS[_OPTITRACK_UNITS[units.lower()]]
    frame_row = next((i for i, r in enumerate(rows) if r and r[0].strip() == "Frame"), None)
    if frame_row is None:
        raise DatasetError("no 'Frame,Time (Seconds),...' header row", path=path)
    type_row = _label_row(rows, "Type", 1, frame_row)
    name_row = _label_row(rows, "Name", 1, frame_row)
    if type_row is None or name_row is None:
        raise DatasetError("header rows 'Type' and 'Name' not found above the 'Frame' row",
                           path=path)
    kinds, names = rows[type_row], rows[name_row]
    quantity, axes = rows[frame_row - 1], rows[frame_row]
    bodies = list(dict.fromkeys(names[j].strip() for j in range(2, min(len(kinds), len(names)))
                                if kinds[j].strip() == "Rigid Body"))
    body = _choose(rigid_body, bodies, "rigid body", path)
    wanted = [("Position", a) for a in "XYZ"] + [("Rotation", a) for a in "XYZW"]
    cols = _columns_once((((quantity[j].strip(), axes[j].strip()), j)
                          for j in range(2, min(len(kinds), len(names), len(quantity), len(axes)))
                          if kinds[j].strip() == "Rigid Body" and names[j].strip() == body),
                         wanted, f"rigid body {body!r}", path, frame_row + 1)
    missing = [f"{q} {a}" for q, a in wanted if (q, a) not in cols]
    if missing:
        raise DatasetError(f"rigid body {body!r} has no column for {', '.join(missing)}",
                           path=path, line=frame_row + 1)
    time_col = next((j for j, c in enumerate(axes) if c.strip().startswith("Time")), None)
    if time_col is None:
        raise DatasetError("no 'Time (Seconds)' column", path=path, line=frame_row + 1)
    order = [time_col] + [cols[w] for w in wanted]
    cell_names = ["Time (Seconds)"] + [f"{body} {q} {a}" for q, a in wanted]
    sink = QuaternionRows(path, cell_names, scale,
                          capacity=count_lines(path, what="OptiTrack CSV export"))
    _complete_rows(stream, order, cell_names, path, section_ends_at_blank=False,
                   missing=f"rigid body {body!r} is not tracked in any frame", sink=sink)
    return sink.trajectory(parent=parent, child=child, duplicates=duplicates)


# --------------------------------------------------------------------------- Vicon


def read_vicon_csv(path: str | os.PathLike, segment: str | None = None, *,
                   parent: str = "world", child: str = "marker",
                   duplicates: str = "error") -> Trajectory:
    """Read one segment's global poses from the ``Segments`` section of a Vicon Nexus export.

    Parameters
    ----------
    path : path-like
    segment : str, optional
        Segment name as in the names row (``Subject:Segment``), or its part after the colon
        when that is unique; needed when the section has several segments.
    parent, child : str
        The poses are ``T_parent_child`` (segment in the Vicon world).
    duplicates : {"error", "drop"}
        As :func:`read_optitrack_csv`.

    Raises
    ------
    DatasetError
        No ``Segments`` section, bad frame rate, unknown units, segment missing (listing those
        present), malformed cells (with the line).
    """
    stream = _rows(_lines(path, "Vicon CSV export"))
    heads = set()   # sections seen, up to Segments; other sections' rows are not kept
    for number, r in stream:  # noqa: B007 (number is read after the loop)
        if r and r[0].strip() in _VICON_SECTIONS and _blank(r[1:]):
            heads.add(r[0].strip())
            if r[0].strip() == "Segments":
                break
    if "Segments" not in heads:
        reason = ("it has only marker Trajectories, which carry no orientation; export the "
                  "Segments section" if "Trajectories" in heads else
                  "expected a section line 'Segments' as Vicon Nexus writes it")
        raise DatasetError(f"no Segments section: {reason}", path=path)
    s = number - 1                              # 0-based index of the section line
    below = [r for _, r in itertools.islice(stream, 5)]
    if len(below) < 4:
        raise DatasetError("Segments section is truncated", path=path, line=s + 1)
    rate = parse_float(below[0][0] if below[0] else "", path=path, line=s + 2,
                       name="the frame rate (Hz)")
    if rate <= 0:
        raise DatasetError(f"frame rate must be positive, got {rate}", path=path, line=s + 2)
    names, labels, units = below[1], below[2], below[3]
    if [c.strip() for c in labels[:2]] != ["Frame", "Sub Frame"]:
        raise DatasetError("expected the labels row 'Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,...'",
                           path=path, line=s + 4)
    starts = [j for j in range(2, len(names)) if names[j].strip()]
    segments = [names[j].strip() for j in starts]
    name = _choose(segment, segments, "segment", path)
    j0 = starts[segments.index(name)]
    j1 = next((j for j in starts if j > j0), len(labels))
    wanted = ("TX", "TY", "TZ", "RX", "RY", "RZ")
    block = _columns_once(((labels[j].strip(), j) for j in range(j0, min(j1, len(labels)))),
                          wanted, f"segment {name!r}", path, s + 4)
    missing = [w for w in wanted if w not in block]
    if missing:
        raise DatasetError(f"segment {name!r} has no column for {', '.join(missing)}",
                           path=path, line=s + 4)
    order = [block[w] for w in wanted]

    def unit_of(label):
        j = block[label]
        return units[j].strip().lower() if j < len(units) else ""

    angle = {unit_of(w) for w in ("RX", "RY", "RZ")}
    length = {unit_of(w) for w in ("TX", "TY", "TZ")}
    if len(angle) != 1 or angle & {"deg", "rad"} != angle:
        raise DatasetError(f"rotation units must be 'deg' or 'rad', got {sorted(angle)}",
                           path=path, line=s + 5)
    if len(length) != 1 or not length <= set(LENGTH_UNITS):
        raise DatasetError(f"translation units must be one of {', '.join(LENGTH_UNITS)}, got "
                           f"{sorted(length)}", path=path, line=s + 5)
    to_rad = np.pi / 180.0 if angle == {"deg"} else 1.0
    scale = LENGTH_UNITS[length.pop()]
    data, lines = _complete_rows(itertools.chain([(s + 6, r) for r in below[4:]], stream), [0, *order],
                                 ("Frame",) + wanted, path,
                                 section_ends_at_blank=True,
                                 missing=f"segment {name!r} has no frame with a complete pose")
    with np.errstate(over="ignore", invalid="ignore"):
        t, rotvec, stamps = data[:, 1:4] * scale, data[:, 4:7] * to_rad, data[:, 0] / rate
    keep, skipped, lines = _screened(stamps, t, rotvec, ("Frame",) + wanted, path, lines,
                                     max_rotation=_MAX_ROTVEC_RAD)
    T = geometry.transform_from_rotvec(rotvec[keep], t[keep])
    return trajectory_from_rows(stamps[keep], T, path=path, lines=lines, frames=(parent, child),
                                skipped=skipped, duplicates=duplicates)


def csv_flavour(path: str | os.PathLike) -> str:
    """``"optitrack"``, ``"vicon"`` or ``"csv"`` from the first non-blank line of a CSV file;
    a Vicon Tracker export is refused (:func:`_refuse_tracker`)."""
    for number, line in text_lines(path, what="CSV file"):
        if line.strip():
            first = line.split(",")[0].strip()
            _refuse_tracker(first, path, number)
            if first == "Format Version":
                return "optitrack"
            if first in _VICON_SECTIONS:
                return "vicon"
            return "csv"
    return "csv"


def refuse_qualisys(path: str | os.PathLike) -> None:
    """Refuse a Qualisys Track Manager TSV export (first key ``NO_OF_FRAMES``), saying what to
    do, instead of reading its header as TUM rows: its 6DOF ``Roll Pitch Yaw`` follow a QTM
    Euler setting the file does not record, so no reading of them is safe."""
    for number, line in text_lines(path, what="motion-capture file"):
        if line.strip():
            if line.split()[0] == "NO_OF_FRAMES":
                raise DatasetError(
                    "a Qualisys Track Manager TSV export (first key NO_OF_FRAMES): multieye does "
                    "not read it (its Roll Pitch Yaw follow a QTM Euler setting the file does not "
                    "record); convert the body's poses to a TUM file (t x y z qx qy qz qw, "
                    "metres) or to rows read with format: tum, values and rotation "
                    "(docs/rig-yaml.md, section 4)", path=path, line=number)
            return
