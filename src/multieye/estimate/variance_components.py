"""Variance components of the image refinement: the pixel and motion-capture noise from the
residuals at an optimum (Förstner's estimate), and the step that brings them to their fixed
point in few passes.

Each group of residuals ``k`` (the pixels; the motion capture's rotation components; its
position components) gets

    sigma_k^2  <-  sigma_k^2 * sum(w z_k^2) / (c_w r_k)

with ``z_k`` its residuals normalised by the current ``sigma_k`` (one prior per instant: a
measurement shared by several images counts once), ``w`` the robust loss's IRLS weights,
``c_w = E[w x^2]`` for a standard normal ``x`` and ``r_k`` the group's redundancy: its count of
residuals minus the share of the parameters it pays for, ``tr(J_k Cov J_k^T)`` at the optimum.
Unlike the RMS of the corrections, which shrinks with the sigma that produced them and so
collapses to zero when the pixels cannot contradict the poses, this is the restricted-likelihood
fixed point.

The split into *sums* (from the residuals alone: free after any evaluation) and *redundancies*
(from the covariance: one linearisation and the marginal covariance) is what makes the passes
cheap: the redundancies move by a fraction of a percent between passes (on the 4 x 100 rendered
rig of ``benchmarks/bench_peers.py``: 0.3 % of the pixels', 2 % of the priors'), so a pass
between two covariances only needs the sums at its end.  The fixed-point map ``s -> estimate(s)``
contracts by a constant factor (0.2 on that rig); :func:`secant` extrapolates two of its steps
to the fixed point.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core.robust_loss import rho
from multieye.estimate.image_data import ImageData
from multieye.estimate.image_residuals import DenominatorPrior
from multieye.estimate.uncertainty import MOCAP_SIGMA_FLOOR

__all__ = ["Sums", "Redundancy", "weighted_sums", "redundancy", "estimate", "secant",
           "image_noise", "clock_noise", "IMAGE_PSEUDO_COUNT",
           "is_prior", "MIN_REDUNDANCY", "SETTLED", "MOCAP_SETTLED", "FINAL_SHARE", "STALE",
           "EXTRAPOLATED", "prior_residuals", "pixel_residuals"]

F64 = NDArray[np.float64]

#: Smallest redundancy a variance component is divided by (a component the data barely
#: determine is then not blown up).
MIN_REDUNDANCY = 0.5

#: Relative change of the noise estimates (pixels; the motion capture's) at which their fixed
#: point counts as reached: the passes between the first and the last run until then.
SETTLED = 0.01
MOCAP_SETTLED = 0.1
#: The last pass's estimate is accepted within this share of those (0.1 % for the pixels, 1 %
#: for the motion capture), else another last pass follows.  The former scheme ended one
#: contraction step inside them; on benchmarks/bench_mocap_noise.py's 4 x 40 mocap rig (40
#: rigs, medians) a whole share left the motion capture's estimate 3-6 % above that scheme's,
#: a quarter 1-3 %, a tenth 1-2 % (estimate / truth 1.02 and 1.02 against 1.01 and 1.00).
FINAL_SHARE = 0.1
#: The redundancies are taken again from a covariance at the end of a pass whose sigmas are
#: more than this far (log ratio, about 10 %) from those they were taken at (the priors' share
#: of the parameters moves with the ratio of the sigmas).
STALE = float(np.log(1.1))
#: An estimate extrapolated to the fixed point (:func:`secant`) from a step that moved the
#: sigmas by less than this many settled shares goes to the last pass at once (whose
#: covariance checks it: on the rendered 4 x 100 rig the extrapolation from a 1.5 % step
#: landed within 0.05 % of the fixed point).
EXTRAPOLATED = 5.0

#: Range of the slope of the fixed-point map (per component, in log sigma) within which
#: :func:`secant` extrapolates (its step then at most 3x the plain one); outside it (two steps
#: that do not look like one contraction) the plain estimate is taken.
_SLOPES = (0.0, 2.0 / 3.0)


#: Residual components of the images' mean (logarithmic) pixel noise that an image's own
#: estimate is drawn towards (:func:`image_noise`): an image of 4 corners (8 components)
#: keeps 4/5 of its own log variance, one of 54 corners 98 %.
IMAGE_PSEUDO_COUNT = 2.0


def clock_noise(data: ImageData) -> tuple[float, float]:
    """Motion-capture sample noise (radians, metres) pooled over the clock windows' fit
    residuals (cameras whose clock offset is estimated)."""
    trajs = data.units.trajectories
    w = np.array([len(t.h) * t.dof for t in trajs], dtype=float)
    rot, tr = np.array([t.noise() for t in trajs]).T
    return (max(float(np.sqrt(w @ rot ** 2 / w.sum())), MOCAP_SIGMA_FLOOR),
            max(float(np.sqrt(w @ tr ** 2 / w.sum())), MOCAP_SIGMA_FLOOR))


def is_prior(group) -> bool:
    """A group of motion-capture priors (one row of 6 per instant, touching ``M`` first)."""
    return group.slots[0] == "M"


@dataclass(frozen=True)
class Sums:
    """Robust sums of squared normalised residuals at a point: ``sum(w z^2)``.

    Attributes
    ----------
    pixels : float
        Over every residual that is not a motion-capture prior (pixels, in units of the pixel
        sigma of the groups they were evaluated with).
    rotation, position : float
        Over the priors' rotation (first 3) and position (last 3) components.
    n_pixels : int
        Count of those pixel residual components.
    """

    pixels: float
    rotation: float
    position: float
    n_pixels: int


@dataclass(frozen=True)
class Redundancy:
    """Redundancies of the three components at an optimum (their counts minus the share of
    the parameters they pay for).

    Attributes
    ----------
    pixels, rotation, position : float
    """

    pixels: float
    rotation: float
    position: float


def weighted_sums(groups: Sequence, evaluated: Sequence, loss: str, f_scale: float) -> Sums:
    """:class:`Sums` of the residuals ``evaluated`` (each group's ``(residuals (n, dim), ...)``
    as :func:`multieye.optimize.levenberg_marquardt.evaluate` gives them) of ``groups``."""
    prior = np.zeros(2)
    pixels = []
    for grp, e in zip(groups, evaluated):
        if isinstance(grp, DenominatorPrior):
            continue                             # a prior of fixed scale, not measured noise
        if is_prior(grp):
            w = rho((e[0] / f_scale) ** 2, loss)[1]
            prior[0] += float(np.sum(w[:, :3] * e[0][:, :3] ** 2))
            prior[1] += float(np.sum(w[:, 3:] * e[0][:, 3:] ** 2))
        else:
            pixels.append(e[0].ravel())
    z = np.concatenate(pixels)
    w = rho((z / f_scale) ** 2, loss)[1]
    return Sums(float(w @ z ** 2), float(prior[0]), float(prior[1]), int(z.size))


def redundancy(data: ImageData, fams, groups: Sequence, cov, n_pixels: int) -> Redundancy:
    """:class:`Redundancy` at the families ``fams`` from their covariance ``cov``
    (:class:`multieye.optimize.levenberg_marquardt.Covariance` with the marginal covariance of
    every motion-capture pose, ``local``): per prior row ``h = diag(J_p Cov_M J_p^T)``, its
    share of the parameters; the pixels pay for the rest of them.

    Parameters
    ----------
    data : ImageData
    fams : sequence of Blocks
    groups : sequence of ResidualGroup
        ``data.groups(...)`` at the sigmas ``cov`` was taken with.
    cov : Covariance
    n_pixels : int
        Count of the pixel residual components (:attr:`Sums.n_pixels`).
    """
    values = {f.name: f.value for f in fams}
    h_prior = 0.0
    red = np.zeros(2)
    for grp in groups:
        if isinstance(grp, DenominatorPrior):     # the parameters the lens prior pays for
            Jk = grp.evaluate(values, True)[1][0][0]                      # (3, n_K)
            at = cov.layout.offset[grp.slots[0]]
            C = cov.kept[at:at + Jk.shape[1], at:at + Jk.shape[1]]
            h_prior += float(np.trace(Jk @ C @ Jk.T))
        if is_prior(grp):
            Jp = grp.evaluate(values, True)[1][0]                         # d r / d M, (n, 6, 6)
            h = np.einsum("nki,nij,nkj->nk", Jp, cov.local[grp.index[:, 0]], Jp)   # (n, 6)
            h_prior += float(h.sum())
            red[0] += float(np.sum(1.0 - h[:, :3]))
            red[1] += float(np.sum(1.0 - h[:, 3:]))
    n_params = cov.layout.k + 6 * cov.layout.n_local
    return Redundancy(n_pixels - (n_params - h_prior), float(red[0]), float(red[1]))


def estimate(sigmas: F64, sums: Sums, red: Redundancy, c_w: float) -> F64:
    """The variance-component estimates (module docstring) of ``sigmas`` = (pixels, radians,
    metres) from the sums and redundancies at the optimum they were solved with."""
    s_px, s_rot, s_t = (float(v) for v in sigmas)
    new_px = s_px * np.sqrt(sums.pixels / (c_w * max(red.pixels, 1.0)))
    new_rot, new_t = (max(s * np.sqrt(q / (c_w * max(r, MIN_REDUNDANCY))), MOCAP_SIGMA_FLOOR)
                      for s, q, r in ((s_rot, sums.rotation, red.rotation),
                                      (s_t, sums.position, red.position)))
    return np.array([new_px, new_rot, new_t])


def secant(used: F64, estimated: F64, previous: tuple[F64, F64] | None,
           free: NDArray[np.bool_]) -> tuple[F64, bool]:
    """The next sigmas: the fixed point of the map ``used -> estimated`` extrapolated from this
    step and the ``previous`` one (``(used, estimated)``), per component in log sigma, where
    the two steps look like one contraction (slope within :data:`_SLOPES`); else
    ``estimated``.  The components not ``free`` stay ``used``; the motion capture's free ones
    at least :data:`~multieye.estimate.uncertainty.MOCAP_SIGMA_FLOOR`.

    Parameters
    ----------
    used, estimated : ndarray, shape (3,)
        The sigmas a pass was solved with and their estimate at its optimum.
    previous : (ndarray, ndarray) or None
        The same of the pass before.
    free : ndarray of bool, shape (3,)
        The components being estimated.

    Returns
    -------
    sigmas : ndarray, shape (3,)
    extrapolated : bool
        Whether every free component was extrapolated.
    """
    out = np.where(free, estimated, used).astype(np.float64)
    floor = free & (np.arange(3) > 0)
    out[floor] = np.maximum(out[floor], MOCAP_SIGMA_FLOOR)
    if previous is None:
        return out, False
    x1, y1 = np.log(previous[0]), np.log(previous[1])
    x2, y2 = np.log(used), np.log(estimated)
    extrapolated = True
    for i in np.flatnonzero(free):
        dx = x2[i] - x1[i]
        slope = (y2[i] - y1[i]) / dx if abs(dx) > 1e-12 else np.nan
        if _SLOPES[0] <= slope <= _SLOPES[1]:
            # y = y2 + slope (x - x2) meets y = x at x2 + (y2 - x2) / (1 - slope)
            out[i] = np.exp(x2[i] + (y2[i] - x2[i]) / (1.0 - slope))
        else:
            extrapolated = False
    out[floor] = np.maximum(out[floor], MOCAP_SIGMA_FLOOR)
    return out, extrapolated


def image_noise(data: ImageData, evaluated: Sequence, red: Redundancy, n_pixels: int,
                loss: str, f_scale: float, c_w: float) -> F64:
    """Each motion-captured image's pixel noise over the pooled one, estimated from its own
    residuals: rendered and real images differ in how well their corners are found (blur,
    obliquity, distance), and one sigma for all of them counts the good images as noisy as
    the average and so makes the covariance too large where they carry the information
    (issue 32: on rendered 3 x 40 rigs with the lenses estimated, squared error over
    predicted variance 0.83 / 0.59 in rotation / translation with one sigma, 0.95 / 0.85
    with one per image).

    Image i's variance component over its redundancy ``r_i = n_i red.pixels / n_pixels``
    (its count's share of the pixels' redundancy), its logarithm drawn towards the images'
    mean logarithm by :data:`IMAGE_PSEUDO_COUNT` components (in logarithms: images whose
    noise differs tenfold are not pulled to the noisiest ones' level); the factors are then scaled to a root mean square
    of 1 over the points (the pooled sigma, :func:`estimate`'s, keeps its meaning).

    Parameters
    ----------
    data : ImageData
        With the factors ``evaluated`` was normalised with (``data.image_noise``).
    evaluated : sequence
        The groups' ``(residuals, ...)``; the first ``data.m`` are the cameras' pixels.
    red : Redundancy
    n_pixels : int
        Count of all pixel residual components (:attr:`Sums.n_pixels`).
    loss, f_scale, c_w
        The robust loss, its threshold and ``E[w x^2]`` (module docstring).

    Returns
    -------
    ndarray, shape (N,)
        Each image's noise over the pooled sigma.
    """
    z = np.concatenate([e[0] for e in evaluated[:data.m]])                 # (P, 2)
    w = rho((z / f_scale) ** 2, loss)[1]
    q = np.add.reduceat(np.sum(w * z ** 2, axis=1), data.image_starts) / c_w
    n = 2.0 * np.diff(np.append(data.image_starts, data.n_points))
    r = n * max(red.pixels, 1.0) / n_pixels
    old = np.ones(data.n_images) if data.image_noise is None else data.image_noise
    own = np.log(np.maximum(q * old ** 2 / r, 1e-12 * np.sum(q * old ** 2) / np.sum(r)))
    pooled = float(r @ own / np.sum(r))            # log variances, in units of the sigma^2
    var = np.exp((r * own + IMAGE_PSEUDO_COUNT * pooled) / (r + IMAGE_PSEUDO_COUNT))
    return np.sqrt(var / (np.sum(n * var) / np.sum(n)))


def prior_residuals(data: ImageData, groups, ev) -> F64:
    """Normalised motion-capture prior residuals of every image, (N, 6): each image gets its
    instant's (the images sharing a measurement share its residual)."""
    out = np.zeros((data.n_instants, 6))
    for grp, e in zip(groups, ev):
        if is_prior(grp):
            out[grp.index[:, 0]] = e[0]
    return out[data.instant]


def pixel_residuals(data: ImageData, ev) -> F64:
    """Normalised pixel residuals of every motion-captured image's points, (P, 2)."""
    return np.concatenate([e[0] for e in ev[:data.m]])
