"""Input checks run by every solver before it solves.

Each check raises a subclass of :class:`multieye.CalibrationError` whose message says
what is wrong and what to do about it.
"""

from __future__ import annotations

import math
from itertools import accumulate

import numpy as np

from multieye.core.arguments import camera_names, real_array
from multieye.core.errors import DegenerateMotionError, InputError, TooFewMeasurementsError
from multieye.core.geometry import det3
from multieye.solvers.kronecker import BOTTOM_ROWS, sym3_eigvals, transform_entries
# Measurements and MIN_MEASUREMENTS live in solvers/measurements.py; named here too, since
# the checks return them and callers import them from here
from multieye.solvers.measurements import MIN_MEASUREMENTS, Measurements, default_names

__all__ = [
    "check_transforms",
    "check_measurements",
    "check_motion",
    "given_measurements",
    "Measurements",
    "rotation_spread",
    "MIN_MEASUREMENTS",
    "RIGID_TOL",
    "MAX_TRANSLATION",
    "SINGLE_AXIS_TOL_RAD",
    "SINGLE_AXIS_RATIO",
]

#: Largest |R^T R - I| entry, |det R - 1| and bottom-row deviation accepted as rigid.
RIGID_TOL = 1e-5
#: Largest translation coordinate accepted (metres): far beyond any rig, and small enough
#: that sums of products of translations over many measurements cannot overflow.
MAX_TRANSLATION = 1e100
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
    T = real_array(T, name, expected="an array of 4x4 transforms, shape (N, 4, 4)")
    if T.ndim == 2 and T.shape == (4, 4):
        T = T[None]
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise InputError(f"{name} must have shape (N, 4, 4), got {T.shape}")
    return T


def _first_bad(T: np.ndarray):
    """Index of the first non-rigid transform of ``T`` (N, 4, 4) and what is wrong, or None.

    This is the definition of rigid used everywhere: finite, ``|R^T R - I|``,
    ``|det R - 1|`` and the bottom row's deviation from (0, 0, 0, 1) all within
    :data:`RIGID_TOL`, and no translation coordinate over :data:`MAX_TRANSLATION`.
    """
    if not np.isfinite(T).all():
        i = int(np.argmin(np.isfinite(T).all(axis=(1, 2))))
        return i, "it contains NaN or inf; drop that measurement or fix its source"
    R = np.ascontiguousarray(T[:, :3, :3])
    Rt = np.ascontiguousarray(np.swapaxes(R, 1, 2))   # batched matmul is slow on strided views
    G = Rt @ R
    G -= _EYE
    det = det3(R)
    t = np.abs(T[:, :3, 3]).max(axis=1)
    if (np.abs(G).max() <= RIGID_TOL and np.abs(det - 1.0).max() <= RIGID_TOL
            and (T[:, 3] == _BOTTOM).all() and t.max() <= MAX_TRANSLATION):
        return None
    orth = np.abs(G).max(axis=(1, 2))
    bottom = np.abs(T[:, 3] - _BOTTOM).max(axis=1)
    bad = ((orth > RIGID_TOL) | (np.abs(det - 1.0) > RIGID_TOL) | (bottom > RIGID_TOL)
           | (t > MAX_TRANSLATION))
    if not bad.any():
        return None
    i = int(np.argmax(bad))
    if t[i] > MAX_TRANSLATION:
        return i, (f"its translation reaches {t[i]:.3g}, beyond the {MAX_TRANSLATION:.0e} the "
                   "solvers' sums can hold; give translations in metres")
    if bottom[i] > RIGID_TOL:
        what = f"its bottom row is {T[i, 3].tolist()}, expected [0, 0, 0, 1]"
    elif det[i] < 0:
        what = f"its rotation block has det {det[i]:.6g} (a reflection, often a left-handed frame)"
    else:
        what = (f"its rotation block is not orthonormal (|R^T R - I| = {orth[i]:.3g}, "
                f"det = {det[i]:.6g}); re-orthonormalise it or check the units and element order")
    return i, f"not a rigid transform: {what}"


#: Rows of :func:`transform_entries` giving ``E[i, j] = R[i % 3, j % 3]`` for i, j < 5, so
#: that every cofactor of R is a product of two shifted 3x3 windows of E.
_PERIODIC = np.array([4 * (i % 3) + (j % 3) for i in range(5) for j in range(5)])
#: Transforms per pass of `_surely_rigid` (its temporaries, 25 rows of this, stay in cache).
_RIGID_CHUNK = 4096


def _surely_rigid(entries: np.ndarray) -> bool:
    """Cheap sufficient test that every transform passes `_first_bad`.

    Let ``D = cof(R) - R``, with cof the cofactor matrix.  From the singular values of R,
    ``D`` is small only near SO(3) or near zero (a reflection's D is at least its scale), and
    near SO(3) ``|det R - 1| <= sqrt(3) |D|_F`` to first order.  ``R^T cof(R) = det(R) I``
    gives ``R^T R - I = (det R - 1) I - R^T D``.  So when the sum over all transforms of
    ``|D|_F^2`` is at most ``(tol / 5)^2``, every transform has ``|det R - 1| <= 0.35 tol``
    and ``|R^T R - I| <= 0.7 tol``, or is near zero; and the sum of the determinants, at least
    ``n - 1/2``, rules out any near-zero one: each would take 1 from it, and the others'
    errors add up to at most ``0.35 tol sqrt(n)``, under 1/2 for n < 2e10 transforms at
    ``tol = 1e-5``.  The bottom row must be exactly (0, 0, 0, 1), and the sum of the squared
    translations at most :data:`MAX_TRANSLATION` squared.  NaN and inf fail.  False only
    means: look closer, with `_first_bad`.  About 50 microseconds per thousand transforms.

    Parameters
    ----------
    entries : ndarray, shape (16, n)
        :func:`multieye.solvers.kronecker.transform_entries` of the transforms.
    """
    n = entries.shape[1]
    dd = det_sum = t_ss = 0.0
    exact_bottom = True
    with np.errstate(all="ignore"):              # inf and NaN just fail the test
        for a in range(0, n, _RIGID_CHUNK):      # chunks keep the temporaries in cache
            rows = entries[:, a:a + _RIGID_CHUNK]
            k = rows.shape[1]
            E = rows[_PERIODIC].reshape(5, 5, k)
            D = E[1:4, 1:4] * E[2:5, 2:5]
            D -= E[1:4, 2:5] * E[2:5, 1:4]                       # cofactors of R, (3, 3, k)
            det_sum += E[0, :3].reshape(-1) @ D[0].reshape(-1)   # first-row expansions
            D -= E[:3, :3]
            d = D.reshape(-1)
            dd += d @ d
            exact_bottom = exact_bottom and not (rows[12:] != BOTTOM_ROWS).any()
            t = rows[3:12:4]
            t_ss += np.einsum("ij,ij->", t, t)
    return bool(dd <= (RIGID_TOL / 5) ** 2 and det_sum >= n - 0.5 and exact_bottom
                and t_ss <= MAX_TRANSLATION ** 2)


def _first_bad_place(AB: np.ndarray, counts: list[int]) -> tuple[str, int, int, str] | None:
    """Where the first bad transform of ``[A; B]`` is: ``("A" or "B", camera index, index in
    the camera, what is wrong)``, or None when all are rigid."""
    bad = _first_bad(AB)
    if bad is None:
        return None
    N = AB.shape[0] // 2
    i, label = (bad[0], "A") if bad[0] < N else (bad[0] - N, "B")
    j = 0
    while i >= counts[j]:
        i -= counts[j]
        j += 1
    return label, j, i, bad[1]


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
        Wrong shape, NaN/inf, a rotation block that is not orthonormal with det +1, a
        bottom row other than (0, 0, 0, 1), or a translation over :data:`MAX_TRANSLATION`;
        the message names the first bad index.
    """
    T = _as_batch(T, name)
    if _surely_rigid(transform_entries(T)):
        return T
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
    C = _scatter_from_sum(R.sum(axis=0) @ R[0].T, R.shape[0])
    return np.array(_spread_from_scatter(C, R.shape[0] - 1))


def _scatter_from_sum(S: np.ndarray, n: int) -> tuple[float, ...]:
    """Axis scatter of n rotations ``R_k`` relative to ``R_0`` from ``S = sum_k R_k R_0^T``.

    The sum over k of ``sym(R_k R_0^T) - (tr(R_k R_0^T) - 1)/2 I`` (see `rotation_spread`) is
    linear in ``R_k``, so it is formed from the sum alone (the k = 0 term adds zero).

    Returns its six distinct entries ``(C00, C01, C02, C11, C12, C22)`` as plain floats.
    """
    (a, b, c), (d, e, f), (g, h, i) = S.tolist()
    k = (a + e + i - n) / 2.0
    return a - k, (b + d) / 2.0, (c + g) / 2.0, e - k, (f + h) / 2.0, i - k


def _spread_from_scatter(C: tuple[float, ...], n: int) -> list[float]:
    """RMS rotation about each principal axis (radians, descending) from an axis scatter.

    ``C`` holds the six distinct entries of the symmetric 3x3 scatter (`_scatter_from_sum`);
    ``n`` is the number of relative rotations.
    """
    if n == 0:
        return [0.0, 0.0, 0.0]
    s = [math.sqrt(2.0 * max(lam, 0.0) / n) for lam in sym3_eigvals(*C)]
    if s[1] < 10.0 * max(SINGLE_AXIS_TOL_RAD, SINGLE_AXIS_RATIO * s[0]):
        # Near-repeated eigenvalues: the closed form loses digits there; ask LAPACK.
        c00, c01, c02, c11, c12, c22 = C
        M = np.array([[c00, c01, c02], [c01, c11, c12], [c02, c12, c22]])
        s = np.sqrt(2.0 * np.clip(np.linalg.eigvalsh(M)[::-1], 0.0, None) / n).tolist()
    return s


def check_measurements(A, B, *, names: list[str] | None = None,
                       per_camera_motion: bool = True) -> Measurements:
    """Validate ``A_i^j X^j = Y B_i^j`` input for m cameras.

    Parameters
    ----------
    A, B : sequence of array_like, each shape (N_j, 4, 4)
        One entry per camera (a single (N, 4, 4) array is taken as one camera); or ``A`` is
        :class:`Measurements` validated before and ``B`` is omitted: returned as they are
        (no check runs again, not even the motion's: :func:`check_motion`).
    names : list of str, optional
        Camera names for messages; default ``cam0, cam1, ...``.
    per_camera_motion : bool
        True (single-camera methods): every camera's own motion must rotate about two
        axes.  False (joint methods): the rotation of Y is determined by all cameras
        together, so only the pooled motion must; a camera whose own motion is about
        one axis is still solved through the shared Y.

    Returns
    -------
    Measurements
        With bottom rows set exactly to (0, 0, 0, 1) where they were within tolerance.

    Raises
    ------
    InputError
        Not one B per A, mismatched counts, or a bad transform (see `check_transforms`).
    TooFewMeasurementsError
        A camera with fewer than 3 measurements.
    DegenerateMotionError
        Rotations about a single axis (or none at all).
    """
    if isinstance(A, Measurements):
        meas = given_measurements(A, B)
        if names is not None and tuple(names) != meas.names:
            raise InputError(f"names {list(names)} differ from the measurements' names "
                             f"{list(meas.names)}")
        return meas
    if A is None:
        raise InputError("A is None: give one (N, 4, 4) array of transforms per camera")
    if B is None:
        raise InputError("B is missing: give one B batch per A batch")
    if names is not None:
        m = _camera_count(A)
        names = list(camera_names(names, m if m is not None else
                                  len(names) if hasattr(names, "__len__") else 0))
    if isinstance(A, np.ndarray) and A.ndim == 3:
        A = [A]
    if isinstance(B, np.ndarray) and B.ndim == 3:
        B = [B]
    for label, arg in (("A", A), ("B", B)):
        if isinstance(arg, (str, bytes, dict, set)) or not hasattr(arg, "__len__"):
            raise InputError(f"{label} must be a list with one (N, 4, 4) array of transforms "
                             f"per camera, got {type(arg).__name__}")
    A = list(A)
    B = list(B)
    m = len(A)
    if m != len(B):
        raise InputError(f"A has {m} cameras but B has {len(B)}; give one B batch per A batch")
    if not A:
        raise InputError("no cameras given: A and B are empty")
    if m >= MIN_MEASUREMENTS and not _is_batch(A[0]) and all(np.shape(a) == (4, 4) for a in A):
        raise InputError(f"A is a list of {m} single 4x4 matrices, read as {m} cameras "
                         "with one measurement each; pass one (N, 4, 4) array per camera, e.g. "
                         "solve([np.stack(A)], [np.stack(B)])")
    names = tuple(names) if names else default_names(m)
    counts = []
    for j in range(m):
        Aj, Bj = A[j], B[j]
        if not _is_batch(Aj):
            A[j] = Aj = _as_batch(Aj, f"A[{names[j]}]")
        if not _is_batch(Bj):
            B[j] = Bj = _as_batch(Bj, f"B[{names[j]}]")
        n = Aj.shape[0]
        if n != Bj.shape[0]:
            raise InputError(f"camera {names[j]}: {n} A measurements but {Bj.shape[0]} B "
                             "measurements; every A_i needs its B_i")
        if n < MIN_MEASUREMENTS:
            raise TooFewMeasurementsError(
                f"camera {names[j]} has {n} measurements, at least {MIN_MEASUREMENTS} "
                "are needed; record more target poses for it")
        counts.append(n)
    entries = transform_entries(*A, *B)
    if not _surely_rigid(entries):
        bad = _first_bad_place(entries.T.reshape(-1, 4, 4), counts)
        if bad is not None:
            raise InputError(f"{bad[0]}[{names[bad[1]]}][{bad[2]}]: {bad[3]}")
        entries[12:] = BOTTOM_ROWS       # within tolerance of (0, 0, 0, 1): make it exact
    meas = Measurements(entries=entries, counts=np.array(counts), names=names)
    check_motion(meas, per_camera_motion=per_camera_motion)
    return meas


def check_motion(meas: Measurements, *, per_camera_motion: bool = True) -> None:
    """The motion test of :func:`check_measurements`, for measurements already validated.

    Parameters
    ----------
    meas : Measurements
    per_camera_motion : bool
        As for :func:`check_measurements`.

    Raises
    ------
    DegenerateMotionError
        Rotations about a single axis (or none at all).
    """
    counts = [int(c) for c in meas.counts]
    m, N = len(counts), sum(counts)
    starts = [0, *accumulate(counts[:-1])]
    R0 = meas.entries[:12, starts].reshape(3, 4, m)[:, :3]   # R0[c, b, j]: first R_A of camera j
    if per_camera_motion:
        S = np.einsum("jab,cbj->jac", meas.stats.SA, R0)      # SA_j R0_j^T, camera by camera
        for j in range(m):
            _check_spread(_spread_from_scatter(_scatter_from_sum(S[j], counts[j]),
                                               counts[j] - 1), f"camera {meas.names[j]}")
    else:
        S = np.einsum("jab,cbj->ac", meas.stats.SA, R0)       # sum_j SA_j R0_j^T
        _check_spread(_spread_from_scatter(_scatter_from_sum(S, N), N - m),
                      "the rig (all cameras together)")


def _camera_count(A) -> int | None:
    """The number of cameras of ``A`` as :func:`check_measurements` reads it (a single
    (N, 4, 4) array is one camera), or None when ``A`` has no length."""
    if isinstance(A, Measurements):
        return A.m
    if isinstance(A, np.ndarray) and A.ndim == 3:
        return 1
    try:
        return len(A)
    except TypeError:
        return None


def given_measurements(meas: Measurements, B=None) -> Measurements:
    """``meas`` as passed in place of ``A, B`` to a function that takes either (no new
    checks).

    Raises
    ------
    InputError
        ``B`` given as well.
    """
    if B is not None:
        raise InputError("give either validated Measurements or A and B, not both")
    return meas


def _check_spread(s: list[float], who: str) -> None:
    if s[0] < SINGLE_AXIS_TOL_RAD:
        raise DegenerateMotionError(
            f"{who}: the target never rotates (RMS relative rotation {np.degrees(s[0]):.3g} deg); "
            "rotation cannot be determined: tilt the target about two different axes")
    if s[1] < max(SINGLE_AXIS_TOL_RAD, SINGLE_AXIS_RATIO * s[0]):
        raise DegenerateMotionError(
            f"{who}: all rotations are about a single axis (RMS off-axis rotation "
            f"{np.degrees(s[1]):.3g} deg against {np.degrees(s[0]):.3g} deg about the main axis), "
            "so the rotation is not determined: rotate the target about a second axis as well")
