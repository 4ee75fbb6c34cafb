"""Levenberg-Marquardt refinements of a target's pose through lens models OpenCV's
``cv2.solvePnPRefineLM`` does not hold (:mod:`multieye.imaging.pnp` calls them): the
equidistant fisheye (``cv2.fisheye.projectPoints``' Jacobians) and the wide-angle models of
:mod:`multieye.core.lens_wide` (:func:`multieye.core.lens.project_with_jacobian`).
"""

from __future__ import annotations

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
    """Levenberg-Marquardt on the pixel reprojection error of the equidistant model."""
    pts = obj.reshape(-1, 1, 3)

    def residual(r, t):
        proj, jac = cv2.fisheye.projectPoints(pts, r, t, intrinsics.K, intrinsics.dist)
        return (img - proj.reshape(-1, 2)).ravel(), jac[:, 8:14]   # d/d(rvec, tvec)

    x = np.concatenate([rvec, tvec]).astype(np.float64)
    res, J = residual(x[:3], x[3:])
    cost = float(res @ res)
    damping = 1e-3
    for _ in range(iterations):
        H = J.T @ J
        step = np.linalg.solve(H + damping * np.diag(np.diag(H)), J.T @ res)
        candidate = x + step
        new_res, new_J = residual(candidate[:3], candidate[3:])
        new_cost = float(new_res @ new_res)
        if new_cost < cost:
            x, res, J, cost = candidate, new_res, new_J, new_cost
            damping = max(damping / 10, 1e-12)
            if np.linalg.norm(step) < 1e-12 * (1 + np.linalg.norm(x)):
                break
        else:
            damping *= 10
            if damping > 1e8:
                break
    return x[:3], x[3:]


def refine_wide(obj: F64, img: F64, intrinsics: Intrinsics, rvec: F64, tvec: F64,
                 iterations: int = 50) -> tuple[F64, F64]:
    """Levenberg-Marquardt on the pixel reprojection error of a wide-angle model
    (:func:`multieye.core.lens.project_with_jacobian`), the pose updated on the left,
    ``T <- [exp(w) | v] T`` as :func:`multieye.imaging.pnp.refit_poses` does; a step that takes a point out of the
    model's valid region is refused like one that raises the cost."""
    R = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3))[0]
    t = np.asarray(tvec, dtype=np.float64).reshape(3)

    def residual(R, t):
        P = obj @ R.T + t
        uv, jp, _ = project_with_jacobian(P, intrinsics, lens_jacobian=False)
        J = np.concatenate([np.cross(P[:, None, :], jp), jp], axis=2).reshape(-1, 6)
        return (img - uv).ravel(), -J

    res, J = residual(R, t)
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
        dR = rotation_from_rotvec(step[:3])
        R1, t1 = dR @ R, dR @ t + step[3:]
        new_res, new_J = residual(R1, t1)
        new_cost = float(new_res @ new_res)
        if new_cost < cost:                       # NaN (a point out of the region): refused
            R, t, res, J, cost = R1, t1, new_res, new_J, new_cost
            damping = max(damping / 10, 1e-12)
            if np.linalg.norm(step) < 1e-12 * (1 + np.linalg.norm(t)):
                break
        else:
            damping *= 10
            if damping > 1e8:
                break
    return cv2.Rodrigues(R)[0].reshape(3), t
