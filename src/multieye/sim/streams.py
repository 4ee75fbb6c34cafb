"""A rig of cameras with their own clocks filming a board tracked by one motion-capture stream.

:func:`simulate_rig_stream` makes the image-level data of a continuous recording: every
camera's target points and noisy pixels at its own image times, stamped in its own clock, and
one noisy motion-capture stream in the motion-capture clock, with the ground truth (rig, ``Y``,
clock offsets, the noise-free trajectory).  The board (eye-to-base) or the rig (eye-on-hand)
moves as in :func:`multieye.sim.images.simulate_stream`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core.arguments import with_fields
from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.sim import rigs as sim
from multieye.sim.images import _smooth_board_motion, default_intrinsics, default_target_points

__all__ = ["RigStream", "simulate_rig_stream"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class RigStream:
    """Image-level data of a continuous recording (:func:`simulate_rig_stream`).

    Attributes
    ----------
    setup : str
    X : ndarray, shape (m, 4, 4)
        True ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand).
    Y : ndarray, shape (4, 4)
        True ``T_marker_target`` or ``T_world_target``.
    intrinsics : tuple of Intrinsics
        One per camera.
    observations : tuple over cameras of list of (object_points, image_points, T_world_mocap)
        Target points (48, 3) and noisy pixels (48, 2) of each image; the pose is the noisy
        motion-capture sample nearest the image's true time (what pairing without
        interpolation would give).
    image_stamps : tuple of ndarray, shape (N_j,)
        Each camera's image stamps in its own clock, seconds.
    mocap_stamps : ndarray, shape (L,)
        Motion-capture sample times (its clock), seconds.
    T_world_mocap : ndarray, shape (L, 4, 4)
        Measured (noisy) ``T_world_marker`` or ``T_world_body``.
    T_world_mocap_true : ndarray, shape (L, 4, 4)
        The same without noise.
    time_offsets_s : ndarray, shape (m,)
        True motion-capture clock minus each camera's clock, seconds.
    """

    setup: str
    X: F64
    Y: F64
    intrinsics: tuple[Intrinsics, ...]
    observations: tuple
    image_stamps: tuple[F64, ...]
    mocap_stamps: F64
    T_world_mocap: F64
    T_world_mocap_true: F64
    time_offsets_s: F64


@dataclass(frozen=True)
class RigStreamSpec:
    """The options of :func:`simulate_rig_stream` (see there), taken as one argument or as
    keyword arguments."""

    n_cameras: int = 2
    setup: sim.Setup = "eye-to-base"
    duration_s: float = 20.0
    camera_rate_hz: float = 4.0
    mocap_rate_hz: float = 200.0
    time_offsets_s: object = 0.0
    pixel_sigma: float = 0.5
    mocap_rot_sigma_rad: float = 1e-3
    mocap_trans_sigma_m: float = 0.3e-3
    interleaved: bool = True


def simulate_rig_stream(rng: np.random.Generator | int | None = None,
                        spec: RigStreamSpec = RigStreamSpec(), **kw) -> RigStream:
    """A rig of ``n_cameras`` with their own clocks and one motion-capture stream.

    Camera 0 is the rig of :func:`multieye.sim.rigs.simulate_rig` (one camera); camera j is
    camera 0 moved by a few degrees and centimetres, so that all see the board.  The cameras
    take images at ``camera_rate_hz``, interleaved in time (camera j a fraction ``j / m`` of a
    period after camera 0, so no two images are taken at the same instant) or, with
    ``interleaved=False``, all at the same instants (a hardware-triggered rig).

    Parameters
    ----------
    rng : numpy.random.Generator, int or None
    n_cameras : int
    setup : {"eye-to-base", "eye-on-hand"}
    duration_s : float
        Length of the recording, seconds; the motion capture covers it with 1 s to spare
        on each side.
    camera_rate_hz, mocap_rate_hz : float
    time_offsets_s : float or array_like, shape (m,)
        Motion-capture clock minus each camera's clock, seconds.
    pixel_sigma : float
        Pixel noise per coordinate.
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float
        Noise of each motion-capture sample (:class:`multieye.sim.rigs.GaussianNoise`:
        rotation in the marker/body frame, translation in the world frame).
    interleaved : bool
        Cameras take their images at different instants (default) or at the same ones.

    Returns
    -------
    RigStream
    """
    o = with_fields(spec, kw, RigStreamSpec, "spec")
    n_cameras, setup = o.n_cameras, o.setup
    duration_s, camera_rate_hz = o.duration_s, o.camera_rate_hz
    mocap_rate_hz, time_offsets_s = o.mocap_rate_hz, o.time_offsets_s
    pixel_sigma, mocap_rot_sigma_rad = o.pixel_sigma, o.mocap_rot_sigma_rad
    mocap_trans_sigma_m, interleaved = o.mocap_trans_sigma_m, o.interleaved
    rng = np.random.default_rng(rng)
    m = int(n_cameras)
    offsets = np.broadcast_to(np.asarray(time_offsets_s, dtype=np.float64), (m,)).copy()
    if m < 1 or duration_s <= 0 or camera_rate_hz <= 0 or mocap_rate_hz <= 0:
        raise InputError("need at least one camera, a positive duration and positive rates")
    rig = sim.simulate_rig(rng, n_cameras=1, measurements=3, setup=setup)
    X0, Y = rig.X[0], rig.Y
    D = [np.eye(4)] + [g.transform_from_rotvec(rng.normal(scale=np.deg2rad(3.0), size=3),
                                               rng.uniform(-0.08, 0.08, size=3))
                       for _ in range(m - 1)]
    X = np.stack([X0 @ d for d in D])
    phases = rng.uniform(0.0, 2.0 * np.pi, size=(2, 6))
    freqs = rng.uniform(0.05, 0.4, size=(2, 6))
    depth = rng.uniform(0.9, 1.4)

    def mocap_pose(tau):
        P = _smooth_board_motion(tau, phases, freqs, depth)         # T_cam0_target
        return X0 @ P @ g.inv(Y) if setup == "eye-to-base" else Y @ g.inv(P) @ g.inv(X0)

    mocap_t = np.arange(-1.0, duration_s + 1.0, 1.0 / mocap_rate_hz) + rng.uniform(0, 1e-3)
    M_true = mocap_pose(mocap_t)
    M = sim.GaussianNoise(mocap_rot_sigma_rad, mocap_trans_sigma_m).perturb(M_true, rng)
    pts = default_target_points()
    K = default_intrinsics("pinhole")
    observations, stamps = [], []
    for j in range(m):
        tau = np.arange(0.0, duration_s, 1.0 / camera_rate_hz) + (
            j / (m * camera_rate_hz) if interleaved else 0.0)
        P = g.inv(D[j]) @ _smooth_board_motion(tau, phases, freqs, depth)  # T_camj_target
        near = np.clip(np.searchsorted(mocap_t, tau), 0, len(mocap_t) - 1)
        obs = []
        for T, k in zip(P, near):
            uv = project_points(pts @ T[:3, :3].T + T[:3, 3], K)
            obs.append((pts, uv + rng.normal(scale=pixel_sigma, size=uv.shape), M[k]))
        observations.append(obs)
        stamps.append(tau - offsets[j])          # camera clock: mocap time minus the offset
    return RigStream(setup=setup, X=X, Y=Y, intrinsics=(K,) * m,
                     observations=tuple(observations), image_stamps=tuple(stamps),
                     mocap_stamps=mocap_t, T_world_mocap=M, T_world_mocap_true=M_true,
                     time_offsets_s=offsets)
