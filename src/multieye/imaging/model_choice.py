"""Which lens model the views support: held-out reprojection by radius, per candidate model.

A lens model that does not fit the lens leaves residuals that grow towards the edge of the
image; the same views fitted with another model say whether it does better.  The criterion
is the reprojection of views the lens was not fitted on (k-fold cross-validation over the
views: each fold's views posed with the lens fitted on the others, the lens held), so that a
model with more parameters gains nothing by fitting the noise.  Another model is named
(:attr:`ModelComparison.better`) only when it is clearly better: its held-out RMS in the outer
quarter of the observed radii at most :data:`CLEARLY` times the requested model's and at
least :data:`MIN_GAIN_PX` lower, and lower overall too; or it projects more of the corners
seen (:data:`LOST_SHARE` of them: a fisheye lens cannot project rays beyond 90 degrees off its
axis) and fits them as well (issue 33).  The requested model is scored first: when it
projects every corner and leaves less than 0.2 px in its outer quarter, where no other model
can be clearly better by that rule, the others are not fitted.

Synopsis
--------
>>> cmp = compare_models(views, (640, 720), "fisheye")                  # doctest: +SKIP
>>> cmp.better, cmp.message("cam0")                                      # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import LENS_MODELS
from multieye.core.lens import project_points
from multieye.imaging.generic_start import LensFit, fit_lens, generic_start
from multieye.imaging.pnp import refit_poses

__all__ = ["ModelScore", "ModelComparison", "compare_models", "edge_rms", "may_be_beaten",
           "CANDIDATES",
           "PINHOLE_CANDIDATES", "CLEARLY", "MIN_GAIN_PX", "EDGE_BOUND_PX"]

F64 = NDArray[np.float64]

#: The models a fisheye or wide lens is compared in.
CANDIDATES = ("fisheye", "unified", "double-sphere", "eucm")
#: ... and a pinhole lens (the rational model first: a lens wider than radial-tangential
#: follows).
PINHOLE_CANDIDATES = ("pinhole-rational",) + CANDIDATES
#: Another model is clearly better when its outer held-out RMS is at most this share ...
CLEARLY = 0.75
#: ... and at least this many pixels below the requested model's.
MIN_GAIN_PX = 0.05
#: ... or projects more of the corners seen by this share of them (and fits as well).
LOST_SHARE = 0.02
#: A model that leaves less than this in the outer quarter of its radii cannot be clearly
#: beaten by the rule above (MIN_GAIN_PX / (1 - CLEARLY)), pixels.
EDGE_BOUND_PX = MIN_GAIN_PX / (1 - CLEARLY)
#: Views the comparison uses at most (spread over those given), and its folds.
MAX_VIEWS = 20
FOLDS = 4


@dataclass(frozen=True)
class ModelScore:
    """One model's held-out reprojection.

    Attributes
    ----------
    model : str
    rms_px : float
        Over every held-out point both compared sets share, pixels.
    outer_rms_px : float
        Over those beyond ``outer_from_px`` from the image centre (the outer quarter).
    by_radius : tuple of (float, float, float)
        ``(from_px, to_px, rms_px)`` per band of 100 px from the image centre.
    lost : int
        Held-out points the model does not project (a fisheye lens: beyond 90 degrees off
        its axis), of those some model projects.
    """

    model: str
    rms_px: float
    outer_rms_px: float
    by_radius: tuple[tuple[float, float, float], ...]
    lost: int = 0


@dataclass(frozen=True)
class ModelComparison:
    """The requested model against the others on the same views (module docstring).

    Attributes
    ----------
    requested : str
    scores : dict of str to ModelScore
        The models that could be fitted.
    outer_from_px : float
        Where the outer quarter of the observed radii starts, pixels from the centre.
    views : int
    better : str or None
        The clearly better model, if any.
    """

    requested: str
    scores: dict[str, ModelScore]
    outer_from_px: float
    views: int
    better: str | None

    def message(self, camera: str) -> str | None:
        """The warning that names the better model with the figures, or None."""
        if self.better is None:
            return None
        a, b = self.scores[self.requested], self.scores[self.better]
        if a.lost > b.lost:
            return (f"{camera}: the {self.requested} lens model leaves {a.lost} of the corners "
                    "seen without a projection (beyond 90 degrees off its axis, or in views it "
                    f"cannot pose because of such points); {self.better} projects "
                    f"{a.lost - b.lost} more of them, with {b.rms_px:.2f} px of held-out "
                    f"reprojection RMS ({self.requested} {a.rms_px:.2f} px on the corners it "
                    f"projects; {FOLDS}-fold cross-validation on {self.views} views): "
                    f"consider model: {self.better}")
        return (f"{camera}: the {self.requested} lens leaves {a.outer_rms_px:.2f} px of "
                f"held-out reprojection RMS beyond {self.outer_from_px:.0f} px from the image "
                f"centre, {self.better} {b.outer_rms_px:.2f} px ({a.rms_px:.2f} against "
                f"{b.rms_px:.2f} px over the image; {FOLDS}-fold cross-validation on "
                f"{self.views} views): consider model: {self.better}")


def _spread(n: int, k: int) -> NDArray[np.int64]:
    return np.unique(np.linspace(0, n - 1, min(n, k)).round().astype(np.int64))


def _full_fit(views, size, model: str) -> LensFit:
    """``model`` fitted to every view: OpenCV's calibration for the pinhole models (which
    :func:`generic_start` does not start), the generic start for the others."""
    if LENS_MODELS[model][0] != "pinhole":
        return generic_start(views, size, model)
    from multieye.imaging.calibrate import initial_intrinsics  # noqa: PLC0415 (OpenCV's calibration: only when a pinhole model is compared)

    start = initial_intrinsics(views, size, model)
    T = start.T_cam_target
    rms = np.array([np.sqrt(np.mean(np.sum((project_points(
        o @ Ti[:3, :3].T + Ti[:3, 3], start.intrinsics) - u) ** 2, axis=1)))
        if np.all(np.isfinite(Ti)) else np.inf for (o, u), Ti in zip(views, T)])
    return LensFit(start.intrinsics, T, np.where(np.isfinite(rms), rms, np.inf))


def edge_rms(views, intrinsics, T_cam_target: F64, size) -> tuple[float, float]:
    """The reprojection RMS of a fitted lens over the outer quarter of the observed radii
    from the image centre and over the inner three quarters, pixels (its training
    residuals: a cheap bound for whether a model comparison could name another model; NaN
    without a posed view)."""
    uv, err = [], []
    for (o, u), T in zip(views, T_cam_target):
        if np.all(np.isfinite(T)):
            d = project_points(np.asarray(o) @ T[:3, :3].T + T[:3, 3], intrinsics) - u
            uv.append(np.asarray(u))
            err.append(np.hypot(d[:, 0], d[:, 1]))
    if not uv:
        return float("nan"), float("nan")
    uv, err = np.concatenate(uv), np.where(np.isfinite(np.concatenate(err)),
                                           np.concatenate(err), 1e3)
    radius = np.hypot(*(uv - (np.array(size, np.float64) - 1) / 2).T)
    outer = radius >= np.quantile(radius, 0.75)
    return (float(np.sqrt(np.mean(err[outer] ** 2))),
            float(np.sqrt(np.mean(err[~outer] ** 2))) if np.any(~outer) else float("nan"))


def may_be_beaten(outer_px: float, inner_px: float) -> bool:
    """Whether a lens leaving ``outer_px`` in the outer quarter of its radii and ``inner_px``
    inside could be clearly beaten (the rule of :func:`compare_models`): no model fits below
    the noise, which the inner residuals bound, so the outer ones must be at least
    :data:`EDGE_BOUND_PX` and 1 / :data:`CLEARLY` times the inner ones (a misfit that grows
    towards the edge)."""
    return bool(outer_px >= EDGE_BOUND_PX and outer_px >= inner_px / CLEARLY)


def _held_out(views, size, model: str) -> F64 | None:
    """Per point of ``views`` (stacked), its held-out reprojection error in ``model``,
    pixels (NaN where the model does not project it); None when no lens can be fitted."""
    try:
        full = _full_fit(views, size, model)
    except (InputError, np.linalg.LinAlgError, ValueError):
        return None
    counts = [len(o) for o, _ in views]
    at = np.concatenate([[0], np.cumsum(counts)])
    err = np.full(at[-1], np.nan)
    posed = np.flatnonzero(np.isfinite(full.rms_px))
    for fold in range(FOLDS):
        test = posed[fold::FOLDS]
        train = np.setdiff1d(posed, test)
        if len(train) < 3 or not len(test):
            continue
        try:
            lens = fit_lens([views[i] for i in train], full.intrinsics,
                            full.T_cam_target[train], max_iterations=50).intrinsics
            poses = refit_poses(full.T_cam_target[test], [views[i][0] for i in test],
                                [views[i][1] for i in test], lens)
        except (InputError, np.linalg.LinAlgError):
            continue
        for i, pose in zip(test, poses):
            obj, uv = views[i]
            T = pose.T_cam_target
            d = project_points(obj @ T[:3, :3].T + T[:3, 3], lens) - uv
            err[at[i]:at[i + 1]] = np.hypot(d[:, 0], d[:, 1])
    return err


def _score(model: str, err: F64, radius: F64, outer_from: float, lost: int) -> ModelScore:
    def rms(mask):
        return float(np.sqrt(np.mean(err[mask] ** 2))) if mask.any() else float("nan")

    bands = tuple((lo, lo + 100.0, rms((radius >= lo) & (radius < lo + 100.0)))
                  for lo in np.arange(0.0, radius.max() + 1e-9, 100.0))
    return ModelScore(model, rms(np.ones_like(radius, bool)), rms(radius >= outer_from),
                      tuple(b for b in bands if np.isfinite(b[2])), lost)


def compare_models(views: Sequence[tuple[F64, F64]], image_size: tuple[int, int],
                   requested: str, *, candidates: Sequence[str] | None = None
                   ) -> ModelComparison:
    """The held-out reprojection of each candidate model on the same views.

    Parameters
    ----------
    views : sequence of (object_points (n, 3), image_points (n, 2))
        At most :data:`MAX_VIEWS` of them are used, spread over the sequence.
    image_size : (int, int)
    requested : str
        The rig.yaml model asked for (:data:`multieye.core.intrinsics.LENS_MODELS`).
    candidates : sequence of str, optional
        Default :data:`PINHOLE_CANDIDATES` for a pinhole model, else :data:`CANDIDATES`.

    Returns
    -------
    ModelComparison
        Scored over the points every fitted model projects (a fisheye lens none beyond 90
        degrees off its axis).
    """
    if candidates is None:
        pinhole = requested in LENS_MODELS and LENS_MODELS[requested][0] == "pinhole"
        candidates = PINHOLE_CANDIDATES if pinhole else CANDIDATES
    views = [(np.asarray(o, np.float64), np.asarray(u, np.float64)) for o, u in views]
    views = [views[i] for i in _spread(len(views), MAX_VIEWS)]
    size = (int(image_size[0]), int(image_size[1]))
    models = [requested] + [m for m in candidates if m != requested]
    uv = np.concatenate([u for _, u in views]) if views else np.zeros((0, 2))
    centre = (np.array(size, np.float64) - 1) / 2
    mine = _held_out(views, size, requested) if requested in LENS_MODELS else None
    if mine is not None and len(mine) and np.all(np.isfinite(mine)):
        # it projects every corner: when it leaves under MIN_GAIN_PX / (1 - CLEARLY) (0.2 px)
        # in its outer quarter no model can be clearly better, and the others are not fitted
        # (1.6-2.2 CPU-s per camera of a 960 x 720 fisheye rig)
        radius = np.hypot(*(uv - centre).T)
        outer_from = float(np.quantile(radius, 0.75))
        alone = _score(requested, mine, radius, outer_from, 0)
        if alone.outer_rms_px < EDGE_BOUND_PX:
            return ModelComparison(requested, {requested: alone}, outer_from, len(views), None)
    errors = {m: e for m in models if m in LENS_MODELS
              for e in ([mine] if m == requested else [_held_out(views, size, m)])
              if e is not None}
    common = np.all([np.isfinite(e) for e in errors.values()], axis=0) if errors else []
    if requested not in errors or not np.any(common):
        return ModelComparison(requested, {}, float("nan"), len(views), None)
    radius = np.hypot(*(uv[common] - centre).T)
    outer_from = float(np.quantile(radius, 0.75))
    some = np.any([np.isfinite(e) for e in errors.values()], axis=0)
    scores = {m: _score(m, e[common], radius, outer_from, int(np.sum(some & ~np.isfinite(e))))
              for m, e in errors.items()}
    mine = scores[requested]
    better = [s for m, s in scores.items() if m != requested and (
        s.outer_rms_px <= CLEARLY * mine.outer_rms_px
        and s.outer_rms_px <= mine.outer_rms_px - MIN_GAIN_PX and s.rms_px < mine.rms_px
        or mine.lost - s.lost > LOST_SHARE * some.sum() and s.rms_px < mine.rms_px + MIN_GAIN_PX)]
    best = min(better, key=lambda s: (s.lost, s.outer_rms_px)).model if better else None
    return ModelComparison(requested, scores, outer_from, len(views), best)
