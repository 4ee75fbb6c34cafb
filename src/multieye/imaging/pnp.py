"""Pose of a planar target from one detection (perspective-n-point).

IPPE (``cv2.solvePnPGeneric`` with ``SOLVEPNP_IPPE``) on the points' viewing rays (turned
into a virtual camera looking along them when they are far off the lens axis:
:func:`multieye.imaging.rays.ippe_on_rays`) gives the two candidate poses of a planar target; the one with the smaller
reprojection error in pixels is refined by Levenberg-Marquardt on the pixel reprojection
error through the full lens model (``cv2.solvePnPRefineLM`` for pinhole cameras, the same
iteration on ``cv2.fisheye.projectPoints`` for fisheye cameras, and on
:func:`multieye.core.lens.project_with_jacobian` for the wide-angle models, whose refinement
uses every point the model places, rays beyond 90 degrees too). Residuals are reported in
pixels of the distorted image.

The other IPPE pose, refined the same way, is kept as :attr:`PoseEstimate.alternative`
when the pixels cannot rule it out: its RMS within :data:`ALTERNATIVE_RATIO` of the first's,
or, for a target of four points (one marker), at most :data:`ALTERNATIVE_PX` above it. The pixels alone then
cannot tell the two apart; the consensus and the closed form choose per image the one the
rig agrees with (:mod:`multieye.estimate.consensus`).

Synopsis
--------
>>> pose = estimate_pose(detection, intrinsics)                     # doctest: +SKIP
>>> pose.T_cam_target, pose.rms_px, pose.max_px, pose.n_points     # doctest: +SKIP
>>> pose.alternative, pose.alternative_rms_px, pose.ambiguous       # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import WIDE_MODELS, Intrinsics
from multieye.core.geometry import rotation_from_rotvec
from multieye.core.lens import project_points, project_with_jacobian
from multieye.imaging.detect import Detection
from multieye.imaging.pnp_refine import refine_fisheye, refine_wide
from multieye.imaging.rays import bearings, ippe_on_rays

__all__ = ["PoseEstimate", "collinear", "estimate_pose", "estimate_poses", "refit_pose", "refit_poses",
           "reprojection_residuals",
           "ambiguity_warning", "ALTERNATIVE_RATIO", "ALTERNATIVE_PX",
           "AMBIGUOUS_RATIO", "AMBIGUOUS_PX"]

F64 = NDArray[np.float64]

#: The second IPPE pose is kept as an alternative when its pixel RMS is at most this many
#: times the first's, or for four points (one marker, two redundant coordinates, so an RMS
#: near zero whatever the noise) at most this many pixels above it.
ALTERNATIVE_RATIO = 3.0
ALTERNATIVE_PX = 1.0
#: The two poses "fit almost equally" (:attr:`PoseEstimate.ambiguous`) when the alternative's
#: pixel RMS is at most this many times the first's, or at most :data:`AMBIGUOUS_PX` above it.
AMBIGUOUS_RATIO = 2.0
AMBIGUOUS_PX = 0.3
#: :func:`refit_poses` stops when no view's step is larger (radians, metres): the iteration
#: converges linearly at a rate of about 1e-2 there, so the pose is then within 1e-12.
_REFIT_STEP = 1e-10
#: :func:`refit_poses` fits at most this many views at once (its arrays are views x points).
_REFIT_VIEWS = 256
#: Poses closer than this (degrees) are one solution, not two.
_DISTINCT_DEG = 0.5


@dataclass(frozen=True)
class PoseEstimate:
    """Pose of the target in one image.

    Attributes
    ----------
    T_cam_target : ndarray, shape (4, 4)
        Target frame in the camera frame (``p_cam = T_cam_target @ p_target``), metres.
    rms_px : float
        Root mean square reprojection error, pixels.
    max_px : float
        Largest reprojection error, pixels.
    n_points : int
        Points used.
    alternative : ndarray, shape (4, 4), or None
        The other IPPE pose (the target's tilt mirrored about the line of sight), refined,
        when the pixels cannot rule it out (module docstring); None otherwise.
    alternative_rms_px : float or None
        Its root mean square reprojection error, pixels.
    """

    T_cam_target: F64
    rms_px: float
    max_px: float
    n_points: int
    alternative: F64 | None = None
    alternative_rms_px: float | None = None

    @property
    def ambiguous(self) -> bool:
        """The two poses fit almost equally (:data:`AMBIGUOUS_RATIO`, :data:`AMBIGUOUS_PX`):
        the image alone does not say which is right."""
        if self.alternative_rms_px is None:
            return False
        return bool(self.alternative_rms_px <= max(AMBIGUOUS_RATIO * self.rms_px,
                                                   self.rms_px + AMBIGUOUS_PX))


def reprojection_residuals(T_cam_target: F64, object_points: F64, image_points: F64,
                           intrinsics: Intrinsics) -> F64:
    """Pixel distance between the projected object points and the image points.

    Parameters
    ----------
    T_cam_target : ndarray, shape (4, 4)
    object_points : ndarray, shape (N, 3)
        Target frame, metres.
    image_points : ndarray, shape (N, 2)
        Pixels.
    intrinsics : Intrinsics

    Returns
    -------
    ndarray, shape (N,)
        Pixels; inf for points behind the camera.
    """
    P = object_points @ T_cam_target[:3, :3].T + T_cam_target[:3, 3]
    d = np.linalg.norm(project_points(P, intrinsics) - image_points, axis=1)
    return np.where(np.isfinite(d), d, np.inf)


def estimate_pose(detection: Detection, intrinsics: Intrinsics) -> PoseEstimate:
    """Pose of a planar target (z = 0 in its frame) from its detected points.

    Parameters
    ----------
    detection : Detection
        At least 4 points, object points on the plane z = 0 and not all on one line.
    intrinsics : Intrinsics

    Returns
    -------
    PoseEstimate

    Raises
    ------
    InputError
        Fewer than 4 points (or fewer than 4 whose pixel the lens model can undistort),
        object points not on z = 0, or all on one line (the pose is then not determined).

    Notes
    -----
    Circle grids with a stated diameter (``detection.circle_diameter``): the blob centroids
    are corrected by the offset between the centroid of each circle's projected outline and
    the projection of its centre, at the estimated pose; residuals are those of the
    corrected points.

    Degenerate and weak cases: with a small or distant target (weak perspective) the two
    IPPE poses mirror each other about the line of sight and fit almost equally well, so the
    tilt can flip; the smaller pixel error decides ``T_cam_target`` and the other is kept as
    ``alternative`` (always for four points) for the rig to decide. A target seen nearly edge-on, or points
    bunched in a small part of the board, give a poorly determined pose with a small RMS;
    check ``n_points`` and the spread of the views.
    """
    obj = np.asarray(detection.object_points, dtype=np.float64)
    img = np.asarray(detection.image_points, dtype=np.float64)
    if len(obj) < 4:
        raise InputError(f"PnP needs at least 4 points, got {len(obj)}")
    if not np.abs(obj[:, 2]).max() <= 1e-8:           # np.allclose(z, 0), 10x faster
        raise InputError("PnP here is for planar targets: object points must have z = 0")
    xy = bearings(img, intrinsics)
    ok = np.isfinite(xy).all(axis=1)
    if not ok.all():
        if ok.sum() < 4:
            raise InputError(f"only {int(ok.sum())} of {len(obj)} points lie where the lens "
                             "model can be inverted; PnP needs 4")
        obj, img, xy = obj[ok], img[ok], xy[ok]
    if collinear(obj[:, :2]):
        raise InputError(f"the {len(obj)} points lie on one line: the pose is not determined")

    candidates = _ippe_candidates(obj, img, xy, intrinsics)
    if not candidates:
        raise InputError(f"the {len(obj)} points' rays span more than a half-space: no "
                         "planar pose")
    _, rvec, tvec = candidates[0]
    rvec, tvec = _refine(obj, img, intrinsics, rvec, tvec)
    if detection.circle_diameter is not None:
        # blob centroids are not the images of the circle centres: model the offset at the
        # current pose and fit again (two rounds reach the noise floor)
        raw = img
        for _ in range(2):
            img = raw - _centroid_offsets(_transform(rvec, tvec), obj, detection.circle_diameter / 2, intrinsics)
            rvec, tvec = _refine(obj, img, intrinsics, rvec, tvec)
    T = _transform(rvec, tvec)
    err = _pixel_errors(obj, img, intrinsics, rvec, tvec)
    rms = float(np.sqrt(np.add.reduce(err ** 2) / len(err)))       # np.mean's arithmetic
    alt, alt_rms = None, None
    if len(candidates) == 2 and _could_be_kept(candidates, len(obj)):
        alt, alt_rms = _alternative(obj, img, intrinsics, candidates[1][1:], T, rms)
    return PoseEstimate(T_cam_target=T, rms_px=rms, max_px=float(err.max()), n_points=len(obj),
                        alternative=alt, alternative_rms_px=alt_rms)


def estimate_poses(detections: Sequence[Detection], intrinsics: Intrinsics
                   ) -> list[PoseEstimate | InputError]:
    """:func:`estimate_pose` of many views with one lens, the common case of them together.

    A view of at least 4 points on z = 0, not on one line, every pixel undistorted, without
    a circle diameter and whose second IPPE pose is far from fitting (no alternative to keep)
    is done as :func:`estimate_pose` does it, but with the undistortion of every view in one
    call and the chosen IPPE pose refined by :func:`refit_poses` (all views in one
    Gauss-Newton, to the minimum ``cv2.solvePnPRefineLM`` stops short of by up to 1e-9); every
    other view by :func:`estimate_pose` itself.

    Returns
    -------
    list
        Per detection its :class:`PoseEstimate`, or the :class:`InputError` that
        :func:`estimate_pose` raises for it.
    """
    views = [(np.asarray(d.object_points, dtype=np.float64),
              np.asarray(d.image_points, dtype=np.float64)) for d in detections]
    batch = [k for k, (obj, _) in enumerate(views) if detections[k].circle_diameter is None
             and len(obj) >= 4 and np.abs(obj[:, 2]).max() <= 1e-8]
    every = bearings(np.concatenate([views[k][1] for k in batch]), intrinsics) \
        if batch else None
    chosen, starts, at = [], [], 0
    for k in batch:
        obj, img = views[k]
        xy_k, at = every[at:at + len(img)], at + len(img)
        if not np.isfinite(xy_k).all() or collinear(obj[:, :2]):
            continue                                # alone: fewer points, or its error
        candidates = _ippe_candidates(obj, img, xy_k, intrinsics)
        if not candidates or len(candidates) == 2 and _could_be_kept(candidates, len(obj)):
            continue                                # alone: it may keep the alternative
        chosen.append(k)
        starts.append(_transform(*candidates[0][1:]))
    out: list = [None] * len(detections)
    if chosen:
        fitted = refit_poses(np.stack(starts), [views[k][0] for k in chosen],
                             [views[k][1] for k in chosen], intrinsics)
        for k, pose in zip(chosen, fitted):
            out[k] = pose
    for k, det in enumerate(detections):
        if out[k] is None:
            try:
                out[k] = estimate_pose(det, intrinsics)
            except InputError as exc:
                out[k] = exc
    return out


def _ippe_candidates(obj: F64, img: F64, rays: F64, intrinsics: Intrinsics) -> list:
    """IPPE's poses of planar points ``obj`` (z = 0) from their unit viewing ``rays``
    (:func:`multieye.imaging.rays.ippe_on_rays`), as ``(sum of squared pixel errors against
    img, rvec, tvec)``, the better fit first (empty when IPPE has none)."""
    candidates = []
    for rvec, tvec in ippe_on_rays(obj, rays):
        err = _pixel_errors(obj, img, intrinsics, rvec, tvec)
        candidates.append((float(np.sum(err ** 2)), rvec, tvec))
    return sorted(candidates, key=lambda c: c[0])


def collinear(xy: F64) -> bool:
    """Whether planar points lie on one line: the smaller singular value of the centred
    points at most 1e-6 of the larger (from the 2 x 2 scatter matrix, in closed form)."""
    c = xy - np.add.reduce(xy, axis=0) / len(xy)                     # centred
    a, b, d = float(c[:, 0] @ c[:, 0]), float(c[:, 0] @ c[:, 1]), float(c[:, 1] @ c[:, 1])
    mean, spread = (a + d) / 2, float(np.hypot((a - d) / 2, b))
    return bool(mean - spread <= 1e-12 * (mean + spread))


def _pixel_errors(obj: F64, img: F64, intrinsics: Intrinsics, rvec: F64, tvec: F64) -> F64:
    """:func:`reprojection_residuals` at the pose ``(rvec, tvec)``, without its checks of the
    input: pixel distance per point, inf for points not in front of the camera."""
    rvec = np.ascontiguousarray(rvec, dtype=np.float64).reshape(3, 1)
    tvec = np.ascontiguousarray(tvec, dtype=np.float64).reshape(3, 1)
    if intrinsics.model in WIDE_MODELS:             # NaN outside the model's region
        d = project_points(obj @ cv2.Rodrigues(rvec)[0].T + tvec[:, 0], intrinsics) - img
        err = np.sqrt(np.einsum("ij,ij->i", d, d))
        return np.where(np.isfinite(err), err, np.inf)
    z = obj @ cv2.Rodrigues(rvec)[0][2] + tvec[2, 0]
    pts = obj.reshape(-1, 1, 3)
    if intrinsics.model == "fisheye":
        uv, _ = cv2.fisheye.projectPoints(pts, rvec, tvec, intrinsics.K, intrinsics.dist)
    else:
        uv, _ = cv2.projectPoints(pts, rvec, tvec, intrinsics.K, intrinsics.dist)
    d = uv.reshape(-1, 2) - img
    err = np.sqrt(np.einsum("ij,ij->i", d, d))
    return np.where((z > 0) & np.isfinite(err), err, np.inf)


def _limit_px(rms: float, n_points: int) -> float:
    """Largest pixel RMS of a second pose kept beside a first of ``rms`` (module docstring)."""
    return max(ALTERNATIVE_RATIO * rms, rms + ALTERNATIVE_PX if n_points == 4 else 0.0)


def _could_be_kept(candidates, n_points: int) -> bool:
    """The unrefined second IPPE pose is near enough to the first's pixel RMS that, refined,
    it might be kept (twice the limit, and a pixel: refinement moves both a little)."""
    rms1, rms2 = (np.sqrt(c[0] / n_points) for c in candidates)
    return bool(rms2 <= 2 * _limit_px(rms1, n_points) + 1.0)


def _alternative(obj: F64, img: F64, intrinsics: Intrinsics, start, T: F64, rms: float):
    """The other IPPE pose refined, and its pixel RMS, if the pixels cannot rule it out."""
    rvec, tvec = _refine(obj, img, intrinsics, *start)
    T2 = _transform(rvec, tvec)
    cos = (np.trace(T[:3, :3].T @ T2[:3, :3]) - 1.0) / 2.0
    if np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))) < _DISTINCT_DEG or T2[2, 3] <= 0:
        return None, None                       # the refinement fell into the first pose
    err2 = _pixel_errors(obj, img, intrinsics, rvec, tvec) ** 2
    rms2 = float(np.sqrt(np.add.reduce(err2) / len(err2)))
    if not rms2 <= _limit_px(rms, len(obj)):
        return None, None
    return T2, rms2


def ambiguity_warning(camera: str, poses) -> str | None:
    """A warning when the two poses fit almost equally in most of a camera's images.

    Parameters
    ----------
    camera : str
    poses : sequence of PoseEstimate
        The camera's usable poses.

    Returns
    -------
    str or None
        None when at most half of the poses are :attr:`PoseEstimate.ambiguous`.
    """
    poses = list(poses)
    n = sum(p.ambiguous for p in poses)
    if not poses or 2 * n <= len(poses):
        return None
    return (f"{camera}: in {n} of {len(poses)} images the target's two mirrored poses fit "
            "almost equally (the target is small in the image, so its perspective says little); "
            "the motion decides between them, image by image. Use a bigger marker, bring it "
            "closer to the camera, or use a marker grid or a board")


def refit_pose(T_cam_target: F64, object_points: F64, image_points: F64,
               intrinsics: Intrinsics) -> PoseEstimate:
    """The pose of a target refitted from a nearby one, e.g. after the intrinsics changed.

    Levenberg-Marquardt on the pixel reprojection error through ``intrinsics``, started at
    ``T_cam_target`` (no IPPE, no choice between mirrored poses: the start decides).

    Parameters
    ----------
    T_cam_target : ndarray, shape (4, 4)
        Starting pose, metres.
    object_points : ndarray, shape (n, 3)
        Target frame, metres.
    image_points : ndarray, shape (n, 2)
        Pixels, as the image-level refinement sees them.
    intrinsics : Intrinsics
    """
    obj = np.asarray(object_points, dtype=np.float64)
    img = np.asarray(image_points, dtype=np.float64)
    T0 = np.asarray(T_cam_target, dtype=np.float64)
    if len(obj) < 4:
        raise InputError(f"PnP needs at least 4 points, got {len(obj)}")
    rvec = cv2.Rodrigues(T0[:3, :3])[0].reshape(3)
    rvec, tvec = _refine(obj, img, intrinsics, rvec, T0[:3, 3].copy())
    T = _transform(rvec, tvec)
    err = reprojection_residuals(T, obj, img, intrinsics)
    return PoseEstimate(T_cam_target=T, rms_px=float(np.sqrt(np.mean(err ** 2))),
                        max_px=float(err.max()), n_points=len(obj))


def refit_poses(T_cam_target: F64, object_points, image_points, intrinsics: Intrinsics, *,
                iterations: int = 30) -> list[PoseEstimate]:
    """:func:`refit_pose` of many views at once: Gauss-Newton on all of them together.

    Each view's pose is updated on the left, ``T <- [exp(w) | v] T``, from its 6 x 6 normal
    equations, all views in one numpy pass per iteration (the lens' projection and Jacobian,
    :func:`multieye.core.lens.project_with_jacobian`; the views padded to one number of
    points, :data:`_REFIT_VIEWS` at a time), until no step is above :data:`_REFIT_STEP` or after ``iterations``; a view
    whose fit does not end finite and converged is refitted alone by :func:`refit_pose`.
    From poses near the optimum (the same views with a slightly different lens) four
    iterations reach the minimum ``cv2.solvePnPRefineLM`` finds (to 2e-9 in the poses' terms
    and 1e-13 px in the RMS on ``benchmarks/.cache/peers_4x100_model``, where the RMS is
    flat to rounding), in a fraction of its time.

    Parameters
    ----------
    T_cam_target : ndarray, shape (n, 4, 4)
        Starting poses, metres.
    object_points : sequence of n ndarrays, shape (k_i, 3)
        Target frame, metres; at least 4 points each.
    image_points : sequence of n ndarrays, shape (k_i, 2)
        Pixels.
    intrinsics : Intrinsics
    iterations : int
        Gauss-Newton steps at most.

    Returns
    -------
    list of PoseEstimate
        One per view, in order.
    """
    T0 = np.asarray(T_cam_target, dtype=np.float64).reshape(-1, 4, 4)
    counts = np.array([len(o) for o in object_points], dtype=np.int64)
    if len(counts) != len(T0) or len(image_points) != len(T0):
        raise InputError(f"{len(T0)} poses, {len(counts)} sets of object points and "
                         f"{len(image_points)} of image points: one of each per view")
    if not len(T0):
        return []
    if counts.min() < 4:
        raise InputError(f"PnP needs at least 4 points, got {int(counts.min())}")
    if len(T0) > _REFIT_VIEWS:                 # bounded memory: the views in parts
        return [pose for a in range(0, len(T0), _REFIT_VIEWS)
                for pose in refit_poses(T0[a:a + _REFIT_VIEWS],
                                        object_points[a:a + _REFIT_VIEWS],
                                        image_points[a:a + _REFIT_VIEWS], intrinsics,
                                        iterations=iterations)]
    n, k = len(T0), int(counts.max())
    # every view padded to k points (copies of its first point, weighed 0): one batch
    pad = np.minimum(np.arange(k), counts[:, None] - 1)                    # (n, k)
    used = (np.arange(k) < counts[:, None]).astype(np.float64)
    obj = np.stack([np.asarray(o, dtype=np.float64)[pad[i]] for i, o in enumerate(object_points)])
    img = np.stack([np.asarray(u, dtype=np.float64)[pad[i]] for i, u in enumerate(image_points)])
    R, t = T0[:, :3, :3].copy(), T0[:, :3, 3].copy()
    converged, failed = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    for _ in range(iterations):
        act = np.flatnonzero(~(converged | failed))       # the views still moving
        if not act.size:
            break
        step = _gauss_newton_step(obj[act], img[act], used[act], R[act], t[act], intrinsics)
        bad = ~np.isfinite(step).all(axis=1)
        failed[act[bad]] = True
        step[bad] = 0.0
        dR = rotation_from_rotvec(step[:, :3])
        R[act], t[act] = dR @ R[act], (dR @ t[act][:, :, None])[..., 0] + step[:, 3:]
        converged[act] = (np.abs(step).max(axis=1) <= _REFIT_STEP) & ~bad
    P = (obj @ R.transpose(0, 2, 1) + t[:, None, :]).reshape(-1, 3)
    err = np.linalg.norm(project_points(P, intrinsics) - img.reshape(-1, 2), axis=1)
    err = np.where(np.isfinite(err), err, np.inf).reshape(n, k) * used   # NaN: not projected
    rms = np.sqrt((err ** 2).sum(axis=1) / counts)
    worst = err.max(axis=1)
    out = []
    for i in range(n):
        if not (converged[i] and np.isfinite(rms[i])):
            out.append(refit_pose(T0[i], object_points[i], image_points[i], intrinsics))
            continue
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R[i], t[i]
        out.append(PoseEstimate(T_cam_target=T, rms_px=float(rms[i]), max_px=float(worst[i]),
                                n_points=int(counts[i])))
    return out


def _gauss_newton_step(obj: F64, img: F64, used: F64, R: F64, t: F64,
                       intrinsics: Intrinsics) -> F64:
    """Gauss-Newton steps ``(w, v)`` of :func:`refit_poses`, shape (n, 6): views of k points
    (``obj`` (n, k, 3), ``img`` (n, k, 2), weights ``used`` (n, k)) at poses ``R``, ``t``;
    NaN rows where a point does not project."""
    n, k = used.shape
    P = (obj @ R.transpose(0, 2, 1) + t[:, None, :]).reshape(-1, 3)
    uv, J_point, _ = project_with_jacobian(P, intrinsics, lens_jacobian=False)
    # d uv / d (w, v) of p -> p + w x p + v: (J_point (p x .), J_point), rows weighed
    J = np.concatenate([np.cross(P[:, None, :], J_point), J_point], axis=2)
    J = (J.reshape(n, k, 2, 6) * used[:, :, None, None]).reshape(n, 2 * k, 6)
    r = (img - uv.reshape(n, k, 2)).reshape(n, 2 * k, 1)
    Jt = J.transpose(0, 2, 1)
    with np.errstate(invalid="ignore"):
        try:
            return np.linalg.solve(Jt @ J, Jt @ r)[..., 0]
        except np.linalg.LinAlgError:       # one singular view: each alone, to say which
            return np.stack([_solve6(a, b) for a, b in zip(Jt @ J, Jt @ r)])


def _solve6(H: F64, b: F64) -> F64:
    try:
        return np.linalg.solve(H, b)[:, 0]
    except np.linalg.LinAlgError:
        return np.full(6, np.nan)


def _transform(rvec, tvec) -> F64:
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3))[0]
    T[:3, 3] = np.asarray(tvec, dtype=np.float64).reshape(3)
    return T


def _refine(obj: F64, img: F64, intrinsics: Intrinsics, rvec, tvec) -> tuple[F64, F64]:
    """Levenberg-Marquardt on the pixel reprojection error through the lens model."""
    if intrinsics.model == "fisheye":
        return refine_fisheye(obj, img, intrinsics, rvec, tvec)
    if intrinsics.model in WIDE_MODELS:
        return refine_wide(obj, img, intrinsics, rvec, tvec)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-12)
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, intrinsics.K, intrinsics.dist,
                                      np.asarray(rvec, dtype=np.float64).reshape(3, 1),
                                      np.asarray(tvec, dtype=np.float64).reshape(3, 1), criteria=criteria)
    return rvec.reshape(3), tvec.reshape(3)


def _centroid_offsets(T_cam_target: F64, centres: F64, radius: float, intrinsics: Intrinsics,
                      n: int = 48) -> F64:
    """Centroid of each circle's projected outline minus the projection of its centre, pixels.

    Parameters
    ----------
    T_cam_target : ndarray, shape (4, 4)
    centres : ndarray, shape (N, 3)
        Circle centres, target frame (z = 0), metres.
    radius : float
        Metres.
    intrinsics : Intrinsics
    n : int
        Outline samples per circle (the polygon's area centroid).

    Returns
    -------
    ndarray, shape (N, 2)
        Zero for circles whose outline does not project (behind the camera).
    """
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.column_stack([radius * np.cos(a), radius * np.sin(a), np.zeros(n)])
    pts = (centres[:, None, :] + ring[None, :, :]).reshape(-1, 3)
    R, t = T_cam_target[:3, :3], T_cam_target[:3, 3]
    outline = project_points(pts @ R.T + t, intrinsics).reshape(len(centres), n, 2)
    centre_px = project_points(centres @ R.T + t, intrinsics)
    x, y = outline[..., 0], outline[..., 1]
    x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * y1 - x1 * y
    area = cross.sum(axis=1) / 2
    with np.errstate(divide="ignore", invalid="ignore"):
        centroid = np.column_stack([((x + x1) * cross).sum(axis=1), ((y + y1) * cross).sum(axis=1)]) / (6 * area[:, None])
    offset = centroid - centre_px
    return np.where(np.isfinite(offset), offset, 0.0)
