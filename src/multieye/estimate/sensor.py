"""What measures the motion-capture poses, and the noise it can have at most.

A pose noise estimated from the data (:func:`multieye.estimate.refine_images.refine_images`
with the noise unstated) absorbs whatever the model leaves out: a lens distortion missing
from the intrinsics, a wrong target size, a wrong clock.  The estimate is therefore checked
against what the sensor has at most (:func:`multieye.estimate.plausibility.check_noise`), and
the plausibility hypotheses are tested against the noise the sensor should have, never the
estimate.  The bounds, per pose and per axis (docs/rig-yaml.md, section 4, gives the
reasoning):

``motion-capture``
    0.5 degrees, 3 mm.  Marker-based systems (Vicon, OptiTrack) locate markers to 0.1-0.3 mm
    static and to about 2 mm on moving bodies; a rigid body of markers about 10 cm apart turns
    a 1 mm marker error into about 0.5 degrees.
``robot``
    0.1 degrees, 1 mm.  Industrial arms repeat a pose to 0.02-0.1 mm (ISO 9283 repeatability
    in their data sheets); the absolute pose an uncalibrated arm reports across its working
    range is off by up to about 0.5-1 mm and a few hundredths of a degree.

rig.yaml's ``mocap:`` may name the sensor (``sensor: motion-capture | robot``) or give its own
bounds (``noise_bounds: {rotation_deg, translation_m}``); otherwise the sensor is inferred
from the pose source: poses matched to the images by name (one pose file per image, a table
with an image column) or in their order (``match: order``) or a robot's frame names
(``T_base_tool0``, ``flange``, ``tcp``, ...) are a robot; time-stamped trajectories (TUM,
CSV, OptiTrack, Vicon, bags) motion capture.

Synopsis
--------
>>> bounds = sensor_bounds(rig.mocap)                    # doctest: +SKIP
>>> bounds.kind, bounds.rot_rad, bounds.trans_m, bounds.why  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from multieye.io.mocap import MocapSpec

__all__ = ["SENSOR_BOUNDS", "TYPICAL_NOISE", "ROBOT_FRAME_NAMES", "SensorBounds",
           "sensor_bounds", "hypothesis_noise"]

#: The largest plausible noise per pose and axis of each sensor: rotation (rad), translation (m).
SENSOR_BOUNDS = {"motion-capture": (math.radians(0.5), 3e-3),
                 "robot": (math.radians(0.1), 1e-3)}
#: The noise the plausibility hypotheses are tested against when none is stated (rotation,
#: translation): what a good motion capture or robot has, and at most each sensor's bound.
TYPICAL_NOISE = (math.radians(0.1), 0.3e-3)
#: Frame names (lower case, or their start) that say the poses come from a robot.
ROBOT_FRAME_NAMES = ("base", "tool", "flange", "tcp", "ee", "end_effector", "endeffector",
                     "end", "gripper", "wrist", "link", "robot", "arm")


@dataclass(frozen=True)
class SensorBounds:
    """The sensor behind the poses and its largest plausible noise.

    Attributes
    ----------
    kind : {"motion-capture", "robot"}
    rot_rad, trans_m : float
        Largest plausible noise per pose and axis: rotation (radians), translation (metres).
    why : str
        How the sensor was known, for messages (``sensor: robot in rig.yaml``, ``inferred
        from the pose files matched to the images by name``, ...).
    """

    kind: str
    rot_rad: float
    trans_m: float
    why: str

    @property
    def name(self) -> str:
        """``robot`` or ``motion capture``, for messages."""
        return self.kind.replace("-", " ")


def _robot_frame(name: str) -> bool:
    n = name.lower()
    return any(n == r or n.startswith(r) for r in ROBOT_FRAME_NAMES)


def sensor_bounds(spec: MocapSpec | None) -> SensorBounds:
    """The sensor of a motion-capture section and its noise bounds (module docstring).

    Parameters
    ----------
    spec : MocapSpec or None
        None: a rig without motion capture (motion-capture bounds, unused).

    Returns
    -------
    SensorBounds
    """
    if spec is None:
        kind, why = "motion-capture", "no motion capture given"
    elif spec.sensor is not None:
        kind, why = spec.sensor, f"sensor: {spec.sensor} in rig.yaml"
    elif spec.by_name:
        how = "in their order (match: order)" if spec.match == "order" else "by name"
        kind, why = "robot", (f"inferred from the poses matched to the images {how}; say "
                              "sensor: motion-capture under mocap if they are not a robot's")
    elif spec.frames is not None and any(_robot_frame(f) for f in spec.frames):
        kind, why = "robot", (f"inferred from the frame names T_{spec.frames[0]}_"
                              f"{spec.frames[1]}; say sensor: motion-capture under mocap if "
                              "they are not a robot's")
    else:
        kind, why = "motion-capture", (f"inferred from the time-stamped {spec.format} "
                                       "trajectory; say sensor: robot under mocap if a robot "
                                       "gives the poses")
    rot, trans = SENSOR_BOUNDS[kind]
    own = None if spec is None else spec.noise_bounds
    if own is not None:
        rot = own[0] if own[0] is not None else rot
        trans = own[1] if own[1] is not None else trans
        why = "noise_bounds in rig.yaml"
    return SensorBounds(kind, float(rot), float(trans), why)


def hypothesis_noise(bounds: SensorBounds, rot_rad: float | None = None,
                     trans_m: float | None = None) -> tuple[float, float]:
    """The motion-capture noise the plausibility hypotheses are tested against: the stated
    one (``rot_rad``, ``trans_m``), else :data:`TYPICAL_NOISE` capped at the sensor's bounds
    (radians, metres)."""
    return (min(TYPICAL_NOISE[0], bounds.rot_rad) if rot_rad is None else rot_rad,
            min(TYPICAL_NOISE[1], bounds.trans_m) if trans_m is None else trans_m)
