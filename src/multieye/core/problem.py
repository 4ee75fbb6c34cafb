"""The calibration problem's description, shared by every layer: setups and measurement groups.

docs/conventions.md, section 2: both setups are ``A_i^j X^j = Y B_i^j``; the
general problem tags each measurement with one unknown on each side, ``A_i X_a = Y_b B_i``.
:mod:`multieye.pipeline.problem` is the same kind of thing one layer up: the problem model the
pipeline's stages pass down, keyed by camera name.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["Setup", "SETUPS", "MeasurementGroup"]

F64 = NDArray[np.float64]

#: The two setups (docs/conventions.md, section 2): static cameras and a moved target, or
#: cameras on a moved rig and a static target.
Setup = Literal["eye-to-base", "eye-on-hand"]
SETUPS: tuple[str, ...] = ("eye-to-base", "eye-on-hand")


class MeasurementGroup(NamedTuple):
    """Measurements ``A[i] @ X[x_name] ≈ Y[y_name] @ B[i]`` of one pair of unknowns.

    Attributes
    ----------
    x_name, y_name : str
        Names of the unknowns on the left (X) and right (Y) side.  The two sides are separate
        name spaces.
    A, B : ndarray, shape (N, 4, 4)
        Rigid transforms, metres.
    """

    x_name: str
    y_name: str
    A: F64
    B: F64
