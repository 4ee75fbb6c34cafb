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
per-camera sums of :class:`multieye.solvers.kronecker.CameraStats`.  Cost is linear in
measurements and cameras; with one camera the result equals Shah's (2013) method.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from multieye.core.errors import DegenerateMotionError
from multieye.solvers.measurements import Measurements
from multieye.solvers.kronecker import normalize_rotation, solve_translations, unvec

__all__ = ["solve_joint", "joint_rotation"]


def joint_rotation(K: np.ndarray, counts: np.ndarray, out: np.ndarray | None = None):
    """Rotations of Y and of every X from the per-camera Kronecker sums.

    Parameters
    ----------
    K : ndarray, shape (m, 9, 9)
        ``K_j = sum_i R_B ⊗ R_A``.
    counts : ndarray, shape (m,)
    out : ndarray, shape (m + 1, 3, 3), optional
        Where to write the result; it may be a view.

    Returns
    -------
    R : ndarray, shape (m + 1, 3, 3)
        ``R_X^1 .. R_X^m``, then ``R_Y``.
    """
    m = K.shape[0]
    S = np.einsum("jab,jcb->ac", K / counts[:, None, None], K)      # sum_j K_j K_j^T / n_j
    # Top eigenvector of S = bottom one of sum_j n_j I - K_j K_j^T / n_j.  LAPACK's dsyevr
    # called directly costs a third of numpy.linalg.eigh's call on a 9x9 matrix; S.T is
    # the same symmetric matrix in the column-major order LAPACK works in place on.
    _, V, _, _, info = lapack.dsyevr(S.T, range="I", il=9, iu=9, overwrite_a=True)
    if info != 0:
        raise DegenerateMotionError(f"the 9x9 rotation eigenproblem did not converge (LAPACK "
                                    f"dsyevr info {info}); check the input for extreme values")
    v = np.empty((m + 1, 9))
    np.matmul(V[:, 0], K, out=v[:m])                  # vec(R_X^j) ~ K_j^T y
    v[m] = V[:, 0]                                    # vec(R_Y) ~ y
    return normalize_rotation(unvec(v), out=out)


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
    m = stats.n.shape[0]
    T = np.zeros((m + 1, 4, 4))                       # X^1 .. X^m, then Y
    T[:, 3, 3] = 1.0
    R = joint_rotation(stats.K, stats.n, out=T[:, :3, :3])
    solve_translations(stats, R[m], out=T[:, :3, 3])
    return T[:m], T[m]
