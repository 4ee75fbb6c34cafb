"""The paper's synthetic experiments (Wang et al., ICRA 2022, section V-B), as sweeps.

Each sweep simulates a rig (:mod:`multieye.sim.rigs`, eye-to-base by default), corrupts both
measurement streams with the paper's multiplicative noise, solves with every method on the
same data, and records per trial:

- ``e_R_deg``, ``e_t_m``: the loop residuals of paper section V-A on the noisy data;
- ``rel_rot_err_deg``, ``rel_trans_err_m``: the error of the relative extrinsics ``T_ref_cam``
  against the ground truth (rotation angle, translation distance), averaged over the
  non-reference cameras; with a single camera, the error of ``X`` itself;
- ``time_s``: the wall time of the :func:`multieye.solvers.solve` call;
- ``failure``: empty, or the error class with which the method refused the data (its error
  columns then NaN; e.g. ``DegenerateMotionError`` for single-camera methods when one
  camera's few rotations are about one axis).

========== ======================================== =======================================
sweep      parameter (column ``param``)             fixed
========== ======================================== =======================================
noise      noise level f, 0 to 0.30                 4 cameras x 40 measurements
cameras    number of cameras, 1 to 4                40 measurements each, f = 0.05
measure-   measurements per camera, 3 to 40         4 cameras, f = 0.05
ments
timing     measurements per camera, 5 to 160        4 cameras, f = 0.05
========== ======================================== =======================================

Trial ``t`` draws its rig and board poses from ``default_rng([seed, t])`` and its noise from
``default_rng([seed, t, k])`` for the k-th parameter value, so the noise sweep sees the same
scenes at every level and any (trial, parameter) can be reproduced alone.

>>> from multieye.experiments.sweeps import run_experiment
>>> out = run_experiment("noise", trials=100, seed=0, out_dir="docs/experiments")  # doctest: +SKIP
>>> out.csv_path, out.png_path                                                       # doctest: +SKIP
"""

from __future__ import annotations

import io
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import astuple, dataclass, fields, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from multieye.core.arguments import with_fields
from multieye.core.errors import CalibrationError, InputError
from multieye.core.metrics import extrinsic_errors, relative_extrinsics
from multieye.experiments.figures import sweep_png
from multieye.io.atomic import write_bytes_atomic, write_text_atomic
from multieye.sim import rigs as sim
from multieye.solvers import METHODS, solve

__all__ = [
    "EXPERIMENTS",
    "SweepScene",
    "METHODS",
    "NOISE_LEVELS",
    "CAMERA_COUNTS",
    "MEASUREMENT_COUNTS",
    "TIMING_COUNTS",
    "COLUMNS",
    "METRICS",
    "ExperimentRow",
    "SweepResult",
    "ExperimentOutput",
    "noise_experiment",
    "cameras_experiment",
    "measurements_experiment",
    "timing_experiment",
    "run_experiment",
    "summarize",
    "rows_to_csv",
]

NOISE_LEVELS: tuple[float, ...] = (0.0, 0.05, 0.10, 0.15, 0.20, 0.25, 0.30)
CAMERA_COUNTS: tuple[int, ...] = (1, 2, 3, 4)
MEASUREMENT_COUNTS: tuple[int, ...] = (3, 5, 10, 15, 20, 25, 30, 35, 40)
TIMING_COUNTS: tuple[int, ...] = (5, 10, 20, 40, 80, 160)

#: Problem of one trial at one parameter value: (parameter, scene rng, noise rng) -> scenario.
ProblemFactory = Callable[[float, np.random.Generator, np.random.Generator], sim.RigScenario]


@dataclass(frozen=True)
class ExperimentRow:
    """One solve: a method on one trial at one parameter value (one CSV line).

    Attributes
    ----------
    param : float
        The swept parameter (noise level f as a fraction, camera count, or measurements per
        camera).
    method : str
    trial : int
    e_R_deg, e_t_m : float
        Mean loop residuals of paper section V-A on the noisy data, degrees and metres.
    rel_rot_err_deg, rel_trans_err_m : float
        Error of ``T_ref_cam`` against the ground truth averaged over non-reference cameras
        (error of ``X`` with one camera), degrees and metres.
    time_s : float
        Wall time of the solve, seconds.
    failure : str
        Empty, or the class of the :class:`~multieye.core.errors.CalibrationError` with which
        the method refused the data (``DegenerateMotionError``: e.g. a camera whose rotations
        are about one axis, which single-camera methods cannot solve); the error columns are
        then NaN.  A solver never returns NaN without refusing (:func:`multieye.solvers.solve`).
    """

    param: float
    method: str
    trial: int
    e_R_deg: float
    e_t_m: float
    rel_rot_err_deg: float
    rel_trans_err_m: float
    time_s: float
    failure: str = ""


#: CSV header, in order.
COLUMNS: tuple[str, ...] = tuple(f.name for f in fields(ExperimentRow))
#: Numeric columns that :func:`summarize` reduces.
METRICS: tuple[str, ...] = ("e_R_deg", "e_t_m", "rel_rot_err_deg", "rel_trans_err_m", "time_s")


@dataclass(frozen=True)
class SweepResult:
    """All rows of one sweep.

    Attributes
    ----------
    name : str
        ``noise``, ``cameras``, ``measurements`` or ``timing``.
    param_label : str
        What ``param`` is, with its unit, for tables and figures.
    rows : tuple of ExperimentRow
        Ordered by trial, then parameter, then method.
    """

    name: str
    param_label: str
    rows: tuple[ExperimentRow, ...]

    @property
    def methods(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.method for r in self.rows))

    @property
    def params(self) -> tuple[float, ...]:
        return tuple(sorted({r.param for r in self.rows}))

    @property
    def failures(self) -> int:
        """Number of solves that raised a CalibrationError (NaN rows)."""
        return sum(1 for r in self.rows if r.failure or np.isnan(r.rel_rot_err_deg))

    def failure_summary(self) -> str:
        """The refused solves by method, parameter and error class, one line (empty if none):
        ``shah at 3: DegenerateMotionError x1; ...``."""
        counts = Counter((r.method, r.param, r.failure or "NaN") for r in self.rows
                         if r.failure or np.isnan(r.rel_rot_err_deg))
        return "; ".join(f"{m} at {p:g}: {kind} x{n}" for (m, p, kind), n in counts.items())


@dataclass(frozen=True)
class ExperimentOutput:
    """Files written by :func:`run_experiment`, and the sweep behind them."""

    csv_path: Path
    png_path: Path
    result: SweepResult


def _evaluate(scenario: sim.RigScenario, method: str, param: float, trial: int) -> ExperimentRow:
    """Solve ``scenario`` with ``method`` and score it against the ground truth."""
    start = time.perf_counter()
    try:
        sol = solve(scenario.A, scenario.B, method=method)
    except CalibrationError as exc:
        nan = float("nan")
        return ExperimentRow(param, method, trial, nan, nan, nan, nan,
                             time.perf_counter() - start, type(exc).__name__)
    elapsed = time.perf_counter() - start
    if scenario.n_cameras == 1:
        rot, trans = extrinsic_errors(sol.X, scenario.X)
    else:
        rot, trans = extrinsic_errors(relative_extrinsics(sol.X)[1:], scenario.T_ref_cam[1:])
    return ExperimentRow(param, method, trial, sol.e_R_deg, sol.e_t_m, float(np.mean(rot)),
                         float(np.mean(trans)), elapsed)


def progress_bar(total: int, desc: str, progress: bool):
    """A tqdm bar on stderr when ``progress`` is set and stderr is a terminal, else None."""
    if not (progress and sys.stderr.isatty()):
        return None
    return tqdm(total=total, desc=desc, unit="problem", leave=False, file=sys.stderr)


def _sweep(name: str, param_label: str, params: Sequence[float], problem: ProblemFactory, *,
           trials: int, seed: int, methods: Sequence[str], progress: bool) -> SweepResult:
    """Run every method on every (trial, parameter) problem; see the module docstring."""
    if trials < 1:
        raise InputError(f"trials must be at least 1, got {trials}")
    if seed < 0:
        raise InputError(f"seed must be a non-negative integer, got {seed}")
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise InputError(f"unknown method(s) {', '.join(unknown)}; choose from {', '.join(METHODS)}")
    # The first call of each method pays for lazy imports and caches; keep it out of the timings.
    warm = problem(params[-1], np.random.default_rng([seed, trials]), np.random.default_rng(0))
    for method in methods:
        _evaluate(warm, method, params[-1], -1)
    bar = progress_bar(trials * len(params), name, progress)
    rows: list[ExperimentRow] = []
    try:
        for trial in range(trials):
            for k, param in enumerate(params):
                scenario = problem(param, np.random.default_rng([seed, trial]),
                                   np.random.default_rng([seed, trial, k]))
                rows.extend(_evaluate(scenario, m, param, trial) for m in methods)
                if bar is not None:
                    bar.update()
    finally:
        if bar is not None:
            bar.close()
    return SweepResult(name=name, param_label=param_label, rows=tuple(rows))


@dataclass(frozen=True)
class SweepScene:
    """The simulated rig of a sweep, at every value but the one the sweep varies.

    Attributes
    ----------
    n_cameras, measurements : int
        Rig size and measurements per camera.
    noise : float
        Level f of the paper's multiplicative noise (fraction, e.g. 0.05 for 5 %).
    setup : {"eye-to-base", "eye-on-hand"}
    """

    n_cameras: int = 4
    measurements: int = 40
    noise: float = 0.05
    setup: sim.Setup = "eye-to-base"


def _scene(scene: SweepScene, kw: dict, swept: str) -> SweepScene:
    """``scene`` with the fields given as keywords, refusing the one the sweep varies."""
    if swept in kw:
        raise InputError(f"{swept} is what this experiment varies; give its values instead")
    return with_fields(scene, kw, SweepScene, "scene")


def _scenario(scene_rng: np.random.Generator, noise_rng: np.random.Generator,
              scene: SweepScene) -> sim.RigScenario:
    """A simulated rig with the paper's multiplicative noise of level ``scene.noise`` on both
    streams."""
    clean = sim.simulate_rig(scene_rng, n_cameras=scene.n_cameras,
                             measurements=scene.measurements, setup=scene.setup)
    return sim.add_noise(clean, sim.MultiplicativeNoise(scene.noise), noise_rng)


def noise_experiment(trials: int = 100, seed: int = 0, *,
                     levels: Sequence[float] = NOISE_LEVELS, methods: Sequence[str] = METHODS,
                     progress: bool = False, scene: SweepScene = SweepScene(),
                     **kw) -> SweepResult:
    """Errors against the noise level f of the paper's multiplicative model (paper Fig. 4).

    Parameters
    ----------
    trials : int
        Monte Carlo trials per level.
    seed : int
    levels : sequence of float
        Noise levels f (fractions, e.g. 0.05 for 5 %).
    methods : sequence of str
        Solver names (:data:`multieye.solvers.METHODS`).
    progress : bool
        Show a progress bar on stderr if it is a terminal.
    scene : SweepScene
        The rig (camera count, measurements per camera, setup); its ``noise`` is varied.
    **kw
        Or :class:`SweepScene`'s fields as keyword arguments (``n_cameras=2``,
        ``setup="eye-on-hand"``).

    Returns
    -------
    SweepResult
        ``param`` is f.
    """
    scene = _scene(scene, kw, "noise")

    def problem(f, scene_rng, noise_rng):
        return _scenario(scene_rng, noise_rng, replace(scene, noise=f))

    return _sweep("noise", "noise level f", [float(f) for f in levels], problem, trials=trials,
                  seed=seed, methods=methods, progress=progress)


def cameras_experiment(trials: int = 100, seed: int = 0, *,
                       counts: Sequence[int] = CAMERA_COUNTS, methods: Sequence[str] = METHODS,
                       progress: bool = False, scene: SweepScene = SweepScene(),
                       **kw) -> SweepResult:
    """Errors against the number of cameras on the rig (a ring of m cameras).

    Parameters are as for :func:`noise_experiment`; ``counts`` are the camera counts m (the
    scene's ``n_cameras`` is varied, its ``noise`` is the fixed level f). ``param`` is m.
    """
    scene = _scene(scene, kw, "n_cameras")

    def problem(m, scene_rng, noise_rng):
        return _scenario(scene_rng, noise_rng, replace(scene, n_cameras=int(m)))

    return _sweep("cameras", "number of cameras (at 1: error of X itself)",
                  [float(m) for m in counts], problem,
                  trials=trials, seed=seed, methods=methods, progress=progress)


def measurements_experiment(trials: int = 100, seed: int = 0, *,
                            counts: Sequence[int] = MEASUREMENT_COUNTS,
                            methods: Sequence[str] = METHODS, progress: bool = False,
                            scene: SweepScene = SweepScene(), **kw) -> SweepResult:
    """Errors against the number of measurements per camera.

    Parameters are as for :func:`noise_experiment`; ``counts`` are the measurements per
    camera (the scene's ``measurements`` is varied). ``param`` is that count.
    """
    scene = _scene(scene, kw, "measurements")

    def problem(n, scene_rng, noise_rng):
        return _scenario(scene_rng, noise_rng, replace(scene, measurements=int(n)))

    return _sweep("measurements", "measurements per camera", [float(n) for n in counts],
                  problem, trials=trials, seed=seed, methods=methods, progress=progress)


def timing_experiment(trials: int = 100, seed: int = 0, *,
                      counts: Sequence[int] = TIMING_COUNTS, methods: Sequence[str] = METHODS,
                      progress: bool = False, scene: SweepScene = SweepScene(),
                      **kw) -> SweepResult:
    """Solve time against the number of measurements per camera.

    As :func:`measurements_experiment` over larger counts; the figure shows ``time_s``. Wall
    times depend on the machine and its load: compare methods within one run.
    """
    result = measurements_experiment(trials, seed, counts=counts, methods=methods,
                                     progress=progress, scene=_scene(scene, kw, "measurements"))
    return SweepResult(name="timing", param_label=result.param_label, rows=result.rows)


#: Sweep functions by name, as the command line calls them.
EXPERIMENTS: dict[str, Callable[..., SweepResult]] = {
    "noise": noise_experiment,
    "cameras": cameras_experiment,
    "measurements": measurements_experiment,
    "timing": timing_experiment,
}


def summarize(result: SweepResult, metric: str, statistic: str = "mean"
              ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per-method curve of one metric: the mean or median over trials at each parameter.

    Parameters
    ----------
    result : SweepResult
    metric : str
        A numeric column: ``e_R_deg``, ``e_t_m``, ``rel_rot_err_deg``, ``rel_trans_err_m`` or
        ``time_s``.
    statistic : {"mean", "median"}
        Failed solves (NaN) are left out.

    Returns
    -------
    dict
        method -> (parameters, statistic), both arrays of shape (n_params,).
    """
    if metric not in METRICS:
        raise InputError(f"unknown metric {metric!r}; choose one of {', '.join(METRICS)}")
    reduce = {"mean": np.nanmean, "median": np.nanmedian}.get(statistic)
    if reduce is None:
        raise InputError(f"statistic must be 'mean' or 'median', got {statistic!r}")
    params = np.array(result.params)
    curves = {}
    for method in result.methods:
        values = [[getattr(r, metric) for r in result.rows if r.method == method and r.param == p]
                  for p in params]
        with np.errstate(all="ignore"):
            stat = np.array([reduce(v) if np.any(np.isfinite(v)) else np.nan for v in values])
        curves[method] = (params, stat)
    return curves


def rows_to_csv(rows: Iterable[ExperimentRow]) -> str:
    """CSV text with a header line ``param,method,trial,e_R_deg,...,time_s,failure``.

    Floats are written as Python's shortest exact round-trip form; NaN as ``nan``.
    """
    out = io.StringIO()
    out.write(",".join(COLUMNS) + "\n")
    for row in rows:
        out.write(",".join(v if isinstance(v, str) else repr(v) for v in astuple(row)) + "\n")
    return out.getvalue()


_PANELS: dict[str, tuple[tuple[str, str, float], ...]] = {
    # metric, axis label, factor from the stored unit to the plotted one
    "errors": (("rel_rot_err_deg", "T_ref_cam rotation error (deg)", 1.0),
               ("rel_trans_err_m", "T_ref_cam translation error (mm)", 1e3),
               ("e_R_deg", "loop residual e_R (deg)", 1.0),
               ("e_t_m", "loop residual e_t (mm)", 1e3)),
    "timing": (("time_s", "solve time (ms)", 1e3),),
}


def _figure(result: SweepResult, statistic: str) -> bytes:
    timing = result.name == "timing"
    x_scale, x_label = ((100.0, "noise level f (%)") if result.name == "noise"
                        else (1.0, result.param_label))
    panels = []
    for metric, label, factor in _PANELS["timing" if timing else "errors"]:
        curves = {m: (x * x_scale, y * factor)
                  for m, (x, y) in summarize(result, metric, statistic).items()}
        panels.append((f"{statistic} {label}", curves))
    trials = len({r.trial for r in result.rows})
    title = f"{result.name} sweep: {statistic} over {trials} trials"
    if result.failures:
        title += f" ({result.failures} failed solves left out)"
    return sweep_png(x_label, panels, title=title, log_x=timing, log_y=timing)


def run_experiment(name: str, trials: int = 100, seed: int = 0, out_dir: str | Path = ".",
                   progress: bool = True, *, statistic: str | None = None,
                   **options) -> ExperimentOutput:
    """Run one sweep and write ``out_dir/<name>.csv`` and ``out_dir/<name>.png`` atomically.

    Parameters
    ----------
    name : {"noise", "cameras", "measurements", "timing"}
    trials : int
        Monte Carlo trials per parameter value (>= 1).
    seed : int
    out_dir : path-like
        Created if missing.
    progress : bool
        Show a progress bar on stderr when it is a terminal (never in pipes or logs).
    statistic : {"mean", "median"}, optional
        What the figure plots; default the mean for error sweeps (the paper's "on average")
        and the median for timing.
    **options
        Passed to the sweep function (e.g. ``levels=``, ``counts=``, ``methods=``, ``setup=``);
        see :func:`noise_experiment` and the others.

    Returns
    -------
    ExperimentOutput

    Raises
    ------
    InputError
        Unknown experiment name or trials < 1.
    DatasetError
        The output folder cannot be written.
    """
    if name not in EXPERIMENTS:
        raise InputError(f"unknown experiment {name!r}; choose one of {', '.join(EXPERIMENTS)}")
    result = EXPERIMENTS[name](trials, seed, progress=progress, **options)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = write_text_atomic(out / f"{name}.csv", rows_to_csv(result.rows))
    stat = statistic or ("median" if name == "timing" else "mean")
    png_path = write_bytes_atomic(out / f"{name}.png", _figure(result, stat))
    return ExperimentOutput(csv_path=csv_path, png_path=png_path, result=result)
