"""Image-level simulation: target points in pixels with Gaussian noise, mocap poses with noise.

:mod:`multieye.sim.rigs` simulates what PnP and the motion capture return (poses).  The
refinement of :mod:`multieye.estimate.refine_images` works on what a camera measures, the pixels of the target
points, so its experiments need one level lower:

1. a rig, a board and its poses from :func:`multieye.sim.rigs.simulate_rig` (paper section
   V-B), with the board sized to the chessboard whose corners are projected;
2. the corners projected through a pinhole or fisheye camera
   (:func:`multieye.core.lens.project_points`), plus i.i.d. Gaussian noise of
   ``pixel_sigma`` on every pixel coordinate;
3. the motion-capture poses (``T_world_marker`` or ``T_world_body``) perturbed by
   :class:`multieye.sim.rigs.GaussianNoise` (rotation noise in the marker/body frame,
   translation noise in the world frame): exactly the noise model :mod:`multieye.estimate.refine_images`
   assumes, so that the Cramér-Rao bound applies;
4. ``T_cam_target`` measured from the noisy pixels by maximum-likelihood PnP (Gauss-Newton on
   the reprojection error), which is what the closed form gets.

:func:`corrupt` turns a fraction of the measurements into the gross errors a real pipeline
meets (a motion-capture glitch: a random pose; a board detected upside down: the point order
reversed, so PnP returns the board turned by half a turn), and :func:`simulate_stream` makes
continuously moving, time-stamped streams with a clock offset for :mod:`multieye.estimate.clock`.

Synopsis
--------
>>> from multieye.sim.images import simulate_images
>>> sc = simulate_images(0, n_cameras=4, images=40, pixel_sigma=0.3)
>>> len(sc.observations), len(sc.observations[0])      # cameras, images of camera 0
(4, 40)
>>> sc.A[0].shape, sc.B[0].shape                        # for multieye.solve
((40, 4, 4), (40, 4, 4))
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from multieye.core.arguments import with_fields
from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, project_with_jacobian
from multieye.sim import rigs as sim

__all__ = [
    "ImageScenario",
    "StreamScenario",
    "CORRUPTIONS",
    "default_target_points",
    "default_intrinsics",
    "simulate_images",
    "corrupt",
    "estimate_target_poses",
    "simulate_stream",
]

F64 = NDArray[np.float64]

#: Kinds of gross error :func:`corrupt` can inject.
CORRUPTIONS: tuple[str, ...] = ("random-pose", "flipped-board")

#: Default board: 6 x 8 inner chessboard corners, 50 mm squares (0.35 m x 0.25 m of corners).
_ROWS, _COLS, _SPACING = 6, 8, 0.05


def default_target_points() -> F64:
    """Corners of the default chessboard, shape (48, 3), metres, target frame (row-major).

    6 rows x 8 columns of inner corners 50 mm apart, origin at the first corner, the board in
    the xy plane: the layout of :class:`multieye.imaging.targets.Chessboard`.  Its
    ``rows + cols`` is even, so a half turn about the board centre maps point k onto point
    ``n - 1 - k``: reversing the order is a flipped detection.
    """
    r, c = np.divmod(np.arange(_ROWS * _COLS), _COLS)
    return np.column_stack([c * _SPACING, r * _SPACING, np.zeros(r.size)])


def default_intrinsics(model: str = "pinhole") -> Intrinsics:
    """A 1280 x 960 camera whose field of view covers the simulation's (+-40 x +-30 degrees).

    ``"pinhole"``: f = 700 px and mild barrel distortion (k1 = -0.1, k2 = 0.02).
    ``"fisheye"``: equidistant, f = 450 px, k1..k4 = (0.02, -0.01, 0.003, -0.001).
    The wide-angle models, about 450 px per radian at the centre like the fisheye:
    ``"unified"``: xi = 0.9, f = 855 px, k1 k2 p1 p2 = (-0.05, 0.01, 0.0005, -0.0003);
    ``"double-sphere"``: xi = -0.17, alpha = 0.59 (TUM VI's lenses), f = 375 px;
    ``"eucm"``: alpha = 0.6, beta = 1.1, f = 450 px.
    """
    wide = {"unified": (855.0, [0.9, -0.05, 0.01, 0.0005, -0.0003]),
            "double-sphere": (375.0, [-0.17, 0.59]), "eucm": (450.0, [0.6, 1.1])}
    if model in wide:
        f, dist = wide[model]
        return Intrinsics(K=[[f, 0, 639.5], [0, f, 479.5], [0, 0, 1]], dist=dist, model=model,
                          width=1280, height=960)
    if model == "pinhole":
        return Intrinsics(K=[[700.0, 0, 639.5], [0, 700.0, 479.5], [0, 0, 1]],
                          dist=[-0.1, 0.02, 0.0, 0.0], width=1280, height=960)
    if model == "fisheye":
        return Intrinsics(K=[[450.0, 0, 639.5], [0, 450.0, 479.5], [0, 0, 1]],
                          dist=[0.02, -0.01, 0.003, -0.001], model="fisheye",
                          width=1280, height=960)
    raise InputError("camera model must be 'pinhole', 'fisheye', 'unified', 'double-sphere' "
                     f"or 'eucm', got {model!r}")


@dataclass(frozen=True)
class ImageScenario:
    """An image-level calibration problem with its ground truth.

    Attributes
    ----------
    truth : multieye.sim.rigs.RigScenario
        Noise-free scenario: ``X``, ``Y``, true mocap poses and true ``T_cam_target``.
    intrinsics : tuple of Intrinsics
        One per camera.
    object_points : ndarray, shape (n, 3)
        Target points, metres, target frame.
    image_points : tuple of ndarray, shape (N_j, n, 2)
        Measured pixels of every point in every image of camera j.
    mocap : tuple of ndarray, shape (N_j, 4, 4)
        Measured motion-capture poses (``T_world_marker`` or ``T_world_body``).
    T_cam_target : tuple of ndarray, shape (N_j, 4, 4)
        PnP on the measured pixels.
    corrupted : tuple of ndarray, shape (N_j,), bool
        Measurements :func:`corrupt` replaced by a gross error.
    pixel_sigma, mocap_rot_sigma_rad, mocap_trans_sigma_m : float
        The noise levels used (pixels, radians, metres).
    """

    truth: sim.RigScenario
    intrinsics: tuple[Intrinsics, ...]
    object_points: F64
    image_points: tuple[F64, ...]
    mocap: tuple[F64, ...]
    T_cam_target: tuple[F64, ...]
    corrupted: tuple[NDArray[np.bool_], ...]
    pixel_sigma: float
    mocap_rot_sigma_rad: float
    mocap_trans_sigma_m: float

    @property
    def setup(self) -> str:
        return self.truth.setup

    @property
    def n_cameras(self) -> int:
        return self.truth.n_cameras

    @property
    def X(self) -> F64:
        """Ground-truth ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand)."""
        return self.truth.X

    @property
    def Y(self) -> F64:
        """Ground-truth ``T_marker_target`` (eye-to-base) or ``T_world_target`` (eye-on-hand)."""
        return self.truth.Y

    @property
    def T_ref_cam(self) -> F64:
        """Ground-truth relative extrinsics, camera 0 the reference, (m, 4, 4)."""
        return self.truth.T_ref_cam

    @property
    def A(self) -> tuple[F64, ...]:
        """Measured ``A_i^j`` (docs/conventions.md, section 2) per camera, from the noisy mocap."""
        if self.setup == "eye-on-hand":
            return tuple(np.array(M) for M in self.mocap)
        return tuple(g.inv(M) for M in self.mocap)

    @property
    def B(self) -> tuple[F64, ...]:
        """Measured ``B_i^j = inv(T_cam_target)`` per camera, from PnP on the noisy pixels."""
        return tuple(g.inv(P) for P in self.T_cam_target)

    @property
    def observations(self) -> tuple[tuple[tuple[F64, F64, F64], ...], ...]:
        """Input of :func:`multieye.estimate.refine_images.refine_images`: (points, pixels, mocap) per image."""
        return tuple(tuple((self.object_points, uv, M) for uv, M in zip(U, Ms))
                     for U, Ms in zip(self.image_points, self.mocap))

    @property
    def true_observations(self) -> tuple[tuple[tuple[F64, F64, F64], ...], ...]:
        """As :attr:`observations` with noise-free pixels and the true mocap poses.

        The linearisation point of the Cramér-Rao bound
        (:func:`multieye.estimate.uncertainty.cramer_rao_bound`).
        """
        return tuple(tuple((self.object_points, _project(self.object_points, P, K), M)
                           for P, M in zip(Ps, Ms))
                     for Ps, Ms, K in zip(self.truth.T_cam_target, self.truth.mocap,
                                          self.intrinsics))


def _project(points: F64, T_cam_target: F64, intrinsics: Intrinsics) -> F64:
    """Pixels (n, 2) of target points seen from one pose (4, 4)."""
    pc = points @ T_cam_target[:3, :3].T + T_cam_target[:3, 3]
    return project_points(pc, intrinsics)


def estimate_target_poses(object_points: F64, image_points: F64, T_init: F64,
                          intrinsics: Intrinsics, *, iterations: int = 20) -> F64:
    """Maximum-likelihood PnP of many images at once (Gauss-Newton on the reprojection error).

    A simulation knows a starting pose within the basin of the optimum, so no minimal solver
    is needed: every pose converges to the minimiser of its pixel residuals, which is what a
    PnP with a final Levenberg-Marquardt polish returns on real images.

    Parameters
    ----------
    object_points : ndarray, shape (n, 3)
        Target points, metres.
    image_points : ndarray, shape (N, n, 2)
        Their pixels in N images.
    T_init : ndarray, shape (N, 4, 4)
        Starting ``T_cam_target``.
    intrinsics : Intrinsics
    iterations : int
        Gauss-Newton steps at most.

    Returns
    -------
    ndarray, shape (N, 4, 4)
        ``T_cam_target`` minimising the sum of squared pixel residuals.
    """

    T = np.array(T_init, dtype=np.float64)
    N, n = image_points.shape[:2]
    for _ in range(iterations):
        Rp = np.einsum("nij,kj->nki", T[:, :3, :3], object_points)           # (N, n, 3)
        pc = Rp + T[:, None, :3, 3]
        uv, Jp, _ = project_with_jacobian(pc.reshape(-1, 3), intrinsics)
        r = (uv.reshape(N, n, 2) - image_points).reshape(N, n * 2)
        Jpose = np.concatenate([-Jp @ g.skew(Rp.reshape(-1, 3)),
                                np.broadcast_to(Jp, Jp.shape)], axis=2)      # (N n, 2, 6)
        Jpose = Jpose.reshape(N, n * 2, 6)
        H = np.swapaxes(Jpose, 1, 2) @ Jpose
        step = -np.linalg.solve(H, np.einsum("nri,nr->ni", Jpose, r)[..., None])[..., 0]
        dR = g.transform_from_rotvec(step[:, :3], np.zeros((N, 3)))[:, :3, :3]
        T = g.make_transform(dR @ T[:, :3, :3], T[:, :3, 3] + step[:, 3:])
        if np.max(np.abs(step)) < 1e-12:
            break
    return T


@dataclass(frozen=True)
class ImageSpec:
    """The options of :func:`simulate_images` (see there), taken as one argument or as
    keyword arguments."""

    n_cameras: int = 4
    images: int | Sequence[int] = 40
    setup: sim.Setup = "eye-to-base"
    pixel_sigma: float = 0.3
    mocap_rot_sigma_rad: float = float(np.deg2rad(0.1))
    mocap_trans_sigma_m: float = 0.3e-3
    model: str = "pinhole"
    intrinsics: Sequence[Intrinsics] | None = None
    noise_rng: np.random.Generator | int | None = None
    scenario: sim.ScenarioSpec | None = None


def simulate_images(rng: np.random.Generator | int | None = None,
                    spec: ImageSpec = ImageSpec(), **kw) -> ImageScenario:
    """Simulate a rig calibration at the image level (module docstring).

    Parameters
    ----------
    rng : numpy.random.Generator, int or None
        Generator or seed of the scene (and of the noise, unless ``noise_rng`` is given).
    n_cameras : int
        Cameras on the rig (a surround ring, :func:`multieye.sim.rigs.surround_rig`).
    images : int or sequence of int
        Images per camera (one count for all, or one per camera).
    setup : {"eye-to-base", "eye-on-hand"}
    pixel_sigma : float
        Standard deviation of each pixel coordinate, pixels.
    mocap_rot_sigma_rad : float
        Standard deviation of each rotation-vector component of the mocap error, radians.
    mocap_trans_sigma_m : float
        Standard deviation of each coordinate of the mocap position error, metres.
    model : {"pinhole", "fisheye", "unified", "double-sphere", "eucm"}
        Camera model of :func:`default_intrinsics` (ignored when ``intrinsics`` is given).
    intrinsics : sequence of Intrinsics, optional
        One per camera; must cover +-40 x +-30 degrees.
    noise_rng : numpy.random.Generator, int or None, optional
        Separate source of the pixel and mocap noise, so that one scene can be seen at
        several noise levels.
    scenario : multieye.sim.rigs.ScenarioSpec, optional
        Geometry of the rig and the board's poses (its ``board_size_m`` is replaced by the
        default target's); default ``ScenarioSpec()``.

    Returns
    -------
    ImageScenario
    """
    o = with_fields(spec, kw, ImageSpec, "spec")
    n_cameras, images, setup, pixel_sigma = o.n_cameras, o.images, o.setup, o.pixel_sigma
    mocap_rot_sigma_rad, mocap_trans_sigma_m = o.mocap_rot_sigma_rad, o.mocap_trans_sigma_m
    model, intrinsics = o.model, o.intrinsics
    noise_rng, scenario = o.noise_rng, o.scenario
    rng = np.random.default_rng(rng)
    if pixel_sigma < 0 or mocap_rot_sigma_rad < 0 or mocap_trans_sigma_m < 0:
        raise InputError("noise standard deviations must be >= 0, got "
                         f"{pixel_sigma} px, {mocap_rot_sigma_rad} rad, {mocap_trans_sigma_m} m")
    pts = default_target_points()
    size = (float(pts[:, 0].max()), float(pts[:, 1].max()))
    spec = replace(sim.ScenarioSpec() if scenario is None else scenario, board_size_m=size)
    truth = sim.simulate_rig(rng, n_cameras=n_cameras, measurements=images, setup=setup,
                             spec=spec)
    if intrinsics is None:
        intrinsics = (default_intrinsics(model),) * n_cameras
    intrinsics = tuple(intrinsics)
    if len(intrinsics) != n_cameras:
        raise InputError(f"{len(intrinsics)} intrinsics given for {n_cameras} cameras")
    noise = sim.GaussianNoise(mocap_rot_sigma_rad, mocap_trans_sigma_m)
    nrng = rng if noise_rng is None else np.random.default_rng(noise_rng)
    uv, mocap, poses = [], [], []
    for P, M, K in zip(truth.T_cam_target, truth.mocap, intrinsics):
        clean = np.stack([_project(pts, T, K) for T in P])
        noisy = clean + nrng.normal(scale=pixel_sigma, size=clean.shape)
        uv.append(noisy)
        mocap.append(noise.perturb(M, nrng))
        poses.append(estimate_target_poses(pts, noisy, P, K))
    return ImageScenario(truth=truth, intrinsics=intrinsics, object_points=pts,
                         image_points=tuple(uv), mocap=tuple(mocap), T_cam_target=tuple(poses),
                         corrupted=tuple(np.zeros(len(P), dtype=bool) for P in poses),
                         pixel_sigma=float(pixel_sigma),
                         mocap_rot_sigma_rad=float(mocap_rot_sigma_rad),
                         mocap_trans_sigma_m=float(mocap_trans_sigma_m))


def _half_turn(points: F64) -> F64:
    """``T_target_flipped``: the half turn about the board's z axis through its centre."""
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    R = np.diag([-1.0, -1.0, 1.0])
    return g.make_transform(R, centre - R @ centre)


def corrupt(scenario: ImageScenario, fraction: float, rng: np.random.Generator | int | None
            = None, *, kinds: Sequence[str] = CORRUPTIONS) -> ImageScenario:
    """Replace a fraction of every camera's measurements by gross errors.

    - ``"random-pose"``: a motion-capture glitch; the mocap pose becomes a random rotation at
      a position 0.5 m (standard deviation per axis) from the true one.
    - ``"flipped-board"``: the detector reports the points in reverse order (a half-turn
      symmetric board seen upside down); the pixels are reordered and PnP re-run, giving the
      board turned by half a turn about its centre.

    Parameters
    ----------
    scenario : ImageScenario
    fraction : float
        Share of each camera's measurements to corrupt, in [0, 1); rounded per camera.
    rng : numpy.random.Generator, int or None
    kinds : sequence of str
        Which corruptions to use, in turn.

    Returns
    -------
    ImageScenario
        With :attr:`ImageScenario.corrupted` marking the corrupted measurements.
    """
    rng = np.random.default_rng(rng)
    if not 0.0 <= fraction < 1.0:
        raise InputError(f"fraction must be in [0, 1), got {fraction}")
    unknown = [k for k in kinds if k not in CORRUPTIONS]
    if unknown or not kinds:
        raise InputError(f"unknown corruption(s) {unknown}; choose from {CORRUPTIONS}")
    pts = scenario.object_points
    flip = _half_turn(pts)
    uv, mocap, poses, flags = [], [], [], []
    for j in range(scenario.n_cameras):
        U = scenario.image_points[j].copy()
        M = scenario.mocap[j].copy()
        P = scenario.T_cam_target[j].copy()
        bad = scenario.corrupted[j].copy()
        n = len(U)
        chosen = rng.choice(np.flatnonzero(~bad), size=int(round(fraction * n)), replace=False)
        for k, i in enumerate(np.sort(chosen)):
            kind = kinds[k % len(kinds)]
            if kind == "random-pose":
                T = g.random_transforms(rng)
                T[:3, 3] = M[i, :3, 3] + rng.normal(scale=0.5, size=3)
                M[i] = T
            else:
                U[i] = U[i][::-1]
                P[i] = estimate_target_poses(pts, U[i][None], (P[i] @ flip)[None],
                                             scenario.intrinsics[j])[0]
            bad[i] = True
        uv.append(U)
        mocap.append(M)
        poses.append(P)
        flags.append(bad)
    return replace(scenario, image_points=tuple(uv), mocap=tuple(mocap),
                   T_cam_target=tuple(poses), corrupted=tuple(flags))


@dataclass(frozen=True)
class StreamScenario:
    """Time-stamped, unsynchronised streams of one camera and the motion capture.

    Attributes
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    X, Y : ndarray, shape (4, 4)
        Ground truth (docs/conventions.md, section 2).
    cam_stamps : ndarray, shape (K,)
        Image times in the camera clock, seconds.
    T_cam_target : ndarray, shape (K, 4, 4)
        Measured board poses (with noise).
    mocap_stamps : ndarray, shape (L,)
        Motion-capture sample times in its own clock, seconds.
    T_world_mocap : ndarray, shape (L, 4, 4)
        Measured ``T_world_marker`` (eye-to-base) or ``T_world_body`` (eye-on-hand).
    time_offset_s : float
        True motion-capture clock minus camera clock, seconds: the image stamped ``c`` by the
        camera was taken when the motion capture's clock read ``c + time_offset_s``.
    """

    setup: str
    X: F64
    Y: F64
    cam_stamps: F64
    T_cam_target: F64
    mocap_stamps: F64
    T_world_mocap: F64
    time_offset_s: float


def _smooth_board_motion(t: F64, phases: F64, freqs: F64, depth: float) -> F64:
    """``T_cam_target`` (K, 4, 4) of a board waved smoothly in front of a camera.

    The board centre moves +-0.15 m sideways and +-0.2 m in depth about ``depth`` metres
    ahead, and the board turns by up to 30 degrees about each axis, every component a sum of
    two sinusoids (0.05-0.4 Hz).
    """
    w = 2.0 * np.pi * freqs                                     # (2, 6)
    s = (np.sin(w[0] * t[:, None] + phases[0]) + np.sin(w[1] * t[:, None] + phases[1])) / 2.0
    rot = np.deg2rad(30.0) * s[:, :3]
    shift = s[:, 3:] * np.array([0.15, 0.15, 0.2])
    centre = np.array([_SPACING * (_COLS - 1) / 2, _SPACING * (_ROWS - 1) / 2, 0.0])
    R = g.transform_from_rotvec(rot, np.zeros_like(rot))[:, :3, :3]
    position = np.array([0.0, 0.0, depth]) + shift
    return g.make_transform(R, position - R @ centre)


@dataclass(frozen=True)
class StreamSpec:
    """The options of :func:`simulate_stream` (see there), taken as one argument or as
    keyword arguments."""

    setup: sim.Setup = "eye-to-base"
    duration_s: float = 60.0
    camera_rate_hz: float = 20.0
    mocap_rate_hz: float = 200.0
    time_offset_s: float = 0.0
    drop_fraction: float = 0.05
    cam_rot_sigma_rad: float = float(np.deg2rad(0.1))
    cam_trans_sigma_m: float = 1e-3
    mocap_rot_sigma_rad: float = float(np.deg2rad(0.1))
    mocap_trans_sigma_m: float = 0.3e-3


def simulate_stream(rng: np.random.Generator | int | None = None,
                    spec: StreamSpec = StreamSpec(), **kw) -> StreamScenario:
    """One camera and a motion capture recording continuous motion, with a clock offset.

    The board moves smoothly in front of the camera (eye-to-base: the board carries the
    marker body; eye-on-hand: the rig moves and the board stands still); the camera takes
    images at ``camera_rate_hz`` (a random ``drop_fraction`` of them lost, as failed
    detections are), the motion capture samples at ``mocap_rate_hz`` in its own clock.
    The rig and ``Y`` come from :func:`multieye.sim.rigs.simulate_rig`.

    Parameters
    ----------
    rng : numpy.random.Generator, int or None
    setup : {"eye-to-base", "eye-on-hand"}
    duration_s : float
        Length of the camera recording, seconds; the motion capture covers it with a margin
        of 1 s plus the offset on each side.
    camera_rate_hz, mocap_rate_hz : float
    time_offset_s : float
        Motion-capture clock minus camera clock, seconds.
    drop_fraction : float
        Share of images left out at random.
    cam_rot_sigma_rad, cam_trans_sigma_m : float
        Pose noise of ``T_cam_target`` (:class:`multieye.sim.rigs.GaussianNoise`).
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float
        Pose noise of the motion capture.

    Returns
    -------
    StreamScenario
    """
    o = with_fields(spec, kw, StreamSpec, "spec")
    setup, duration_s = o.setup, o.duration_s
    camera_rate_hz, mocap_rate_hz = o.camera_rate_hz, o.mocap_rate_hz
    time_offset_s, drop_fraction = o.time_offset_s, o.drop_fraction
    cam_rot_sigma_rad, cam_trans_sigma_m = o.cam_rot_sigma_rad, o.cam_trans_sigma_m
    mocap_rot_sigma_rad, mocap_trans_sigma_m = o.mocap_rot_sigma_rad, o.mocap_trans_sigma_m
    rng = np.random.default_rng(rng)
    if duration_s <= 0 or camera_rate_hz <= 0 or mocap_rate_hz <= 0:
        raise InputError("duration and rates must be positive, got "
                         f"{duration_s} s, {camera_rate_hz} Hz, {mocap_rate_hz} Hz")
    rig = sim.simulate_rig(rng, n_cameras=1, measurements=3, setup=setup)
    X, Y = rig.X[0], rig.Y
    phases = rng.uniform(0.0, 2.0 * np.pi, size=(2, 6))
    freqs = rng.uniform(0.05, 0.4, size=(2, 6))
    depth = rng.uniform(0.9, 1.4)
    cam_t = np.arange(0.0, duration_s, 1.0 / camera_rate_hz)
    cam_t = cam_t[rng.uniform(size=cam_t.size) >= drop_fraction]
    margin = 1.0 + abs(time_offset_s)
    mocap_stamps = np.arange(-margin, duration_s + margin, 1.0 / mocap_rate_hz) + time_offset_s
    true_t = mocap_stamps - time_offset_s                          # true time of each sample
    P_mocap = _smooth_board_motion(true_t, phases, freqs, depth)
    if setup == "eye-to-base":
        M = X @ P_mocap @ g.inv(Y)                                  # T_world_marker
    else:
        M = Y @ g.inv(P_mocap) @ g.inv(X)                           # T_world_body
    P_cam = _smooth_board_motion(cam_t, phases, freqs, depth)
    P_cam = sim.GaussianNoise(cam_rot_sigma_rad, cam_trans_sigma_m).perturb(P_cam, rng)
    M = sim.GaussianNoise(mocap_rot_sigma_rad, mocap_trans_sigma_m).perturb(M, rng)
    return StreamScenario(setup=setup, X=X, Y=Y, cam_stamps=cam_t, T_cam_target=P_cam,
                          mocap_stamps=mocap_stamps, T_world_mocap=M,
                          time_offset_s=float(time_offset_s))
