"""The image-level problem as residual groups for the engine: target pixels and mocap priors.

What is measured are the target points' pixels and the motion-capture poses; with the true
motion-capture pose ``M_i`` of every image as a nuisance parameter (``T_world_marker``
eye-to-base, ``T_world_body`` eye-on-hand)::

    T_cam_target_i = inv(X^j) @ M_i @ Y          eye-to-base   (A_i = inv(M_i))
    T_cam_target_i = inv(X^j) @ inv(M_i) @ Y     eye-on-hand   (A_i = M_i)

i.e. ``T_cam_target = inv(X) inv(A) Y`` in both setups (docs/conventions.md, section 2).

One motion-capture measurement is one unknown: images whose given poses are bitwise equal
(cameras triggered together, paired with the same sample or interpolated at the same time)
share one block ``M_k`` of one *instant* k and its one prior, so that the measurement's
information is counted once, not once per camera (counted m times, the covariance of X and
Y came out too small: benchmarks/bench_shared_instants.py, docs/results/shared_instants.md).
Images of a camera whose clock offset is estimated keep a block each (their poses come from
the smoothed trajectory at the camera's own times), except on a clock shared by several
cameras (:attr:`ClockData.shared`): its images with bitwise equal stamps share one.  So N
images map to K <= N instants (:attr:`ImageData.instant`).

Residual groups (:class:`multieye.optimize.blocks.ResidualGroup`):

- :class:`PixelResiduals`: per target point, ``(pi_j(T_cam_target_i p_k) - u_ik) / sigma_px``
  (2 components), touching its camera's ``X``, ``Y`` and its image's instant ``M_k``; one
  segment per image.  Jacobian: the lens model's ``d uv / d p_cam`` from OpenCV
  (:func:`multieye.core.lens.project_with_jacobian`) chained with the pose derivatives below.
- :class:`MocapPriors`: per instant, ``(Log(R_meas^T R_M) / sigma_R, (t_M - t_meas) / sigma_t)``
  (6 components), touching ``M``; its Jacobian is ``diag(J_r^-1(r_R) / sigma_R, I / sigma_t)``.

Block families (:class:`multieye.optimize.blocks.Blocks`): ``X`` (m poses) and ``Y`` (one)
on ``se3-left``, ``R = Exp(phi) R_hat``, ``t = t_hat + tau`` (the covariance convention of
docs/conventions.md); ``M`` (one per instant) on ``se3-right``, ``R_M = R Exp(phi)`` (rotation
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

from multieye.core.arguments import camera_names, real_array
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, project_with_jacobian
from multieye.core.lie import left_jacobian_inv, log_so3
from multieye.core.problem import SETUPS
from multieye.estimate.clock_residuals import ClockData, ClockUnits
from multieye.optimize.blocks import Blocks, ResidualGroup, SegmentRange

__all__ = ["ImageData", "PixelResiduals", "MocapPriors"]

F64 = NDArray[np.float64]


def _as_pose(T, what: str) -> F64:
    T = real_array(T, what, expected="a finite 4x4 transform")
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InputError(f"{what} must be a finite 4x4 transform, got shape {T.shape}")
    return T


def _view(item, where: str, pose: str, min_points: int):
    """One image's (object_points, image_points, pose), checked: the arrays, their shapes, the
    finite points (at least ``min_points``) and the pose; returns them and the finite mask."""
    try:
        o, u, T = item
    except (TypeError, ValueError):
        raise InputError(f"{where}: expected (object_points, image_points, {pose})") from None
    o = real_array(o, f"{where}: object points", expected="an array (n, 3)")
    u = real_array(u, f"{where}: image points", expected="an array (n, 2)")
    if o.ndim != 2 or o.shape[1] != 3 or u.shape != (len(o), 2):
        raise InputError(f"{where}: object points must be (n, 3) and image points "
                         f"(n, 2), got {o.shape} and {u.shape}")
    ok = np.all(np.isfinite(o), axis=1) & np.all(np.isfinite(u), axis=1)
    if ok.sum() < min_points:
        raise InputError(f"{where}: " + ("no finite target point" if min_points == 1 else
                                         f"fewer than {min_points} finite target points"))
    return o, u, _as_pose(T, f"{where}: {pose}"), ok


class ImageData:
    """Target points, pixels and motion-capture poses of every image, stacked.

    Images are numbered camera by camera (N in all); points image by image.  The images of
    cameras without a clock whose motion-capture poses are bitwise equal share one instant
    (one block of ``M``, one prior); every other image has an instant of its own, so K = N
    when no pose is repeated (module docstring).

    Attributes
    ----------
    instant : ndarray of int, shape (N,)
        Block of ``M`` (instant) of each image, numbered in the order of first appearance.
    n_instants : int
        K, the number of blocks of ``M``.
    instant_image : ndarray of int, shape (K,)
        The first image of each instant.
    mocap_measured : ndarray, shape (N, 4, 4)
        The given motion-capture pose of each image.

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
    free_intrinsics : sequence of bool, optional
        Per camera: estimate its intrinsics (default: all held fixed).
    intrinsics_observations : sequence over cameras of sequence of (object_points, image_points, T_cam_target), optional
        Images without motion capture that only inform a camera's intrinsics (cameras whose
        intrinsics are estimated): the target points, their pixels and a starting
        ``T_cam_target`` (PnP).  An empty list for a camera without such images.
    clocks : sequence of (ClockData or None), optional
        Per camera: its clock offset is an unknown (family ``dt:<camera>``, or
        ``dt:<first camera>`` of a shared clock: :class:`ClockUnits`) and its images'
        motion-capture priors compare ``M_i`` with the smoothed trajectory at
        ``t_i + delta`` (:mod:`multieye.estimate.clock_residuals`); the image stamps are the
        camera's images in the order of ``observations[j]``.  None: the given poses are the
        measurements (default for every camera).
    """

    def __init__(self, setup: str, observations: Sequence, intrinsics: Sequence[Intrinsics],
                 names: Sequence[str] | None = None, *,
                 free_intrinsics: Sequence[bool] | None = None,
                 intrinsics_observations: Sequence | None = None,
                 clocks: Sequence | None = None):
        if not isinstance(setup, str) or setup not in SETUPS:
            raise InputError(f"setup must be one of {SETUPS}, got {setup!r}")
        for label, arg in (("observations", observations), ("intrinsics", intrinsics)):
            if arg is None or isinstance(arg, (str, bytes)) or not hasattr(arg, "__iter__"):
                raise InputError(f"{label} must be a list with one entry per camera, got "
                                 f"{type(arg).__name__}")
        observations = list(observations)
        intrinsics = list(intrinsics)
        m = len(observations)
        if m == 0:
            raise InputError("no cameras given: observations is empty")
        if len(intrinsics) != m:
            raise InputError(f"{m} cameras of observations but {len(intrinsics)} intrinsics; "
                             "give one Intrinsics per camera")
        bad = [j for j, c in enumerate(intrinsics) if not isinstance(c, Intrinsics)]
        if bad:
            raise InputError(f"intrinsics[{bad[0]}] must be a multieye Intrinsics, got "
                             f"{type(intrinsics[bad[0]]).__name__}")
        names = camera_names(names, m)
        self.names = names if names is not None else tuple(f"cam{j}" for j in range(m))
        self.setup = setup
        self.intrinsics = tuple(intrinsics)
        self.m = m
        obj, uv, mocap, img_of_point, cam_of_image, counts, keep = [], [], [], [], [], [], []
        for j, images in enumerate(observations):
            if images is None or isinstance(images, (str, bytes)) or not hasattr(images,
                                                                                  "__iter__"):
                raise InputError(f"observations[{j}] must be a list of (object_points, "
                                 f"image_points, T_world_mocap), got {type(images).__name__}")
            images = list(images)
            if not images:
                raise InputError(f"camera {self.names[j]} has no images")
            counts.append(len(images))
            for i, item in enumerate(images):
                where = f"camera {self.names[j]}, image {i}"
                o, u, M, ok = _view(item, where, "T_world_mocap", 1)
                obj.append(o[ok])
                uv.append(u[ok])
                keep.append(ok)
                mocap.append(M)
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
        free = [False] * m if free_intrinsics is None else [bool(f) for f in free_intrinsics]
        if len(free) != m:
            raise InputError(f"free_intrinsics has {len(free)} entries for {m} cameras")
        self.free = tuple(free)
        self.clocks = tuple(clocks) if clocks is not None else (None,) * m
        if len(self.clocks) != m:
            raise InputError(f"clocks has {len(self.clocks)} entries for {m} cameras")
        for j, c in enumerate(self.clocks):
            if c is not None and not isinstance(c, ClockData):
                raise InputError(f"clocks[{j}] must be a ClockData or None, got "
                                 f"{type(c).__name__}")
            if c is not None and len(c.image_stamps) != counts[j]:
                raise InputError(f"camera {self.names[j]}: {len(c.image_stamps)} image stamps "
                                 f"for {counts[j]} images")
        #: The cameras' clocks: one offset and one trajectory per camera or shared clock.
        self.units = ClockUnits(self.clocks, self.names)
        self._instants()
        self.extra = (None if intrinsics_observations is None else
                      IntrinsicsImages(intrinsics_observations, self.names, self.free))
        if self.extra is not None and self.extra.n_images == 0:
            self.extra = None

    def _instants(self) -> None:
        """Number the instants: one per distinct given pose of the cameras without a clock
        (bitwise equal 4x4), one per distinct stamp of a shared clock, one per image of a
        camera with a clock of its own."""
        seen: dict = {}
        instant = np.empty(self.n_images, dtype=np.int64)
        first = []
        in_camera = np.arange(self.n_images) - np.repeat(np.cumsum(self.counts) - self.counts,
                                                         self.counts)
        for i, (M, j) in enumerate(zip(self.mocap_measured, self.cam_of_image)):
            key = (M.tobytes() if self.clocks[j] is None
                   else self.units.key(int(j), int(in_camera[i])))
            k = seen.get(key) if key is not None else None
            if k is None:
                k = len(first)
                first.append(i)
                if key is not None:
                    seen[key] = k
            instant[i] = k
        self.instant = instant
        self.instant_image = np.asarray(first, dtype=np.int64)
        self.n_instants = len(first)
        self.units.build(instant, self.instant_image, self.cam_of_image, in_camera)

    def families(self, X: F64, Y: F64, M: F64 | None = None, *,
                 intrinsics: Sequence[Intrinsics] | None = None,
                 free_poses: F64 | None = None) -> list[Blocks]:
        """Block families: ``X`` (m), ``Y`` (1), ``M`` (one per instant, (K, 4, 4)),
        ``K:<camera>`` for every camera whose intrinsics are estimated (:attr:`free`; values
        from ``intrinsics``, default the given ones), ``dt:<camera>`` for every camera with a
        clock (its starting offset), and ``T`` for the intrinsics-only images (``free_poses``,
        default their starting poses).  ``M`` defaults to :meth:`mocap_start`."""
        M = self.mocap_start() if M is None else M
        intrinsics = self.intrinsics if intrinsics is None else intrinsics
        fams = [Blocks("X", X, "se3-left"), Blocks("Y", np.asarray(Y)[None], "se3-left")]
        fams += [Blocks(intrinsics_family(n), intrinsics[j].params[None], "euclidean")
                 for j, n in enumerate(self.names) if self.free[j]]
        fams += self.units.families()
        fams.append(Blocks("M", M, "se3-right", eliminate=True))
        if self.extra is not None:
            T = self.extra.poses if free_poses is None else free_poses
            fams.append(Blocks("T", T, "se3-left", eliminate=True))
        return fams

    def groups(self, sigma_px: float, sigma_rot: float, sigma_t: float) -> list[ResidualGroup]:
        """One pixel group per camera, the motion-capture priors, then one group of
        intrinsics-only images per camera that has them, at these noise levels."""
        out: list[ResidualGroup] = [PixelResiduals(self, j, sigma_px, self.free[j])
                                    for j in range(self.m)]
        timed = [j for j, c in enumerate(self.clocks) if c is not None]
        plain = np.flatnonzero(~np.isin(self.cam_of_image[self.instant_image], timed))
        if plain.size:                                  # one prior per instant, not per image
            out.append(MocapPriors(self.mocap_measured[self.instant_image], sigma_rot, sigma_t,
                                   plain))
        out += self.units.priors(sigma_rot, sigma_t)
        if self.extra is not None:
            out += self.extra.groups(self, sigma_px)
        return out

    def mocap_start(self, offsets: Sequence[float | None] | None = None) -> F64:
        """The motion-capture poses the refinement starts from, one per instant (K, 4, 4):
        the given ones, and for a clock the smoothed trajectory at ``t_i + offset``
        (``offsets`` per camera, a shared clock taking its first camera's; default each
        clock's starting offset)."""
        out = self.mocap_measured[self.instant_image]
        for u, traj in enumerate(self.units.trajectories):
            j = self.units.cameras[u][0]
            d = self.units.clock[u].offset if offsets is None or offsets[j] is None else offsets[j]
            out[self.units.blocks[u]] = traj.at(float(d))[0]
        return out

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


def intrinsics_family(name: str) -> str:
    """Block-family name of a camera's intrinsics when they are estimated."""
    return f"K:{name}"


def _pixels(pc: F64, intr: Intrinsics, with_jacobian: bool):
    """Pixels of camera-frame points and, when asked, d uv / d pc and d uv / d intrinsics."""
    if with_jacobian:
        return project_with_jacobian(pc, intr)
    return project_points(pc, intr), None, None


def _current_intrinsics(values: Mapping[str, F64], name: str, fixed: Intrinsics,
                        free: bool) -> Intrinsics | None:
    """The camera's intrinsics at the current values (None if the values are not valid)."""
    if not free:
        return fixed
    try:
        return fixed.with_params(values[intrinsics_family(name)][0])
    except InputError:
        return None


class IntrinsicsImages:
    """Images without motion capture that only inform the intrinsics, stacked camera by camera.

    Attributes
    ----------
    poses : ndarray, shape (n_images, 4, 4)
        Starting ``T_cam_target`` of each image.
    camera : ndarray of int, shape (n_images,)
    object_points, image_points : ndarray, shape (P, 3), (P, 2)
    image : ndarray of int, shape (P,)
        Image of each point.
    """

    def __init__(self, per_camera: Sequence, names: Sequence[str], free: Sequence[bool]):
        per_camera = list(per_camera)
        if len(per_camera) != len(names):
            raise InputError(f"intrinsics_observations has {len(per_camera)} entries for "
                             f"{len(names)} cameras (give an empty list for a camera without "
                             "such images)")
        poses, cams, obj, uv, img = [], [], [], [], []
        for j, images in enumerate(per_camera):
            images = list(images or ())
            if images and not free[j]:
                raise InputError(f"camera {names[j]}: images for the intrinsics given, but its "
                                 "intrinsics are not estimated")
            for i, item in enumerate(images):
                where = f"camera {names[j]}, intrinsics image {i}"
                o, u, T, ok = _view(item, where, "T_cam_target", 4)
                obj.append(o[ok])
                uv.append(u[ok])
                img.append(np.full(int(ok.sum()), len(poses)))
                poses.append(T)
                cams.append(j)
        self.names = tuple(names)
        self.n_images = len(poses)
        if not poses:
            return
        self.poses = np.stack(poses)
        self.camera = np.asarray(cams)
        self.object_points = np.concatenate(obj)
        self.image_points = np.concatenate(uv)
        self.image = np.concatenate(img)

    def groups(self, data: ImageData, sigma_px: float) -> list[ResidualGroup]:
        """One :class:`FreePoseResiduals` per camera that has such images."""
        out = []
        for j in np.unique(self.camera):
            pts = self.camera[self.image] == j
            first = int(np.flatnonzero(self.camera == j)[0])
            out.append(FreePoseResiduals(self.names[j], data.intrinsics[j],
                                         self.object_points[pts], self.image_points[pts],
                                         self.image[pts], first, sigma_px))
        return out


class PixelResiduals(ResidualGroup):
    """One camera's target-point pixel residuals over ``sigma_px`` (module docstring).

    Slots ``X``, ``Y``, ``M`` (the instant of each image, :attr:`ImageData.instant`) and,
    when the camera's intrinsics are estimated, its intrinsics
    family ``K:<camera>`` (``fx fy cx cy`` then the distortion, :attr:`Intrinsics.params`).
    The chain is evaluated image by image on zero-padded ``(n_images, n_max, 3)`` point
    arrays, so every rotation is one batched 3x3 product per image rather than per point, and
    :meth:`linearize` hands the engine the per-image Jacobian blocks directly.

    Parameters
    ----------
    data : ImageData
    camera : int
    sigma_px : float
    free_intrinsics : bool
        Estimate the camera's intrinsics (a slot of their own).
    """

    def __init__(self, data: ImageData, camera: int, sigma_px: float,
                 free_intrinsics: bool = False):
        images = np.flatnonzero(data.cam_of_image == camera)
        self.first = int(images[0])
        pts = data.camera_slices[camera]
        slots = ("X", "Y", "M") + ((intrinsics_family(data.names[camera]),)
                                   if free_intrinsics else ())
        index = np.column_stack([np.full(images.size, camera), np.zeros(images.size, int),
                                 data.instant[images]] + ([np.zeros(images.size, int)]
                                            if free_intrinsics else []))
        super().__init__(slots, index, data.image[pts] - self.first, 2)
        self.data, self.camera, self.points = data, camera, pts
        self.images = images
        self.blocks = data.instant[images]                          # block of M of each image
        self.sigma = float(sigma_px)
        self.free = bool(free_intrinsics)
        self._obj = np.zeros((images.size, self.longest, 3))
        self._obj[self.segment, self.position] = data.object_points[pts]
        self._uv = data.image_points[pts]

    def _chain(self, X: F64, Y: F64, M: F64, images: slice = slice(None)):
        """Per image (n, n_max, 3): ``R_Y p``, ``p_y``, ``q``, ``d`` and ``p_cam``."""
        RX, tX = X[self.camera, :3, :3], X[self.camera, :3, 3]
        blocks = self.blocks[images]
        RM, tM = M[blocks, :3, :3], M[blocks, :3, 3]
        ry = self._obj[images] @ Y[:3, :3].T
        py = ry + Y[:3, 3]
        if self.data.setup == "eye-to-base":
            q = py @ np.swapaxes(RM, 1, 2) + tM[:, None]                # R_M p_y + t_M
        else:
            q = (py - tM[:, None]) @ RM                                  # R_M^T (p_y - t_M)
        d = q - tX
        return ry, py, q, d, d @ RX                                      # p_cam = R_X^T d

    def camera_points(self, X: F64, Y: F64, M: F64) -> F64:
        """The camera's target points in its frame, (P_j, 3), metres."""
        return self._chain(X, Y, M)[4][self.segment, self.position]

    def _intrinsics(self, values) -> Intrinsics | None:
        return _current_intrinsics(values, self.data.names[self.camera],
                                   self.data.intrinsics[self.camera], self.free)

    def _linear(self, values: Mapping[str, F64], part: SegmentRange):
        """Residuals and per-image Jacobian blocks of the images of ``part``."""
        X, Y, M, intr = values["X"], values["Y"][0], values["M"], self._intrinsics(values)
        images, seg, pos = slice(*part.index_range), part.segment, part.position
        ry, py, q, d, pc = self._chain(X, Y, M, images)
        uv, Jp, Jk = _pixels(pc[seg, pos], intr, True)
        r = (uv - self._uv[part.rows]) / self.sigma
        n_img, n = len(self.blocks[images]), self.longest
        Jp_pad = np.zeros((n_img, n, 2, 3))
        Jp_pad[seg, pos] = Jp / self.sigma
        RX = X[self.camera, :3, :3]
        RM = M[self.blocks[images], :3, :3]
        G = RX.T @ (RM if self.data.setup == "eye-to-base" else RM.swapaxes(1, 2))
        flat = Jp_pad.reshape(n_img, 2 * n, 3)
        JpR = (flat @ RX.T).reshape(n_img, n, 2, 3)                     # d r / d q
        JpG = (flat @ G).reshape(n_img, n, 2, 3)                        # d r / d p_y
        if self.data.setup == "eye-to-base":
            JM = [-_cross(JpG, py), JpR]
        else:
            JM = [_cross(JpR, q), -JpG]
        parts = [_cross(JpR, d), -JpR, -_cross(JpG, ry), JpG] + JM
        if self.free:
            Jk_pad = np.zeros((n_img, n, 2, Jk.shape[2]))
            Jk_pad[seg, pos] = Jk / self.sigma
            parts.append(Jk_pad)
        return r, np.concatenate(parts, axis=3)                          # (n_img, n, 2, c)

    def linearize(self, values: Mapping[str, F64]):
        return next(self.linearize_chunks(values, len(self.images)))[1:]

    def linearize_chunks(self, values: Mapping[str, F64], max_segments: int):
        """:meth:`linearize` ``max_segments`` images at a time (so the whole Jacobian is never held)."""
        if self._intrinsics(values) is None:
            raise InputError(f"camera {self.data.names[self.camera]}: intrinsics outside the model's valid range")
        for lo in range(0, len(self.images), max(int(max_segments), 1)):
            part = SegmentRange(self, lo, min(lo + max_segments, len(self.images)))
            r, blocks = self._linear(values, part)
            yield part, r, blocks.reshape(len(blocks), -1, blocks.shape[-1]), part.pad(r)

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        intr = self._intrinsics(values)
        if intr is None:
            return np.full((self.n_rows, 2), np.nan), None
        if jacobians:
            r, blocks = self._linear(values, SegmentRange(self, 0, len(self.images)))
            rows = blocks[self.segment, self.position]                   # (P_j, 2, c)
            cuts = np.cumsum([0, 6, 6, 6] + ([rows.shape[2] - 18] if self.free else []))
            return r, [rows[:, :, a:b] for a, b in zip(cuts[:-1], cuts[1:])]
        pc = self.camera_points(values["X"], values["Y"][0], values["M"])
        return (_pixels(pc, intr, False)[0] - self._uv) / self.sigma, None


class FreePoseResiduals(ResidualGroup):
    """Pixel residuals of images that only inform a camera's intrinsics (no motion capture):
    each image has its own ``T_cam_target`` (family ``T``, ``se3-left``, eliminated).

    ``d p_cam / d phi_T = -[R_T p]_x``, ``d p_cam / d tau_T = I``.

    Parameters
    ----------
    name : str
        Camera name.
    intrinsics : Intrinsics
        The camera's (starting) intrinsics.
    object_points, image_points : ndarray, shape (P, 3), (P, 2)
        Target points and pixels, image by image.
    image : ndarray of int, shape (P,)
        Block of family ``T`` of each point (non-decreasing).
    first : int
        Block of ``T`` of this camera's first image.
    sigma_px : float
    """

    def __init__(self, name: str, intrinsics: Intrinsics, object_points: F64,
                 image_points: F64, image, first: int, sigma_px: float):
        image = np.asarray(image)
        n_img = int(image.max()) + 1 - first
        super().__init__(("T", intrinsics_family(name)),
                         np.column_stack([first + np.arange(n_img), np.zeros(n_img, int)]),
                         image - first, 2)
        self.name, self.intrinsics = name, intrinsics
        self._uv = image_points
        self._obj = np.zeros((n_img, self.longest, 3))
        self._obj[self.segment, self.position] = object_points
        self.first, self.n_img = first, n_img
        self.sigma = float(sigma_px)

    def _points(self, T: F64):
        T = T[self.first:self.first + self.n_img]
        rp = self._obj @ np.swapaxes(T[:, :3, :3], 1, 2)
        return rp, rp + T[:, None, :3, 3]

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        intr = _current_intrinsics(values, self.name, self.intrinsics, True)
        if intr is None:
            return np.full((self.n_rows, 2), np.nan), None
        rp, pc = self._points(values["T"])
        seg, pos = self.segment, self.position
        uv, Jp, Jk = _pixels(pc[seg, pos], intr, jacobians)
        r = (uv - self._uv) / self.sigma
        if not jacobians:
            return r, None
        Jp = Jp / self.sigma
        JT = np.concatenate([-_cross(Jp, rp[seg, pos]), Jp], axis=2)
        return r, [JT, Jk / self.sigma]


class MocapPriors(ResidualGroup):
    """Motion-capture pose priors (module docstring), one row of 6 per instant (one
    measurement), slot M.

    Parameters
    ----------
    measured : ndarray, shape (K, 4, 4)
        Measured motion-capture pose of every block of ``M`` (instant).
    sigma_rot, sigma_t : float
        Noise of each rotation-vector component (radians, marker/body frame) and of each
        position coordinate (metres, world frame).
    blocks : array_like of int, shape (n,), optional
        The blocks of ``M`` (instants) these priors cover; default all.
    """

    def __init__(self, measured: F64, sigma_rot: float, sigma_t: float, blocks=None):
        blocks = np.arange(len(measured)) if blocks is None else np.asarray(blocks, int)
        super().__init__(("M",), blocks[:, None], np.arange(len(blocks)), 6)
        self.measured = measured[blocks]
        self.scale = 1.0 / np.repeat([float(sigma_rot), float(sigma_t)], 3)

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        M, Mm = values["M"][self.index[:, 0]], self.measured
        r_rot = log_so3(np.swapaxes(Mm[:, :3, :3], 1, 2) @ M[:, :3, :3])
        r = np.concatenate([r_rot, M[:, :3, 3] - Mm[:, :3, 3]], axis=1) * self.scale
        if not jacobians:
            return r, None
        J = np.zeros((len(M), 6, 6))
        J[:, :3, :3] = left_jacobian_inv(-r_rot) * self.scale[0]        # J_r^-1(r_rot)
        J[:, 3:, 3:] = np.eye(3) * self.scale[3]
        return r, [J]
