"""The result of a closed-form or refined solve (:class:`Solution`); the same kind of module
as :mod:`multieye.pipeline.result`, which holds the result of a whole calibration run."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from multieye.solvers.measurements import Measurements

from multieye.core.metrics import CameraResidual, camera_residuals

__all__ = ["Solution", "CameraResidual"]


@dataclass(frozen=True)
class Solution:
    """Solution of ``A_i^j X^j = Y B_i^j`` for m cameras.

    Attributes
    ----------
    X : ndarray, shape (m, 4, 4)
        Per-camera unknown: ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand).
    Y : ndarray, shape (4, 4)
        Shared unknown: ``T_marker_target`` (eye-to-base) or ``T_world_target`` (eye-on-hand).
    method : str
        Registry name of the solver.
    Y_per_camera : ndarray, shape (m, 4, 4) or None
        Single-camera methods: each camera's own estimate of Y before combination.
    covariance : ndarray, shape (6(m+1), 6(m+1)) or None
        With ``refine=True``: covariance of the perturbations of X^1..X^m then Y, each as
        (rotation vector, translation), radians and metres; ``multieye.solvers.refine_poses``
        documents the perturbation convention.
    measurements : Measurements or None
        The validated input, kept so that :attr:`residuals` can be computed on demand.
    residuals : tuple of CameraResidual
        One per camera, for this X and Y (computed on first access).
    """

    X: np.ndarray
    Y: np.ndarray
    method: str
    Y_per_camera: np.ndarray | None = None
    covariance: np.ndarray | None = None
    measurements: Measurements | None = field(default=None, repr=False, compare=False)

    @cached_property
    def residuals(self) -> tuple[CameraResidual, ...]:
        if self.measurements is None:
            raise AttributeError("this Solution was built without its measurements")
        meas = self.measurements
        return camera_residuals(meas.A, meas.B, self.X, self.Y, meas.camera, meas.starts)

    @property
    def e_R_deg(self) -> float:
        """Mean rotation residual over all measurements of all cameras, degrees."""
        n = sum(r.n for r in self.residuals)
        return float(sum(r.e_R_deg * r.n for r in self.residuals) / n)

    @property
    def e_t_m(self) -> float:
        """Mean translation residual over all measurements of all cameras, metres."""
        n = sum(r.n for r in self.residuals)
        return float(sum(r.e_t_m * r.n for r in self.residuals) / n)
