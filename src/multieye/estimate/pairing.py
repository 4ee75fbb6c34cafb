"""Pairing images with motion-capture samples in time.

Every image is matched with the motion-capture pose at its time stamp (plus the clock
offset, docs/conventions.md, section 4: ``time_offset_s``, motion-capture minus camera
clock).  When two samples bracket the image and are at most ``2 * tolerance`` apart, the
pose is interpolated between them (SLERP for the rotation, linear for the translation);
otherwise the nearest sample is used if it lies within ``tolerance``, and the image is
left unpaired, with the reason, if not.

Synopsis
--------
>>> p = pair_in_time(mocap_stamps, T_world_marker, image_stamps, tolerance=0.03)  # doctest: +SKIP
>>> p.T[k]  # pose at image p.index[k]                                             # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from multieye.core.arguments import real_array, real_number
from multieye.core.errors import InputError
from multieye.core.geometry import make_transform, rotation_from_rotvec, rotvec_from_transform
from multieye.core.limits import MAX_TIME_OFFSET_S

__all__ = ["Pairing", "pair_in_time", "interpolate_poses"]


@dataclass(frozen=True)
class Pairing:
    """Result of :func:`pair_in_time`.

    Attributes
    ----------
    index : ndarray, shape (K,), int
        Indices of the queries that received a pose, increasing.
    T : ndarray, shape (K, 4, 4)
        The pose at each of those queries (same frames as the trajectory).
    gap_s : ndarray, shape (K,)
        Distance in time to the nearest motion-capture sample, seconds.
    interpolated : ndarray, shape (K,), bool
        Whether the pose was interpolated between two bracketing samples.
    unpaired : tuple of (int, str)
        Query index and the reason it got no pose.
    noise_scale : ndarray, shape (K,)
        The standard deviation of each pose's noise over one sample's, for samples whose
        noise is independent: ``sqrt(a^2 + (1 - a)^2)`` for a pose interpolated at ``a``
        between two samples (0.71 midway), 1 for a sample taken as it is.
    """

    index: np.ndarray
    T: np.ndarray
    gap_s: np.ndarray
    interpolated: np.ndarray
    unpaired: tuple[tuple[int, str], ...]
    noise_scale: np.ndarray | None = None



def _unit_hint(q: float, stamps: np.ndarray) -> str:
    """A hint when an image stamp is a power of 1000 times the motion capture's stamps (one
    clock written in milliseconds, microseconds or nanoseconds where the other is in
    seconds): empty otherwise."""
    mid = float(np.median(stamps))
    if not (q > 0 and mid > 0):
        return ""
    power = round(float(np.log10(q / mid)) / 3)
    if power == 0 or abs(float(np.log10(q / mid)) - 3 * power) > 0.05:
        return ""
    bigger = "image stamps" if power > 0 else "motion-capture stamps"
    return (f"; the {bigger} are about {1000 ** abs(power):g} times the others: one clock in "
            "other units (milliseconds, microseconds, nanoseconds) than the other? (a file's "
            "stamps of 16 to 19 digits are read as nanoseconds)")

#: Stamps above this are dates (seconds since 1970: after March 1973) ...
DATE_S = 1e8
#: ... and below this, times since a take or a device started (under 11.6 days).
SINCE_START_S = 1e6


def _clock_hint(q: float, first: float, stamps: np.ndarray) -> str:
    """:func:`_unit_hint`, or a hint when one clock holds dates and the other the time since
    a take started (Motive, Vicon and robot logs write that; image names are often dates):
    with the camera's ``time_offset`` (added to the image stamps) about ``stamps[0] - first``
    the first image falls at the take's start.  Empty otherwise."""
    hint = _unit_hint(q, stamps)
    if hint or not stamps.size:
        return hint
    if q > DATE_S and stamps[-1] < SINCE_START_S:
        which = "the motion capture's times start at {:.3f} s (time since its take started, as "
    elif q < SINCE_START_S and stamps[0] > DATE_S:
        which = "the image stamps are times since a start where the motion capture's ({:.3f} s) "
    else:
        return ""
    return ("; " + which.format(stamps[0]) + "exports write them) where the other clock holds "
            "dates: give the camera's time_offset (seconds added to its image stamps: "
            f"{stamps[0] - first:.3f} if its first image was taken at the motion capture's "
            "first sample) or record both in one clock")


def interpolate_poses(T0: ArrayLike, T1: ArrayLike, alpha: ArrayLike) -> np.ndarray:
    """Poses a fraction ``alpha`` of the way from ``T0`` to ``T1``.

    Rotation by SLERP (``R0 exp(alpha log(R0^T R1))``), translation linearly.

    Parameters
    ----------
    T0, T1 : array_like, shape (K, 4, 4)
    alpha : array_like, shape (K,)
        0 gives ``T0``, 1 gives ``T1``.
    """
    T0 = np.asarray(T0, dtype=np.float64)
    T1 = np.asarray(T1, dtype=np.float64)
    alpha = np.asarray(alpha, dtype=np.float64)
    R0 = T0[:, :3, :3]
    rel = np.swapaxes(R0, 1, 2) @ T1[:, :3, :3]
    step = rotation_from_rotvec(rotvec_from_transform(rel) * alpha[:, None])
    t = (1.0 - alpha)[:, None] * T0[:, :3, 3] + alpha[:, None] * T1[:, :3, 3]
    return make_transform(R0 @ step, t)


def pair_in_time(stamps: ArrayLike, T: ArrayLike, query: ArrayLike, *, tolerance: float,
                 offset: float = 0.0) -> Pairing:
    """Motion-capture poses at the query times.

    Parameters
    ----------
    stamps : array_like, shape (M,)
        Motion-capture sample times, seconds, strictly increasing.
    T : array_like, shape (M, 4, 4)
        Motion-capture poses.
    query : array_like, shape (Q,)
        Image times in the camera clock, seconds.
    tolerance : float
        Largest distance in time to the nearest sample, seconds.
    offset : float
        Motion-capture clock minus camera clock, seconds: the query time in the motion-capture
        clock is ``query + offset``.

    Returns
    -------
    Pairing

    Raises
    ------
    InputError
        Arrays of the wrong shape or not real, non-finite stamps or poses, stamps not
        strictly increasing, a tolerance that is not a positive number, an offset that is not
        a finite number within :data:`~multieye.core.limits.MAX_TIME_OFFSET_S`.
    """
    stamps = real_array(stamps, "motion-capture stamps", shape=(None,))
    T = real_array(T, "motion-capture poses T", shape=(len(stamps), 4, 4),
                   expected=f"one 4x4 pose per stamp, shape ({len(stamps)}, 4, 4)")
    query = real_array(query, "image stamps (query)", shape=(None,))
    tolerance = real_number(tolerance, "time tolerance", positive=True)
    offset = real_number(offset, "time offset")
    if abs(offset) > MAX_TIME_OFFSET_S:
        raise InputError(f"time offset must be within {MAX_TIME_OFFSET_S:g} s, got {offset:g} s")
    for what, arr in (("motion-capture stamps", stamps), ("motion-capture poses", T),
                      ("image stamps", query)):
        if not np.isfinite(arr).all():
            raise InputError(f"{what} must be finite, got NaN or inf")
    q = query + offset
    if stamps.size == 0:
        raise InputError("the motion-capture trajectory is empty")
    if np.any(np.diff(stamps) <= 0):
        raise InputError("motion-capture time stamps must be strictly increasing")
    right = np.searchsorted(stamps, q, side="left")          # first sample >= q
    left = right - 1
    has_left = left >= 0
    has_right = right < stamps.size
    li = np.clip(left, 0, stamps.size - 1)
    ri = np.clip(right, 0, stamps.size - 1)
    dl = np.where(has_left, q - stamps[li], np.inf)
    dr = np.where(has_right, stamps[ri] - q, np.inf)
    gap = np.minimum(dl, dr)
    bracket = has_left & has_right & (stamps[ri] - stamps[li] <= 2.0 * tolerance)
    exact = has_right & (dr == 0)
    ok = (gap <= tolerance) | exact
    interp = ok & bracket & ~exact
    nearest = np.where(dl <= dr, li, ri)

    out = T[nearest].copy()
    scale = np.ones(len(q))
    if np.any(interp):
        k = np.flatnonzero(interp)
        alpha = (q[k] - stamps[li[k]]) / (stamps[ri[k]] - stamps[li[k]])
        out[k] = interpolate_poses(T[li[k]], T[ri[k]], alpha)
        scale[k] = np.sqrt(alpha ** 2 + (1.0 - alpha) ** 2)

    unpaired = []
    for i in np.flatnonzero(~ok):
        if stamps.size and (q[i] < stamps[0] or q[i] > stamps[-1]):
            where = "before" if q[i] < stamps[0] else "after"
            why = (f"{where} the motion-capture recording ({stamps[0]:.3f}..{stamps[-1]:.3f} s), "
                   f"nearest sample {gap[i]:.3f} s away"
                   f"{_clock_hint(q[i], float(np.min(q)), stamps)}")
        else:
            why = f"nearest motion-capture sample is {gap[i]:.3f} s away"
        unpaired.append((int(i), why))
    idx = np.flatnonzero(ok)
    return Pairing(index=idx, T=out[idx], gap_s=gap[idx], interpolated=interp[idx],
                   unpaired=tuple(unpaired), noise_scale=scale[idx])
