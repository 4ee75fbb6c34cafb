"""Pose-level simulation of a camera rig and a motion-captured target (paper section V-B).

Wang et al. (ICRA 2022) evaluate their solver on a simulated surround rig: four cameras in a
horizontal plane, 0.4-0.65 m from the body origin, facing outwards, each observing a
calibration board up to 40 times, with both measurement streams corrupted by noise. This
module builds such scenarios with a known ground truth for both setups (docs/conventions.md,
section 2):

=============  ======================  ===============  =================  ====================
setup          A_i^j                   X^j              Y                  B_i^j
=============  ======================  ===============  =================  ====================
eye-to-base    inv(T_world_marker[i])  ``T_world_cam``  ``T_marker_target``  inv(T_cam_target[i])
eye-on-hand    T_world_body[i]         ``T_body_cam``   ``T_world_target``   inv(T_cam_target[i])
=============  ======================  ===============  =================  ====================

Noise is applied to what a real system measures (the motion-capture pose and the PnP pose
``T_cam_target``), before ``A`` and ``B`` are formed from them.

Synopsis
--------
>>> import numpy as np
>>> from multieye.sim import rigs as sim
>>> scenario = sim.simulate_rig(np.random.default_rng(0), n_cameras=4, measurements=40)
>>> noisy = sim.add_noise(scenario, sim.MultiplicativeNoise(0.05), np.random.default_rng(1))
>>> A, B = noisy.A, noisy.B       # one (40, 4, 4) array per camera in each
>>> X_true, Y_true = noisy.X, noisy.Y
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.problem import SETUPS, Setup

__all__ = [
    "Setup",
    "SETUPS",
    "ScenarioSpec",
    "RigScenario",
    "MultiplicativeNoise",
    "GaussianNoise",
    "NoiseModel",
    "surround_rig",
    "sample_target_poses",
    "simulate_rig",
    "add_noise",
]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class ScenarioSpec:
    """Geometry of a simulated rig, board and capture volume (defaults: paper section V-B).

    Frames: ``body`` has z up; a camera's frame is OpenCV's (x right, y down, z forward);
    the board's ``target`` frame has its origin at the first corner, the board in its xy
    plane and z pointing into the board (away from a camera that sees its front).

    Attributes
    ----------
    radius_m : (float, float)
        Range of camera distances from the body origin, metres (paper: 0.4-0.65 m).
    yaw_jitter_rad : float
        Each camera's heading is its even share of the ring plus U(-jitter, jitter), radians.
    camera_tilt_rad : float
        Largest angle of the small random tilt of each camera away from horizontal-outwards.
    distance_m : (float, float)
        Range of the board centre's depth in front of the camera, metres.
    max_board_tilt_rad : float
        Largest angle between the board's normal and the camera's line of sight to it.
    max_board_roll_rad : float
        In-plane rotation of the board about its normal is drawn from U(-roll, roll).
    board_size_m : (float, float)
        Board width (target x) and height (target y), metres.
    half_fov_rad : (float, float)
        Horizontal and vertical half field of view; all four board corners must lie inside.
    marker_offset_m : (float, float)
        Range of the distance between the board centre and the marker body's origin
        (eye-to-base), metres.
    """

    radius_m: tuple[float, float] = (0.4, 0.65)
    yaw_jitter_rad: float = np.deg2rad(10.0)
    camera_tilt_rad: float = np.deg2rad(5.0)
    distance_m: tuple[float, float] = (0.5, 2.0)
    max_board_tilt_rad: float = np.deg2rad(45.0)
    max_board_roll_rad: float = np.deg2rad(90.0)
    board_size_m: tuple[float, float] = (0.4, 0.3)
    half_fov_rad: tuple[float, float] = (np.deg2rad(40.0), np.deg2rad(30.0))
    marker_offset_m: tuple[float, float] = (0.05, 0.3)


def _frozen(a: F64) -> F64:
    a = np.array(a, dtype=np.float64)
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class RigScenario:
    """A simulated calibration problem with its ground truth (arrays are read-only).

    Attributes
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    T_body_cam : ndarray, shape (m, 4, 4)
        The rig: pose of each camera in the body frame (metres).
    X : ndarray, shape (m, 4, 4)
        Ground-truth per-camera unknown: ``T_world_cam`` (eye-to-base, the rig standing still
        in the motion-capture volume) or ``T_body_cam`` (eye-on-hand).
    Y : ndarray, shape (4, 4)
        Ground-truth shared unknown: ``T_marker_target`` (eye-to-base) or ``T_world_target``
        (eye-on-hand).
    mocap : tuple of ndarray, shape (N_j, 4, 4)
        Motion-capture poses per camera, as measured: ``T_world_marker`` (eye-to-base) or
        ``T_world_body`` (eye-on-hand).
    T_cam_target : tuple of ndarray, shape (N_j, 4, 4)
        Board poses per camera, as measured (what PnP would return).
    """

    setup: Setup
    T_body_cam: F64
    X: F64
    Y: F64
    mocap: tuple[F64, ...]
    T_cam_target: tuple[F64, ...]
    _A: tuple[F64, ...] = field(init=False, repr=False, compare=False)
    _B: tuple[F64, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.setup not in SETUPS:
            raise InputError(f"setup must be one of {SETUPS}, got {self.setup!r}")
        if len(self.mocap) != len(self.T_cam_target) or len(self.mocap) != len(self.X):
            raise InputError(f"one motion-capture and one board-pose array per camera expected, "
                             f"got {len(self.mocap)} and {len(self.T_cam_target)} "
                             f"for {len(self.X)} cameras")
        for name in ("T_body_cam", "X", "Y"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        mocap = tuple(_frozen(M) for M in self.mocap)
        cam_target = tuple(_frozen(P) for P in self.T_cam_target)
        object.__setattr__(self, "mocap", mocap)
        object.__setattr__(self, "T_cam_target", cam_target)
        A = mocap if self.setup == "eye-on-hand" else tuple(g.inv(M) for M in mocap)
        object.__setattr__(self, "_A", tuple(_frozen(a) for a in A))
        object.__setattr__(self, "_B", tuple(_frozen(g.inv(P)) for P in cam_target))

    @property
    def A(self) -> tuple[F64, ...]:
        """Left measurements ``A_i^j`` per camera, each (N_j, 4, 4) (table above)."""
        return self._A

    @property
    def B(self) -> tuple[F64, ...]:
        """Right measurements ``B_i^j = T_target_cam[i]`` per camera, each (N_j, 4, 4)."""
        return self._B

    @property
    def n_cameras(self) -> int:
        return len(self.X)

    @property
    def counts(self) -> tuple[int, ...]:
        """Measurements per camera."""
        return tuple(len(b) for b in self._B)

    @property
    def T_ref_cam(self) -> F64:
        """Ground-truth relative extrinsics ``inv(X[0]) @ X[j]``, shape (m, 4, 4).

        Camera 0 is the reference; the same for both setups (``inv(T_body_ref) T_body_cam``).
        """
        return g.inv(self.X[0]) @ self.X


@dataclass(frozen=True)
class MultiplicativeNoise:
    """The paper's noise model (section V-B).

    Each quaternion component and each translation coordinate of a pose is multiplied by
    ``1 + u`` with ``u ~ U(-f, f)`` drawn independently; the quaternion is then renormalised.
    The translation error therefore grows with the distance of the pose from its frame's
    origin.

    Attributes
    ----------
    f : float
        Relative noise level in [0, 1), e.g. 0.05 for the paper's 5 %.
    """

    f: float

    def __post_init__(self) -> None:
        if not 0.0 <= self.f < 1.0:
            raise InputError(f"multiplicative noise level f must be in [0, 1), got {self.f}")

    def perturb(self, T: F64, rng: np.random.Generator) -> F64:
        """Noisy copies of poses ``T`` (n, 4, 4)."""
        T = np.asarray(T, dtype=np.float64)
        if self.f == 0.0:
            return T.copy()
        q = g.quat_from_transform(T)
        q = q * (1.0 + rng.uniform(-self.f, self.f, size=q.shape))
        t = T[..., :3, 3] * (1.0 + rng.uniform(-self.f, self.f, size=T.shape[:-2] + (3,)))
        return g.transform_from_quat(q, t)


@dataclass(frozen=True)
class GaussianNoise:
    """Isotropic Gaussian pose noise.

    ``R' = R @ exp([w]x)`` with ``w ~ N(0, rot_std_rad^2 I_3)`` (a perturbation in the pose's
    own ``b`` frame for ``T_a_b``) and ``t' = t + e``, ``e ~ N(0, trans_std_m^2 I_3)``.

    Attributes
    ----------
    rot_std_rad : float
        Standard deviation of each rotation-vector component, radians.
    trans_std_m : float
        Standard deviation of each translation coordinate, metres.
    """

    rot_std_rad: float
    trans_std_m: float

    def __post_init__(self) -> None:
        if self.rot_std_rad < 0 or self.trans_std_m < 0:
            raise InputError(f"Gaussian noise standard deviations must be >= 0, got "
                             f"{self.rot_std_rad} rad and {self.trans_std_m} m")

    def perturb(self, T: F64, rng: np.random.Generator) -> F64:
        """Noisy copies of poses ``T`` (n, 4, 4)."""
        T = np.asarray(T, dtype=np.float64)
        shape = T.shape[:-2] + (3,)
        dR = g.transform_from_rotvec(rng.normal(scale=self.rot_std_rad, size=shape), np.zeros(shape))
        R = T[..., :3, :3] @ dR[..., :3, :3]
        t = T[..., :3, 3] + rng.normal(scale=self.trans_std_m, size=shape)
        return g.make_transform(R, t)


NoiseModel = MultiplicativeNoise | GaussianNoise


def _yaw(yaw: F64) -> F64:
    """Rotations about the z axis, shape (..., 3, 3)."""
    c, s = np.cos(yaw), np.sin(yaw)
    z, o = np.zeros_like(yaw), np.ones_like(yaw)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _outward_frames(heading: F64) -> F64:
    """Rotations (..., 3, 3) of OpenCV camera frames looking horizontally along ``heading``.

    Columns: x (right) = (sin, -cos, 0), y (down) = (0, 0, -1), z (forward) = (cos, sin, 0) in
    a parent frame whose z axis points up.
    """
    c, s = np.cos(heading), np.sin(heading)
    z = np.zeros_like(heading)
    x_axis = np.stack([s, -c, z], -1)
    y_axis = np.stack([z, z, -np.ones_like(heading)], -1)
    z_axis = np.stack([c, s, z], -1)
    return np.stack([x_axis, y_axis, z_axis], -1)


def _random_small_rotations(rng: np.random.Generator, n: int, max_angle: float) -> F64:
    """Rotations (n, 3, 3) about uniformly random axes by U(0, max_angle) radians."""
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return Rotation.from_rotvec(axis * rng.uniform(0.0, max_angle, size=(n, 1))).as_matrix()


def surround_rig(rng: np.random.Generator, n_cameras: int = 4, *,
                 spec: ScenarioSpec = ScenarioSpec()) -> F64:
    """A ring of outward-facing cameras in the body's horizontal plane (paper section V-B).

    Camera j sits at heading ``2 pi j / m + U(-yaw_jitter, yaw_jitter)`` and distance
    ``U(*radius_m)`` from the body origin in the plane z = 0, looks outwards along that heading
    and is tilted by a small random rotation (``camera_tilt_rad``).

    Parameters
    ----------
    rng : numpy.random.Generator
    n_cameras : int
        m >= 1.
    spec : ScenarioSpec

    Returns
    -------
    ndarray, shape (m, 4, 4)
        ``T_body_cam`` per camera (metres).
    """
    if n_cameras < 1:
        raise InputError(f"a rig needs at least one camera, got n_cameras={n_cameras}")
    heading = (2.0 * np.pi * np.arange(n_cameras) / n_cameras
               + rng.uniform(-spec.yaw_jitter_rad, spec.yaw_jitter_rad, n_cameras))
    radius = rng.uniform(*spec.radius_m, n_cameras)
    position = np.stack([radius * np.cos(heading), radius * np.sin(heading),
                         np.zeros(n_cameras)], -1)
    R = _outward_frames(heading) @ _random_small_rotations(rng, n_cameras, spec.camera_tilt_rad)
    return g.make_transform(R, position)


def _board_corners(spec: ScenarioSpec) -> F64:
    w, h = spec.board_size_m
    return np.array([[0.0, 0.0, 0.0], [w, 0.0, 0.0], [w, h, 0.0], [0.0, h, 0.0]])


def sample_target_poses(rng: np.random.Generator, n: int, *,
                        spec: ScenarioSpec = ScenarioSpec()) -> F64:
    """Physically plausible board poses seen by one camera.

    The board centre lies at depth ``U(*distance_m)`` in a direction drawn uniformly over the
    image (tangent space); the board faces the camera: its normal makes an angle of at most
    ``max_board_tilt_rad`` with the line of sight (uniform over that cone, about a random
    axis), and it is rolled in its plane by ``U(-max_board_roll_rad, max_board_roll_rad)``.
    Poses whose four corners are not all inside the field of view are drawn again.

    Parameters
    ----------
    rng : numpy.random.Generator
    n : int
        Number of poses.
    spec : ScenarioSpec

    Returns
    -------
    ndarray, shape (n, 4, 4)
        ``T_cam_target`` (metres).
    """
    corners = _board_corners(spec)
    centre = corners.mean(axis=0)
    tan_x, tan_y = np.tan(spec.half_fov_rad[0]), np.tan(spec.half_fov_rad[1])
    cos_max_tilt = np.cos(spec.max_board_tilt_rad)
    accepted: list[F64] = []
    have = 0
    while have < n:
        k = 2 * (n - have) + 8
        depth = rng.uniform(*spec.distance_m, k)
        c = depth[:, None] * np.stack([rng.uniform(-tan_x, tan_x, k),
                                       rng.uniform(-tan_y, tan_y, k), np.ones(k)], -1)
        ray = c / np.linalg.norm(c, axis=1, keepdims=True)
        # Rotation taking the camera's z axis onto the line of sight (never antiparallel here).
        e_z = np.array([0.0, 0.0, 1.0])
        cross = np.cross(e_z, ray)
        align = Rotation.from_rotvec(
            cross / np.maximum(np.linalg.norm(cross, axis=1, keepdims=True), 1e-300)
            * np.arccos(np.clip(ray[:, 2], -1.0, 1.0))[:, None]).as_matrix()
        # Tilt the normal away from the line of sight, uniformly over the cone's solid angle.
        tilt = np.arccos(1.0 - rng.uniform(0.0, 1.0, k) * (1.0 - cos_max_tilt))
        axis = np.cross(ray, rng.normal(size=(k, 3)))
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        tilt_R = Rotation.from_rotvec(axis * tilt[:, None]).as_matrix()
        roll = rng.uniform(-spec.max_board_roll_rad, spec.max_board_roll_rad, k)
        R = tilt_R @ align @ _yaw(roll)
        t = c - R @ centre
        p = np.einsum("kij,cj->kci", R, corners) + t[:, None, :]
        z = p[..., 2]
        ok = np.all((z > 0.05)
                    & (np.abs(p[..., 0]) <= tan_x * z)
                    & (np.abs(p[..., 1]) <= tan_y * z), axis=1)
        accepted.append(g.make_transform(R[ok], t[ok]))
        have += int(ok.sum())
    return np.concatenate(accepted)[:n]


def _counts(n_cameras: int, measurements: int | Sequence[int]) -> tuple[int, ...]:
    if n_cameras < 1:
        raise InputError(f"a rig needs at least one camera, got n_cameras={n_cameras}")
    if isinstance(measurements, (int, np.integer)):
        counts = (int(measurements),) * n_cameras
    else:
        counts = tuple(int(c) for c in measurements)
        if len(counts) != n_cameras:
            raise InputError(f"measurements lists {len(counts)} counts for {n_cameras} cameras; "
                             "give one count per camera or a single integer")
    if min(counts) < 1:
        raise InputError(f"every camera needs at least one measurement, got {counts}")
    return counts


def _upright_pose(rng: np.random.Generator, half_extent_m: float,
                  height_m: tuple[float, float]) -> F64:
    """A pose (4, 4) with random heading and position in a capture volume (z up, metres)."""
    t = np.array([*rng.uniform(-half_extent_m, half_extent_m, 2), rng.uniform(*height_m)])
    return g.make_transform(_yaw(rng.uniform(-np.pi, np.pi)), t)


def simulate_rig(rng: np.random.Generator | int | None = None, *, n_cameras: int = 4,
                 measurements: int | Sequence[int] = 40, setup: Setup = "eye-to-base",
                 spec: ScenarioSpec = ScenarioSpec()) -> RigScenario:
    """A noise-free calibration scenario with its ground truth (paper section V-B).

    The rig is :func:`surround_rig`; each camera sees the board in :func:`sample_target_poses`.

    - eye-to-base: the rig stands still in the capture volume (``T_world_body`` of random
      heading, within 1 m of the world origin horizontally, 0.8-1.2 m high), so
      ``X = T_world_cam = T_world_body @ T_body_cam``; a marker body is fixed to the board at
      ``Y = T_marker_target`` (random orientation, origin ``marker_offset_m`` from the board
      centre); the measured ``T_world_marker[i] = X @ T_cam_target[i] @ inv(Y)``.
    - eye-on-hand: the board stands upright in the volume at ``Y = T_world_target`` (within
      2 m of the origin, 0.5-1.5 m high) and the rig moves; ``X = T_body_cam`` and the
      measured ``T_world_body[i] = Y @ inv(T_cam_target[i]) @ inv(X)``.

    Parameters
    ----------
    rng : numpy.random.Generator, int or None
        Generator or seed (passed to :func:`numpy.random.default_rng`).
    n_cameras : int
        m >= 1.
    measurements : int or sequence of int
        Measurements per camera, one count for all or one per camera (may differ).
    setup : {"eye-to-base", "eye-on-hand"}
    spec : ScenarioSpec

    Returns
    -------
    RigScenario
        Without noise ``A[j][i] @ X[j] == Y @ B[j][i]`` up to rounding; see :func:`add_noise`.
    """
    rng = np.random.default_rng(rng)
    if setup not in SETUPS:
        raise InputError(f"setup must be one of {SETUPS}, got {setup!r}")
    counts = _counts(n_cameras, measurements)
    T_body_cam = surround_rig(rng, n_cameras, spec=spec)
    T_cam_target = tuple(sample_target_poses(rng, n, spec=spec) for n in counts)
    if setup == "eye-to-base":
        X = _upright_pose(rng, 1.0, (0.8, 1.2)) @ T_body_cam
        offset = rng.normal(size=3)
        offset *= rng.uniform(*spec.marker_offset_m) / np.linalg.norm(offset)
        Y = g.make_transform(Rotation.random(random_state=rng).as_matrix(),
                             _board_corners(spec).mean(axis=0) + offset)
        mocap = tuple(X[j] @ P @ g.inv(Y) for j, P in enumerate(T_cam_target))
    else:
        X = T_body_cam
        # Board standing upright: target y down, target z horizontal (facing away from the rig).
        placement = _upright_pose(rng, 2.0, (0.5, 1.5))
        Y = g.make_transform(placement[:3, :3] @ _outward_frames(np.float64(0.0)),
                             placement[:3, 3])
        mocap = tuple(Y @ g.inv(P) @ g.inv(X[j]) for j, P in enumerate(T_cam_target))
    return RigScenario(setup=setup, T_body_cam=T_body_cam, X=X, Y=Y, mocap=mocap,
                       T_cam_target=T_cam_target)


def add_noise(scenario: RigScenario, noise: NoiseModel, rng: np.random.Generator | int | None
              = None) -> RigScenario:
    """The same scenario with both measurement streams perturbed by ``noise``.

    The motion-capture poses (``T_world_marker`` or ``T_world_body``) and the board poses
    ``T_cam_target`` are perturbed independently, as measured; ``A`` and ``B`` then follow
    from them. The ground truth is unchanged.

    Parameters
    ----------
    scenario : RigScenario
    noise : MultiplicativeNoise or GaussianNoise
    rng : numpy.random.Generator, int or None

    Returns
    -------
    RigScenario
    """
    rng = np.random.default_rng(rng)
    mocap = tuple(noise.perturb(M, rng) for M in scenario.mocap)
    cam_target = tuple(noise.perturb(P, rng) for P in scenario.T_cam_target)
    return replace(scenario, mocap=mocap, T_cam_target=cam_target)
