"""The UTIAS generalised robot-world/hand-eye data (Wise et al. 2025): A/B pose pairs per tag and camera.

Layout (``certifiable-rwhe-calibration``, ``data/real-world/combined/``): one pair of files
per (AprilTag, camera) pair, ``tag_<T>_cam_<C>_A.csv`` and ``tag_<T>_cam_<C>_B.csv``.  Row i of
each file is one rigid transform, ``qw, qx, qy, qz, tx, ty, tz`` (unit quaternion, scalar
first, then metres), and row i of ``_A`` pairs with row i of ``_B`` in

    A_i @ X_tag = Y_cam @ B_i.

The source states nothing more about the frames; the data set's PROVENANCE.md argues that
``Y_cam`` is the rig-to-camera extrinsic (``T_body_cam``) and ``X_tag`` the pose of the tag in
the world.  The data carry no license, so they are read from where they are and never copied.

>>> from multieye.io.utias import read_utias_rwhec
>>> groups = read_utias_rwhec("../shared/data/utias_rwhec")      # doctest: +SKIP
>>> groups[0].x_name, groups[0].y_name, groups[0].A.shape        # doctest: +SKIP
('tag0', 'cam0', (208, 4, 4))
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from multieye.core.errors import DatasetError
from multieye.core.problem import MeasurementGroup
from multieye.io.poserows import quaternion_poses
from multieye.io.textfile import data_lines, parse_float, read_text, split_fields

__all__ = ["read_utias_rwhec", "read_pose_rows", "UTIAS_COLUMNS", "COMBINED_DIR"]

UTIAS_COLUMNS = ("qw", "qx", "qy", "qz", "tx", "ty", "tz")
#: Where the pose pairs sit below the data set's root folder.
COMBINED_DIR = Path("data", "real-world", "combined")

_NAME = re.compile(r"tag_(\d+)_cam_(\d+)_([AB])\.csv")


def read_pose_rows(path: str | os.PathLike) -> np.ndarray:
    """Transforms ``(N, 4, 4)`` from a file of ``qw, qx, qy, qz, tx, ty, tz`` rows (metres).

    Raises
    ------
    DatasetError
        With the file and 1-based line: a row without 7 entries, a cell that is not a finite
        number, a quaternion further than 1e-3 from unit norm, or a file without rows.
    """
    text = read_text(path, what="pose file")
    rows, lines = [], []
    for number, content in data_lines(text):
        fields = split_fields(content)
        if len(fields) != len(UTIAS_COLUMNS):
            raise DatasetError(f"expected 7 entries per row (qw, qx, qy, qz, tx, ty, tz), got "
                               f"{len(fields)}", path=path, line=number)
        rows.append([parse_float(f, path=path, line=number, name=name)
                     for f, name in zip(fields, UTIAS_COLUMNS)])
        lines.append(number)
    if not rows:
        raise DatasetError("no poses: expected rows 'qw, qx, qy, qz, tx, ty, tz'", path=path)
    data = np.asarray(rows)
    return quaternion_poses(data[:, 4:7], data[:, [1, 2, 3, 0]], path=path, lines=lines)


def read_utias_rwhec(path: str | os.PathLike) -> list[MeasurementGroup]:
    """Read every (tag, camera) pair of the UTIAS data as groups for ``solve_general``.

    Parameters
    ----------
    path : path-like
        The data set's root (containing ``data/real-world/combined``) or the folder of the
        CSV files itself.

    Returns
    -------
    list of MeasurementGroup
        One per file pair, ordered by tag id then camera id, with ``x_name = "tag<T>"``,
        ``y_name = "cam<C>"`` and ``A[i] @ X[x_name] ≈ Y[y_name] @ B[i]``.

    Raises
    ------
    DatasetError
        Missing folder, no pose files, an ``_A`` file without its ``_B`` (or the reverse), a
        pair whose files have different numbers of rows, or a malformed row (see
        :func:`read_pose_rows`).
    """
    root = Path(path)
    folder = root / COMBINED_DIR if (root / COMBINED_DIR).is_dir() else root
    if not folder.is_dir():
        raise DatasetError("expected the UTIAS data folder (with data/real-world/combined or "
                           "the tag_<T>_cam_<C>_A.csv files)", path=root)
    pairs: dict[tuple[int, int], dict[str, Path]] = {}
    for f in folder.iterdir():
        m = _NAME.fullmatch(f.name)
        if m:
            pairs.setdefault((int(m[1]), int(m[2])), {})[m[3]] = f
    if not pairs:
        raise DatasetError("no tag_<T>_cam_<C>_A.csv / _B.csv files found", path=folder)
    groups = []
    for (tag, cam), files in sorted(pairs.items()):
        for side, other in (("A", "B"), ("B", "A")):
            if side not in files:
                raise DatasetError(f"{files[other].name} has no matching _{side}.csv file",
                                   path=files[other], camera=f"cam{cam}")
        A = read_pose_rows(files["A"])
        B = read_pose_rows(files["B"])
        if len(A) != len(B):
            raise DatasetError(f"{len(A)} rows but {files['B'].name} has {len(B)}; row i of "
                               "_A pairs with row i of _B", path=files["A"], camera=f"cam{cam}")
        groups.append(MeasurementGroup(f"tag{tag}", f"cam{cam}", A, B))
    return groups
