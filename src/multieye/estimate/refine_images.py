"""Image-level maximum-likelihood refinement of a rig: every ``X^j``, ``Y`` and mocap pose.

The closed form (:func:`multieye.solve`) fits the pose loop ``A_i^j X^j = Y B_i^j`` with an
arbitrary weighting of rotation against translation, and treats the PnP poses as if they were
measured.  What is measured are the target points' pixels and the motion-capture poses; this
module minimises exactly their negative log-likelihood (paper section IV, taken to the image
level), jointly over every camera's ``X^j`` (``T_world_cam`` eye-to-base, ``T_body_cam``
eye-on-hand), the shared ``Y`` (``T_marker_target`` / ``T_world_target``) and the true
motion-capture pose ``M_k`` of every motion-capture measurement, observed through it::

    min  sum_points   rho(||pi_j(T_cam_target_i p_k) - u_ik||^2 / sigma_px^2)
       + sum_instants rho(||Log(R_meas^T R_M)||^2 / sigma_R^2)
                      + rho(||t_M - t_meas||^2 / sigma_t^2)

(``rho`` applied per residual component).  Images given the same motion-capture pose
(bitwise equal: cameras triggered together) share one ``M_k`` and its one prior, so a
measurement counts once however many cameras saw the target at its instant
(:class:`multieye.estimate.image_data.ImageData`).  The residuals, their analytic
Jacobians and the parameterisation are in :mod:`multieye.estimate.image_residuals`; the
minimisation is the engine's (:mod:`multieye.optimize`): Levenberg-Marquardt with the
motion-capture poses eliminated by the Schur complement, cost linear in the points.

With ``clocks``, a camera's clock offset is an unknown too: its images' motion-capture
priors compare ``M_i`` with the locally smoothed motion-capture trajectory at ``t_i + delta``
(:mod:`multieye.estimate.clock_residuals`), so the offsets' uncertainty enters the covariance
of X and Y.  Cameras on one clock (``ClockData.shared``) share the offset and, per stamp, the
pose and its prior.

Covariance: ``kappa (J^T J)^-1`` restricted to X and Y by the Schur complement (which
marginalises the mocap poses), with ``J`` the Jacobian of the sigma-normalised residuals at
the optimum and ``kappa = E[psi^2] / E[psi']^2`` the asymptotic efficiency factor of the robust
loss for Gaussian residuals (1 for the linear loss: the Cramér-Rao bound,
:func:`multieye.estimate.uncertainty.cramer_rao_bound`).  When the pixel noise is not given it
is estimated by variance components: the robust sum of squared pixel residuals over their
redundancy ``n_pixel - (n_params - tr(H_prior cov_M))``, and each image's over its share (images
differ in how well their corners are found), re-solving until they settle.  When the
motion-capture noise is not given, its rotation and position components are estimated the
same way, each from its own residuals (how far the refinement moves the measured poses) over
its own redundancy (:mod:`multieye.estimate.variance_components`; the plain RMS of the corrections, which
shrinks with the sigma that produced it, collapsed to zero on small robot recordings:
benchmarks/bench_mocap_noise.py).  Like every covariance from a linearised model this one covers the
measurement noise only: not errors in the intrinsics, unsynchronised clocks (unless their
offsets are estimated, ``clocks``), a non-rigid rig,
or outliers that the robust loss did not catch.

Synopsis
--------
>>> from multieye.estimate.refine_images import refine_images
>>> res = refine_images("eye-to-base", observations, intrinsics, sol.X, sol.Y)  # doctest: +SKIP
>>> res.X, res.camera_rms_px, res.covariance.shape                               # doctest: +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import chdtri  # chi-square quantiles; scipy.stats costs 0.66 s to import

from multieye.core.arguments import transform, with_fields
from multieye.core.errors import InputError, UnprojectableStartError
from multieye.core.intrinsics import Intrinsics
from multieye.core.robust_loss import (LOSSES, gaussian_kappa, gaussian_scale_constant,
                                       gaussian_slope, rho)
from multieye.estimate import variance_components as vc
from multieye.estimate.clock_residuals import ClockData
from multieye.estimate.image_data import ImageData, ImageProblem, image_data
from multieye.estimate.image_residuals import intrinsics_family
# estimate_mocap_noise is named here too: it is the plain form of this module's estimate
from multieye.estimate.uncertainty import estimate_mocap_noise
from multieye.optimize.levenberg_marquardt import (NEAR_DAMPING, Options,
                                                   covariance_and_residuals, minimize)
from multieye.optimize.threads import threads_for

__all__ = [
    "refine_images",
    "RefineOptions",
    "RefinementResult",
    "estimate_mocap_noise",
    "DEFAULT_MOCAP_ROT_SIGMA_RAD",
    "DEFAULT_MOCAP_TRANS_SIGMA_M",
    "DEFAULT_F_SCALE",
    "OUTLIER_PROBABILITY",
]

F64 = NDArray[np.float64]

#: Rotation noise of an optical motion-capture pose, per rotation-vector component (0.1 deg).
DEFAULT_MOCAP_ROT_SIGMA_RAD = float(np.deg2rad(0.1))
#: Translation noise of an optical motion-capture pose, per coordinate (0.3 mm).
DEFAULT_MOCAP_TRANS_SIGMA_M = 0.3e-3
#: Where the robust loss departs from least squares, in standard deviations (Huber at 2 sigma
#: keeps 99 % of the efficiency of least squares on Gaussian noise).
DEFAULT_F_SCALE = 2.0
#: A point (2 residuals) or an image's mocap prior (6) is flagged as an outlier when its
#: squared normalised residual exceeds the chi-square quantile of this tail probability.
OUTLIER_PROBABILITY = 1e-4
_MAX_SIGMA_PASSES = 6
#: Stopping tolerance of the first pass while the noise is estimated: the steps and the final
#: pass go on from there (4 x 100 rig: the estimate moved by < 0.01 % in the iteration saved).
_FIRST_TOL = 1e-3
#: Clock windows are re-centred when an offset moved by more than this share of their
#: half-width (at most this many times).
_RECENTRE_SHARE = 0.25
_MAX_RECENTRES = 3


@dataclass(frozen=True)
class RefinementResult:
    """Result of :func:`refine_images`.

    Attributes
    ----------
    X : ndarray, shape (m, 4, 4)
        ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand), metres.
    Y : ndarray, shape (4, 4)
        ``T_marker_target`` (eye-to-base) or ``T_world_target`` (eye-on-hand).
    covariance : ndarray, shape (6(m+1), 6(m+1))
        Covariance of the perturbations of X^0..X^{m-1} then Y, each (rotation vector,
        translation) with ``R = Exp(phi) R_hat``, ``t = t_hat + tau`` (radians, metres), the
        per-image mocap poses marginalised (module docstring).
    full_covariance : ndarray, shape (k, k)
        Covariance of every kept parameter: X, Y, then the intrinsics of each camera whose
        intrinsics were estimated (``layout.offset["K:<camera>"]``); X and Y's block is
        ``covariance`` (which therefore includes the intrinsics' uncertainty).
    layout : multieye.optimize.normal_equations.Layout
        Where each family sits in ``full_covariance``.
    undetermined : tuple of str
        Families (``X``, ``Y``, ``K:<camera>``) involved in a combination of parameters the
        data do not determine (e.g. the rational model's numerator and denominator terms over
        a narrow field of view); their covariance covers the determined directions only.
        Empty in a well-posed problem.
    intrinsics : tuple of Intrinsics
        Per camera: refined when estimated, else as given.
    intrinsics_covariance : tuple of (ndarray or None)
        Per camera: covariance of ``Intrinsics.params`` (fx fy cx cy, then the distortion)
        when estimated, else None.
    mocap_covariance : ndarray, shape (N, 6, 6)
        Marginal covariance of the refined motion-capture pose of each image (``se3-right``:
        rotation in the marker/body frame, translation in the world frame), images camera by
        camera; images that share a measurement (one instant) share the pose and repeat it.
    T_world_mocap : tuple of ndarray, shape (N_j, 4, 4)
        Refined motion-capture poses (``T_world_marker`` or ``T_world_body``) of each
        camera's images (one pose for all the images of an instant).
    image_rms_px : tuple of ndarray, shape (N_j,)
        Reprojection RMS of every image (root mean square of the point distances), pixels.
    camera_rms_px : ndarray, shape (m,)
        Reprojection RMS over all points of each camera, pixels.
    point_weights : tuple of tuple of ndarray, shape (n_i,)
        Per camera, per image: the robust loss's weight of each point (the smaller of its two
        coordinates' IRLS weights ``rho'``; 1 = full least-squares weight; NaN for points left
        out for non-finite coordinates).
    point_outliers : tuple of tuple of ndarray, shape (n_i,), bool
        Points whose squared normalised residual exceeds the chi-square (2 dof) quantile of
        :data:`OUTLIER_PROBABILITY`.
    image_outliers : tuple of ndarray, shape (N_j,), bool
        Images with more than half their points flagged, or whose mocap pose had to move
        further from its measurement than the chi-square (6 dof) quantile allows (a shared
        measurement flags every image of its instant).
    pixel_sigma : float
        Pixel noise used, pixels (given, or estimated from the data): the root mean square
        of the images' over their points.
    image_sigma_px : tuple of ndarray, shape (N_j,)
        Each image's pixel noise: estimated per image when the pixel noise is
        (:func:`multieye.estimate.variance_components.image_noise`), else ``pixel_sigma``.
    jackknife_covariance : ndarray, shape (6(m+1), 6(m+1)), or None
        With ``RefineOptions.jackknife``: as ``covariance``, the delete-one-instant jackknife
        (each instant's images and prior a cluster), bread ``E[psi'] J^T J``.
    pixel_sigma_estimated : bool
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float
        Motion-capture noise used.
    mocap_sigma_estimated : bool
        Whether it was estimated from the data.
    loss : str
    f_scale : float
        Threshold of the robust loss, in standard deviations.
    iterations : int
        Levenberg-Marquardt iterations (Jacobian evaluations) over all passes.
    evaluations : int
        Residual evaluations over all passes.
    passes : int
        Optimisations run (more than one when the pixel noise is estimated).
    time_s : float
        Wall time, seconds.
    converged : bool
        Whether the last pass met its stopping rule.
    message : str
        Why the last pass stopped.
    time_offsets : tuple of (float or None)
        Per camera: its clock offset (motion-capture clock minus camera clock, seconds) when
        it was an unknown of the problem (``clocks``), else None.
    time_offset_std_s : tuple of (float or None)
        Its standard deviation, seconds (X, Y and the intrinsics' covariances include its
        uncertainty).
    """

    X: F64
    Y: F64
    covariance: F64
    full_covariance: F64
    layout: object
    undetermined: tuple[str, ...]
    intrinsics: tuple[Intrinsics, ...]
    intrinsics_covariance: tuple
    mocap_covariance: F64
    T_world_mocap: tuple[F64, ...]
    image_rms_px: tuple[F64, ...]
    camera_rms_px: F64
    point_weights: tuple[tuple[F64, ...], ...]
    point_outliers: tuple[tuple[NDArray[np.bool_], ...], ...]
    image_outliers: tuple[NDArray[np.bool_], ...]
    pixel_sigma: float
    pixel_sigma_estimated: bool
    mocap_rot_sigma_rad: float
    mocap_trans_sigma_m: float
    mocap_sigma_estimated: bool
    loss: str
    f_scale: float
    iterations: int
    evaluations: int
    passes: int
    time_s: float
    converged: bool
    message: str
    time_offsets: tuple = ()
    time_offset_std_s: tuple = ()
    image_sigma_px: tuple = ()
    jackknife_covariance: F64 | None = None


def _check_sigma(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a positive number, got {value!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise InputError(f"{name} must be a positive number, got {value!r}")
    return v


def _value(fams, name: str):
    return next(f.value for f in fams if f.name == name)


@dataclass(frozen=True)
class RefineOptions:
    """How :func:`refine_images` refines, and what it knows per camera besides the images.

    Attributes
    ----------
    mocap_rot_sigma_rad : float or None
        Standard deviation of each component of the rotation-vector error of a motion-capture
        pose, in the marker (body) frame, radians.  Default 0.1 degrees.
    mocap_trans_sigma_m : float or None
        Standard deviation of each coordinate of its position error, metres.  Default 0.3 mm.
        Either mocap sigma may be None: then both are estimated by variance components
        (module docstring), alternating with the refinement until they settle.
    pixel_sigma : float, optional
        Standard deviation of each pixel coordinate of a detected target point.  Estimated
        from the data when not given (module docstring), and the covariance scaled with it.
    loss : {"huber", "linear", "soft_l1", "cauchy", "arctan"}
        scipy's robust loss, applied to every normalised residual component.
    f_scale : float
        Threshold of the loss in standard deviations (default 2: 99 % efficient on Gaussian
        noise, so the covariance stays within 1 % of the Cramér-Rao bound).
    max_iter : int
        Levenberg-Marquardt iterations per pass at most.
    tol : float
        Stop when an iteration lowers the cost by less than ``tol`` times the cost (1e-8:
        within about 1 % of a standard deviation of the optimum; ``sqrt(tol)`` while the
        pixel noise is still being estimated).
    names, free_intrinsics, intrinsics_observations
        :func:`multieye.estimate.image_data.image_data`.
    clocks : sequence of (ClockData or None), optional
        Per camera: estimate its clock offset in the problem, from
        ``ClockData(image_stamps, mocap_stamps, mocap_T, offset=start)`` (the camera's image
        stamps in the order of ``observations[j]``, its motion-capture stream and a starting
        offset): the mocap pose of each of its images is then the locally smoothed trajectory
        at ``t_i + offset`` (:mod:`multieye.estimate.clock_residuals`; the poses given in
        ``observations[j]`` are not used), and the motion-capture noise is that of one
        sample.  Unstated motion-capture noise is then estimated from the smoothing's
        residuals.  Cameras stamped by one clock (triggered together) pass ClockData with the
        same ``shared`` name, each with its own image stamps: they get one offset (family
        ``dt:<first of them>``) and their images with bitwise equal stamps one pose block
        and one prior.  The offsets and their standard deviations are
        ``RefinementResult.time_offsets`` and ``time_offset_std_s`` (per camera; equal on a
        shared clock).
    mocap_noise_scale : sequence over cameras of sequence of float, optional
        Per camera, per image: its motion-capture pose's noise over the stated (or
        estimated) noise of one sample, in (0, 1]: ``sqrt(a^2 + (1 - a)^2)`` for a pose
        interpolated at ``a`` between two samples
        (:attr:`multieye.estimate.pairing.Pairing.noise_scale`).  Default 1.
    jackknife : bool
        Also ``RefinementResult.jackknife_covariance`` (:mod:`multieye.optimize.clusters`;
        noisy with few images per camera, docs/results/nees.md).
    """

    mocap_rot_sigma_rad: float | None = DEFAULT_MOCAP_ROT_SIGMA_RAD
    mocap_trans_sigma_m: float | None = DEFAULT_MOCAP_TRANS_SIGMA_M
    pixel_sigma: float | None = None
    loss: str = "huber"
    f_scale: float = DEFAULT_F_SCALE
    max_iter: int = 100
    tol: float = 1e-8
    names: Sequence[str] | None = None
    free_intrinsics: Sequence[bool] | None = None
    intrinsics_observations: Sequence | None = None
    clocks: Sequence[ClockData | None] | None = None
    mocap_noise_scale: Sequence | None = None
    jackknife: bool = False


def refine_images(setup: str, observations: Sequence, intrinsics: Sequence[Intrinsics],
                  X0: ArrayLike, Y0: ArrayLike, options: RefineOptions = RefineOptions(),
                  **kw) -> RefinementResult:
    """Maximum-likelihood refinement of every ``X^j`` and ``Y`` from pixels and mocap poses.

    Parameters
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
        docs/conventions.md, section 2.
    observations : sequence over cameras of sequence over images
        ``observations[j][i] = (object_points, image_points, T_world_mocap)``: the target
        points seen in image i of camera j, shape (n, 3), metres in the ``target`` frame;
        their pixels, shape (n, 2); and the motion-capture pose at that image's time, (4, 4):
        ``T_world_marker`` (eye-to-base) or ``T_world_body`` (eye-on-hand).  Rows with
        non-finite coordinates are left out.
    intrinsics : sequence of Intrinsics
        One per camera (pinhole or fisheye), held fixed.
    X0 : array_like, shape (m, 4, 4)
        Starting ``T_world_cam`` / ``T_body_cam`` (the closed form, :func:`multieye.solve`).
    Y0 : array_like, shape (4, 4)
        Starting ``T_marker_target`` / ``T_world_target``.
    options : RefineOptions
        Or its fields as keyword arguments (``pixel_sigma=0.3, clocks=...``): the noise
        levels, the loss, the stopping rule, and per camera its name, whether its intrinsics
        are estimated (with its intrinsics-only images) and its clock.

    Returns
    -------
    RefinementResult

    Raises
    ------
    InputError
        Unknown setup or loss, mismatched counts, malformed points or poses, non-positive
        noise levels; UnprojectableStartError: target points behind a camera at the start.

    Examples
    --------
    >>> from multieye.sim.images import simulate_images
    >>> sc = simulate_images(0, n_cameras=2, images=8)
    >>> import multieye
    >>> sol = multieye.solve(sc.A, sc.B)
    >>> res = refine_images(sc.setup, sc.observations, sc.intrinsics, sol.X, sol.Y)
    >>> bool(res.converged), res.covariance.shape
    (True, (18, 18))
    """
    start = time.perf_counter()
    opts = with_fields(options, kw, RefineOptions, "options")
    noise = _given_noise(opts)
    data = image_data(ImageProblem(setup, observations, intrinsics, opts.names,
                                   opts.free_intrinsics, opts.intrinsics_observations, opts.clocks,
                                   opts.mocap_noise_scale))
    fams, noise = _start(data, X0, Y0, noise)
    # BLAS threads for the reduced system's size over the whole solve (refine_rig's reason)
    with threads_for(sum(f.count * f.size for f in fams if not f.eliminate)):
        data, fams, noise, res, counts, at = _solve(data, fams, noise, loss=opts.loss,
                                                    max_iter=int(opts.max_iter), tol=opts.tol,
                                                    jackknife=bool(opts.jackknife))
        return _result(data, fams, noise, res, counts, at, loss=opts.loss, start=start)


@dataclass(frozen=True)
class _Noise:
    """The noise levels of one pass (pixels; radians and metres per motion-capture pose), and
    which of them are estimated from the data."""

    s_px: float | None
    s_rot: float
    s_t: float
    estimate_px: bool
    estimate_mocap: bool
    f_scale: float


def _given_noise(opts: RefineOptions) -> _Noise:
    """The options of :func:`refine_images` checked, and the noise levels they state."""
    loss, max_iter = opts.loss, opts.max_iter
    if not isinstance(loss, str) or loss not in LOSSES:
        raise InputError(f"unknown loss {loss!r}; expected one of {', '.join(LOSSES)}")
    f_scale = _check_sigma(opts.f_scale, "f_scale")
    rot, trans, px = opts.mocap_rot_sigma_rad, opts.mocap_trans_sigma_m, opts.pixel_sigma
    s_rot = DEFAULT_MOCAP_ROT_SIGMA_RAD if rot is None else _check_sigma(rot, "mocap_rot_sigma_rad")
    s_t = DEFAULT_MOCAP_TRANS_SIGMA_M if trans is None else _check_sigma(trans,
                                                                        "mocap_trans_sigma_m")
    s_px = None if px is None else _check_sigma(px, "pixel_sigma")
    if not (isinstance(max_iter, (int, np.integer)) and max_iter >= 1):
        raise InputError(f"max_iter must be a whole number >= 1, got {max_iter!r}")
    return _Noise(s_px=s_px, s_rot=s_rot, s_t=s_t, estimate_px=px is None,
                  estimate_mocap=rot is None or trans is None, f_scale=f_scale)


def _start(data: ImageData, X0: ArrayLike, Y0: ArrayLike, noise: _Noise):
    """The parameter families at ``X0``, ``Y0`` (checked), and the starting noise: of one
    motion-capture sample from the smoothing residuals on timed cameras, and of the pixels
    from the starting residuals when not given."""
    timed = [j for j, c in enumerate(data.clocks) if c is not None]
    s_rot, s_t, s_px = noise.s_rot, noise.s_t, noise.s_px
    if noise.estimate_mocap and timed:      # one sample's noise, from the smoothing residuals
        s_rot, s_t = vc.clock_noise(data)
    X0 = transform(X0, "X0", count=data.m)
    Y0 = transform(Y0, "Y0")
    fams = data.families(X0, Y0)
    values = {f.name: f.value for f in fams}
    r0 = np.concatenate([g_.evaluate(values, False)[0] for g_ in data.groups(1.0, s_rot, s_t)
                         [:data.m]])
    bad = np.unique(data.image[~np.all(np.isfinite(r0), axis=1)])
    if bad.size:
        j = data.cam_of_image[bad]                # items: (camera, its image) of each
        raise UnprojectableStartError(
            f"{data.where(int(bad[0]))}: target points project behind the camera at the "
            f"starting estimate; check X0, Y0, the setup ({data.setup}) and the direction of "
            "T_world_mocap", tuple(zip(j.tolist(), (bad - np.cumsum(np.r_[0, data.counts])[j]).tolist())))
    if noise.estimate_px:
        s_px = max(1.4826 * float(np.median(np.abs(r0))), 1e-3)
    return fams, replace(noise, s_px=s_px, s_rot=s_rot, s_t=s_t)


def _pass_options(stage: str, loss: str, f_scale: float, max_iter: int, tol: float,
                  first: bool) -> Options:
    """Levenberg-Marquardt's options of a pass: ``first`` from the closed form (to
    :data:`_FIRST_TOL` or ``sqrt(tol)``, the looser, while the noise is being estimated, the
    robust cost's curvature only near the optimum); ``step``, one step (the robust cost's
    curvature) from an earlier pass's optimum, only to re-estimate the noise there; ``final``
    to ``tol`` with the robust cost's curvature
    (:class:`~multieye.optimize.levenberg_marquardt.Options`), from its start when it starts
    at an earlier pass's optimum."""
    if stage == "step":
        return Options(loss=loss, f_scale=f_scale, max_iter=1, tol=np.sqrt(tol),
                       newton_below=np.inf, initial_damping=NEAR_DAMPING)
    if stage == "first":
        return Options(loss=loss, f_scale=f_scale, max_iter=max_iter,
                       tol=max(np.sqrt(tol), _FIRST_TOL))
    return Options(loss=loss, f_scale=f_scale, max_iter=max_iter, tol=tol,
                   newton_below=np.sqrt(tol) if first else np.inf,
                   initial_damping=1e-4 if first else NEAR_DAMPING)


def _recentre(data: ImageData, fams, noise: _Noise, sigmas: F64, recentres: int):
    """The data with the clock windows recentred on the offsets that moved far from where
    they are centred (at most :data:`_MAX_RECENTRES` times in all), the sigmas (the motion
    capture's from the new windows when estimated), and whether anything moved."""
    units = data.units
    moved = [u for u, f in enumerate(units.family) if abs(float(_value(fams, f)[0, 0])
                                                           - units.trajectories[u].centre_offset)
             > _RECENTRE_SHARE * units.clock[u].half_window_s]
    if not moved or recentres >= _MAX_RECENTRES:
        return data, sigmas, False
    data = data.recentred({u: float(_value(fams, units.family[u])[0, 0]) for u in moved})
    if noise.estimate_mocap:
        sigmas = np.array([sigmas[0], *vc.clock_noise(data)])
    return data, sigmas, True


def _solve(data: ImageData, fams, noise: _Noise, *, loss: str, max_iter: int, tol: float,
           jackknife: bool = False):
    """The refinement, alternating with the variance components of the noise levels being
    estimated (:mod:`multieye.estimate.variance_components`) until they settle, and the
    clock windows recentred on offsets that moved far.

    1. ``first`` pass from the closed form; the noise estimated at its optimum from its
       covariance (the redundancies) and residuals.
    2. While the estimate moves by more than the settled share (``SETTLED``, the motion
       capture's ``MOCAP_SETTLED``, :mod:`~multieye.estimate.variance_components`): one
       ``step`` from there with the new noise, and the estimate
       at its end from its residuals and the last redundancies, extrapolated to the fixed
       point from the last two (:func:`~multieye.estimate.variance_components.secant`).
    3. ``final`` pass to ``tol``; its covariance (which the result needs anyway) checks the
       estimate there: another final pass if it moved by more than a tenth of the settled
       share (:data:`~multieye.estimate.variance_components.FINAL_SHARE`).

    Returns the data (recentred), the families, the noise, the last pass's result,
    (iterations, evaluations, passes) and the covariance and residuals at the optimum."""
    f_scale = noise.f_scale
    s = np.array([noise.s_px, noise.s_rot, noise.s_t], dtype=np.float64)
    iterate_mocap = noise.estimate_mocap and not any(c is not None for c in data.clocks)
    free = np.array([noise.estimate_px, iterate_mocap, iterate_mocap])
    share = np.array([vc.SETTLED, vc.MOCAP_SETTLED, vc.MOCAP_SETTLED])
    c_w = gaussian_scale_constant(loss, f_scale)
    counts = np.zeros(3, dtype=np.int64)          # iterations, evaluations, passes
    stage, red, red_at, previous, recentres, estimates = (
        "final" if not free.any() else "first", None, s, None, 0, 0)
    while True:
        groups = data.groups(*s)
        res = minimize(fams, groups, _pass_options(stage, loss, f_scale, max_iter, tol,
                                                   first=counts[2] == 0))
        fams = res.families
        counts += (res.iterations, res.evaluations, 1)
        data, s, recentred = _recentre(data, fams, noise, s, recentres)
        if recentred:
            recentres += 1
            red, previous, groups = None, None, data.groups(*s)
            if stage == "final":
                continue
        if stage == "final" or red is None or np.any(np.abs(np.log(s / red_at)) > vc.STALE):
            cov, ev = covariance_and_residuals(fams, groups, local=True, jackknife=Options(
                loss=loss, f_scale=f_scale) if jackknife and stage == "final" else None)
            if not free.any():
                break
            evaluated = ev
            sums = vc.weighted_sums(groups, ev, loss, f_scale)
            red, red_at, previous = vc.redundancy(data, fams, groups, cov, sums.n_pixels), s, None
        else:
            evaluated = res.residuals
            sums = vc.weighted_sums(groups, evaluated, loss, f_scale)
        new = vc.estimate(s, sums, red, c_w)
        estimates += 1
        moved = float(np.max(np.abs(new / s - 1.0)[free] / share[free]))
        if free[0]:                     # each image's noise over the pooled one
            f = vc.image_noise(data, evaluated, red, sums.n_pixels, loss, f_scale, c_w)
            f0 = np.ones(data.n_images) if data.image_noise is None else data.image_noise
            moved = max(moved, float(np.sqrt(np.mean((f / f0 - 1.0) ** 2))) / vc.SETTLED)
        if stage == "final" and (moved < vc.FINAL_SHARE or estimates > _MAX_SIGMA_PASSES):
            break
        following, extrapolated = vc.secant(s, new, previous, free)
        previous, s = (s, new), following
        if free[0]:
            data = replace(data, image_noise=f)
        if stage != "final":
            near = moved < 1.0 or (extrapolated and moved < vc.EXTRAPOLATED)
            stage = "final" if near or estimates >= _MAX_SIGMA_PASSES else "step"
    return (data, fams, replace(noise, s_px=float(s[0]), s_rot=float(s[1]), s_t=float(s[2])),
            res, tuple(int(c) for c in counts), (cov, ev))


def _result(data: ImageData, fams, noise: _Noise, res, counts: tuple[int, int, int], at, *,
            loss: str, start: float) -> RefinementResult:
    """The result at the optimum: covariance (scaled by the loss's kappa), per-point and
    per-image residuals and outliers, the intrinsics and clock offsets per camera; ``at``:
    the covariance and residuals there (with every pose's marginal covariance)."""
    s_px, s_rot, s_t, f_scale = noise.s_px, noise.s_rot, noise.s_t, noise.f_scale
    kappa = gaussian_kappa(loss, f_scale)
    X, Y, M = _value(fams, "X"), _value(fams, "Y")[0], _value(fams, "M")
    groups = data.groups(s_px, s_rot, s_t)
    cov, ev = at
    z_pix = vc.pixel_residuals(data, ev)
    sigma_img = s_px * (np.ones(data.n_images) if data.image_noise is None else data.image_noise)
    r_pix = z_pix * sigma_img[data.image][:, None]                       # (P, 2) pixels
    w_pt = rho((z_pix / f_scale) ** 2, loss)[1].min(axis=1)
    d2 = np.sum(r_pix ** 2, axis=1)
    point_out = np.sum(z_pix ** 2, axis=1) > chdtri(2, OUTLIER_PROBABILITY)
    per_image = np.diff(np.append(data.image_starts, data.n_points))
    img_rms = np.sqrt(np.add.reduceat(d2, data.image_starts) / per_image)
    frac_out = np.add.reduceat(point_out.astype(float), data.image_starts) / per_image
    prior = vc.prior_residuals(data, groups, ev)
    img_out = (frac_out > 0.5) | (np.sum(prior ** 2, axis=1) > chdtri(6, OUTLIER_PROBABILITY))
    cam_rms = np.array([np.sqrt(np.mean(d2[s])) for s in data.camera_slices])
    k_xy = 6 * (data.m + 1)
    undetermined = tuple(f.name for f in fams if not f.eliminate and cov.undetermined_in(
        f.name, f.count, f.size))
    intr_out, intr_cov = [], []
    for j, name in enumerate(data.names):
        if data.free[j]:
            fam = intrinsics_family(name)
            o = cov.layout.offset[fam]
            n = data.intrinsics[j].params.size
            intr_out.append(data.intrinsics[j].with_params(_value(fams, fam)[0]))
            intr_cov.append(kappa * cov.kept[o:o + n, o:o + n])
        else:
            intr_out.append(data.intrinsics[j])
            intr_cov.append(None)
    offsets, offset_std = [None] * data.m, [None] * data.m
    for fam, cams in zip(data.units.family, data.units.cameras):
        o = cov.layout.offset[fam]
        for j in cams:                          # a shared clock: one value for its cameras
            offsets[j] = float(_value(fams, fam)[0, 0])
            offset_std[j] = float(np.sqrt(kappa * cov.kept[o, o]))
    return RefinementResult(
        time_offsets=tuple(offsets), time_offset_std_s=tuple(offset_std),
        X=X, Y=Y, covariance=kappa * cov.kept[:k_xy, :k_xy],
        jackknife_covariance=None if cov.jackknife is None else       # bread E[psi'] J^T J
        cov.jackknife[:k_xy, :k_xy] / gaussian_slope(loss, f_scale) ** 2,
        full_covariance=kappa * cov.kept, layout=cov.layout, undetermined=undetermined,
        intrinsics=tuple(intr_out), intrinsics_covariance=tuple(intr_cov),
        mocap_covariance=kappa * cov.local[:data.n_instants][data.instant],
        T_world_mocap=data.split_images(M[data.instant]),
        image_rms_px=data.split_images(img_rms), camera_rms_px=cam_rms,
        point_weights=data.split_points(w_pt, np.nan),
        point_outliers=data.split_points(point_out, False),
        image_outliers=data.split_images(img_out), pixel_sigma=float(s_px),
        image_sigma_px=data.split_images(sigma_img),
        pixel_sigma_estimated=noise.estimate_px, mocap_rot_sigma_rad=s_rot,
        mocap_trans_sigma_m=s_t, mocap_sigma_estimated=noise.estimate_mocap,
        loss=loss, f_scale=f_scale, iterations=counts[0], evaluations=counts[1],
        passes=counts[2], time_s=time.perf_counter() - start, converged=res.converged,
        message=res.message)
