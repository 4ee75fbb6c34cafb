"""A camera's intrinsics from its own target images: OpenCV's calibration as the starting point.

The joint problem (:func:`multieye.estimate.refine_images.refine_images` with
``free_intrinsics``) estimates every camera's intrinsics together with the extrinsics and the
motion capture; it needs a start.  That start is what a user would get from
``cv2.calibrateCamera`` (pinhole models) or ``cv2.fisheye.calibrate`` (equidistant fisheye)
on the same detected points, camera by camera (on at most :data:`START_VIEWS` of them, which
is enough for a start and several times faster; the other views' poses follow by PnP).

Synopsis
--------
>>> start = initial_intrinsics(views, (1280, 960), "pinhole-radtan")      # doctest: +SKIP
>>> start.intrinsics.K, start.rms_px                                       # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import partial

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import LENS_MODELS, Intrinsics
from multieye.imaging.batch import DEFAULT_MAX_RMS_PX, ImageResult
from multieye.core.lens import project_points
from multieye.imaging.generic_start import ValleyRival, fit_lens, generic_start
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import collinear, estimate_pose, estimate_poses
from multieye.imaging.rays import bearings
from multieye.imaging.pool_tasks import SplitTask
from multieye.imaging.image_file import read_region
from multieye.imaging.targets import Chessboard, Target
from multieye.imaging.wide_look import is_wide, second_look

__all__ = ["InitialIntrinsics", "initial_intrinsics", "MIN_VIEWS", "StartedLens",
           "LensFromViews", "lens_start_task", "poses_from_detections", "lens_from_detections",
           "poses_with_start", "started_lens", "accept_on_refined_lens", "look_again"]

F64 = NDArray[np.float64]

#: Views of the target below which a camera's intrinsics are not estimated at all.
MIN_VIEWS = 3
_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
#: Views (at most) that OpenCV's calibration starts a lens from (:func:`_fisheye_start`).
START_VIEWS = 20


@dataclass(frozen=True)
class InitialIntrinsics:
    """OpenCV's per-camera calibration.

    Attributes
    ----------
    intrinsics : Intrinsics
    T_cam_target : ndarray, shape (n_views, 4, 4)
        The pose of the target in each view, as OpenCV estimated it with these intrinsics
        (NaN rows for the views not calibrated from, when asked for no others: see
        :func:`initial_intrinsics`' ``all_poses``).
    rms_px : float
        OpenCV's RMS reprojection error over the views it calibrated from (at most
        :data:`START_VIEWS`, spread over the recording; the others' poses are PnP with the
        lens found), pixels.
    rivals : tuple of ValleyRival
        Wide models with a valley (unified, double-sphere): lenses at other optima that fit
        the views the start was fitted to as well (:attr:`multieye.imaging.generic_start.
        LensFit.rivals`); none otherwise.
    """

    intrinsics: Intrinsics
    T_cam_target: F64
    rms_px: float
    rivals: tuple[ValleyRival, ...] = ()


def _flat_guess(views, size) -> F64:
    """A pinhole camera matrix from the views' homographies (Zhang's method, via OpenCV)."""
    obj = [np.ascontiguousarray(o[:, :2], np.float64) for o, _ in views]
    img = [np.ascontiguousarray(u, np.float64) for _, u in views]
    return cv2.initCameraMatrix2D([np.column_stack([o, np.zeros(len(o))]).astype(np.float32)
                                   for o in obj],
                                  [u.astype(np.float32) for u in img], size)


def _equidistant_from_radial(dist: F64, K: F64, views) -> F64:
    """Fisheye (equidistant) k1..k4 that bend rays as OpenCV's radial ``k1 k2 k3`` do.

    Both map the angle ``theta`` of a ray off the axis to a normalised image radius: the
    pinhole ``r = tan(theta) (1 + k1 tan^2 + k2 tan^4 + k3 tan^6)``, the equidistant
    ``r = theta (1 + c1 theta^2 + c2 theta^4 + c3 theta^6 + c4 theta^8)``; the ``c`` are the
    linear least-squares fit over the angles up to the largest the views show.

    Parameters
    ----------
    dist : ndarray, shape (k,)
        OpenCV distortion ``k1 k2 p1 p2 k3``; tangential terms ignored.
    K : ndarray, shape (3, 3)
    views : sequence of (object_points, image_points)
    """
    d = np.zeros(5)
    d[:min(5, dist.size)] = dist[:5]
    uv = np.concatenate([u for _, u in views])
    xy = (uv - K[:2, 2]) / np.diag(K)[:2]
    r_max = float(np.max(np.hypot(xy[:, 0], xy[:, 1])))
    # the pinhole radius is monotonic up to where its derivative vanishes: stay below
    t = np.linspace(1e-3, max(r_max, 1e-2), 200)
    r = t * (1 + d[0] * t ** 2 + d[1] * t ** 4 + d[4] * t ** 6)
    keep = np.concatenate([[True], np.diff(r) > 0]) & (r > 0)
    theta = np.arctan(t[keep])
    A = theta[:, None] * theta[:, None] ** np.array([2, 4, 6, 8])
    c, *_ = np.linalg.lstsq(A, r[keep] - theta, rcond=None)
    return c if np.all(np.isfinite(c)) else np.zeros(4)


def _spread(n: int, k: int) -> NDArray[np.int64]:
    """``min(n, k)`` indices evenly spread over ``0 .. n - 1``."""
    return np.unique(np.linspace(0, n - 1, min(n, k)).round().astype(np.int64))


def _calibrate_camera(obj, img, size, flags: int):
    """``cv2.calibrateCamera`` on one thread: on several, OpenCV sums its normal equations
    in an order that changes from call to call, and the lens (with every result after it)
    differed in its last digits between identical runs (up to 2e-7 relative)."""
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        return cv2.calibrateCamera(obj, img, size, None, None, flags=flags, criteria=_CRITERIA)
    finally:
        cv2.setNumThreads(threads)


def _pinhole_start(obj, img, size, flags: int, all_poses: bool = True):
    """``cv2.calibrateCamera`` on at most :data:`START_VIEWS` views spread over the
    recording, then (``all_poses``) every other view's pose by ``cv2.solvePnP`` with that
    lens (same return values, None for a view not posed; the RMS over the calibrated views).
    See :func:`_fisheye_start`.  Views of fewer than 4 points or of points on one line (a
    ChArUco board's single column of corners) determine no homography and would make OpenCV
    fail: they are neither calibrated from nor posed (None)."""
    good = np.array([i for i, o in enumerate(obj) if len(o) >= 4
                     and not collinear(np.asarray(o, np.float64)[:, :2])], np.int64)
    if good.size < MIN_VIEWS:
        raise cv2.error(f"only {good.size} views of 4 or more points not on one line")
    pick = good[_spread(good.size, START_VIEWS)]
    rms, K, D, rv, tv = _calibrate_camera([obj[i] for i in pick], [img[i] for i in pick],
                                          size, flags)
    rvecs, tvecs = [None] * len(obj), [None] * len(obj)
    for i, r, t in zip(pick, rv, tv):
        rvecs[i], tvecs[i] = r, t
    for i in np.setdiff1d(good, pick) if all_poses else ():
        ok, rvecs[i], tvecs[i] = cv2.solvePnP(obj[i], img[i], K, D)
        if not ok:
            raise cv2.error(f"no pose of view {i} with the start lens")
    return rms, K, D, rvecs, tvecs


def _generic_start(views, size, model: str, name: str, all_poses: bool) -> InitialIntrinsics:
    """A lens of a fisheye or wide model from at most :data:`START_VIEWS` views spread over
    the recording, started from a generic lens (:func:`multieye.imaging.generic_start.
    generic_start`: no OpenCV calibration, any field of view), then (``all_poses``) every
    other view's pose by PnP with it (NaN rows for the views not posed).

    On 20 views of ``boofcv_fisheye`` (about 180 degrees) it takes about 0.3 CPU-s and
    leaves 0.1-0.3 px per view, where ``cv2.fisheye.calibrate`` left 2-5 px or failed.
    """
    pick = _spread(len(views), START_VIEWS)
    try:
        fit = generic_start([views[i] for i in pick], size, model)
    except (InputError, np.linalg.LinAlgError) as exc:
        raise InputError(f"camera {name}: no lens start from {len(views)} images ({exc}); "
                         "add images with the whole target in view at different tilts"
                         ) from None
    T = np.full((len(views), 4, 4), np.nan)
    T[pick] = fit.T_cam_target
    rms = fit.rms_px[np.isfinite(fit.rms_px)]
    if rms.size < MIN_VIEWS:
        raise InputError(f"camera {name}: only {rms.size} of {len(pick)} images fit a lens; "
                         f"at least {MIN_VIEWS} are needed (add images of the whole target)")
    rest = np.setdiff1d(np.arange(len(views)), pick) if all_poses else ()
    for i in rest:
        T[i] = _pnp_pose(*views[i], fit.intrinsics)
    return InitialIntrinsics(fit.intrinsics, T, float(np.sqrt(np.mean(rms ** 2))), fit.rivals)


def initial_intrinsics(views: Sequence[tuple[F64, F64]], image_size: tuple[int, int],
                       model: str, *, name: str = "camera", all_poses: bool = True
                       ) -> InitialIntrinsics:
    """Intrinsics of one camera from views of a planar target (OpenCV's calibration).

    Parameters
    ----------
    views : sequence of (object_points, image_points)
        Per image: the target points in the target frame, (n, 3) metres with z = 0, and
        their pixels, (n, 2).
    image_size : (int, int)
        Width and height, pixels.
    model : {"pinhole-radtan", "pinhole-radtan4", "pinhole-rational", "fisheye"}
        Lens model (:data:`multieye.core.intrinsics.LENS_MODELS`).
    name : str
        Camera name for messages.
    all_poses : bool
        Pose every view with the lens found; False: only the views OpenCV calibrated from
        (the others' rows of ``T_cam_target`` are NaN), for a caller that poses every view
        anyway (:func:`lens_start_task`).

    Returns
    -------
    InitialIntrinsics

    Raises
    ------
    InputError
        Unknown model, fewer than :data:`MIN_VIEWS` views, or OpenCV failing to calibrate
        (the message names the camera and what to add).
    """
    if model not in LENS_MODELS:
        raise InputError(f"camera {name}: unknown lens model {model!r}; expected one of "
                         f"{', '.join(LENS_MODELS)}")
    views = [(np.asarray(o, np.float64), np.asarray(u, np.float64)) for o, u in views]
    if len(views) < MIN_VIEWS:
        raise InputError(f"camera {name}: {len(views)} image(s) with the target, at least "
                         f"{MIN_VIEWS} are needed to estimate its intrinsics (add images of "
                         "the target at different tilts, or give intrinsics:)")
    w, h = int(image_size[0]), int(image_size[1])
    kind, coefficients = LENS_MODELS[model]
    try:
        if kind != "pinhole":
            try:
                return _generic_start(views, (w, h), model, name, all_poses)
            except InputError:
                if kind != "fisheye":
                    raise
                # views of a few points (one ArUco marker's 4 corners) may give no start:
                # OpenCV's pinhole calibration then, its radial distortion carried over to
                # the equidistant model (the joint refinement estimates the fisheye's)
                obj = [o.astype(np.float32) for o, _ in views]
                img = [u.astype(np.float32) for _, u in views]
                rms, K, Dp, rvecs, tvecs = _calibrate_camera(obj, img, (w, h),
                                                             cv2.CALIB_ZERO_TANGENT_DIST)
                D = _equidistant_from_radial(np.asarray(Dp, np.float64).reshape(-1), K, views)
        else:
            obj = [o.astype(np.float32) for o, _ in views]
            img = [u.astype(np.float32) for _, u in views]
            # the rational model starts from OpenCV's 5 coefficients, its denominator at 1:
            # with CALIB_RATIONAL_MODEL OpenCV lands anywhere along the family of numerators
            # and denominators that nearly share a factor (k1..k6 in the tens to thousands,
            # issue 32), and the joint refinement stays there (its denominator prior,
            # multieye.estimate.image_residuals.DenominatorPrior, then cannot pull it back)
            flags = cv2.CALIB_FIX_K3 if len(coefficients) == 4 else 0
            rms, K, D, rvecs, tvecs = _pinhole_start(obj, img, (w, h), flags, all_poses)
    except cv2.error as exc:
        raise InputError(f"camera {name}: OpenCV could not calibrate its intrinsics from "
                         f"{len(views)} images ({str(exc).strip().splitlines()[-1]}); add "
                         "images with the target tilted and in the corners of the image"
                         ) from None
    D = np.asarray(D, np.float64).reshape(-1)[:len(coefficients)]
    D = np.concatenate([D, np.zeros(len(coefficients) - D.size)])
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(D)) and np.isfinite(rms)):
        raise InputError(f"camera {name}: OpenCV's calibration of its intrinsics did not "
                         "converge; add images with the target tilted and covering the image")
    K = np.asarray(K, np.float64)
    K[0, 1] = 0.0
    try:
        intr = Intrinsics(K=K, dist=D, model=kind, width=w, height=h)
    except InputError as exc:
        raise InputError(f"camera {name}: OpenCV's calibration gave intrinsics outside any "
                         f"plausible range ({exc}); check the target and the images") from None
    T = np.zeros((len(views), 4, 4))
    T[:, 3, 3] = 1.0
    for k, (r, t) in enumerate(zip(rvecs, tvecs)):
        if r is None:
            T[k, :3] = np.nan
            continue
        T[k, :3, :3] = cv2.Rodrigues(np.asarray(r, np.float64).reshape(3))[0]
        T[k, :3, 3] = np.asarray(t, np.float64).reshape(3)
    return InitialIntrinsics(intrinsics=intr, T_cam_target=T, rms_px=float(rms))


@dataclass(frozen=True)
class StartedLens:
    """A camera's starting lens from its detections, and their poses by PnP with it.

    Attributes
    ----------
    start : InitialIntrinsics
        With every view's pose (those of ``results`` where OpenCV did not calibrate from it).
    results : tuple of ImageResult
        The detections, completed with their pose (:func:`poses_from_detections`).
    """

    start: InitialIntrinsics
    results: tuple[ImageResult, ...]


def lens_start_task(model: str, name: str = "camera", target: Target | None = None
                    ) -> SplitTask:
    """A camera's whole lens start from its detection-only results, as a task that a worker
    pool runs as soon as the camera's images are detected
    (:func:`multieye.imaging.batch.detect_jobs_then`): :func:`initial_intrinsics`
    (:func:`lens_from_detections`) on one worker, then every detection's pose with that lens
    (:func:`poses_with_start`) in parts on every worker, joined as a :class:`StartedLens`
    (:func:`started_lens`).  Called on the results (a sequence of :class:`ImageResult`,
    detection only), it runs here; its result is None when no start can be made (no image
    read, images of different sizes, too few views, OpenCV failing): the caller then starts
    the lens itself, to say why.

    Parameters
    ----------
    model : str
        Lens model (:data:`multieye.core.intrinsics.LENS_MODELS`).
    name : str
        Camera name for messages.
    target : Target, optional
        The board of the images: where it is a chessboard and the start is a wide lens,
        the images whose board was not found are looked at again through it first
        (:func:`look_again`, in the parts of :func:`poses_with_start`).
    """
    return SplitTask(partial(lens_from_detections, model=model, name=name),
                     partial(poses_with_start, target=target), started_lens)


@dataclass(frozen=True)
class LensFromViews:
    """The first step's result of :func:`lens_start_task`: OpenCV's start, and which of the
    results its views are (``start.T_cam_target[k]`` is the view of ``results[views[k]]``).

    Attributes
    ----------
    start : InitialIntrinsics
    views : tuple of int
    """

    start: InitialIntrinsics
    views: tuple[int, ...]


def lens_from_detections(results: Sequence[ImageResult], model: str, name: str = "camera"
                         ) -> LensFromViews | None:
    """The first step of :func:`lens_start_task`: :func:`initial_intrinsics` from
    one camera's detection-only results (None where no start can be made)."""
    sizes = {r.image_size for r in results if r.image_size is not None}
    if len(sizes) != 1:
        return None
    used = tuple(k for k, r in enumerate(results) if r.detection is not None and r.reason is None)
    views = [(results[k].detection.object_points, results[k].detection.image_points)
             for k in used]
    try:
        start = initial_intrinsics(views, sizes.pop(), model, name=name, all_poses=False)
    except InputError:
        return None
    return LensFromViews(start, used)


def poses_with_start(first: LensFromViews, results: Sequence[ImageResult], *,
                     max_rms_px: float = DEFAULT_MAX_RMS_PX, target: Target | None = None
                     ) -> list[ImageResult]:
    """The second step of :func:`lens_start_task`, for any part of the results: each
    one's pose with the start's lens (:func:`poses_from_detections`), after the second look
    of a wide lens at the images of ``target`` not found (:func:`look_again`)."""
    lens = first.start.intrinsics
    results = results if target is None else look_again(results, target, lens)
    return poses_from_detections(results, lens, max_rms_px=max_rms_px)


def look_again(results: Sequence[ImageResult], target: Target, intrinsics: Intrinsics
               ) -> list[ImageResult]:
    """Detection-only results, those of image files whose ``target`` was not found looked
    at again through the wide lens ``intrinsics`` (the start of the camera's lens:
    :func:`multieye.imaging.wide_look.second_look`; only a chessboard, only a wide lens:
    :func:`~multieye.imaging.wide_look.is_wide`); a board found so is a detection without
    a reason, ``second_look`` True.  The files are read again (checked as before:
    :func:`multieye.imaging.image_file.read_region`, in the region each was read in:
    ``ImageResult.crop``); results of other sizes than the lens's are left as they are."""
    if not isinstance(target, Chessboard) or not is_wide(intrinsics):
        return list(results)
    out = []
    for r in results:
        image = None
        if r.detection is None and (r.reason or "").startswith("target not detected") \
                and r.image_size == (intrinsics.width, intrinsics.height):
            image = read_region(r.path, r.image_size, r.crop)[0]
        det = None if image is None else second_look(image, target, intrinsics)
        out.append(r if det is None else replace(r, detection=det, reason=None,
                                                 warnings=r.warnings + det.warnings,
                                                 second_look=True))
    return out


def started_lens(first: LensFromViews, results: Sequence[ImageResult]) -> StartedLens:
    """The last step of :func:`lens_start_task`: the :class:`StartedLens`, its start's poses
    of the views OpenCV did not calibrate from (:func:`lens_from_detections` leaves them out)
    those of ``results`` (PnP with the start lens); ``cv2.solvePnP`` where PnP failed."""
    start = first.start
    T = start.T_cam_target.copy()
    missing = np.flatnonzero(np.isnan(T[:, 0, 0]))
    for k in missing:
        r = results[first.views[k]]
        T[k] = r.pose.T_cam_target if r.pose is not None else _pnp_pose(
            r.detection.object_points, r.detection.image_points, start.intrinsics)
    start = replace(start, T_cam_target=T) if missing.size else start
    refined, accepted = accept_on_refined_lens(results, start.intrinsics)
    if refined is not start.intrinsics:       # every view's pose with the refined lens
        T = start.T_cam_target.copy()
        for k, j in enumerate(first.views):
            pose = accepted[j].pose
            T[k] = np.nan if pose is None else pose.T_cam_target
        start = replace(start, intrinsics=refined, T_cam_target=T)
    return StartedLens(start, tuple(accepted))


def _pnp_pose(object_points: F64, image_points: F64, intrinsics: Intrinsics) -> F64:
    """``T_cam_target`` by ``cv2.solvePnP`` (pinhole lenses, as :func:`initial_intrinsics`
    poses a view) or :func:`multieye.imaging.pnp.estimate_pose` (on the viewing rays: every
    other model); NaN where none is found."""
    obj = np.asarray(object_points, np.float64).reshape(-1, 3)
    img = np.asarray(image_points, np.float64).reshape(-1, 2)
    if intrinsics.model != "pinhole":
        try:
            return estimate_pose(Detection(np.arange(len(obj)), img, obj), intrinsics
                                 ).T_cam_target
        except InputError:
            return np.full((4, 4), np.nan)
    try:
        ok, r, t = cv2.solvePnP(obj.astype(np.float32), img.astype(np.float32),
                                intrinsics.K, intrinsics.dist)
    except cv2.error:
        ok = False
    T = np.full((4, 4), np.nan)
    if ok:
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = cv2.Rodrigues(r)[0], t.reshape(3)
    return T


def poses_from_detections(results: Sequence[ImageResult], intrinsics: Intrinsics, *,
                          max_rms_px: float = DEFAULT_MAX_RMS_PX) -> list[ImageResult]:
    """Detection-only results completed with the target pose by PnP with ``intrinsics``
    (the same rules as detection with known intrinsics: a failed PnP or a bad fit becomes the
    image's reason), every view together (:func:`multieye.imaging.pnp.estimate_poses`).

    Points the lens model does not project at the pose found (a fisheye lens' points beyond
    90 degrees off its axis) are left out of the detection, with a warning, so that every
    point the later stages see has a pixel in the model."""
    out = list(results)
    if intrinsics.model != "pinhole":   # pixels without a ray in the model: left out first
        out = [_projected_only(r, intrinsics) if r.detection is not None and r.reason is None
               else r for r in out]
    todo = [k for k, r in enumerate(out) if r.detection is not None and r.reason is None]
    results = list(out)
    poses = estimate_poses([results[k].detection for k in todo], intrinsics)
    for k, pose in zip(todo, poses):
        if isinstance(pose, InputError):
            out[k] = replace(results[k], reason=f"PnP failed: {pose}")
            continue
        reason = None if pose.rms_px <= max_rms_px else (
            f"bad fit: reprojection RMS {pose.rms_px:.2f} px > {max_rms_px:g} px")
        out[k] = replace(results[k], pose=pose, reason=reason)
        if pose.n_points < len(results[k].detection) or not np.isfinite(pose.rms_px):
            out[k] = _projected_only(out[k], intrinsics)    # PnP left points out
    return out


def _projected_only(result: ImageResult, intrinsics: Intrinsics) -> ImageResult:
    """``result`` with its detection's points that ``intrinsics`` does not project at its
    pose (without a pose: whose pixels it has no ray for) left out; a warning names how
    many; fewer than 4 left: PnP failed."""
    det = result.detection
    if result.pose is None:
        keep = np.isfinite(bearings(det.image_points, intrinsics)).all(axis=1)
    else:
        T = result.pose.T_cam_target
        uv = project_points(det.object_points @ T[:3, :3].T + T[:3, 3], intrinsics)
        keep = np.isfinite(uv).all(axis=1)
    if keep.all():
        return result
    if keep.sum() < 4:
        return replace(result, reason=f"PnP failed: only {int(keep.sum())} of {len(keep)} "
                       f"points lie where the {intrinsics.model} lens projects")
    note = (f"{int((~keep).sum())} of {len(keep)} target points lie outside what the "
            f"{intrinsics.model} lens model projects (beyond 90 degrees off its axis for "
            "pinhole and fisheye); left out")
    return replace(result, detection=replace(det, ids=det.ids[keep],
                                             image_points=det.image_points[keep],
                                             object_points=det.object_points[keep]),
                   warnings=result.warnings + (note,))


def accept_on_refined_lens(results: Sequence[ImageResult], intrinsics: Intrinsics, *,
                           max_rms_px: float = DEFAULT_MAX_RMS_PX
                           ) -> tuple[Intrinsics, list[ImageResult]]:
    """Images judged on the refined lens, not on the start: those rejected as a bad fit
    with the starting lens are taken back when they fit the lens refined on them.

    When no image was rejected as a bad fit, nothing is done (``intrinsics`` and ``results``
    are returned as they are).  Otherwise the lens is fitted again with its views' poses
    (:func:`multieye.imaging.generic_start.fit_lens`, Huber loss, so that a truly bad view
    does not pull it) on at most :data:`START_VIEWS` accepted views spread over the
    recording and at most as many rejected ones, and every view is posed again with the
    refined lens: each image is accepted or rejected (RMS above ``max_rms_px``) on it.

    Parameters
    ----------
    results : sequence of ImageResult
        Posed with ``intrinsics`` (:func:`poses_from_detections`).
    intrinsics : Intrinsics
        The starting lens.
    max_rms_px : float

    Returns
    -------
    intrinsics : Intrinsics
        The refined lens (the start itself when no image was rejected or the refit did not
        lower the views' cost).
    results : list of ImageResult
        Every image posed with it.
    """
    early = [k for k, r in enumerate(results) if r.pose is not None and r.reason is not None
             and r.reason.startswith("bad fit")]
    if not early:
        return intrinsics, list(results)
    kept = [k for k, r in enumerate(results) if r.ok]
    fitted = [kept[i] for i in _spread(len(kept), START_VIEWS)] + early[:START_VIEWS]
    views = [(results[k].detection.object_points, results[k].detection.image_points)
             for k in fitted]
    T0 = np.stack([results[k].pose.T_cam_target for k in fitted])
    try:
        fit = fit_lens(views, intrinsics, T0)
    except (InputError, np.linalg.LinAlgError):
        return intrinsics, list(results)
    before = np.array([results[k].pose.rms_px for k in fitted])
    if not np.sum(np.minimum(fit.rms_px, 1e6) ** 2) < np.sum(before ** 2):
        return intrinsics, list(results)
    again = [replace(r, reason=None, pose=None) if k in early else r
             for k, r in enumerate(results)]
    return fit.intrinsics, poses_from_detections(again, fit.intrinsics, max_rms_px=max_rms_px)
