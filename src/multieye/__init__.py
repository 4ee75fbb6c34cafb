"""multieye: extrinsic calibration of multi-camera rigs from a motion-captured target.

The core is the closed-form joint solver of Wang, Jiang, Huang, Schwertfeger and Kneip,
"Accurate calibration of multi-perspective cameras from a generalization of the hand-eye
constraint" (ICRA 2022), solving ``A_i^j X^j = Y B_i^j`` for every camera j at once.

>>> import multieye
>>> sol = multieye.solve(A, B, method="joint")   # doctest: +SKIP
"""

from .errors import (
    CalibrationError,
    DatasetError,
    DegenerateMotionError,
    DisconnectedError,
    InputError,
    TooFewMeasurementsError,
)

from .general import GeneralSolution, solve_general
from .solvers import METHODS, Solution, solve

__version__ = "0.1.0"

__all__ = [
    "CalibrationError",
    "DatasetError",
    "DegenerateMotionError",
    "DisconnectedError",
    "InputError",
    "TooFewMeasurementsError",
    "METHODS",
    "Solution",
    "solve",
    "solve_general",
    "GeneralSolution",
    "__version__",
]
