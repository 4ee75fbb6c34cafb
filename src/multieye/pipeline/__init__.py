"""From a dataset folder to a calibrated rig: reading, detection, pairing, solve, refinement.

Synopsis
--------
>>> from multieye.pipeline import calibrate
>>> run = calibrate("dataset", method="joint")          # doctest: +SKIP
>>> run.T_ref_cam["cam1"]                               # doctest: +SKIP
"""

from multieye.pipeline.camera_data import (
    CameraData,
    Observation,
    PairedCamera,
    load_camera_data,
    pair_camera,
)
from multieye.pipeline.options import Options
from multieye.pipeline.result import CalibrationRun, Refinement
from multieye.pipeline.run import calibrate, calibrate_rig

__all__ = ["CameraData", "Observation", "PairedCamera", "CalibrationRun", "Options",
           "Refinement", "load_camera_data", "pair_camera", "calibrate", "calibrate_rig"]
