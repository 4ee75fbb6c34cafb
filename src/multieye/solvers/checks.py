"""Input checks run by every solver before it solves.

Each check raises a subclass of :class:`multieye.CalibrationError` whose message says
what is wrong and what to do about it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import DegenerateMotionError, InputError, TooFewMeasurementsError
from ..geometry import det3
from .kronecker import CameraStats, camera_stats

__all__ = [
    "check_transforms",
    "check_measurements",
    "Measurements",
    "rotation_spread",
    "MIN_MEASUREMENTS",
    "RIGID_TOL",
    "SINGLE_AXIS_TOL_RAD",
    "SINGLE_AXIS_RATIO",
]

#: Fewest measurements a camera needs.
MIN_MEASUREMENTS = 3
#: Largest |R^T R - I| entry, |det R - 1| and bottom-row deviation accepted as rigid.
RIGID_TOL = 1e-5
#: RMS angle (radians) of the relative rotations off their dominant axis below which the
#: motion counts as rotation about a single axis (0.057 degrees: far above rounding).
SINGLE_AXIS_TOL_RAD = 1e-3
#: ... or below this fraction of the RMS rotation about the dominant axis.  Motion-capture
#: and PnP noise alone put 0.05-0.1 degrees off any axis, so an absolute threshold cannot
#: tell a turntable from real motion; a second axis carrying under 2 % of the motion
#: determines the rotation no better than the noise does.
SINGLE_AXIS_RATIO = 0.02
_BOTTOM = np.array([0.0, 0.0, 0.0, 1.0])
_EYE = np.eye(3)


def _is_batch(T) -> bool:
    return type(T) is np.ndarray and T.dtype == np.float64 and T.ndim == 3 and T.shape[1:] == (4, 4)


def _as_batch(T, name: str) -> np.ndarray:
    if _is_batch(T):
        return T
    try:
        T = np.asarray(T, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be an array of 4x4 transforms: {exc}") from None
    if T.ndim == 2 and T.shape == (4, 4):
        T = T[None]
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise InputError(f"{name} must have shape (N, 4, 4), got {T.shape}")
    return T


def _first_bad(T: np.ndarray, R: np.ndarray | None = None):
    """Index of the first non-rigid transform and what is wrong with it, or None.

    ``R`` may pass a contiguous copy of the rotation blocks ``(N, 3, 3)`` already made.
    """
    if not np.isfinite(T).all():
        i = int(np.argmin(np.isfinite(T).all(axis=(1, 2))))
        return i, "it contains NaN or inf; drop that measurement or fix its source"
    if R is None:
        R = np.ascontiguousarray(T[:, :3, :3])
    Rt = np.ascontiguousarray(np.swapaxes(R, 1, 2))   # batched matmul is slow on strided views
    G = Rt @ R
    G -= _EYE
    det = det3(R)
    if (np.abs(G).max() <= RIGID_TOL and np.abs(det - 1.0).max() <= RIGID_TOL
            and (T[:, 3] == _BOTTOM).all()):
        return None
    orth = np.abs(G).max(axis=(1, 2))
    bottom = np.abs(T[:, 3] - _BOTTOM).max(axis=1)
    bad = (orth > RIGID_TOL) | (np.abs(det - 1.0) > RIGID_TOL) | (bottom > RIGID_TOL)
    if not bad.any():
        return None
    i = int(np.argmax(bad))
    if bottom[i] > RIGID_TOL:
        what = f"its bottom row is {T[i, 3].tolist()}, expected [0, 0, 0, 1]"
    elif det[i] < 0:
        what = f"its rotation block has det {det[i]:.6g} (a reflection, often a left-handed frame)"
    else:
        what = (f"its rotation block is not orthonormal (|R^T R - I| = {orth[i]:.3g}, "
                f"det = {det[i]:.6g}); re-orthonormalise it or check the units and element order")
    return i, f"not a rigid transform: {what}"


def check_transforms(T, name: str = "T") -> np.ndarray:
    """Validate and convert a batch of rigid transforms.

    Parameters
    ----------
    T : array_like, shape (N, 4, 4)
    name : str
        How the batch is named in error messages (e.g. ``"A[cam1]"``).

    Returns
    -------
    ndarray, shape (N, 4, 4), float64

    Raises
    ------
    InputError
        Wrong shape, NaN/inf, a rotation block that is not orthonormal with det +1,
        or a bottom row other than (0, 0, 0, 1); the message names the first bad index.
    """
    T = _as_batch(T, name)
    bad = _first_bad(T)
    if bad is not None:
        raise InputError(f"{name}[{bad[0]}]: {bad[1]}")
    return T


def rotation_spread(A: np.ndarray) -> np.ndarray:
    """RMS relative rotation (radians) about the principal axes of ``R_A[k] R_A[0]^T``.

    For a rotation by theta about the unit axis a, ``(R + R^T)/2 - (tr R - 1)/2 I =
    (1 - cos theta) a a^T``.  Summed over the relative rotations this is a 3x3 scatter of
    the rotation axes weighted by ``2 sin^2(theta/2) ~ theta^2 / 2``; the roots of its
    eigenvalues, scaled, are the RMS rotation about each principal axis (exact for small
    angles, saturating at 180 degrees).  A second value near zero means every relative
    rotation shares one axis, so the rotation unknowns are not determined.

    Parameters
    ----------
    A : ndarray, shape (N, 4, 4)

    Returns
    -------
    ndarray, shape (3,)
        Descending, radians.
    """
    R = np.asarray(A, dtype=np.float64)[:, :3, :3]
    C = _axis_scatters(R.sum(axis=0)[None], R[:1], np.array([R.shape[0]]))[0]
    return _spread_from_scatter(C, A.shape[0] - 1)


def _axis_scatters(SA: np.ndarray, R0: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Per-camera axis scatter of ``R_A[k] R_A[first]^T`` (see `rotation_spread`), (m, 3, 3).

    The sum over k of ``sym(R_k R_0^T) - (tr(R_k R_0^T) - 1)/2 I`` is linear in ``R_k``, so it
    is formed from ``SA = sum_k R_k`` and ``R_0`` (the k = 0 term adds zero).

    Parameters
    ----------
    SA : ndarray, shape (m, 3, 3)
    R0 : ndarray, shape (m, 3, 3)
        First rotation of each camera.
    n : ndarray, shape (m,)
        Counts.
    """
    S = SA @ np.ascontiguousarray(np.swapaxes(R0, 1, 2))
    c = (S[:, 0, 0] + S[:, 1, 1] + S[:, 2, 2] - n) / 2.0
    C = (S + np.swapaxes(S, 1, 2)) / 2.0
    C[:, 0, 0] -= c
    C[:, 1, 1] -= c
    C[:, 2, 2] -= c
    return C


def _spread_from_scatter(C: np.ndarray, n: int) -> np.ndarray:
    if n == 0:
        return np.zeros(3)
    lam = np.clip(_sym3_eigvals(C), 0.0, None)
    s = np.sqrt(2.0 * lam / n)
    if s[1] < 10.0 * max(SINGLE_AXIS_TOL_RAD, SINGLE_AXIS_RATIO * s[0]):
        # Near-repeated eigenvalues: the closed form loses digits there; ask LAPACK.
        s = np.sqrt(2.0 * np.clip(np.linalg.eigvalsh(C)[::-1], 0.0, None) / n)
    return s


def _sym3_eigvals(C: np.ndarray) -> np.ndarray:
    """Eigenvalues of one symmetric 3x3 matrix, descending (closed form, trigonometric).

    Plain floats: for one 3x3 matrix this is several times cheaper than LAPACK's call.
    """
    (a, b, c), (_, d, e), (_, _, f) = C.tolist()
    p1 = b * b + c * c + e * e
    q = (a + d + f) / 3.0
    p2 = (a - q) ** 2 + (d - q) ** 2 + (f - q) ** 2 + 2.0 * p1
    if p2 <= 1e-300:
        return np.array([q, q, q])
    p = math.sqrt(p2 / 6.0)
    # det((C - q I) / p) / 2, clipped to [-1, 1]
    a1, d1, f1 = (a - q) / p, (d - q) / p, (f - q) / p
    b1, c1, e1 = b / p, c / p, e / p
    r = (a1 * (d1 * f1 - e1 * e1) - b1 * (b1 * f1 - e1 * c1) + c1 * (b1 * e1 - d1 * c1)) / 2.0
    phi = math.acos(min(1.0, max(-1.0, r))) / 3.0
    l1 = q + 2.0 * p * math.cos(phi)
    l3 = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    return np.array([l1, 3.0 * q - l1 - l3, l3])


@dataclass(frozen=True)
class Measurements:
    """Validated measurements of all cameras, concatenated camera by camera.

    Attributes
    ----------
    A, B : ndarray, shape (N, 4, 4)
    RA, RB : ndarray, shape (N, 3, 3)
        Contiguous copies of the rotation blocks.
    tA, tB : ndarray, shape (N, 3)
        Contiguous copies of the translations, metres.
    camera : ndarray, shape (N,), int
        Camera index of each row.
    counts : ndarray, shape (m,), int
        Measurements per camera.
    starts : ndarray, shape (m,), int
        Index of each camera's first row (for ``np.add.reduceat``).
    names : tuple of str
        Camera names used in messages.
    """

    A: np.ndarray
    B: np.ndarray
    RA: np.ndarray
    RB: np.ndarray
    tA: np.ndarray
    tB: np.ndarray
    camera: np.ndarray
    counts: np.ndarray
    starts: np.ndarray
    names: tuple[str, ...]

    @property
    def m(self) -> int:
        return int(self.counts.size)

    @cached_property
    def stats(self) -> CameraStats:
        """Per-camera sums the closed forms need (formed once, on first use)."""
        return camera_stats(self.RA, self.tA, self.RB, self.tB, self.starts)

    def split(self, arr: np.ndarray) -> list[np.ndarray]:
        """Split a per-row array back into per-camera arrays."""
        return np.split(arr, self.starts[1:])

    @classmethod
    def from_arrays(cls, A: np.ndarray, B: np.ndarray, counts, names=None) -> "Measurements":
        """Build from concatenated arrays ``(N, 4, 4)`` (no checks)."""
        return cls._from_stacked(np.concatenate([A, B]), counts, names)

    @classmethod
    def _from_stacked(cls, AB: np.ndarray, counts, names=None,
                      R: np.ndarray | None = None) -> "Measurements":
        """Build from ``[A; B]`` stacked ``(2N, 4, 4)``, reusing contiguous rotations ``R``."""
        N = AB.shape[0] // 2
        A, B = AB[:N], AB[N:]
        if R is None:
            R = np.ascontiguousarray(AB[:, :3, :3])
        t = np.ascontiguousarray(AB[:, :3, 3])
        counts = np.asarray(counts, dtype=int)
        starts = np.zeros(counts.size, dtype=int)
        np.cumsum(counts[:-1], out=starts[1:])
        names = tuple(names or (f"cam{j}" for j in range(counts.size)))
        return cls(A=A, B=B, RA=R[:N], RB=R[N:], tA=t[:N], tB=t[N:],
                   camera=np.repeat(np.arange(counts.size), counts), counts=counts, starts=starts,
                   names=names)


def check_measurements(A, B, *, names: list[str] | None = None,
                       per_camera_motion: bool = True) -> Measurements:
    """Validate ``A_i^j X^j = Y B_i^j`` input for m cameras.

    Parameters
    ----------
    A, B : sequence of array_like, each shape (N_j, 4, 4)
        One entry per camera (a single (N, 4, 4) array is taken as one camera).
    names : list of str, optional
        Camera names for messages; default ``cam0, cam1, ...``.
    per_camera_motion : bool
        True (single-camera methods): every camera's own motion must rotate about two
        axes.  False (joint methods): the rotation of Y is determined by all cameras
        together, so only the pooled motion must; a camera whose own motion is about
        one axis is still solved through the shared Y.

    Raises
    ------
    InputError
        Not one B per A, mismatched counts, or a bad transform (see `check_transforms`).
    TooFewMeasurementsError
        A camera with fewer than 3 measurements.
    DegenerateMotionError
        Rotations about a single axis (or none at all).
    """
    if isinstance(A, np.ndarray) and A.ndim == 3:
        A = [A]
    if isinstance(B, np.ndarray) and B.ndim == 3:
        B = [B]
    A = list(A)
    B = list(B)
    if len(A) != len(B):
        raise InputError(f"A has {len(A)} cameras but B has {len(B)}; give one B batch per A batch")
    if not A:
        raise InputError("no cameras given: A and B are empty")
    if len(A) >= MIN_MEASUREMENTS and all(np.shape(a) == (4, 4) for a in A):
        raise InputError(f"A is a list of {len(A)} single 4x4 matrices, read as {len(A)} cameras "
                         "with one measurement each; pass one (N, 4, 4) array per camera, e.g. "
                         "solve([np.stack(A)], [np.stack(B)])")
    names = names or [f"cam{j}" for j in range(len(A))]
    As, Bs = [], []
    for j, (Aj, Bj) in enumerate(zip(A, B)):
        if not _is_batch(Aj):
            Aj = _as_batch(Aj, f"A[{names[j]}]")
        if not _is_batch(Bj):
            Bj = _as_batch(Bj, f"B[{names[j]}]")
        if Aj.shape[0] != Bj.shape[0]:
            raise InputError(f"camera {names[j]}: {Aj.shape[0]} A measurements but {Bj.shape[0]} B "
                             "measurements; every A_i needs its B_i")
        if Aj.shape[0] < MIN_MEASUREMENTS:
            raise TooFewMeasurementsError(
                f"camera {names[j]} has {Aj.shape[0]} measurements, at least {MIN_MEASUREMENTS} "
                "are needed; record more target poses for it")
        As.append(Aj)
        Bs.append(Bj)
    counts = [a.shape[0] for a in As]
    N = sum(counts)
    AB = np.concatenate(As + Bs)
    R = np.ascontiguousarray(AB[:, :3, :3])
    meas = Measurements._from_stacked(AB, counts, names, R)
    bad = _first_bad(AB, R)
    if bad is not None:
        i, label = (bad[0], "A") if bad[0] < N else (bad[0] - N, "B")
        j = int(meas.camera[i])
        raise InputError(f"{label}[{names[j]}][{i - meas.starts[j]}]: {bad[1]}")
    C = _axis_scatters(meas.stats.SA, meas.RA[meas.starts], meas.stats.n)
    if per_camera_motion:
        for j in range(meas.m):
            _check_spread(_spread_from_scatter(C[j], counts[j] - 1), f"camera {names[j]}")
    else:
        _check_spread(_spread_from_scatter(C.sum(axis=0), N - meas.m),
                      "the rig (all cameras together)")
    return meas


def _check_spread(s: np.ndarray, who: str) -> None:
    if s[0] < SINGLE_AXIS_TOL_RAD:
        raise DegenerateMotionError(
            f"{who}: the target never rotates (RMS relative rotation {np.degrees(s[0]):.3g} deg); "
            "rotation cannot be determined: tilt the target about two different axes")
    if s[1] < max(SINGLE_AXIS_TOL_RAD, SINGLE_AXIS_RATIO * s[0]):
        raise DegenerateMotionError(
            f"{who}: all rotations are about a single axis (RMS off-axis rotation "
            f"{np.degrees(s[1]):.3g} deg against {np.degrees(s[0]):.3g} deg about the main axis), "
            "so the rotation is not determined: rotate the target about a second axis as well")
