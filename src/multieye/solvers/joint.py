"""The joint multi-camera closed form (default method ``joint``).

Least-squares solution of the stacked joint Kronecker system of Wang et al. (ICRA 2022,
section IV), one row block per measurement:

    (R_B ⊗ R_A) vec(R_X^j) - vec(R_Y) = 0                           (rotation)
    R_A t_X^j - t_Y = R_Y t_B - t_A                                  (translation)

with the scale of the homogeneous rotation system fixed by ``||vec(R_Y)||``.  The
per-camera unknowns are eliminated in closed form: for a given ``y = vec(R_Y)`` the best
``x_j = K_j^T y / n_j`` (``K_j = sum_i R_B ⊗ R_A``), which leaves

    min_y  y^T (sum_j n_j I - K_j K_j^T / n_j) y,   ||y||^2 = 3,

a 9x9 symmetric eigenproblem.  ``R_Y`` and every ``R_X^j`` are then projected onto SO(3)
(sign fixed by the determinant), and the translations follow from a 3x3 system
(:func:`multieye.solvers.kronecker.solve_translations`).  Both stages use only the
per-camera sums of :class:`multieye.solvers.kronecker.CameraStats`.  Cost is linear in measurements and
cameras; with one camera the result equals Shah's (2013) method.
"""

from __future__ import annotations

import numpy as np

from ..geometry import make_transform
from .checks import Measurements
from .kronecker import normalize_rotation, solve_translations, unvec

__all__ = ["solve_joint", "joint_rotation"]


def joint_rotation(K: np.ndarray, counts: np.ndarray):
    """Rotations of Y and of every X from the per-camera Kronecker sums.

    Parameters
    ----------
    K : ndarray, shape (m, 9, 9)
        ``K_j = sum_i R_B ⊗ R_A``.
    counts : ndarray, shape (m,)

    Returns
    -------
    RX : ndarray, shape (m, 3, 3)
    RY : ndarray, shape (3, 3)
    """
    m = K.shape[0]
    Kn = K * (1.0 / np.sqrt(counts))[:, None, None]
    Kcat = Kn.transpose(1, 0, 2).reshape(9, 9 * m)      # [K_1/sqrt(n_1), ..., K_m/sqrt(n_m)]
    _, V = np.linalg.eigh(Kcat @ Kcat.T)                 # sum_j K_j K_j^T / n_j
    y = V[:, -1]                     # largest of S = smallest of sum n_j I - K_j K_j^T / n_j
    x = y @ K                                            # K_j^T y for every j, shape (m, 9)
    R = normalize_rotation(unvec(np.concatenate([x, y[None]])))
    return R[:m], R[m]


def solve_joint(meas: Measurements):
    """Solve all cameras and Y at once.

    Parameters
    ----------
    meas : Measurements
        Validated input (see :func:`multieye.solvers.checks.check_measurements`).

    Returns
    -------
    X : ndarray, shape (m, 4, 4)
    Y : ndarray, shape (4, 4)
    """
    stats = meas.stats
    RX, RY = joint_rotation(stats.K, stats.n)
    tX, tY = solve_translations(stats, RY)
    return make_transform(RX, tX), make_transform(RY, tY)
