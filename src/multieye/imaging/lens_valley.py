"""Other optima along a wide-angle model's valley: lenses of nearly the same image (issue 33).

The unified model's ``xi`` trades against its focal length and ``k1``, ``k2``, and the double
sphere's ``xi`` against its focal length and ``alpha``: along that one direction the lenses'
images of the observed rays differ by hundredths of a pixel.  For the double sphere the
difference is not even monotone: on a lens of 190 or 220 degrees with ``xi = -0.15``,
``alpha = 0.6`` (:mod:`multieye.sim.wide_lens`) the lenses with ``xi`` near 0.2 and (190
degrees) 1.6, focal lengths 1.4 and 3 times the true one, fit the noise-free corners of 20
views to a sum of squares of 0.04-0.06 px^2 (an RMS of 0.005 px over 960 corners), with
barriers of 1.8-13 px^2 between: separate local optima, which a least-squares fit started
in one of them does not leave, and which 0.2 px of noise puts in either order.  A fit
started from a single lens therefore stops in the optimum nearest its start, not in the best
one.

:func:`valley_lenses` finds the lenses of a model's other optima along its valley parameter:
it walks that parameter from the fitted lens' value up and down (continuation: each step's
lens started from the previous step's), fits the model's other radial parameters so that the
rays at 0 to ``theta_max`` fall where the fitted lens puts them, and returns the lens at every
local minimum of that curve's mismatch within ``tol_px``; the caller fits the lens and poses
from each (the same rays, so the poses still hold) and keeps the best.

Synopsis
--------
>>> for lens in valley_lenses(fit.intrinsics, theta_max):           # doctest: +SKIP
...     candidates.append(fit_lens(views, lens, fit.T_cam_target))
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points

__all__ = ["valley_lenses", "VALLEY_STEP", "VALLEY_MODELS"]

F64 = NDArray[np.float64]

#: Per model: the index in ``dist`` of the valley parameter, its range walked, and the indices
#: in ``dist`` of the radial parameters fitted at each of its values (with the focal length).
_VALLEY = {"unified": (0, (0.0, 4.0), (1, 2)), "double-sphere": (0, (-0.8, 2.0), (1,))}
#: The models with such a valley.
VALLEY_MODELS = tuple(_VALLEY)
#: Step of the walk along the valley parameter.
VALLEY_STEP = 0.05
#: Pixel offset given to a ray a trial lens does not project.
_OUTSIDE_PX = 1e3


def _curve_fit(lens: Intrinsics, value: float, x0: F64, P: F64, want: F64):
    """The lens with the valley parameter at ``value`` whose rays ``P`` fall nearest ``want``
    (their x pixel): its focal lengths' common scale and radial parameters fitted from
    ``x0``; ``(x, rms_px, lens)``, rms inf when no such lens is valid."""
    from scipy.optimize import least_squares  # noqa: PLC0415 (heavy: SciPy)

    k, _, shape = _VALLEY[lens.model]
    p0 = lens.params

    def make(x):
        p = p0.copy()
        p[:2] *= x[0]
        p[4 + k] = value
        p[[4 + j for j in shape]] = x[1:]
        return lens.with_params(p)

    def residual(x):
        try:
            u = project_points(P, make(x))[:, 0]
        except InputError:
            return np.full(len(P), _OUTSIDE_PX)
        return np.where(np.isfinite(u), u - want, _OUTSIDE_PX)

    fit = least_squares(residual, x0, method="lm", x_scale="jac")
    rms = float(np.sqrt(np.mean(fit.fun ** 2)))
    try:
        return fit.x, rms, make(fit.x)
    except InputError:
        return fit.x, np.inf, None


def valley_lenses(lens: Intrinsics, theta_max: float, tol_px: float = 0.5
                  ) -> list[Intrinsics]:
    """The lenses of ``lens``' model at the other local optima of its valley (module doc).

    Parameters
    ----------
    lens : Intrinsics
        A fitted lens; a model without a valley (:data:`_VALLEY`: other than unified and
        double-sphere) gives none.
    theta_max : float
        Radians off the optical axis up to which the lens is observed.
    tol_px : float
        RMS, pixels, over 40 rays from 0.02 rad to ``theta_max`` along the image's x axis,
        within which another lens' curve must match the given one's.

    Returns
    -------
    list of Intrinsics
        One per local minimum of the mismatch along the valley parameter, other than the
        given lens' own (within two steps of it), best first.
    """
    if lens.model not in _VALLEY:
        return []
    k, (lo, hi), shape = _VALLEY[lens.model]
    theta = np.linspace(0.02, max(theta_max, 0.1), 40)
    P = np.column_stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)])
    want = project_points(P, lens)[:, 0]
    own = float(lens.dist[k])
    x_own = np.concatenate([[1.0], lens.dist[list(shape)]])
    values = np.arange(lo, hi + VALLEY_STEP / 2, VALLEY_STEP)
    rms = np.full(len(values), np.inf)
    lenses: list[Intrinsics | None] = [None] * len(values)
    start = int(np.argmin(np.abs(values - own)))
    for order in (range(start, len(values)), range(start - 1, -1, -1)):
        x = x_own
        for i in order:
            x_i, rms[i], lenses[i] = _curve_fit(lens, float(values[i]), x, P, want)
            if np.isfinite(rms[i]):
                x = x_i                       # continuation: the next step starts here
    padded = np.concatenate([[np.inf], rms, [np.inf]])
    minima = np.flatnonzero((padded[1:-1] <= padded[:-2]) & (padded[1:-1] < padded[2:])
                            & (padded[1:-1] <= tol_px))
    far = np.abs(values[minima] - own) > 2 * VALLEY_STEP
    return [lenses[i] for i in minima[far][np.argsort(rms[minima[far]])]]
