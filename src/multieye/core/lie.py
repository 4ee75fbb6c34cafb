"""SO(3) exponential and logarithm and the left Jacobian, on batches of rotation vectors.

Conventions: rotation vectors ``phi`` in radians, ``(..., 3)``; ``Exp(phi)`` is the rotation
by ``|phi|`` about ``phi / |phi|``; the left Jacobian ``J_l(phi)`` satisfies
``Exp(phi + d) ~ Exp(J_l(phi) d) Exp(phi)`` for small ``d``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from multieye.core.geometry import rotation_from_rotvec, rotvec_from_transform, skew

__all__ = ["exp_so3", "log_so3", "left_jacobian", "left_jacobian_inv"]

F64 = NDArray[np.float64]


def left_jacobian(phi: F64) -> F64:
    """Left Jacobian of SO(3), ``(..., 3, 3)`` for rotation vectors ``(..., 3)``."""
    th = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = th < 1e-6
    ths = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th ** 2 / 24.0, (1.0 - np.cos(ths)) / ths ** 2)
    b = np.where(small, 1.0 / 6.0 - th ** 2 / 120.0, (ths - np.sin(ths)) / ths ** 3)
    return np.eye(3) + a * K + b * (K @ K)


def left_jacobian_inv(phi: F64) -> F64:
    """Inverse of :func:`left_jacobian`."""
    th = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = th < 1e-6
    ths = np.where(small, 1.0, th)
    c = np.where(small, 1.0 / 12.0 + th ** 2 / 720.0,
                 1.0 / ths ** 2 - (1.0 + np.cos(ths)) / (2.0 * ths * np.sin(ths)))
    return np.eye(3) - 0.5 * K + c * (K @ K)


def exp_so3(phi: F64) -> F64:
    """Rotation matrices ``(..., 3, 3)`` of rotation vectors ``(..., 3)``."""
    return rotation_from_rotvec(phi)


def log_so3(R: F64) -> F64:
    """Rotation vectors ``(..., 3)`` of rotation matrices ``(..., 3, 3)``."""
    return rotvec_from_transform(R)
