"""The image-level problem as residual groups for the engine: target pixels and mocap priors.

What is measured are the target points' pixels and the motion-capture poses; with the true
motion-capture pose ``M_i`` of every image as a nuisance parameter (``T_world_marker``
eye-to-base, ``T_world_body`` eye-on-hand)::

    T_cam_target_i = inv(X^j) @ M_i @ Y          eye-to-base   (A_i = inv(M_i))
    T_cam_target_i = inv(X^j) @ inv(M_i) @ Y     eye-on-hand   (A_i = M_i)

i.e. ``T_cam_target = inv(X) inv(A) Y`` in both setups (docs/conventions.md, section 2).

Residual groups (:class:`multieye.optimize.blocks.ResidualGroup`):

- :class:`PixelResiduals`: per target point, ``(pi_j(T_cam_target_i p_k) - u_ik) / sigma_px``
  (2 components), touching its camera's ``X``, ``Y`` and its image's ``M``; one segment per
  image.  Jacobian: the lens model's ``d uv / d p_cam`` from OpenCV
  (:func:`multieye.core.lens.project_with_jacobian`) chained with the pose derivatives below.
- :class:`MocapPriors`: per image, ``(Log(R_meas^T R_M) / sigma_R, (t_M - t_meas) / sigma_t)``
  (6 components), touching ``M``; its Jacobian is ``diag(J_r^-1(r_R) / sigma_R, I / sigma_t)``.

Block families (:class:`multieye.optimize.blocks.Blocks`): ``X`` (m poses) and ``Y`` (one)
on ``se3-left``, ``R = Exp(phi) R_hat``, ``t = t_hat + tau`` (the covariance convention of
docs/conventions.md); ``M`` (one per image) on ``se3-right``, ``R_M = R Exp(phi)`` (rotation
noise in the marker/body frame, translation noise in the world frame: the noise model of
:class:`multieye.sim.rigs.GaussianNoise`), eliminated by the Schur complement.

Pose derivatives at zero perturbation, with ``p_y = R_Y p + t_Y`` (marker or world frame),
``q`` the point in the world (eye-to-base) or body (eye-on-hand) frame, ``d = q - t_X``,
``G = d p_cam / d p_y`` (``R_X^T R_M`` or ``R_X^T R_M^T``) and ``a^T [v]_x = (a x v)^T``::

    d p_cam / d phi_X = R_X^T [d]_x             d p_cam / d tau_X = -R_X^T
    d p_cam / d phi_Y = -G [R_Y p]_x            d p_cam / d tau_Y = G
    eye-to-base:  d p_cam / d phi_M = -G [p_y]_x,      d p_cam / d tau_M = R_X^T
    eye-on-hand:  d p_cam / d phi_M = R_X^T [q]_x,     d p_cam / d tau_M = -G
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, project_with_jacobian
from multieye.core.lie import left_jacobian_inv, log_so3
from multieye.core.problem import SETUPS
from multieye.optimize.blocks import Blocks, ResidualGroup

__all__ = ["ImageData", "PixelResiduals", "MocapPriors"]

F64 = NDArray[np.float64]


def _as_pose(T, what: str) -> F64:
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InputError(f"{what} must be a finite 4x4 transform, got shape {T.shape}")
    return T


class ImageData:
    """Target points, pixels and motion-capture poses of every image, stacked.

    Images are numbered camera by camera; points image by image.

    Parameters
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    observations : sequence over cameras of sequence of (object_points, image_points, T_world_mocap)
        ``observations[j][i]``: target points of image i of camera j, (n, 3), metres in the
        ``target`` frame; their pixels, (n, 2); the motion-capture pose at that image's
        time, (4, 4).  Points with non-finite coordinates are left out.
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
        if names is not None and len(names) != m:
            raise InputError(f"{len(names)} camera names for {m} cameras")
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
        self.keep = keep                                       # finite points of each image
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

    def families(self, X: F64, Y: F64, M: F64 | None = None) -> list[Blocks]:
        """Block families ``X`` (m), ``Y`` (1) and ``M`` (one per image; default measured)."""
        M = self.mocap_measured if M is None else M
        return [Blocks("X", X, "se3-left"), Blocks("Y", np.asarray(Y)[None], "se3-left"),
                Blocks("M", M, "se3-right", eliminate=True)]

    def groups(self, sigma_px: float, sigma_rot: float, sigma_t: float) -> list[ResidualGroup]:
        """The pixel residuals and the motion-capture priors at these noise levels."""
        return [PixelResiduals(self, sigma_px), MocapPriors(self.mocap_measured, sigma_rot,
                                                            sigma_t)]

    def split_images(self, arr: np.ndarray) -> tuple[np.ndarray, ...]:
        """Per-image array (N, ...) to one array per camera."""
        return tuple(np.split(arr, np.cumsum(self.counts)[:-1]))

    def split_points(self, arr: np.ndarray, fill) -> tuple[tuple[np.ndarray, ...], ...]:
        """Per-point array (P,) to per camera, per image arrays over the input's points.

        Points left out for non-finite coordinates get ``fill``.
        """
        per_image = []
        for values, ok in zip(np.split(arr, self.image_starts[1:]), self.keep):
            full = np.full(ok.shape, fill, dtype=arr.dtype)
            full[ok] = values
            per_image.append(full)
        bounds = np.concatenate([[0], np.cumsum(self.counts)])
        return tuple(tuple(per_image[bounds[j]:bounds[j + 1]]) for j in range(self.m))

    def where(self, image: int) -> str:
        """``camera NAME, image I`` of a global image number."""
        j = int(self.cam_of_image[image])
        return f"camera {self.names[j]}, image {image - int(np.sum(self.counts[:j]))}"


def _cross(a: F64, v: F64) -> F64:
    """Row-wise ``a x v`` for a (..., k, 3) against v (..., 3): ``a^T [v]_x`` per row."""
    v = v[..., None, :]
    return np.stack([a[..., 1] * v[..., 2] - a[..., 2] * v[..., 1],
                     a[..., 2] * v[..., 0] - a[..., 0] * v[..., 2],
                     a[..., 0] * v[..., 1] - a[..., 1] * v[..., 0]], axis=-1)


class PixelResiduals(ResidualGroup):
    """Target-point pixel residuals over ``sigma_px`` (module docstring), slots X, Y, M.

    The chain is evaluated image by image on zero-padded ``(N, n_max, 3)`` point arrays, so
    every rotation is one batched 3x3 product per image rather than per point, and
    :meth:`linearize` hands the engine the per-image Jacobian blocks directly.
    """

    def __init__(self, data: ImageData, sigma_px: float):
        index = np.column_stack([data.cam_of_image, np.zeros(data.n_images, int),
                                 np.arange(data.n_images)])
        super().__init__(("X", "Y", "M"), index, data.image, 2)
        self.data = data
        self.sigma = float(sigma_px)
        self._obj = np.zeros((data.n_images, self.longest, 3))
        self._obj[data.image, self.position] = data.object_points

    def _chain(self, X: F64, Y: F64, M: F64):
        """Per image (N, n_max, 3): ``R_Y p``, ``p_y``, ``q``, ``d`` and ``p_cam``."""
        c = self.data.cam_of_image
        RX, tX = X[c, :3, :3], X[c, :3, 3]
        RM, tM = M[:, :3, :3], M[:, :3, 3]
        ry = self._obj @ Y[:3, :3].T
        py = ry + Y[:3, 3]
        if self.data.setup == "eye-to-base":
            q = py @ np.swapaxes(RM, 1, 2) + tM[:, None]                # R_M p_y + t_M
        else:
            q = (py - tM[:, None]) @ RM                                  # R_M^T (p_y - t_M)
        d = q - tX[:, None]
        return ry, py, q, d, d @ RX                                      # p_cam = R_X^T d

    def _project(self, pc: F64, with_jacobian: bool):
        """Pixels (P, 2) of camera-frame points (P, 3), camera by camera (and d uv / d pc)."""
        dat = self.data
        uv = np.empty((dat.n_points, 2))
        J = np.empty((dat.n_points, 2, 3)) if with_jacobian else None
        for j, s in enumerate(dat.camera_slices):
            if with_jacobian:
                uv[s], J[s], _ = project_with_jacobian(pc[s], dat.intrinsics[j])
            else:
                uv[s] = project_points(pc[s], dat.intrinsics[j])
        return uv, J

    def camera_points(self, X: F64, Y: F64, M: F64) -> F64:
        """Every target point in its camera's frame, (P, 3), metres."""
        return self._chain(X, Y, M)[4][self.data.image, self.position]

    def _linear(self, values: Mapping[str, F64]):
        X, Y, M = values["X"], values["Y"][0], values["M"]
        dat = self.data
        ry, py, q, d, pc = self._chain(X, Y, M)
        uv, Jp = self._project(pc[dat.image, self.position], True)
        r = (uv - dat.image_points) / self.sigma
        N, n = len(M), self.longest
        Jp_pad = np.zeros((N, n, 2, 3))
        Jp_pad[dat.image, self.position] = Jp / self.sigma
        RX = X[dat.cam_of_image, :3, :3]
        RM = M[:, :3, :3]
        G = RX.swapaxes(1, 2) @ (RM if dat.setup == "eye-to-base" else RM.swapaxes(1, 2))
        JpR = (Jp_pad.reshape(N, 2 * n, 3) @ RX.swapaxes(1, 2)).reshape(N, n, 2, 3)   # d r/d q
        JpG = (Jp_pad.reshape(N, 2 * n, 3) @ G).reshape(N, n, 2, 3)                   # d r/d p_y
        if dat.setup == "eye-to-base":
            JM = [-_cross(JpG, py), JpR]
        else:
            JM = [_cross(JpR, q), -JpG]
        blocks = np.concatenate([_cross(JpR, d), -JpR, -_cross(JpG, ry), JpG] + JM, axis=3)
        return r, blocks                                                 # (N, n, 2, 18)

    def linearize(self, values: Mapping[str, F64]):
        r, blocks = self._linear(values)
        N, n = blocks.shape[:2]
        return r, blocks.reshape(N, 2 * n, 18), self.pad(r)

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        if jacobians:
            r, blocks = self._linear(values)
            rows = blocks[self.data.image, self.position]                # (P, 2, 18)
            return r, [rows[:, :, 0:6], rows[:, :, 6:12], rows[:, :, 12:18]]
        pc = self.camera_points(values["X"], values["Y"][0], values["M"])
        return (self._project(pc, False)[0] - self.data.image_points) / self.sigma, None


class MocapPriors(ResidualGroup):
    """Motion-capture pose priors (module docstring), one row of 6 per image, slot M.

    Parameters
    ----------
    measured : ndarray, shape (N, 4, 4)
        Measured motion-capture poses.
    sigma_rot, sigma_t : float
        Noise of each rotation-vector component (radians, marker/body frame) and of each
        position coordinate (metres, world frame).
    """

    def __init__(self, measured: F64, sigma_rot: float, sigma_t: float):
        n = len(measured)
        super().__init__(("M",), np.arange(n)[:, None], np.arange(n), 6)
        self.measured = measured
        self.scale = 1.0 / np.repeat([float(sigma_rot), float(sigma_t)], 3)

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        M, Mm = values["M"], self.measured
        r_rot = log_so3(np.swapaxes(Mm[:, :3, :3], 1, 2) @ M[:, :3, :3])
        r = np.concatenate([r_rot, M[:, :3, 3] - Mm[:, :3, 3]], axis=1) * self.scale
        if not jacobians:
            return r, None
        J = np.zeros((len(M), 6, 6))
        J[:, :3, :3] = left_jacobian_inv(-r_rot) * self.scale[0]        # J_r^-1(r_rot)
        J[:, 3:, 3:] = np.eye(3) * self.scale[3]
        return r, [J]
