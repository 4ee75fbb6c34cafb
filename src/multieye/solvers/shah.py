"""Method ``shah``: Shah (2013), Kronecker product and SVD, one camera at a time.

M. Shah, "Solving the robot-world/hand-eye calibration problem using the Kronecker
product", Journal of Mechanisms and Robotics 5, 031007, 2013; computed as OpenCV 4.x
``calibrateRobotWorldHandEye(..., CALIB_ROBOT_WORLD_HAND_EYE_SHAH)`` does: the top singular
pair of ``K = sum_i R_B ⊗ R_A`` gives vec(R_X) (right) and vec(R_Y) (left), each
normalised by its determinant's sign and projected onto SO(3); the translations then solve
``R_A t_X - t_Y = R_Y t_B - t_A`` in the least-squares sense.
"""

from __future__ import annotations

import numpy as np

from multieye.core.geometry import make_transform
from multieye.solvers.kronecker import (camera_stats, normalize_rotation, solve_translations,
                        transform_entries, unvec)

__all__ = ["solve_shah_single"]


def solve_shah_single(A: np.ndarray, B: np.ndarray):
    """Solve one camera. A, B: (N, 4, 4). Returns X, Y: (4, 4)."""
    stats = camera_stats(transform_entries(A, B, exact_bottom=True), [A.shape[0]])
    U, _, Vt = np.linalg.svd(stats.K[0])
    RX = normalize_rotation(unvec(Vt[0]))
    RY = normalize_rotation(unvec(U[:, 0]))
    tX, tY = solve_translations(stats, RY)
    return make_transform(RX, tX[0]), make_transform(RY, tY)
