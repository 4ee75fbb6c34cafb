"""Kronecker forms of the constraint and the per-camera sufficient statistics.

Vectorisation is column-major, ``vec(M) = M.T.reshape(9)``, so that
``vec(R_A R_X R_B^T) = (R_B ⊗ R_A) vec(R_X)`` (paper section IV-A): the rotation part of
``A_i X = Y B_i`` reads ``(R_B ⊗ R_A) vec(R_X) = vec(R_Y)``.  Its translation part reads
``R_A t_X - t_Y = R_Y t_B - t_A``, and ``R_A^T R_Y t_B = (t_B^T ⊗ R_A^T) vec(R_Y)``.

Every closed form here needs only a few sums over each camera's measurements
(:class:`CameraStats`), formed in one pass; everything after that costs O(m).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.linalg import lapack

from multieye.core.errors import DegenerateMotionError
from multieye.core.geometry import det3

__all__ = [
    "vec",
    "unvec",
    "normalize_rotation",
    "CameraStats",
    "camera_stats",
    "transform_entries",
    "solve_translations",
]


_EYE3 = np.eye(3)
#: Rows 12-15 of :func:`transform_entries` for exact homogeneous transforms.
BOTTOM_ROWS = np.array([[0.0], [0.0], [0.0], [1.0]])
#: Smallest eigenvalue of a translation system, relative to its largest, below which the
#: translations count as undetermined.
TRANSLATION_RCOND = 1e-10


def vec(R: np.ndarray) -> np.ndarray:
    """Column-major vectorisation of ``(..., 3, 3)`` into ``(..., 9)``."""
    return np.swapaxes(R, -1, -2).reshape(R.shape[:-2] + (9,))


def unvec(v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`vec`: ``(..., 9)`` into ``(..., 3, 3)``."""
    v = np.asarray(v)
    return np.swapaxes(v.reshape(v.shape[:-1] + (3, 3)), -1, -2)


def normalize_rotation(M: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Rotation from an estimate known up to scale and sign.

    The paper (section IV-A) scales each 3x3 block by ``sign(det) |det|^(-1/3)`` and
    projects it onto SO(3) by SVD.  The positive factor does not change the projection, and
    for ``M = U S V^T`` the sign of ``det M`` is ``det(U V^T)`` (``S >= 0``), so one SVD gives
    both: the result is ``det(U V^T) U V^T``, which is the nearest rotation to
    ``sign(det M) M`` whenever ``det M != 0`` (and a rotation in every case).

    Parameters
    ----------
    M : ndarray, shape (..., 3, 3)
    out : ndarray, shape (..., 3, 3), optional
        Where to write the result (it may be a view, such as the rotation blocks of
        transforms).

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    U, _, Vt = np.linalg.svd(M)
    R = np.matmul(U, Vt, out=out)
    R *= np.copysign(1.0, det3(R))[..., None, None]
    return R


class CameraStats(NamedTuple):
    """Per-camera sums over measurements i of camera j (all arrays lead with m).

    An immutable record (a named tuple: formed on every solve, it must cost nothing).

    Attributes
    ----------
    n : ndarray, shape (m,)
        Measurement counts, float.
    K : ndarray, shape (m, 9, 9)
        ``sum_i R_B ⊗ R_A`` (paper section IV-A).
    G : ndarray, shape (m, 3, 9)
        ``sum_i t_B^T ⊗ R_A^T``, so that ``sum_i R_A^T R_Y t_B = G vec(R_Y)``.
    h : ndarray, shape (m, 3)
        ``sum_i R_A^T t_A``.
    SA : ndarray, shape (m, 3, 3)
        ``sum_i R_A``.
    StA, StB : ndarray, shape (m, 3)
        ``sum_i t_A``, ``sum_i t_B``.
    totals : ndarray, shape (7,)
        Over all cameras: ``sum t_A`` (3), ``sum t_B`` (3), the number of measurements.
    """

    n: np.ndarray
    K: np.ndarray
    G: np.ndarray
    h: np.ndarray
    SA: np.ndarray
    StA: np.ndarray
    StB: np.ndarray
    totals: np.ndarray


def transform_entries(*batches: np.ndarray, exact_bottom: bool = False) -> np.ndarray:
    """Entries of transforms as rows: batches ``(N_k, 4, 4)`` to C-contiguous ``(16, sum N_k)``.

    Row ``4 r + c`` holds entry (r, c) of every transform, in the order given (A's batches,
    then B's).  In this layout the per-measurement arithmetic of the checks runs along long
    contiguous rows, and for ``[A; B]`` ``reshape(32, N)`` interleaves A's and B's entries
    (row ``2 k`` is entry k of A, row ``2 k + 1`` entry k of B) as the per-camera
    products of :func:`camera_stats` want.  ``exact_bottom`` sets every bottom row to
    exactly (0, 0, 0, 1), which :func:`camera_stats` relies on (for transforms already known
    to be rigid).
    """
    out = np.empty((16, sum(T.shape[0] for T in batches)))    # C order: rows contiguous
    np.concatenate([T.reshape(T.shape[0], 16).T for T in batches], axis=1, out=out)
    if exact_bottom:
        out[12:] = BOTTOM_ROWS
    return out


def _stat_columns() -> np.ndarray:
    """Where each statistic sits in ``M = sum_i [a_i; b_i] a_i^T``, flattened ``(32 * 16,)``.

    ``a_i``, ``b_i`` are the 16 entries of ``A_i``, ``B_i`` (entry (r, c) at ``4 r + c``),
    interleaved: row ``2 k`` of M is A's entry k, row ``2 k + 1`` B's.  The bottom-right
    entries (15) are exactly 1 and serve as the constant.
    Order: K (81), G (27), h (9, summed in threes), SA (9), StA (3), StB (3), n (1).
    """
    def at(b_row: bool, r: int, c: int, a_r: int, a_c: int) -> int:
        return (2 * (4 * r + c) + b_row) * 16 + 4 * a_r + a_c

    K = [at(True, p, q, r, s) for p in range(3) for r in range(3)    # row 3p + r
         for q in range(3) for s in range(3)]                         # col 3q + s
    G = [at(True, k, 3, s, r) for r in range(3) for k in range(3) for s in range(3)]
    h = [at(False, s, 3, s, r) for r in range(3) for s in range(3)]
    SA = [at(True, 3, 3, r, s) for r in range(3) for s in range(3)]
    StA = [at(True, 3, 3, r, 3) for r in range(3)]
    StB = [at(True, r, 3, 3, 3) for r in range(3)]
    return np.array(K + G + h + SA + StA + StB + [at(True, 3, 3, 3, 3)])


_STAT_COLUMNS = _stat_columns()


def camera_stats(entries: np.ndarray, counts: list[int]) -> CameraStats:
    """Form :class:`CameraStats` in one pass over the measurements.

    Every statistic is an entry of ``sum_i [a_i; b_i] a_i^T`` over a camera's measurements,
    with ``a_i``, ``b_i`` the 16 entries of ``A_i`` and ``B_i``: one matrix product per
    camera (one batched product when all cameras have the same count), then one gather.

    Parameters
    ----------
    entries : ndarray, shape (16, 2N)
        :func:`transform_entries` of ``[A; B]``, each concatenated camera by camera, with
        bottom rows exactly (0, 0, 0, 1) (their last entry serves as the constant 1).
    counts : list of int, length m
        Measurements per camera.
    """
    m, N = len(counts), entries.shape[1] // 2
    L = entries.reshape(32, N)          # row 2k: entry k of A_i; row 2k + 1: entry k of B_i
    FA = L[0::2]                        # (16, N): the entries of A_i
    if m > 1 and counts.count(counts[0]) == m:
        c = counts[0]
        M = np.matmul(L.reshape(32, m, c).transpose(1, 0, 2),
                      FA.reshape(16, m, c).transpose(1, 2, 0))
    else:
        M = np.empty((m, 32, 16))
        a = 0
        for j, c in enumerate(counts):
            np.dot(L[:, a:a + c], FA[:, a:a + c].T, out=M[j])
            a += c
    s = M.reshape(m, 512)[:, _STAT_COLUMNS]
    return CameraStats(n=s[:, 132], K=s[:, :81].reshape(m, 9, 9),
                       G=s[:, 81:108].reshape(m, 3, 9),
                       h=s[:, 108:117].reshape(m, 3, 3).sum(axis=2),
                       SA=s[:, 117:126].reshape(m, 3, 3), StA=s[:, 126:129], StB=s[:, 129:132],
                       totals=s[:, 126:133].sum(axis=0))


def solve_translations(stats: CameraStats, RY: np.ndarray, out: np.ndarray | None = None):
    """Least-squares translations of all cameras and of Y, given ``R_Y``.

    Minimises ``sum_j sum_i ||R_A t_X^j + t_A - R_Y t_B - t_Y||^2``.  With
    ``c_i = R_Y t_B - t_A``, ``P_j = sum_i R_A^T = SA_j^T``, ``q_j = sum_i R_A^T c_i`` and
    ``s_j = sum_i c_i``, the per-camera unknowns are eliminated in closed form,
    ``t_X^j = (P_j t_Y + q_j) / n_j``, leaving the 3x3 system
    ``(sum_j n_j I - SA_j SA_j^T / n_j) t_Y = sum_j (SA_j q_j / n_j - s_j)``.

    Parameters
    ----------
    stats : CameraStats
    RY : ndarray, shape (3, 3)
    out : ndarray, shape (m + 1, 3), optional
        Where to write ``tX`` (first m rows) and ``tY`` (last row); it may be a view.

    Returns
    -------
    tX : ndarray, shape (m, 3)
    tY : ndarray, shape (3,)

    Raises
    ------
    DegenerateMotionError
        The 3x3 system is singular: the target never rotates relative to the cameras.
    """
    n, tot = stats.n, stats.totals
    q = stats.G @ RY.T.reshape(9)                     # G vec(R_Y) - h = sum_i R_A^T c_i
    q -= stats.h
    Wn = stats.SA / n[:, None, None]
    M = tot[6] * _EYE3 - np.einsum("jab,jcb->ac", Wn, stats.SA)
    (a, b, c), (_, d, e), (_, _, f) = M.tolist()         # plain floats: cheaper arithmetic
    lam = sym3_eigvals(a, b, c, d, e, f)
    if not lam[2] > TRANSLATION_RCOND * lam[0]:
        raise DegenerateMotionError("the translations are not determined: the target never "
                                    "rotates relative to the cameras about two axes")
    rhs = np.einsum("jab,jb->a", Wn, q) - RY @ tot[3:6] + tot[0:3]
    _, _, tY, _ = lapack.dgesv(M, rhs)        # LAPACK directly: numpy.linalg.solve costs 5x
    m = n.shape[0]
    if out is None:
        out = np.empty((m + 1, 3))
    tX = np.matmul(tY, stats.SA, out=out[:m])
    tX += q
    tX /= n[:, None]
    out[m] = tY
    return tX, out[m]


def sym3_eigvals(a: float, b: float, c: float, d: float, e: float,
                 f: float) -> tuple[float, float, float]:
    """Eigenvalues of the symmetric matrix [[a, b, c], [b, d, e], [c, e, f]], descending.

    Closed form (trigonometric), in plain floats: for one 3x3 matrix this is several
    times cheaper than LAPACK's call.  Absolute error a few ulps of the largest eigenvalue,
    except for near-repeated eigenvalues, where it may grow to the square root of that.
    """
    p1 = b * b + c * c + e * e
    q = (a + d + f) / 3.0
    p2 = (a - q) ** 2 + (d - q) ** 2 + (f - q) ** 2 + 2.0 * p1
    if p2 <= 1e-300:
        return q, q, q
    p = math.sqrt(p2 / 6.0)
    # det((C - q I) / p) / 2, clipped to [-1, 1]
    a1, d1, f1 = (a - q) / p, (d - q) / p, (f - q) / p
    b1, c1, e1 = b / p, c / p, e / p
    r = (a1 * (d1 * f1 - e1 * e1) - b1 * (b1 * f1 - e1 * c1) + c1 * (b1 * e1 - d1 * c1)) / 2.0
    phi = math.acos(min(1.0, max(-1.0, r))) / 3.0
    l1 = q + 2.0 * p * math.cos(phi)
    l3 = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    return l1, 3.0 * q - l1 - l3, l3
