"""The lens freed: the plausibility's hypothesis that the given intrinsics do not belong to
the images (:mod:`multieye.estimate.plausibility` decides what it means), the lens fitted to
the camera's own detections (:func:`lens_search`) and compared with the given one, in pixels
and in the loop residuals of the hand-eye fit (:mod:`multieye.estimate.hypotheses`).

A lens given without distortion
-------------------------------
An intrinsics file that states a camera matrix and no distortion (or zeros) is a common
mistake: the coefficients were left out, or read under another key.  Freeing every parameter
of the lens needs many views (OpenCV's calibration from a handful of views trades the focal
length against the distortion); the camera matrix given is usually right, so here only the
radial coefficients k1 and k2 are freed, with the pose of every view, by least squares on the
pixels::

    min over k1, k2, T_1..T_n of  sum_i sum_p || project(T_i P_p; K, k1, k2) - u_ip ||^2

which a few views of a board determine (the coefficients move the pixels by ``r^2`` and
``r^4`` of the normalised radius ``r``, which every view of a board spans).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, project_with_jacobian, unproject_points
from multieye.estimate import hypotheses as h
from multieye.optimize.blocks import Blocks, ResidualGroup

__all__ = ["MIN_DISTORTION_VIEWS", "MIN_LENS_VIEWS", "LensTest", "lacks_distortion",
           "lens_bend", "distortion_part", "distortion_missing",
           "free_distortion", "lens_bound", "lens_search"]

F64 = NDArray[np.float64]

#: Fewest views the distortion is freed on (the camera matrix kept).
MIN_DISTORTION_VIEWS = 3
#: Fewest views, and fewest target points per view (median), every parameter of a camera's
#: lens is freed on.
MIN_LENS_VIEWS = 5
_MIN_LENS_POINTS = 8
#: Most views the lens is fitted on (evenly spaced over the recording; PnP runs on all).
_MAX_LENS_VIEWS = 50
#: Most views k1 and k2 are refitted and compared on (evenly spaced; 0.02-0.05 CPU-s a
#: camera instead of 0.1 for 40 views: it runs on every camera with a given lens).
_MAX_RADIAL_VIEWS = 16
#: Models whose first two coefficients are the radial k1 and k2 (OpenCV's pinhole and
#: fisheye).
_RADIAL_FIRST = {"pinhole": 5, "fisheye": 4}


def lacks_distortion(intr: Intrinsics) -> bool:
    """Whether ``intr`` is a pinhole or fisheye lens given without distortion (none, or
    every coefficient zero)."""
    return intr.model in _RADIAL_FIRST and not np.any(intr.dist)


def distortion_part(intr: Intrinsics) -> F64 | None:
    """The coefficients of ``intr`` that an intrinsics file states as its distortion: all of
    a pinhole's or fisheye's, a unified lens's radial-tangential ones after xi; None for the
    double-sphere and eucm lenses, whose two parameters are their projection."""
    if intr.model in _RADIAL_FIRST:
        return np.asarray(intr.dist, dtype=np.float64)
    if intr.model == "unified":
        return np.asarray(intr.dist[1:], dtype=np.float64)
    return None


def distortion_missing(intr: Intrinsics) -> bool:
    """Whether ``intr`` states no distortion (its :func:`distortion_part` none or zeros)."""
    part = distortion_part(intr)
    return part is not None and not np.any(part)


def _without_distortion(intr: Intrinsics) -> Intrinsics:
    """``intr`` with its :func:`distortion_part` zero (a pinhole: its camera matrix alone; a
    fisheye: the equidistant projection; a unified lens: its xi alone)."""
    dist = np.zeros_like(np.asarray(intr.dist, dtype=np.float64))
    if intr.model == "unified":
        dist[0] = intr.dist[0]
    return Intrinsics(K=intr.K, dist=dist, model=intr.model, width=intr.width,
                      height=intr.height)


def lens_bend(pixels: F64, intr: Intrinsics) -> float:
    """How far the distortion of ``intr`` bends the rays of ``pixels``: the angle between
    each pixel's ray under ``intr`` and under the same lens without its distortion
    (:func:`distortion_part` zero), in pixels at the focal length, at its 90th percentile
    over the pixels (the outer target points, where a distortion shows; 0 for a lens
    without distortion; NaN when no pixel unprojects, or for the double-sphere and eucm
    lenses, which have no distortion apart from their projection).

    Parameters
    ----------
    pixels : ndarray, shape (N, 2)
        Observed pixels.
    intr : Intrinsics
    """
    if distortion_part(intr) is None:
        return math.nan
    uv = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    with np.errstate(all="ignore"):
        rays = unproject_points(uv, intr)
        plain = unproject_points(uv, _without_distortion(intr))
        angle = np.arccos(np.clip(np.sum(rays * plain, axis=1), -1.0, 1.0))
    angle = angle[np.isfinite(angle)]
    return float(np.percentile(angle, 90) * intr.K[0, 0]) if angle.size else math.nan


#: Where each model's first two radial coefficients are in ``Intrinsics.dist`` (the unified
#: model's after xi); double-sphere and eucm have none and free their own two parameters.
_RADIAL_AT = {"pinhole": 0, "fisheye": 0, "unified": 1, "double-sphere": 0, "eucm": 0}


def _with_radial(intr: Intrinsics, k: F64) -> Intrinsics:
    """``intr`` with its two radial coefficients (:data:`_RADIAL_AT`) set to ``k``; a lens
    without distortion gets OpenCV's 5 (pinhole) or 4 (fisheye) coefficients."""
    if lacks_distortion(intr):
        dist = np.zeros(_RADIAL_FIRST[intr.model])
    else:
        dist = np.array(intr.dist, dtype=np.float64)
    at = _RADIAL_AT[intr.model]
    dist[at:at + 2] = k
    return Intrinsics(K=intr.K, dist=dist, model=intr.model, width=intr.width,
                      height=intr.height)


def _radial(intr: Intrinsics) -> F64:
    """The two coefficients :func:`_with_radial` sets, as ``intr`` gives them."""
    if lacks_distortion(intr):
        return np.zeros(2)
    at = _RADIAL_AT[intr.model]
    return np.array(intr.dist[at:at + 2], dtype=np.float64)


def free_distortion(views: Sequence[tuple[F64, F64]], T_cam_target: F64,
                    intr: Intrinsics) -> Intrinsics | None:
    """``intr`` with k1 and k2 fitted to the views (module docstring); the other coefficients
    as given (a lens given with distortion: its two radial coefficients refitted, the
    double-sphere and eucm lenses their two parameters).

    Parameters
    ----------
    views : sequence of (object_points, image_points)
        Per view: the target points (n, 3), metres, in the target frame, and their pixels
        (n, 2).
    T_cam_target : ndarray, shape (len(views), 4, 4)
        Starting pose of each view (PnP with ``intr``).
    intr : Intrinsics
        The given lens; its camera matrix is kept.

    Returns
    -------
    Intrinsics or None
        The camera matrix of ``intr`` with the fitted k1, k2 (the other coefficients as
        given, zero for a lens given without); None with fewer than
        :data:`MIN_DISTORTION_VIEWS` views or when the fit fails.
    """
    fitted = _free_distortion_with_poses(views, T_cam_target, intr)
    return None if fitted is None else fitted[0]


def _free_distortion_with_poses(views: Sequence[tuple[F64, F64]], T_cam_target: F64,
                                intr: Intrinsics) -> tuple[Intrinsics, F64, F64] | None:
    """:func:`free_distortion`, with the fit's own pose of each view T_cam_target (n, 4, 4)
    and each view's reprojection RMS with the fitted lens (n,), pixels: what PnP with the
    fitted lens gives (at the fit's optimum each pose is its view's best with that lens)."""
    n = len(views)
    if n < MIN_DISTORTION_VIEWS or (intr.dist.size < 2 and not lacks_distortion(intr)):
        return None
    obj = [np.asarray(o, dtype=np.float64) for o, _ in views]
    img = np.concatenate([np.asarray(u, dtype=np.float64) for _, u in views])
    which = np.repeat(np.arange(n), [len(o) for o in obj])
    T = np.asarray(T_cam_target, dtype=np.float64)
    try:
        with np.errstate(all="ignore"):
            k, T_fit, r = _radial_fit(np.concatenate(obj), img, which, T, intr)
    except (np.linalg.LinAlgError, InputError):
        return None
    if not (np.all(np.isfinite(k)) and np.all(np.isfinite(T_fit))):
        return None
    sq = np.bincount(which, weights=np.sum(r ** 2, axis=1), minlength=n)
    rms = np.sqrt(sq / np.bincount(which, minlength=n))
    return _with_radial(intr, k), T_fit, rms


def _skew(v: F64) -> F64:
    """(N, 3) -> (N, 3, 3) cross-product matrices."""
    z = np.zeros(len(v))
    return np.stack([np.stack([z, -v[:, 2], v[:, 1]], -1), np.stack([v[:, 2], z, -v[:, 0]], -1),
                     np.stack([-v[:, 1], v[:, 0], z], -1)], axis=1)


#: Residual of a pixel coordinate whose point the lens cannot project (behind the camera,
#: outside the model's valid region), pixels; its Jacobian is zero.
_UNPROJECTED_PX = 1e3


class _RadialPixels(ResidualGroup):
    """The pixels of every view against the lens with radial coefficients ``k`` (family
    "k", euclidean, one block of 2) and the view's pose T_cam_target (family "T",
    se3-left, eliminated): rows are target points, segments views, residuals in pixels."""

    def __init__(self, P: F64, img: F64, which: NDArray[np.intp], n: int, intr: Intrinsics):
        super().__init__(("k", "T"), np.column_stack([np.zeros(n, dtype=int), np.arange(n)]),
                         which, 2)
        self.P, self.img, self.which, self.intr = P, img, which, intr
        self.at = 4 + _RADIAL_AT[intr.model]

    def evaluate(self, values, jacobians):
        T = values["T"]
        RP = np.einsum("nij,nj->ni", T[:, :3, :3][self.which], self.P)
        X = RP + T[:, :3, 3][self.which]
        lens = _with_radial(self.intr, values["k"][0])
        if not jacobians:
            r = project_points(X, lens) - self.img
            return np.where(np.isfinite(r), r, _UNPROJECTED_PX), None
        uv, Jp, Ji = project_with_jacobian(X, lens)
        r = uv - self.img
        ok = np.all(np.isfinite(r), axis=1) & np.all(np.isfinite(Jp), axis=(1, 2))
        J_pose = np.concatenate([-Jp @ _skew(RP), Jp], axis=2)
        J_k = Ji[:, :, self.at:self.at + 2]
        J_pose[~ok] = 0.0
        J_k = np.where(ok[:, None, None], J_k, 0.0)
        return np.where(np.isfinite(r), r, _UNPROJECTED_PX), [J_k, J_pose]


def _radial_fit(P: F64, img: F64, which: NDArray[np.intp], T: F64, intr: Intrinsics,
                iterations: int = 30) -> tuple[F64, F64, F64]:
    """k1 and k2 with every view's pose, least squares on the pixels by the shared
    Levenberg-Marquardt (:func:`multieye.optimize.levenberg_marquardt.minimize`; the poses
    eliminated by their Schur complement).  ``P`` (N, 3) target points, ``img`` (N, 2)
    pixels, ``which`` (N,) each point's view (non-decreasing), ``T`` (n, 4, 4) starting
    T_cam_target.  A point the lens cannot project counts :data:`_UNPROJECTED_PX` per
    coordinate.  Returns k (2,), the poses T_cam_target (n, 4, 4) and the pixel residuals
    (N, 2) at the optimum."""
    from multieye.optimize.levenberg_marquardt import Options, minimize  # noqa: PLC0415 (only when a lens is refitted)

    group = _RadialPixels(P, img, which, len(T), intr)
    fams = [Blocks("k", _radial(intr)[None], "euclidean"),
            Blocks("T", T, "se3-left", eliminate=True)]
    res = minimize(fams, [group], Options(max_iter=iterations, tol=1e-10,
                                          initial_damping=1e-3))
    return res.value("k")[0], res.value("T"), res.residuals[0][0]


# --------------------------------------------------------------------------- the test


@dataclass(frozen=True)
class LensTest:
    """The given lens against one fitted to the camera's own detections.

    Attributes
    ----------
    intrinsics : Intrinsics
        The lens fitted to the detections (OpenCV's calibration, the given model).
    rms_given_px, rms_freed_px : float
        Median over the views of the PnP reprojection RMS with each lens, pixels.
    cost_given, cost_freed : float
        The camera's loop cost with the target poses of each lens, both weighted with the
        pixel noise the fitted lens leaves (the given lens's own residuals would inflate it).
    loop_given, loop_freed : (float, float)
        The camera's mean loop residual with the target poses of each lens: rotation
        (degrees) and translation (metres).
    """

    intrinsics: Intrinsics
    rms_given_px: float
    rms_freed_px: float
    cost_given: float
    cost_freed: float
    loop_given: tuple[float, float] = (math.nan, math.nan)
    loop_freed: tuple[float, float] = (math.nan, math.nan)


def _lens_model(intr: Intrinsics) -> str:
    """The model name of :data:`multieye.core.intrinsics.LENS_MODELS` to free ``intr`` in
    (no distortion given: OpenCV's five coefficients)."""
    if intr.model != "pinhole":
        return intr.model                       # fisheye and the wide-angle models
    return {4: "pinhole-radtan4"}.get(intr.dist.size,
                                      "pinhole-rational" if intr.dist.size >= 8
                                      else "pinhole-radtan")


def _pnp_with_rms(cam: h.CameraEvidence, intr: Intrinsics, views=None):
    """PnP with ``intr`` on every view of ``cam`` (or on the views of index ``views``): the
    poses T_cam_target (n, 4, 4) and each view's RMS (n,), pixels; None when PnP fails."""
    from multieye.imaging.detect import Detection  # noqa: PLC0415 (heavy: OpenCV, only when the lens is doubted)
    from multieye.imaging.pnp import estimate_pose  # noqa: PLC0415 (heavy: OpenCV, only when the lens is doubted)

    pick = range(len(cam.image_points)) if views is None else views
    poses, rms = [], []
    for obj, img in ((cam.object_points[i], cam.image_points[i]) for i in pick):
        det = Detection(ids=np.arange(len(obj)), image_points=np.asarray(img, dtype=np.float64),
                        object_points=np.asarray(obj, dtype=np.float64))
        try:
            est = estimate_pose(det, intr)
        except Exception:   # noqa: BLE001 - PnP failing under a wrong hypothesis is an answer
            return None
        poses.append(est.T_cam_target)
        rms.append(est.rms_px)
    return np.stack(poses), np.asarray(rms, dtype=np.float64)


def lens_bound(cam: h.CameraEvidence, mocap_sigma: tuple[float, float]
               ) -> tuple[float, float] | None:
    """What a freed lens could at most show, without freeing it (:func:`lens_search` costs
    0.2-1 s a camera): the median over the views of the given lens's reprojection RMS, and
    the camera's loop cost with its target poses weighted as if the pixel noise were at its
    floor (0.05 px, the least the PnP noise is predicted from).

    A freed lens fits the pixels at best to the noise, so the given lens's RMS bounds the
    systematic part it could reveal; and :func:`lens_search` weighs the given lens's poses
    with the pixel noise the freed lens leaves, at least that floor, so the cost here bounds
    the loop cost it reports for them.  None without points or reprojection RMS.
    """
    if not cam.has_points or cam.rms_px is None:
        return None
    floor = h.noise(cam, mocap_sigma, rms_px=np.full(len(cam.A), h.MIN_RMS_PX))
    return float(np.median(cam.rms_px)), h.fit([cam.A], [cam.B], [floor]).cost


def _loop_residual(cam: h.CameraEvidence, T_cam_target: F64) -> tuple[float, float]:
    """Mean loop residual of the camera alone with these target poses: degrees, metres."""
    f = h.fit([cam.A], [g.inv(T_cam_target)], [np.tile(np.eye(6), (len(cam.A), 1, 1))])
    with np.errstate(all="ignore"):
        r = h.loop_residuals(cam.A, g.inv(T_cam_target), f.X[0], f.Y)
    return (float(np.degrees(np.mean(np.linalg.norm(r[:, :3], axis=1)))),
            float(np.mean(np.linalg.norm(r[:, 3:], axis=1))))


def lens_search(cam: h.CameraEvidence, mocap_sigma: tuple[float, float], *,
                radial_only: bool = False) -> LensTest | None:
    """Free the lens: fit the camera's intrinsics to its own detections and compare the
    reprojection and loop residuals with those of the given lens.  A lens given without
    distortion, or any lens with ``radial_only``, keeps its camera matrix and gets its k1 and
    k2 refitted (:func:`multieye.estimate.lens_freed.free_distortion`, from 3 views); any
    other, every parameter of its model (:func:`multieye.imaging.calibrate.
    initial_intrinsics`, from :data:`MIN_LENS_VIEWS`).  None with too few views, fewer than 8
    points per view (one marker's 4 corners do not determine a lens), or when the fit
    fails."""
    if not cam.has_points:
        return None
    if np.median([len(p) for p in cam.image_points]) < _MIN_LENS_POINTS:
        return None
    intr = cam.intrinsics
    if radial_only or distortion_missing(intr):
        cam = _fewer_views(cam, _MAX_RADIAL_VIEWS)
        # the given lens's poses and RMS are the measurements' own (B = inv(PnP) with it)
        given = (_pnp_with_rms(cam, intr) if cam.rms_px is None
                 else (g.inv(cam.B), np.asarray(cam.rms_px, dtype=np.float64)))
        refit = None if given is None else _free_distortion_with_poses(
            list(zip(cam.object_points, cam.image_points)), given[0], intr)
        # the refit's own poses and RMS are PnP's with the refitted lens (no second PnP)
        return None if refit is None else _lens_test(cam, mocap_sigma, given, refit[0],
                                                     _unstuck(cam, *refit))
    if len(cam.A) < MIN_LENS_VIEWS:
        return None
    return _lens_test(cam, mocap_sigma, None, _all_parameters(cam, intr))


#: A view whose RMS after the radial refit exceeds this many times the median view's is
#: taken again by PnP with the refitted lens: a pose that PnP took wrongly under the given
#: lens (the mirror pose of a flat board: 64 degrees off in one of 12 views of a rendered
#: 140-degree fisheye given without its k1 -0.2, 4 px against 0.2-0.4) stays in its minimum
#: through the refit.
_STUCK_VIEW_RMS = 2.0


def _unstuck(cam: h.CameraEvidence, freed: Intrinsics, T: F64, rms: F64) -> tuple[F64, F64]:
    """The refit's poses T_cam_target (n, 4, 4) and view RMS (n,) with those of the views
    above :data:`_STUCK_VIEW_RMS` times the median replaced by PnP's with ``freed`` where
    that fits them better."""
    stuck = np.flatnonzero(rms > _STUCK_VIEW_RMS * np.median(rms))
    again = _pnp_with_rms(cam, freed, stuck) if stuck.size else None
    if again is None:
        return T, rms
    better = again[1] < rms[stuck]
    T, rms = T.copy(), rms.copy()
    T[stuck[better]], rms[stuck[better]] = again[0][better], again[1][better]
    return T, rms


def _fewer_views(cam: h.CameraEvidence, most: int) -> h.CameraEvidence:
    """``cam`` with at most ``most`` of its views, evenly spaced over the recording."""
    n = len(cam.A)
    if n <= most:
        return cam
    pick = np.unique(np.linspace(0, n - 1, most).round().astype(int))

    def cut(v):
        return v if v is None else tuple(v[i] for i in pick)

    return replace(cam, A=cam.A[pick], B=cam.B[pick], T_world_mocap=cam.T_world_mocap[pick],
                   object_points=cut(cam.object_points), image_points=cut(cam.image_points),
                   rms_px=None if cam.rms_px is None else cam.rms_px[pick],
                   stamps=None if cam.stamps is None else cam.stamps[pick])


def _all_parameters(cam: h.CameraEvidence, intr: Intrinsics) -> Intrinsics | None:
    """Every parameter of ``intr``'s model fitted to (up to 50 of) the camera's views."""
    from multieye.imaging.calibrate import initial_intrinsics  # noqa: PLC0415 (heavy: OpenCV, only when the lens is doubted)

    size = ((intr.width, intr.height) if intr.width is not None and intr.height is not None
            else (int(round(2 * intr.K[0, 2] + 1)), int(round(2 * intr.K[1, 2] + 1))))
    pick = np.unique(np.linspace(0, len(cam.A) - 1, min(len(cam.A), _MAX_LENS_VIEWS)
                                 ).round().astype(int))
    views = [(cam.object_points[i], cam.image_points[i]) for i in pick]
    try:
        with np.errstate(all="ignore"):
            return initial_intrinsics(views, size, _lens_model(intr), name=cam.name).intrinsics
    except InputError:
        return None


def _lens_test(cam: h.CameraEvidence, mocap_sigma: tuple[float, float], given,
               freed: Intrinsics | None, fitted=None) -> LensTest | None:
    """The given lens (its PnP poses and RMS ``given``, None: computed here) against
    ``freed`` (its poses and RMS ``fitted``, None: PnP here)."""
    if freed is None:
        return None
    given = _pnp_with_rms(cam, cam.intrinsics) if given is None else given
    fitted = _pnp_with_rms(cam, freed) if fitted is None else fitted
    if given is None or fitted is None:
        return None
    # both lenses' poses weighted with the pixel noise the fitted lens leaves
    w = h.noise(cam, mocap_sigma, rms_px=fitted[1])
    return LensTest(freed, float(np.median(given[1])), float(np.median(fitted[1])),
                    h.cost_with(cam, given[0], w), h.cost_with(cam, fitted[0], w),
                    _loop_residual(cam, given[0]), _loop_residual(cam, fitted[0]))
