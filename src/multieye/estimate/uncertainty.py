"""Uncertainty of rig extrinsics: relative-pose covariances and the Cramér-Rao bound.

A refinement (:func:`multieye.estimate.refine_images.refine_images`, :mod:`multieye.solvers.refine_poses`) returns the
covariance of the perturbations of every ``X^j`` and ``Y``, each as (rotation vector,
translation) with ``R = Exp(phi) R_hat`` and ``t = t_hat + tau`` (radians, metres).  Users care
about the relative extrinsics ``T_ref_cam = inv(X_ref) @ X_cam`` (docs/conventions.md,
sections 2 and 6), whose covariance follows to first order from the joint covariance of
``X_ref`` and ``X_cam`` (:func:`multieye.solvers.refine_poses.relative_pose_covariance`).
``calibration.json`` (docs/outputs.md, section 2) reports it per camera as

- ``std_rot_deg``: root of the trace of the 3x3 rotation block, in degrees (the RMS of the
  rotation error angle, to first order);
- ``std_trans_m``: root of the trace of the 3x3 translation block, metres (the RMS of the
  position error);
- ``covariance``: the full 6x6, rotation vector (in the ``ref`` frame) then translation.

:func:`cramer_rao_bound` evaluates the Fisher information of the image-level problem at the
truth (pixels with i.i.d. Gaussian noise, mocap poses with the Gaussian noise of
:class:`multieye.sim.rigs.GaussianNoise`): the smallest covariance any unbiased estimator
of X and Y can have on simulated data.

Synopsis
--------
>>> from multieye.estimate.uncertainty import relative_covariance
>>> rel = relative_covariance(res.X, res.covariance, reference=0)   # doctest: +SKIP
>>> rel.std_rot_deg, rel.std_trans_m                                # (m,), (m,)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from multieye.core.arguments import real_array
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_with_jacobian
from multieye.core.lie import log_so3
from multieye.estimate.image_data import image_data
from multieye.optimize.levenberg_marquardt import covariance
from multieye.solvers.refine_poses import relative_pose_covariance

__all__ = ["RelativeUncertainty", "relative_covariance", "pose_std", "pose_error",
           "cramer_rao_bound", "projection_std", "projection_std_at", "estimate_mocap_noise",
           "MOCAP_SIGMA_FLOOR"]

F64 = NDArray[np.float64]


def pose_error(T_est: ArrayLike, T_true: ArrayLike) -> F64:
    """The error of an estimated pose in the convention of the covariances here.

    ``(phi, tau)`` with ``R_est = Exp(phi) R_true`` and ``t_est = t_true + tau`` (the
    ``se3-left`` perturbation of :mod:`multieye.optimize.blocks`), so that ``e^T C^-1 e`` is
    the normalised estimation error squared of a reported 6x6 covariance ``C``.

    Parameters
    ----------
    T_est, T_true : array_like, shape (4, 4)

    Returns
    -------
    ndarray, shape (6,)
        Rotation vector (radians) then translation (metres).
    """
    T_est, T_true = np.asarray(T_est, dtype=np.float64), np.asarray(T_true, dtype=np.float64)
    return np.concatenate([log_so3(T_est[:3, :3] @ T_true[:3, :3].T),
                           T_est[:3, 3] - T_true[:3, 3]])


@dataclass(frozen=True)
class RelativeUncertainty:
    """Uncertainty of every ``T_ref_cam``.

    Attributes
    ----------
    reference : int
        Index of the reference camera (its covariance is zero).
    covariance : ndarray, shape (m, 6, 6)
        Covariance of (rotation vector in the ``ref`` frame, translation) of each
        ``T_ref_cam``, radians and metres.
    std_rot_deg : ndarray, shape (m,)
        Root of the trace of each rotation block, degrees.
    std_trans_m : ndarray, shape (m,)
        Root of the trace of each translation block, metres.
    """

    reference: int
    covariance: F64
    std_rot_deg: F64
    std_trans_m: F64


def pose_std(covariance: ArrayLike) -> tuple[F64, F64]:
    """Root of the trace of the rotation and translation blocks of 6x6 pose covariances.

    Parameters
    ----------
    covariance : array_like, shape (..., 6, 6)
        (rotation vector, translation), radians and metres.

    Returns
    -------
    std_rot_deg : ndarray, shape (...)
        Degrees.
    std_trans_m : ndarray, shape (...)
        Metres.
    """
    C = real_array(covariance, "covariance")
    if C.shape[-2:] != (6, 6):
        raise InputError(f"pose covariances must be 6x6, got shape {C.shape}")
    rot = np.trace(C[..., :3, :3], axis1=-2, axis2=-1)
    trans = np.trace(C[..., 3:, 3:], axis1=-2, axis2=-1)
    return np.degrees(np.sqrt(np.clip(rot, 0.0, None))), np.sqrt(np.clip(trans, 0.0, None))


def relative_covariance(X: ArrayLike, covariance: ArrayLike, reference: int = 0
                        ) -> RelativeUncertainty:
    """Covariance of every ``T_ref_cam = inv(X_ref) @ X_cam`` from the joint covariance of X.

    Parameters
    ----------
    X : array_like, shape (m, 4, 4)
        ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand).
    covariance : array_like, shape (6m, 6m) or (6(m+1), 6(m+1))
        Joint covariance of X^0..X^{m-1} (then optionally Y, ignored), each (rotation vector,
        translation) with ``R = Exp(phi) R_hat``, ``t = t_hat + tau``: the ``covariance`` of
        :class:`multieye.estimate.refine_images.RefinementResult` or of a refined
        :class:`multieye.solvers.Solution`.  Cross-covariances between cameras matter (they
        share Y) and are used.
    reference : int
        Index of the reference camera.

    Returns
    -------
    RelativeUncertainty

    Raises
    ------
    InputError
        Shapes that do not match, arrays that are not real and finite, or a reference that
        is not an index in range.
    """
    X = real_array(X, "X", shape=(None, 4, 4))
    C = real_array(covariance, "covariance")
    m = X.shape[0]
    if C.shape not in ((6 * m, 6 * m), (6 * m + 6, 6 * m + 6)):
        raise InputError(f"covariance must be {6 * m}x{6 * m} (X) or {6 * m + 6}x{6 * m + 6} "
                         f"(X and Y) for {m} cameras, got {C.shape}")
    if not (np.isfinite(X).all() and np.isfinite(C).all()):
        raise InputError("X and covariance must be finite, got NaN or inf")
    if isinstance(reference, bool) or not isinstance(reference, (int, np.integer)):
        raise InputError(f"reference must be a camera index (int), got {reference!r}")
    if not 0 <= reference < m:
        raise InputError(f"reference camera index {reference} out of range for {m} cameras")
    out = np.zeros((m, 6, 6))
    r = slice(6 * reference, 6 * reference + 6)
    for j in range(m):
        if j == reference:
            continue
        c = slice(6 * j, 6 * j + 6)
        joint = np.block([[C[r, r], C[r, c]], [C[c, r], C[c, c]]])
        out[j] = relative_pose_covariance(X[reference], X[j], joint)
    out = 0.5 * (out + np.swapaxes(out, 1, 2))
    std_rot, std_trans = pose_std(out)
    return RelativeUncertainty(reference=reference, covariance=out, std_rot_deg=std_rot,
                               std_trans_m=std_trans)


def cramer_rao_bound(setup: str, observations: Sequence, intrinsics: Sequence[Intrinsics],
                     X: ArrayLike, Y: ArrayLike, *, pixel_sigma: float,
                     mocap_rot_sigma_rad: float, mocap_trans_sigma_m: float) -> F64:
    """Cramér-Rao bound of X and Y for the image-level problem of :mod:`multieye.estimate.refine_images`.

    The inverse of the Fisher information ``J^T J`` of the sigma-normalised residuals
    (pixels, mocap priors), evaluated at the true parameters, restricted to X and Y by the
    Schur complement (the true mocap poses are nuisance parameters).  Exact for the Gaussian
    noise models of :mod:`multieye.sim.images`, to first order in the noise.

    Parameters
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    observations : sequence over cameras of sequence of (object_points, image_points, T_world_mocap)
        As for :func:`multieye.estimate.refine_images.refine_images`, with the *true* motion-capture poses
        (the image points are not used): e.g.
        :attr:`multieye.sim.images.ImageScenario.true_observations`.
    intrinsics : sequence of Intrinsics
    X : array_like, shape (m, 4, 4)
        True ``T_world_cam`` / ``T_body_cam``.
    Y : array_like, shape (4, 4)
        True ``T_marker_target`` / ``T_world_target``.
    pixel_sigma : float
        Pixel noise, pixels.
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float
        Motion-capture noise, radians and metres.

    Returns
    -------
    ndarray, shape (6(m+1), 6(m+1))
        Lower bound of the covariance of X^0..X^{m-1}, Y in the convention of
        :class:`multieye.estimate.refine_images.RefinementResult`; pass it to :func:`relative_covariance` for
        the bound of every ``T_ref_cam``.
    """

    data = image_data(setup, observations, intrinsics)
    sigmas = np.array([pixel_sigma, mocap_rot_sigma_rad, mocap_trans_sigma_m], dtype=np.float64)
    if not np.all(np.isfinite(sigmas) & (sigmas > 0)):
        raise InputError(f"noise levels must be positive, got {sigmas.tolist()}")
    X = np.asarray(X, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    return covariance(data.families(X, Y), data.groups(*sigmas)).kept


def projection_std_at(intrinsics: Intrinsics, covariance: ArrayLike, points_cam: ArrayLike
                      ) -> F64:
    """How uncertain a camera's projection is at each of some camera-frame points.

    For each point (a fixed ray), the 2x2 pixel covariance ``J Sigma J^T`` with
    ``J = d uv / d (fx fy cx cy dist...)`` (:func:`multieye.core.lens.project_with_jacobian`);
    its standard deviation is the root of half its trace (the RMS over the two pixel axes).
    It counts the lens' uncertainty only (the camera's pose held fixed).

    Parameters
    ----------
    intrinsics : Intrinsics
    covariance : array_like, shape (4 + k, 4 + k)
        Over ``Intrinsics.params``.
    points_cam : array_like, shape (P, 3)

    Returns
    -------
    ndarray, shape (P,)
        Pixels; NaN for points the lens cannot project.

    Raises
    ------
    InputError
        A covariance of the wrong size or not finite.
    """

    C = np.asarray(covariance, dtype=np.float64)
    n = intrinsics.params.size
    if C.shape != (n, n) or not np.all(np.isfinite(C)):
        raise InputError(f"the intrinsics covariance must be a finite {n}x{n} array, got "
                         f"shape {C.shape}")
    _, _, J = project_with_jacobian(np.asarray(points_cam, dtype=np.float64), intrinsics)
    return np.sqrt(np.clip(np.einsum("pik,kl,pil->p", J, C, J) / 2.0, 0.0, None))


def projection_std(intrinsics: Intrinsics, covariance: ArrayLike, points_cam: ArrayLike
                   ) -> tuple[float, float]:
    """Mean and largest :func:`projection_std_at` over ``points_cam`` (e.g. the observed
    target points in the camera frame), pixels.

    Raises
    ------
    InputError
        A covariance of the wrong size, or no point the lens can project.
    """
    s = projection_std_at(intrinsics, covariance, points_cam)
    s = s[np.isfinite(s)]
    if s.size == 0:
        raise InputError("no point in front of the camera to evaluate the projection at")
    return float(s.mean()), float(s.max())


#: Smallest motion-capture noise an estimate gives (radians, metres): never exactly zero.
MOCAP_SIGMA_FLOOR = 1e-7


def estimate_mocap_noise(measured: F64, refined: F64) -> tuple[float, float]:
    """Motion-capture noise from the refinement's corrections of the measured poses.

    The rotation error is the rotation vector of ``R_measured^T R_refined`` (marker/body
    frame), the position error ``t_refined - t_measured``; returned as the RMS per component
    (radians, metres), the convention of
    :func:`multieye.estimate.refine_images.refine_images`.  With many target points per
    image the refined pose is close to the truth, so the corrections are close to the errors;
    with few, the corrections shrink with the sigma the refinement was given, so iterating
    this estimate drifts to zero: ``refine_images`` divides by the redundancy instead.  Kept as the plain figure and for
    benchmarks/bench_mocap_noise.py.

    Parameters
    ----------
    measured, refined : ndarray, shape (N, 4, 4)
    """
    dr = log_so3(np.swapaxes(measured[:, :3, :3], 1, 2) @ refined[:, :3, :3])
    dt = refined[:, :3, 3] - measured[:, :3, 3]
    return (max(float(np.sqrt(np.mean(dr ** 2))), MOCAP_SIGMA_FLOOR),
            max(float(np.sqrt(np.mean(dt ** 2))), MOCAP_SIGMA_FLOOR))
