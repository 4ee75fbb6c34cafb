"""A given lens doubted on what the lens freed on the camera's own detections shows
(:mod:`multieye.estimate.lens_freed`): the ``intrinsics`` finding's rule for rigs without
motion capture (:func:`given_lens_findings`, pixels and the camera's pose residuals against
the rig) and its message (:func:`lens_message`), which names a distortion left out of the
intrinsics file, or one far weaker than the images show, with the residuals before and after
and how to let multieye estimate the lens.  The motion-capture rule, on the loop residuals,
is :mod:`multieye.estimate.plausibility`'s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from multieye.estimate import hypotheses as h
from multieye.estimate import lens_freed as lf
from multieye.estimate.findings import Finding, _times
from multieye.estimate.hypotheses import CameraEvidence

__all__ = ["LENS_PIXEL_GAIN", "MIN_LENS_EXCESS_PX", "MIN_GIVEN_LENS_RMS_PX",
           "BARE_LENS_PIXEL_GAIN", "BARE_LENS_POSE_GAIN", "ALONE_PIXEL_GAIN",
           "given_lens_findings",
           "lens_message", "radial_doubt", "bare_doubt"]

#: Fewest-fold drop of the median reprojection RMS when the lens is freed, for the given lens
#: to be doubted on its pixels alone (the freed lens shows the detection noise: a correct lens
#: leaves at most about 1.5-1.8 times it on the shared recordings, docs/results/
#: plausibility_real.md), and the smallest systematic part of the given lens's RMS, pixels.
LENS_PIXEL_GAIN = 3.0
MIN_LENS_EXCESS_PX = 0.2
#: Median view RMS of a given lens from which a rig without motion capture frees it, pixels
#: (a lens without its distortion leaves 1-2 px on boofcv_stereo; good corners 0.1-0.3 px).
MIN_GIVEN_LENS_RMS_PX = 0.5
#: A lens whose k1 and k2 are refitted (given without distortion, or fitting its views within
#: MIN_GIVEN_LENS_RMS_PX), in a rig without motion capture: fewest-fold drop of the
#: median reprojection RMS with k1 and k2 freed (it must not grow; a correct lens: 1.00 on
#: rendered rigs; k1 -0.05 left out: 1.5; a 190-degree unified lens's k1 -0.08 given as -0.02
#: under 0.2 px of noise: 1.2; a fisheye's k1 0.05 left out: 1.01, the PnP poses absorbing
#: it) and of the camera's pose residuals against the rig (a correct lens: 0.95-1.05 over 40
#: rendered cameras; k1 -0.05 left out: 3.7 in rotation, 4.3 in translation; the unified
#: lens: 10; the fisheye: 2.0).  The pose residuals decide.
BARE_LENS_PIXEL_GAIN = 1.0
BARE_LENS_POSE_GAIN = 1.5
#: A camera alone, given without distortion: fewest-fold drop of the median reprojection RMS
#: with k1 and k2 freed (a right lens: 1.00; k1 -0.05 left out on a rendered 640 x 480 camera:
#: 1.52).
ALONE_PIXEL_GAIN = 1.3


def _coefficients(intr) -> str:
    """The lens's distortion in words: k1 and k2 (a unified lens's xi first; the rational
    model's trade off against its denominator: not shown), a double-sphere or eucm lens's
    two parameters."""
    names = {"double-sphere": ("xi", "alpha"), "eucm": ("alpha", "beta"),
             "unified": ("xi", "k1", "k2")}.get(intr.model, ("k1", "k2"))
    if lf.distortion_missing(intr):
        return "none" if intr.model != "unified" else f"xi {intr.dist[0]:.3g}, no k1 k2 p1 p2"
    if intr.model == "pinhole" and intr.dist.size > 5:
        return "fitted (rational model)"
    return ", ".join(f"{n} {v:.3g}" for n, v in zip(names, intr.dist))


def given_lens_findings(cameras: Sequence[CameraEvidence], *, alone: bool = False
                        ) -> tuple[Finding, ...]:
    """Rigs without motion capture: each camera's given lens against the lens freed on its
    own detections, judged on the pixels alone (no motion capture to close a loop with).

    A lens given without its distortion fits every view about equally badly, so a camera's
    PnP poses and the rig's projection agree and the rig's own ``fit`` check does not see
    it, while the extrinsics come out wrong (boofcv_stereo's baseline 17 % long).  Doubted,
    cause ``intrinsics``, when the freed lens lowers the median reprojection RMS at least
    :data:`LENS_PIXEL_GAIN` times and by at least :data:`MIN_LENS_EXCESS_PX`.  A given lens
    that leaves less than :data:`MIN_GIVEN_LENS_RMS_PX` in the median view (a distortion
    left out or far too weak leaves 0.07-0.4 px on rendered 640 x 480 rigs, exit status 0
    before) is not freed whole (0.1-1 CPU-s a camera, more for the wide models) but has its
    k1 and k2 refitted with the camera matrix kept, and is doubted when that lowers the RMS
    :data:`BARE_LENS_PIXEL_GAIN` times and the camera's pose residuals against the rig
    :data:`BARE_LENS_POSE_GAIN` times; a lens without distortion is refitted so too.

    Parameters
    ----------
    cameras : sequence of CameraEvidence
        The cameras with given intrinsics (``intrinsics_estimated`` False) and their views'
        points and PnP RMS; ``A``, ``B`` the rig's layout (board in the reference camera).
    alone : bool
        The rig is one camera: its board poses are its own PnP poses, so its pose residuals
        say nothing of the lens; a lens given without distortion is doubted on the pixels
        (:data:`ALONE_PIXEL_GAIN`), the message gives no pose residuals.

    Returns
    -------
    tuple of Finding
    """
    out = []
    for cam in cameras:
        if not cam.has_points or cam.intrinsics_estimated or cam.rms_px is None:
            continue
        # a lens that fits its views within MIN_GIVEN_LENS_RMS_PX gets only its k1 and k2
        # refitted (cheap); one that does not, every parameter
        close = float(np.median(cam.rms_px)) < MIN_GIVEN_LENS_RMS_PX
        test = lf.lens_search(cam, h.MOCAP_NOISE, radial_only=close)
        if test is None:
            continue
        if alone:
            test = replace(test, loop_given=(math.nan, math.nan),
                           loop_freed=(math.nan, math.nan))
        bare = lf.distortion_missing(cam.intrinsics)
        if _pixels_doubt(test, radial=close or bare) or (bare and (
                bare_doubt(test) or alone and _gain(test) >= ALONE_PIXEL_GAIN)):
            out.append(lens_message(cam, test, loop=False))
    return tuple(out)


def _gain(test: lf.LensTest) -> float:
    """How many times the freed lens lowers the median reprojection RMS."""
    return test.rms_given_px / max(test.rms_freed_px, 1e-9)


def _pixels_doubt(test: lf.LensTest, radial: bool) -> bool:
    """Whether the freed lens's pixels alone doubt the given one (rigs without motion
    capture): :data:`LENS_PIXEL_GAIN` times and :data:`MIN_LENS_EXCESS_PX` less RMS; or, with
    only k1 and k2 refitted (``radial``), :func:`radial_doubt`."""
    ratio = test.rms_given_px / max(test.rms_freed_px, 1e-9)
    excess = math.sqrt(max(test.rms_given_px ** 2 - test.rms_freed_px ** 2, 0.0))
    if ratio >= LENS_PIXEL_GAIN and excess >= MIN_LENS_EXCESS_PX:
        return True
    return radial and radial_doubt(test)


def bare_doubt(test: lf.LensTest) -> bool:
    """A lens given without distortion whose k1 and k2 freed lower the RMS
    :data:`LENS_PIXEL_GAIN` times, however few pixels that is: the images show a distortion
    the file lacks (a right lens: 1.00), whether or not it shows in the loop residuals (k1
    -0.1 left out under motion capture of 0.5 degrees and 5 mm: RMS 3.3 times, 0.10 px)."""
    return _gain(test) >= LENS_PIXEL_GAIN


def radial_doubt(test: lf.LensTest) -> bool:
    """Whether the given lens is doubted against itself with k1 and k2 refitted (two
    parameters, which move a right lens's RMS by a fraction of a percent):
    :data:`BARE_LENS_PIXEL_GAIN` times less RMS with the camera's mean pose (loop) residuals
    :data:`BARE_LENS_POSE_GAIN` times smaller in both rotation and translation (the
    distortion moves the result, not only the pixels)."""
    ratio = test.rms_given_px / max(test.rms_freed_px, 1e-9)
    if ratio < BARE_LENS_PIXEL_GAIN:
        return False
    gains = [b / a for b, a in zip(test.loop_given, test.loop_freed) if a > 0 and np.isfinite(b)]
    return len(gains) == 2 and min(gains) >= BARE_LENS_POSE_GAIN


#: The given lens bends the observed rays less than this share of the freed lens's bend (with
#: focal lengths within :data:`_SAME_FOCAL` of each other): its distortion is named as far
#: weaker than the images show, rather than the lens as another camera's.
_WEAK_BEND = 0.5
_SAME_FOCAL = 0.03


def _distortion_cause(cam: CameraEvidence, freed) -> str:
    """Why the given lens fits worse than ``freed``, in words."""
    given = cam.intrinsics
    if lf.distortion_missing(given):
        return ("the intrinsics give no lens distortion while these images show one: the "
                "distortion coefficients were probably left out of the intrinsics file (or "
                "read under another key)")
    pixels = np.concatenate([np.asarray(p, dtype=np.float64) for p in cam.image_points])
    bend_given, bend_freed = lf.lens_bend(pixels, given), lf.lens_bend(pixels, freed)
    if (abs(freed.K[0, 0] / given.K[0, 0] - 1.0) <= _SAME_FOCAL
            and bend_given < _WEAK_BEND * bend_freed):
        return (f"the intrinsics give a far weaker lens distortion than these images show "
                f"(it bends the rays by {bend_given:.3g} px at its outer target points, the "
                f"freed lens by {bend_freed:.3g} px): the distortion coefficients were probably "
                "truncated, scaled or copied from another lens, or the images were undistorted "
                "for another lens")
    return ("the intrinsics probably do not belong to these images (another camera or lens, "
            "a zoom or focus setting, distortion coefficients in another order or model)")


def lens_message(cam: CameraEvidence, test: lf.LensTest, *, loop: bool) -> Finding:
    """The ``intrinsics`` finding of a freed lens: with motion capture (``loop``) the loop
    residuals before and after; without, the camera's pose residuals against the rig."""
    given, freed = cam.intrinsics, test.intrinsics
    if loop:
        loops = (f", mean loop residual {_loop(test.loop_given)} -> {_loop(test.loop_freed)}, "
                 f"loop residuals {_times(test.cost_given)} -> {_times(test.cost_freed)} times "
                 "what the noise explains")
    elif all(np.isfinite(test.loop_given + test.loop_freed)):
        loops = (f", mean pose residual against the rig {_loop(test.loop_given)} -> "
                 f"{_loop(test.loop_freed)}")
    else:
        loops = ""
    return Finding(
        "intrinsics", f"intrinsics: camera {cam.name}'s lens freed (fitted to its own "
        f"detections) fits better than the given intrinsics: reprojection RMS "
        f"{test.rms_given_px:.3g} -> {test.rms_freed_px:.3g} px{loops} "
        f"(fx {given.K[0, 0]:.1f} -> {freed.K[0, 0]:.1f} px; distortion "
        f"{_coefficients(given)} -> {_coefficients(freed)}): "
        f"{_distortion_cause(cam, freed)}; calibrate the intrinsics again, or let multieye "
        "estimate them (model: instead of intrinsics:, or refine_intrinsics: true)", cam.name,
        test.cost_given, test.cost_freed,
        {"rms_given_px": test.rms_given_px, "rms_freed_px": test.rms_freed_px,
         "cost_given": test.cost_given, "cost_freed": test.cost_freed,
         "loop_given_deg": test.loop_given[0], "loop_given_m": test.loop_given[1],
         "loop_freed_deg": test.loop_freed[0], "loop_freed_m": test.loop_freed[1]})


def _loop(residual: tuple[float, float]) -> str:
    """``1.03 deg / 14.5 mm``."""
    return f"{residual[0]:.3g} deg / {1e3 * residual[1]:.3g} mm"


