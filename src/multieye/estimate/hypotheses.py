"""Refits of the closed form under the hypotheses that explain a poor fit, and how poor a
fit is (:mod:`multieye.estimate.plausibility` decides what they mean).

Residuals are the predicted target pose ``inv(X) inv(A_i) Y`` against the measured
``inv(B_i)`` in the camera frame (docs/conventions.md, section 2), as a left perturbation
(rotation vector, then translation), weighted by the inverse of the noise the measurement
carries: the PnP covariance predicted to first order from the point geometry and the
reprojection RMS (depth is far less certain than the lateral position), plus the
motion-capture noise; fixed noise levels for precomputed poses.  The ``cost`` of a fit, the
root of the median weighted square over the measurements divided by its value under pure
noise (after one trimming of outliers), is about 1 when the noise explains the residuals.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.errors import CalibrationError
from multieye.core.intrinsics import Intrinsics
from multieye.solvers.checks import Measurements
from multieye.solvers.joint import solve_joint
from multieye.core.metrics import chordal_angle
from multieye.estimate.clock import estimate_offset
from multieye.estimate.pairing import pair_in_time

__all__ = ["CameraEvidence", "Fit", "noise", "fit", "mocap_A", "scaled_A", "scale_factor",
           "permuted", "QUATERNION_ORDERS", "other_rotations", "reread_rotations",
           "focal_search", "resize_search", "clock_search",
           "MOCAP_NOISE", "RESIZE_FACTORS", "cost_with", "loop_residuals", "MIN_RMS_PX"]

F64 = NDArray[np.float64]

#: Image resize factors tried for intrinsics of another image size.
RESIZE_FACTORS = (1 / 4, 1 / 3, 1 / 2, 2 / 3, 3 / 4, 4 / 3, 3 / 2, 2.0, 3.0, 4.0)
#: Motion-capture noise per axis when none is stated: rotation (rad), translation (m); the
#: refinement's defaults.
MOCAP_NOISE = (math.radians(0.1), 0.3e-3)
#: Median of a chi-square with 6 degrees of freedom: the median weighted square of a
#: measurement's residual (rotation and translation) when the noise explains it.
_MEDIAN_E2 = 5.348
#: Noise assumed for precomputed poses (no points to predict it from): rotation (rad) and
#: translation (m) per axis.
_POSE_NOISE = (math.radians(0.1), 1e-3)
#: Smallest reprojection RMS the PnP noise is predicted from, pixels.
MIN_RMS_PX = 0.05
#: Largest median rotation between consecutive motion-capture samples of a trajectory the
#: clock can be estimated on (larger: poses recorded one by one, not a continuous motion).
_MAX_MOCAP_STEP_RAD = math.radians(5.0)
#: Measurements whose weighted residual is over this many times the median's (in root) are
#: left out of the refit.
_TRIM = 4.0
#: Smallest angular-speed correlation at which a clock offset is believed.
_MIN_CLOCK_SCORE = 0.5


@dataclass(frozen=True)
class CameraEvidence:
    """What one camera's measurements are, for the checks.

    Attributes
    ----------
    name : str
    A, B : ndarray, shape (n, 4, 4)
        The measurements of ``A_i X = Y B_i`` (docs/conventions.md, section 2).
    T_world_mocap : ndarray, shape (n, 4, 4)
        The motion-capture pose of each measurement (``T_world_marker`` or ``T_world_body``).
    stamps : ndarray, shape (n,), or None
        Camera clock of each measurement, seconds.
    intrinsics : Intrinsics or None
    object_points, image_points : tuple of ndarray, or None
        Per measurement, the detected target points (metres) and their pixels; None for
        precomputed poses.
    rms_px : ndarray, shape (n,), or None
        PnP reprojection RMS of each measurement, pixels.
    mocap_stamps : ndarray, shape (L,), or None
    mocap_T : ndarray, shape (L, 4, 4), or None
        The whole motion-capture stream (for the clock offset).
    time_offset : float
        The clock offset the measurements were paired with (motion capture minus camera).
    intrinsics_estimated : bool
        The intrinsics are estimated with the rig (a start only): not a cause to test.
    """

    name: str
    A: F64
    B: F64
    T_world_mocap: F64
    stamps: F64 | None = None
    intrinsics: Intrinsics | None = None
    object_points: tuple | None = None
    image_points: tuple | None = None
    rms_px: F64 | None = None
    mocap_stamps: F64 | None = None
    mocap_T: F64 | None = None
    time_offset: float = 0.0
    intrinsics_estimated: bool = False

    @property
    def has_points(self) -> bool:
        return (self.intrinsics is not None and self.image_points is not None
                and self.object_points is not None and len(self.image_points) == len(self.A))

    @cached_property
    def pnp_unit_covariance(self) -> F64:
        """``(J^T J)^-1`` of every PnP pose at unit pixel noise (:func:`pnp_information`),
        (n, 6, 6), infinite where undetermined; computed once, however many noise levels
        the checks weigh the poses with (requires :attr:`has_points`)."""
        return _inverse_or_infinite(pnp_information(g.inv(self.B), self.object_points,
                                                    self.intrinsics))


# --------------------------------------------------------------------------- noise and fits


def pnp_information(T_cam_target: F64, object_points: Sequence[F64], intr: Intrinsics) -> F64:
    """``J^T J`` of every PnP pose at unit pixel noise, under the left perturbation
    ``T = Exp(phi, tau) T_hat`` in the camera frame (rotation vector, then translation), to
    first order from the point geometry (pinhole approximation).

    Parameters
    ----------
    T_cam_target : ndarray, shape (n, 4, 4)
    object_points : sequence of n ndarray, shape (n_i, 3)
        Each pose's target points, metres in the target frame.
    intr : Intrinsics
        Its focal lengths are used.

    Returns
    -------
    ndarray, shape (n, 6, 6)
        Per pose, the sum over its points of ``J_k^T J_k`` with
        ``J_k = d(pixel)/d(p) [-[p]x | I]`` (2 x 6), all the poses at once on points padded
        to the longest pose (padding rows are zero).
    """
    n = len(T_cam_target)
    counts = np.array([len(o) for o in object_points], dtype=int)
    longest = int(counts.max(initial=0))
    real = np.arange(longest) < counts[:, None]                              # (n, longest)
    obj = np.zeros((n, longest, 3))
    if n and longest:
        obj[real] = np.concatenate([np.asarray(o, dtype=np.float64).reshape(-1, 3)
                                    for o in object_points])
    p = obj @ np.swapaxes(T_cam_target[:, :3, :3], 1, 2) + T_cam_target[:, None, :3, 3]
    z = np.maximum(p[..., 2], 1e-9)
    fx, fy = intr.K[0, 0], intr.K[1, 1]
    zero = np.zeros_like(z)
    J = np.empty((n, longest, 2, 6))
    J[:, :, 0, 3:] = np.stack([fx / z, zero, -fx * p[..., 0] / z ** 2], axis=-1)   # d u / d p
    J[:, :, 1, 3:] = np.stack([zero, fy / z, -fy * p[..., 1] / z ** 2], axis=-1)   # d v / d p
    J[:, :, :, :3] = -np.cross(J[:, :, :, 3:], p[:, :, None, :])
    J *= real[:, :, None, None]
    J = J.reshape(n, 2 * longest, 6)
    return np.swapaxes(J, 1, 2) @ J


def _pnp_covariances(cam: CameraEvidence, rms_px: F64) -> F64:
    """Covariance (n, 6, 6) of every PnP pose of ``cam`` (:func:`pnp_information`) for the
    reprojection RMS ``rms_px`` of each (pixels, at least :data:`MIN_RMS_PX`); a pose
    whose information is singular gets infinite variances."""
    unit = cam.pnp_unit_covariance
    n_pts = np.array([len(o) for o in cam.object_points], dtype=float)
    sigma2 = (np.maximum(rms_px, MIN_RMS_PX) ** 2 / 2.0
              * (2 * n_pts / np.maximum(2 * n_pts - 6, 1)))
    return sigma2[:, None, None] * unit


def _inverse_or_infinite(info: F64) -> F64:
    """Inverses of (n, 6, 6) information matrices; infinite variances for a singular one."""
    try:
        return np.linalg.inv(info)
    except np.linalg.LinAlgError:
        out = np.empty_like(info)
        for i, m in enumerate(info):
            try:
                out[i] = np.linalg.inv(m)
            except np.linalg.LinAlgError:
                out[i] = np.diag(np.full(6, np.inf))
        return out


def noise(cam: CameraEvidence, mocap_sigma: tuple[float, float], rms_px: F64 | None = None
          ) -> F64:
    """Per measurement, the information matrix (6, 6) of the residual of
    :func:`loop_residuals`: the inverse of the PnP covariance plus the motion-capture noise.

    ``rms_px`` (n,) replaces the camera's reprojection RMS in the PnP covariance (the point
    geometry, :attr:`CameraEvidence.pnp_unit_covariance`, is computed once per camera)."""
    n = len(cam.A)
    T_ct = g.inv(cam.B)
    if cam.has_points:
        if rms_px is None:
            rms_px = cam.rms_px if cam.rms_px is not None else np.full(n, MIN_RMS_PX)
        C = _pnp_covariances(cam, np.asarray(rms_px, dtype=np.float64))
    else:
        C = np.tile(np.diag([_POSE_NOISE[0] ** 2] * 3 + [_POSE_NOISE[1] ** 2] * 3), (n, 1, 1))
    sr, st = mocap_sigma
    lever2 = np.sum(T_ct[:, :3, 3] ** 2, axis=1)        # target origin from the camera
    C[:, :3, :3] += sr ** 2 * np.eye(3)
    C[:, 3:, 3:] += (st ** 2 + sr ** 2 * lever2)[:, None, None] * np.eye(3)
    with np.errstate(all="ignore"):
        W = np.linalg.pinv(C, hermitian=True)
    return np.where(np.isfinite(W), W, 0.0)


def loop_residuals(A: F64, B: F64, X: F64, Y: F64) -> F64:
    """The predicted target pose ``inv(X) inv(A_i) Y`` against the measured ``inv(B_i)`` as
    a left perturbation in the camera frame: (n, 6), rotation vector then translation."""

    pred = g.inv(X) @ g.inv(A) @ Y
    meas = g.inv(B)
    dR = pred[:, :3, :3] @ np.swapaxes(meas[:, :3, :3], 1, 2)
    phi = g.rotvec_from_transform(dR)
    tau = pred[:, :3, 3] - np.einsum("nij,nj->ni", dR, meas[:, :3, 3])
    return np.concatenate([phi, tau], axis=1)


@dataclass(frozen=True)
class Fit:
    """A closed-form fit: X (m, 4, 4), Y, per camera the weighted squared residual of every
    measurement (``e2``), the cost over all and per camera."""

    X: F64
    Y: F64
    e2: tuple
    cost: float
    camera_cost: tuple


def _cost(e2: F64) -> float:
    """About 1 when the weighted squares are the noise's (module docstring)."""
    e2 = e2[np.isfinite(e2)] if np.any(np.isfinite(e2)) else np.array([np.inf])
    return float(np.sqrt(np.median(e2) / _MEDIAN_E2))


def _e2(A, B, X, Y, W) -> F64:
    with np.errstate(all="ignore"):
        r = loop_residuals(A, B, X, Y)
        e2 = np.einsum("ni,nij,nj->n", r, W, r)
    return np.where(np.isfinite(e2), e2, np.inf)


def fit(A: Sequence[F64], B: Sequence[F64], weights: Sequence[F64]) -> Fit:
    """Closed form of ``A[j]``, ``B[j]`` per camera, outliers trimmed once, and the weighted
    residuals of every measurement (``weights[j]``: :func:`noise` of camera j)."""
    keep = [np.ones(len(a), dtype=bool) for a in A]
    for _ in range(2):
        try:
            with np.errstate(all="ignore"):
                X, Y = solve_joint(Measurements.from_cameras([a[k] for a, k in zip(A, keep)],
                                                             [b[k] for b, k in zip(B, keep)]))
        except (CalibrationError, np.linalg.LinAlgError, ValueError):
            inf = tuple(np.full(len(a), np.inf) for a in A)
            return Fit(np.tile(np.eye(4), (len(A), 1, 1)), np.eye(4), inf, math.inf,
                       tuple(math.inf for _ in A))
        with np.errstate(all="ignore"):
            e2 = [_e2(a, b, X[j], Y, nz) for j, (a, b, nz) in enumerate(zip(A, B, weights))]
        limit = _TRIM ** 2 * np.median(np.concatenate(e2))
        keep = []
        for e in e2:
            k = e <= limit
            if k.sum() < 3:
                k = np.zeros(len(e), dtype=bool)
                k[np.argsort(e)[:3]] = True
            keep.append(k)
    return Fit(X, Y, tuple(e2), _cost(np.concatenate(e2)), tuple(_cost(e) for e in e2))


# --------------------------------------------------------------------------- hypotheses


def mocap_A(setup: str, T_world_mocap: F64) -> F64:
    """A from the motion capture (docs/conventions.md, section 2)."""
    return T_world_mocap if setup == "eye-on-hand" else g.inv(T_world_mocap)


def scaled_A(A: F64, k: float) -> F64:
    """A with its translations times ``k`` (the motion capture in another unit)."""
    out = A.copy()
    out[:, :3, 3] *= k
    return out


def scale_factor(A: Sequence[F64], B: Sequence[F64], base: Fit) -> tuple[float, float]:
    """``k`` of ``R_A t_X + k t_A - t_Y = R_Y t_B`` by least squares over the measurements
    the base fit kept, with its rotations; returns ``k`` and its standard deviation."""
    m = len(A)
    rows, rhs = [], []
    limit = _TRIM ** 2 * np.median(np.concatenate(base.e2))
    for j, (a, b, e) in enumerate(zip(A, B, base.e2)):
        a, b = a[e <= limit], b[e <= limit]
        M = np.zeros((len(a), 3, 3 * m + 4))
        M[:, :, 3 * j:3 * j + 3] = a[:, :3, :3]
        M[:, :, 3 * m:3 * m + 3] = -np.eye(3)
        M[:, :, -1] = a[:, :3, 3]
        rows.append(M.reshape(-1, 3 * m + 4))
        rhs.append((b[:, :3, 3] @ base.Y[:3, :3].T).reshape(-1))
    M, r = np.concatenate(rows), np.concatenate(rhs)
    col = np.linalg.norm(M, axis=0)
    col[col == 0] = 1.0
    Ms = M / col
    for _ in range(2):
        sol, *_ = np.linalg.lstsq(Ms, r, rcond=None)
        res = (Ms @ sol - r).reshape(-1, 3)
        norm = np.linalg.norm(res, axis=1)
        keep = np.repeat(norm <= _TRIM * np.median(norm) + 1e-300, 3)
        if keep.all() or keep.sum() < Ms.shape[1] + 3:
            break
        Ms, r = Ms[keep], r[keep]
    dof = max(len(r) - Ms.shape[1], 1)
    s2 = float(np.sum((Ms @ sol - r) ** 2)) / dof
    try:
        var = s2 * np.linalg.inv(Ms.T @ Ms)[-1, -1]
    except np.linalg.LinAlgError:
        return float("nan"), float("inf")
    return float(sol[-1] / col[-1]), float(np.sqrt(max(var, 0.0)) / col[-1])


def permuted(T: F64, order: Sequence[int]) -> F64:
    """Poses with their quaternions' components (x y z w) taken in another order."""
    q = g.quat_from_transform(T)
    return g.transform_from_quat(q[:, list(order)], T[:, :3, 3])


def other_rotations(rotation: str) -> tuple[str, ...]:
    """The rotation conventions a file read as ``rotation`` (rig.yaml's ``mocap.rotation``:
    ``euler-<axes>-<unit>`` or ``rotvec``) is re-read in by :func:`reread_rotations`: Euler
    angles about moving instead of fixed axes (``xyz`` <-> ``XYZ``, the sequence's letters
    and so each angle's axis kept), radians read as degrees; a rotation vector read as the
    angles about x, y and z of the common robot conventions.  ``()`` for other rotations."""
    if rotation == "rotvec":     # angles named by axis: ZYX is xyz, zyx is XYZ
        return ("euler-xyz-rad", "euler-XYZ-rad")
    if not rotation.startswith("euler-"):
        return ()
    _, axes, unit = rotation.split("-")
    return (f"euler-{axes.swapcase()}-{unit}",) + (("euler-" + axes + "-rad",) if unit == "deg"
                                                   else ())


def _angles_by_axis(rotation: str, R: F64) -> dict[str, F64]:
    """The numbers a file read as ``rotation`` held for the rotations ``R`` (n, 3, 3), by the
    axis they turn about (``x``, ``y``, ``z``; a rotation vector's components), or in the
    order of the Euler sequence (``1``, ``2``, ``3``) when the axes repeat one."""
    from scipy.spatial.transform import Rotation  # noqa: PLC0415 (only when a rotation is doubted)

    if rotation == "rotvec":
        v = Rotation.from_matrix(R).as_rotvec()
        return dict(zip("xyz", v.T))
    _, axes, unit = rotation.split("-")
    import warnings  # noqa: PLC0415 (gimbal lock of single poses is no error here)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        v = Rotation.from_matrix(R).as_euler(axes, degrees=unit == "deg")
    keys = axes.lower() if sorted(axes.lower()) == ["x", "y", "z"] else "123"
    return dict(zip(keys, v.T))


def reread_rotations(T: F64, rotation: str, other: str, inverse: bool) -> F64:
    """Poses ``T`` (n, 4, 4) read as ``rotation`` with their file's numbers read as ``other``
    instead (:func:`other_rotations`), the translations kept; ``inverse``: the file held the
    inverse poses (``T_<tracked>_<fixed>``), so its rotations are those of ``inv(T)``."""
    from scipy.spatial.transform import Rotation  # noqa: PLC0415 (only when a rotation is doubted)

    F = g.inv(T) if inverse else T
    by_axis = _angles_by_axis(rotation, F[:, :3, :3])
    _, axes, unit = other.split("-")
    keys = axes.lower() if set(by_axis) == set("xyz") else "123"
    angles = np.stack([by_axis[k] for k in keys], axis=1)
    out = F.copy()       # the numbers as the file held them (degrees read as radians too)
    out[:, :3, :3] = Rotation.from_euler(axes, angles, degrees=unit == "deg").as_matrix()
    return g.inv(out) if inverse else out


#: Quaternion orders tried: the file holds w x y z but was read as x y z w, and the reverse.
QUATERNION_ORDERS = (((1, 2, 3, 0), "w x y z (scalar first) where x y z w (scalar last) was "
                                    "expected"),
                     ((3, 0, 1, 2), "x y z w (scalar last) where w x y z (scalar first) was "
                                    "expected"))


def _pnp_poses(cam: CameraEvidence, intr: Intrinsics) -> F64 | None:
    """T_cam_target of every measurement by PnP with other intrinsics (None if one fails)."""
    from multieye.imaging.detect import Detection  # noqa: PLC0415 (heavy: OpenCV, only when the lens is doubted)
    from multieye.imaging.pnp import estimate_pose  # noqa: PLC0415 (heavy: OpenCV, only when the lens is doubted)

    out = []
    for obj, img in zip(cam.object_points, cam.image_points):
        det = Detection(ids=np.arange(len(obj)), image_points=np.asarray(img, dtype=np.float64),
                        object_points=np.asarray(obj, dtype=np.float64))
        try:
            out.append(estimate_pose(det, intr).T_cam_target)
        except Exception:   # noqa: BLE001 - PnP failing under a wrong hypothesis is an answer
            return None
    return np.stack(out)


def _scaled_intrinsics(intr: Intrinsics, focal: float = 1.0, image: float = 1.0) -> Intrinsics:
    """The focal length times ``focal``; the camera matrix of images resized by ``image``."""
    K = intr.K.copy()
    K[0, 0] *= focal * image
    K[1, 1] *= focal * image
    K[0, 1] *= focal * image
    K[:2, 2] = (K[:2, 2] + 0.5) * image - 0.5
    return Intrinsics(K=K, dist=intr.dist, model=intr.model)


def cost_with(cam: CameraEvidence, T_cam_target: F64, noise: F64) -> float:
    """Cost of the camera alone with other target poses."""
    return fit([cam.A], [g.inv(T_cam_target)], [noise]).cost


def focal_search(cam: CameraEvidence, noise: F64) -> tuple[float, float, float] | None:
    """Focal-length factor that fits best: (factor, cost at 1, cost at the factor).

    PnP runs at factors 1 and 1.02; the poses in between and beyond are extrapolated on the
    group (``Exp(u xi) T(1)``), the factor minimising the closed form's cost is found on that
    model and PnP confirms it."""
    base = _pnp_poses(cam, cam.intrinsics)
    step = 1.02
    moved = _pnp_poses(cam, _scaled_intrinsics(cam.intrinsics, focal=step))
    if base is None or moved is None:
        return None
    xi = _log(moved @ g.inv(base)) / math.log(step)

    def model_cost(log_k: float) -> float:
        return cost_with(cam, _exp(log_k * xi) @ base, noise)

    grid = np.linspace(math.log(0.7), math.log(1.4), 29)
    costs = [model_cost(v) for v in grid]
    i = int(np.argmin(costs))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    for _ in range(20):                          # golden section
        a, b = hi - 0.618 * (hi - lo), lo + 0.618 * (hi - lo)
        if model_cost(a) < model_cost(b):
            hi = b
        else:
            lo = a
    factor = math.exp(0.5 * (lo + hi))
    poses = _pnp_poses(cam, _scaled_intrinsics(cam.intrinsics, focal=factor))
    if poses is None:
        return None
    return factor, cost_with(cam, base, noise), cost_with(cam, poses, noise)


def _log(T: F64) -> F64:
    """Twists (rotation vector, translation) of transforms near the identity."""

    return np.concatenate([g.rotvec_from_transform(T), T[:, :3, 3]], axis=1)


def _exp(xi: F64) -> F64:
    return g.transform_from_rotvec(xi[:, :3], xi[:, 3:])


def resize_search(cam: CameraEvidence, noise: F64) -> tuple[float, float, float] | None:
    """Image resize factor of :data:`RESIZE_FACTORS` that fits best, with the camera matrix
    scaled by it: (factor, cost at 1, cost at the factor), PnP run again for each."""
    base = _pnp_poses(cam, cam.intrinsics)
    if base is None:
        return None
    best = None
    for r in RESIZE_FACTORS:
        poses = _pnp_poses(cam, _scaled_intrinsics(cam.intrinsics, image=r))
        if poses is None:
            continue
        c = cost_with(cam, poses, noise)
        if best is None or c < best[1]:
            best = (r, c)
    if best is None:
        return None
    return best[0], cost_with(cam, base, noise), best[1]


def clock_search(setup: str, cam: CameraEvidence, noise: F64, max_offset_s: float
                 ) -> tuple[float, float, float, float] | None:
    """Clock offset that fits best (:func:`multieye.estimate.clock.estimate_offset`, searched
    ``max_offset_s`` either side of the one used): (offset, its standard deviation, cost at
    the offset used, cost at the new one), on the images paired at both; None when the
    offset cannot be estimated (too few images, motion capture sparser than the images or
    not a continuous motion, pose pairs recorded together, a weak correlation, an optimum at
    the edge of the search)."""

    if cam.stamps is None or cam.mocap_stamps is None or len(cam.stamps) < 10:
        return None
    dt_img = float(np.median(np.diff(cam.stamps)))
    dt_m = float(np.median(np.diff(cam.mocap_stamps)))
    if not dt_m <= 2.0 * dt_img:
        return None                       # motion capture too sparse to time the images
    step = chordal_angle(cam.mocap_T[:-1], cam.mocap_T[1:])
    if not np.median(step) < _MAX_MOCAP_STEP_RAD:
        return None                       # not a continuous trajectory: poses one by one
    q = cam.stamps + cam.time_offset
    right = np.clip(np.searchsorted(cam.mocap_stamps, q), 1, len(cam.mocap_stamps) - 1)
    gap = np.minimum(np.abs(cam.mocap_stamps[right] - q), np.abs(cam.mocap_stamps[right - 1] - q))
    if dt_m >= 0.5 * dt_img and np.mean(gap <= 1e-3 * dt_m) > 0.5:
        return None                       # one pose per image, recorded together: no clock
    T_ct = g.inv(cam.B)
    lo, hi = cam.time_offset - max_offset_s, cam.time_offset + max_offset_s
    try:
        est = estimate_offset(cam.stamps, T_ct, cam.mocap_stamps, cam.mocap_T, setup=setup,
                              search_s=(lo, hi))
    except CalibrationError:
        return None
    edge = 0.02 * (hi - lo)
    if not (est.score >= _MIN_CLOCK_SCORE and lo + edge < est.offset_s < hi - edge) or est.note:
        return None                       # (note: no loop-residual minimum near the peak)
    tol = 2.5 * dt_m
    at = [pair_in_time(cam.mocap_stamps, cam.mocap_T, cam.stamps, tolerance=tol, offset=o)
          for o in (cam.time_offset, est.offset_s)]
    common = np.intersect1d(at[0].index, at[1].index)
    if common.size < 6:
        return None
    sub = noise[common]
    costs = []
    for p in at:
        T = p.T[np.searchsorted(p.index, common)]
        costs.append(fit([mocap_A(setup, T)], [cam.B[common]], [sub]).cost)
    return est.offset_s, est.std_s, costs[0], costs[1]
