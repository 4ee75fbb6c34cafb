"""What a calibration run produced: :class:`CalibrationRun` (every per-camera result keyed by
camera name) and the :class:`Refinement` after the closed form; the same kind of module as
:mod:`multieye.solvers.result`, which holds one solve's :class:`~multieye.solvers.Solution`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from multieye.core.intrinsics import Intrinsics
from multieye.estimate.plausibility import Plausibility
from multieye.estimate.refine_images import RefinementResult
from multieye.io import CalibrationRecord, Rig
from multieye.io.calibration_json import SETUP_KEYS
from multieye.io.run_details import StageTimings
from multieye.pipeline.camera_data import CameraData, PairedCamera
from multieye.solvers import Solution

__all__ = ["Refinement", "CalibrationRun"]


@dataclass(frozen=True)
class Refinement:
    """What the maximum-likelihood refinement after the closed form gave.

    Attributes
    ----------
    kind : {"images", "poses"}
        On the target points and motion-capture poses, or on the pose residuals.
    X : ndarray, shape (m, 4, 4)
    Y : ndarray, shape (4, 4)
    covariance : ndarray, shape (6(m+1), 6(m+1)), or None
        Of the perturbations of X^1..X^m then Y (rotation vector, translation; radians,
        metres).
    reprojection_rms_px : dict of str to float
        Per camera, from the refined rig (image refinement only).
    warnings : tuple of str
    result : RefinementResult or Solution
        The refinement's own result: :class:`multieye.estimate.refine_images.RefinementResult`
        on images, a refined :class:`~multieye.solvers.Solution` on poses.
    intrinsics : dict of str to Intrinsics
        Per camera whose intrinsics were estimated: the refined lens (image refinement only).
    intrinsics_covariance : dict of str to ndarray
        Their covariance over ``Intrinsics.params`` (fx fy cx cy, then the distortion).
    time_offsets, time_offset_std : dict of str to float
        Per camera whose clock offset was an unknown of the image refinement
        (``time_offset="auto"``): its estimate and standard deviation, seconds.
    """

    kind: str
    X: np.ndarray
    Y: np.ndarray
    covariance: np.ndarray | None
    reprojection_rms_px: dict[str, float]
    warnings: tuple[str, ...]
    result: RefinementResult | Solution
    intrinsics: dict[str, Intrinsics] = field(default_factory=dict)
    intrinsics_covariance: dict[str, np.ndarray] = field(default_factory=dict)
    time_offsets: dict[str, float] = field(default_factory=dict)
    time_offset_std: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class CalibrationRun:
    """Everything a calibration produced, for writers, reports and Python users.

    Every per-camera result is keyed by camera name, in rig.yaml's order (``run.X["cam0"]``,
    ``run.T_ref_cam["cam0"]``, ``run.X_std["cam0"]``, ``run.intrinsics["cam0"]``).  The final
    result (refined when the refinement ran, else the closed form) is ``X``, ``Y``,
    ``T_ref_cam`` and their uncertainty; the closed form stays on ``closed_form``.

    >>> run = multieye.calibrate("dataset")                      # doctest: +SKIP
    >>> run.X["cam0"][:3, 3], run.X_std["cam0"]                  # doctest: +SKIP
    >>> run.T_ref_cam["cam1"], run.T_ref_cam_covariance["cam1"]  # doctest: +SKIP

    Attributes
    ----------
    rig : Rig
    record : CalibrationRecord
        The final result as written to ``calibration.json``.
    closed_form : Solution or None
        The closed form on the measurements kept (``closed_form.X`` in camera order,
        ``closed_form.Y``); None without motion capture (no closed form).
    cameras : dict of str to CameraData
        The inputs, per camera.
    paired : dict of str to PairedCamera
        The measurements kept, per camera.
    refinement : Refinement or None
        The refinement, when it ran and succeeded; its own result (a
        :class:`multieye.estimate.refine_images.RefinementResult` on images, a refined
        :class:`~multieye.solvers.Solution` on poses) is ``refinement.result``.
    timings : StageTimings
        Seconds per stage; ``reading`` and ``detection`` are 0 when the cameras were loaded
        outside :func:`calibrate`; ``outputs`` is 0: writing the files adds it to the
        timings written into ``details.json`` (``multieye.outputs.write.write_outputs``).
    plausibility : Plausibility or None
        The plausibility checks after the solve
        (:func:`multieye.estimate.plausibility.check_plausibility`).
    reference : str
        The camera whose frame is ``ref``.
    warnings : tuple of str
        Everything the run doubts (``calibration.json``'s ``warnings``).
    doubts : tuple of Finding
        What the plausibility checks doubt, each with its cause and message (also in
        ``warnings`` and ``record.plausibility``); empty when nothing is doubted.  The
        command line exits with status 3 when it is not empty.
    X : dict of str to (ndarray, shape (4, 4), or None)
        Per camera, final ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand); None
        without motion capture (setup ``overlap``).
    Y : ndarray, shape (4, 4), or None
        Final ``T_marker_target`` (eye-to-base) or ``T_world_target`` (eye-on-hand); None
        without motion capture.
    links : dict of str to CameraLinks
        Per camera, what links it to the others (shared views, motion capture).
    T_ref_cam : dict of str to ndarray, shape (4, 4)
        Per camera, final extrinsics relative to the reference camera.
    X_covariance, T_ref_cam_covariance : dict of str to (ndarray, shape (6, 6)) or None
        Per camera, the covariance of ``X`` / ``T_ref_cam`` (rotation vector then
        translation, left perturbation, radians and metres; docs/conventions.md); None
        without refinement.
    X_std, T_ref_cam_std : dict of str to (float, float) or None
        Per camera, (degrees, metres): root of the trace of the rotation / translation block
        of that covariance.
    Y_covariance : ndarray, shape (6, 6), or None
    Y_std : (float, float) or None
    intrinsics : dict of str to Intrinsics
        Per camera that has one, the final lens (estimated ones refined).
    covariance : ndarray, shape (6(m+1), 6(m+1)), or None
        Joint covariance of X^1..X^m (cameras in the order of ``X``) then Y
        (:attr:`Refinement.covariance`); None without refinement.
    """

    rig: Rig
    record: CalibrationRecord
    closed_form: Solution | None
    cameras: dict[str, CameraData]
    paired: dict[str, PairedCamera]
    refinement: Refinement | None = None
    timings: StageTimings = field(default_factory=StageTimings)
    plausibility: Plausibility | None = None

    @property
    def doubts(self) -> tuple:
        return () if self.plausibility is None else self.plausibility.findings

    @property
    def reference(self) -> str:
        return self.record.reference_camera

    @property
    def warnings(self) -> tuple[str, ...]:
        return self.record.warnings

    @property
    def X(self) -> dict[str, np.ndarray]:
        return {c.name: c.X for c in self.record.cameras}

    @property
    def Y(self) -> np.ndarray:
        return self.record.Y

    @property
    def T_ref_cam(self) -> dict[str, np.ndarray]:
        return {c.name: c.T_ref_cam for c in self.record.cameras}

    def _uncertainty(self, key: str) -> dict:
        return {c.name: (c.uncertainty or {}).get(key) for c in self.record.cameras}

    @property
    def X_covariance(self) -> dict[str, np.ndarray | None]:
        x_key = SETUP_KEYS.get(self.record.setup, (None, None))[1]     # overlap: no X
        return {n: None if u is None else u.covariance
                for n, u in self._uncertainty(x_key).items()}

    @property
    def X_std(self) -> dict[str, tuple[float, float] | None]:
        x_key = SETUP_KEYS.get(self.record.setup, (None, None))[1]
        return {n: None if u is None else (u.std_rot_deg, u.std_trans_m)
                for n, u in self._uncertainty(x_key).items()}

    @property
    def links(self) -> dict:
        """Per camera, what links it (:class:`multieye.io.calibration_json.CameraLinks`)."""
        return {c.name: c.links for c in self.record.cameras}

    @property
    def T_ref_cam_covariance(self) -> dict[str, np.ndarray | None]:
        return {c.name: c.covariance for c in self.record.cameras}

    @property
    def T_ref_cam_std(self) -> dict[str, tuple[float, float] | None]:
        return {c.name: None if c.covariance is None else (c.std_rot_deg, c.std_trans_m)
                for c in self.record.cameras}

    @property
    def Y_covariance(self) -> np.ndarray | None:
        u = (self.record.uncertainty or {}).get(SETUP_KEYS.get(self.record.setup, (None,))[0])
        return None if u is None else u.covariance

    @property
    def Y_std(self) -> tuple[float, float] | None:
        u = (self.record.uncertainty or {}).get(SETUP_KEYS.get(self.record.setup, (None,))[0])
        return None if u is None else (u.std_rot_deg, u.std_trans_m)

    @property
    def intrinsics(self) -> dict:
        return {c.name: c.intrinsics.intrinsics for c in self.record.cameras
                if c.intrinsics is not None}

    @property
    def covariance(self) -> np.ndarray | None:
        return None if self.refinement is None else self.refinement.covariance
