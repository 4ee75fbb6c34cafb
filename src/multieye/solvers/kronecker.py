"""Kronecker forms of the constraint and the per-camera sufficient statistics.

Vectorisation is column-major, ``vec(M) = M.T.reshape(9)``, so that
``vec(R_A R_X R_B^T) = (R_B ⊗ R_A) vec(R_X)`` (paper section IV-A): the rotation part of
``A_i X = Y B_i`` reads ``(R_B ⊗ R_A) vec(R_X) = vec(R_Y)``.  Its translation part reads
``R_A t_X - t_Y = R_Y t_B - t_A``, and ``R_A^T R_Y t_B = (t_B^T ⊗ R_A^T) vec(R_Y)``.

Every closed form here needs only a few sums over each camera's measurements
(:class:`CameraStats`), formed in one pass; everything after that costs O(m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import det3, project_to_so3

__all__ = [
    "vec",
    "unvec",
    "normalize_rotation",
    "CameraStats",
    "camera_stats",
    "solve_translations",
]

def vec(R: np.ndarray) -> np.ndarray:
    """Column-major vectorisation of ``(..., 3, 3)`` into ``(..., 9)``."""
    return np.swapaxes(R, -1, -2).reshape(R.shape[:-2] + (9,))


def unvec(v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`vec`: ``(..., 9)`` into ``(..., 3, 3)``."""
    v = np.asarray(v)
    return np.swapaxes(v.reshape(v.shape[:-1] + (3, 3)), -1, -2)


def normalize_rotation(M: np.ndarray) -> np.ndarray:
    """Rotation from an estimate known up to scale and sign.

    Scales each 3x3 block by ``sign(det)``, then projects onto SO(3) by SVD
    (paper section IV-A; the positive ``|det|^(-1/3)`` factor does not change the
    projection and is left out).

    Parameters
    ----------
    M : ndarray, shape (..., 3, 3)
    """
    d = np.where(det3(M) < 0, -1.0, 1.0)
    return project_to_so3(M * d[..., None, None])


@dataclass(frozen=True)
class CameraStats:
    """Per-camera sums over measurements i of camera j (all arrays lead with m).

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
    """

    n: np.ndarray
    K: np.ndarray
    G: np.ndarray
    h: np.ndarray
    SA: np.ndarray
    StA: np.ndarray
    StB: np.ndarray


def camera_stats(RA: np.ndarray, tA: np.ndarray, RB: np.ndarray, tB: np.ndarray,
                 starts: np.ndarray) -> CameraStats:
    """Form :class:`CameraStats` in one pass over the measurements.

    Parameters
    ----------
    RA, RB : ndarray, shape (N, 3, 3)
        Contiguous rotation blocks of A and B, camera by camera.
    tA, tB : ndarray, shape (N, 3)
        Translations, metres.
    starts : ndarray, shape (m,)
        First row of each camera.
    """
    N = RA.shape[0]
    # Every sum is a block of sum_i l_i r_i^T with l = (vec_r R_B, t_B, t_A, 1) and
    # r = (vec_r R_A, t_A, t_B) (row-major vec_r): one small product per camera.
    left = np.empty((N, 16))
    left[:, :9] = RB.reshape(N, 9)
    left[:, 9:12] = tB
    left[:, 12:15] = tA
    left[:, 15] = 1.0
    right = np.empty((N, 15))
    right[:, :9] = RA.reshape(N, 9)
    right[:, 9:12] = tA
    right[:, 12:15] = tB
    ends = np.append(starts[1:], N)
    M = np.stack([left[a:b].T @ right[a:b] for a, b in zip(starts, ends)])     # (m, 16, 15)
    m = M.shape[0]
    # (R_B ⊗ R_A)[3p + r, 3q + s] = R_B[p, q] R_A[r, s]
    K = M[:, :9, :9].reshape(m, 3, 3, 3, 3).transpose(0, 1, 3, 2, 4).reshape(m, 9, 9)
    # (t_B^T ⊗ R_A^T)[r, 3k + s] = t_B[k] R_A[s, r]
    G = M[:, 9:12, :9].reshape(m, 3, 3, 3).transpose(0, 3, 1, 2).reshape(m, 3, 9)
    # (R_A^T t_A)[r] = sum_s t_A[s] R_A[s, r]: the diagonal s = s' of sum t_A[s'] R_A[s, r]
    TR = M[:, 12:15, :9].reshape(m, 3, 3, 3)
    h = TR[:, 0, 0] + TR[:, 1, 1] + TR[:, 2, 2]
    n = (ends - starts).astype(np.float64)
    return CameraStats(n=n, K=K, G=G, h=h, SA=M[:, 15, :9].reshape(m, 3, 3),
                       StA=M[:, 15, 9:12], StB=M[:, 15, 12:15])


def solve_translations(stats: CameraStats, RY: np.ndarray):
    """Least-squares translations of all cameras and of Y, given ``R_Y``.

    Minimises ``sum_j sum_i ||R_A t_X^j + t_A - R_Y t_B - t_Y||^2``.  With
    ``c_i = R_Y t_B - t_A``, ``P_j = sum_i R_A^T``, ``q_j = sum_i R_A^T c_i`` and
    ``s_j = sum_i c_i``, the per-camera unknowns are eliminated in closed form,
    ``t_X^j = (P_j t_Y + q_j) / n_j``, leaving the 3x3 system
    ``(sum_j n_j I - P_j^T P_j / n_j) t_Y = sum_j (P_j^T q_j / n_j - s_j)``.

    Returns
    -------
    tX : ndarray, shape (m, 3)
    tY : ndarray, shape (3,)
    """
    n = stats.n
    q = stats.G @ vec(RY) - stats.h
    s = stats.StB.sum(axis=0) @ RY.T - stats.StA.sum(axis=0)
    rn = 1.0 / np.sqrt(n)
    Scat = (stats.SA * rn[:, None, None]).transpose(1, 0, 2).reshape(3, -1)  # P_j = SA_j^T
    M = n.sum() * np.eye(3) - Scat @ Scat.T
    rhs = Scat @ (q * rn[:, None]).reshape(-1) - s
    tY = np.linalg.solve(M, rhs)
    tX = (tY @ stats.SA + q) / n[:, None]
    return tX, tY
