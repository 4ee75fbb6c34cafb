"""Motion capture of the rig in the problem of a rig linked by its motion (issue 34).

The motion capture's frame ``mocap`` and its marker body ``marker`` on the rig add two
unknowns to :mod:`multieye.estimate.motion_residuals`' problem: ``Ym = T_mocap_world`` and
``Xm = T_rig_marker``.  At every instant ``t`` it has, it measures::

    M(t) = T_mocap_marker(t) = Ym @ inv(S(t)) @ Xm          (S(t) = T_ref_world(t))

with noise in the marker's rotation (``sigma_rot_rad`` per axis, right perturbation: the
marker's frame) and in its position (``sigma_trans_m`` per axis, the motion capture's frame):
the residual ``[log(R_M^T R_P) / sigma_rot, (t_P - t_M) / sigma_trans]`` of the prediction
``P``.  With it the image views (overlap), the rig's motion and the motion capture are one
problem: the instants' rig poses are shared, so a camera is tied by whichever of the three
its views reach.

Jacobians (``Ym``, ``Xm`` and ``S`` perturbed on the left, ``q = R_S^T (t_X - t_S)``,
``J = J_r^-1(e_R)`` the inverse right Jacobian of SO(3) at the rotation residual)::

    d e_R / d phi_Y = J R_P^T        d e_t / d phi_Y = -[R_Y q]_x     d e_t / d tau_Y = I
    d e_R / d phi_S = -J R_X^T       d e_t / d phi_S = R_Y R_S^T [t_X - t_S]_x
                                     d e_t / d tau_S = -R_Y R_S^T
    d e_R / d phi_X = J R_X^T        d e_t / d tau_X = R_Y R_S^T
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.lie import left_jacobian_inv, log_so3
from multieye.optimize.blocks import Blocks, ResidualGroup
from multieye.solvers.general import solve_general

__all__ = ["RigMocap", "MocapPoseResiduals", "mocap_families"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class RigMocap:
    """The rig's motion capture at some of the problem's instants.

    Attributes
    ----------
    instant : ndarray of int, shape (n,)
    T_mocap_marker : ndarray, shape (n, 4, 4)
    sigma_rot_rad, sigma_trans_m : float
        Noise per axis.
    """

    instant: NDArray[np.int64]
    T_mocap_marker: F64
    sigma_rot_rad: float
    sigma_trans_m: float

    def __post_init__(self):
        inst = np.asarray(self.instant, dtype=np.int64).reshape(-1)
        M = np.asarray(self.T_mocap_marker, dtype=np.float64).reshape(-1, 4, 4)
        if len(inst) != len(M) or len(inst) < 3 or np.unique(inst).size != inst.size:
            raise InputError(f"motion capture: {len(M)} poses for {len(inst)} instants; give "
                             "one pose per instant, at 3 instants or more")
        if not (self.sigma_rot_rad > 0 and self.sigma_trans_m > 0):
            raise InputError("motion capture noise must be positive")
        object.__setattr__(self, "instant", inst)
        object.__setattr__(self, "T_mocap_marker", M)


def mocap_families(mocap: RigMocap, T_world_rig: F64) -> list[Blocks]:
    """``Ym`` and ``Xm`` started from the rig's poses (the joint hand-eye problem
    ``T_world_rig(t) Xm = inv(Ym) M(t)``)."""
    sol = solve_general([("marker", "mocap", np.asarray(T_world_rig)[mocap.instant],
                          mocap.T_mocap_marker)])
    return [Blocks("Ym", g.inv(sol.Y["mocap"])[None], "se3-left"),
            Blocks("Xm", sol.X["marker"][None], "se3-left")]


class MocapPoseResiduals(ResidualGroup):
    """The motion capture's pose residuals (module docstring), one 6-row segment per pose."""

    def __init__(self, mocap: RigMocap):
        n = len(mocap.instant)
        index = np.column_stack([mocap.instant, np.zeros(n, dtype=np.int64),
                                 np.zeros(n, dtype=np.int64)])
        super().__init__(["S", "Ym", "Xm"], index, np.arange(n), 6)
        self.mocap = mocap
        self.scale = np.array([1 / mocap.sigma_rot_rad] * 3 + [1 / mocap.sigma_trans_m] * 3)

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        S = values["S"][self.mocap.instant]
        Y, X = values["Ym"][0], values["Xm"][0]
        M = self.mocap.T_mocap_marker
        RS, tS = S[:, :3, :3], S[:, :3, 3]
        RYS = Y[:3, :3] @ np.swapaxes(RS, 1, 2)                               # R_Y R_S^T
        RP = RYS @ X[:3, :3]
        d = X[:3, 3] - tS
        tP = np.einsum("nij,nj->ni", RYS, d) + Y[:3, 3]
        eR = log_so3(np.swapaxes(M[:, :3, :3], 1, 2) @ RP)
        r = np.concatenate([eR, tP - M[:, :3, 3]], axis=1)
        r3 = r * self.scale                                                # (n, 6)
        if not jacobians:
            return r3, None
        n = len(S)
        J = left_jacobian_inv(-eR)                                         # J_r^-1(e_R)
        zero = np.zeros((n, 3, 3))
        eye = np.broadcast_to(np.eye(3), (n, 3, 3))
        jS = np.block([[-J @ X[:3, :3].T, zero], [RYS @ g.skew(d), -RYS]])
        jY = np.block([[J @ np.swapaxes(RP, 1, 2), zero],
                       [-g.skew(tP - Y[:3, 3]), eye]])
        jX = np.block([[J @ X[:3, :3].T, zero], [zero, RYS]])
        s = self.scale[None, :, None]
        return r3, [jS * s, jY * s, jX * s]
