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
``rotation-convention``
    Poses read from Euler angles or rotation vectors (``mocap.rotation``) re-read in the
    conventions robot files are confused with (:func:`multieye.estimate.hypotheses.
    other_rotations`): Euler angles about the moving instead of the fixed axes (or the
    reverse), radians read as degrees, Euler angles read as a rotation vector.
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
    (intrinsics calibrated on images of another size, the file stating no size); and the lens
    freed (:func:`multieye.estimate.lens_freed.lens_search`: every intrinsic parameter of the
    given model fitted to the camera's own detections): named when the given lens leaves
    reprojection residuals at least :data:`LENS_PIXEL_GAIN` times those of the freed lens (and
    at least :data:`MIN_LENS_EXCESS_PX` beyond them), or when the freed lens's target poses fit
    the loop clearly better (a distortion left out of the intrinsics file, a lens of another
    camera).  Run on every camera with given intrinsics and at least 5 views of 8 or more
    points, whatever its loop cost: a wrong lens inflates the pixel noise the loop is weighed
    with, and so hides itself there.
``observability``
    After the refinement (:func:`check_determined`): a camera whose refined pose has a
    standard deviation beyond :data:`UNDETERMINED_ROT_DEG` or half its distance to the target
    (a few images, or a motion too small to determine it), whatever its residuals.
``noise``
    After the refinement (:func:`check_noise`): a motion-capture noise estimated from the data
    beyond what the sensor has at most (:mod:`multieye.estimate.sensor`: a robot 0.1 degrees
    and 1 mm, motion capture 0.5 degrees and 3 mm per pose, or rig.yaml's ``noise_bounds``):
    the estimate has absorbed a wrong input, which the message names when a hypothesis
    explains it.

The ``cost`` of a fit (:mod:`multieye.estimate.hypotheses`) is about 1 when the noise the
measurements carry explains the residuals.  Hypotheses that change how the data are read
(quaternion order, when the rotations were read as quaternions; inverted poses) are always
tested, since they cost one closed form each; the per-camera searches (clock, intrinsics)
run on cameras whose cost is at least :data:`POOR_COST`.  A hypothesis is reported when it lowers the cost at least
:data:`DISCRETE_GAIN`-fold (a corrected reading: no parameter is fitted) or
:data:`CONTINUOUS_GAIN`-fold (a fitted factor or offset, which must also be clearly away
from its neutral value), costs below 1 counting as 1: on data that fit as well as their
noise allows nothing is reported.  The motion-capture noise is the one stated in rig.yaml,
else the noise the sensor should have (:func:`multieye.estimate.sensor.hypothesis_noise`:
0.1 degrees and 0.3 mm, at most the sensor's bounds), never the one the refinement estimates
(a wrong input inflates that estimate until it hides itself).  The checks see the
measurements the solve used: after the consensus, only those it kept (an outlier it rejected
is no evidence against the result).

When several hypotheses explain the fit, the one whose corrected cost is lowest is the
explanation; a whole-rig one gives way to per-camera ones only when those explain most
cameras clearly better.  A camera whose cost reaches :data:`UNEXPLAINED_COST` while no
hypothesis explains it is doubted all the same (cause ``fit``): its residuals are far beyond
its noise for a reason the checks cannot name.

Synopsis
--------
>>> from multieye.estimate.plausibility import CameraEvidence, check_plausibility
>>> report = check_plausibility([CameraEvidence("cam0", A, B, T)])  # doctest: +SKIP
>>> [(f.cause, f.message) for f in report.findings]                                 # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import replace

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.problem import SETUPS
from multieye.estimate import hypotheses as h
from multieye.estimate import lens_freed as lf
from multieye.estimate.lens_doubt import (
    LENS_PIXEL_GAIN,
    MIN_LENS_EXCESS_PX,
    given_lens_findings,
    bare_doubt,
    lens_message,
    radial_doubt,
)
from multieye.estimate.findings import (
    Declared,
    Finding,
    Plausibility,
    _costs,
    _gain,
    _quaternion_finding,
    _rotation_finding,
    _scale_finding,
    _setup_finding,
    _times,
)
from multieye.estimate.hypotheses import CameraEvidence
from multieye.estimate.sensor import SensorBounds, hypothesis_noise, sensor_bounds

if TYPE_CHECKING:  # the refinement's result type, for the annotation only
    from multieye.estimate.refine_images import RefinementResult

__all__ = ["CAUSES", "CameraEvidence", "Declared", "Finding", "Plausibility",
           "check_plausibility", "check_noise", "given_lens_findings", "target_size_findings",
           "MAX_TARGET_FEATURE_M", "DISCRETE_GAIN", "CONTINUOUS_GAIN", "check_determined",
           "UNDETERMINED_ROT_DEG", "UNDETERMINED_DISTANCE_SHARE",
           "POOR_COST", "LENS_PIXEL_GAIN", "MIN_LENS_EXCESS_PX"]

#: The causes a finding can name.
CAUSES = ("scale", "unit", "quaternion-order", "rotation-convention", "setup", "inverted-poses",
          "time-offset", "intrinsics", "noise", "fit", "observability")
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
#: Fewest-fold drop of the median reprojection RMS with which a freed lens that fits the loop
#: clearly better is believed.
_LENS_LOOP_PIXEL_GAIN = 1.5
#: A camera's pose whose rotation standard deviation (root of the trace, degrees) exceeds
#: this is not determined by the measurements (cause ``observability``): the real sets'
#: one-axis recording of 30 images (young_mocap_cam) has 1.6, five of its images 42.
UNDETERMINED_ROT_DEG = 10.0
#: ... or whose translation standard deviation exceeds this share of the camera's median
#: distance to the target.
UNDETERMINED_DISTANCE_SHARE = 0.5
# --------------------------------------------------------------------------- the checks


def check_plausibility(cameras: Sequence[CameraEvidence], *,
                       declared: Declared = Declared(),
                       mocap_rot_sigma_rad: float | None = None,
                       mocap_trans_sigma_m: float | None = None,
                       sensor: SensorBounds | None = None,
                       clock: bool = True, max_time_offset_s: float = 0.5) -> Plausibility:
    """Test the hypotheses that explain a poor fit; say which one fits (module docstring).

    Parameters
    ----------
    cameras : sequence of CameraEvidence
        Every camera's measurements the solve used (after the consensus: those it kept; the
        fits trim outliers once more).
    declared : Declared
        What rig.yaml says: its setup (``declared.setup``, the one the hypotheses start
        from) and, for the messages, the rest.
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float, optional
        Motion-capture noise per axis, as stated; default the noise the sensor should have
        (:func:`multieye.estimate.sensor.hypothesis_noise`: 0.1 degrees and 0.3 mm, at most
        ``sensor``'s bounds), never an estimate.
    sensor : SensorBounds, optional
        The sensor's noise bounds; default :func:`multieye.estimate.sensor.sensor_bounds` of
        ``declared.mocap``.
    clock : bool
        Test clock offsets (False when they were estimated already).
    max_time_offset_s : float
        Clock offsets searched either side of the one used, seconds.

    Returns
    -------
    Plausibility
    """
    setup = declared.setup
    if not isinstance(setup, str) or setup not in SETUPS:
        raise InputError(f"setup must be one of {SETUPS}, got {setup!r}")
    cams = list(cameras)
    if not cams:
        raise InputError("check_plausibility needs at least one camera")
    if sensor is None and declared.mocap is not None:
        sensor = sensor_bounds(declared.mocap)
    if sensor is not None:
        sigma = hypothesis_noise(sensor, mocap_rot_sigma_rad, mocap_trans_sigma_m)
    else:
        sigma = (h.MOCAP_NOISE[0] if mocap_rot_sigma_rad is None else mocap_rot_sigma_rad,
                 h.MOCAP_NOISE[1] if mocap_trans_sigma_m is None else mocap_trans_sigma_m)
    weights = [h.noise(c, sigma) for c in cams]
    A, B = [c.A for c in cams], [c.B for c in cams]
    base = h.fit(A, B, weights)
    singles = [h.fit([c.A], [c.B], [w]) for c, w in zip(cams, weights)]
    tested: list[str] = []
    latent: list[Finding] = []
    rig = _rig_findings(cams, weights, base, declared, tested, latent)
    per_camera = {}
    for j, (cam, w, single) in enumerate(zip(cams, weights, singles)):
        if single.cost >= POOR_COST:
            per_camera[j] = _camera_findings(cam, w, declared, clock, max_time_offset_s, tested)
    findings = _select(rig, per_camera, len(cams))
    for cam in cams:       # the lens, on every camera: its own residuals hide it elsewhere
        if cam.has_points and not cam.intrinsics_estimated and not any(
                f.camera == cam.name and f.cause == "intrinsics" for f in findings):
            lens = _lens_finding(cam, sigma, tested)
            findings += () if lens is None else (lens,)
    if not findings:
        findings = tuple(_unexplained(c.name, f.cost, tested, declared.mocap)
                         for c, f in zip(cams, singles)
                         if f.cost >= UNEXPLAINED_COST)
    findings = tuple(_partial(f, declared.mocap) for f in findings)
    return Plausibility(findings=findings, cost=base.cost,
                        camera_cost={c.name: s.cost for c, s in zip(cams, singles)},
                        tested=tuple(tested),
                        latent=tuple(sorted(latent, key=lambda f: f.corrected_cost)))


def _rig_findings(cams: list[CameraEvidence], weights, base: h.Fit, declared: Declared,
                  tested: list[str], latent: list[Finding]) -> list[tuple[Finding, tuple]]:
    """The whole-rig hypotheses (scale, quaternion order, setup, inverted poses) that fit
    better than ``base``, with their per-camera costs; each hypothesis tested is added to
    ``tested``, each that lowers a cost below 1 as clearly to ``latent``."""
    A, B, setup = [c.A for c in cams], [c.B for c in cams], declared.setup
    rig: list[tuple[Finding, tuple]] = []     # whole-rig findings, with their per-camera costs

    def consider(fit: h.Fit, make, gain: float) -> None:
        if _gain(base.cost, fit.cost) >= gain:
            rig.append((make(base.cost, fit.cost), fit.camera_cost))
        elif base.cost >= gain * max(fit.cost, 1e-12):   # hidden by the noise assumed
            latent.append(make(base.cost, fit.cost))

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
    if _read_as_quaternions(declared):
        tested.append("quaternion-order")
        for order, desc in h.QUATERNION_ORDERS:
            fit = h.fit([h.mocap_A(setup, h.permuted(c.T_world_mocap, order)) for c in cams],
                        B, weights)
            consider(fit, lambda b, a, desc=desc: _quaternion_finding(desc, b, a, declared),
                     DISCRETE_GAIN)
    rotation = str(getattr(declared.mocap, "rotation", None) or "")
    if rotation == "quaternion-xyzw" and declared.mocap_format in ("pose-files", "pose-table"):
        rotation = "rotvec"      # named rx ry rz are read as a rotation vector by default
    if h.other_rotations(rotation):
        tested.append("rotation-convention")
        inverse = str(declared.mocap_pose or "").endswith("_world")   # the file holds inv(T)
        for other in h.other_rotations(rotation):
            fit = h.fit([h.mocap_A(setup, h.reread_rotations(c.T_world_mocap, rotation, other,
                                                              inverse)) for c in cams], B, weights)
            consider(fit, lambda b, a, other=other: _rotation_finding(other, b, a, rotation),
                     DISCRETE_GAIN)
    tested.append("setup")
    consider(h.fit([g.inv(a) for a in A], B, weights),
             lambda b, a: _setup_finding(b, a, declared), DISCRETE_GAIN)
    posed = [j for j, c in enumerate(cams) if c.image_points is None]
    if posed:
        tested.append("inverted-poses")
        for group in [posed] + ([[j] for j in posed] if len(posed) > 1 else []):
            fit = h.fit(A, [g.inv(b) if j in group else b for j, b in enumerate(B)], weights)
            names = ", ".join(cams[j].name for j in group)
            consider(fit, lambda b, a, names=names: Finding(
                "inverted-poses", f"inverted poses: the precomputed target poses of {names} "
                f"fit as their inverses ({_costs(b, a)}): the poses file probably holds "
                "the other direction (T_target_cam for T_cam_target); say which in rig.yaml: "
                "poses: {file: ..., pose: T_target_cam} (or T_cam_target)", None, b, a, {}),
                DISCRETE_GAIN)
    return rig


def _read_as_quaternions(declared: Declared) -> bool:
    """Whether the motion-capture rotations were read as quaternions, so that a quaternion
    order can explain a poor fit: not when rig.yaml reads them as matrices, rotation vectors
    or Euler angles (``mocap.rotation``), nor from a Vicon export (rotation vectors), where
    a permuted quaternion that happens to fit better would name a cause the file cannot
    have."""
    rotation = str(getattr(declared.mocap, "rotation", None) or "quaternion-xyzw")
    return rotation.startswith("quaternion") and declared.mocap_format != "vicon"


def _camera_findings(cam: CameraEvidence, w, declared: Declared, clock: bool,
                     max_offset_s: float, tested: list[str]) -> list[Finding]:
    """The per-camera hypotheses: clock offset, focal length, image size."""
    found = []
    if clock:
        res = h.clock_search(declared.setup, cam, w, max_offset_s)
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


def _lens_finding(cam: CameraEvidence, sigma: tuple[float, float], tested: list[str]
                  ) -> Finding | None:
    """The given lens against the lens freed on the camera's own detections.

    Not freed whole (it costs 0.2-1 s a camera) when neither finding could follow: the given
    lens leaves less than :data:`MIN_LENS_EXCESS_PX` of reprojection RMS (so no systematic
    part that large) and its poses fit the loop even weighted as if the pixel noise were at
    its floor (:func:`multieye.estimate.lens_freed.lens_bound`).  Such a lens, and one given
    without distortion, has its k1 and k2 refitted instead (the camera matrix kept), and is
    doubted by :func:`multieye.estimate.lens_doubt.radial_doubt` on its mean loop residuals
    (a robot's 0.1 deg / 1 mm hid k1 -0.05 left out in the loop cost: exit status 0, the
    camera 2.7 mm off at 1.3 mm sigma)."""
    bound = lf.lens_bound(cam, sigma)
    quiet = bound is not None and bound[0] < MIN_LENS_EXCESS_PX and bound[1] < POOR_COST
    test = lf.lens_search(cam, sigma, radial_only=quiet)
    if test is None:
        return None
    tested.append(f"intrinsics:{cam.name}")
    ratio = test.rms_given_px / max(test.rms_freed_px, 1e-9)
    excess = math.sqrt(max(test.rms_given_px ** 2 - test.rms_freed_px ** 2, 0.0))
    pixels = ratio >= LENS_PIXEL_GAIN and excess >= MIN_LENS_EXCESS_PX
    loop = (ratio >= _LENS_LOOP_PIXEL_GAIN and test.cost_given >= POOR_COST
            and _gain(test.cost_given, test.cost_freed) >= CONTINUOUS_GAIN)
    bare = lf.distortion_missing(cam.intrinsics)
    radial = (quiet or bare) and radial_doubt(test) or bare and bare_doubt(test)
    if not (pixels or loop or radial):
        return None
    return lens_message(cam, test, loop=True)


#: A target's square (or marker) side from which a rig without motion capture doubts its
#: scale, metres: printed and painted boards have squares of a few millimetres to about a
#: quarter of a metre; a spacing of 1-10 is centimetres written as metres.
MAX_TARGET_FEATURE_M = 1.0


def target_size_findings(spacings: dict[str, float]) -> tuple[Finding, ...]:
    """Rigs without motion capture take their scale from the target alone: a target spacing
    in the wrong unit scales every translation and gives no misfit to see (``spacing: 3``
    meant as centimetres: a 100 times longer baseline, exit status 0 before).  Doubted,
    cause ``scale``, for a square or marker side of :data:`MAX_TARGET_FEATURE_M` or more.

    Parameters
    ----------
    spacings : dict of str to float
        Each target's square side (``spacing``; a marker's side for ArUco), metres, by name.

    Returns
    -------
    tuple of Finding
    """
    return tuple(
        Finding("scale", f"scale: target {name!r} has squares or markers of {s:g} m, far "
                "larger than any calibration board; without motion capture the target alone "
                "gives the scale, so every translation is in proportion to it: if they "
                f"measure {s:g} cm, write {s / 100:g} in rig.yaml (metres)", None,
                float("nan"), float("nan"), {"spacing_m": float(s)})
        for name, s in spacings.items() if s >= MAX_TARGET_FEATURE_M)


def check_noise(report: Plausibility, refined: RefinementResult | None, mocap=None, *,
                sensor: SensorBounds | None = None) -> Plausibility:
    """A motion-capture noise estimated from the data, checked against what the sensor has.

    Parameters
    ----------
    report : Plausibility
        The checks after the solve (:func:`check_plausibility`).
    refined : RefinementResult or None
        The image-level refinement (:func:`multieye.estimate.refine_images.refine_images`):
        when its ``mocap_sigma_estimated``, its ``mocap_rot_sigma_rad`` and
        ``mocap_trans_sigma_m`` (per pose and axis) are checked; None (no image-level
        refinement, so no estimated noise): nothing is.
    mocap : MocapSpec, optional
        rig.yaml's motion-capture section, for :func:`multieye.estimate.sensor.sensor_bounds`.
    sensor : SensorBounds, optional
        The bounds themselves (instead of ``mocap``).

    Returns
    -------
    Plausibility
        ``report`` with a finding of cause ``noise`` added when the estimate is beyond either
        bound (its message names the causes found, else those tested).
    """
    if refined is None or not refined.mocap_sigma_estimated:
        return report
    rot_rad, trans_m = float(refined.mocap_rot_sigma_rad), float(refined.mocap_trans_sigma_m)
    sensor = sensor_bounds(mocap) if sensor is None else sensor
    over = [what for what, v, bound in (("rotation", rot_rad, sensor.rot_rad),
                                        ("translation", trans_m, sensor.trans_m)) if v > bound]
    if not over:
        return report
    found = [f for f in report.findings if f.cause not in ("noise", "fit")]
    if not found and report.latent:      # the estimate confirms what the assumed noise hid
        report = replace(report, findings=report.findings + report.latent[:1])
        found = list(report.latent[:1])
    if found:
        cause = ("; " + ", ".join(sorted({f.cause for f in found})) + " (above) probably "
                 "explains it")
    else:
        causes = sorted({t.split(":")[0] for t in report.tested})
        cause = (f"; none of the causes tested ({', '.join(causes)}) explains it: check the "
                 "intrinsics (the lens distortion too), the target size, the time offset "
                 f"(--time-offset auto){rotation_hint(mocap)} and the motion-capture poses")
    finding = Finding(
        "noise", f"noise: the {sensor.name} noise estimated from the data, "
        f"{math.degrees(rot_rad):.3g} deg and {trans_m * 1e3:.3g} mm per pose, is beyond what "
        f"a {sensor.name} has (at most {math.degrees(sensor.rot_rad):.3g} deg and "
        f"{sensor.trans_m * 1e3:.3g} mm; {sensor.kind}: {sensor.why}), so the residuals come "
        f"from something the model leaves out, not from the {sensor.name}'s noise{cause}; if "
        "this sensor really is that noisy, state it under mocap in rig.yaml (noise_bounds: "
        "{rotation_deg, translation_m}, or rotation_noise_deg and translation_noise_m)",
        None, report.cost, report.cost,
        {"rot_deg": math.degrees(rot_rad), "trans_m": trans_m,
         "bound_rot_deg": math.degrees(sensor.rot_rad), "bound_trans_m": sensor.trans_m})
    return Plausibility(findings=report.findings + (finding,), cost=report.cost,
                        camera_cost=report.camera_cost, tested=report.tested + ("noise",))


def check_determined(report: Plausibility, std: Sequence[tuple[str, float, float, float, int]],
                     pose: str = "T_ref_cam") -> Plausibility:
    """``report`` with a doubt (cause ``observability``) for every camera whose refined pose
    the measurements do not determine: a result whose spread is that large is no answer,
    whatever the loop residuals say (a few images of one motion fit any pose).

    Parameters
    ----------
    report : Plausibility
    std : sequence of (camera, std_rot_deg, std_trans_m, distance_m, measurements)
        Per camera the standard deviations (roots of the traces) of its refined pose's
        rotation (degrees) and translation (metres), its median distance to the target
        (metres) and how many measurements it used.
    pose : str
        The pose's name in the outputs (``T_body_cam``, ``T_world_cam``), for the message.

    Returns
    -------
    Plausibility
        ``report`` with the findings added: rotation above :data:`UNDETERMINED_ROT_DEG`, or
        translation above :data:`UNDETERMINED_DISTANCE_SHARE` times the distance; ``report``
        itself when it doubts the result already (a wrong input spreads the pose too).
    """
    found = []
    if report.findings:          # a wrong input named already: the spread follows from it
        return report
    for name, rot, trans, dist, n in std:
        if not (rot > UNDETERMINED_ROT_DEG or trans > UNDETERMINED_DISTANCE_SHARE * dist):
            continue
        found.append(Finding(
            "observability", f"observability: camera {name}'s {pose} is not determined by its "
            f"{n} measurements: standard deviation {rot:.3g} deg and {1000 * trans:.4g} mm "
            f"(more than {UNDETERMINED_ROT_DEG:g} deg, or more than "
            f"{UNDETERMINED_DISTANCE_SHARE:g} x its {dist:.3g} m from the target), so the "
            f"pose given is one of many that fit; record more views with the rig or target "
            f"turned by 30 degrees or more about two axes while {name} sees the target",
            name, rot, rot, {"std_rot_deg": rot, "std_trans_m": trans, "distance_m": dist}))
    if not found:
        return report
    return replace(report, findings=report.findings + tuple(found),
                   tested=report.tested + ("observability",))


def _unexplained(name: str, cost: float, tested: list[str], mocap=None) -> Finding:
    causes = sorted({t.split(":")[0] for t in tested})
    return Finding("fit", f"poor fit: camera {name}'s residuals are {_times(cost)} times what "
                   f"the noise explains and none of the causes tested ({', '.join(causes)}) "
                   "explains them; check its target poses (images, detections), the time offset "
                   f"(--time-offset auto){rotation_hint(mocap)}, and state the motion-capture "
                   "noise (rotation_noise_deg, translation_noise_m) if it is this large", name,
                   cost, cost, {})


def _partial(finding: Finding, mocap) -> Finding:
    """``finding`` said to be at most part of the cause when its correction leaves residuals
    of :data:`UNEXPLAINED_COST` or more times what the noise explains (a factor fitted to
    data that something else spoils lowers the cost without explaining it)."""
    if finding.cause in ("fit", "noise") or finding.corrected_cost < UNEXPLAINED_COST:
        return finding
    return replace(finding, message=(
        f"{finding.message} (but with that correction the residuals are still "
        f"{_times(finding.corrected_cost)} times what the noise explains: it is at most a part "
        f"of the cause; check the target poses (images, detections), the time offset"
        f"{rotation_hint(mocap)} and the motion-capture poses too)"))


def rotation_hint(mocap) -> str:
    """A pointer at the poses' rotation convention when rig.yaml reads three angles per pose
    (``rotation: rotvec`` or ``euler-...``: :mod:`multieye.io.pose_files`), which no
    hypothesis tests: Euler angles read as a rotation vector (or the other way, another axis
    order, degrees read as radians) leave residuals no other cause explains; a matrix
    (``rotation: matrix``) stored column-major reads as its transpose; else ``""``.
    ``mocap`` is rig.yaml's motion-capture section (:class:`multieye.io.mocap.MocapSpec`)."""
    rotation = getattr(mocap, "rotation", None)
    if rotation == "matrix":
        return (", the poses' rotation convention (rig.yaml reads rotation: matrix, row-major: "
                "a matrix stored column-major reads as its transpose)")
    if not isinstance(rotation, str) or not (rotation == "rotvec"
                                             or rotation.startswith("euler-")):
        return ""
    return (f", the poses' rotation convention (rig.yaml reads rotation: {rotation}: Euler "
            "angles read as a rotation vector or the other way, another axis order or degrees "
            "read as radians fit this badly; the robot's manual names its convention)")


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
