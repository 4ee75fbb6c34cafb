"""Methods ``tabb-c1`` and ``tabb-c2``: Tabb and Yousef (2017), iterative, one camera at a time.

A. Tabb, K. M. Ahmad Yousef, "Solving the robot-world hand-eye(s) calibration problem with
iterative methods", Machine Vision and Applications 28, 2017.  Separable variants: the
rotations are solved first, parameterised by Euler angles, then the translations, each
stage with :func:`scipy.optimize.least_squares`, over the top 3x4 block of

    c1 = sum_i ||A_i X - Y B_i||^2          c2 = sum_i ||A_i - Y B_i X^-1||^2.

For the rotation stage the two costs coincide (``||R_A R_X - R_Y R_B||_F`` is invariant
under right multiplication by ``R_X^T``); they differ in the translation stage, where c2
measures ``t_A - (R_Y R_B R_X^T (-t_X) + R_Y t_B + t_Y)`` through the estimated rotations.
Started from Shah's closed form (the Euler angles are taken relative to it, so the
parameterisation stays far from gimbal lock).
"""

from __future__ import annotations

import numpy as np

from multieye.core.geometry import make_transform
from multieye.solvers.shah import solve_shah_single

__all__ = ["solve_tabb_single"]

_TOL = dict(xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200)


def _euler(e: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation  # noqa: PLC0415 (heavy: scipy.spatial, about 0.1 CPU-s for every calibrate; only the tabb methods use it)

    return Rotation.from_euler("xyz", e).as_matrix()


def solve_tabb_single(A: np.ndarray, B: np.ndarray, cost: str = "c1"):
    """Solve one camera with cost ``"c1"`` or ``"c2"``. A, B: (N, 4, 4). Returns X, Y."""
    from scipy.optimize import least_squares  # noqa: PLC0415 (heavy: 0.1-0.3 CPU-s of start-up for every calibrate; only the tabb methods use it)

    X0, Y0 = solve_shah_single(A, B)
    RA, tA = A[:, :3, :3], A[:, :3, 3]
    RB, tB = B[:, :3, :3], B[:, :3, 3]
    RX0, RY0 = X0[:3, :3], Y0[:3, :3]

    def rot_res(p):
        RX = RX0 @ _euler(p[:3])
        RY = RY0 @ _euler(p[3:])
        return (RA @ RX - RY @ RB).reshape(-1)

    p = least_squares(rot_res, np.zeros(6), method="lm", **_TOL).x
    RX = RX0 @ _euler(p[:3])
    RY = RY0 @ _euler(p[3:])

    if cost == "c1":
        # R_A t_X + t_A - R_Y t_B - t_Y
        def tr_res(t):
            return (RA @ t[:3] + tA - tB @ RY.T - t[3:]).reshape(-1)
    elif cost == "c2":
        # t_A - (R_Y R_B R_X^T (-t_X) + R_Y t_B + t_Y)
        G = RY @ RB @ RX.T

        def tr_res(t):
            return (tA + G @ t[:3] - tB @ RY.T - t[3:]).reshape(-1)
    else:
        raise ValueError(f"unknown Tabb cost {cost!r}")
    t = least_squares(tr_res, np.concatenate([X0[:3, 3], Y0[:3, 3]]), method="lm", **_TOL).x
    return make_transform(RX, t[:3]), make_transform(RY, t[3:])
