"""Error metrics of paper section V-A, and errors against ground truth.

Synopsis
--------
>>> rot_deg, trans_m = loop_residuals(A, B, X, Y)        # doctest: +SKIP
>>> T_ref_cam = relative_extrinsics(sol.X, reference=0)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from multieye.core import geometry as g

__all__ = [
    "CameraResidual",
    "loop_residuals",
    "camera_residual",
    "camera_residuals",
    "relative_extrinsics",
    "extrinsic_errors",
    "pose_row",
    "PoseErrorRow",
    "error_table",
]


@dataclass(frozen=True)
class CameraResidual:
    """Residuals of one camera's loop ``A_i X = Y B_i`` (paper section V-A).

    Attributes
    ----------
    e_R_deg : float
        Mean over measurements of angle((R_Y R_B)^T (R_A R_X)), degrees.
    e_t_m : float
        Mean of ||(R_A t_X + t_A) - (R_Y t_B + t_Y)||, metres.
    max_R_deg, max_t_m : float
        Worst measurement.
    n : int
        Measurements used.
    """

    e_R_deg: float
    e_t_m: float
    max_R_deg: float
    max_t_m: float
    n: int



def loop_residuals(A: ArrayLike, B: ArrayLike, X: ArrayLike, Y: ArrayLike):
    """Per-measurement residuals of ``A_i X = Y B_i`` (paper section V-A).

    Parameters
    ----------
    A, B : array_like, shape (N, 4, 4)
    X, Y : array_like, shape (4, 4)

    Returns
    -------
    rot_deg : ndarray, shape (N,)
        angle((R_Y R_B)^T (R_A R_X)), degrees.
    trans_m : ndarray, shape (N,)
        ||(R_A t_X + t_A) - (R_Y t_B + t_Y)||, metres.
    """
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    left = A @ np.asarray(X, dtype=np.float64)  # X may be (4, 4) or one per row
    right = np.asarray(Y, dtype=np.float64) @ B
    return np.degrees(chordal_angle(left, right)), g.translation_distance(left, right)


def chordal_angle(T1: np.ndarray, T2: np.ndarray) -> np.ndarray:
    """Angle (radians) of ``R1^T R2`` from the chordal distance, accurate near zero.

    ``||R1 - R2||_F^2 = 8 sin^2(theta / 2)``; cheaper than forming ``R1^T R2``.
    """
    d = ((T1[..., :3, :3] - T2[..., :3, :3]) ** 2).sum(axis=(-2, -1)) / 8.0
    return 2.0 * np.arctan2(np.sqrt(d), np.sqrt(np.clip(1.0 - d, 0.0, None)))


def camera_residual(A: ArrayLike, B: ArrayLike, X: ArrayLike, Y: ArrayLike) -> CameraResidual:
    """Summary of :func:`loop_residuals` for one camera."""
    rot, trans = loop_residuals(A, B, X, Y)
    return CameraResidual(e_R_deg=float(rot.mean()), e_t_m=float(trans.mean()),
                          max_R_deg=float(rot.max()), max_t_m=float(trans.max()), n=int(rot.size))


def camera_residuals(A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray,
                     camera: np.ndarray, starts: np.ndarray) -> tuple[CameraResidual, ...]:
    """:func:`camera_residual` for every camera at once.

    Parameters
    ----------
    A, B : ndarray, shape (N, 4, 4)
        All measurements, camera by camera.
    X : ndarray, shape (m, 4, 4)
    Y : ndarray, shape (4, 4)
    camera : ndarray, shape (N,)
        Camera index of each row; rows of one camera are contiguous.
    starts : ndarray, shape (m,)
        First row of each camera.
    """
    rot, trans = loop_residuals(A, B, X[camera], Y)
    n = np.diff(np.append(starts, rot.size))
    both = np.stack([rot, trans], axis=1)
    sums = np.add.reduceat(both, starts, axis=0)
    maxs = np.maximum.reduceat(both, starts, axis=0)
    return tuple(CameraResidual(e_R_deg=float(sums[j, 0] / n[j]), e_t_m=float(sums[j, 1] / n[j]),
                                max_R_deg=float(maxs[j, 0]), max_t_m=float(maxs[j, 1]), n=int(n[j]))
                 for j in range(starts.size))


def relative_extrinsics(X: ArrayLike, reference: int = 0) -> np.ndarray:
    """``T_ref_cam = inv(X_ref) @ X_cam`` for every camera (docs/conventions.md, section 2).

    Valid for both setups: X is ``T_world_cam`` (eye-to-base) or ``T_body_cam``
    (eye-on-hand), and the chain ``T_ref_world @ T_world_cam`` (or through ``body``)
    cancels the shared frame.

    Parameters
    ----------
    X : array_like, shape (m, 4, 4)
    reference : int
        Index of the reference camera.

    Returns
    -------
    ndarray, shape (m, 4, 4)
    """
    X = np.asarray(X, dtype=np.float64)
    return g.inv(X[reference]) @ X


def extrinsic_errors(T_est: ArrayLike, T_true: ArrayLike):
    """Rotation angle (degrees) and translation distance (metres) between transforms.

    Parameters
    ----------
    T_est, T_true : array_like, shape (..., 4, 4)

    Returns
    -------
    rot_deg, trans_m : ndarray, shape (...)
    """
    return (np.degrees(g.rotation_angle_between(T_est, T_true)),
            g.translation_distance(T_est, T_true))


@dataclass(frozen=True)
class PoseErrorRow:
    """One row of the paper's table: pose parameters and their errors.

    Translations in metres, angles in degrees; yaw, pitch, roll with
    ``R = Rz(yaw) Ry(pitch) Rx(roll)``.
    """

    camera: str
    tx: float
    ty: float
    tz: float
    yaw: float
    pitch: float
    roll: float
    rot_err_deg: float | None = None
    trans_err_m: float | None = None


def pose_row(T: ArrayLike) -> np.ndarray:
    """``(tx, ty, tz, yaw, pitch, roll)`` of a transform, metres and degrees."""
    T = np.asarray(T, dtype=np.float64)
    return np.concatenate([T[..., :3, 3], np.degrees(g.ypr_from_rotation(T))], axis=-1)


def error_table(T_est: Mapping[str, ArrayLike] | ArrayLike,
                T_true: Mapping[str, ArrayLike] | ArrayLike | None = None) -> list[PoseErrorRow]:
    """The paper's tx ty tz yaw pitch roll table for ``T_ref_cam`` of every camera.

    Parameters
    ----------
    T_est : mapping of str to array_like, shape (4, 4), or array_like, shape (m, 4, 4)
        By camera name (``run.T_ref_cam``); an array names the cameras ``cam0, cam1, ...``.
    T_true : the same, optional
        Ground truth (a mapping: by the same names); fills the error columns.
    """
    if isinstance(T_est, Mapping):
        names = list(T_est)
        T_est = np.stack([np.asarray(T_est[n], dtype=np.float64) for n in names])
    else:
        T_est = np.asarray(T_est, dtype=np.float64)
        names = [f"cam{j}" for j in range(T_est.shape[0])]
    if isinstance(T_true, Mapping):
        T_true = np.stack([np.asarray(T_true[n], dtype=np.float64) for n in names])
    m = T_est.shape[0]
    rows = []
    errs = extrinsic_errors(T_est, T_true) if T_true is not None else None
    for j in range(m):
        p = pose_row(T_est[j])
        rows.append(PoseErrorRow(names[j], *map(float, p),
                                 rot_err_deg=None if errs is None else float(errs[0][j]),
                                 trans_err_m=None if errs is None else float(errs[1][j])))
    return rows
