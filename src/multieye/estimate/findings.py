"""What the plausibility checks report (:mod:`multieye.estimate.plausibility`): what rig.yaml
declares, one finding (a cause and its message), the whole report, and the messages of the
whole-rig causes (scale or unit, quaternion order, setup or inverted poses), in the words a
user would search for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from multieye.core.limits import MAX_SPACING_M

__all__ = ["Declared", "Finding", "Plausibility"]

#: Plausible median distance of the target from a camera, and the largest plausible median
#: distance of the motion-capture positions from their median, metres: which of the two is
#: in the wrong unit.
_TARGET_DISTANCE_M = (0.02, 20.0)
_MOCAP_SPREAD_M = 20.0
#: Lengths in metres of the units rig.yaml knows.
_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
#: setup -> (the other setup, what it means, the pose name and its inverse).
_SETUPS = {"eye-to-base": ("eye-on-hand", "cameras on the moved rig, target static",
                           "T_world_marker", "T_marker_world"),
           "eye-on-hand": ("eye-to-base", "static cameras, target moved",
                           "T_world_body", "T_body_world")}


@dataclass(frozen=True)
class Declared:
    """What rig.yaml says, for the messages and the hypotheses.

    Attributes
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
        rig.yaml's ``setup``.
    spacing_m : float or None
        The target's ``spacing``.
    mocap_unit : str
        The motion capture's ``unit`` (``m`` when not stated).
    mocap_pose : str or None
        The motion capture's ``pose`` (``T_world_marker``, ``T_marker_world``, ...).
    mocap_frames : (str, str) or None
        The user's names of the fixed and the tracked frame (rig.yaml's ``pose:``), when
        they are not ``world`` and the role name.
    mocap_format : str
        ``tum``, ``csv``, ``optitrack``, ``vicon`` or ``rosbag``.
    target_kind : str or None
        The target's ``type`` (the messages name its size key: ``marker_size`` of a marker).
    mocap : MocapSpec or None
        rig.yaml's motion-capture section (its sensor and noise bounds,
        :func:`multieye.estimate.sensor.sensor_bounds`).
    """

    setup: str = "eye-to-base"
    spacing_m: float | None = None
    mocap_unit: str = "m"
    mocap_pose: str | None = None
    mocap_format: str = "tum"
    mocap_frames: tuple[str, str] | None = None
    target_kind: str | None = None
    mocap: object | None = None

    @property
    def size_key(self) -> str:
        """The rig.yaml key that gives the target's size."""
        return {"aruco": "marker_size", "aruco-grid": "marker_size and marker_separation",
                "aprilgrid": "spacing (the tag size)",
                "charuco": "spacing and marker_size"}.get(self.target_kind, "spacing")

    @property
    def size_name(self) -> str:
        """What the target's size is called, for messages."""
        return {"aruco": "marker size", "aruco-grid": "marker size",
                "aprilgrid": "tag size"}.get(self.target_kind, "target spacing")


@dataclass(frozen=True)
class Finding:
    """One hypothesis that explains the fit far better than the data as given.

    Attributes
    ----------
    cause : str
        One of :data:`CAUSES`.
    message : str
        What is probably wrong and what to do, in the words a user would search for; starts
        with the cause (``scale:``, ``unit:``, ``quaternion order:``, ``setup or inverted
        poses:``, ``inverted poses:``, ``time offset:``, ``intrinsics:``).
    camera : str or None
        The camera it concerns; None for the whole rig.
    cost, corrected_cost : float
        The fit's cost as given and with the correction (about 1: the noise explains it).
    evidence : dict of str to float
        The numbers behind it (the fitted factor, offset, ...).
    """

    cause: str
    message: str
    camera: str | None
    cost: float
    corrected_cost: float
    evidence: dict = field(default_factory=dict)

    @property
    def gain(self) -> float:
        """How many times the correction lowers the cost (costs below 1 count as 1)."""
        return _gain(self.cost, self.corrected_cost)


@dataclass(frozen=True)
class Plausibility:
    """Result of :func:`check_plausibility`.

    Attributes
    ----------
    findings : tuple of Finding
        The explanation (best first); empty when nothing explains the fit better.
    cost : float
        Cost of the data as given, all cameras solved together.
    camera_cost : dict of str to float
        Per camera, each solved alone.
    tested : tuple of str
        The hypotheses tested (a cause, ``cause:camera`` for per-camera ones that could be
        tested).
    latent : tuple of Finding
        Whole-rig hypotheses that lower the cost as clearly as a finding must, but from a
        cost the assumed noise already explains (below 1): not reported by themselves, they
        are the likely cause when the noise the refinement estimates is beyond the sensor's
        (:func:`multieye.estimate.plausibility.check_noise`); best first.
    """

    findings: tuple[Finding, ...]
    cost: float
    camera_cost: dict
    tested: tuple[str, ...]
    latent: tuple[Finding, ...] = ()

    @property
    def doubts(self) -> bool:
        return bool(self.findings)

    @property
    def messages(self) -> tuple[str, ...]:
        return tuple(f.message for f in self.findings)


def _gain(before: float, after: float) -> float:
    return max(before, 1.0) / max(after, 1.0)


def _times(v: float) -> str:
    """``1000``, ``0.01``, ``1.25``: three significant digits, no exponent."""
    return np.format_float_positional(v, precision=3, unique=False, fractional=False, trim="-")


def _costs(before: float, after: float) -> str:
    return (f"residuals {_times(before)} times what the noise explains, {_times(after)} times "
            "with that correction")


# --------------------------------------------------------------------------- messages


def _scale_finding(s: float, rel_std: float, before: float, after: float, declared: Declared,
                   d_pnp: float, r_mocap: float, images: bool) -> Finding:
    """``s``: the factor the target poses need (``1/s`` the one the motion capture needs);
    ``d_pnp``: median target distance, ``r_mocap``: spread of the motion capture, as given;
    ``images``: whether PnP made the target poses (then focal lengths that are all off by
    ``1/s`` would do the same, for factors a focal length can be off by)."""

    k = 1.0 / s
    power = round(math.log10(s))
    unit_like = power != 0 and abs(math.log10(s) - power) < math.log10(1.1)
    # Which side is off: the one whose numbers are absurd as given and right once scaled.
    pnp_fine = _TARGET_DISTANCE_M[0] <= d_pnp <= _TARGET_DISTANCE_M[1]
    mocap_fine = r_mocap <= _MOCAP_SPREAD_M
    spacing = declared.spacing_m
    spacing_ok = (_TARGET_DISTANCE_M[0] <= d_pnp * s <= _TARGET_DISTANCE_M[1]
                  and (spacing is None or 1e-3 <= spacing * s <= MAX_SPACING_M))
    mocap_ok = r_mocap * k <= _MOCAP_SPREAD_M
    if pnp_fine != mocap_fine:
        spacing_ok, mocap_ok = spacing_ok and not pnp_fine, mocap_ok and not mocap_fine
    evidence = {"scale": s, "scale_rel_std": rel_std, "target_distance_m": d_pnp,
                "mocap_spread_m": r_mocap}
    key = declared.size_key.split(" ")[0]
    fits = (f" ({declared.size_key})" if spacing is None
            else f" (rig.yaml says {key}: {spacing:g}; {_times(spacing * s)} fits)")
    size = declared.size_name
    unit = declared.mocap_unit
    if unit_like and mocap_ok and not spacing_ok:
        actual = next((u for u, v in _UNITS.items()
                       if abs(math.log10(_UNITS.get(unit, 1.0) * k / v)) < 0.04), None)
        advice = (f"it is probably in {actual}: set unit: {actual} under mocap in rig.yaml"
                  if actual else f"its unit is probably {_times(k)} times the declared one")
        return Finding("unit", f"unit: the motion capture looks like it is not in {unit} as "
                       f"declared: the target poses fit it only when scaled by x{_times(s)} "
                       f"({_costs(before, after)}); {advice}", None, before, after, evidence)
    if unit_like and spacing_ok and not mocap_ok:
        return Finding("unit", f"unit: the {size} looks like it is in the wrong unit: "
                       f"the target poses fit the motion capture only when scaled by x{_times(s)}"
                       f"{fits} ({_costs(before, after)}); give the {size} "
                       f"({declared.size_key}) in metres", None, before, after, evidence)
    word = "unit" if unit_like else "scale"
    focal = (f"; if both are right, the intrinsics' focal lengths may all be off by about "
             f"x{_times(k)}" if images and not unit_like and 0.87 <= s <= 1.15 else "")
    return Finding(word, f"{word}: the {size} or the motion-capture unit looks off by "
                   f"x{_times(s)}: the target poses fit the motion capture only when scaled by "
                   f"x{_times(s)} ({_costs(before, after)}); check the {size}{fits} and the "
                   f"motion capture's unit ({unit}){focal}",
                   None, before, after, evidence)


def _quaternion_finding(desc: str, before: float, after: float, declared: Declared) -> Finding:
    scalar_first = desc.startswith("w x y z")      # the order the file holds
    quat = "qw, qx, qy, qz" if scalar_first else "qx, qy, qz, qw"
    fmt = declared.mocap_format
    if fmt in ("pose-files", "pose-table") and not str(
            getattr(declared.mocap, "rotation", "quaternion")).startswith("quaternion"):
        fmt = None                                 # poses not read as quaternions
    where = {"tum": "the TUM file probably has its quaternion columns in another order (TUM "
                    f"is t tx ty tz qx qy qz qw): reorder them, or say so under mocap in "
                    f"rig.yaml: values: [t, x, y, z, {quat}]",
             "pose-files": "the pose files probably hold the quaternion in another order: say "
                           "so under mocap in rig.yaml: rotation: quaternion-"
                           f"{'wxyz' if scalar_first else 'xyzw'}",
             "pose-table": "the pose table probably holds the quaternion in another order: say "
                           "so under mocap in rig.yaml: rotation: quaternion-"
                           f"{'wxyz' if scalar_first else 'xyzw'}",
             "csv": "the CSV columns are probably named in the wrong order: check which one "
                    "holds qw",
             "rosbag": "the publisher probably fills the quaternion's x y z w in another "
                       "order"}.get(fmt, "the file probably stores the quaternion in another "
                                         "order")
    return Finding("quaternion-order", f"quaternion order: the motion-capture rotations fit "
                   f"when their quaternions are read as {desc} ({_costs(before, after)}); "
                   f"{where}", None, before, after, {})


def _rotation_finding(other: str, before: float, after: float, given: str) -> Finding:
    """The poses' numbers fit as rotation convention ``other`` instead of ``given``."""
    if given == "rotvec":
        what = "the three numbers are Euler angles, not a rotation vector"
    elif other.endswith("-rad") and given.endswith("-deg"):
        what = "the angles are in radians, not degrees"
    elif other.split("-")[1].isupper():
        what = "the Euler angles turn about the moving axes (intrinsic: upper case), not the fixed ones"
    else:
        what = "the Euler angles turn about the fixed axes (extrinsic: lower case), not the moving ones"
    return Finding("rotation-convention", f"rotation convention: the poses' rotations fit when "
                   f"their numbers are read as {other} where they were read as {given} "
                   f"({_costs(before, after)}): {what}; set rotation: {other} under mocap in "
                   "rig.yaml (the robot's manual names its convention)", None, before, after,
                   {})


def _setup_finding(before: float, after: float, declared: Declared) -> Finding:
    setup = declared.setup
    other, meaning, pose, inverse = _SETUPS[setup]
    given = declared.mocap_pose or pose
    flipped = {pose: inverse, inverse: pose}.get(given, inverse)
    fix = f"pose: {flipped}"
    if declared.mocap_frames is not None:          # the user's own names (rig.yaml's pose)
        fixed, tracked = declared.mocap_frames
        pairs = {pose: (fixed, tracked), inverse: (tracked, fixed)}    # (parent, child)
        parent, child = pairs[flipped]
        given, flipped = "T_{}_{}".format(*pairs[given]), f"T_{parent}_{child}"
        # names holding '_' are spelled out (pose alone would be ambiguous)
        fix = (f"frames: [{parent}, {child}]" if "_" in parent + child
               else f"pose: {flipped}")
        fix += "" if fixed in ("world", parent) else f" and fixed_frame: {fixed}"
    return Finding("setup", f"setup or inverted poses: the motion capture fits as its inverse "
                   f"({_costs(before, after)}): either the data are {other} ({meaning}), not "
                   f"{setup} as rig.yaml says (setup: {other}), or the motion-capture poses "
                   f"are inverted ({flipped}, not {given}: {fix} under mocap)", None,
                   before, after, {})
