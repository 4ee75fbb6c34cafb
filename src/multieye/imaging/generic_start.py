"""A lens start from a generic model, for lenses however wide (issue 33), and the per-camera
fit of a lens with its views' poses.

OpenCV's ``cv2.fisheye.calibrate`` starts from a pinhole guess and fails or stops far off on a
lens near 180 degrees (on ``boofcv_fisheye`` it leaves reprojection RMS of 2-5 px, or
asserts in ``InitExtrinsics``).  The start here does not use it; as Kalibr and Basalt start
their wide models, it starts from a generic one:

1. the equidistant lens ``r = f theta`` centred on the image, ``f`` the one under which the
   views' rays fit planar boards best (IPPE on the rays, :func:`multieye.imaging.rays.
   ippe_on_rays`; a grid of focal lengths then a bounded search, :func:`equidistant_focal`);
2. that lens written in the requested model (its shape parameters fitted to the same radial
   curve, :func:`model_from_equidistant`);
3. the lens and every view's pose fitted together on the pixels (:func:`fit_lens`:
   ``scipy.optimize.least_squares``, analytic Jacobian from
   :func:`multieye.core.lens.project_with_jacobian`, a Huber loss so that a mis-detected view
   does not pull the start);
4. for the unified and double-sphere models, the same fit started from the lenses at the
   other optima along the model's valley, the best kept (:func:`best_in_valley`), and the
   others that fit the views as well recorded (:attr:`LensFit.rivals`: the views then
   determine the lens' projection but not its parameters).

Synopsis
--------
>>> fit = generic_start(views, (640, 720), "fisheye")                 # doctest: +SKIP
>>> fit.intrinsics, fit.rms_px                                          # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import LENS_MODELS, Intrinsics
from multieye.core.lens import project_points, project_with_jacobian
from multieye.imaging.lens_valley import VALLEY_MODELS, valley_lenses
from multieye.imaging.rays import bearings, ippe_on_rays

__all__ = ["LensFit", "generic_start", "fit_lens", "equidistant_focal",
           "model_from_equidistant", "START_DIST", "pose_on_rays", "best_in_valley",
           "ValleyRival", "RIVAL_SIGMA2"]

F64 = NDArray[np.float64]

#: Each model's distortion at the start, before its shape is fitted to the equidistant curve
#: (unified: xi = 1, Kalibr's omni start; double-sphere, eucm: Basalt's defaults).
START_DIST = {"pinhole": (), "fisheye": (0.0, 0.0, 0.0, 0.0),
              "unified": (1.0, 0.0, 0.0, 0.0, 0.0), "double-sphere": (0.0, 0.6),
              "eucm": (0.6, 1.0)}
#: The distortion parameters fitted to the equidistant curve (the others stay at
#: :data:`START_DIST`; the per-camera fit frees them all).
_SHAPE = {"pinhole": (0, 1), "fisheye": (), "unified": (0,), "double-sphere": (0, 1),
          "eucm": (0, 1)}
#: Pixels of a point the lens does not project during the fit (a constant: no gradient).
_OUTSIDE_PX = 2.0
#: Huber scale of the start's fit, pixels.
HUBER_PX = 2.0
#: Views the focal length is searched on (spread over the views given).
_FOCAL_VIEWS = 10
#: Another optimum whose sum of squares is within this many times the pixel noise's variance
#: of the kept one's is not excluded by the views (a likelihood ratio of 9 for one parameter:
#: three standard deviations).
RIVAL_SIGMA2 = 9.0


@dataclass(frozen=True)
class ValleyRival:
    """A lens at another optimum along its model's valley that the views do not exclude.

    Attributes
    ----------
    intrinsics : Intrinsics
        The lens fitted (with the views' poses) from that optimum's start.
    delta_sigma2 : float
        Its sum of squared pixel residuals less the kept fit's, in units of the kept fit's
        residual variance per pixel coordinate (sum of squares over its degrees of freedom);
        at least 0 (the kept fit is the best) and at most :data:`RIVAL_SIGMA2`.
    """

    intrinsics: Intrinsics
    delta_sigma2: float


@dataclass(frozen=True)
class LensFit:
    """A lens fitted with its views' poses.

    Attributes
    ----------
    intrinsics : Intrinsics
    T_cam_target : ndarray, shape (n, 4, 4)
        Per view, the target's pose (metres as the object points).
    rms_px : ndarray, shape (n,)
        Per view, the pixel RMS (inf where a point does not project).
    rivals : tuple of ValleyRival
        The lenses at other optima of the model's valley that fit the same views as well
        (:func:`best_in_valley`), best first; none for the other models.
    """

    intrinsics: Intrinsics
    T_cam_target: F64
    rms_px: F64
    rivals: tuple[ValleyRival, ...] = ()

    @property
    def total_rms_px(self) -> float:
        """RMS over every view (the views weighed by their points as well)."""
        return float(np.sqrt(np.mean(self.rms_px ** 2)))


def _equidistant_rays(uv: F64, f: float, c: F64) -> F64:
    d = uv - c
    r = np.hypot(d[:, 0], d[:, 1])
    theta = np.minimum(r / f, np.pi - 1e-6)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(r > 0, np.sin(theta) / r, 1.0 / f)
    return np.column_stack([d * s[:, None], np.cos(theta)])


def _equidistant_pixels(P: F64, f: float, c: F64) -> F64:
    rho = np.hypot(P[:, 0], P[:, 1])
    theta = np.arctan2(rho, P[:, 2])
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(rho > 0, f * theta / rho, f / np.maximum(P[:, 2], 1e-300))
    return c + P[:, :2] * s[:, None]


def pose_on_rays(obj: F64, rays: F64, pixels_of) -> tuple[F64, float]:
    """The better of IPPE's poses of a view from its rays (:func:`multieye.imaging.rays.
    ippe_on_rays`) by the pixel RMS that ``pixels_of`` (camera-frame points -> pixels,
    ``(n, 3) -> (n, 2)``, with the view's pixels subtracted) gives; ``(T_cam_target, rms)``,
    NaN and inf when no pose can be made."""
    best = (np.full((4, 4), np.nan), np.inf)
    ok = np.isfinite(rays).all(axis=1)
    if ok.sum() < 4:
        return best
    for rvec, tvec in ippe_on_rays(obj[ok], rays[ok]):
        R = cv2.Rodrigues(rvec)[0]
        d = pixels_of(obj @ R.T + tvec)
        rms = float(np.sqrt(np.mean(np.sum(d ** 2, axis=1))))
        rms = rms if np.isfinite(rms) else np.inf
        if rms < best[1] or not np.isfinite(best[0][0, 0]):
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, tvec
            best = (T, rms)
    return best


def _equidistant_fit(views, f: float, c: F64) -> tuple[F64, F64]:
    """Per view, its best IPPE pose and pixel RMS under the equidistant lens ``f``, ``c``."""
    poses, rms = [], []
    for obj, uv in views:
        T, e = pose_on_rays(obj, _equidistant_rays(uv, f, c),
                            lambda P, uv=uv: _equidistant_pixels(P, f, c) - uv)
        poses.append(T)
        rms.append(e)
    return np.array(poses), np.array(rms)


def equidistant_focal(views, size: tuple[int, int]) -> tuple[float, F64]:
    """The focal length of the equidistant lens centred on the image under which the views
    fit planar boards best (the median of their pixel RMS), and that centre.

    A grid of 24 focal lengths over fields of view of about 20 to 240 degrees across the
    observed points, then a bounded search around the best."""
    c = np.array([(size[0] - 1) / 2.0, (size[1] - 1) / 2.0])
    r_max = max(float(np.max(np.hypot(*(uv - c).T))) for _, uv in views)
    some = [views[i] for i in _spread(len(views), _FOCAL_VIEWS)]

    def score(log_f: float) -> float:
        return float(np.median(_equidistant_fit(some, float(np.exp(log_f)), c)[1]))

    grid = np.linspace(np.log(r_max / 2.1), np.log(r_max / 0.17), 24)
    scores = np.array([score(x) for x in grid])
    k = int(np.argmin(scores))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    from scipy.optimize import minimize_scalar  # noqa: PLC0415 (heavy: SciPy, imported while the workers detect, not before the first image is sent)

    best = minimize_scalar(score, bounds=(lo, hi), method="bounded",
                           options={"xatol": 1e-3})
    log_f = best.x if best.fun <= scores[k] else grid[k]
    return float(np.exp(log_f)), c


def model_from_equidistant(model: str, f: float, c: F64, theta_max: float,
                           size: tuple[int, int]) -> Intrinsics:
    """The lens of ``model`` (an :class:`Intrinsics` model name) nearest the equidistant
    ``r = f theta`` centred at ``c``, over the angles 0 to ``theta_max`` radians: its focal
    length and shape parameters (:data:`_SHAPE`) fitted to the same pixels of rays at those
    angles, the other parameters at :data:`START_DIST`."""
    dist0 = np.array(START_DIST[model], np.float64)
    base = Intrinsics(K=np.array([[f, 0, c[0]], [0, f, c[1]], [0, 0, 1.0]]), dist=dist0,
                      model=model, width=int(size[0]), height=int(size[1]))
    free = list(_SHAPE[model])
    if not free:
        return base
    theta = np.linspace(0.02, max(theta_max, 0.1), 40)
    P = np.column_stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)])
    want = c[0] + f * theta

    def lens(x):
        d = dist0.copy()
        d[free] = x[1:]
        return base.with_params(np.concatenate([[x[0], x[0]], c, d]))

    def residual(x):
        try:
            u = project_points(P, lens(x))[:, 0]
        except InputError:
            return np.full(len(theta), 1e3)
        return np.where(np.isfinite(u), u - want, 1e3)

    x0 = np.concatenate([[f], dist0[free]])
    from scipy.optimize import least_squares  # noqa: PLC0415 (heavy: SciPy, imported while the workers detect, not before the first image is sent)

    fit = least_squares(residual, x0, method="trf", x_scale="jac")
    try:
        return lens(fit.x)
    except InputError:
        return base


def _spread(n: int, k: int) -> NDArray[np.int64]:
    return np.unique(np.linspace(0, n - 1, min(n, k)).round().astype(np.int64))


def _rotations(w: F64) -> tuple[F64, F64]:
    """``exp(w)`` of each row of ``w`` (n, 3) and its derivative, (n, 3, 3, 3): ``[i, k]`` is
    ``d R_i / d w_k`` (OpenCV's Rodrigues Jacobian)."""
    R, dR = np.empty((len(w), 3, 3)), np.empty((len(w), 3, 3, 3))
    for i, wi in enumerate(w):
        Ri, J = cv2.Rodrigues(np.ascontiguousarray(wi, np.float64).reshape(3, 1))
        R[i], dR[i] = Ri, J.reshape(3, 3, 3)
    return R, dR


class _Problem:
    """The stacked residuals of a lens and the views' poses (left increments ``w``, ``v``
    on the starting poses) and their Jacobian, for ``least_squares``."""

    def __init__(self, views, intrinsics: Intrinsics, T0: F64):
        self.obj = [np.asarray(o, np.float64) for o, _ in views]
        self.img = np.concatenate([np.asarray(u, np.float64) for _, u in views])
        self.view_of = np.repeat(np.arange(len(views)), [len(o) for o in self.obj])
        self.base = intrinsics
        self.T0 = T0
        # each view's points in its starting camera frame: P = exp(w) (R0 X + t0 - ...)
        self.Q = np.concatenate([o @ T[:3, :3].T for o, T in zip(self.obj, T0)])
        self.t0 = T0[:, :3, 3]
        self.n_lens = 4 + intrinsics.dist.size

    def unpack(self, x):
        lens = self.base.with_params(x[:self.n_lens])
        pose = x[self.n_lens:].reshape(-1, 6)
        return lens, pose

    def _points(self, pose):
        R, dR = _rotations(pose[:, :3])
        Rv, dRv = R[self.view_of], dR[self.view_of]
        P = np.einsum("nij,nj->ni", Rv, self.Q) + self.t0[self.view_of] + pose[self.view_of, 3:]
        dP_dw = np.einsum("nkij,nj->nik", dRv, self.Q)                  # (N, 3, 3)
        return P, dP_dw

    def residual(self, x):
        try:
            lens, pose = self.unpack(x)
        except InputError:
            return np.full(2 * len(self.img), _OUTSIDE_PX)
        P, _ = self._points(pose)
        d = project_points(P, lens) - self.img
        return np.where(np.isfinite(d), d, _OUTSIDE_PX).ravel()

    def jacobian(self, x):
        N, nv = len(self.img), len(self.T0)
        J = np.zeros((N, 2, self.n_lens + 6 * nv))
        try:
            lens, pose = self.unpack(x)
        except InputError:
            return J.reshape(2 * N, -1)
        P, dP_dw = self._points(pose)
        _, Jp, Ji = project_with_jacobian(P, lens)
        ok = np.isfinite(Jp).all(axis=(1, 2)) & np.isfinite(Ji).all(axis=(1, 2))
        Jp, Ji = np.where(ok[:, None, None], Jp, 0.0), np.where(ok[:, None, None], Ji, 0.0)
        J[:, :, :self.n_lens] = Ji
        cols = self.n_lens + 6 * self.view_of
        rows = np.arange(N)
        for k in range(3):
            J[rows, :, cols + k] = np.einsum("nij,nj->ni", Jp, dP_dw[:, :, k])
            J[rows, :, cols + 3 + k] = Jp[:, :, k]
        return J.reshape(2 * N, -1)

    def poses(self, pose) -> F64:
        R, _ = _rotations(pose[:, :3])
        T = self.T0.copy()
        T[:, :3, :3] = R @ self.T0[:, :3, :3]
        T[:, :3, 3] = self.t0 + pose[:, 3:]
        return T


def fit_lens(views: Sequence[tuple[F64, F64]], intrinsics: Intrinsics, T_cam_target: F64, *,
             huber_px: float | None = HUBER_PX, max_iterations: int = 200) -> LensFit:
    """The lens and every view's pose fitted together on the pixels.

    Parameters
    ----------
    views : sequence of (object_points (n, 3), image_points (n, 2))
        Target frame, metres (any unit, as the poses); pixels.
    intrinsics : Intrinsics
        The starting lens (its model is the model fitted).
    T_cam_target : ndarray, shape (n_views, 4, 4)
        Starting poses.
    huber_px : float or None
        Huber loss scale, pixels (None: plain least squares).
    max_iterations : int

    Returns
    -------
    LensFit
    """
    prob = _Problem(views, intrinsics, np.asarray(T_cam_target, np.float64))
    x = _levenberg_marquardt(prob, np.concatenate([intrinsics.params, np.zeros(6 * len(views))]),
                             huber_px, max_iterations)
    lens, pose = prob.unpack(x)
    T = prob.poses(pose)
    return LensFit(lens, T, _view_rms(views, lens, T))


def _huber_cost(r: F64, scale: float | None) -> tuple[float, F64]:
    """Huber cost of residuals ``r`` (pairs of pixel coordinates: one weight per point) and
    the IRLS weights per residual."""
    e = np.hypot(r[0::2], r[1::2])
    if scale is None:
        return float(e @ e), np.ones_like(r)
    big = e > scale
    cost = np.where(big, 2 * scale * e - scale ** 2, e ** 2)
    w = np.where(big, scale / np.maximum(e, 1e-300), 1.0)
    return float(cost.sum()), np.repeat(w, 2)


def _levenberg_marquardt(prob: _Problem, x: F64, huber_px: float | None, max_iterations: int
                         ) -> F64:
    """Levenberg-Marquardt (Marquardt's diagonal damping) with Huber weights by iterative
    reweighting, on the dense normal equations (a start has a few tens of views)."""
    r = prob.residual(x)
    cost, w = _huber_cost(r, huber_px)
    damping = 1e-3
    for _ in range(max_iterations):
        J = prob.jacobian(x)
        Jw = J * w[:, None]
        H, g = Jw.T @ J, Jw.T @ r
        s = 1.0 / np.sqrt(np.maximum(np.diag(H), 1e-300))   # Jacobi scaling: H's diagonal 1
        Hs, gs = H * s[:, None] * s[None, :], g * s
        while damping <= 1e10:
            try:
                step = -s * np.linalg.solve(Hs + damping * np.eye(len(s)), gs)
            except np.linalg.LinAlgError:
                damping *= 10
                continue
            r_new = prob.residual(x + step)
            cost_new, w_new = _huber_cost(r_new, huber_px)
            if cost_new < cost:
                break
            damping *= 10
        else:
            return x
        x, r, w = x + step, r_new, w_new
        done = cost - cost_new <= 1e-10 * cost
        cost, damping = cost_new, max(damping / 10, 1e-9)
        if done or np.max(np.abs(step)) <= 1e-10 * (1 + np.max(np.abs(x))):
            break
    return x


def _fit_cost(views, fit: LensFit, huber_px: float | None) -> float:
    """The (Huber) cost :func:`fit_lens` minimises, at ``fit``."""
    d = np.concatenate([project_points(o @ T[:3, :3].T + T[:3, 3], fit.intrinsics) - u
                        for (o, u), T in zip(views, fit.T_cam_target)])
    return _huber_cost(np.where(np.isfinite(d), d, _OUTSIDE_PX).ravel(), huber_px)[0]


def best_in_valley(views: Sequence[tuple[F64, F64]], fit: LensFit, *,
                   huber_px: float | None = HUBER_PX, max_iterations: int = 200) -> LensFit:
    """``fit`` or, when better, the fit of the lens and poses started from a lens at another
    optimum along the model's valley (:func:`multieye.imaging.lens_valley.valley_lenses`;
    unified and double-sphere: a fit from one lens stops in the optimum nearest it, which
    may not be the best), with the other optima the views do not exclude as its
    :attr:`LensFit.rivals` (:func:`_rivals`).

    Parameters
    ----------
    views : sequence of (object_points (n, 3), image_points (n, 2))
        The views ``fit`` was fitted to (its poses in the same order).
    fit : LensFit
        A fit of :func:`fit_lens` with ``huber_px``.
    huber_px, max_iterations
        As :func:`fit_lens`.

    Returns
    -------
    LensFit
        The one of least cost.
    """
    if fit.intrinsics.model not in VALLEY_MODELS:
        return fit
    uv = np.concatenate([u for _, u in views])
    rays = bearings(uv, fit.intrinsics)
    theta = np.arctan2(np.hypot(rays[:, 0], rays[:, 1]), rays[:, 2])
    if not np.any(np.isfinite(theta)):
        return fit
    fits = [fit] + [fit_lens(views, lens, fit.T_cam_target, huber_px=huber_px,
                             max_iterations=max_iterations)
                    for lens in valley_lenses(fit.intrinsics, float(np.nanmax(theta)))]
    costs = [_fit_cost(views, f, huber_px) for f in fits]
    best = fits[int(np.argmin(costs))]
    return replace(best, rivals=_rivals(views, best, [f for f in fits if f is not best]))


def _sum_of_squares(views, fit: LensFit) -> tuple[float, int]:
    """Sum of squared pixel residuals at ``fit`` and how many points it does not project."""
    d = np.concatenate([project_points(o @ T[:3, :3].T + T[:3, 3], fit.intrinsics) - u
                        for (o, u), T in zip(views, fit.T_cam_target)])
    lost = ~np.all(np.isfinite(d), axis=1)
    return float(np.sum(d[~lost] ** 2)), int(np.count_nonzero(lost))


def _rivals(views, best: LensFit, others: Sequence[LensFit]) -> tuple[ValleyRival, ...]:
    """The ``others`` the views do not exclude against ``best``: every point projected and
    a sum of squares within :data:`RIVAL_SIGMA2` times the pixel noise's variance of
    ``best``'s (estimated from its own residuals), best first."""
    ss, lost = _sum_of_squares(views, best)
    points = sum(len(u) for _, u in views) - lost
    dof = 2 * points - len(best.intrinsics.params) - 6 * len(views)
    if dof <= 0 or ss <= 0:
        return ()
    variance = ss / dof
    out = []
    for other in others:
        ss_other, lost_other = _sum_of_squares(views, other)
        delta = (ss_other - ss) / variance
        if lost_other <= lost and delta <= RIVAL_SIGMA2:
            out.append(ValleyRival(other.intrinsics, max(delta, 0.0)))
    return tuple(sorted(out, key=lambda r: r.delta_sigma2))


def _view_rms(views, lens: Intrinsics, T: F64) -> F64:
    out = []
    for (obj, uv), Ti in zip(views, T):
        d = project_points(obj @ Ti[:3, :3].T + Ti[:3, 3], lens) - uv
        e = np.sum(d ** 2, axis=1)
        out.append(float(np.sqrt(np.mean(e))) if np.all(np.isfinite(e)) else np.inf)
    return np.array(out)


def generic_start(views: Sequence[tuple[F64, F64]], image_size: tuple[int, int],
                  model: str) -> LensFit:
    """A lens of ``model`` (rig.yaml name, :data:`multieye.core.intrinsics.LENS_MODELS`)
    from views of a planar target, without OpenCV's calibration (module docstring).

    Parameters
    ----------
    views : sequence of (object_points (n, 3), image_points (n, 2))
        Target frame with z = 0; pixels.  All are fitted: give at most the few tens a start
        needs.
    image_size : (int, int)
        Width, height, pixels.
    model : str

    Returns
    -------
    LensFit
        Views no pose could be found for have NaN poses and infinite RMS; they are not fitted.

    Raises
    ------
    InputError
        Fewer than 3 views could be posed under the best equidistant lens.
    """
    kind = LENS_MODELS[model][0]
    views = [(np.asarray(o, np.float64), np.asarray(u, np.float64)) for o, u in views]
    f, c = equidistant_focal(views, image_size)
    T, rms = _equidistant_fit(views, f, c)
    posed = np.flatnonzero(np.isfinite(rms))
    if posed.size < 3:
        raise InputError(f"only {posed.size} views could be posed under any equidistant lens")
    r_max = max(float(np.max(np.hypot(*(views[i][1] - c).T))) for i in posed)
    lens = model_from_equidistant(kind, f, c, r_max / f, image_size)
    if kind != "fisheye":
        # the poses again under the converted lens (the same rays, to the fit's accuracy)
        for i in posed:
            obj, uv = views[i]
            T[i], rms[i] = pose_on_rays(obj, bearings(uv, lens),
                                        lambda P, uv=uv: project_points(P, lens) - uv)
        posed = np.flatnonzero(np.isfinite(rms))
    fit = best_in_valley([views[i] for i in posed], fit_lens([views[i] for i in posed],
                                                               lens, T[posed]))
    T_all = np.full((len(views), 4, 4), np.nan)
    rms_all = np.full(len(views), np.inf)
    T_all[posed], rms_all[posed] = fit.T_cam_target, fit.rms_px
    return LensFit(fit.intrinsics, T_all, rms_all, fit.rivals)
