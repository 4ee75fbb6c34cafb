"""Which optimum does the pipeline reach on a rendered wide lens, and is the cost quadratic
there? (issue 33; docs/results/wide_render.md, section 4)

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_wide_render_optimum.py [--rig single] [--model unified]
        [--field 190] [--variant base] [--seeds 0-9] [--json OUT.jsonl]

For each seed the wide camera of ``bench_wide_render.py`` (the same rendered images:
:func:`bench_wide_render.single_dataset` or, ``--rig mixed``, :func:`~bench_wide_render.
mixed_dataset`) is calibrated by the pipeline; then, on the corners the pipeline used for that
camera, the lens and every view's pose are fitted by plain least squares
(:func:`multieye.imaging.generic_start.fit_lens`, no robust loss, no motion capture) twice:
from the pipeline's lens and poses, and from the true lens and the true poses (the mixed rig:
the first fit's poses).  Per seed:

- ``dcost_sigma2``: the cost (sum of squared pixel residuals) of the first less the second,
  in sigma^2 (sigma^2 = the smaller cost over its redundancy): negative or zero when the
  pipeline's optimum is the truth's or better, positive when it stopped in a worse one;
- ``xi`` of the truth, the pipeline, the first and the second fit (the model's first
  distortion parameter);
- ``nees_par``, ``nees_curve``: the pipeline's lens NEES / dim in its parameters in its
  reported covariance, and of calibration.json's ``lens_curve`` (three radii) in theirs;
- at the truth-started optimum, in the least squares' own covariance (sigma^2 (J^T J)^-1, the
  poses marginalised): ``wald_par`` (NEES / dim of the parameters), ``wald_curve`` (of the
  curve parameters of :mod:`multieye.core.lens_curve`) and ``lr_truth``: the cost with the
  lens held at the truth (poses refitted) less the optimum's, over sigma^2 and the lens'
  dimension, the likelihood-ratio statistic, which does not linearise (about 1 when the
  truth is where the noise puts it);
- ``profile``: the cost with ``xi`` held at the optimum's plus -2, -1, 1, 2, 3 of its
  standard deviations (every other parameter and pose refitted), less the optimum's, in
  sigma^2 (4, 1, 1, 4, 9 if the cost were quadratic in ``xi``), and ``profile_truth`` with
  ``xi`` held at the truth's;
- ``nees_curve_ls``: the NEES / 3 of the radii of calibration.json's rays under the
  truth-started fit, in that fit's covariance, and the ratio of its standard deviations to
  the pipeline's (the mixed rig: the pipeline's poses are held by the motion capture too).

This is a script, not a test: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_wide_render as b  # noqa: E402

from multieye.core.lens_curve import curve_jacobian, radial_curve  # noqa: E402
from multieye.imaging.generic_start import _Problem, fit_lens  # noqa: E402
from multieye.pipeline import calibrate  # noqa: E402


def held_fit(views, lens, T, held) -> float:
    """Least-squares cost of the lens and poses with the lens parameters ``held`` (indices in
    ``lens.params``) fixed at ``lens``'s values."""
    from scipy.optimize import least_squares  # noqa: PLC0415

    prob = _Problem(views, lens, T)
    x0 = np.concatenate([lens.params, np.zeros(6 * len(views))])
    free = np.setdiff1d(np.arange(x0.size), held)

    def full(z):
        x = x0.copy()
        x[free] = z
        return x

    fit = least_squares(lambda z: prob.residual(full(z)), x0[free],
                        jac=lambda z: prob.jacobian(full(z))[:, free], method="lm",
                        x_scale="jac", xtol=1e-12, ftol=1e-12)
    return float(fit.fun @ fit.fun)


def _cost(fit, views) -> float:
    return float(np.sum(fit.rms_px ** 2 * [len(o) for o, _ in views]))


def _pipeline(rig: str, model: str, fov: float, seed: int, variant: str):
    """The wide camera of bench_wide_render's ``single`` or ``mixed`` rig, calibrated: the
    run, the true lens, the camera's name, the observations the pipeline used (the mixed
    rig's motion-captured views and its ``intrinsics_images``) and, for the single camera,
    their true poses (None for the mixed rig)."""
    with tempfile.TemporaryDirectory() as tmp:
        if rig == "single":
            folder, true, poses, _ = b.single_dataset(model, fov, seed, variant, Path(tmp))
        else:
            folder, true, _, _ = b.mixed_dataset(model, fov, seed, variant, Path(tmp))
        run = calibrate(folder, processes=1)
    name = "wide" if rig == "single" else "cam2"
    obs = list(run.paired[name].observations) if name in run.paired else []
    obs += list(run.cameras[name].intrinsics_views)
    obs = [o for o in (obs or run.cameras[name].observations) if o.image_points is not None]
    T_true = (np.array([poses[int(Path(o.name).stem)] for o in obs]) if rig == "single"
              else None)
    return run, true, name, obs, T_true


def trial(rig: str, model: str, fov: float, seed: int, variant: str) -> dict:
    """One seed's figures (module docstring)."""
    run, true, name, obs, T_true = _pipeline(rig, model, fov, seed, variant)
    est, C = run.intrinsics[name], run.refinement.intrinsics_covariance[name]
    views = [(o.object_points, o.image_points) for o in obs]
    fe = fit_lens(views, est, np.array([o.T_cam_target for o in obs]), huber_px=None,
                  max_iterations=500)
    ft = fit_lens(views, true, fe.T_cam_target if T_true is None else T_true, huber_px=None,
                  max_iterations=500)
    n_lens = true.params.size
    dof = 2 * sum(len(o) for o, _ in views) - n_lens - 6 * len(views)
    c_opt = _cost(ft, views)
    s2 = min(_cost(fe, views), c_opt) / dof
    e = est.params - true.params
    curve = run.record.camera(name).intrinsics.lens_curve
    angles = np.radians(curve.angles_deg)
    ec = curve.radii_px - radial_curve(true, C, angles).radii_px
    prob = _Problem(views, ft.intrinsics, ft.T_cam_target)
    J = prob.jacobian(np.concatenate([ft.intrinsics.params, np.zeros(6 * len(views))]))
    C_ls = s2 * np.linalg.inv(J.T @ J)[:n_lens, :n_lens]
    el = ft.intrinsics.params - true.params
    own = radial_curve(ft.intrinsics, C_ls, angles)
    eo = own.radii_px - radial_curve(true, C_ls, angles).radii_px
    rec = {"rig": rig, "model": model, "fov": fov, "variant": variant, "seed": seed,
           "views": len(views), "curve_err_px": ec.tolist(),
           "curve_sd_px": np.sqrt(np.diag(curve.covariance)).tolist(),
           "curve_sd_ls_px": np.sqrt(np.diag(own.covariance)).tolist(),
           "nees_curve_ls": float(eo @ np.linalg.solve(own.covariance, eo)) / len(eo),
           "sigma_px": float(np.sqrt(s2)), "dcost_sigma2": (_cost(fe, views) - c_opt) / s2,
           "xi_true": float(true.dist[0]), "xi_pipeline": float(est.dist[0]),
           "xi_from_pipeline": float(fe.intrinsics.dist[0]),
           "xi_from_truth": float(ft.intrinsics.dist[0]),
           "nees_par": float(e @ np.linalg.solve(C, e)) / n_lens,
           "nees_curve": float(ec @ np.linalg.solve(curve.covariance, ec)) / len(ec),
           "wald_par": float(el @ np.linalg.solve(C_ls, el)) / n_lens,
           "lr_truth": (held_fit(views, true, ft.T_cam_target, np.arange(n_lens)) - c_opt)
           / s2 / n_lens}
    if model in ("unified", "double-sphere"):
        theta = np.radians(fov / 2)
        phi, G = curve_jacobian(ft.intrinsics, theta)
        ep = phi - curve_jacobian(true, theta)[0]
        rec["wald_curve"] = float(ep @ np.linalg.solve(G @ C_ls @ G.T, ep)) / n_lens
        sd = float(np.sqrt(C_ls[4, 4]))
        rec["sd_xi"] = sd

        def at(xi):
            p = ft.intrinsics.params.copy()
            p[4] = xi
            lens = ft.intrinsics.with_params(p)
            return (held_fit(views, lens, ft.T_cam_target, np.array([4])) - c_opt) / s2

        rec["profile"] = [at(p_xi) for p_xi in ft.intrinsics.dist[0] + sd * np.array(
            [-2.0, -1.0, 1.0, 2.0, 3.0])]
        rec["profile_truth"] = at(true.dist[0])
    return rec


def _seeds(text: str) -> list[int]:
    if "-" in text:
        lo, hi = map(int, text.split("-"))
        return list(range(lo, hi + 1))
    return [int(s) for s in text.split(",")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rig", default="single", choices=("single", "mixed"))
    ap.add_argument("--model", default="unified")
    ap.add_argument("--field", type=float, default=190.0)
    ap.add_argument("--variant", default="base", choices=sorted(b.VARIANTS))
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--json", default=None, help="append every seed's record here")
    args = ap.parse_args()
    print("seed  NEES/dim par  curve  dcost sigma^2  xi pipeline  xi from it  xi from truth  "
          "LR truth/dim  Wald par/dim  Wald curve/dim  profile xi -2 -1 +1 +2 +3 sd  at truth  "
          "curve NEES/3 least squares  its sd / the pipeline's")
    for seed in _seeds(args.seeds):
        r = trial(args.rig, args.model, args.field, seed, args.variant)
        if args.json:
            with open(args.json, "a") as fh:
                fh.write(json.dumps(r) + "\n")
        prof = " ".join(f"{v:.2f}" for v in r.get("profile", []))
        print(f"{seed:>4}  {r['nees_par']:>12.2f}  {r['nees_curve']:>5.2f}  "
              f"{r['dcost_sigma2']:>13.3f}  {r['xi_pipeline']:>11.4f}  "
              f"{r['xi_from_pipeline']:>10.4f}  {r['xi_from_truth']:>13.4f}  "
              f"{r['lr_truth']:>12.2f}  {r['wald_par']:>12.2f}  {r.get('wald_curve', np.nan):>14.2f}"
              f"  {prof}  {r.get('profile_truth', np.nan):.2f}  {r['nees_curve_ls']:.2f}  "
              + " ".join(f"{a / c:.2f}" for a, c in zip(r["curve_sd_ls_px"], r["curve_sd_px"])),
              flush=True)


if __name__ == "__main__":
    main()
