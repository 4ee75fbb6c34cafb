"""Image-level maximum-likelihood refinement of a rig: every ``X^j``, ``Y`` and mocap pose.

The closed form (:func:`multieye.solve`) fits the pose loop ``A_i^j X^j = Y B_i^j`` with an
arbitrary weighting of rotation against translation, and treats the PnP poses as if they were
measured.  What is measured are the target points' pixels and the motion-capture poses; this
module minimises exactly their negative log-likelihood (paper section IV, taken to the image
level), jointly over

- every camera's unknown ``X^j`` (``T_world_cam`` eye-to-base, ``T_body_cam`` eye-on-hand),
- the shared ``Y`` (``T_marker_target`` eye-to-base, ``T_world_target`` eye-on-hand),
- the true motion-capture pose ``M_i`` (``T_world_marker`` or ``T_world_body``) of every
  image, a nuisance parameter observed through its measurement ``M_i^meas``::

    min  sum_points  rho(||pi_j(T_cam_target_i p_k) - u_ik||^2 / sigma_px^2)
       + sum_images  rho(||Log(R_meas^T R_M)||^2 / sigma_R^2) + rho(||t_M - t_meas||^2 / sigma_t^2)

(``rho`` applied per residual component, as :func:`scipy.optimize.least_squares` does) with

    T_cam_target_i = inv(X^j) @ M_i @ Y          eye-to-base   (A_i = inv(M_i))
    T_cam_target_i = inv(X^j) @ inv(M_i) @ Y     eye-on-hand   (A_i = M_i)

i.e. ``T_cam_target = inv(X) inv(A) Y`` in both setups (DESIGN.md section 2).

Parameterisation (6 per pose, rotation then translation, radians and metres):

- ``X^j`` and ``Y``: ``R = Exp(phi) R_0``, ``t = t_0 + tau`` around the starting estimate, the
  convention of :mod:`multieye.solvers.refine_poses`, so that covariances from both modules propagate
  with :func:`multieye.estimate.uncertainty.relative_covariance` alike;
- ``M_i``: ``R_M = R_meas Exp(phi)``, ``t_M = t_meas + tau`` around the measurement, the noise
  model of :class:`multieye.sim.rigs.GaussianNoise` (rotation noise in the marker/body frame,
  translation noise in the world frame).  Its prior residual is then exactly
  ``(phi / sigma_R, tau / sigma_t)``: linear, with a constant diagonal Jacobian.

Jacobian: analytic in the poses, chained with the 2x3 derivative of the pixel with respect to
the camera-frame point (:func:`project_with_jacobian`: the lens model's 2x2 derivative by
central differences of :func:`multieye.core.lens.distort_points`, so every OpenCV
pinhole and fisheye model works, times the analytic perspective division).  Each pixel row
depends on 18 parameters (its camera's X, Y, its image's M), each prior row on one
(:attr:`ImageProblem.sparsity`).

Minimisers (``solver``): ``"lm"`` (default) is Levenberg-Marquardt on the normal equations
with the per-image 6x6 mocap blocks eliminated by the Schur complement, as bundle adjusters
do: a (6(m+1))^2 system per iteration, cost linear in the points (about 0.6 s for 4 cameras x
40 images x 48 points).  ``"scipy"`` hands the same residuals and sparse CSR Jacobian to
:func:`scipy.optimize.least_squares` (trust-region reflective, LSMR inner solver, ``x_scale``
set to the expected size of each correction); it reaches the same optimum, but LSMR on this
badly scaled problem (pixels against sub-millimetre mocap priors) makes it 10-50x slower,
beyond the 5 s budget of issue 4 for the demo rig.

Covariance: ``kappa (J^T J)^-1`` restricted to X and Y by the Schur complement of the
block-diagonal per-image part (which marginalises the mocap poses), with ``J`` the Jacobian of
the sigma-normalised residuals at the optimum and ``kappa = E[psi^2] / E[psi']^2`` the
asymptotic efficiency factor of the robust loss for Gaussian residuals (1 for the linear
loss: the Cramér-Rao bound, :func:`multieye.estimate.uncertainty.cramer_rao_bound`).  When the pixel
noise is not given it is estimated from the data by variance-component estimation: the
robust sum of squared pixel residuals over their redundancy ``n_pixel - (n_params -
tr(H_prior))`` (the share of the parameters the mocap priors do not already pay for), and the
problem is re-solved with it until the estimate settles.  Like every covariance from a
linearised model this one covers the measurement noise only: not errors in the intrinsics,
unsynchronised clocks, a non-rigid rig, or outliers that the robust loss did not catch.

Synopsis
--------
>>> from multieye.estimate.refine_images import refine_images
>>> res = refine_images("eye-to-base", observations, intrinsics, sol.X, sol.Y)  # doctest: +SKIP
>>> res.X, res.camera_rms_px, res.covariance.shape                               # doctest: +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.stats import chi2

from multieye.core.errors import InputError
from multieye.core.geometry import make_transform
from multieye.core.intrinsics import Intrinsics
from multieye.core.lie import exp_so3, left_jacobian
from multieye.core.robust_loss import LOSSES, gaussian_kappa, rho, robust_cost
from multieye.core.problem import SETUPS

__all__ = [
    "refine_images",
    "RefinementResult",
    "ImageProblem",
    "project_with_jacobian",
    "DEFAULT_MOCAP_ROT_SIGMA_RAD",
    "DEFAULT_MOCAP_TRANS_SIGMA_M",
    "DEFAULT_F_SCALE",
    "OUTLIER_PROBABILITY",
    "SOLVERS",
]

F64 = NDArray[np.float64]

#: Rotation noise of an optical motion-capture pose, per rotation-vector component (0.1 deg).
DEFAULT_MOCAP_ROT_SIGMA_RAD = float(np.deg2rad(0.1))
#: Translation noise of an optical motion-capture pose, per coordinate (0.3 mm).
DEFAULT_MOCAP_TRANS_SIGMA_M = 0.3e-3
#: Where the robust loss departs from least squares, in standard deviations (Huber at 2 sigma
#: keeps 99 % of the efficiency of least squares on Gaussian noise).
DEFAULT_F_SCALE = 2.0
#: A point (2 residuals) or an image's mocap prior (6) is flagged as an outlier when its
#: squared normalised residual exceeds the chi-square quantile of this tail probability.
OUTLIER_PROBABILITY = 1e-4
#: Step of the central differences of the lens model, in normalised image coordinates.
_LENS_STEP = 1e-6
_MAX_SIGMA_PASSES = 6


def project_with_jacobian(points_cam: ArrayLike, intrinsics: Intrinsics) -> tuple[F64, F64]:
    """Pixels of camera-frame points and their derivative with respect to the points.

    Parameters
    ----------
    points_cam : array_like, shape (P, 3)
        Points in the camera frame (x right, y down, z forward), metres, ``z > 0``.
    intrinsics : Intrinsics
        Pinhole (any OpenCV distortion) or fisheye (equidistant).

    Returns
    -------
    uv : ndarray, shape (P, 2)
        Pixels (:func:`multieye.core.lens.project_points`); NaN behind the camera.
    J : ndarray, shape (P, 2, 3)
        ``d uv / d points_cam``, pixels per metre: the lens model's 2x2 derivative with respect
        to the normalised coordinates ``(x/z, y/z)`` by central differences (step 1e-6),
        times the analytic derivative of the perspective division.
    """
    from multieye.core.lens import distort_points

    P = np.asarray(points_cam, dtype=np.float64).reshape(-1, 3)
    z = P[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = P[:, :2] / z[:, None]
    xy = np.where((z > 0)[:, None], xy, np.nan)
    h = _LENS_STEP
    n = len(P)
    stacked = np.concatenate([xy, xy + [h, 0.0], xy - [h, 0.0], xy + [0.0, h], xy - [0.0, h]])
    out = distort_points(stacked, intrinsics).reshape(5, n, 2)
    uv = out[0]
    D = np.stack([(out[1] - out[2]) / (2 * h), (out[3] - out[4]) / (2 * h)], axis=-1)  # (n,2,2)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_z = 1.0 / z
    Pi = np.zeros((n, 2, 3))
    Pi[:, 0, 0] = inv_z
    Pi[:, 1, 1] = inv_z
    Pi[:, 0, 2] = -xy[:, 0] * inv_z
    Pi[:, 1, 2] = -xy[:, 1] * inv_z
    return uv, D @ Pi


@dataclass(frozen=True)
class RefinementResult:
    """Result of :func:`refine_images`.

    Attributes
    ----------
    X : ndarray, shape (m, 4, 4)
        ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand), metres.
    Y : ndarray, shape (4, 4)
        ``T_marker_target`` (eye-to-base) or ``T_world_target`` (eye-on-hand).
    covariance : ndarray, shape (6(m+1), 6(m+1))
        Covariance of the perturbations of X^0..X^{m-1} then Y, each (rotation vector,
        translation) with ``R = Exp(phi) R_hat``, ``t = t_hat + tau`` (radians, metres), the
        per-image mocap poses marginalised (module docstring).
    T_world_mocap : tuple of ndarray, shape (N_j, 4, 4)
        Refined motion-capture poses (``T_world_marker`` or ``T_world_body``) per camera.
    image_rms_px : tuple of ndarray, shape (N_j,)
        Reprojection RMS of every image (root mean square of the point distances), pixels.
    camera_rms_px : ndarray, shape (m,)
        Reprojection RMS over all points of each camera, pixels.
    point_weights : tuple of tuple of ndarray, shape (n_i,)
        Per camera, per image: the robust loss's weight of each point (the smaller of its two
        coordinates' IRLS weights ``rho'``; 1 = full least-squares weight; NaN for points left
        out for non-finite coordinates).
    point_outliers : tuple of tuple of ndarray, shape (n_i,), bool
        Points whose squared normalised residual exceeds the chi-square (2 dof) quantile of
        :data:`OUTLIER_PROBABILITY`.
    image_outliers : tuple of ndarray, shape (N_j,), bool
        Images with more than half their points flagged, or whose mocap pose had to move
        further from its measurement than the chi-square (6 dof) quantile allows.
    pixel_sigma : float
        Pixel noise used, pixels (given, or estimated from the data).
    pixel_sigma_estimated : bool
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float
        Motion-capture noise used.
    loss : str
    f_scale : float
        Threshold of the robust loss, in standard deviations.
    iterations : int
        Jacobian evaluations (trust-region iterations) over all passes.
    evaluations : int
        Residual evaluations over all passes.
    passes : int
        Optimisations run (more than one when the pixel noise is estimated).
    time_s : float
        Wall time, seconds.
    converged : bool
        Whether scipy reported convergence in the last pass.
    message : str
        scipy's status message of the last pass.
    """

    X: F64
    Y: F64
    covariance: F64
    T_world_mocap: tuple[F64, ...]
    image_rms_px: tuple[F64, ...]
    camera_rms_px: F64
    point_weights: tuple[tuple[F64, ...], ...]
    point_outliers: tuple[tuple[NDArray[np.bool_], ...], ...]
    image_outliers: tuple[NDArray[np.bool_], ...]
    pixel_sigma: float
    pixel_sigma_estimated: bool
    mocap_rot_sigma_rad: float
    mocap_trans_sigma_m: float
    loss: str
    f_scale: float
    iterations: int
    evaluations: int
    passes: int
    time_s: float
    converged: bool
    message: str


def _as_pose(T, what: str) -> F64:
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InputError(f"{what} must be a finite 4x4 transform, got shape {T.shape}")
    return T


class ImageProblem:
    """The stacked image-level problem: data layout, residuals, Jacobian, information.

    Parameters are ``[X^0 .. X^{m-1}, Y, M_0 .. M_{N-1}]``, 6 each (module docstring), with
    the images numbered camera by camera.  Residuals are the pixel residuals (u, v of every
    point, camera by camera, image by image) divided by ``sigma_px``, then 6 per image for the
    mocap prior.

    Parameters
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    observations : sequence over cameras of sequence of (object_points, image_points, T_world_mocap)
        See :func:`refine_images`.
    intrinsics : sequence of Intrinsics
        One per camera.
    names : sequence of str, optional
        Camera names for messages.
    """

    def __init__(self, setup: str, observations: Sequence, intrinsics: Sequence[Intrinsics],
                 names: Sequence[str] | None = None):
        if setup not in SETUPS:
            raise InputError(f"setup must be one of {SETUPS}, got {setup!r}")
        observations = list(observations)
        intrinsics = list(intrinsics)
        m = len(observations)
        if m == 0:
            raise InputError("no cameras given: observations is empty")
        if len(intrinsics) != m:
            raise InputError(f"{m} cameras of observations but {len(intrinsics)} intrinsics; "
                             "give one Intrinsics per camera")
        self.names = tuple(names) if names is not None else tuple(f"cam{j}" for j in range(m))
        self.setup = setup
        self.intrinsics = tuple(intrinsics)
        self.m = m
        obj, uv, mocap, img_of_point, cam_of_image, counts, keep = [], [], [], [], [], [], []
        for j, images in enumerate(observations):
            images = list(images)
            if not images:
                raise InputError(f"camera {self.names[j]} has no images")
            counts.append(len(images))
            for i, item in enumerate(images):
                where = f"camera {self.names[j]}, image {i}"
                try:
                    o, u, M = item
                except (TypeError, ValueError):
                    raise InputError(f"{where}: expected (object_points, image_points, "
                                     "T_world_mocap)") from None
                o = np.asarray(o, dtype=np.float64)
                u = np.asarray(u, dtype=np.float64)
                if o.ndim != 2 or o.shape[1] != 3 or u.shape != (len(o), 2):
                    raise InputError(f"{where}: object points must be (n, 3) and image points "
                                     f"(n, 2), got {o.shape} and {u.shape}")
                ok = np.all(np.isfinite(o), axis=1) & np.all(np.isfinite(u), axis=1)
                if not np.any(ok):
                    raise InputError(f"{where}: no finite target point")
                obj.append(o[ok])
                uv.append(u[ok])
                keep.append(ok)
                mocap.append(_as_pose(M, f"{where}: T_world_mocap"))
                img_of_point.append(np.full(int(ok.sum()), len(mocap) - 1))
                cam_of_image.append(j)
        self._keep = keep                                      # finite points of each image
        self.object_points = np.concatenate(obj)
        self.image_points = np.concatenate(uv)
        self.mocap_measured = np.stack(mocap)
        self.image = np.concatenate(img_of_point)              # (P,) image of each point
        self.cam_of_image = np.asarray(cam_of_image)           # (N,)
        self.camera = self.cam_of_image[self.image]            # (P,)
        self.counts = np.asarray(counts)                       # images per camera
        self.n_images = len(mocap)
        self.n_points = len(self.object_points)
        self.image_starts = np.flatnonzero(np.diff(self.image, prepend=-1))     # (N,)
        self.camera_slices = [slice(int(a), int(b)) for a, b in zip(
            np.searchsorted(self.camera, np.arange(m)),
            np.searchsorted(self.camera, np.arange(m), side="right"))]
        self._local = np.arange(self.n_points) - self.image_starts[self.image]
        self._n_max = int(self._local.max()) + 1
        self.k = 6 * (m + 1)                                   # X and Y parameters
        self.n_params = self.k + 6 * self.n_images
        self._build_structure()

    # --- layout ------------------------------------------------------------------------

    def _build_structure(self) -> None:
        """CSR indices: 18 entries per pixel row (X, Y, M blocks, ascending), 1 per prior row."""
        P, m = self.n_points, self.m
        cols = np.concatenate([6 * self.camera[:, None] + np.arange(6),
                               np.broadcast_to(6 * m + np.arange(6), (P, 6)),
                               self.k + 6 * self.image[:, None] + np.arange(6)], axis=1)
        pix_cols = np.repeat(cols[:, None, :], 2, axis=1).reshape(-1)          # (2P * 18,)
        prior_cols = self.k + np.arange(6 * self.n_images)
        self._indices = np.concatenate([pix_cols, prior_cols]).astype(np.int32)
        n_pix = 2 * P
        self._indptr = np.concatenate([np.arange(n_pix + 1) * 18,
                                       n_pix * 18 + 1 + np.arange(6 * self.n_images)]
                                      ).astype(np.int64)
        self.n_residuals = n_pix + 6 * self.n_images

    def pad(self, per_point: F64) -> F64:
        """Per-point rows (P, 2, c) to zero-padded per-image blocks (N, 2 n_max, c)."""
        out = np.zeros((self.n_images, self._n_max, 2, per_point.shape[-1]))
        out[self.image, self._local] = per_point
        return out.reshape(self.n_images, 2 * self._n_max, -1)

    @property
    def sparsity(self) -> sp.csr_matrix:
        """Structural non-zeros of the Jacobian, (n_residuals, n_params)."""
        return sp.csr_matrix((np.ones(self._indices.size), self._indices, self._indptr),
                             shape=(self.n_residuals, self.n_params))

    def split_images(self, arr: np.ndarray) -> tuple[np.ndarray, ...]:
        """Per-image array (N, ...) to one array per camera."""
        return tuple(np.split(arr, np.cumsum(self.counts)[:-1]))

    def split_points(self, arr: np.ndarray, fill) -> tuple[tuple[np.ndarray, ...], ...]:
        """Per-point array (P,) to per camera, per image arrays over the input's points.

        Points left out for non-finite coordinates get ``fill``.
        """
        per_image = []
        for values, ok in zip(np.split(arr, self.image_starts[1:]), self._keep):
            full = np.full(ok.shape, fill, dtype=arr.dtype)
            full[ok] = values
            per_image.append(full)
        bounds = np.concatenate([[0], np.cumsum(self.counts)])
        return tuple(tuple(per_image[bounds[j]:bounds[j + 1]]) for j in range(self.m))

    # --- state -------------------------------------------------------------------------

    def poses(self, p: F64, X0: F64, Y0: F64) -> tuple[F64, F64, F64]:
        """X (m, 4, 4), Y (4, 4) and mocap poses M (N, 4, 4) at parameters ``p``."""
        q = np.asarray(p, dtype=np.float64)
        xy = q[:self.k].reshape(self.m + 1, 6)
        T0 = np.concatenate([X0, Y0[None]])
        T = make_transform(exp_so3(xy[:, :3]) @ T0[:, :3, :3], T0[:, :3, 3] + xy[:, 3:])
        pm = q[self.k:].reshape(self.n_images, 6)
        Mm = self.mocap_measured
        M = make_transform(Mm[:, :3, :3] @ exp_so3(pm[:, :3]), Mm[:, :3, 3] + pm[:, 3:])
        return T[:self.m], T[self.m], M

    def _chain(self, X: F64, Y: F64, M: F64):
        """Camera-frame points and the intermediate quantities the Jacobian needs."""
        c, i = self.camera, self.image
        RY, tY = Y[:3, :3], Y[:3, 3]
        RM, tM = M[:, :3, :3], M[:, :3, 3]
        RXt = np.swapaxes(X[:, :3, :3], 1, 2)
        ry = self.object_points @ RY.T                  # R_Y p (P, 3)
        py = ry + tY                                    # point in the marker / world frame
        if self.setup == "eye-to-base":
            q = np.einsum("pij,pj->pi", RM[i], py) + tM[i]                 # world
        else:
            q = np.einsum("pji,pj->pi", RM[i], py - tM[i])                 # body
        d = q - X[c, :3, 3]
        pc = np.einsum("pij,pj->pi", RXt[c], d)
        return pc, ry, py, q, d, RXt

    def project(self, pc: F64, with_jacobian: bool = False):
        """Pixels (P, 2) of camera-frame points, camera by camera (and d uv / d pc)."""
        uv = np.empty((self.n_points, 2))
        J = np.empty((self.n_points, 2, 3)) if with_jacobian else None
        for j, s in enumerate(self.camera_slices):
            if with_jacobian:
                uv[s], J[s] = project_with_jacobian(pc[s], self.intrinsics[j])
            else:
                from multieye.core.lens import project_points
                uv[s] = project_points(pc[s], self.intrinsics[j])
        return uv, J

    def pixel_residuals(self, X: F64, Y: F64, M: F64) -> F64:
        """Raw pixel residuals ``projected - observed``, (P, 2), pixels."""
        pc = self._chain(X, Y, M)[0]
        return self.project(pc)[0] - self.image_points

    def prior_residuals(self, p: F64) -> F64:
        """Mocap prior residuals ``(phi, tau)`` per image, (N, 6), radians and metres."""
        return np.asarray(p, dtype=np.float64)[self.k:].reshape(self.n_images, 6)

    # --- least squares -----------------------------------------------------------------

    def residuals(self, p: F64, X0: F64, Y0: F64, sigmas: F64) -> F64:
        """Normalised residual vector (n_residuals,); ``sigmas = (px, rot, trans)``."""
        X, Y, M = self.poses(p, X0, Y0)
        r_pix = self.pixel_residuals(X, Y, M) / sigmas[0]
        prior = self.prior_residuals(p) / np.repeat(sigmas[1:], 3)
        return np.concatenate([r_pix.ravel(), prior.ravel()])

    def jacobian_blocks(self, p: F64, X0: F64, Y0: F64, sigma_px: float) -> F64:
        """Per-point blocks (P, 2, 18) of the normalised pixel residuals' Jacobian.

        Columns: phi_X, tau_X of the point's camera, phi_Y, tau_Y, phi_M, tau_M of its image.
        With ``Jp = d uv / d p_cam`` and ``a^T [v]_x = (a x v)^T`` row by row::

            d/d phi_X = Jp R_X^T [d]_x J_l(phi_X)      d/d tau_X = -Jp R_X^T
            d/d phi_Y = -Jp G [R_Y p]_x J_l(phi_Y)     d/d tau_Y = Jp G
            eye-to-base:  d/d phi_M = -Jp G [p_y]_x J_r(phi_M),   d/d tau_M = Jp R_X^T
            eye-on-hand:  d/d phi_M = Jp R_X^T [q]_x J_r(phi_M),  d/d tau_M = -Jp G

        where ``p_y = Y p`` (marker or world frame), ``q`` the point in the world
        (eye-to-base) or body (eye-on-hand) frame, ``d = q - t_X`` and ``G = d p_cam / d p_y``
        (``R_X^T R_M`` or ``R_X^T R_M^T``).
        """
        q = np.asarray(p, dtype=np.float64)
        X, Y, M = self.poses(q, X0, Y0)
        pc, ry, py, qm, d, RXt = self._chain(X, Y, M)
        _, Jp = self.project(pc, with_jacobian=True)                     # (P, 2, 3)
        c, i = self.camera, self.image
        xy = q[:self.k].reshape(self.m + 1, 6)
        JlX = left_jacobian(xy[:self.m, :3])                            # (m, 3, 3)
        JlY = left_jacobian(xy[self.m, :3])                             # (3, 3)
        JrM = np.swapaxes(left_jacobian(q[self.k:].reshape(-1, 6)[:, :3]), 1, 2)[i]
        RM = M[:, :3, :3][i]
        JpR = Jp @ RXt[c]                                                # d uv / d q
        JpG = JpR @ (RM if self.setup == "eye-to-base" else np.swapaxes(RM, 1, 2))
        blk = np.empty((self.n_points, 2, 18))
        rot_x = np.cross(JpR, d[:, None, :])
        for j, s in enumerate(self.camera_slices):
            blk[s, :, 0:3] = rot_x[s] @ JlX[j]
        blk[:, :, 3:6] = -JpR
        blk[:, :, 6:9] = -np.cross(JpG, ry[:, None, :]) @ JlY
        blk[:, :, 9:12] = JpG
        if self.setup == "eye-to-base":
            blk[:, :, 12:15] = -np.cross(JpG, py[:, None, :]) @ JrM
            blk[:, :, 15:18] = JpR
        else:
            blk[:, :, 12:15] = np.cross(JpR, qm[:, None, :]) @ JrM
            blk[:, :, 15:18] = -JpG
        return blk / sigma_px

    def jacobian(self, p: F64, X0: F64, Y0: F64, sigmas: F64) -> sp.csr_matrix:
        """Analytic sparse Jacobian (n_residuals, n_params) of :meth:`residuals`."""
        blk = self.jacobian_blocks(p, X0, Y0, sigmas[0])
        prior = np.tile(1.0 / np.repeat(sigmas[1:], 3), self.n_images)
        data = np.concatenate([blk.reshape(-1), prior])
        return sp.csr_matrix((data, self._indices, self._indptr),
                             shape=(self.n_residuals, self.n_params))

    # --- information -------------------------------------------------------------------

    def information(self, blk: F64, prior_info: F64):
        """Blocks of ``J^T J``: U (k, k) of X and Y, W (N, 12, 6), V (N, 6, 6).

        Parameters
        ----------
        blk : ndarray, shape (P, 2, 18)
            Per-point Jacobian blocks (:meth:`jacobian_blocks`), weighted if need be.
        prior_info : ndarray, shape (N, 6) or (6,)
            Information each mocap prior adds to the diagonal of its image's block.

        ``W[i]`` couples image i's mocap pose with its camera's X (rows 0-5) and Y (6-11).
        """
        B = self.pad(blk)                                                # (N, 2 n_max, 18)
        per_image = np.swapaxes(B, 1, 2) @ B                             # (N, 18, 18)
        V = per_image[:, 12:, 12:].copy()
        V[:, np.arange(6), np.arange(6)] += prior_info
        U = self._scatter_xy(per_image[:, :12, :12])
        return U, per_image[:, :12, 12:], V

    def _scatter_xy(self, blocks: F64) -> F64:
        """Sum per-image (N, 12, 12) blocks over (X of the image's camera, Y) into (k, k)."""
        m = self.m
        U = np.zeros((self.k, self.k))
        for j in range(m):
            sel = blocks[self.cam_of_image == j].sum(axis=0)
            x = slice(6 * j, 6 * j + 6)
            U[x, x] += sel[:6, :6]
            U[x, 6 * m:] += sel[:6, 6:]
            U[6 * m:, x] += sel[6:, :6]
            U[6 * m:, 6 * m:] += sel[6:, 6:]
        return U

    def _xy_rows(self) -> np.ndarray:
        """Parameter indices (N, 12) of each image's camera X and of Y."""
        return np.concatenate([6 * self.cam_of_image[:, None] + np.arange(6),
                               np.broadcast_to(6 * self.m + np.arange(6), (self.n_images, 6))],
                              axis=1)

    def schur(self, U: F64, W: F64, V: F64):
        """Reduced system ``S = U - W V^-1 W^T`` (k, k), with ``V^-1`` and ``W V^-1`` per image."""
        Vinv = np.linalg.inv(V)
        WVi = W @ Vinv                                                  # (N, 12, 6)
        S = U - self._scatter_xy(WVi @ np.swapaxes(W, 1, 2))
        return S, Vinv, WVi

    def marginal(self, blk: F64, prior_info: F64):
        """Covariance of X and Y with the mocap poses marginalised, and of each mocap pose.

        Returns
        -------
        cov_xy : ndarray, shape (k, k)
            ``(U - W V^-1 W^T)^-1``: the X-and-Y block of ``(J^T J)^-1``.
        cov_m : ndarray, shape (N, 6, 6)
            Diagonal blocks of ``(J^T J)^-1`` of the mocap poses.
        """
        S, Vinv, WVi = self.schur(*self.information(blk, prior_info))
        cov_xy = np.linalg.inv(S)
        cov_xy = 0.5 * (cov_xy + cov_xy.T)
        idx = self._xy_rows()
        C = cov_xy[idx[:, :, None], idx[:, None, :]]                    # (N, 12, 12)
        cov_m = Vinv + np.swapaxes(WVi, 1, 2) @ C @ WVi
        return cov_xy, cov_m

    def gradient(self, blk: F64, f: F64, prior_jac: F64) -> F64:
        """``J^T f`` (n_params,) for pixel blocks ``blk`` and residuals ``f`` (both weighted)."""
        P = self.n_points
        fp = self.pad(f[:2 * P].reshape(P, 2, 1))                           # (N, 2 n_max, 1)
        per_image = (np.swapaxes(self.pad(blk), 1, 2) @ fp)[..., 0]         # (N, 18)
        g = np.zeros(self.n_params)
        np.add.at(g, self._xy_rows(), per_image[:, :12])
        g[self.k:] = (per_image[:, 12:] + f[2 * P:].reshape(-1, 6) * prior_jac).ravel()
        return g

    def step(self, U: F64, W: F64, V: F64, g: F64) -> F64:
        """Solution of ``[[U, W], [W^T, V]] dp = -g`` by the Schur complement (n_params,)."""
        S, Vinv, WVi = self.schur(U, W, V)
        gm = g[self.k:].reshape(-1, 6)
        idx = self._xy_rows()
        rhs = -g[:self.k]
        np.add.at(rhs, idx, np.einsum("nij,nj->ni", WVi, gm))
        dxy = np.linalg.solve(S, rhs)
        dm = -np.einsum("nij,nj->ni", Vinv, gm + np.einsum("nji,nj->ni", W, dxy[idx]))
        return np.concatenate([dxy, dm.ravel()])


def _minimize_lm(problem: ImageProblem, p: F64, X0: F64, Y0: F64, sigmas: F64, loss: str,
                 f_scale: float, max_iter: int, tol: float):
    """Levenberg-Marquardt on the robust cost, normal equations reduced by the Schur complement.

    Each iteration weights the residuals by the loss's IRLS weights ``rho'`` (which makes
    the weighted Gauss-Newton step a descent direction of scipy's robust cost
    ``f_scale^2 sum rho(f^2 / f_scale^2) / 2``), damps the diagonal of ``J^T W J`` by
    ``lambda``, eliminates the per-image mocap blocks (6x6 each), solves the (6(m+1))^2
    reduced system for X and Y, back-substitutes the mocap steps, and accepts the step when
    the robust cost decreases.  Cost per iteration: linear in the points.

    Returns
    -------
    p : ndarray
        Final parameters.
    iterations, evaluations : int
    converged : bool
    message : str
    """
    P = problem.n_points
    prior_jac = np.tile(1.0 / np.repeat(sigmas[1:], 3), problem.n_images).reshape(-1, 6)
    f = problem.residuals(p, X0, Y0, sigmas)
    cost = robust_cost(f, loss, f_scale)
    lam = 1e-4
    evaluations, iterations = 1, 0
    for iterations in range(1, max_iter + 1):
        w = rho((f / f_scale) ** 2, loss)[1]
        sw = np.sqrt(w)
        blk = problem.jacobian_blocks(p, X0, Y0, sigmas[0]) * sw[:2 * P].reshape(P, 2, 1)
        prior_w = w[2 * P:].reshape(-1, 6) * prior_jac ** 2
        U, W, V = problem.information(blk, prior_w)
        g = problem.gradient(blk, sw * f, prior_jac * sw[2 * P:].reshape(-1, 6))
        dU, dV = np.diag(U).copy(), np.diagonal(V, axis1=1, axis2=2).copy()
        while True:
            Ud = U + lam * np.diag(dU)
            Vd = V.copy()
            Vd[:, np.arange(6), np.arange(6)] += lam * dV
            dp = problem.step(Ud, W, Vd, g)
            f_new = problem.residuals(p + dp, X0, Y0, sigmas)
            evaluations += 1
            cost_new = (robust_cost(f_new, loss, f_scale) if np.all(np.isfinite(f_new))
                        else np.inf)
            if cost_new <= cost:
                break
            lam *= 10.0
            if lam > 1e10:
                return p, iterations, evaluations, True, "no further decrease of the cost"
        decrease = cost - cost_new
        p, f, cost = p + dp, f_new, cost_new
        lam = max(lam / 10.0, 1e-12)
        if decrease <= tol * cost:
            return p, iterations, evaluations, True, "relative decrease of the cost below tol"
    return p, iterations, evaluations, False, f"stopped after {max_iter} iterations"


def _minimize_scipy(problem: ImageProblem, p: F64, X0: F64, Y0: F64, sigmas: F64, loss: str,
                    f_scale: float, max_iter: int, tol: float):
    """The same minimisation with :func:`scipy.optimize.least_squares` (trf, LSMR).

    ``x_scale``: 0.01 (radians, metres) for X and Y, the mocap noise for the mocap poses:
    the size of the corrections each parameter is expected to need, so that the first trust
    region already admits them.
    """
    xs = np.concatenate([np.full(problem.k, 1e-2),
                         np.tile(np.repeat(sigmas[1:], 3), problem.n_images)])
    res = least_squares(problem.residuals, p, jac=problem.jacobian, args=(X0, Y0, sigmas),
                        method="trf", tr_solver="lsmr", x_scale=xs, loss=loss,
                        f_scale=f_scale, ftol=tol, xtol=tol, gtol=tol, max_nfev=max_iter)
    return res.x, int(res.njev or 0), int(res.nfev), bool(res.status > 0), str(res.message)


#: Minimisers of :func:`refine_images` by name.
SOLVERS = {"lm": _minimize_lm, "scipy": _minimize_scipy}


def _check_sigma(value, name: str) -> float:
    v = float(value)
    if not (np.isfinite(v) and v > 0):
        raise InputError(f"{name} must be a positive number, got {value!r}")
    return v


def _gaussian_scale_constant(loss: str, f_scale: float) -> float:
    """``E[w(x) x^2]`` for standard normal x, with the IRLS weight ``w = rho'(x^2 / f^2)``."""
    if loss == "linear":
        return 1.0
    x, wq = np.polynomial.hermite_e.hermegauss(201)
    wq = wq / wq.sum()
    w = rho((x / f_scale) ** 2, loss)[1]
    return float(wq @ (w * x ** 2))


def refine_images(setup: str, observations: Sequence, intrinsics: Sequence[Intrinsics],
                  X0: ArrayLike, Y0: ArrayLike, *,
                  mocap_rot_sigma_rad: float = DEFAULT_MOCAP_ROT_SIGMA_RAD,
                  mocap_trans_sigma_m: float = DEFAULT_MOCAP_TRANS_SIGMA_M,
                  pixel_sigma: float | None = None, loss: str = "huber",
                  f_scale: float = DEFAULT_F_SCALE, names: Sequence[str] | None = None,
                  solver: str = "lm", max_iter: int = 100, tol: float = 1e-8
                  ) -> RefinementResult:
    """Maximum-likelihood refinement of every ``X^j`` and ``Y`` from pixels and mocap poses.

    Parameters
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
        DESIGN.md section 2.
    observations : sequence over cameras of sequence over images
        ``observations[j][i] = (object_points, image_points, T_world_mocap)``: the target
        points seen in image i of camera j, shape (n, 3), metres in the ``target`` frame;
        their pixels, shape (n, 2); and the motion-capture pose at that image's time, (4, 4):
        ``T_world_marker`` (eye-to-base) or ``T_world_body`` (eye-on-hand).  Rows with
        non-finite coordinates are left out.
    intrinsics : sequence of Intrinsics
        One per camera (pinhole or fisheye), held fixed.
    X0 : array_like, shape (m, 4, 4)
        Starting ``T_world_cam`` / ``T_body_cam`` (the closed form, :func:`multieye.solve`).
    Y0 : array_like, shape (4, 4)
        Starting ``T_marker_target`` / ``T_world_target``.
    mocap_rot_sigma_rad : float
        Standard deviation of each component of the rotation-vector error of a motion-capture
        pose, in the marker (body) frame, radians.  Default 0.1 degrees.
    mocap_trans_sigma_m : float
        Standard deviation of each coordinate of its position error, metres.  Default 0.3 mm.
    pixel_sigma : float, optional
        Standard deviation of each pixel coordinate of a detected target point.  Estimated
        from the data when not given (module docstring), and the covariance scaled with it.
    loss : {"huber", "linear", "soft_l1", "cauchy", "arctan"}
        scipy's robust loss, applied to every normalised residual component.
    f_scale : float
        Threshold of the loss in standard deviations (default 2: 99 % efficient on Gaussian
        noise, so the covariance stays within 1 % of the Cramér-Rao bound).
    names : sequence of str, optional
        Camera names for messages.
    solver : {"lm", "scipy"}
        ``"lm"``: Levenberg-Marquardt with the mocap poses eliminated by the Schur complement
        (bundle-adjustment style, cost linear in the points).  ``"scipy"``:
        :func:`scipy.optimize.least_squares` (trf) with the same sparse analytic Jacobian;
        same optimum, but its LSMR inner solver makes it 10-50x slower on this problem.
    max_iter : int
        Iterations (``"lm"``) or residual evaluations (``"scipy"``) per pass at most.
    tol : float
        Stop when an iteration lowers the cost by less than ``tol`` times the cost
        (``ftol``, ``xtol`` and ``gtol`` for ``"scipy"``); 1e-8 leaves the parameters within
        about 1 % of a standard deviation of the optimum.  While the pixel noise is still
        being estimated, passes stop at ``sqrt(tol)``.

    Returns
    -------
    RefinementResult

    Raises
    ------
    InputError
        Unknown setup, loss or solver, mismatched counts, malformed points or poses, non-positive
        noise levels, or target points behind a camera at the starting estimate.

    Examples
    --------
    >>> from multieye.sim.images import simulate_images
    >>> sc = simulate_images(0, n_cameras=2, images=8)
    >>> import multieye
    >>> sol = multieye.solve(sc.A, sc.B)
    >>> res = refine_images(sc.setup, sc.observations, sc.intrinsics, sol.X, sol.Y)
    >>> bool(res.converged), res.covariance.shape
    (True, (18, 18))
    """
    start = time.perf_counter()
    if loss not in LOSSES:
        raise InputError(f"unknown loss {loss!r}; expected one of {', '.join(LOSSES)}")
    if solver not in SOLVERS:
        raise InputError(f"unknown solver {solver!r}; expected one of {', '.join(SOLVERS)}")
    f_scale = _check_sigma(f_scale, "f_scale")
    s_rot = _check_sigma(mocap_rot_sigma_rad, "mocap_rot_sigma_rad")
    s_t = _check_sigma(mocap_trans_sigma_m, "mocap_trans_sigma_m")
    estimate = pixel_sigma is None
    s_px = None if estimate else _check_sigma(pixel_sigma, "pixel_sigma")
    problem = ImageProblem(setup, observations, intrinsics, names)
    X0 = np.asarray(X0, dtype=np.float64)
    Y0 = _as_pose(Y0, "Y0")
    if X0.shape != (problem.m, 4, 4) or not np.all(np.isfinite(X0)):
        raise InputError(f"X0 must be {problem.m} finite 4x4 transforms (one per camera), "
                         f"got shape {X0.shape}")
    p = np.zeros(problem.n_params)
    X, Y, M = problem.poses(p, X0, Y0)
    r0 = problem.pixel_residuals(X, Y, M)
    bad = ~np.all(np.isfinite(r0), axis=1)
    if np.any(bad):
        i = int(problem.image[np.argmax(bad)])
        j = int(problem.cam_of_image[i])
        local = i - int(np.sum(problem.counts[:j]))
        raise InputError(f"camera {problem.names[j]}, image {local}: target points project "
                         "behind the camera at the starting estimate; check X0, Y0, the setup "
                         f"({setup}) and the direction of T_world_mocap")
    if estimate:
        s_px = max(1.4826 * float(np.median(np.abs(r0))), 1e-3)

    kappa = gaussian_kappa(loss, f_scale)
    c_w = _gaussian_scale_constant(loss, f_scale)
    iterations = evaluations = passes = 0
    settled = False
    while True:
        sigmas = np.array([s_px, s_rot, s_t])
        final = not estimate or passes > 0 and settled
        p, its, evals, converged, message = SOLVERS[solver](
            problem, p, X0, Y0, sigmas, loss, f_scale, max_iter, tol if final else np.sqrt(tol))
        passes += 1
        iterations += its
        evaluations += evals
        if final:
            break
        # Variance-component estimate of the pixel noise (module docstring).
        prior_info = 1.0 / np.repeat(sigmas[1:], 3) ** 2
        _, cov_m = problem.marginal(problem.jacobian_blocks(p, X0, Y0, s_px), prior_info)
        h_prior = float(np.einsum("nii,i->", cov_m, prior_info))
        redundancy = 2 * problem.n_points - (problem.n_params - h_prior)
        X, Y, M = problem.poses(p, X0, Y0)
        z = problem.pixel_residuals(X, Y, M).ravel() / s_px
        w = rho((z / f_scale) ** 2, loss)[1]
        new = s_px * np.sqrt(float(w @ z ** 2) / (c_w * max(redundancy, 1.0)))
        settled = abs(new / s_px - 1.0) < 0.01 or passes >= _MAX_SIGMA_PASSES - 1
        s_px = new

    sigmas = np.array([s_px, s_rot, s_t])
    X, Y, M = problem.poses(p, X0, Y0)
    blk = problem.jacobian_blocks(p, X0, Y0, s_px)
    cov_xy, _ = problem.marginal(blk, 1.0 / np.repeat(sigmas[1:], 3) ** 2)
    r_pix = problem.pixel_residuals(X, Y, M)                              # (P, 2) pixels
    z = r_pix / s_px
    w_pt = rho((z / f_scale) ** 2, loss)[1].min(axis=1)
    d2 = np.sum(r_pix ** 2, axis=1)
    point_out = d2 / s_px ** 2 > chi2.isf(OUTLIER_PROBABILITY, 2)
    img_rms = np.sqrt(np.add.reduceat(d2, problem.image_starts)
                      / np.diff(np.append(problem.image_starts, problem.n_points)))
    prior = problem.prior_residuals(p) / np.repeat(sigmas[1:], 3)
    frac_out = (np.add.reduceat(point_out.astype(float), problem.image_starts)
                / np.diff(np.append(problem.image_starts, problem.n_points)))
    img_out = (frac_out > 0.5) | (np.sum(prior ** 2, axis=1) > chi2.isf(OUTLIER_PROBABILITY, 6))
    cam_rms = np.array([np.sqrt(np.mean(d2[s])) for s in problem.camera_slices])
    return RefinementResult(
        X=X, Y=Y, covariance=kappa * cov_xy, T_world_mocap=problem.split_images(M),
        image_rms_px=problem.split_images(img_rms), camera_rms_px=cam_rms,
        point_weights=problem.split_points(w_pt, np.nan),
        point_outliers=problem.split_points(point_out, False),
        image_outliers=problem.split_images(img_out), pixel_sigma=float(s_px),
        pixel_sigma_estimated=estimate, mocap_rot_sigma_rad=s_rot, mocap_trans_sigma_m=s_t,
        loss=loss, f_scale=f_scale, iterations=iterations, evaluations=evaluations,
        passes=passes, time_s=time.perf_counter() - start, converged=converged,
        message=message)
