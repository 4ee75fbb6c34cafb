"""multieye: extrinsic calibration of multi-camera rigs from a motion-captured target.

The core is the closed-form joint solver of Wang, Jiang, Huang, Schwertfeger and Kneip,
"Accurate calibration of multi-perspective cameras from a generalization of the hand-eye
constraint" (ICRA 2022), solving ``A_i^j X^j = Y B_i^j`` for every camera j at once.

>>> import multieye
>>> run = multieye.calibrate("dataset")                 # doctest: +SKIP
>>> run.X["cam0"], run.X_std["cam0"], run.T_ref_cam["cam1"], run.warnings  # doctest: +SKIP
>>> sol = multieye.solve(A, B, method="joint")          # doctest: +SKIP

The functions are below; the classes they return or take, each with its own ``help``:
``multieye.Options`` (how :func:`calibrate` runs), ``CalibrationRun`` (what it returns:
``multieye.pipeline.CalibrationRun``), ``multieye.Solution`` and ``multieye.GeneralSolution``
(what the solvers return).  Errors, all subclasses of ``multieye.CalibrationError``:
``InputError`` (a bad argument), ``DatasetError`` (a bad file), ``TooFewMeasurementsError``,
``DegenerateMotionError``, ``DisconnectedError``.

The solvers and the pipeline are imported on first use (numpy and scipy load then), so
that ``import multieye`` and ``multieye --help`` stay instant.
"""

from importlib import import_module

# the errors: attributes of the package (``multieye.CalibrationError``), named in the docstring
from multieye.core.errors import CalibrationError as CalibrationError
from multieye.core.errors import DatasetError as DatasetError
from multieye.core.errors import DegenerateMotionError as DegenerateMotionError
from multieye.core.errors import DisconnectedError as DisconnectedError
from multieye.core.errors import InputError as InputError
from multieye.core.errors import TooFewMeasurementsError as TooFewMeasurementsError
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
    "calibrate_many": "many",
}

#: What ``help(multieye)`` documents: the functions and the method names (the classes and
#: the errors are attributes of the package too, each with its own ``help``).
__all__ = ["calibrate", "calibrate_many", "solve", "solve_general", "METHODS", "__version__"]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
