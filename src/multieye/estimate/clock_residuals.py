"""A camera's clock offset as an unknown of the image-level problem, on a smoothed trajectory.

With the offset ``delta`` (motion-capture clock minus camera clock, seconds) the motion-capture
pose of image i is the trajectory at ``t_i + delta`` (``t_i`` the image's camera-clock stamp).
The trajectory there is not one noisy sample, nor the piecewise-linear path between two of them
(whose value is jagged in ``delta`` and whose velocity is mostly noise), but a local cubic
least-squares fit (:class:`LocalTrajectory`) to the ``n_w`` motion-capture samples around the
image's time (a Savitzky-Golay smoother, default about +-50 ms): per image, rotation as the
rotation vector ``phi(s) = Log(R_c^T R(s))`` in a chart around the window's middle sample
``R_c`` (body frame, the frame of the noise), translation per world axis, each a cubic in
``u = (s - c_i) / a`` (``c_i`` the window's centre, ``a`` its half-width, seconds)::

    S_i(delta) = (R_c Exp(phi_i(u)), t_c + p_i(u)),      u = (t_i + delta - c_i) / a

A linear smoother: with iid sample noise (``sigma_R`` per rotation-vector component,
``sigma_t`` per coordinate) the fit's value at ``u`` carries ``sigma^2 h(u)``,
``h(u) = e(u)^T (A^T A)^-1 e(u)`` (``A`` the window's design matrix, ``e(u) = (1, u, u^2,
u^3)``; the hat matrix's diagonal at ``u``; about ``2.25 / n_w`` at the centre).  Profiling
the window's cubic out of its samples' likelihood leaves, exactly, the prior of image i::

    r = (Log(S_R^T R_M), t_M - S_t) / (sigma sqrt(h(u)))

with ``h`` at the current ``u``: were it held at the centre, the fit's error (which moves with
``delta``) would pull every offset towards where the fit is most precise, a bias of up to one
standard deviation for short windows.  With ``omega = J_r(phi) dphi/ds`` the body-frame
angular velocity and ``v = dp/ds`` the velocity of the fit (exact derivatives of the model),
``rho = (Log(S_R^T R_M), t_M - S_t)`` and ``s = 1 / (sigma sqrt(h(u)))``::

    d r_R / d delta = -J_l^-1(rho_R) omega s_R - r_R h'(u) / (2 a h(u)),
    d r_t / d delta = -v s_t - r_t h'(u) / (2 a h(u)),
    d r_R / d phi_M = J_r^-1(rho_R) s_R,      d r_t / d tau_M = I s_t

(``M`` on ``se3-right``).  The offset is an ``euclidean`` block of size 1 (family
``dt:<camera>``), one per camera, or one per clock shared by several cameras
(:attr:`ClockData.shared`, family ``dt:<first of them>``, :class:`ClockUnits`): cameras
triggered together are stamped by one clock, and their images with bitwise equal stamps are
one instant, one block of ``M``, one window fit and one prior, so the motion capture's error
there counts once.  The windows are centred at the offset they were built at
(:meth:`LocalTrajectory.__init__`); :func:`multieye.estimate.refine_images.refine_images`
re-centres them when the offset moves by more than a quarter of the half-width.

Assumptions: the errors of the fits at two instants are independent; exact when their windows
share no sample, an approximation when they do (images of one camera closer than the window,
or cameras triggered together but each given its own clock).  benchmarks/bench_clock_joint.py
measures what it costs (docs/results/clock_joint.md): with 3 cameras triggered together on
their own clocks the mean NEES of X and Y is about 1.2, 1.3 with nearly noise-free pixels, and
near 1 on one shared clock; counting the shared error once per image instead (variance times
the summed correlations) overshoots to 0.5-0.6.
The trajectory is smooth at the window's scale (a cubic's bias, about ``0.004 a^4`` times
the fourth derivative, is below the noise); the sample noise is white.  The sample noise
itself can be estimated from the fits' residuals (:meth:`LocalTrajectory.noise`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.lie import exp_so3, left_jacobian, left_jacobian_inv, log_so3
from multieye.optimize.blocks import Blocks, ResidualGroup

__all__ = ["ClockData", "ClockUnits", "clock_units", "LocalTrajectory", "TimedMocapPriors", "offset_family",
           "shared_clocks", "DEFAULT_HALF_WINDOW_S", "DEGREE", "MIN_SAMPLES"]

F64 = NDArray[np.float64]

#: Half-width of the window of motion-capture samples fitted around each image, seconds.
DEFAULT_HALF_WINDOW_S = 0.05
#: Degree of the local polynomial.
DEGREE = 3
#: Fewest samples in a window (a slower motion capture gets a wider window).
MIN_SAMPLES = DEGREE + 5


def offset_family(name: str) -> str:
    """Block-family name of a camera's clock offset."""
    return f"dt:{name}"


def shared_clocks(stamps, mocaps=None) -> list[list[int]]:
    """Cameras stamped by one clock, from their image stamps: two cameras are on one clock
    when at least half of the images of each have an equal stamp in the other (cameras
    triggered together) and, given ``mocaps``, they pair with one motion capture; transitively.

    Parameters
    ----------
    stamps : sequence of 1-D array
        Per camera, its image stamps (seconds).
    mocaps : sequence of (ndarray (K,), ndarray (K, 4, 4)), optional
        Per camera, the motion capture it pairs with (sample stamps, poses): cameras on
        different motion captures are never on one clock (one offset would not fit both).

    Returns
    -------
    list of list of int
        The groups of two or more cameras (indices into ``stamps``), each ascending.
    """
    t = [np.asarray(x, dtype=np.float64).reshape(-1) for x in stamps]
    parent = list(range(len(t)))

    def root(a):
        while parent[a] != a:
            a = parent[a]
        return a

    def one_mocap(a, b) -> bool:
        return mocaps is None or mocaps[a] is mocaps[b] or all(
            np.array_equal(x, y) for x, y in zip(mocaps[a], mocaps[b]))

    for a in range(len(t)):
        for b in range(a + 1, len(t)):
            if (t[a].size and t[b].size and 2 * np.isin(t[a], t[b]).sum() >= t[a].size
                    and 2 * np.isin(t[b], t[a]).sum() >= t[b].size and one_mocap(a, b)):
                parent[max(root(a), root(b))] = min(root(a), root(b))
    groups: dict[int, list[int]] = {}
    for a in range(len(t)):
        groups.setdefault(root(a), []).append(a)
    return [g for g in groups.values() if len(g) > 1]


@dataclass(frozen=True)
class ClockData:
    """What a camera's clock offset is estimated from.

    Attributes
    ----------
    image_stamps : ndarray, shape (N_j,)
        Camera-clock time of each of the camera's images (in the order of its
        observations), seconds.
    mocap_stamps : ndarray, shape (K,)
        Motion-capture sample times (its own clock), strictly increasing, seconds.
    mocap_T : ndarray, shape (K, 4, 4)
        The motion-capture trajectory (``T_world_marker`` or ``T_world_body``), metres.
    offset : float
        Starting offset, seconds (motion-capture clock minus camera clock).
    half_window_s : float
        Half-width of the window fitted around each image (:class:`LocalTrajectory`).
    shared : str or None
        Name of a clock shared by several cameras (cameras triggered together, stamped by
        one clock): the cameras whose ClockData carry the same name have ONE offset (family
        ``dt:<first of them>``, :class:`ClockUnits`), started at the mean of their
        ``offset``; their images with bitwise equal stamps are one motion-capture instant
        (one block of ``M``, one prior, one window fit).  They must give the same motion
        capture and ``half_window_s``.  None (default): the camera's own clock.
    """

    image_stamps: F64
    mocap_stamps: F64
    mocap_T: F64
    offset: float = 0.0
    half_window_s: float = DEFAULT_HALF_WINDOW_S
    shared: str | None = None

    def __post_init__(self):
        s = np.asarray(self.mocap_stamps, dtype=np.float64).reshape(-1)
        T = np.asarray(self.mocap_T, dtype=np.float64)
        if (len(s) < MIN_SAMPLES or T.shape != (len(s), 4, 4) or np.any(np.diff(s) <= 0)
                or not np.all(np.isfinite(s)) or not np.all(np.isfinite(T))):
            raise InputError(f"a clock needs at least {MIN_SAMPLES} motion-capture samples with "
                             "finite, strictly increasing stamps and one finite 4x4 pose each")
        t = np.asarray(self.image_stamps, dtype=np.float64).reshape(-1)
        if not np.all(np.isfinite(t)):
            raise InputError("image stamps must be finite")
        if not (np.isfinite(self.offset) and np.isfinite(self.half_window_s)
                and self.half_window_s > 0):
            raise InputError(f"clock offset must be finite and the half window positive, got "
                             f"{self.offset!r} and {self.half_window_s!r}")
        object.__setattr__(self, "mocap_stamps", s)
        object.__setattr__(self, "mocap_T", T)
        object.__setattr__(self, "image_stamps", t)
        object.__setattr__(self, "offset", float(self.offset))


class LocalTrajectory:
    """Local cubic fits of the motion-capture trajectory around each image (module docstring).

    Parameters
    ----------
    clock : ClockData
    centre_offset : float, optional
        Offset at which the windows are centred (default ``clock.offset``): the window of
        image i holds the ``n_w`` samples nearest ``t_i + centre_offset``.

    Attributes
    ----------
    centre_offset : float
    n_window : int
        Samples per window.
    h : ndarray, shape (N_j,)
        Variance factor of each fit at its window's centre: the fit's value there has
        variance ``h_i sigma^2`` per component for sample noise ``sigma``.
    """

    def __init__(self, clock: ClockData, centre_offset: float | None = None):
        self.clock = clock
        self.centre_offset = clock.offset if centre_offset is None else float(centre_offset)
        s, T, t = clock.mocap_stamps, clock.mocap_T, clock.image_stamps
        K = len(s)
        dt = float(np.median(np.diff(s)))
        n_w = min(max(2 * int(round(clock.half_window_s / dt)) + 1, MIN_SAMPLES), K)
        self.n_window = n_w
        c = t + self.centre_offset
        k0 = np.clip(np.searchsorted(s, c) - n_w // 2, 0, K - n_w)
        idx = k0[:, None] + np.arange(n_w)                                 # (N, n_w)
        a = np.maximum(0.5 * (s[idx[:, -1]] - s[idx[:, 0]]), 1e-9)        # half-widths, s
        u = (s[idx] - c[:, None]) / a[:, None]
        outside = (np.abs(u[np.arange(len(c)), np.argmin(np.abs(u), axis=1)]) * a
                   > 2.0 * dt + clock.half_window_s)
        if np.any(outside):
            i = int(np.argmax(outside))
            raise InputError(f"image {i} at {t[i]:.6f} s (+ offset {self.centre_offset:+.6f} s) "
                             "is outside the motion capture or in a gap of it")
        near = idx[np.arange(len(c)), np.argmin(np.abs(u), axis=1)]
        self.c, self.a = c, a
        self.Rc, self.tc = T[near, :3, :3], T[near, :3, 3]
        phi = log_so3(np.swapaxes(self.Rc, 1, 2)[:, None] @ T[idx, :3, :3])  # (N, n_w, 3)
        Z = np.concatenate([phi, T[idx, :3, 3] - self.tc[:, None]], axis=2)  # (N, n_w, 6)
        A = u[..., None] ** np.arange(DEGREE + 1)                          # (N, n_w, 4)
        self.inv = np.linalg.inv(np.swapaxes(A, 1, 2) @ A)                 # (N, 4, 4)
        self.coef = self.inv @ (np.swapaxes(A, 1, 2) @ Z)                  # (N, 4, 6)
        fit = Z - A @ self.coef
        self.rss = np.einsum("nki,nki->ni", fit, fit)                      # (N, 6)
        self.h = self.inv[:, 0, 0].copy()

    @property
    def dof(self) -> int:
        """Residual degrees of freedom of each window's fit."""
        return self.n_window - DEGREE - 1

    def noise(self) -> tuple[float, float]:
        """Sample noise from the fits' residuals: RMS per rotation-vector component (radians)
        and per coordinate (metres), pooled over the windows."""
        n = len(self.rss) * self.dof * 3
        return (float(np.sqrt(self.rss[:, :3].sum() / n)),
                float(np.sqrt(self.rss[:, 3:].sum() / n)))

    def at(self, delta: float) -> tuple[F64, F64, F64]:
        """The fitted poses at offset ``delta`` and their derivatives in time.

        Returns
        -------
        poses : ndarray, shape (N_j, 4, 4)
            ``S_i(delta)``: the fitted pose at ``t_i + delta`` (motion-capture clock).
        omega : ndarray, shape (N_j, 3)
            Body-frame angular velocity ``J_r(phi) dphi/ds``, rad/s.
        velocity : ndarray, shape (N_j, 3)
            World-frame velocity, m/s.
        """
        u = (self.clock.image_stamps + delta - self.c) / self.a
        k = np.arange(DEGREE + 1)
        powers = u[:, None] ** k                                           # (N, 4)
        dpowers = np.zeros_like(powers)
        dpowers[:, 1:] = k[1:] * u[:, None] ** (k[1:] - 1) / self.a[:, None]
        p = np.einsum("nk,nkc->nc", powers, self.coef)
        dp = np.einsum("nk,nkc->nc", dpowers, self.coef)
        phi = p[:, :3]
        poses = np.tile(np.eye(4), (len(u), 1, 1))
        poses[:, :3, :3] = self.Rc @ exp_so3(phi)
        poses[:, :3, 3] = self.tc + p[:, 3:]
        omega = np.einsum("nij,nj->ni", left_jacobian(-phi), dp[:, :3])    # J_r(phi) dphi/ds
        return poses, omega, dp[:, 3:]

    def variance_factor(self, delta: float) -> tuple[F64, F64]:
        """``h(u)`` of each fit at offset ``delta`` (module docstring) and its derivative
        with respect to ``delta`` (1/s), both shape (N_j,)."""
        u = (self.clock.image_stamps + delta - self.c) / self.a
        k = np.arange(DEGREE + 1)
        e = u[:, None] ** k
        de = np.zeros_like(e)
        de[:, 1:] = k[1:] * u[:, None] ** (k[1:] - 1)
        h = np.einsum("ni,nij,nj->n", e, self.inv, e)
        return h, 2.0 * np.einsum("ni,nij,nj->n", de, self.inv, e) / self.a


class TimedMocapPriors(ResidualGroup):
    """The motion-capture priors of one camera's images with its clock offset free
    (module docstring): one row of 6 per image, slots ``M`` and ``dt:<camera>``.

    Parameters
    ----------
    name : str
        Camera name.
    images : ndarray of int, shape (N_j,)
        Block of ``M`` of each of the camera's images.
    trajectory : LocalTrajectory
        The smoothed trajectory around each of these images.
    sigma_rot, sigma_t : float
        Noise of one motion-capture sample: per rotation-vector component (radians,
        marker/body frame) and per position coordinate (metres, world frame).
    """

    def __init__(self, name: str, images, trajectory: LocalTrajectory, sigma_rot: float,
                 sigma_t: float):
        images = np.asarray(images, dtype=np.int64)
        if len(images) != len(trajectory.h):
            raise InputError(f"camera {name}: {len(trajectory.h)} image stamps for "
                             f"{len(images)} images")
        super().__init__(("M", offset_family(name)),
                         np.column_stack([images, np.zeros(len(images), int)]),
                         np.arange(len(images)), 6)
        self.name, self.trajectory = name, trajectory
        self.sigma = np.repeat([float(sigma_rot), float(sigma_t)], 3)

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        delta = float(values[offset_family(self.name)][0, 0])
        S, omega, vel = self.trajectory.at(delta)
        h, dh = self.trajectory.variance_factor(delta)
        scale = 1.0 / np.sqrt(h)[:, None] / self.sigma        # (N_j, 6)
        M = values["M"][self.index[:, 0]]
        r_rot = log_so3(np.swapaxes(S[:, :3, :3], 1, 2) @ M[:, :3, :3])
        raw = np.concatenate([r_rot, M[:, :3, 3] - S[:, :3, 3]], axis=1)
        r = raw * scale
        if not jacobians:
            return r, None
        n = len(M)
        JM = np.zeros((n, 6, 6))
        JM[:, :3, :3] = left_jacobian_inv(-r_rot) * scale[:, :1, None]        # J_r^-1(r_R)
        JM[:, 3:, 3:] = np.eye(3) * scale[:, 3:4, None]
        Jd = np.zeros((n, 6, 1))
        Jd[:, :3, 0] = -np.einsum("nij,nj->ni", left_jacobian_inv(r_rot), omega)
        Jd[:, 3:, 0] = -vel
        Jd[:, :, 0] = Jd[:, :, 0] * scale - 0.5 * r * (dh / h)[:, None]      # d scale / d delta
        return r, [JM, Jd]


@dataclass(frozen=True)
class ClockUnits:
    """The clocks of the cameras of an image-level problem: one *unit* per camera with a clock
    of its own, one per shared clock (:attr:`ClockData.shared`), in the order of their first
    camera.  A unit has one offset block (family ``dt:<first camera>``), one
    :class:`LocalTrajectory` over its instants and one :class:`TimedMocapPriors`.  Built in
    two steps, both returning a new value: :func:`clock_units` (the units, before the
    instants are numbered), then :meth:`built` (their blocks and trajectories).

    Attributes
    ----------
    clocks : tuple of (ClockData or None)
        Per camera.
    cameras : tuple of tuple of int
        The cameras of each unit.
    family : tuple of str
        Offset family of each unit.
    unit_of_camera : dict of int to int
    blocks : tuple of ndarray of int
        Blocks of ``M`` (instants) of each unit, after :meth:`built`.
    clock : tuple of ClockData
        Per unit, over its instants' stamps (a camera's own ClockData when not shared).
    trajectories : tuple of LocalTrajectory
    """

    clocks: tuple
    cameras: tuple[tuple[int, ...], ...]
    family: tuple[str, ...]
    unit_of_camera: dict[int, int]
    blocks: tuple[np.ndarray, ...] = ()
    clock: tuple[ClockData, ...] = ()
    trajectories: tuple[LocalTrajectory, ...] = ()

    def key(self, camera: int, i: int):
        """Instant key of image ``i`` of ``camera`` (a camera with a clock): None (an instant
        of its own) unless the clock is shared, then the unit and the stamp's bits."""
        c = self.clocks[camera]
        if c.shared is None:
            return None
        return ("clock", self.unit_of_camera[camera], c.image_stamps[i].tobytes())

    def built(self, instant, instant_image, cam_of_image, image_in_camera) -> ClockUnits:
        """These units with each unit's blocks of ``M``, its ClockData over them and its
        trajectory."""
        blocks, clock = [], []
        for js in self.cameras:
            c0 = self.clocks[js[0]]
            b = np.unique(instant[np.isin(cam_of_image, js)])   # order of appearance
            if c0.shared is not None:
                first = instant_image[b]
                stamps = np.array([self.clocks[cam_of_image[i]].image_stamps[image_in_camera[i]]
                                   for i in first])
                c0 = replace(c0, image_stamps=stamps,
                             offset=float(np.mean([self.clocks[j].offset for j in js])))
            blocks.append(b)
            clock.append(c0)
        return replace(self, blocks=tuple(blocks), clock=tuple(clock),
                       trajectories=tuple(LocalTrajectory(c) for c in clock))

    def families(self) -> list[Blocks]:
        """One offset block per unit, at its starting offset."""
        return [Blocks(f, np.array([[c.offset]]), "euclidean")
                for f, c in zip(self.family, self.clock)]

    def priors(self, sigma_rot: float, sigma_t: float) -> list[TimedMocapPriors]:
        """One group of timed priors per unit."""
        return [TimedMocapPriors(self.family[u][3:], self.blocks[u], self.trajectories[u],
                                 sigma_rot, sigma_t) for u in range(len(self.cameras))]

    def recentred(self, offsets: Mapping[int, float]) -> ClockUnits:
        """These units with the windows of each unit in ``offsets`` centred at its offset
        (seconds)."""
        trajectories = list(self.trajectories)
        for unit, offset in offsets.items():
            trajectories[unit] = LocalTrajectory(self.clock[unit], float(offset))
        return replace(self, trajectories=tuple(trajectories))


def clock_units(clocks: Mapping[str, ClockData | None]) -> ClockUnits:
    """The units of the cameras' clocks (:class:`ClockUnits`), before their blocks are known.

    Parameters
    ----------
    clocks : mapping of camera name to (ClockData or None)
        Every camera's, in camera order (checked by the caller).
    """
    names, clocks = list(clocks), list(clocks.values())
    units: dict = {}
    for j, c in enumerate(clocks):
        if c is not None:
            units.setdefault(j if c.shared is None else ("shared", c.shared), []).append(j)
    cameras = tuple(tuple(v) for v in units.values())
    for js in cameras:
        c0 = clocks[js[0]]
        for j in js[1:]:
            c = clocks[j]
            if not (c.half_window_s == c0.half_window_s
                    and np.array_equal(c.mocap_stamps, c0.mocap_stamps)
                    and np.array_equal(c.mocap_T, c0.mocap_T)):
                raise InputError(f"cameras {names[js[0]]} and {names[j]} share the clock "
                                 f"{c0.shared!r} but not its motion capture or half window")
    return ClockUnits(clocks=tuple(clocks), cameras=cameras,
                      family=tuple(offset_family(names[js[0]]) for js in cameras),
                      unit_of_camera={j: u for u, js in enumerate(cameras) for j in js})
