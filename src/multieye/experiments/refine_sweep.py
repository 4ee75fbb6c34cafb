"""The ``refine`` experiment: closed form, image-level refinement and the Cramér-Rao bound.

On image-level simulation (:mod:`multieye.sim.images`: a surround rig, a 6 x 8 chessboard
projected with Gaussian pixel noise, motion capture with 0.1 degree / 0.3 mm Gaussian noise),
for every pixel-noise level and trial it records the error of the relative extrinsics
``T_ref_cam`` (camera 0 the reference) of

- ``joint``: the closed form (:func:`multieye.solve`) on PnP poses and mocap poses;
- ``refined``: :func:`multieye.estimate.refine_images.refine_images` started from it, with the pixel noise
  estimated from the data (the default), and its predicted standard deviation;
- ``cramer-rao``: the bound from the Fisher information at the truth
  (:func:`multieye.estimate.uncertainty.cramer_rao_bound`).

Each row holds one method on one trial: the RMS over the non-reference cameras of the
rotation error angle (degrees) and of the translation error (metres); for ``refined`` also the
predicted RMS (root of the mean trace of the reported covariances), for ``cramer-rao`` the
bound itself in both.  Trial ``t`` draws its scene from ``default_rng([seed, t])`` and its
noise from ``default_rng([seed, t, k])`` at the k-th level, so every level sees the same
scenes.

>>> from multieye.experiments.refine_sweep import run_refine_experiment
>>> paths = run_refine_experiment(100, 0, "docs/experiments", progress=False)  # doctest: +SKIP
"""

from __future__ import annotations

import io
import time
from collections.abc import Iterable, Sequence
from dataclasses import astuple, dataclass, fields
from pathlib import Path

import numpy as np

from multieye.core.arguments import with_fields
from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.metrics import relative_extrinsics
from multieye.estimate.refine_images import refine_images
from multieye.estimate.uncertainty import cramer_rao_bound, relative_covariance
from multieye.experiments.figures import sweep_png
from multieye.experiments.sweeps import progress_bar
from multieye.io.atomic import write_bytes_atomic, write_text_atomic
from multieye.sim.images import simulate_images
from multieye.solvers import solve

__all__ = ["PIXEL_NOISE_LEVELS", "METHODS", "RefineRow", "refine_trial", "refine_sweep",
           "summarize_refine", "refine_rows_to_csv", "run_refine_experiment",
           "relative_rms_errors"]

#: Pixel noise levels swept, pixels.
PIXEL_NOISE_LEVELS: tuple[float, ...] = (0.1, 0.3, 0.5, 1.0, 2.0)
#: Methods recorded per trial.
METHODS: tuple[str, ...] = ("joint", "refined", "cramer-rao")


@dataclass(frozen=True)
class RefineRow:
    """One method on one trial at one pixel-noise level (one CSV line).

    Attributes
    ----------
    pixel_sigma : float
        Pixel noise, pixels.
    trial : int
    method : {"joint", "refined", "cramer-rao"}
    rot_err_deg : float
        RMS over the non-reference cameras of the ``T_ref_cam`` rotation error, degrees
        (``cramer-rao``: the bound, root of the mean trace).
    trans_err_m : float
        RMS of the ``T_ref_cam`` translation error, metres (``cramer-rao``: the bound).
    pred_rot_deg, pred_trans_m : float
        Predicted RMS from the reported covariance (``refined``; the bound for
        ``cramer-rao``; NaN for ``joint``).
    time_s : float
        Wall time of the solve, refinement or bound.
    """

    pixel_sigma: float
    trial: int
    method: str
    rot_err_deg: float
    trans_err_m: float
    pred_rot_deg: float
    pred_trans_m: float
    time_s: float


COLUMNS: tuple[str, ...] = tuple(f.name for f in fields(RefineRow))


def relative_rms_errors(X, X_true) -> tuple[float, float]:
    """RMS over the non-reference cameras of the ``T_ref_cam`` errors (camera 0 the reference).

    Parameters
    ----------
    X, X_true : array_like, shape (m, 4, 4)
        Estimated and true ``T_world_cam`` / ``T_body_cam``.

    Returns
    -------
    rot_deg, trans_m : float
        RMS rotation error angle (degrees) and translation error (metres).
    """
    Tr, Tt = relative_extrinsics(X)[1:], relative_extrinsics(X_true)[1:]
    rot = np.degrees(g.rotation_angle_between(Tr, Tt))
    trans = np.linalg.norm(Tr[:, :3, 3] - Tt[:, :3, 3], axis=1)
    return float(np.sqrt(np.mean(rot ** 2))), float(np.sqrt(np.mean(trans ** 2)))


def _predicted(X, covariance) -> tuple[float, float]:
    rel = relative_covariance(X, covariance)
    return (float(np.sqrt(np.mean(rel.std_rot_deg[1:] ** 2))),
            float(np.sqrt(np.mean(rel.std_trans_m[1:] ** 2))))


@dataclass(frozen=True)
class TrialSpec:
    """The options of :func:`refine_trial` (see there), taken as one argument or as
    keyword arguments."""

    trial: int = 0
    n_cameras: int = 4
    images: int = 40
    setup: str = "eye-to-base"
    mocap_rot_sigma_rad: float = float(np.deg2rad(0.1))
    mocap_trans_sigma_m: float = 0.3e-3


def refine_trial(pixel_sigma: float, scene_rng, noise_rng, spec: TrialSpec = TrialSpec(),
                 **kw) -> list[RefineRow]:
    """Simulate one rig and score ``joint``, ``refined`` and the bound on it.

    Parameters
    ----------
    pixel_sigma : float
        Pixel noise, pixels.
    scene_rng, noise_rng : numpy.random.Generator or int
        Sources of the scene and of the noise.
    trial : int
        Recorded in the rows.
    n_cameras, images : int
        Rig size and images per camera.
    setup : {"eye-to-base", "eye-on-hand"}
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float
        Motion-capture noise, radians and metres.

    Returns
    -------
    list of RefineRow
        One per method of :data:`METHODS`.
    """
    o = with_fields(spec, kw, TrialSpec, "spec")
    trial, n_cameras, images, setup = o.trial, o.n_cameras, o.images, o.setup
    mocap_rot_sigma_rad, mocap_trans_sigma_m = o.mocap_rot_sigma_rad, o.mocap_trans_sigma_m
    sc = simulate_images(scene_rng, n_cameras=n_cameras, images=images, setup=setup,
                         pixel_sigma=pixel_sigma, mocap_rot_sigma_rad=mocap_rot_sigma_rad,
                         mocap_trans_sigma_m=mocap_trans_sigma_m, noise_rng=noise_rng)
    nan = float("nan")
    start = time.perf_counter()
    sol = solve(sc.A, sc.B, method="joint")
    rows = [RefineRow(pixel_sigma, trial, "joint", *relative_rms_errors(sol.X, sc.X), nan,
                      nan, time.perf_counter() - start)]
    res = refine_images(sc.setup, sc.observations, sc.intrinsics, sol.X, sol.Y,
                        mocap_rot_sigma_rad=mocap_rot_sigma_rad,
                        mocap_trans_sigma_m=mocap_trans_sigma_m)
    rows.append(RefineRow(pixel_sigma, trial, "refined", *relative_rms_errors(res.X, sc.X),
                          *_predicted(res.X, res.covariance), res.time_s))
    start = time.perf_counter()
    crb = cramer_rao_bound(sc.setup, sc.true_observations, sc.intrinsics, sc.X, sc.Y,
                           pixel_sigma=pixel_sigma, mocap_rot_sigma_rad=mocap_rot_sigma_rad,
                           mocap_trans_sigma_m=mocap_trans_sigma_m)
    bound = _predicted(sc.X, crb)
    rows.append(RefineRow(pixel_sigma, trial, "cramer-rao", *bound, *bound,
                          time.perf_counter() - start))
    return rows


def refine_sweep(trials: int = 100, seed: int = 0, *,
                 levels: Sequence[float] = PIXEL_NOISE_LEVELS, progress: bool = False,
                 **options) -> tuple[RefineRow, ...]:
    """:func:`refine_trial` over trials and pixel-noise levels (module docstring).

    Parameters
    ----------
    trials : int
        Monte Carlo trials per level (>= 1).
    seed : int
        >= 0.
    levels : sequence of float
        Pixel noise levels, pixels (> 0).
    progress : bool
        Progress bar on stderr when it is a terminal.
    **options
        Passed to :func:`refine_trial` (``n_cameras``, ``images``, ``setup``, mocap noise).

    Returns
    -------
    tuple of RefineRow
        Ordered by trial, level, method.
    """

    if trials < 1:
        raise InputError(f"trials must be at least 1, got {trials}")
    if seed < 0:
        raise InputError(f"seed must be a non-negative integer, got {seed}")
    if not levels or min(levels) <= 0:
        raise InputError(f"pixel noise levels must be positive, got {list(levels)}")
    bar = progress_bar(trials * len(levels), "refine", progress)
    rows: list[RefineRow] = []
    try:
        for trial in range(trials):
            for k, level in enumerate(levels):
                rows.extend(refine_trial(float(level), np.random.default_rng([seed, trial]),
                                         np.random.default_rng([seed, trial, k]), trial=trial,
                                         **options))
                if bar is not None:
                    bar.update()
    finally:
        if bar is not None:
            bar.close()
    return tuple(rows)


def summarize_refine(rows: Iterable[RefineRow]) -> dict[str, dict[str, np.ndarray]]:
    """RMS over trials per method and level.

    Returns
    -------
    dict
        method -> ``{"pixel_sigma", "rot_rms_deg", "trans_rms_m", "pred_rot_rms_deg",
        "pred_trans_rms_m"}``, each an array over the levels (ascending); RMS is the root
        of the mean over trials of the squared per-trial values.
    """
    rows = list(rows)
    levels = np.array(sorted({r.pixel_sigma for r in rows}))
    out = {}
    for method in dict.fromkeys(r.method for r in rows):
        cols = {"pixel_sigma": levels}
        for key, attr in (("rot_rms_deg", "rot_err_deg"), ("trans_rms_m", "trans_err_m"),
                          ("pred_rot_rms_deg", "pred_rot_deg"),
                          ("pred_trans_rms_m", "pred_trans_m")):
            cols[key] = np.array([np.sqrt(np.mean([getattr(r, attr) ** 2 for r in rows
                                                   if r.method == method
                                                   and r.pixel_sigma == s]))
                                  for s in levels])
        out[method] = cols
    return out


def refine_rows_to_csv(rows: Iterable[RefineRow]) -> str:
    """CSV text with a header line ``pixel_sigma,trial,method,...``; floats as ``repr``."""
    out = io.StringIO()
    out.write(",".join(COLUMNS) + "\n")
    for row in rows:
        out.write(",".join(v if isinstance(v, str) else repr(v) for v in astuple(row)) + "\n")
    return out.getvalue()


def _figure(rows: Sequence[RefineRow]) -> bytes:
    summary = summarize_refine(rows)
    curves = {"rot": {}, "trans": {}}
    labels = {"joint": "joint (closed form)", "refined": "refined",
              "cramer-rao": "Cramér-Rao bound"}
    for method, label in labels.items():
        s = summary[method]
        curves["rot"][label] = (s["pixel_sigma"], s["rot_rms_deg"])
        curves["trans"][label] = (s["pixel_sigma"], 1e3 * s["trans_rms_m"])
    s = summary["refined"]
    curves["rot"]["refined, predicted"] = (s["pixel_sigma"], s["pred_rot_rms_deg"])
    curves["trans"]["refined, predicted"] = (s["pixel_sigma"], 1e3 * s["pred_trans_rms_m"])
    trials = len({r.trial for r in rows})
    return sweep_png("pixel noise (px)",
                     [("RMS T_ref_cam rotation error (deg)", curves["rot"]),
                      ("RMS T_ref_cam translation error (mm)", curves["trans"])],
                     title=f"refine: RMS over {trials} trials (mocap 0.1 deg / 0.3 mm)",
                     log_x=True, log_y=True)


def run_refine_experiment(trials: int = 100, seed: int = 0, out_dir: str | Path = ".",
                          progress: bool = True, **options) -> list[Path]:
    """Run the sweep and write ``out_dir/refine.csv`` and ``out_dir/refine.png`` atomically.

    Parameters
    ----------
    trials : int
        Monte Carlo trials per pixel-noise level.
    seed : int
    out_dir : path-like
        Created if missing.
    progress : bool
        Progress bar on stderr when it is a terminal (never in pipes or logs).
    **options
        Passed to :func:`refine_sweep` (``levels``, ``n_cameras``, ``images``, ``setup``...).

    Returns
    -------
    list of Path
        The CSV and the PNG.
    """
    rows = refine_sweep(trials, seed, progress=progress, **options)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = write_text_atomic(out / "refine.csv", refine_rows_to_csv(rows))
    png_path = write_bytes_atomic(out / "refine.png", _figure(rows))
    return [Path(csv_path), Path(png_path)]
