"""Wide lenses (issue 33): the lens start from a generic model, on real and simulated lenses.

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_wide_lens.py [--trials 20] [--seed 0]
        [--draws 60] [--skip boofcv,sim,mc,valley,mixed,timing]

1. ``boofcv``: ``../shared/data/boofcv_fisheye`` (26 images of a fisheye of about 180
   degrees, BoofCV's unified-model calibration as reference; ``MULTIEYE_SHARED_DATA``) with
   ``model:`` fisheye, unified, double-sphere and eucm, each through ``multieye calibrate``
   (its exit status): images used, the reprojection RMS, the lens against BoofCV's within
   150 and 250 px of its principal point (RMS and largest, pixels, over every detected corner
   there, after the rotation between the two camera frames that fits best:
   :func:`multieye.core.lens_compare.lens_difference_px`), and the model warning, if any.
2. ``sim``: ``--trials`` sets of 20 views (6 x 8 corners, 0.2 px noise) of lenses of each
   model at 190 and 220 degrees (fisheye: 170; :mod:`multieye.sim.wide_lens`; the corners
   are projected, not rendered), each started by :func:`multieye.imaging.generic_start.
   generic_start` and fitted to the optimum by :func:`~multieye.imaging.generic_start.
   fit_lens`: how often the start reached the optimum that the fit started from the truth
   reaches (its cost within 0.5 sigma^2), how often it found a better one (more than 0.5
   sigma^2 below), how often it is that same optimum (unified, double-sphere: ``xi`` within
   0.05 of it), the lens error against the truth (RMS over the observed rays after the best
   rotation, pixels; median and largest over the trials), and the lens NEES / dim: the
   parameters' error in the covariance of the fit (sigma^2 times the lens block of
   (J^T J)^-1), the same in the curve parameters (:mod:`multieye.core.lens_curve`), and
   the error of the pixels of three rays in theirs, over the trials (1 when the covariance
   is right).
2b. ``mc``: the covariance at the truth against the spread of ``--draws`` estimates
   (:func:`monte_carlo`).
2c. ``valley``: the cost along ``xi`` without noise (:func:`valley_profile`).
3. ``mixed``: ``--trials // 2`` rigs of two pinhole cameras and one wide camera of each
   model seeing the board together: the NEES / 6 of ``T_ref_cam`` (cameras 1 and 2), the
   largest error of any of its six coordinates in its own standard deviations, how many
   rigs reach the optimum the refinement started from the true lenses reaches (the wide
   lens' ``xi`` within 0.05), and the wide lens' NEES / dim, over all rigs and over those
   (:func:`mixed_rig`).
4. ``timing``: CPU seconds of :func:`multieye.imaging.calibrate.initial_intrinsics` and of
   :func:`multieye.imaging.calibrate.poses_from_detections` on 40 views of a pinhole lens
   (median of 5); run it with ``PYTHONPATH`` on another source tree for the before/after.

This is a script, not a test: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from multieye.core.intrinsics import Intrinsics

BOOFCV_REFERENCE = dict(
    K=[[398.77492706579216, 0.0, 319.17879590584187], [0.0, 398.7685638672075, 319.71743712432686],
       [0.0, 0.0, 1.0]],
    dist=[1.1331346732794045, -0.24972089525362837, 0.009672326567075125, 0.0, 0.0],
    model="unified", width=640, height=720)
SIM_CASES = (("fisheye", 170.0), ("unified", 190.0), ("unified", 220.0),
             ("double-sphere", 190.0), ("double-sphere", 220.0), ("eucm", 190.0),
             ("eucm", 220.0))


def _boofcv_dataset(shared: Path, out: Path, model: str) -> Path:
    (out / "images").mkdir(parents=True)
    for k in range(1, 27):
        os.symlink(shared / "boofcv_fisheye" / f"{k}.jpg", out / "images" / f"{k}.jpg")
    (out / "rig.yaml").write_text(
        "target: {type: chessboard, rows: 6, cols: 4, spacing: 1.0}\n"
        f"cameras:\n  fish: {{model: {model}, images: images/}}\n")
    return out


def boofcv(shared: Path) -> None:
    from multieye.core.lens_compare import lens_difference_px  # noqa: PLC0415

    ref = Intrinsics(**BOOFCV_REFERENCE)
    print("1. boofcv_fisheye (26 images), lens against BoofCV's (unified) after the best "
          "rotation")
    print("model          exit  used  reproj px  <=150 px rms/max  <=250 px rms/max  seconds")
    warnings = []
    for model in ("fisheye", "unified", "double-sphere", "eucm"):
        with tempfile.TemporaryDirectory() as tmp:
            folder = _boofcv_dataset(shared, Path(tmp) / "set", model)
            t0 = time.perf_counter()
            done = subprocess.run([sys.executable, "-m", "multieye", "calibrate", str(folder),
                                   "-o", str(Path(tmp) / "out")], capture_output=True,
                                  text=True)
            seconds = time.perf_counter() - t0
            if done.returncode not in (0, 3):
                print(f"{model:<14} {done.returncode:>4}  {done.stderr.strip()[-200:]}")
                continue
            rec = json.loads((Path(tmp) / "out" / "calibration.json").read_text())
            details = json.loads((Path(tmp) / "out" / "details.json").read_text())
        cam = rec["cameras"][0] if isinstance(rec["cameras"], list) else rec["cameras"]["fish"]
        i = cam["intrinsics"]
        lens = Intrinsics(K=i["K"], dist=i["distortion"], model=i["model"], width=640,
                          height=720)
        uv = np.concatenate([np.array(v, np.float64).reshape(-1, 2)
                             for v in details["cameras"]["fish"]["points"]["uv"]])
        r = np.hypot(*(uv - ref.K[:2, 2]).T)
        cols = []
        for radius in (150, 250):
            d = lens_difference_px(lens, ref, uv[r <= radius])
            cols.append(f"{np.sqrt(np.nanmean(d ** 2)):.2f} / {np.nanmax(d):.2f}")
        used = cam.get("measurements_used", "?")
        reproj = cam.get("residuals", {}).get("reprojection_rms_px", float("nan"))
        print(f"{model:<14} {done.returncode:>4}  {used:>4}  {reproj:>9.2f}  {cols[0]:>16}  "
              f"{cols[1]:>16}  {seconds:>7.1f}")
        warnings += [f"   {model}: {w}" for w in rec.get("warnings", []) if "consider model" in w]
    print("model warnings:" if warnings else "model warnings: none")
    print("\n".join(warnings))


def _lens_covariance(views, fit, sigma: float) -> np.ndarray:
    """sigma^2 times the lens block of (J^T J)^-1 at the fit (the poses marginalised)."""
    from multieye.imaging.generic_start import _Problem  # noqa: PLC0415

    prob = _Problem(views, fit.intrinsics, fit.T_cam_target)
    x = np.concatenate([fit.intrinsics.params, np.zeros(6 * len(views))])
    J = prob.jacobian(x)
    return sigma ** 2 * np.linalg.inv(J.T @ J)[:prob.n_lens, :prob.n_lens]


def _nees(est: Intrinsics, true: Intrinsics, C: np.ndarray, fov: float
          ) -> tuple[float, float, float, float, float]:
    """The lens' NEES / dim in its parameters; in its curve parameters where the model has
    them (:mod:`multieye.core.lens_curve`, rays up to 0.9 of the half field; NaN for the
    other models); in the pixels of three rays (at 0.3, 0.6 and 0.9 of the half field
    of view, azimuths 0, 120 and 240 degrees), whose covariance is ``J C J^T``; in the curve
    parameters other than ``xi`` (its marginal); and (unified only) in the parameters with
    ``fx, fy`` replaced by ``fx / (1 + xi), fy / (1 + xi)``."""
    from multieye.core.lens import project_points, project_with_jacobian  # noqa: PLC0415
    from multieye.core.lens_curve import (CURVE_MODELS, curve_jacobian,  # noqa: PLC0415
                                          curve_names)

    def nees(err, cov):
        return float(err @ np.linalg.solve(cov, err)) / len(err)

    e = est.params - true.params
    curve = no_xi = gamma = float("nan")
    if est.model in CURVE_MODELS:
        phi, G = curve_jacobian(est, np.radians(fov / 2))
        ec, Cc = phi - curve_jacobian(true, np.radians(fov / 2))[0], G @ C @ G.T
        curve = nees(ec, Cc)
        k = [i for i, n in enumerate(curve_names(est)) if n != "xi"]
        no_xi = nees(ec[k], Cc[np.ix_(k, k)])
    if est.model == "unified":
        p, q = est.params, true.params
        G = np.eye(len(p))
        G[0, 0] = G[1, 1] = 1.0 / (1.0 + p[4])
        G[:2, 4] = -p[:2] / (1.0 + p[4]) ** 2
        eg = np.concatenate([p[:2] / (1 + p[4]) - q[:2] / (1 + q[4]), e[2:]])
        gamma = nees(eg, G @ C @ G.T)
    a = np.radians(fov / 2) * np.array([0.3, 0.6, 0.9])
    phi = np.radians([0.0, 120.0, 240.0])
    rays = np.column_stack([np.sin(a) * np.cos(phi), np.sin(a) * np.sin(phi), np.cos(a)])
    uv, _, Ji = project_with_jacobian(rays, est)
    d = (uv - project_points(rays, true)).ravel()
    J = Ji.reshape(-1, Ji.shape[-1])
    return nees(e, C), curve, nees(d, J @ C @ J.T), no_xi, gamma


def _mean_median(values) -> str:
    v = np.asarray(values, np.float64)
    return "     -" if np.all(np.isnan(v)) else f"{np.mean(v):.2f} / {np.median(v):.2f}"


def simulated(trials: int, seed: int) -> None:
    from multieye.core.lens_compare import lens_difference_px  # noqa: PLC0415
    from multieye.imaging.generic_start import fit_lens, generic_start  # noqa: PLC0415
    from multieye.sim.wide_lens import IMAGE_SIDE, board_views, wide_lens  # noqa: PLC0415

    print(f"\n2. simulated wide lenses, {trials} trials of 20 views, 0.2 px noise")
    print("model          fov deg  start at optimum  below truth's  truth's mode  "
          "lens error px median / max  NEES/dim params (mean / median)  (truth's mode)  "
          "curve params  (truth's mode)  pixels  start CPU s  curve without xi")
    for model, fov in SIM_CASES:
        true = wide_lens(model, fov)
        hits, below, same, errors, nees, cpu = 0, 0, [], [], [], []
        for t in range(trials):
            views, T = board_views(true, fov, 20, np.random.default_rng([seed, t]),
                                   noise_px=0.2)
            c0 = time.process_time()
            start = generic_start(views, (IMAGE_SIDE, IMAGE_SIDE), model)
            cpu.append(time.process_time() - c0)
            fit = fit_lens(views, start.intrinsics, start.T_cam_target, huber_px=None,
                           max_iterations=500)
            best = fit_lens(views, true, T, huber_px=None, max_iterations=500)
            n = np.array([len(o) for o, _ in views])
            cost = float(np.sum(fit.rms_px ** 2 * n))
            best_cost = float(np.sum(best.rms_px ** 2 * n))
            hits += cost <= best_cost + 0.5 * 0.04
            below += cost < best_cost - 0.5 * 0.04
            # the same optimum as the fit started from the truth (the valley's xi within 0.05)
            same.append(abs(fit.intrinsics.params[4] - best.intrinsics.params[4]) < 0.05
                        if model in ("unified", "double-sphere") else True)
            uv = np.concatenate([u for _, u in views])
            d = lens_difference_px(fit.intrinsics, true, uv)
            errors.append(float(np.sqrt(np.nanmean(d ** 2))))
            nees.append(_nees(fit.intrinsics, true, _lens_covariance(views, fit, 0.2), fov))
        nees, same = np.array(nees), np.array(same)
        print(f"{model:<14} {fov:>7.0f}  {hits:>8} of {trials:<5}  {below:>13}  "
              f"{same.sum():>12}  {np.median(errors):>13.3f} / {np.max(errors):.3f}  "
              f"{_mean_median(nees[:, 0]):>31}  {np.mean(nees[same, 0]):>12.2f}  "
              f"{_mean_median(nees[:, 1]):>12}  {np.mean(nees[same, 1]):>12.2f}  "
              f"{np.mean(nees[:, 2]):>6.2f}  {np.median(cpu):>11.2f}  "
              f"{_mean_median(nees[:, 3]):>12}")


def monte_carlo(draws: int, seed: int) -> None:
    """The covariance at the truth against the spread of the estimates: one set of 20 views
    per case, ``draws`` draws of 0.2 px noise on its pixels, each fitted from the truth
    (lens and poses); the spread of each lens parameter over the draws in its predicted
    standard deviation (sigma^2 (J^T J)^-1 at the truth, poses marginalised), and the mean
    NEES / dim in the published and the curve parameters (covariance at each estimate)."""
    from multieye.imaging.generic_start import fit_lens  # noqa: PLC0415
    from multieye.sim.wide_lens import board_views, wide_lens  # noqa: PLC0415

    print(f"\n2b. covariance against Monte Carlo at the truth, {draws} noise draws, 0.2 px")
    print("model          fov deg  spread / predicted sd per parameter            "
          "NEES/dim params (mean / median)  curve params  curve without xi  fx / (1 + xi)")
    for model, fov in SIM_CASES:
        true = wide_lens(model, fov)
        clean, T = board_views(true, fov, 20, np.random.default_rng([seed, 99]), noise_px=0.0)
        rng = np.random.default_rng([seed, 98])
        truth_fit = fit_lens(clean, true, T, huber_px=None)
        sd = np.sqrt(np.diag(_lens_covariance(clean, truth_fit, 0.2)))
        est, nees = [], []
        for _ in range(draws):
            views = [(o, u + rng.normal(0.0, 0.2, u.shape)) for o, u in clean]
            fit = fit_lens(views, true, T, huber_px=None, max_iterations=500)
            est.append(fit.intrinsics.params)
            nees.append(_nees(fit.intrinsics, true, _lens_covariance(views, fit, 0.2), fov))
        ratio = np.std(np.array(est), axis=0) / sd
        nees = np.array(nees)
        print(f"{model:<14} {fov:>7.0f}  {' '.join(f'{r:.2f}' for r in ratio):<46}  "
              f"{_mean_median(nees[:, 0]):>31}  {_mean_median(nees[:, 1]):>12}  "
              f"{_mean_median(nees[:, 3]):>16}  {_mean_median(nees[:, 4]):>14}")


def valley_profile(seed: int) -> None:
    """The cost along the valley: trial 0's 20 views without noise, ``xi`` held at each
    value and everything else (lens, poses) fitted from the previous value's optimum,
    walking away from the truth both ways; the sum of squares in sigma^2 (sigma 0.2 px),
    the focal length and the model's radial parameters there."""
    from scipy.optimize import least_squares  # noqa: PLC0415

    from multieye.imaging.generic_start import _Problem  # noqa: PLC0415
    from multieye.sim.wide_lens import board_views, wide_lens  # noqa: PLC0415

    print("\n2c. cost along xi (noise-free, trial 0, xi held, the rest fitted), sigma^2")
    walks = {"unified": (np.round(np.arange(1.0, 0.55, -0.1), 2),
                         np.round(np.arange(1.2, 1.75, 0.1), 2)),
             "double-sphere": (np.round(np.arange(-0.2, -0.35, -0.05), 2),
                               np.round(np.arange(-0.1, 1.95, 0.05), 2))}
    for model, fov in (("unified", 190.0), ("double-sphere", 190.0), ("double-sphere", 220.0)):
        true = wide_lens(model, fov)
        views, T = board_views(true, fov, 20, np.random.default_rng([seed, 0]), noise_px=0.0)
        prob = _Problem(views, true, T)
        free = np.ones(prob.n_lens + 6 * len(views), bool)
        free[4] = False
        rows = []
        for walk in walks[model]:
            x = np.concatenate([true.params, np.zeros(6 * len(views))])
            for xi in walk:
                x[4] = xi

                def part(z, f, x=x):
                    y = x.copy()
                    y[free] = z
                    return f(y)

                fit = least_squares(lambda z: part(z, prob.residual), x[free], method="lm",
                                    jac=lambda z: part(z, prob.jacobian)[:, free],
                                    x_scale="jac", ftol=1e-15, xtol=1e-15, gtol=1e-15)
                x[free] = fit.x
                rows.append((xi, 2 * fit.cost / 0.04, x[:prob.n_lens].copy()))
        print(f"{model} {fov:.0f} deg, truth xi {true.dist[0]}:")
        for xi, cost, p in sorted(rows, key=lambda r: r[0]):
            print(f"   xi {xi:+.2f}  {cost:10.3f}  fx {p[0]:7.1f}  "
                  + " ".join(f"{v:+.4f}" for v in p[5:7]))


def mixed_rig(trials: int, seed: int) -> None:
    """Three cameras on an arc (two pinhole, one wide lens of each model at 190 degrees)
    seeing a board together (:mod:`multieye.sim.overlap`, pixels projected with 0.3 px
    noise), the wide one also in 12 views of its own over its whole field; every lens started as the pipeline starts it
    (:func:`multieye.imaging.calibrate.initial_intrinsics`: OpenCV's for the pinholes, the
    generic start for the wide one) and refined with the rig
    (:func:`multieye.estimate.refine_rig.refine_rig`, lenses free)."""
    from multieye.core import geometry as g  # noqa: PLC0415
    from multieye.core.lie import log_so3  # noqa: PLC0415
    from multieye.estimate.refine_rig import refine_rig  # noqa: PLC0415
    from multieye.estimate.rig_residuals import RigViews  # noqa: PLC0415
    from multieye.imaging.calibrate import initial_intrinsics  # noqa: PLC0415
    from multieye.sim.dataset import default_intrinsics  # noqa: PLC0415
    from multieye.sim.overlap import OverlapSpec, pixel_views, simulate_overlap  # noqa: PLC0415
    from multieye.sim.wide_lens import IMAGE_SIDE, board_views, wide_lens  # noqa: PLC0415

    print(f"\n3. mixed rig: 2 pinhole + 1 wide camera (190 deg), {trials} rigs of 30 instants, "
          "0.3 px; T_ref_cam error in its covariance")
    print("wide model     NEES/6 cams 1,2  largest |error| / sigma  as from truth  "
          "wide lens NEES/dim params (mean / median)  (those)  curve params  (those)  pixels  "
          "curve without xi")
    spec = OverlapSpec(n_instants=30, width=IMAGE_SIDE, height=IMAGE_SIDE, fisheye=())
    for model in ("unified", "double-sphere", "eucm"):
        nees, worst, lens_nees, same, apart = [], [], [], [], []
        for t in range(trials):
            rng = np.random.default_rng([seed, t, 4])
            pin = default_intrinsics(2, IMAGE_SIDE, IMAGE_SIDE, fisheye=(), rng=rng)
            sc = simulate_overlap(rng, spec, intrinsics=[*pin, wide_lens(model, 190.0)])
            views = pixel_views(sc, 0.3, rng)
            # the arc's boards fill only the middle of the wide lens: 12 more views of the
            # board over its whole field, seen by it alone (as intrinsics_images would be)
            own, _ = board_views(sc.intrinsics[2], 190.0, 12, rng, noise_px=0.3)
            views[2] = views[2] + [(o, u, len(sc.T_ref_target) + k) for k, (o, u) in
                                   enumerate(own)]
            starts, T0 = [], []
            for j, vs in enumerate(views):
                kind = model if j == 2 else "pinhole-radtan4"
                st = initial_intrinsics([(o, u) for o, u, _ in vs], (IMAGE_SIDE, IMAGE_SIDE),
                                        kind)
                starts.append(st.intrinsics)
                T0.extend(st.T_cam_target)
            rv = RigViews(dict(zip("abc", views)), starts, free_intrinsics=[True] * 3)
            res = refine_rig(rv, np.array(T0), pixel_sigma=0.3)
            # the same refinement started from the true lenses: the same optimum?
            rv = RigViews(dict(zip("abc", views)), list(sc.intrinsics), free_intrinsics=[True] * 3)
            other = refine_rig(rv, np.array(T0), pixel_sigma=0.3)
            same.append(abs(res.intrinsics[2].dist[0] - other.intrinsics[2].dist[0]) < 0.05
                        or model == "eucm")
            if not same[-1]:       # sum of squares in sigma^2 against the one from the truth
                apart.append(f"rig {t}: xi {res.intrinsics[2].dist[0]:.2f} against "
                             f"{other.intrinsics[2].dist[0]:.2f}, "
                             f"{np.sum(res.residuals_px ** 2 - other.residuals_px ** 2) / 0.09:+.2f}"
                             f" (converged: {res.converged}, {other.converged})")
            for j in (1, 2):
                dR = res.T_ref_cam[j, :3, :3] @ sc.T_ref_cam[j, :3, :3].T
                e = np.concatenate([log_so3(dR), res.T_ref_cam[j, :3, 3] - sc.T_ref_cam[j, :3, 3]])
                C = res.covariance[j]
                nees.append(float(e @ np.linalg.solve(C, e)) / 6)
                worst.append(float(np.max(np.abs(e) / np.sqrt(np.diag(C)))))
            lens_nees.append(_nees(res.intrinsics[2], sc.intrinsics[2],
                                   res.intrinsics_covariance[2], 190.0))
        lens_nees, same = np.array(lens_nees), np.array(same)
        print(f"{model:<14} {np.mean(nees):>15.2f}  {np.max(worst):>23.2f}  "
              f"{same.sum():>2} of {trials:<2}  "
              f"{_mean_median(lens_nees[:, 0]):>42}  {np.mean(lens_nees[same, 0]):>8.2f}  "
              f"{_mean_median(lens_nees[:, 1]):>12}  {np.mean(lens_nees[same, 1]):>8.2f}  "
              f"{np.mean(lens_nees[:, 2]):>6.2f}  {_mean_median(lens_nees[:, 3]):>16}")
        if apart:
            print("   not as from the truth: " + "; ".join(apart))


def timing() -> None:
    from multieye.core.lens import project_points  # noqa: PLC0415
    from multieye.imaging.batch import ImageResult  # noqa: PLC0415
    from multieye.imaging.calibrate import initial_intrinsics, poses_from_detections  # noqa: PLC0415
    from multieye.imaging.detect import Detection  # noqa: PLC0415

    lens = Intrinsics(K=[[705.0, 0, 635.0], [0, 703.0, 482.0], [0, 0, 1]],
                      dist=[-0.11, 0.025, 4e-4, 2e-4, -0.003], width=1280, height=960)
    rng = np.random.default_rng(0)
    j, i = np.meshgrid(np.arange(8), np.arange(6))
    obj = np.column_stack([j.ravel() * 0.05, i.ravel() * 0.05, np.zeros(48)])
    views = []
    while len(views) < 40:
        R = np.linalg.qr(np.eye(3) + rng.normal(0, 0.3, (3, 3)))[0]
        R *= np.sign(np.diag(R))
        t = np.array([rng.uniform(-0.3, 0.1), rng.uniform(-0.2, 0.05), rng.uniform(0.6, 1.2)])
        P = obj @ R.T + t
        uv = project_points(P, lens)
        if np.all(P[:, 2] > 0) and np.all((uv > 0) & (uv < [1279, 959])):
            views.append((obj, uv + rng.normal(0, 0.3, uv.shape)))
    results = [ImageResult(f"{k}.png", None, Detection(np.arange(48), u, o), None,
                           image_size=(1280, 960)) for k, (o, u) in enumerate(views)]
    print("\n4. pinhole lens start, 40 views of 48 corners, CPU seconds (median of 5)")
    for name, call in (("initial_intrinsics", lambda: initial_intrinsics(
            views, (1280, 960), "pinhole-radtan")),
            ("poses_from_detections", lambda: poses_from_detections(results, lens))):
        cpu = []
        for _ in range(5):
            c0 = time.process_time()
            call()
            cpu.append(time.process_time() - c0)
        print(f"{name:<22} {np.median(cpu):.4f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--draws", type=int, default=60)
    ap.add_argument("--skip", default="")
    args = ap.parse_args()
    skip = set(args.skip.split(","))
    shared = Path(os.environ.get("MULTIEYE_SHARED_DATA", "../shared/data"))
    if "boofcv" not in skip:
        if (shared / "boofcv_fisheye").is_dir():
            boofcv(shared.resolve())
        else:
            print(f"1. boofcv_fisheye: not found under {shared} (set MULTIEYE_SHARED_DATA)")
    if "sim" not in skip:
        simulated(args.trials, args.seed)
    if "mc" not in skip:
        monte_carlo(args.draws, args.seed)
    if "valley" not in skip:
        valley_profile(args.seed)
    if "mixed" not in skip:
        mixed_rig(max(args.trials // 2, 1), args.seed)
    if "timing" not in skip:
        timing()


if __name__ == "__main__":
    main()
