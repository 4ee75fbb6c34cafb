"""From a dataset folder to a calibrated rig: reading, detection, pairing, solve, refinement.

The names below are imported on first use: :func:`calibrate` reads the dataset and starts
the detection before the later stages (SciPy and the solvers) are imported, and imports
those while the images are detected (issue 21, :mod:`multieye.pipeline.calibrate_dataset`).

Synopsis
--------
>>> from multieye.pipeline import calibrate
>>> run = calibrate("dataset", method="joint")          # doctest: +SKIP
>>> run.T_ref_cam["cam1"]                               # doctest: +SKIP
"""

from importlib import import_module

#: Public names and the submodule that defines each, imported when first used.
_LAZY = {
    "CameraData": "camera_data",
    "Observation": "camera_data",
    "PairedCamera": "camera_data",
    "load_camera_data": "camera_data",
    "pair_camera": "camera_data",
    "Options": "options",
    "CalibrationRun": "result",
    "Refinement": "result",
    "calibrate": "calibrate_dataset",
    "calibrate_rig": "run",
}

__all__ = ["CameraData", "Observation", "PairedCamera", "CalibrationRun", "Options",
           "Refinement", "load_camera_data", "pair_camera", "calibrate", "calibrate_rig"]


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    if not name.startswith("_"):   # a submodule, as when this package imported them all
        try:
            return import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
