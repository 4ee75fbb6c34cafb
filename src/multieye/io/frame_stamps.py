"""A video's frame stamps file: one time stamp per frame, in frame order.

Each line holds the stamp of one frame, by the rule of image names
(:func:`multieye.io.image_folder.stamp_from_name`): seconds with a decimal point
(``1700000000.033333``) or integer nanoseconds (16 to 19 digits), or whole seconds of at most
10 digits; ``#`` starts a comment, empty lines are skipped.  Stamps must increase.

Synopsis
--------
>>> from multieye.io.frame_stamps import read_frame_stamps
>>> ns = read_frame_stamps("cam0_stamps.txt")       # doctest: +SKIP
"""

from __future__ import annotations

import os

import numpy as np

from multieye.core.errors import DatasetError
from multieye.io.image_folder import stamp_from_name
from multieye.io.textfile import text_lines

__all__ = ["read_frame_stamps"]


def read_frame_stamps(path: str | os.PathLike) -> np.ndarray:
    """Integer nanoseconds of every frame, (n,), from a stamps file (module docstring).

    Raises
    ------
    DatasetError
        Missing or unreadable file, a line that is not one time stamp (with its number), a
        stamp not after the one before, no stamp at all.
    """
    out: list[int] = []
    for number, text in text_lines(path, what="frame stamps file"):
        try:
            ns = stamp_from_name(text)
        except ValueError as exc:
            raise DatasetError(f"expected one time stamp per line: {exc}", path=path,
                               line=number) from None
        if out and ns <= out[-1]:
            raise DatasetError("stamps must increase, frame by frame", path=path, line=number)
        out.append(ns)
    if not out:
        raise DatasetError("no frame stamp in the file", path=path)
    return np.array(out, dtype=np.int64)
