"""From a dataset folder to a calibrated rig: reading, detection, pairing, solve, refinement.

Synopsis
--------
>>> from multieye.pipeline import calibrate
>>> run = calibrate("dataset", method="joint")          # doctest: +SKIP
>>> run.record.cameras[0].T_ref_cam                     # doctest: +SKIP
"""

from multieye.pipeline.camera_data import (
    CameraData,
    Observation,
    PairedCamera,
    load_camera_data,
    pair_camera,
)
from multieye.pipeline.run import CalibrationRun, Options, Refinement, calibrate, calibrate_rig

__all__ = ["CameraData", "Observation", "PairedCamera", "CalibrationRun", "Options",
           "Refinement", "load_camera_data", "pair_camera", "calibrate", "calibrate_rig"]
