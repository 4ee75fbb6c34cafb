"""Consensus over measurements: find the wrong ones before any least squares sees them.

A wrong PnP solution, a board detected upside down or a motion-capture glitch gives a
measurement ``(A_i, B_i)`` that no ``X``, ``Y`` fits; one such measurement can pull the closed
form (and a refinement started from it) far off.  :func:`consensus` finds them with RANSAC
per camera, the closed form as the minimal solver, then a joint check with the shared ``Y``:

1. Per camera: draw 3 measurements (the fewest that determine ``X^j`` and ``Y`` when their
   relative rotations are about different axes; samples about a single axis are skipped),
   solve them with the joint closed form (:func:`multieye.solvers.joint.solve_joint`), and
   count the measurements whose loop residual (:func:`measurement_residuals`: the paper's
   rotation residual ``angle((R_Y R_B)^T R_A R_X)`` and the distance between the measured
   and the predicted target origin in the camera frame) is within both thresholds.  The best
   sample so far is re-solved on all of its inliers (local optimisation) and the number of
   samples adapts to the inlier share (``confidence``).
2. Jointly: the inliers of all cameras are solved together (one ``Y``), every measurement is
   scored against that solution, and the fit is repeated on the new inliers until the set
   no longer changes.

Two poses per image (``B_alternative``): a single planar marker has two poses that fit its
four corners almost equally (:attr:`multieye.imaging.pnp.PoseEstimate.alternative`), and PnP
picks the mirrored one in many images.  Given both, every hypothesis scores each image by
the pose that agrees with it better, a minimal sample is solved with every combination of
its images' poses, and the local optimisation and the joint fit use per image the pose
chosen; :attr:`ConsensusResult.alternative` says which images took their second pose.
:func:`choose_poses` makes that choice for a given ``X``, ``Y`` (the closed form without
consensus uses it too).

Every rejected measurement keeps its residuals and a reason, e.g.
``"outlier by consensus (loop residual 12.3 deg / 0.410 m above threshold 5 deg / 0.05 m)"``.

The default thresholds (5 degrees, 5 cm) separate gross errors from noise: a half-turned
board, a wrong PnP branch or a motion-capture glitch is off by tens of degrees, while a
board 2 m away seen with 0.3 px noise has PnP rotation errors with a tail to about 2.5
degrees.  Lower them for close, well-detected targets.

Synopsis
--------
>>> from multieye.estimate.consensus import consensus
>>> cons = consensus(A, B, threshold_rot_deg=5.0, threshold_trans_m=0.05)   # doctest: +SKIP
>>> A_in = [a[k] for a, k in zip(A, cons.inliers)]                          # doctest: +SKIP
>>> [(r.camera, r.index, r.reason) for r in cons.rejected]                  # doctest: +SKIP
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.arguments import with_fields
from multieye.core.errors import CalibrationError, InputError, TooFewMeasurementsError
from multieye.core.metrics import loop_residuals
from multieye.solvers.checks import (
    MIN_MEASUREMENTS,
    Measurements,
    check_measurements,
    rotation_spread,
)
from multieye.solvers.joint import solve_joint

__all__ = ["DEFAULT_THRESHOLDS", "RejectedMeasurement", "ConsensusResult", "ConsensusOptions",
           "consensus", "measurement_residuals", "choose_poses", "check_alternatives"]

#: The loop-residual thresholds (degrees, metres) a measurement must meet by default: a
#: half-turned board, a wrong PnP branch or a motion-capture glitch is far beyond them.
DEFAULT_THRESHOLDS = (5.0, 0.05)

F64 = NDArray[np.float64]

#: RMS rotation (radians) about the second principal axis below which a minimal sample counts
#: as rotating about a single axis and is skipped (1 degree).
_MIN_SAMPLE_SPREAD_RAD = np.deg2rad(1.0)
_SAMPLE = 3


@dataclass(frozen=True)
class RejectedMeasurement:
    """One measurement left out by :func:`consensus`.

    Attributes
    ----------
    camera : str
    index : int
        Index of the measurement among that camera's (0-based, input order).
    rot_deg : float
        Loop rotation residual under the final solution, degrees.
    trans_m : float
        Loop translation residual, metres.
    reason : str
    """

    camera: str
    index: int
    rot_deg: float
    trans_m: float
    reason: str


@dataclass(frozen=True)
class ConsensusResult:
    """Result of :func:`consensus`.

    Attributes
    ----------
    inliers : tuple of ndarray, shape (N_j,), bool
        Measurements kept, per camera.
    rejected : tuple of RejectedMeasurement
        Measurements left out, camera by camera, in input order.
    X : ndarray, shape (m, 4, 4)
        Closed-form solution on the inliers (``T_world_cam`` or ``T_body_cam``).
    Y : ndarray, shape (4, 4)
    rot_deg, trans_m : tuple of ndarray, shape (N_j,)
        Loop residuals of every measurement under ``X``, ``Y``, degrees and metres.
    threshold_rot_deg, threshold_trans_m : float
    samples : tuple of int
        Minimal samples solved per camera.
    alternative : tuple of ndarray, shape (N_j,), bool
        Per camera, the measurements whose second pose (``B_alternative``) was chosen, and
        that ``rot_deg``, ``trans_m``, ``X`` and ``Y`` use; all False without alternatives.
    """

    inliers: tuple[NDArray[np.bool_], ...]
    rejected: tuple[RejectedMeasurement, ...]
    X: F64
    Y: F64
    rot_deg: tuple[F64, ...]
    trans_m: tuple[F64, ...]
    threshold_rot_deg: float
    threshold_trans_m: float
    samples: tuple[int, ...]
    alternative: tuple[NDArray[np.bool_], ...] = ()


def _real(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _labels(labels, meas: Measurements) -> list[list[str]]:
    """Per-camera measurement names for messages, checked against the counts."""
    counts = [int(c) for c in meas.counts]
    if labels is None:
        return [[f"measurement {i}" for i in range(n)] for n in counts]
    if isinstance(labels, (str, bytes)) or len(labels) != len(counts) or any(
            isinstance(lj, (str, bytes)) or len(lj) != n for lj, n in zip(labels, counts)):
        raise InputError(f"labels must hold one name per measurement of each camera "
                         f"(counts {counts})")
    return [[str(x) for x in lj] for lj in labels]


def measurement_residuals(A: F64, B: F64, X: F64, Y: F64) -> tuple[F64, F64]:
    """Residuals of ``A_i X = Y B_i`` as errors of the target pose seen by the camera.

    The measured ``T_cam_target = inv(B_i)`` against the predicted ``inv(X) inv(A_i) Y``
    (both setups, docs/conventions.md, section 2).

    Parameters
    ----------
    A, B : ndarray, shape (N, 4, 4)
    X, Y : ndarray, shape (4, 4)

    Returns
    -------
    rot_deg : ndarray, shape (N,)
        Angle between the two, degrees: the paper's loop rotation residual (section V-A).
    trans_m : ndarray, shape (N,)
        Distance between the two target origins in the camera frame, metres.  Unlike the
        paper's ``e_t`` (a camera position in the marker frame), it does not multiply PnP
        rotation errors by the target distance, so one threshold suits near and far views.
    """
    pred = g.inv(X) @ g.inv(A) @ Y
    return loop_residuals(pred, g.inv(B), np.eye(4), np.eye(4))


def check_alternatives(B_alternative, B: Sequence[F64]) -> list[F64]:
    """Validated second poses: per camera an array like ``B[j]``, NaN where none.

    Parameters
    ----------
    B_alternative : sequence of array_like, each shape (N_j, 4, 4), or None
        ``T_target_cam`` as ``B``; rows entirely NaN where a measurement has no second pose.
    B : sequence of ndarray, each shape (N_j, 4, 4)

    Returns
    -------
    list of ndarray, each shape (N_j, 4, 4)

    Raises
    ------
    InputError
        Not one array per camera of the shape of ``B[j]``, or a row that is neither all NaN
        nor a rigid transform.
    """
    if B_alternative is None:
        return [np.full_like(b, np.nan) for b in B]
    if isinstance(B_alternative, (str, bytes)) or len(B_alternative) != len(B):
        raise InputError(f"B_alternative must hold one array per camera ({len(B)})")
    out = []
    for j, (alt, b) in enumerate(zip(B_alternative, B)):
        try:
            alt = np.array(alt, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"B_alternative of camera {j} is not an array of numbers") from None
        if alt.shape != b.shape:
            raise InputError(f"B_alternative of camera {j} must have shape {b.shape}, got "
                             f"{alt.shape}")
        given = ~np.all(np.isnan(alt.reshape(len(alt), -1)), axis=1)
        R = alt[given, :3, :3]
        if given.any() and not (np.all(np.isfinite(alt[given]))
                                and np.allclose(R @ R.transpose(0, 2, 1), np.eye(3), atol=1e-6)
                                and np.all(np.linalg.det(R) > 0)
                                and np.allclose(alt[given, 3], [0, 0, 0, 1])):
            raise InputError(f"B_alternative of camera {j}: a row is neither all NaN nor a "
                             "rigid transform")
        out.append(alt)
    return out


def _has(Balt: F64) -> NDArray[np.bool_]:
    return ~np.isnan(Balt[:, 0, 0])


def _chosen(B: F64, Balt: F64, choice: NDArray[np.bool_]) -> F64:
    return np.where(choice[:, None, None], Balt, B)


def _residuals(A: F64, B: F64, Balt: F64, X: F64, Y: F64, thr_rot: float, thr_t: float):
    """Loop residuals (deg, m) per measurement under X, Y, of the pose that agrees better,
    and which pose that is (True: the alternative)."""
    rot, trans = measurement_residuals(A, B, X, Y)
    choice = np.zeros(len(A), dtype=bool)
    has = _has(Balt)
    if has.any():
        r2, t2 = measurement_residuals(A[has], Balt[has], X, Y)
        better = (r2 / thr_rot) ** 2 + (t2 / thr_t) ** 2 < \
            (rot[has] / thr_rot) ** 2 + (trans[has] / thr_t) ** 2
        choice[np.flatnonzero(has)[better]] = True
        rot, trans = rot.copy(), trans.copy()
        rot[choice], trans[choice] = r2[better], t2[better]
    return rot, trans, choice


def choose_poses(A: F64, B: F64, B_alternative: F64, X: F64, Y: F64, *,
                 threshold_rot_deg: float = 5.0,
                 threshold_trans_m: float = 0.05) -> NDArray[np.bool_]:
    """Per measurement, whether its second pose agrees better with ``X``, ``Y``.

    Parameters
    ----------
    A, B : ndarray, shape (N, 4, 4)
    B_alternative : ndarray, shape (N, 4, 4)
        Second ``T_target_cam`` per measurement, all NaN where none.
    X, Y : ndarray, shape (4, 4)
    threshold_rot_deg, threshold_trans_m : float
        Scales of the rotation (degrees) and position (metres) residuals in the comparison.

    Returns
    -------
    ndarray, shape (N,), bool
        True where the second pose has the smaller scaled loop residual.
    """
    return _residuals(A, B, B_alternative, X, Y, threshold_rot_deg, threshold_trans_m)[2]


def _score(A: F64, B: F64, X: F64, Y: F64, thr_rot: float, thr_t: float, Balt: F64):
    """Inlier mask, truncated cost (MSAC) and pose choice of one camera's measurements."""
    rot, trans, choice = _residuals(A, B, Balt, X, Y, thr_rot, thr_t)
    inl = (rot <= thr_rot) & (trans <= thr_t)
    cost = np.minimum((rot / thr_rot) ** 2 + (trans / thr_t) ** 2, 2.0).sum()
    return inl, float(cost), choice


def _fit(A: F64, B: F64) -> tuple[F64, F64]:
    """Closed form of one camera's measurements: X (4, 4), Y (4, 4)."""
    X, Y = solve_joint(Measurements.from_arrays(A, B, [len(A)]))
    return X[0], Y


def _sample_fits(A: F64, B: F64, Balt: F64, idx, thr_rot: float, thr_t: float):
    """Inlier mask, cost and pose choice of the best fit of a minimal sample, over every
    combination of its measurements' poses."""
    amb = [k for k in idx if not np.isnan(Balt[k, 0, 0])]
    best = None
    for flips in itertools.product((False, True), repeat=len(amb)):
        Bs = B.copy()
        for k, flip in zip(amb, flips):
            if flip:
                Bs[k] = Balt[k]
        inl, cost, choice = _score(A, B, *_fit(A[idx], Bs[idx]), thr_rot, thr_t, Balt)
        if best is None or (inl.sum(), -cost) > (best[0].sum(), -best[1]):
            best = (inl, cost, choice)
    return best


def _ransac_camera(A: F64, B: F64, thr_rot: float, thr_t: float, rng: np.random.Generator,
                   max_samples: int, confidence: float, Balt: F64):
    """Best inlier mask and pose choice of one camera (all inliers, first poses, when no
    usable minimal sample exists)."""
    n = len(A)
    best_inl, best_count, best_cost = np.ones(n, dtype=bool), -1, np.inf
    best_choice = np.zeros(n, dtype=bool)
    samples = 0
    needed = max_samples
    attempts = 0
    while samples < min(needed, max_samples) and attempts < 10 * max_samples:
        attempts += 1
        idx = rng.choice(n, size=_SAMPLE, replace=False)
        if rotation_spread(A[idx])[1] < _MIN_SAMPLE_SPREAD_RAD:
            continue
        samples += 1
        inl, cost, choice = _sample_fits(A, B, Balt, idx, thr_rot, thr_t)
        count = int(inl.sum())
        if count > best_count or (count == best_count and cost < best_cost):
            # Local optimisation: re-solve on the inliers (each with the pose chosen) while
            # that gains inliers.
            for _ in range(3):
                if inl.sum() < MIN_MEASUREMENTS:
                    break
                inl2, cost2, choice2 = _score(A, B, *_fit(A[inl], _chosen(B, Balt, choice)[inl]),
                                              thr_rot, thr_t, Balt)
                if inl2.sum() < inl.sum() or (inl2.sum() == inl.sum() and cost2 >= cost):
                    break
                inl, cost, choice = inl2, cost2, choice2
            best_inl, best_count, best_cost, best_choice = inl, int(inl.sum()), cost, choice
            w = best_count / n
            if w >= 1.0:
                needed = samples
            elif w > 0.0:
                needed = int(np.ceil(np.log(1.0 - confidence) / np.log(1.0 - w ** _SAMPLE)))
    return best_inl, best_choice, samples


@dataclass(frozen=True)
class ConsensusOptions:
    """How :func:`consensus` samples and what it calls agreement.

    Attributes
    ----------
    threshold_rot_deg : float
        Largest loop rotation residual of an inlier, degrees.
    threshold_trans_m : float
        Largest translation residual of an inlier (target origin in the camera frame, see
        :func:`measurement_residuals`), metres.
    names : sequence of str, optional
        Camera names used in the result and in messages; default ``cam0, cam1, ...``.
    max_samples : int
        Minimal samples per camera at most.
    confidence : float
        Stop sampling a camera when a sample of inliers only has been drawn with this
        probability, given the best inlier share so far.
    seed : int, Generator or None
        Random source of the samples (fixed by default: same input, same answer).
    labels : sequence of sequence of str, optional
        Per camera, a name for each measurement (its image file), used in messages; default
        ``measurement <i>``.
    B_alternative : sequence of array_like, each shape (N_j, 4, 4), optional
        Per camera a second ``T_target_cam`` per measurement (the mirrored PnP pose of a
        single marker), rows all NaN where there is none; each measurement is then counted
        with the pose that agrees better (module docstring).
    """

    threshold_rot_deg: float = 5.0
    threshold_trans_m: float = 0.05
    names: Sequence[str] | None = None
    max_samples: int = 500
    confidence: float = 0.999
    seed: int | np.random.Generator | None = 0
    labels: Sequence[Sequence[str]] | None = None
    B_alternative: Sequence[F64] | None = None


def consensus(A, B=None, options: ConsensusOptions = ConsensusOptions(), **kw
              ) -> ConsensusResult:
    """Find the measurements that agree with one ``X^j`` per camera and a shared ``Y``.

    Parameters
    ----------
    A, B : sequence of array_like, each shape (N_j, 4, 4)
        One entry per camera, as for :func:`multieye.solve` (docs/conventions.md, section 2);
        or ``A`` is a :class:`~multieye.solvers.checks.Measurements` validated before and
        ``B`` is omitted (no checks run again).
    options : ConsensusOptions
        Or its fields as keyword arguments (``threshold_rot_deg=5.0, names=[...]``): the
        thresholds, the sampling, the camera names, the measurements' labels and a single
        marker's second pose.

    Returns
    -------
    ConsensusResult

    Raises
    ------
    InputError
        Non-positive thresholds, bad shapes or non-rigid transforms.
    TooFewMeasurementsError
        A camera with fewer than 3 measurements, or fewer than 3 that agree with the rest;
        the message names the camera and the thresholds.
    DegenerateMotionError
        The pooled rotations of all cameras are about a single axis.
    """
    opts = with_fields(options, kw, ConsensusOptions, "options")
    _check_options(opts)
    meas = check_measurements(A, B, names=opts.names, per_camera_motion=False)
    labels = _labels(opts.labels, meas)
    As, Bs = meas.split(meas.A), meas.split(meas.B)
    Balts = check_alternatives(opts.B_alternative, Bs)
    try:
        rng = np.random.default_rng(opts.seed)
    except (TypeError, ValueError):
        raise InputError(f"seed must be an int, a numpy Generator or None, got {opts.seed!r}"
                         ) from None
    thr = (opts.threshold_rot_deg, opts.threshold_trans_m)
    inliers, choices, samples = [], [], []
    for Aj, Bj, Balt in zip(As, Bs, Balts):
        inl, choice, s = _ransac_camera(Aj, Bj, *thr, rng, opts.max_samples, opts.confidence,
                                        Balt)
        inliers.append(inl)
        choices.append(choice)
        samples.append(s)
    choices = _aligned(As, Bs, Balts, inliers, choices, thr)
    inliers, X, Y, res = _settle(meas, As, Bs, Balts, inliers, choices, thr, labels)
    return ConsensusResult(inliers=tuple(inliers), rejected=_rejected(inliers, res, thr, meas),
                           X=X, Y=Y, rot_deg=tuple(r for r, _, _ in res),
                           trans_m=tuple(t for _, t, _ in res),
                           threshold_rot_deg=float(thr[0]), threshold_trans_m=float(thr[1]),
                           samples=tuple(samples), alternative=tuple(c for _, _, c in res))


def _check_options(opts: ConsensusOptions) -> None:
    for name in ("threshold_rot_deg", "threshold_trans_m", "confidence"):
        v = getattr(opts, name)
        if not _real(v):
            raise InputError(f"{name} must be a real number, got {v!r}")
        if name != "confidence" and not (np.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v!r}")
    if not 0.0 < opts.confidence < 1.0:
        raise InputError(f"confidence must be in (0, 1), got {opts.confidence}")
    max_samples = opts.max_samples
    if isinstance(max_samples, bool) or not isinstance(max_samples, (int, np.integer)) \
            or max_samples < 1:
        raise InputError(f"max_samples must be a positive integer, got {max_samples!r}")


def _aligned(As, Bs, Balts, inliers, choices, thr) -> list[NDArray[np.bool_]]:
    """Per camera its pose choices, or all of them toggled where it has second poses,
    whichever agrees with the cameras before it (more inliers under their joint fit, then
    the smaller cost).  A board that looks the same after a half turn fits one camera alike in
    either of its two frames (every view's second pose is the other frame's), so each camera's
    own consensus may have found either, and the joint fit needs one; a single marker's
    mirrored poses, all taken, fit worse and are left.  Cameras with too few inliers are left
    for :func:`_settle` to name."""
    if any(k.sum() < MIN_MEASUREMENTS for k in inliers):
        return list(choices)
    out = [choices[0]]
    for j in range(1, len(As)):
        has = _has(Balts[j])
        if not has.any():
            out.append(choices[j])
            continue
        best, best_key = choices[j], None
        for c in (choices[j], choices[j] ^ has):
            used = [_chosen(b, alt, ch) for b, alt, ch in zip(Bs[:j + 1], Balts[:j + 1],
                                                               out + [c])]
            try:
                X, Y = solve_joint(Measurements.from_arrays(
                    np.concatenate([a[k] for a, k in zip(As, inliers[:j + 1])]),
                    np.concatenate([b[k] for b, k in zip(used, inliers)]),
                    [int(k.sum()) for k in inliers[:j + 1]]))
            except CalibrationError:
                continue
            scores = [_score(a, b, X[k], Y, *thr, np.full_like(b, np.nan))
                      for k, (a, b) in enumerate(zip(As, used))]
            key = (sum(int(i.sum()) for i, _, _ in scores), -sum(cost for _, cost, _ in scores))
            if best_key is None or key > best_key:
                best, best_key = c, key
        out.append(best)
    return out


def _settle(meas: Measurements, As, Bs, Balts, inliers, choices, thr, labels):
    """Refit on the inliers of every camera together and rescore until the inliers (and
    the poses chosen) no longer change (10 rounds at most).  Returns the inliers, ``X``,
    ``Y`` and per camera the residuals (rotation, translation, choice)."""
    threshold_rot_deg, threshold_trans_m = thr
    names = meas.names
    for _ in range(10):
        for j, inl in enumerate(inliers):
            if inl.sum() < MIN_MEASUREMENTS:
                out = [labels[j][i] for i in np.flatnonzero(~inl)]
                listed = ", ".join(out[:5]) + (f" and {len(out) - 5} more" if len(out) > 5 else "")
                raise TooFewMeasurementsError(
                    f"camera {names[j]}: only {int(inl.sum())} of {len(inl)} measurements agree "
                    f"within {threshold_rot_deg:g} deg / {threshold_trans_m:g} m, at least "
                    f"{MIN_MEASUREMENTS} are needed (outliers: {listed}); check its detections "
                    "and time pairing, or raise the thresholds")
        used = [_chosen(b, alt, c) for b, alt, c in zip(Bs, Balts, choices)]
        X, Y = solve_joint(replace(Measurements.from_arrays(
            np.concatenate([a[k] for a, k in zip(As, inliers)]),
            np.concatenate([b[k] for b, k in zip(used, inliers)]),
            [int(k.sum()) for k in inliers]), names=tuple(names)))
        res = [_residuals(a, b, alt, X[j], Y, threshold_rot_deg, threshold_trans_m)
               for j, (a, b, alt) in enumerate(zip(As, Bs, Balts))]
        new = [(r <= threshold_rot_deg) & (t <= threshold_trans_m) for r, t, _ in res]
        new_choices = [c for _, _, c in res]
        if all(np.array_equal(a, b) for a, b in zip(new, inliers)) and all(
                np.array_equal(a, b) for a, b in zip(new_choices, choices)):
            break
        inliers, choices = new, new_choices
    return inliers, X, Y, res


def _rejected(inliers, res, thr, meas: Measurements) -> tuple[RejectedMeasurement, ...]:
    rejected, names = [], meas.names
    for j, (inl, (rot, trans, _)) in enumerate(zip(inliers, res)):
        for i in np.flatnonzero(~inl):
            rejected.append(RejectedMeasurement(
                camera=names[j], index=int(i), rot_deg=float(rot[i]), trans_m=float(trans[i]),
                reason=(f"outlier by consensus (loop residual {rot[i]:.1f} deg / "
                        f"{trans[i]:.3f} m above threshold {thr[0]:g} deg / {thr[1]:g} m)")))
    return tuple(rejected)
