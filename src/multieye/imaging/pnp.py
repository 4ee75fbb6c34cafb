"""Pose of a planar target from one detection (perspective-n-point).

IPPE (``cv2.solvePnPGeneric`` with ``SOLVEPNP_IPPE``) on the undistorted, normalised
points gives the two candidate poses of a planar target; the one with the smaller
reprojection error in pixels is refined by Levenberg-Marquardt on the pixel reprojection
error through the full lens model (``cv2.solvePnPRefineLM`` for pinhole cameras, the same
iteration on ``cv2.fisheye.projectPoints`` for fisheye cameras). Residuals are reported in
pixels of the distorted image.

Synopsis
--------
>>> pose = estimate_pose(detection, intrinsics)                     # doctest: +SKIP
>>> pose.T_cam_target, pose.rms_px, pose.max_px, pose.n_points     # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, undistort_points
from multieye.imaging.detect import Detection

__all__ = ["PoseEstimate", "estimate_pose", "refit_pose", "reprojection_residuals"]

F64 = NDArray[np.float64]


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
    """

    T_cam_target: F64
    rms_px: float
    max_px: float
    n_points: int


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
    tilt can flip; the smaller pixel error decides. A target seen nearly edge-on, or points
    bunched in a small part of the board, give a poorly determined pose with a small RMS;
    check ``n_points`` and the spread of the views.
    """
    obj = np.asarray(detection.object_points, dtype=np.float64)
    img = np.asarray(detection.image_points, dtype=np.float64)
    if len(obj) < 4:
        raise InputError(f"PnP needs at least 4 points, got {len(obj)}")
    if not np.allclose(obj[:, 2], 0.0):
        raise InputError("PnP here is for planar targets: object points must have z = 0")
    xy = undistort_points(img, intrinsics)
    ok = np.all(np.isfinite(xy), axis=1)
    if ok.sum() < 4:
        raise InputError(f"only {int(ok.sum())} of {len(obj)} points lie where the lens model can "
                         "be inverted; PnP needs 4")
    obj, img, xy = obj[ok], img[ok], xy[ok]
    centred = obj[:, :2] - obj[:, :2].mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[1] <= 1e-6 * sv[0]:
        raise InputError(f"the {len(obj)} points lie on one line: the pose is not determined")

    _, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, xy, np.eye(3), None, flags=cv2.SOLVEPNP_IPPE)
    best = None
    for rvec, tvec in zip(rvecs, tvecs):
        T = _transform(rvec, tvec)
        err = reprojection_residuals(T, obj, img, intrinsics)
        cost = float(np.sum(err ** 2))
        if best is None or cost < best[0]:
            best = (cost, rvec.reshape(3).copy(), tvec.reshape(3).copy())
    _, rvec, tvec = best
    rvec, tvec = _refine(obj, img, intrinsics, rvec, tvec)
    if detection.circle_diameter is not None:
        # blob centroids are not the images of the circle centres: model the offset at the
        # current pose and fit again (two rounds reach the noise floor)
        raw = img
        for _ in range(2):
            img = raw - _centroid_offsets(_transform(rvec, tvec), obj, detection.circle_diameter / 2, intrinsics)
            rvec, tvec = _refine(obj, img, intrinsics, rvec, tvec)
    T = _transform(rvec, tvec)
    err = reprojection_residuals(T, obj, img, intrinsics)
    return PoseEstimate(T_cam_target=T, rms_px=float(np.sqrt(np.mean(err ** 2))),
                        max_px=float(err.max()), n_points=len(obj))


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


def _transform(rvec, tvec) -> F64:
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3))[0]
    T[:3, 3] = np.asarray(tvec, dtype=np.float64).reshape(3)
    return T


def _refine(obj: F64, img: F64, intrinsics: Intrinsics, rvec, tvec) -> tuple[F64, F64]:
    """Levenberg-Marquardt on the pixel reprojection error through the lens model."""
    if intrinsics.model == "fisheye":
        return _refine_fisheye(obj, img, intrinsics, rvec, tvec)
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


def _refine_fisheye(obj: F64, img: F64, intrinsics: Intrinsics, rvec: F64, tvec: F64,
                    iterations: int = 50) -> tuple[F64, F64]:
    """Levenberg-Marquardt on the pixel reprojection error of the equidistant model."""
    pts = obj.reshape(-1, 1, 3)

    def residual(r, t):
        proj, jac = cv2.fisheye.projectPoints(pts, r, t, intrinsics.K, intrinsics.dist)
        return (img - proj.reshape(-1, 2)).ravel(), jac[:, 8:14]   # d/d(rvec, tvec)

    x = np.concatenate([rvec, tvec]).astype(np.float64)
    res, J = residual(x[:3], x[3:])
    cost = float(res @ res)
    damping = 1e-3
    for _ in range(iterations):
        H = J.T @ J
        step = np.linalg.solve(H + damping * np.diag(np.diag(H)), J.T @ res)
        candidate = x + step
        new_res, new_J = residual(candidate[:3], candidate[3:])
        new_cost = float(new_res @ new_res)
        if new_cost < cost:
            x, res, J, cost = candidate, new_res, new_J, new_cost
            damping = max(damping / 10, 1e-12)
            if np.linalg.norm(step) < 1e-12 * (1 + np.linalg.norm(x)):
                break
        else:
            damping *= 10
            if damping > 1e8:
                break
    return x[:3], x[3:]
