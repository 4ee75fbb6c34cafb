"""multieye: extrinsic calibration of multi-camera rigs from a motion-captured target.

The core is the closed-form joint solver of Wang, Jiang, Huang, Schwertfeger and Kneip,
"Accurate calibration of multi-perspective cameras from a generalization of the hand-eye
constraint" (ICRA 2022), solving ``A_i^j X^j = Y B_i^j`` for every camera j at once.

>>> import multieye
>>> sol = multieye.solve(A, B, method="joint")          # doctest: +SKIP
>>> run = multieye.calibrate("dataset")                 # doctest: +SKIP

The solvers and the pipeline are imported on first use (numpy and scipy load then), so
that ``import multieye`` and ``multieye --help`` stay instant.
"""

from importlib import import_module

from multieye.core.errors import (
    CalibrationError,
    DatasetError,
    DegenerateMotionError,
    DisconnectedError,
    InputError,
    TooFewMeasurementsError,
)

from multieye.core.version import __version__

#: Public names defined in submodules, imported when first used.
_LAZY = {
    "METHODS": "solvers",
    "Solution": "solvers",
    "solve": "solvers",
    "solve_general": "solvers",
    "GeneralSolution": "solvers",
    "calibrate": "pipeline",
    "Options": "pipeline",
}

__all__ = [
    "CalibrationError",
    "DatasetError",
    "DegenerateMotionError",
    "DisconnectedError",
    "InputError",
    "TooFewMeasurementsError",
    *_LAZY,
    "__version__",
]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
