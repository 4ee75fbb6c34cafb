"""Clock offset between a camera and the motion capture, estimated from the data.

The paper (Wang et al. 2022) requires hard-synchronised clocks.  When the camera and the
motion capture each stamp their samples with their own clock, the offset (docs/conventions.md,
section 4: ``time_offset_s`` = motion-capture clock minus camera clock; the image stamped
``c`` matches the motion-capture sample stamped ``c + offset``) is estimated in two steps:

1. **Coarse: angular speeds.**  The angle of the relative rotation between two poses of the
   target seen by the camera equals the angle between the two motion-capture poses, whatever
   ``X`` and ``Y`` are: eye-to-base, ``R_ct(t1)^T R_ct(t2) = R_Y^T R_wm(t1)^T R_wm(t2) R_Y``;
   eye-on-hand, ``R_Y^T R_wb(t1) R_wb(t2)^T R_Y``, whose trace (hence angle) equals that of
   ``R_wb(t1)^T R_wb(t2)``.  So the camera's mean angular speed over a baseline (the angle
   between images about ``baseline_s`` apart over their interval) is compared with the
   motion capture's over the same baseline (SLERP on a uniform grid at its own rate)
   shifted by every candidate offset; the normalised cross-correlation peaks at the offset
   (refined by a parabola through the peak).
2. **Fine: loop residuals.**  Around the coarse offset, the motion-capture pose of every
   image is interpolated at ``c + offset`` (SLERP and linear,
   :func:`multieye.estimate.pairing.interpolate_poses`), the camera's ``X`` and ``Y`` are re-solved in
   closed form (:func:`multieye.solvers.joint.solve_joint`) and the offset minimising the
   chi-square of the loop residuals (rotation and translation, each normalised by its
   noise level; gross outliers left out) is found: a grid search around the coarse offset
   (widened to half the baseline either side when the residuals still fall at its end: on
   noisy streams the correlation peak can miss by tens of milliseconds; when they still fall
   at the end of that, the offset is reported with a note and no standard deviation),
   then the vertex of a least-squares parabola over +-4 motion-capture sample intervals
   (interpolation between noisy samples halves their noise halfway between samples, which
   scallops the profile with the sample period; the parabola averages that out).  The
   standard deviation follows from the parabola's curvature, ``sqrt(2 / chi2'')``; it
   covers the measurement noise only,
   not motion-capture latency that varies, nor residuals correlated in time (real data:
   take it as a lower bound).

Synopsis
--------
>>> from multieye.estimate.clock import estimate_offset
>>> off = estimate_offset(cam_stamps, T_cam_target, mocap_stamps, T_world_marker)  # doctest: +SKIP
>>> off.offset_s, off.std_s, off.score                                             # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from multieye.core.arguments import real_array, real_number, with_fields
from multieye.core import geometry as g
from multieye.core.errors import DegenerateMotionError, InputError, TooFewMeasurementsError
from multieye.core.metrics import chordal_angle, loop_residuals
from multieye.estimate.pairing import interpolate_poses
from multieye.core.problem import SETUPS
from multieye.solvers.checks import rotation_spread
from multieye.solvers.measurements import Measurements
from multieye.solvers.joint import solve_joint

__all__ = ["ClockOffset", "OffsetSearch", "estimate_offset", "angular_speed"]

F64 = NDArray[np.float64]

#: Loop residuals larger than this many times their median are left out of the fine search.
_OUTLIER_MEDIANS = 5.0
#: RMS rotation (radians) about the second principal axis below which the loop residuals do
#: not determine X and Y, so the fine step is skipped (2 degrees).
_MIN_SPREAD_RAD = np.deg2rad(2.0)
_MIN_PAIRS = 10
#: Half-width of the parabola fitted to the loop-residual profile, in motion-capture sample
#: intervals.  Interpolating between noisy samples averages their noise, so the profile is
#: scalloped with the sample period (lowest halfway between samples); a least-squares
#: parabola over several periods averages the scallops out.
_FIT_PERIODS = 4


@dataclass(frozen=True)
class ClockOffset:
    """Estimated clock offset of one camera.

    Attributes
    ----------
    offset_s : float
        Motion-capture clock minus camera clock, seconds (docs/conventions.md, section 4).
    std_s : float
        Standard deviation from the curvature of the loop-residual profile, seconds (NaN when
        only the coarse step ran).
    score : float
        Peak normalised cross-correlation of the angular speeds, in [-1, 1]; below about 0.5
        the motion is too weak or too uniform to time it.
    coarse_offset_s : float
        Offset from the angular-speed correlation alone, seconds.
    method : str
        What produced ``offset_s``.
    n_used : int
        Images used by the fine step (angular-speed pairs for the coarse step alone).
    rot_rms_deg, trans_rms_m : float
        RMS loop residuals of the closed form at ``offset_s`` (NaN when coarse only).
    note : str
        Empty, or why ``offset_s`` is doubtful (the loop residuals have no minimum near the
        angular-speed peak); ``std_s`` is then NaN.
    """

    offset_s: float
    std_s: float
    score: float
    coarse_offset_s: float
    method: str
    n_used: int
    rot_rms_deg: float
    trans_rms_m: float
    note: str = ""


def angular_speed(stamps: ArrayLike, T: ArrayLike, *, baseline_s: float | None = None,
                  max_gap_s: float | None = None) -> tuple[F64, F64, F64]:
    """Mean angular speed between poses a baseline apart.

    Parameters
    ----------
    stamps : array_like, shape (K,)
        Increasing times, seconds.
    T : array_like, shape (K, 4, 4)
        Poses (any frames: only relative rotation angles are used).
    baseline_s : float, optional
        Each pose is paired with the first pose at least this much later; default: the
        next pose.
    max_gap_s : float, optional
        Pairs further apart are left out; default 1.5 times the baseline, or 2.5 times the
        median interval when pairing consecutive poses.

    Returns
    -------
    mid_s : ndarray, shape (n,)
        Midpoint time of each kept pair, seconds.
    speed : ndarray, shape (n,)
        Rotation angle between the two poses over their interval, rad/s.
    dt_s : ndarray, shape (n,)
        Interval of each pair, seconds.
    """
    t = np.asarray(stamps, dtype=np.float64)
    T = np.asarray(T, dtype=np.float64)
    k = np.arange(len(t))
    if baseline_s is None:
        j = k + 1
        if max_gap_s is None:
            max_gap_s = 2.5 * float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    else:
        j = np.searchsorted(t, t + baseline_s, side="left")
        if max_gap_s is None:
            max_gap_s = 1.5 * baseline_s
    ok = j < len(t)
    k, j = k[ok], j[ok]
    dt = t[j] - t[k]
    keep = (dt > 0) & (dt <= max_gap_s)
    k, j, dt = k[keep], j[keep], dt[keep]
    return 0.5 * (t[k] + t[j]), chordal_angle(T[k], T[j]) / dt, dt


def _interpolate(stamps: F64, T: F64, query: F64) -> F64:
    """Poses at ``query`` times inside ``stamps`` (SLERP and linear between neighbours)."""
    right = np.clip(np.searchsorted(stamps, query, side="left"), 1, len(stamps) - 1)
    left = right - 1
    alpha = (query - stamps[left]) / (stamps[right] - stamps[left])
    return interpolate_poses(T[left], T[right], alpha)


#: Most grid points of the coarse search and of the motion-capture resampling.
_MAX_GRID = 1e7


def _check_stream(stamps, T, what: str) -> tuple[F64, F64]:
    t = real_array(stamps, f"{what}: time stamps").reshape(-1)
    P = real_array(T, f"{what}: poses")
    if P.ndim != 3 or P.shape[1:] != (4, 4) or len(P) != len(t):
        raise InputError(f"{what}: expected one 4x4 pose per time stamp, got {len(t)} stamps "
                         f"and poses of shape {P.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(P))):
        raise InputError(f"{what}: time stamps and poses must be finite")
    if np.any(np.diff(t) <= 0):
        raise InputError(f"{what}: time stamps must be strictly increasing")
    if len(t) < _MIN_PAIRS:
        raise TooFewMeasurementsError(f"{what}: {len(t)} samples, at least {_MIN_PAIRS} are "
                                      "needed to estimate a clock offset")
    return t, P


def _correlate(cam_t, P, mocap_t, M, baseline, search, step):
    """Coarse offset, its peak correlation and the number of pairs used (module docstring)."""
    mid, speed, _ = angular_speed(cam_t, P, baseline_s=baseline)
    if mid.size < _MIN_PAIRS:
        raise TooFewMeasurementsError(
            f"only {mid.size} pairs of images {baseline:g} s apart; at least {_MIN_PAIRS} are "
            "needed to time the motion (record longer, or lower baseline_s)")
    if float(np.ptp(speed)) <= 0.0:
        raise DegenerateMotionError("the target never changes its angular speed in front of "
                                    "the camera, so the motion carries no timing; move it "
                                    "irregularly (turn, stop, turn back)")
    # The same quantity for the motion capture on a uniform grid at its own rate.
    dt_m = float(np.median(np.diff(mocap_t)))
    grid = np.arange(mocap_t[0] + baseline / 2, mocap_t[-1] - baseline / 2, dt_m)
    sig = chordal_angle(_interpolate(mocap_t, M, grid - baseline / 2),
                        _interpolate(mocap_t, M, grid + baseline / 2)) / baseline
    offsets = np.arange(search[0], search[1] + 0.5 * step, step)
    scores = np.full(offsets.size, -np.inf)
    used = 0
    for k, d in enumerate(offsets):
        q = mid + d
        ok = (q >= grid[0]) & (q <= grid[-1])
        if ok.sum() < _MIN_PAIRS:
            continue
        a = speed[ok] - speed[ok].mean()
        b = np.interp(q[ok], grid, sig)
        b = b - b.mean()
        denom = np.sqrt((a @ a) * (b @ b))
        if denom > 0:
            scores[k] = (a @ b) / denom
            used = max(used, int(ok.sum()))
    if not np.any(np.isfinite(scores)):
        raise InputError("the camera and motion-capture streams do not overlap in time for any "
                         f"offset in {search[0]:g}..{search[1]:g} s; widen search_s or check the "
                         "time stamps (same unit, seconds)")
    k = int(np.argmax(scores))
    best = float(offsets[k])
    if 0 < k < offsets.size - 1 and np.all(np.isfinite(scores[k - 1:k + 2])):
        y0, y1, y2 = scores[k - 1:k + 2]
        curv = y0 - 2.0 * y1 + y2
        if curv < 0:
            best += step * 0.5 * (y0 - y2) / curv
    return float(best), float(scores[k]), used


class _LoopProfile:
    """Chi-square of the closed form's loop residuals as a function of the offset."""

    def __init__(self, cam_t, B, mocap_t, mocap_T, opts: OffsetSearch, window):
        lo, hi = window
        max_gap = 3.0 * float(np.median(np.diff(mocap_t)))
        # Images whose interpolation interval stays inside the recording, without gaps,
        # for every offset in the window: the same images for every offset.
        first = np.searchsorted(mocap_t, cam_t + lo, side="right") - 1
        last = np.searchsorted(mocap_t, cam_t + hi, side="left")
        ok = (first >= 0) & (last < len(mocap_t))
        first, last = np.clip(first, 0, len(mocap_t) - 1), np.clip(last, 0, len(mocap_t) - 1)
        gaps = np.diff(mocap_t)
        cum_bad = np.concatenate([[0], np.cumsum(gaps > max_gap)])
        ok &= (cum_bad[last] - cum_bad[first]) == 0
        self.cam_t, self.B = cam_t[ok], B[ok]
        self.mocap_t, self.mocap_T, self.setup = mocap_t, mocap_T, opts.setup
        self.keep = np.ones(int(ok.sum()), dtype=bool)
        self.s_rot = self.s_t = 1.0

    def A(self, offset: float) -> F64:
        M = _interpolate(self.mocap_t, self.mocap_T, self.cam_t + offset)
        return M if self.setup == "eye-on-hand" else g.inv(M)

    def residuals(self, offset: float) -> tuple[F64, F64]:
        A, B = self.A(offset)[self.keep], self.B[self.keep]
        X, Y = solve_joint(Measurements.from_arrays(A, B, [len(A)]))
        rot_deg, trans = loop_residuals(A, B, X[0], Y)
        return np.radians(rot_deg), trans

    def set_scales(self, offset: float) -> None:
        """Noise levels per residual component (robust), and outliers, at ``offset``."""
        self.keep[:] = True
        rot, trans = self.residuals(offset)
        # The norm of a 3-vector of N(0, s^2) components has median ~1.54 s, so this keeps
        # residuals within about 7.7 s.
        self.keep = ((rot <= _OUTLIER_MEDIANS * np.median(rot))
                     & (trans <= _OUTLIER_MEDIANS * np.median(trans)))
        rot, trans = self.residuals(offset)
        self.s_rot = max(float(np.sqrt(np.mean(rot ** 2) / 3.0)), 1e-12)
        self.s_t = max(float(np.sqrt(np.mean(trans ** 2) / 3.0)), 1e-12)

    def chi2(self, offset: float) -> float:
        rot, trans = self.residuals(offset)
        return float(np.sum((rot / self.s_rot) ** 2) + np.sum((trans / self.s_t) ** 2))


@dataclass(frozen=True)
class OffsetSearch:
    """How :func:`estimate_offset` searches.

    Attributes
    ----------
    search_s : (float, float)
        Range of offsets searched, seconds.
    setup : {"eye-to-base", "eye-on-hand"}
        How A is formed from the motion capture for the fine step (docs/conventions.md, section 2).
    baseline_s : float
        Time between the two poses of each angular-speed sample, seconds.  Longer baselines
        average out the PnP noise (which dominates the speed between consecutive images of a
        slowly moving target) at the cost of timing resolution, which the fine step restores.
    step_s : float, optional
        Grid step of the coarse search; default a quarter of the median camera interval,
        at most 5 ms.
    refine : bool
        Run the fine step (loop residuals); when False, or when the camera's rotations do
        not determine X and Y (about a single axis), the coarse offset is returned.
    """

    search_s: tuple[float, float] = (-0.5, 0.5)
    setup: str = "eye-to-base"
    baseline_s: float = 0.5
    step_s: float | None = None
    refine: bool = True


def estimate_offset(cam_stamps: ArrayLike, T_cam_target: ArrayLike, mocap_stamps: ArrayLike,
                    T_world_mocap: ArrayLike, search: OffsetSearch = OffsetSearch(), **kw
                    ) -> ClockOffset:
    """Clock offset between one camera and the motion capture (module docstring).

    Parameters
    ----------
    cam_stamps : array_like, shape (K,)
        Image times in the camera clock, seconds, increasing.
    T_cam_target : array_like, shape (K, 4, 4)
        Target pose in each image (PnP), metres.
    mocap_stamps : array_like, shape (L,)
        Motion-capture times in its own clock, seconds, increasing.
    T_world_mocap : array_like, shape (L, 4, 4)
        ``T_world_marker`` (eye-to-base) or ``T_world_body`` (eye-on-hand).
    search : OffsetSearch
        Or its fields as keyword arguments (``search_s=(-0.5, 0.5), setup="eye-on-hand"``).

    Returns
    -------
    ClockOffset

    Raises
    ------
    InputError
        Malformed streams, an unknown setup, or streams that never overlap in the search
        range.
    TooFewMeasurementsError
        Fewer than 10 samples in a stream.
    DegenerateMotionError
        The target (or rig) never turns, so angular speeds carry no timing.
    """
    opts = with_fields(search, kw, OffsetSearch, "search")
    setup, search_s, refine = opts.setup, opts.search_s, opts.refine
    if not isinstance(setup, str) or setup not in SETUPS:
        raise InputError(f"setup must be one of {SETUPS}, got {setup!r}")
    search = real_array(search_s, "search_s", shape=(2,),
                        expected="(low, high), two finite numbers of seconds")
    lo, hi = (float(v) for v in search)
    if not (np.isfinite(search).all() and hi > lo):
        raise InputError(f"search_s must be (low, high) with low < high, got {search_s}")
    baseline_s = real_number(opts.baseline_s, "baseline_s", positive=True)
    step_s = real_number(opts.step_s, "step_s", positive=True, allow_none=True)
    cam_t, P = _check_stream(cam_stamps, T_cam_target, "camera stream")
    mocap_t, M = _check_stream(mocap_stamps, T_world_mocap, "motion-capture stream")
    camera_dt = float(np.median(np.diff(cam_t)))
    step = step_s if step_s is not None else min(camera_dt / 4.0, 0.005)
    if (hi - lo) / step > _MAX_GRID or np.ptp(mocap_t) / np.median(np.diff(mocap_t)) > _MAX_GRID:
        raise InputError(f"the search ({hi - lo:g} s in steps of {step:g} s) or the motion "
                         f"capture ({np.ptp(mocap_t):g} s at its median interval) spans more "
                         f"than {_MAX_GRID:g} grid points; narrow search_s or check the stamps")
    coarse, score, pairs = _correlate(cam_t, P, mocap_t, M, baseline_s, (lo, hi), step)
    method = "angular-speed correlation"
    nan = float("nan")
    if not refine or rotation_spread(g.inv(P))[1] < _MIN_SPREAD_RAD:
        return ClockOffset(coarse, nan, score, coarse, method, pairs, nan, nan)

    half = max(3.0 * step, camera_dt, 0.03)
    fit_half = _FIT_PERIODS * float(np.median(np.diff(mocap_t)))
    wide = max(half, baseline_s / 2.0)
    fine = _fine_step(lambda w: _LoopProfile(cam_t, g.inv(P), mocap_t, M, opts, w), coarse,
                      (coarse - half, coarse + half),
                      (max(lo, coarse - wide), min(hi, coarse + wide)), fit_half)
    if fine is None:
        return ClockOffset(coarse, nan, score, coarse, method, pairs, nan, nan)
    best, std, profile, note = fine
    rot, trans = profile.residuals(best)
    return ClockOffset(best, std, score, coarse,
                       "angular-speed correlation, refined on closed-form loop residuals",
                       int(profile.keep.sum()), float(np.degrees(np.sqrt(np.mean(rot ** 2)))),
                       float(np.sqrt(np.mean(trans ** 2))), note)


def _fine_step(profile_over, coarse: float, interval: tuple[float, float],
               reach: tuple[float, float], fit_half: float):
    """Offset minimising the loop-residual chi-square near ``coarse`` (module docstring).

    A grid search over ``interval`` (41 points); when its minimum sits at an end of the
    interval (the residuals still fall there: the angular-speed peak is off by more than the
    interval, as on noisy streams), the same grid over ``reach`` (seconds; half the baseline
    of the angular speeds either side of ``coarse``, within the search range).  Then the
    vertex of least-squares parabolas over +-``fit_half``, never outside the interval the
    grid examined (a flat profile under slow motion capture would drift).

    Returns
    -------
    (offset_s, std_s, profile, note) or None
        ``None`` when too few images stay in the recording for every offset examined.
        ``note`` is non-empty, and ``std_s`` NaN, when the residuals fall all the way to an
        end of ``reach``: the offset is then not determined by them.
    """
    spacing = (interval[1] - interval[0]) / 40.0
    for span in (interval, reach):
        profile = profile_over((span[0] - 2.0 * fit_half, span[1] + 2.0 * fit_half))
        if profile.keep.sum() < _MIN_PAIRS:
            return None
        profile.set_scales(coarse)
        grid = np.linspace(span[0], span[1], 1 + max(1, round((span[1] - span[0]) / spacing)))
        k = int(np.argmin([profile.chi2(d) for d in grid]))
        if 0 < k < grid.size - 1:
            break
    best = float(grid[k])
    profile.set_scales(best)
    a2 = 0.0
    for _ in range(3):
        fit = np.linspace(best - fit_half, best + fit_half, 33)
        a2, a1, _ = np.polyfit(fit - best, [profile.chi2(d) for d in fit], 2)
        if a2 <= 0:
            break
        new = float(np.clip(best - a1 / (2.0 * a2), max(best - fit_half, span[0]),
                            min(best + fit_half, span[1])))
        shift, best = new - best, new
        if abs(shift) < 1e-3 * fit_half:
            break
    if not 0 < k < grid.size - 1:
        return best, float("nan"), profile, (
            f"the loop residuals still fall at {best:+.3f} s, the end of the offsets examined "
            f"({span[0]:+.3f}..{span[1]:+.3f} s around the angular-speed peak "
            f"{coarse:+.3f} s): the offset is not determined by them")
    return best, float(np.sqrt(1.0 / a2)) if a2 > 0 else float("nan"), profile, ""
