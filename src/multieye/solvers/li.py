"""Method ``li``: Li, Wang and Wu (2010), one camera at a time.

A. Li, L. Wang, D. Wu, "Simultaneous robot-world and hand-eye calibration using
dual-quaternions and Kronecker product", International Journal of the Physical Sciences 5,
1530-1536, 2010; computed as OpenCV 4.x ``calibrateRobotWorldHandEye(...,
CALIB_ROBOT_WORLD_HAND_EYE_LI)`` does.  With row-major vectorisation ``vec_r``, every
measurement gives 12 rows of one linear system in 24 unknowns
``(vec_r R_X, vec_r R_Y, t_X, t_Y)``:

    (R_A ⊗ I) vec_r R_X - (I ⊗ R_B^T) vec_r R_Y = 0
    (I ⊗ t_B^T) vec_r R_Y - R_A t_X + t_Y = t_A

solved in the least-squares sense (SVD); the rotation blocks are then normalised by their
determinant and projected onto SO(3), the translations are kept as solved.
"""

from __future__ import annotations

import numpy as np

from multieye.core.geometry import make_transform
from multieye.solvers.kronecker import normalize_rotation

__all__ = ["solve_li_single"]


def solve_li_single(A: np.ndarray, B: np.ndarray):
    """Solve one camera. A, B: (N, 4, 4). Returns X, Y: (4, 4)."""
    n = A.shape[0]
    RA, tA = A[:, :3, :3], A[:, :3, 3]
    RB, tB = B[:, :3, :3], B[:, :3, 3]
    eye = np.eye(3)
    M = np.zeros((n, 12, 24))
    M[:, :9, :9] = np.einsum("nij,kl->nikjl", RA, eye).reshape(n, 9, 9)
    M[:, :9, 9:18] = -np.einsum("ij,nlk->nikjl", eye, RB).reshape(n, 9, 9)
    M[:, 9:, 9:18] = np.einsum("ij,nl->nijl", eye, tB).reshape(n, 3, 9)
    M[:, 9:, 18:21] = -RA
    M[:, 9:, 21:24] = eye
    b = np.zeros((n, 12))
    b[:, 9:] = tA
    x, *_ = np.linalg.lstsq(M.reshape(12 * n, 24), b.reshape(-1), rcond=None)
    RX = normalize_rotation(x[:9].reshape(3, 3))
    RY = normalize_rotation(x[9:18].reshape(3, 3))
    return make_transform(RX, x[18:21]), make_transform(RY, x[21:24])
