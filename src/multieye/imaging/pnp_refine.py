"""Levenberg-Marquardt refinements of a target's pose through lens models OpenCV's
``cv2.solvePnPRefineLM`` does not hold (:mod:`multieye.imaging.pnp` calls them): the
equidistant fisheye (``cv2.fisheye.projectPoints``' Jacobians) and the wide-angle models of
:mod:`multieye.core.lens_wide` (:func:`multieye.core.lens.project_with_jacobian`), both on
one loop (:func:`_levenberg_marquardt`) that only their residuals and pose updates tell apart.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core.geometry import rotation_from_rotvec
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_with_jacobian

__all__ = ["refine_fisheye", "refine_wide"]

F64 = NDArray[np.float64]


def refine_fisheye(obj: F64, img: F64, intrinsics: Intrinsics, rvec: F64, tvec: F64,
                   iterations: int = 50) -> tuple[F64, F64]:
    """Levenberg-Marquardt on the pixel reprojection error of the equidistant model, the
    pose ``(rvec, tvec)`` updated by addition."""
    pts = obj.reshape(-1, 1, 3)

    def residual(x):
        proj, jac = cv2.fisheye.projectPoints(pts, x[:3], x[3:], intrinsics.K, intrinsics.dist)
        return (img - proj.reshape(-1, 2)).ravel(), -jac[:, 8:14]   # d/d(rvec, tvec)

    x = _levenberg_marquardt(residual, lambda x, step: x + step, np.linalg.norm,
                             np.concatenate([rvec, tvec]).astype(np.float64), iterations)
    return x[:3], x[3:]


def refine_wide(obj: F64, img: F64, intrinsics: Intrinsics, rvec: F64, tvec: F64,
                iterations: int = 50) -> tuple[F64, F64]:
    """Levenberg-Marquardt on the pixel reprojection error of a wide-angle model
    (:func:`multieye.core.lens.project_with_jacobian`), the pose updated on the left,
    ``T <- [exp(w) | v] T`` as :func:`multieye.imaging.pnp.refit_poses` does; a step that takes
    a point out of the model's valid region is refused like one that raises the cost."""
    def residual(pose):
        R, t = pose
        P = obj @ R.T + t
        uv, jp, _ = project_with_jacobian(P, intrinsics, lens_jacobian=False)
        J = np.concatenate([np.cross(P[:, None, :], jp), jp], axis=2).reshape(-1, 6)
        return (img - uv).ravel(), -J

    def update(pose, step):
        dR = rotation_from_rotvec(step[:3])
        return dR @ pose[0], dR @ pose[1] + step[3:]

    R = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3))[0]
    t = np.asarray(tvec, dtype=np.float64).reshape(3)
    R, t = _levenberg_marquardt(residual, update, lambda pose: np.linalg.norm(pose[1]),
                                (R, t), iterations)
    return cv2.Rodrigues(R)[0].reshape(3), t


def _levenberg_marquardt(residual: Callable, update: Callable, size: Callable, state,
                         iterations: int):
    """The pose ``state`` that ends Levenberg-Marquardt on ``residual(state) -> (r, J)``
    (``r`` (2n,) pixels, ``J`` (2n, 6) its derivative along the step), each step taken as
    ``update(state, step)``.  A step that does not lower the cost is refused (also one whose
    residual is NaN: a point out of the lens model's valid region); the loop stops when the
    step is below ``1e-12 * (1 + size(state))``, the damping beyond 1e8, or on a start whose
    residual is not finite."""
    res, J = residual(state)
    cost = float(res @ res) if np.all(np.isfinite(res)) else np.inf
    damping = 1e-3
    for _ in range(iterations):
        if not np.isfinite(cost):
            break
        H = J.T @ J
        try:
            step = -np.linalg.solve(H + damping * np.diag(np.diag(H)), J.T @ res)
        except np.linalg.LinAlgError:
            break
        candidate = update(state, step)
        new_res, new_J = residual(candidate)
        new_cost = float(new_res @ new_res)
        if new_cost < cost:                       # NaN (a point out of the region): refused
            state, res, J, cost = candidate, new_res, new_J, new_cost
            damping = max(damping / 10, 1e-12)
            if np.linalg.norm(step) < 1e-12 * (1 + size(state)):
                break
        else:
            damping *= 10
            if damping > 1e8:
                break
    return state
