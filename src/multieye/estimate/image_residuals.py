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
- :class:`DenominatorPrior`: per estimated rational lens, its denominator coefficients
  k4..k6 drawn towards 0 (3 components), touching ``K:<camera>``.

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

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.geometry import skew
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, project_with_jacobian
from multieye.core.lie import left_jacobian_inv, log_so3
from multieye.optimize.blocks import ResidualGroup, SegmentRange

__all__ = ["PixelResiduals", "FreePoseResiduals", "MocapPriors", "intrinsics_family",
           "DenominatorPrior", "RATIONAL_DENOMINATOR", "DENOMINATOR_PRIOR", "rational_edge"]

F64 = NDArray[np.float64]


def cross_rows(a: F64, v: F64, out: F64 | None = None) -> F64:
    """Row-wise ``a x v`` for a (..., k, 3) against v (..., 3): ``a^T [v]_x`` per row
    (written into ``out``, shaped like ``a``, when given)."""
    v = v[..., None, :]
    if out is None:
        out = np.empty(np.broadcast_shapes(a.shape, v.shape))
    for i, (j, k) in enumerate(((1, 2), (2, 0), (0, 1))):
        np.subtract(a[..., j] * v[..., k], a[..., k] * v[..., j], out=out[..., i])
    return out


def intrinsics_family(name: str) -> str:
    """Block-family name of a camera's intrinsics when they are estimated."""
    return f"K:{name}"


def _pixels(pc: F64, intr: Intrinsics, with_jacobian: bool, lens: bool = True):
    """Pixels of camera-frame points and, when asked, d uv / d pc and (with ``lens``)
    d uv / d intrinsics."""
    if with_jacobian:
        return project_with_jacobian(pc, intr, lens_jacobian=lens)
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
        The pixel noise; an image's is ``sigma_px`` times its ``data.image_noise`` (when set).
    free_intrinsics : bool
        Estimate the camera's intrinsics (a slot of their own).
    """

    def __init__(self, data, camera: int, sigma_px: float,
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
        rel = getattr(data, "image_noise", None)
        # per point (P_j, 1): its image's noise
        self.sigma = float(sigma_px) * (np.ones((pts.stop - pts.start, 1)) if rel is None
                                        else rel[data.image[pts]][:, None])
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
        images = slice(*part.index_range)
        ry, py, q, d, pc = self._chain(X, Y, M, images)
        uv, Jp, Jk = _pixels(part.gather(pc), intr, True, self.free)
        sigma = self.sigma[part.rows]
        r = (uv - self._uv[part.rows]) / sigma
        n_img, n = len(self.blocks[images]), self.longest
        RX = X[self.camera, :3, :3]
        RM = M[self.blocks[images], :3, :3]
        G = RX.T @ (RM if self.data.setup == "eye-to-base" else RM.swapaxes(1, 2))
        flat = part.pad(Jp / sigma[:, :, None]).reshape(n_img, 2 * n, 3)
        JpR = (flat @ RX.T).reshape(n_img, n, 2, 3)                     # d r / d q
        JpG = (flat @ G).reshape(n_img, n, 2, 3)                        # d r / d p_y
        c = 18 + (Jk.shape[2] if self.free else 0)
        out = np.empty((n_img, n, 2, c))                                # (n_img, n, 2, c)
        # two row-wise cross products; the third differs from one of them by a constant
        # vector, a^T [v + t]_x = a^T [v]_x + a^T [t]_x (one matrix product)
        np.negative(JpR, out=out[..., 3:6])
        cross_rows(JpG, ry, out=out[..., 6:9])
        np.negative(out[..., 6:9], out=out[..., 6:9])
        out[..., 9:12] = JpG
        if self.data.setup == "eye-to-base":                 # p_y = R_Y p + t_Y
            cross_rows(JpR, d, out=out[..., 0:3])
            np.subtract(out[..., 6:9], (flat @ (G @ skew(Y[:3, 3]))).reshape(JpG.shape),
                        out=out[..., 12:15])
            out[..., 15:18] = JpR
        else:                                                # d = q - t_X
            cross_rows(JpR, q, out=out[..., 12:15])
            np.subtract(out[..., 12:15], (flat @ (RX.T @ skew(X[self.camera, :3, 3])))
                        .reshape(JpR.shape), out=out[..., 0:3])
            np.negative(JpG, out=out[..., 15:18])
        if self.free:
            out[..., 18:] = part.pad(Jk / sigma[:, :, None]).reshape(n_img, n, 2, -1)
        return r, out

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
        JT = np.concatenate([-cross_rows(Jp, rp[seg, pos]), Jp], axis=2)
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
    factors : array_like, shape (n,), optional
        Per prior, its noise over ``sigma_rot, sigma_t`` (a pose interpolated between two
        samples is less noisy than one); default 1.
    """

    def __init__(self, measured: F64, sigma_rot: float, sigma_t: float, blocks=None,
                 factors=None):
        blocks = np.arange(len(measured)) if blocks is None else np.asarray(blocks, int)
        super().__init__(("M",), blocks[:, None], np.arange(len(blocks)), 6)
        self.measured = measured[blocks]
        f = np.ones(len(blocks)) if factors is None else np.asarray(factors, float)
        self.scale = 1.0 / (np.repeat([float(sigma_rot), float(sigma_t)], 3) * f[:, None])

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        M, Mm = values["M"][self.index[:, 0]], self.measured
        r_rot = log_so3(np.swapaxes(Mm[:, :3, :3], 1, 2) @ M[:, :3, :3])
        r = np.concatenate([r_rot, M[:, :3, 3] - Mm[:, :3, 3]], axis=1) * self.scale
        if not jacobians:
            return r, None
        J = np.zeros((len(M), 6, 6))
        J[:, :3, :3] = left_jacobian_inv(-r_rot) * self.scale[:, :1, None]  # J_r^-1(r_rot)
        J[:, 3:, 3:] = np.eye(3) * self.scale[:, 3:4, None]
        return r, [J]


#: The rational lens model's denominator ``1 + k4 r^2 + k5 r^4 + k6 r^6`` (OpenCV's order of
#: :attr:`Intrinsics.dist`: k1 k2 p1 p2 k3 k4 k5 k6): positions of k4..k6 in ``params``.
RATIONAL_DENOMINATOR = (9, 10, 11)

#: Prior standard deviation of each denominator term ``k_i x_edge^i`` (``x_edge`` the
#: squared normalised radius of the image's corner): the denominator is drawn towards 1
#: (OpenCV's 5-coefficient lens), by at most a unit change of the distortion at the edge.
DENOMINATOR_PRIOR = 1.0


def rational_edge(intr: Intrinsics) -> float:
    """Squared normalised radius ``x_edge`` of the image's corner (pinhole, distortion
    ignored): the scale of :class:`DenominatorPrior`'s terms."""
    K = intr.K
    return float((0.5 * intr.width / K[0, 0]) ** 2 + (0.5 * intr.height / K[1, 1]) ** 2)


class DenominatorPrior(ResidualGroup):
    """A weak prior on a rational lens's denominator coefficients: 3 residuals
    ``k_i x_edge^i / DENOMINATOR_PRIOR`` (i = 1..3 for k4..k6), slot ``K:<camera>``.

    Over an image's field of view the rational model's numerator and denominator nearly
    share a factor: a family of coefficients (k1..k6 in the tens to thousands, issue 32's
    k1 -117, k2 3386 ...) fits the pixels equally, and the estimate lands anywhere along it,
    with near-cancelling poles and zeros inside the image where the linearised covariance
    does not hold (the principal point's standard deviation came out 0.01-0.07 px against
    0.15 on the same images elsewhere on the valley).  The prior picks the member with the
    smallest denominator, which costs the pixels nothing where they do not determine it and
    is negligible against them where they do.
    """

    def __init__(self, name: str, intr: Intrinsics):
        super().__init__((intrinsics_family(name),), [[0]], [0], 3)
        x = rational_edge(intr)
        self.scale = np.array([x, x ** 2, x ** 3]) / DENOMINATOR_PRIOR
        self.n_params = len(intr.params)

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        k = values[self.slots[0]][0][list(RATIONAL_DENOMINATOR)]
        r = (k * self.scale)[None]
        if not jacobians:
            return r, None
        J = np.zeros((1, 3, self.n_params))
        J[0, [0, 1, 2], list(RATIONAL_DENOMINATOR)] = self.scale
        return r, [J]
