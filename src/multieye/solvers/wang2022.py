"""Method ``wang2022``: the paper's closed form, exactly as published.

Wang, Jiang, Huang, Schwertfeger, Kneip, "Accurate calibration of multi-perspective
cameras from a generalization of the hand-eye constraint", ICRA 2022, sections IV-A, IV-B.

For camera j with ``N_j`` measurements, ``K_j = sum_i R_B ⊗ R_A`` and
``L_j = sum_i R_B^T ⊗ R_A^T``.  Summing the rotation constraint both ways gives

    N_j vec(R_X^j) - L_j vec(R_Y) = 0,     -K_j vec(R_X^j) + N_j vec(R_Y) = 0,

18 rows per camera; stacked, the 18m x 9(m+1) matrix U.  Its right singular vector of the
smallest singular value holds every vec(R_X^j) and vec(R_Y); each 3x3 block is scaled by
``sign(det) |det|^(-1/3)`` and orthonormalised by SVD.  All translations are then solved
jointly from the normal equations of the stacked translation constraints.  The dense SVD
makes this cubic in the number of cameras; ``joint`` computes the same least-squares
problem in linear time.
"""

from __future__ import annotations

import numpy as np

from multieye.core.geometry import make_transform, project_to_so3
from multieye.solvers.measurements import Measurements
from multieye.solvers.kronecker import unvec

__all__ = ["solve_wang2022"]


def _scale_block(M: np.ndarray) -> np.ndarray:
    det = np.linalg.det(M)
    if abs(det) < np.finfo(float).eps:
        return M
    return M * (np.sign(det) * abs(det) ** (-1.0 / 3.0))


def solve_wang2022(meas: Measurements):
    """Solve all cameras and Y with the paper's SVD of U and normal equations.

    Returns
    -------
    X : ndarray, shape (m, 4, 4)
    Y : ndarray, shape (4, 4)
    """
    m = meas.m
    K = meas.stats.K
    L = np.swapaxes(K, 1, 2)  # sum_i R_B^T ⊗ R_A^T = (sum_i R_B ⊗ R_A)^T
    U = np.zeros((18 * m, 9 * (m + 1)))
    eye = np.eye(9)
    for j in range(m):
        nj = float(meas.counts[j])
        r = 18 * j
        U[r:r + 9, 9 * j:9 * j + 9] = nj * eye
        U[r:r + 9, 9 * m:] = -L[j]
        U[r + 9:r + 18, 9 * j:9 * j + 9] = -K[j]
        U[r + 9:r + 18, 9 * m:] = nj * eye
    _, _, Vt = np.linalg.svd(U, full_matrices=False)
    v = Vt[-1]
    blocks = unvec(v.reshape(m + 1, 9))
    R = np.stack([project_to_so3(_scale_block(b)) for b in blocks])
    RX, RY = R[:m], R[m]

    # Translation: rows R_A t_X^j - t_Y = R_Y t_B - t_A, normal equations.
    N = meas.A.shape[0]
    M = np.zeros((3 * N, 3 * (m + 1)))
    rows = np.arange(N)
    for k in range(3):
        for l in range(3):
            M[3 * rows + k, 3 * meas.camera + l] = meas.A[:, k, l]
        M[3 * rows + k, 3 * m + k] = -1.0
    b = (meas.B[:, :3, 3] @ RY.T - meas.A[:, :3, 3]).reshape(-1)
    t = np.linalg.solve(M.T @ M, M.T @ b)
    tX = t[:3 * m].reshape(m, 3)
    tY = t[3 * m:]
    return make_transform(RX, tX), make_transform(RY, tY)
