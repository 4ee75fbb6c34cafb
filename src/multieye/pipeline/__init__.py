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

from multieye.core.lazy_names import lazy_names

#: Public names and the submodule that defines each, imported when first used.
_LAZY = {
    "CameraData": ".camera_data",
    "Observation": ".camera_data",
    "PairedCamera": ".camera_data",
    "load_camera_data": ".camera_data",
    "pair_camera": ".camera_data",
    "Options": ".options",
    "CalibrationRun": ".result",
    "Refinement": ".result",
    "calibrate": ".calibrate_dataset",
    "calibrate_rig": ".run",
}

__all__ = ["CameraData", "Observation", "PairedCamera", "CalibrationRun", "Options",
           "Refinement", "load_camera_data", "pair_camera", "calibrate", "calibrate_rig"]


__getattr__, __dir__ = lazy_names(__name__, _LAZY)
