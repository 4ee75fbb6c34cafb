"""Poses stamped in time, one row of plain numbers each: a TUM-like motion-capture file
whose ``values`` include ``t``, or whose ``rotation`` is not ``quaternion-xyzw``
(``mocap: {format: tum, values: [...], rotation: ...}`` in rig.yaml; docs/rig-yaml.md,
section 4).  The numbers of one row are read as :mod:`multieye.io.pose_files` reads a pose
file's; stamps are seconds, or integer nanoseconds (16 to 19 digits, as TUM files and image
names: :func:`multieye.io.textfile.is_nanoseconds`) decided by the file's first row.
"""

from __future__ import annotations

import os
import re

import numpy as np

from multieye.core.errors import DatasetError
from multieye.io.pose_files import (PoseFormat, _checked, _is_number, _matrix, _named,
                                    default_values)
from multieye.io.poserows import RowPlace, trajectory_from_rows, usable_rows
from multieye.io.textfile import (first_cell_is_nanoseconds, header_row, length_scale,
                                  read_number_rows, split_fields, text_lines)

__all__ = ["read_stamped_table"]


#: The numbers of a matrix stamped in time: ``t`` then its top three rows, or (17 numbers
#: in the first row) its four rows.
_MATRIX_ROW = ("t",) + tuple(f"m{r}{c}" for r in range(1, 4) for c in range(1, 5))
_MATRIX_ROW4 = ("t",) + tuple(f"m{r}{c}" for r in range(1, 5) for c in range(1, 5))


def _first_row_count(path) -> int:
    """How many numbers the file's first row of numbers holds (0 without rows)."""
    for _, content in text_lines(path, what="motion-capture file"):
        cells = split_fields(content)
        if any(_is_number(c) for c in cells):
            return len(cells)
    return 0


def _header_order(header: tuple[int, list[str]], order: tuple[str, ...], path
                  ) -> tuple[str, ...]:
    """The order of a row's numbers given a header row (a CSV export's first line): the
    header's names when they are those of ``order`` (any order, any case, a leading ``#``
    and a unit suffix ``[m]`` ignored), else ``order`` itself, the header only counted."""
    line, cells = header
    names = [re.sub(r"\s*[\[(][^\])]*[\])]$", "", c.lstrip("#").strip()).lower()
             for c in cells]
    if len(names) != len(order):
        raise DatasetError(f"the header row has {len(names)} names ({', '.join(cells)[:120]}) "
                           f"and the rows are read as {len(order)} numbers "
                           f"({' '.join(order)}); give values: with one name per column",
                           path=path, line=line)
    return tuple(names) if sorted(names) == sorted(order) else order


def read_stamped_table(path: str | os.PathLike, fmt: PoseFormat, *, parent: str = "world",
                       child: str = "marker", duplicates: str = "error"):
    """Poses stamped in time, one row of plain numbers each (a TUM-like file whose ``values``
    include ``t``, or whose ``rotation`` is not ``quaternion-xyzw``).

    ``values`` default to ``t`` then :func:`default_values`; ``rotation: matrix`` rows are
    ``t`` then the 12 numbers of the pose's top three rows (row-major), or the 16 of its
    four rows when the first row holds 17 numbers. Rows with a value that
    is not finite or absurd are left out and listed in ``skipped`` as TUM rows are
    (:func:`multieye.io.poserows.usable_rows`).

    Raises
    ------
    DatasetError
        A row with another count of numbers, a bad rotation, stamps that repeat or go back;
        with the file and the line.
    """

    matrix = fmt.rotation == "matrix"
    if matrix:
        order = _MATRIX_ROW4 if _first_row_count(path) == len(_MATRIX_ROW4) else _MATRIX_ROW
    else:
        order = (
            fmt.values if fmt.values is not None else ("t",) + default_values(fmt.rotation))
    header = header_row(path, what="motion-capture file")
    if header is not None:
        order = _header_order(header, order, path)
    data, lines = read_number_rows(path, order, files=f"pose rows ({fmt.rotation})",
                                   what="motion-capture file", finite=False,
                                   skip_line=None if header is None else header[0])
    if first_cell_is_nanoseconds(path, order.index("t")):
        data[:, order.index("t")] *= 1e-9
    scale = length_scale(fmt.unit, path=path)
    col = {n: i for i, n in enumerate(order)}
    xyz = ("m14", "m24", "m34") if matrix else ("x", "y", "z")
    rot = [n for n in order if n not in xyz and n != "t"]
    with np.errstate(over="ignore", invalid="ignore"):
        t_xyz = data[:, [col[n] for n in xyz]] * scale
    keep, skipped, kept = usable_rows(data[:, col["t"]], t_xyz, data[:, [col[n] for n in rot]],
                                      where=RowPlace(path, lines), columns=("t", *xyz, *rot))
    T = []
    for row, line in zip(data[keep], kept):
        try:
            if matrix:
                T.append(_checked(_matrix(row[1:], scale, path), path))
            else:
                T.append(_named(dict(zip(order, row)), PoseFormat(fmt.rotation, order, None,
                                                                  fmt.unit), scale, path))
        except DatasetError as exc:
            raise DatasetError(exc.reason, path=path, line=line) from None
    return trajectory_from_rows(data[keep, col["t"]], np.stack(T) if T else np.zeros((0, 4, 4)),
                                path=path, lines=kept, frames=(parent, child),
                                duplicates=duplicates, skipped=skipped)
