"""The content of ``calibration.json`` as records: what the pipeline fills and the readers give.

:class:`CalibrationRecord` holds the result of a calibration, one :class:`CameraRecord` per
camera; :mod:`multieye.io.calibration_json` writes and reads it (docs/outputs.md, section 2).
Keys depend on the setup (docs/conventions.md, section 2; :data:`SETUP_KEYS`); a rig without
motion capture (setup ``overlap``) has no ``Y`` and no camera an ``X``: each camera's
``T_ref_cam`` is the result, and ``links`` says what ties each camera to the others.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from multieye.core.errors import InputError
from multieye.core.arguments import transform
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens_curve import RadialCurve

__all__ = [
    "FORMAT_VERSION",
    "WIDE_LENS_VERSION",
    "SETUP_KEYS",
    "OVERLAP",
    "ROLE_NAMES",
    "Residuals",
    "RejectedItem",
    "PlausibilityItem",
    "PoseUncertainty",
    "BoardRecord",
    "IntrinsicsRecord",
    "CameraLinks",
    "CameraRecord",
    "CalibrationRecord",
]

#: Newest ``format_version`` this version writes and reads: raised whenever a key changes
#: meaning (docs/outputs.md, section 2).  Files without it are of version 1.  Version 2:
#: ``setup`` may be ``overlap`` (no motion capture: no ``Y``, no ``X``), and every camera has
#: ``links``.  Version 3: a camera's ``intrinsics.model`` may be ``unified``,
#: ``double-sphere`` or ``eucm``, whose ``distortion`` holds that model's parameters (a
#: version-2 reader would take them for OpenCV's coefficients); a file is written as version
#: 3 only when it has such a lens (:data:`WIDE_LENS_VERSION`), else as version 2.
FORMAT_VERSION = 3
#: The first version whose cameras may have a wide-angle lens.
WIDE_LENS_VERSION = 3

#: The setup of a rig linked by co-observations only (no motion capture).
OVERLAP = "overlap"

#: setup -> (key of the shared unknown Y, key of each camera's X).
SETUP_KEYS = {
    "eye-to-base": ("T_marker_target", "T_world_cam"),
    "eye-on-hand": ("T_world_target", "T_body_cam"),
}

#: setup -> the roles of the frames ``calibration.json``'s ``frames`` names: the motion
#: capture's fixed frame and the tracked one.
ROLE_NAMES = {"eye-to-base": ("world", "marker"), "eye-on-hand": ("world", "body")}


def _rigid(T, what: str) -> np.ndarray:
    return transform(T, what, rigid=True)


@dataclass(frozen=True)
class Residuals:
    """Residuals of the loop ``A_i X = Y B_i`` (paper section V-A; docs/conventions.md, section 7).

    Attributes
    ----------
    e_R_deg : float
        Mean rotation residual, degrees.
    e_t_m : float
        Mean translation residual, metres.
    max_R_deg, max_t_m : float or None
        Worst measurement.
    reprojection_rms_px : float or None
        RMS reprojection error of the target points, pixels (image pipeline).
    """

    e_R_deg: float
    e_t_m: float
    max_R_deg: float | None = None
    max_t_m: float | None = None
    reprojection_rms_px: float | None = None


@dataclass(frozen=True)
class RejectedItem:
    """An image or measurement left out, and why (``item`` is e.g. the image file name)."""

    item: str
    reason: str


@dataclass(frozen=True)
class PlausibilityItem:
    """What a plausibility check doubts (:mod:`multieye.estimate.plausibility`): its
    ``cause`` (``scale``, ``unit``, ``quaternion-order``, ``rotation-convention``, ``setup``,
    ``inverted-poses``, ``time-offset``, ``intrinsics``, ``noise``, ``fit``, ``observability``,
    ``given-pose``), the ``message`` and, for a per-camera doubt, the
    ``camera``."""

    cause: str
    message: str
    camera: str | None = None


@dataclass(frozen=True)
class PoseUncertainty:
    """Uncertainty of one transform (docs/conventions.md, covariance convention).

    Attributes
    ----------
    std_rot_deg, std_trans_m : float
        Root of the trace of the rotation / translation block of ``covariance``.
    covariance : ndarray, shape (6, 6)
        Rotation vector (rad) then translation (m), perturbation ``R = Exp(phi) R_hat``,
        ``t = t_hat + tau``, in the frame the transform maps into.
    """

    std_rot_deg: float
    std_trans_m: float
    covariance: np.ndarray

    def __post_init__(self):
        C = np.asarray(self.covariance, dtype=np.float64)
        if C.shape != (6, 6) or not np.all(np.isfinite(C)):
            raise InputError(f"a pose covariance must be a finite 6x6 matrix, got shape {C.shape}")
        object.__setattr__(self, "covariance", C)


@dataclass(frozen=True)
class BoardRecord:
    """One board of a rig with several (rig.yaml's ``targets:``; issue 34).

    Attributes
    ----------
    T_world_target : ndarray, shape (4, 4)
        The board's pose; without motion capture in the first board's frame (the identity
        for the first board).
    given : bool
        The pose is rig.yaml's ``pose:`` (held fixed), not estimated.
    views : int
        Views of this board used, over every camera.
    cameras : mapping of str to int
        Camera name -> views of this board it contributed (cameras with at least one).
    uncertainty : PoseUncertainty or None
        Left perturbation in the fixed frame (zero for the first board without motion
        capture and for a given pose).
    bounds : (float, float, float, float) or None
        ``x_min, x_max, y_min, y_max`` of the printed pattern in the board's frame, metres
        (what the report draws); None in files written before it was kept.
    z_into_board : bool
        The board's +z points away from the side it is seen from.
    """

    T_world_target: np.ndarray
    given: bool = False
    views: int = 0
    cameras: Mapping = field(default_factory=dict)
    uncertainty: PoseUncertainty | None = None
    bounds: tuple | None = None
    z_into_board: bool = True

    def __post_init__(self):
        object.__setattr__(self, "T_world_target", _rigid(self.T_world_target,
                                                          "T_world_target"))
        counts = [self.views, *dict(self.cameras).values()] if isinstance(
            self.cameras, Mapping) else [None]
        if not isinstance(self.given, bool) or not all(
                isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 0
                for v in counts):
            raise InputError("a target's given must be true or false, its views and the "
                             "views per camera whole numbers >= 0")
        object.__setattr__(self, "views", int(self.views))
        object.__setattr__(self, "cameras", {str(k): int(v) for k, v in self.cameras.items()})
        if self.bounds is not None:
            b = np.asarray(self.bounds, dtype=np.float64)
            if b.shape != (4,) or not np.all(np.isfinite(b)) or b[0] >= b[1] or b[2] >= b[3]:
                raise InputError("a target's bounds must be [x_min, x_max, y_min, y_max] "
                                 "with x_min < x_max and y_min < y_max, metres")
            object.__setattr__(self, "bounds", tuple(float(x) for x in b))
        if not isinstance(self.z_into_board, bool):
            raise InputError("a target's z_into_board must be true or false")


@dataclass(frozen=True)
class IntrinsicsRecord:
    """A camera's intrinsics as calibration.json states them.

    Attributes
    ----------
    intrinsics : Intrinsics
    estimated : bool
        Estimated (or refined) from the recording; False: given and held fixed.
    covariance : ndarray, shape (4 + k, 4 + k), or None
        Over fx fy cx cy then the distortion coefficients (OpenCV order), when estimated.
    projection_std_px : (float, float) or None
        Mean and largest standard deviation of the projection of a fixed camera-frame ray
        over the observed target points (root of half the trace of the 2x2 pixel covariance
        from ``covariance``), pixels.
    lens_curve : RadialCurve or None
        A wide-angle or fisheye lens' radial curve at three rays over the observed field and
        its covariance (:func:`multieye.core.lens_curve.observed_curve`), when estimated
        with a covariance; the honest statement of its uncertainty where the parameters'
        covariance is not (docs/outputs.md).
    """

    intrinsics: Intrinsics
    estimated: bool = False
    covariance: np.ndarray | None = None
    projection_std_px: tuple[float, float] | None = None
    lens_curve: RadialCurve | None = None


@dataclass(frozen=True)
class CameraLinks:
    """What ties one camera to the others.

    Attributes
    ----------
    overlap : mapping of str to int
        The other cameras it saw the target together with, and at how many instants.
    mocap : bool
        Paired with motion capture.
    motion : tuple of (tuple of str, tuple of str)
        Linked through the rig's motion (no motion capture, issue 34): the cameras whose
        boards gave the rig's pose at the instants that placed it, and those boards; empty
        when not.
    boards : mapping of str to int
        With several boards: the boards the camera saw, with its views of each.
    """

    overlap: Mapping = field(default_factory=dict)
    mocap: bool = False
    motion: tuple = ()
    boards: Mapping = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.overlap, Mapping) or not all(
                isinstance(k, str) and isinstance(v, (int, np.integer)) and not
                isinstance(v, bool) and v > 0 for k, v in self.overlap.items()):
            raise InputError(f"links.overlap must map camera names to positive counts, got "
                             f"{self.overlap!r}")
        if not isinstance(self.mocap, bool):
            raise InputError(f"links.mocap must be true or false, got {self.mocap!r}")
        object.__setattr__(self, "overlap", {k: int(v) for k, v in self.overlap.items()})
        if not isinstance(self.boards, Mapping) or not all(
                isinstance(k, str) and isinstance(v, (int, np.integer)) and not
                isinstance(v, bool) and v > 0 for k, v in self.boards.items()):
            raise InputError(f"links.boards must map board names to positive counts, got "
                             f"{self.boards!r}")
        object.__setattr__(self, "boards", {k: int(v) for k, v in self.boards.items()})
        if self.motion:
            parts = tuple(self.motion) if isinstance(self.motion, (tuple, list)) else ()
            if not (len(parts) == 2 and all(isinstance(p, (tuple, list)) and p and all(
                    isinstance(x, str) for x in p) for p in parts)):
                raise InputError("links.motion must name the cameras and the boards it came "
                                 f"through, got {self.motion!r}")
            object.__setattr__(self, "motion", (tuple(parts[0]), tuple(parts[1])))

    def describe(self) -> str:
        """``overlap with cam1 (31 instants), cam2 (28); motion via cam0 and board north;
        motion capture`` (what links it)."""
        parts = []
        if self.overlap:
            parts.append("overlap with " + ", ".join(
                f"{n} ({k}{' instants' if i == 0 else ''})"
                for i, (n, k) in enumerate(self.overlap.items())))
        if self.motion:
            via, boards = self.motion
            parts.append(f"motion via {', '.join(via)} and board{'s' * (len(boards) > 1)} "
                         f"{', '.join(boards)}")
        if self.mocap:
            parts.append("motion capture")
        return "; ".join(parts) or "nothing"


@dataclass(frozen=True)
class CameraRecord:
    """One camera of a calibration result.

    Attributes
    ----------
    name : str
    X : ndarray, shape (4, 4), or None
        ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand), metres; None without
        motion capture (setup ``overlap``).
    T_ref_cam : ndarray, shape (4, 4)
        Pose of the camera in the reference camera's frame.
    measurements_used : int
    residuals : Residuals or None
    time_offset_s : float or None
        Motion-capture clock minus camera clock, seconds.
    time_offset_std_s : float or None
        Standard deviation of ``time_offset_s`` when it was estimated in the joint problem.
    std_rot_deg, std_trans_m : float or None
        Root of the trace of the rotation / translation covariance of ``T_ref_cam``.
    covariance : ndarray, shape (6, 6), or None
        Covariance of ``T_ref_cam``: rotation vector (rad) then translation (m), both in the
        reference camera's frame, for the perturbation ``R = Exp(phi) R_hat``,
        ``t = t_hat + tau`` (left, not the camera-frame convention some tools use).
    rejected : tuple of RejectedItem
    intrinsics : IntrinsicsRecord or None
        None for a camera given by precomputed poses without intrinsics.
    uncertainty : mapping of str to PoseUncertainty, or None
        Of ``X`` (under its key, ``T_world_cam`` or ``T_body_cam``) and of ``T_ref_cam``.
    links : CameraLinks or None
        What ties the camera to the others (None in files of version 1).
    """

    name: str
    X: np.ndarray | None
    T_ref_cam: np.ndarray
    measurements_used: int
    residuals: Residuals | None = None
    time_offset_s: float | None = None
    std_rot_deg: float | None = None
    std_trans_m: float | None = None
    covariance: np.ndarray | None = None
    rejected: tuple[RejectedItem, ...] = ()
    intrinsics: IntrinsicsRecord | None = None
    uncertainty: Mapping | None = None
    time_offset_std_s: float | None = None
    links: CameraLinks | None = None

    def __post_init__(self):
        if self.X is not None:
            object.__setattr__(self, "X", _rigid(self.X, f"camera {self.name}: X"))
        object.__setattr__(self, "T_ref_cam", _rigid(self.T_ref_cam,
                                                     f"camera {self.name}: T_ref_cam"))
        if self.covariance is not None:
            C = np.asarray(self.covariance, dtype=np.float64)
            if C.shape != (6, 6) or not np.all(np.isfinite(C)):
                raise InputError(f"camera {self.name}: covariance must be a finite 6x6 matrix, "
                                 f"got shape {C.shape}")
            object.__setattr__(self, "covariance", C)
        n = self.measurements_used
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise InputError(f"camera {self.name}: measurements_used must be a non-negative "
                             f"integer, got {n!r}")
        object.__setattr__(self, "measurements_used", int(n))
        object.__setattr__(self, "rejected", tuple(self.rejected))


@dataclass(frozen=True)
class CalibrationRecord:
    """Everything ``calibration.json`` holds.

    Attributes
    ----------
    setup : {"eye-to-base", "eye-on-hand", "overlap"}
        ``overlap``: no motion capture, the cameras linked by the views they share (no ``Y``,
        no camera has an ``X``).
    method : str
        Solver registry name (``covisibility`` for ``overlap``: the start from the graph of
        shared views).
    reference_camera : str
        Name of the camera whose frame is ``ref``; one of ``cameras``.
    Y : ndarray, shape (4, 4), or None
        ``T_marker_target`` (eye-to-base) or ``T_world_target`` (eye-on-hand), metres; None
        for ``overlap``.
    cameras : tuple of CameraRecord
        In output order.
    residuals : Residuals
        Over all cameras.
    warnings : tuple of str
    refinement : str or None
        What followed the closed form: ``"images"`` (maximum likelihood on the target points
        and the motion capture), ``"poses"`` (on the pose residuals), or None.
    motion_diagnostics : mapping or None
        Per camera, the numbers of :func:`multieye.estimate.diagnostics.motion_diagnostics` (rotation
        range, spread of rotation axes, conditions), plain JSON values.
    plausibility : tuple of PlausibilityItem
        What the plausibility checks doubt; empty when nothing (their messages are among
        ``warnings`` too).
    uncertainty : mapping of str to PoseUncertainty, or None
        Of ``Y`` (under its key, ``T_marker_target`` or ``T_world_target``).
    frames : mapping of str to str, or None
        The user's names of the frames by role (``{"world": "base", "body": "tool0"}``,
        rig.yaml's ``pose:``); None: the role names.  The keys of ``calibration.json`` keep
        the role names; screen, report and exports use these (:meth:`CalibrationRecord.named_keys`).
    targets : mapping of str to BoardRecord, or None
        With several boards: every board by name, in rig.yaml's order.
    """

    setup: str
    method: str
    reference_camera: str
    Y: np.ndarray | None
    cameras: tuple[CameraRecord, ...]
    residuals: Residuals
    warnings: tuple[str, ...] = field(default=())
    refinement: str | None = None
    motion_diagnostics: Mapping | None = None
    plausibility: tuple[PlausibilityItem, ...] = ()
    uncertainty: Mapping | None = None
    frames: Mapping[str, str] | None = None
    targets: Mapping | None = None

    def __post_init__(self):
        if self.targets is not None and not (isinstance(self.targets, Mapping) and all(
                isinstance(k, str) and isinstance(v, BoardRecord)
                for k, v in self.targets.items())):
            raise InputError("targets must map board names to their records")
        if self.setup not in SETUP_KEYS and self.setup != OVERLAP:
            raise InputError(f"setup must be one of {', '.join(SETUP_KEYS)} or {OVERLAP}, got "
                             f"{self.setup!r}")
        mocap = self.setup != OVERLAP
        if (self.Y is None) == mocap or any((c.X is None) == mocap for c in self.cameras):
            raise InputError(f"setup {self.setup}: " + (
                "Y and every camera's X are needed" if mocap else
                "a rig without motion capture has no Y and no X"))
        if self.frames is not None and not mocap:
            raise InputError("a rig without motion capture names no motion-capture frames")
        if self.frames is not None:
            roles = ROLE_NAMES[self.setup]
            if (not isinstance(self.frames, Mapping) or set(self.frames) != set(roles)
                    or not all(isinstance(v, str) and v for v in self.frames.values())
                    or len(set(self.frames.values())) != 2):
                raise InputError(f"frames must name the roles {', '.join(roles)} with two "
                                 f"different names, got {self.frames!r}")
            object.__setattr__(self, "frames", {r: self.frames[r] for r in roles})
        if mocap:
            object.__setattr__(self, "Y", _rigid(self.Y, SETUP_KEYS[self.setup][0]))
        cams = tuple(self.cameras)
        names = [c.name for c in cams]
        if len(set(names)) != len(names):
            raise InputError(f"camera names must be unique, got {names}")
        if self.reference_camera not in names:
            raise InputError(f"reference camera {self.reference_camera!r} is not one of "
                             f"{names}")
        object.__setattr__(self, "cameras", cams)
        object.__setattr__(self, "warnings", tuple(self.warnings))
        object.__setattr__(self, "plausibility", tuple(self.plausibility))

    @property
    def mocap(self) -> bool:
        """Motion capture links the rig (``Y`` and every ``X`` exist)."""
        return self.setup != OVERLAP

    def named_keys(self) -> tuple[str, str]:
        """:data:`SETUP_KEYS` of the record's setup with the user's frame names (rig.yaml's
        ``pose:``, :attr:`frames`) for the roles: ``("T_base_target", "T_tool0_cam")`` for
        eye-on-hand with ``frames={"world": "base", "body": "tool0"}``,
        ``("T_marker_target", "T_world_cam")`` for eye-to-base without frames."""
        y_key, x_key = SETUP_KEYS[self.setup]
        frames = self.frames
        if not frames:
            return y_key, x_key

        def rename(key: str) -> str:           # T_<role>_<target or cam>
            _, role, frame = key.split("_")
            return f"T_{frames.get(role, role)}_{frame}"

        return rename(y_key), rename(x_key)

    def camera(self, name: str) -> CameraRecord:
        """The record of camera ``name``."""
        for cam in self.cameras:
            if cam.name == name:
                return cam
        raise KeyError(name)
