"""The image-level problem's data, stacked once and frozen: :class:`ImageData` built by
:func:`image_data` from per camera the images (target points, pixels, motion-capture pose),
the lens, whether it is estimated (with its intrinsics-only images) and the clock.

The residual groups it makes (:meth:`ImageData.groups`) are in
:mod:`multieye.estimate.image_residuals`; the refinement on them in
:mod:`multieye.estimate.refine_images`.  Images whose given motion-capture poses are bitwise
equal share one *instant* (one pose block, one prior); see the module docstring of
:mod:`multieye.estimate.image_residuals`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from multieye.core.arguments import camera_names, real_array, transform
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.problem import SETUPS
from multieye.estimate.clock_residuals import ClockData, ClockUnits, clock_units
from multieye.estimate.image_residuals import (
    DenominatorPrior,
    FreePoseResiduals,
    MocapPriors,
    PixelResiduals,
    intrinsics_family,
)
from multieye.optimize.blocks import Blocks, ResidualGroup

__all__ = ["ImageData", "ImageProblem", "image_data", "PointStack", "IntrinsicsImages", "intrinsics_images"]

F64 = NDArray[np.float64]


def view_points(item, where: str, third: str, min_points: int):
    """One image's ``(object_points, image_points, third)``, its points checked: the arrays,
    their shapes and the finite points (at least ``min_points``).  Returns the two arrays,
    the third item as given (a pose, an instant: the caller checks it) and the finite mask.
    ``third`` names it in the messages; ``where`` names the image."""
    try:
        o, u, x = item
    except (TypeError, ValueError):
        raise InputError(f"{where}: expected (object_points, image_points, {third})") from None
    o = real_array(o, f"{where}: object points", expected="an array (n, 3)")
    u = real_array(u, f"{where}: image points", expected="an array (n, 2)")
    if o.ndim != 2 or o.shape[1] != 3 or u.shape != (len(o), 2):
        raise InputError(f"{where}: object points must be (n, 3) and image points "
                         f"(n, 2), got {o.shape} and {u.shape}")
    ok = np.all(np.isfinite(o), axis=1) & np.all(np.isfinite(u), axis=1)
    if ok.sum() < min_points:
        raise InputError(f"{where}: " + ("no finite target point" if min_points == 1 else
                                         f"fewer than {min_points} finite target points"))
    return o, u, x, ok


def _view(item, where: str, pose: str, min_points: int):
    """One image's (object_points, image_points, pose), checked (:func:`view_points`, then
    the pose as a 4x4 transform); returns them and the finite mask."""
    o, u, T, ok = view_points(item, where, pose, min_points)
    return o, u, transform(T, f"{where}: {pose}"), ok


@dataclass(frozen=True)
class ImageData:
    """Target points, pixels and motion-capture poses of every image, stacked; built by
    :func:`image_data`, never changed after (:meth:`recentred` returns a new one).

    Images are numbered camera by camera (N in all); points image by image.  The images of
    cameras without a clock whose motion-capture poses are bitwise equal share one instant
    (one block of ``M``, one prior); every other image has an instant of its own, so K = N
    when no pose is repeated (module docstring).

    Attributes
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    names : tuple of str
        Camera names (m).
    intrinsics : tuple of Intrinsics
    free : tuple of bool
        Per camera: its intrinsics are estimated.
    clocks : tuple of (ClockData or None)
        Per camera.
    points : PointStack
        Every image's target points and pixels, and what indexes them.
    mocap_measured : ndarray, shape (N, 4, 4)
        The given motion-capture pose of each image.
    instant : ndarray of int, shape (N,)
        Block of ``M`` (instant) of each image, numbered in the order of first appearance.
    instant_image : ndarray of int, shape (K,)
        The first image of each instant.
    units : ClockUnits
        The cameras' clocks: one offset and one trajectory per camera or shared clock.
    extra : IntrinsicsImages or None
        The images that only inform the intrinsics.
    mocap_noise_scale : ndarray, shape (N,), or None
        Per image: the noise of its motion-capture pose over the stated one (below 1 for a
        pose interpolated between two samples); None: 1 for every image.
    image_noise : ndarray, shape (N,), or None
        Per image: its pixel noise over the pixel sigma the groups are made with (estimated
        by :func:`multieye.estimate.variance_components.image_noise`); None: 1 for every image.
    """

    setup: str
    names: tuple[str, ...]
    intrinsics: tuple[Intrinsics, ...]
    free: tuple[bool, ...]
    clocks: tuple
    points: PointStack
    mocap_measured: F64
    instant: np.ndarray
    instant_image: np.ndarray
    units: ClockUnits
    extra: IntrinsicsImages | None
    mocap_noise_scale: F64 | None = None
    image_noise: F64 | None = None

    # the stacked points' indices, as the residual groups read them
    m = property(lambda self: len(self.names))
    object_points = property(lambda self: self.points.object_points)
    image_points = property(lambda self: self.points.image_points)
    image = property(lambda self: self.points.image)
    keep = property(lambda self: self.points.keep)
    cam_of_image = property(lambda self: self.points.cam_of_image)
    camera = property(lambda self: self.points.camera)
    counts = property(lambda self: self.points.counts)
    image_starts = property(lambda self: self.points.image_starts)
    camera_slices = property(lambda self: self.points.camera_slices)
    n_images = property(lambda self: len(self.mocap_measured))
    n_points = property(lambda self: len(self.points.object_points))
    n_instants = property(lambda self: len(self.instant_image))

    def recentred(self, offsets: Mapping[int, float]) -> ImageData:
        """This problem with the windows of each clock unit in ``offsets`` centred at its
        offset (seconds)."""
        return replace(self, units=self.units.recentred(offsets))

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
        """One pixel group per camera, the motion-capture priors, one group of
        intrinsics-only images per camera that has them, at these noise levels, then the
        denominator prior of every estimated rational lens (:class:`DenominatorPrior`)."""
        out: list[ResidualGroup] = [PixelResiduals(self, j, sigma_px, self.free[j])
                                    for j in range(self.m)]
        timed = [j for j, c in enumerate(self.clocks) if c is not None]
        plain = np.flatnonzero(~np.isin(self.cam_of_image[self.instant_image], timed))
        if plain.size:                                  # one prior per instant, not per image
            factors = (None if self.mocap_noise_scale is None
                       else self.mocap_noise_scale[self.instant_image][plain])
            out.append(MocapPriors(self.mocap_measured[self.instant_image], sigma_rot, sigma_t,
                                   plain, factors))
        out += self.units.priors(sigma_rot, sigma_t)
        if self.extra is not None:
            out += self.extra.groups(self, sigma_px)
        out += [DenominatorPrior(n, self.intrinsics[j]) for j, n in enumerate(self.names)
                if self.free[j] and self.intrinsics[j].model == "pinhole"
                and self.intrinsics[j].dist.size >= 8]
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



@dataclass(frozen=True)
class PointStack:
    """The target points of every image, stacked image by image (P in all), and what
    indexes them.

    Attributes
    ----------
    object_points, image_points : ndarray, shape (P, 3), (P, 2)
    image : ndarray of int, shape (P,)
        Image of each point.
    keep : tuple of ndarray of bool
        Per image, which of its input points are finite (and stacked).
    cam_of_image : ndarray of int, shape (N,)
    camera : ndarray of int, shape (P,)
        Camera of each point.
    counts : ndarray of int, shape (m,)
        Images per camera.
    image_starts : ndarray of int, shape (N,)
        First point of each image.
    camera_slices : tuple of slice
        Points of each camera.
    """

    object_points: F64
    image_points: F64
    image: np.ndarray
    keep: tuple[np.ndarray, ...]
    cam_of_image: np.ndarray
    camera: np.ndarray
    counts: np.ndarray
    image_starts: np.ndarray
    camera_slices: tuple[slice, ...]


def _camera_list(arg, label: str) -> list:
    if arg is None or isinstance(arg, (str, bytes)) or not hasattr(arg, "__iter__"):
        raise InputError(f"{label} must be a list with one entry per camera, got "
                         f"{type(arg).__name__}")
    return list(arg)


def _stack(given: ImageProblem) -> tuple[PointStack, F64]:
    """The images' points stacked, and their motion-capture poses (N, 4, 4) (``given``: the
    observations a list per camera, the names a tuple)."""
    observations, names = given.observations, given.names
    obj, uv, mocap, img_of_point, cam_of_image, counts, keep = [], [], [], [], [], [], []
    for j, images in enumerate(observations):
        if images is None or isinstance(images, (str, bytes)) or not hasattr(images,
                                                                              "__iter__"):
            raise InputError(f"observations[{j}] must be a list of (object_points, "
                             f"image_points, T_world_mocap), got {type(images).__name__}")
        images = list(images)
        if not images:
            raise InputError(f"camera {names[j]} has no images")
        counts.append(len(images))
        for i, item in enumerate(images):
            o, u, M, ok = _view(item, f"camera {names[j]}, image {i}", "T_world_mocap", 1)
            obj.append(o[ok])
            uv.append(u[ok])
            keep.append(ok)
            mocap.append(M)
            img_of_point.append(np.full(int(ok.sum()), len(mocap) - 1))
            cam_of_image.append(j)
    image = np.concatenate(img_of_point)
    cam_of_image = np.asarray(cam_of_image)
    camera = cam_of_image[image]
    m = len(names)
    return PointStack(
        object_points=np.concatenate(obj), image_points=np.concatenate(uv), image=image,
        keep=tuple(keep), cam_of_image=cam_of_image, camera=camera, counts=np.asarray(counts),
        image_starts=np.flatnonzero(np.diff(image, prepend=-1)),
        camera_slices=tuple(slice(int(a), int(b)) for a, b in zip(
            np.searchsorted(camera, np.arange(m)),
            np.searchsorted(camera, np.arange(m), side="right")))), np.stack(mocap)


def _checked_clocks(given: ImageProblem, counts: np.ndarray) -> tuple:
    names, clocks = given.names, given.clocks
    m = len(names)
    clocks = tuple(clocks) if clocks is not None else (None,) * m
    if len(clocks) != m:
        raise InputError(f"clocks has {len(clocks)} entries for {m} cameras")
    for j, c in enumerate(clocks):
        if c is not None and not isinstance(c, ClockData):
            raise InputError(f"clocks[{j}] must be a ClockData or None, got "
                             f"{type(c).__name__}")
        if c is not None and len(c.image_stamps) != counts[j]:
            raise InputError(f"camera {names[j]}: {len(c.image_stamps)} image stamps "
                             f"for {counts[j]} images")
    return clocks


def _instants(points: PointStack, mocap: F64, clocks: tuple, units: ClockUnits):
    """Number the instants: one per distinct given pose of the cameras without a clock
    (bitwise equal 4x4), one per distinct stamp of a shared clock, one per image of a
    camera with a clock of its own.  Returns the instant of each image, the first image of
    each instant and the units built over them."""
    seen: dict = {}
    n_images = len(mocap)
    instant = np.empty(n_images, dtype=np.int64)
    first = []
    counts = points.counts
    in_camera = np.arange(n_images) - np.repeat(np.cumsum(counts) - counts, counts)
    for i, (M, j) in enumerate(zip(mocap, points.cam_of_image)):
        key = M.tobytes() if clocks[j] is None else units.key(int(j), int(in_camera[i]))
        k = seen.get(key) if key is not None else None
        if k is None:
            k = len(first)
            first.append(i)
            if key is not None:
                seen[key] = k
        instant[i] = k
    instant_image = np.asarray(first, dtype=np.int64)
    return instant, instant_image, units.built(instant, instant_image, points.cam_of_image,
                                               in_camera)


@dataclass(frozen=True)
class ImageProblem:
    """The image-level problem as given: what :func:`image_data` checks and stacks.

    Attributes
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
    mocap_noise_scale : sequence over cameras of sequence of float, optional
        ``mocap_noise_scale[j][i]``: the noise of image i's motion-capture pose over the
        stated noise, in (0, 1] (:attr:`multieye.estimate.pairing.Pairing.noise_scale`: a
        pose interpolated between two samples); default 1.  Not used for cameras with a clock.
    """

    setup: str
    observations: Sequence
    intrinsics: Sequence[Intrinsics]
    names: Sequence[str] | None = None
    free_intrinsics: Sequence[bool] | None = None
    intrinsics_observations: Sequence | None = None
    clocks: Sequence | None = None
    mocap_noise_scale: Sequence | None = None


def image_data(problem: ImageProblem) -> ImageData:
    """The image-level problem's data (:class:`ImageProblem`), checked and stacked
    (:class:`ImageData`)."""
    setup = problem.setup
    if not isinstance(setup, str) or setup not in SETUPS:
        raise InputError(f"setup must be one of {SETUPS}, got {setup!r}")
    observations = _camera_list(problem.observations, "observations")
    intrinsics = _camera_list(problem.intrinsics, "intrinsics")
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
    names = camera_names(problem.names, m) or tuple(f"cam{j}" for j in range(m))
    given = replace(problem, observations=observations, intrinsics=intrinsics, names=names)
    points, mocap = _stack(given)
    free_intrinsics = problem.free_intrinsics
    free = (False,) * m if free_intrinsics is None else tuple(bool(f) for f in free_intrinsics)
    if len(free) != m:
        raise InputError(f"free_intrinsics has {len(free)} entries for {m} cameras")
    clocks = _checked_clocks(given, points.counts)
    instant, instant_image, units = _instants(points, mocap, clocks, clock_units(dict(zip(names, clocks))))
    extra = (None if problem.intrinsics_observations is None else
             intrinsics_images(replace(given, free_intrinsics=free)))
    return ImageData(setup=setup, names=names, intrinsics=tuple(intrinsics), free=free,
                     clocks=clocks, points=points, mocap_measured=mocap, instant=instant,
                     instant_image=instant_image, units=units,
                     extra=None if extra is None or extra.n_images == 0 else extra,
                     mocap_noise_scale=_noise_scale(problem.mocap_noise_scale, points.counts))


def _noise_scale(given: Sequence | None, counts: np.ndarray) -> F64 | None:
    """``mocap_noise_scale`` of :class:`ImageProblem` checked and stacked, (N,)."""
    if given is None:
        return None
    if len(given) != len(counts):
        raise InputError(f"mocap_noise_scale has {len(given)} entries for {len(counts)} cameras")
    parts = []
    for j, (f, n) in enumerate(zip(given, counts)):
        f = np.ones(n) if f is None else real_array(f, f"mocap_noise_scale[{j}]", shape=(n,))
        if not np.all((f > 0) & (f <= 1)):
            raise InputError(f"mocap_noise_scale[{j}] must be in (0, 1], one per image")
        parts.append(f)
    return np.concatenate(parts)

@dataclass(frozen=True)
class IntrinsicsImages:
    """Images without motion capture that only inform the intrinsics, stacked camera by
    camera; built by :func:`intrinsics_images`.

    Attributes
    ----------
    names : tuple of str
    n_images : int
    poses : ndarray, shape (n_images, 4, 4)
        Starting ``T_cam_target`` of each image.
    camera : ndarray of int, shape (n_images,)
    object_points, image_points : ndarray, shape (P, 3), (P, 2)
    image : ndarray of int, shape (P,)
        Image of each point.
    """

    names: tuple[str, ...]
    n_images: int
    poses: F64 | None = None
    camera: np.ndarray | None = None
    object_points: F64 | None = None
    image_points: F64 | None = None
    image: np.ndarray | None = None

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



def intrinsics_images(given: ImageProblem) -> IntrinsicsImages:
    """The intrinsics-only images (``intrinsics_observations`` of :class:`ImageProblem`),
    checked and stacked (``given``: the names a tuple, ``free_intrinsics`` one per camera)."""
    names, free = given.names, given.free_intrinsics
    per_camera = list(given.intrinsics_observations)
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
            o, u, T, ok = _view(item, f"camera {names[j]}, intrinsics image {i}",
                                "T_cam_target", 4)
            obj.append(o[ok])
            uv.append(u[ok])
            img.append(np.full(int(ok.sum()), len(poses)))
            poses.append(T)
            cams.append(j)
    if not poses:
        return IntrinsicsImages(names=tuple(names), n_images=0)
    return IntrinsicsImages(names=tuple(names), n_images=len(poses), poses=np.stack(poses),
                            camera=np.asarray(cams), object_points=np.concatenate(obj),
                            image_points=np.concatenate(uv), image=np.concatenate(img))

