"""Plausibility checks after the solve: when the fit is poor, which wrong input explains it.

Some wrong inputs give a result with plausible-looking numbers: a target spacing in the wrong
size or unit, motion capture in millimetres declared metres, quaternions in the other order,
eye-on-hand data declared eye-to-base (or inverted poses), a camera clock off the motion
capture, intrinsics that do not belong to the images.  Each leaves a fingerprint in the loop
``A_i X = Y B_i`` (docs/conventions.md, section 2): the residuals are larger than the noise
explains, and they shrink to the noise once that one input is corrected.
:func:`check_plausibility` tests each such hypothesis by correcting the measurements and
solving the closed form again (:mod:`multieye.estimate.hypotheses`):

``scale`` / ``unit``
    The target poses scaled by one factor ``s``, solved in closed form with ``s`` as a further
    unknown of the translation equations ``R_A t_X + t_A / s = R_Y t_B + t_Y``: the target
    spacing or the motion-capture unit is off by ``s`` (``x1000`` and the like: a unit; which
    side is off follows from the one whose distances are absurd as given).
``quaternion-order``
    The motion-capture rotations re-read with the quaternion's scalar first instead of last
    (and the reverse).  SLERP commutes with the permutation, so interpolated poses are exact.
``setup``
    The motion-capture poses inverted: eye-on-hand data declared eye-to-base (or the
    reverse), or ``T_marker_world`` given as ``T_world_marker``: the algebra is the same, so
    the message names both.
``inverted-poses``
    Precomputed target poses inverted (``T_target_cam`` given as ``T_cam_target``).
``time-offset``
    Per camera with time-stamped images and a continuous motion capture, the clock offset of
    :func:`multieye.estimate.clock.estimate_offset` against the one used.
``intrinsics``
    Per camera with detected points, PnP run again with the focal length scaled (found by a
    search on the loop residuals), or with the camera matrix scaled by a common resize factor
    (intrinsics calibrated on images of another size, the file stating no size).

The ``cost`` of a fit (:mod:`multieye.estimate.hypotheses`) is about 1 when the noise the
measurements carry explains the residuals.  Hypotheses that change how the data are read
(quaternion order, inverted poses) are always tested, since they cost one closed form
each; the per-camera searches (clock, intrinsics) run on cameras whose cost is at least
:data:`POOR_COST`.  A hypothesis is reported when it lowers the cost at least
:data:`DISCRETE_GAIN`-fold (a corrected reading: no parameter is fitted) or
:data:`CONTINUOUS_GAIN`-fold (a fitted factor or offset, which must also be clearly away
from its neutral value), costs below 1 counting as 1: on data that fit as well as their
noise allows nothing is reported.  The motion-capture noise is the one stated in rig.yaml,
else 0.1 degrees and 0.3 mm, never the one the refinement estimates (a wrong input inflates
that estimate until it hides itself).

When several hypotheses explain the fit, the one whose corrected cost is lowest is the
explanation; a whole-rig one gives way to per-camera ones only when those explain most
cameras clearly better.  A camera whose cost reaches :data:`UNEXPLAINED_COST` while no
hypothesis explains it is doubted all the same (cause ``fit``): its residuals are far beyond
its noise for a reason the checks cannot name.

Synopsis
--------
>>> from multieye.estimate.plausibility import CameraEvidence, check_plausibility
>>> report = check_plausibility("eye-to-base", [CameraEvidence("cam0", A, B, T)])  # doctest: +SKIP
>>> [(f.cause, f.message) for f in report.findings]                                 # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.problem import SETUPS
from multieye.estimate import hypotheses as h
from multieye.estimate.hypotheses import CameraEvidence

__all__ = ["CAUSES", "CameraEvidence", "Declared", "Finding", "Plausibility",
           "check_plausibility", "DISCRETE_GAIN", "CONTINUOUS_GAIN", "POOR_COST"]

#: The causes a finding can name.
CAUSES = ("scale", "unit", "quaternion-order", "setup", "inverted-poses", "time-offset",
          "intrinsics", "fit")
#: Fewest-fold drop of the cost for a corrected reading (quaternion order, inverted poses).
DISCRETE_GAIN = 1.5
#: ... for a fitted factor or offset (scale, focal length, image size, clock offset).
CONTINUOUS_GAIN = 1.5
#: Cost of a camera from which the per-camera searches (clock, intrinsics) run.
POOR_COST = 1.5
#: Cost of a camera that is doubted even when no cause explains it.
UNEXPLAINED_COST = 10.0
#: Smallest scale error reported (and at least 5 standard deviations of it).
MIN_SCALE_ERROR = 0.015
#: Smallest focal-length error reported.
MIN_FOCAL_ERROR = 0.01
#: Smallest clock-offset correction reported, seconds (and at least 4 standard deviations).
MIN_CLOCK_CHANGE_S = 0.005
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
    """What rig.yaml says, for the messages.

    Attributes
    ----------
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
    """

    spacing_m: float | None = None
    mocap_unit: str = "m"
    mocap_pose: str | None = None
    mocap_format: str = "tum"
    mocap_frames: tuple[str, str] | None = None


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
    """

    findings: tuple[Finding, ...]
    cost: float
    camera_cost: dict
    tested: tuple[str, ...]

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
    from multieye.core.limits import MAX_SPACING_M

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
    fits = "" if spacing is None else f" (rig.yaml says {spacing:g}; {_times(spacing * s)} fits)"
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
        return Finding("unit", f"unit: the target spacing looks like it is in the wrong unit: "
                       f"the target poses fit the motion capture only when scaled by x{_times(s)}"
                       f"{fits} ({_costs(before, after)}); give the target spacing in metres",
                       None, before, after, evidence)
    word = "unit" if unit_like else "scale"
    focal = (f"; if both are right, the intrinsics' focal lengths may all be off by about "
             f"x{_times(k)}" if images and not unit_like and 0.87 <= s <= 1.15 else "")
    return Finding(word, f"{word}: the target spacing or the motion-capture unit looks off by "
                   f"x{_times(s)}: the target poses fit the motion capture only when scaled by "
                   f"x{_times(s)} ({_costs(before, after)}); check the target spacing{fits} and "
                   f"the motion capture's unit ({unit}){focal}", None, before, after, evidence)


def _quaternion_finding(desc: str, before: float, after: float, declared: Declared) -> Finding:
    where = {"tum": "the TUM file probably has its quaternion columns in another order (TUM "
                    "is t tx ty tz qx qy qz qw): reorder them",
             "csv": "the CSV columns are probably named in the wrong order: check which one "
                    "holds qw",
             "rosbag": "the publisher probably fills the quaternion's x y z w in another "
                       "order"}.get(declared.mocap_format,
                                    "the file probably stores the quaternion in another order")
    return Finding("quaternion-order", f"quaternion order: the motion-capture rotations fit "
                   f"when their quaternions are read as {desc} ({_costs(before, after)}); "
                   f"{where}", None, before, after, {})


def _setup_finding(setup: str, before: float, after: float, declared: Declared) -> Finding:
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


# --------------------------------------------------------------------------- the checks


def check_plausibility(setup: str, cameras: Sequence[CameraEvidence], *,
                       declared: Declared = Declared(),
                       mocap_rot_sigma_rad: float | None = None,
                       mocap_trans_sigma_m: float | None = None,
                       clock: bool = True, max_time_offset_s: float = 0.5) -> Plausibility:
    """Test the hypotheses that explain a poor fit; say which one fits (module docstring).

    Parameters
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    cameras : sequence of CameraEvidence
        Every camera's measurements, outliers included (the fits trim them).
    declared : Declared
        What rig.yaml says, for the messages.
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float, optional
        Motion-capture noise per axis, as stated; default 0.1 degrees and 0.3 mm.
    clock : bool
        Test clock offsets (False when they were estimated already).
    max_time_offset_s : float
        Clock offsets searched either side of the one used, seconds.

    Returns
    -------
    Plausibility
    """
    if not isinstance(setup, str) or setup not in SETUPS:
        raise InputError(f"setup must be one of {SETUPS}, got {setup!r}")
    cams = list(cameras)
    if not cams:
        raise InputError("check_plausibility needs at least one camera")
    sigma = (h.MOCAP_NOISE[0] if mocap_rot_sigma_rad is None else mocap_rot_sigma_rad,
             h.MOCAP_NOISE[1] if mocap_trans_sigma_m is None else mocap_trans_sigma_m)
    weights = [h.noise(c, sigma) for c in cams]
    A, B = [c.A for c in cams], [c.B for c in cams]
    base = h.fit(A, B, weights)
    singles = [h.fit([c.A], [c.B], [w]) for c, w in zip(cams, weights)]
    tested: list[str] = []
    rig: list[tuple[Finding, tuple]] = []     # whole-rig findings, with their per-camera costs

    def consider(fit: h.Fit, make, gain: float) -> None:
        if _gain(base.cost, fit.cost) >= gain:
            rig.append((make(base.cost, fit.cost), fit.camera_cost))

    tested.append("scale")
    k, k_std = h.scale_factor(A, B, base)
    if np.isfinite(k) and k > 0:
        s, rel = 1.0 / k, k_std / k
        if abs(math.log(s)) >= math.log1p(MIN_SCALE_ERROR) and abs(math.log(s)) > 5 * rel:
            d_pnp = float(np.median(np.concatenate(
                [np.linalg.norm(g.inv(b)[:, :3, 3], axis=1) for b in B])))
            p = np.concatenate([c.T_world_mocap for c in cams])[:, :3, 3]
            r_mocap = float(np.median(np.linalg.norm(p - np.median(p, axis=0), axis=1)))
            consider(h.fit([h.scaled_A(a, k) for a in A], B, weights),
                     lambda b, a: _scale_finding(s, rel, b, a, declared, d_pnp, r_mocap,
                                                 any(c.has_points for c in cams)),
                     CONTINUOUS_GAIN)
    tested.append("quaternion-order")
    for order, desc in h.QUATERNION_ORDERS:
        fit = h.fit([h.mocap_A(setup, h.permuted(c.T_world_mocap, order)) for c in cams], B,
                    weights)
        consider(fit, lambda b, a, desc=desc: _quaternion_finding(desc, b, a, declared),
                 DISCRETE_GAIN)
    tested.append("setup")
    consider(h.fit([g.inv(a) for a in A], B, weights),
             lambda b, a: _setup_finding(setup, b, a, declared), DISCRETE_GAIN)
    posed = [j for j, c in enumerate(cams) if c.image_points is None]
    if posed:
        tested.append("inverted-poses")
        for group in [posed] + ([[j] for j in posed] if len(posed) > 1 else []):
            fit = h.fit(A, [g.inv(b) if j in group else b for j, b in enumerate(B)], weights)
            names = ", ".join(cams[j].name for j in group)
            consider(fit, lambda b, a, names=names: Finding(
                "inverted-poses", f"inverted poses: the precomputed target poses of {names} "
                f"fit as their inverses ({_costs(b, a)}): the poses file probably holds "
                "T_target_cam, not T_cam_target; invert them", None, b, a, {}), DISCRETE_GAIN)

    per_camera = {}
    for j, (cam, w, single) in enumerate(zip(cams, weights, singles)):
        if single.cost >= POOR_COST:
            per_camera[j] = _camera_findings(setup, cam, w, clock, max_time_offset_s, tested)
    findings = _select(rig, per_camera, len(cams))
    if not findings:
        findings = tuple(_unexplained(c.name, f.cost, tested) for c, f in zip(cams, singles)
                         if f.cost >= UNEXPLAINED_COST)
    return Plausibility(findings=findings, cost=base.cost,
                        camera_cost={c.name: s.cost for c, s in zip(cams, singles)},
                        tested=tuple(tested))


def _camera_findings(setup: str, cam: CameraEvidence, w, clock: bool, max_offset_s: float,
                     tested: list[str]) -> list[Finding]:
    """The per-camera hypotheses: clock offset, focal length, image size."""
    found = []
    if clock:
        res = h.clock_search(setup, cam, w, max_offset_s)
        if res is not None:
            tested.append(f"time-offset:{cam.name}")
            off, std, before, after = res
            change = abs(off - cam.time_offset)
            if (change >= MIN_CLOCK_CHANGE_S and not change < 4 * std
                    and _gain(before, after) >= CONTINUOUS_GAIN):
                found.append(Finding(
                    "time-offset", f"time offset: camera {cam.name}'s images fit the motion "
                    f"capture with a clock offset of {off:+.3f} s instead of "
                    f"{cam.time_offset:+.3f} s ({_costs(before, after)}); run with "
                    f"--time-offset auto (it finds {off:+.3f} s here) or set time_offset for "
                    "the camera in rig.yaml", cam.name, before, after,
                    {"time_offset_s": off, "std_s": std}))
    if not cam.has_points or cam.intrinsics_estimated:
        return found
    res = h.focal_search(cam, w)
    if res is not None:
        tested.append(f"intrinsics:{cam.name}")
        factor, before, after = res
        if (abs(math.log(factor)) >= math.log1p(MIN_FOCAL_ERROR)
                and _gain(before, after) >= CONTINUOUS_GAIN):
            found.append(Finding(
                "intrinsics", f"intrinsics: camera {cam.name}'s target poses fit the motion "
                f"capture when its focal length is scaled by x{_times(factor)} "
                f"({_costs(before, after)}): its intrinsics probably do not belong to these "
                "images (another camera, zoom or focus setting, or a poor intrinsic "
                "calibration); calibrate the intrinsics again", cam.name, before, after,
                {"focal_scale": factor}))
    if cam.intrinsics.width is None or cam.intrinsics.height is None:
        res = h.resize_search(cam, w)
        if res is not None and _gain(res[1], res[2]) >= CONTINUOUS_GAIN:
            factor, before, after = res
            found.append(Finding(
                "intrinsics", f"intrinsics image size: camera {cam.name}'s images fit when "
                f"its intrinsics are scaled by x{_times(factor)} ({_costs(before, after)}): the "
                "images were probably resized after the intrinsics were calibrated (the "
                "intrinsics file states no image size); use intrinsics for this image size "
                "and state image_width and image_height in the file", cam.name, before,
                after, {"image_scale": factor}))
    return found


def _unexplained(name: str, cost: float, tested: list[str]) -> Finding:
    causes = sorted({t.split(":")[0] for t in tested})
    return Finding("fit", f"poor fit: camera {name}'s residuals are {_times(cost)} times what "
                   f"the noise explains and none of the causes tested ({', '.join(causes)}) "
                   "explains them; check its target poses (images, detections), the time offset "
                   "(--time-offset auto), and state the motion-capture noise "
                   "(rotation_noise_deg, translation_noise_m) if it is this large", name, cost,
                   cost, {})


def _select(rig: list[tuple[Finding, tuple]], per_camera: dict[int, list[Finding]],
            n_cameras: int) -> tuple[Finding, ...]:
    """The explanation: the best whole-rig finding (and any other cause fitting as well),
    unless per-camera findings explain most cameras clearly better; then the best finding
    of each camera."""
    best = {j: min(fs, key=lambda f: f.corrected_cost) for j, fs in per_camera.items() if fs}
    if rig:
        finding, camera_cost = min(rig, key=lambda fc: fc[0].corrected_cost)
        better = [j for j, f in best.items()
                  if 1.25 * max(f.corrected_cost, 1.0) < max(camera_cost[j], 1.0)]
        if 2 * len(better) <= n_cameras:
            alike = [f for f, _ in rig if f is not finding and f.cause != finding.cause
                     and f.corrected_cost <= 1.25 * max(finding.corrected_cost, 1.0)]
            return (finding, *alike)
    return tuple(best[j] for j in sorted(best))
