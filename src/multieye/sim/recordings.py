"""Long recordings at the image level: many images per camera, most of them dull.

A real recording is uneven: the board is waved richly for a while and held, carried or
moved slowly the rest of the time.  :func:`simulate_recording` makes such a recording of a
rig (eye-to-base: the board, carrying the marker body, is moved in front of one camera after
the other) at a camera rate: in a ``rich_fraction`` of each camera's segment the board turns
by up to ``rich_rot_deg`` about every axis and moves ``rich_shift_m``, in the rest by
``dull_rot_deg`` and ``dull_shift_m``.  Pixels carry Gaussian noise; the motion capture
noise of :class:`multieye.sim.rigs.GaussianNoise`; ``T_cam_target`` is PnP on the noisy
pixels (:func:`multieye.sim.images.estimate_target_poses`).

Synopsis
--------
>>> from multieye.sim.recordings import simulate_recording
>>> rec = simulate_recording(0, n_cameras=2, images=100)
>>> rec.image_points[0].shape[0], rec.T_world_mocap[0].shape
(100, (100, 4, 4))
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.metrics import relative_extrinsics
from multieye.sim import rigs as sim
from multieye.sim.images import (
    _project,
    default_intrinsics,
    default_target_points,
    estimate_target_poses,
)

__all__ = ["RecordingScenario", "RecordingSpec", "simulate_recording"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class RecordingScenario:
    """A long eye-to-base recording with its truth.

    Attributes
    ----------
    X : ndarray, shape (m, 4, 4)
        True ``T_world_cam``.
    Y : ndarray, shape (4, 4)
        True ``T_marker_target``.
    stamps : tuple of ndarray, shape (N_j,)
        Image stamps per camera, seconds (one clock, no offset).
    T_world_mocap : tuple of ndarray, shape (N_j, 4, 4)
        Measured ``T_world_marker`` at each image.
    T_cam_target : tuple of ndarray, shape (N_j, 4, 4)
        PnP on the noisy pixels.
    object_points : ndarray, shape (n, 3)
    image_points : tuple of ndarray, shape (N_j, n, 2)
    intrinsics : tuple of Intrinsics
    rich : tuple of ndarray of bool, shape (N_j,)
        Images taken while the board was waved richly.
    pixel_sigma, mocap_rot_sigma_rad, mocap_trans_sigma_m : float
    """

    X: F64
    Y: F64
    stamps: tuple[F64, ...]
    T_world_mocap: tuple[F64, ...]
    T_cam_target: tuple[F64, ...]
    object_points: F64
    image_points: tuple[F64, ...]
    intrinsics: tuple[Intrinsics, ...]
    rich: tuple[NDArray[np.bool_], ...]
    pixel_sigma: float
    mocap_rot_sigma_rad: float
    mocap_trans_sigma_m: float

    setup = "eye-to-base"

    @property
    def T_ref_cam(self) -> F64:
        """True relative extrinsics, camera 0 the reference."""
        return relative_extrinsics(self.X)

    def observations(self, keep=None) -> tuple:
        """Input of :func:`multieye.estimate.refine_images.refine_images`, of the images
        ``keep[j]`` (boolean masks per camera; default all)."""
        out = []
        for j, (uv, M) in enumerate(zip(self.image_points, self.T_world_mocap)):
            idx = np.arange(len(M)) if keep is None else np.flatnonzero(keep[j])
            out.append(tuple((self.object_points, uv[i], M[i]) for i in idx))
        return tuple(out)

    def AB(self, keep=None) -> tuple[list[F64], list[F64]]:
        """``A = inv(T_world_marker)`` and ``B = inv(T_cam_target)`` per camera, of the
        images ``keep[j]``, for :func:`multieye.solve`."""
        A, B = [], []
        for j, (M, P) in enumerate(zip(self.T_world_mocap, self.T_cam_target)):
            idx = slice(None) if keep is None else np.flatnonzero(keep[j])
            A.append(g.inv(M[idx]))
            B.append(g.inv(P[idx]))
        return A, B


def _envelope(t: F64, duration: float, rich_fraction: float, rng: np.random.Generator) -> F64:
    """1 inside one rich stretch of ``rich_fraction * duration`` seconds (at a random place),
    0 elsewhere, with 1 s ramps."""
    length = rich_fraction * duration
    start = rng.uniform(0.0, max(duration - length, 0.0))
    ramp = np.clip(np.minimum(t - start, start + length - t) + 0.5, 0.0, 1.0)
    return ramp


@dataclass(frozen=True)
class RecordingSpec:
    """What :func:`simulate_recording` makes.

    Attributes
    ----------
    n_cameras : int
    images : int
        Images per camera.
    rate_hz : float
        Camera rate; each camera's segment lasts ``images / rate_hz`` seconds, 2 s apart.
    rich_fraction : float
        Share of each segment in which the board is waved richly, in (0, 1].
    rich_rot_deg, rich_shift_m, dull_rot_deg, dull_shift_m : float
        Amplitudes of the turns (degrees, about each axis) and of the shifts (metres).
    pixel_sigma, mocap_rot_sigma_rad, mocap_trans_sigma_m : float
        Noise levels.
    """

    n_cameras: int = 3
    images: int = 600
    rate_hz: float = 30.0
    rich_fraction: float = 0.2
    rich_rot_deg: float = 30.0
    rich_shift_m: float = 0.15
    dull_rot_deg: float = 3.0
    dull_shift_m: float = 0.03
    pixel_sigma: float = 0.3
    mocap_rot_sigma_rad: float = float(np.deg2rad(0.1))
    mocap_trans_sigma_m: float = 0.3e-3


def simulate_recording(rng: np.random.Generator | int | None = None,
                       spec: RecordingSpec = RecordingSpec(), **kw) -> RecordingScenario:
    """An uneven recording (module docstring) as ``spec`` says, its fields replaced by ``kw``.

    Returns
    -------
    RecordingScenario
    """
    spec = replace(spec, **kw)
    n_cameras, images, rate_hz, rich_fraction = (spec.n_cameras, spec.images, spec.rate_hz,
                                                 spec.rich_fraction)
    pixel_sigma = spec.pixel_sigma
    rng = np.random.default_rng(rng)
    if images < 3 or n_cameras < 1 or not 0 < rich_fraction <= 1 or rate_hz <= 0:
        raise InputError(f"a recording needs >= 3 images per camera, >= 1 camera, a rich "
                         f"fraction in (0, 1] and a positive rate, got {images}, {n_cameras}, "
                         f"{rich_fraction}, {rate_hz}")
    rig = sim.simulate_rig(rng, n_cameras=n_cameras, measurements=3, setup="eye-to-base")
    X, Y = rig.X, rig.Y
    pts = default_target_points()
    centre = np.array([pts[:, 0].max() / 2, pts[:, 1].max() / 2, 0.0])
    K = default_intrinsics("pinhole")
    noise = sim.GaussianNoise(spec.mocap_rot_sigma_rad, spec.mocap_trans_sigma_m)
    duration = images / rate_hz
    stamps, mocap, poses, uvs, rich = [], [], [], [], []
    t0 = 0.0
    for j in range(n_cameras):
        t = np.arange(images) / rate_hz
        env = _envelope(t, duration, rich_fraction, rng)
        freqs = rng.uniform(0.1, 0.5, size=6)
        phases = rng.uniform(0, 2 * np.pi, size=6)
        s = np.sin(2 * np.pi * freqs * t[:, None] + phases)                  # (N, 6)
        rot_amp = np.deg2rad(spec.dull_rot_deg + env * (spec.rich_rot_deg - spec.dull_rot_deg))
        shift_amp = spec.dull_shift_m + env * (spec.rich_shift_m - spec.dull_shift_m)
        rot = rot_amp[:, None] * s[:, :3]
        shift = shift_amp[:, None] * s[:, 3:] * np.array([1.0, 1.0, 1.3])
        R = g.transform_from_rotvec(rot, np.zeros_like(rot))[:, :3, :3]
        P = g.make_transform(R, np.array([0.0, 0.0, 1.0]) + shift - R @ centre)  # T_cam_target
        clean = np.stack([_project(pts, T, K) for T in P])
        noisy = clean + rng.normal(scale=pixel_sigma, size=clean.shape)
        M = noise.perturb(X[j] @ P @ g.inv(Y), rng)                          # T_world_marker
        stamps.append(t0 + t)
        mocap.append(M)
        uvs.append(noisy)
        poses.append(estimate_target_poses(pts, noisy, P, K))
        rich.append(env > 0.5)
        t0 += duration + 2.0
    return RecordingScenario(X=X, Y=Y, stamps=tuple(stamps), T_world_mocap=tuple(mocap),
                             T_cam_target=tuple(poses), object_points=pts,
                             image_points=tuple(uvs), intrinsics=(K,) * n_cameras,
                             rich=tuple(rich), pixel_sigma=float(pixel_sigma),
                             mocap_rot_sigma_rad=float(spec.mocap_rot_sigma_rad),
                             mocap_trans_sigma_m=float(spec.mocap_trans_sigma_m))
