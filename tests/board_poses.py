"""Boards posed in front of a camera (test helper shared by the imaging tests)."""

from __future__ import annotations

import numpy as np

from multieye.core.geometry import transform_from_rotvec
from multieye.core.intrinsics import Intrinsics

PINHOLE = Intrinsics(K=[[600, 0, 399.5], [0, 600, 299.5], [0, 0, 1]],
                     dist=[-0.3, 0.1, 0.001, -0.001, -0.02], width=800, height=600)


def facing_pose(target, rotvec, distance, offset=(0.0, 0.0)):
    """T_cam_target with the board centre ``distance`` in front of the camera, tilted by
    ``rotvec`` from facing the camera (printed side towards it)."""
    x0, x1, y0, y1 = target.bounds()
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    T = transform_from_rotvec(rotvec, np.zeros(3))
    if not target.z_into_board:                  # AprilGrid: z comes out of the printed face
        T = T @ np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = -T[:3, :3] @ centre + [offset[0], offset[1], distance]
    return T

