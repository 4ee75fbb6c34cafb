"""Is the reported uncertainty of ``T_ref_cam`` honest, and is the joint lens at least OpenCV's?

Run from the repository root (issue 32, items 1 and 2)::

    PYTHONPATH=src python benchmarks/bench_nees.py [--rigs 20] [--images 12 100]
        [--variants base,hd-jpeg,noisy] [--data /tmp/bench_nees] [--lens known,unknown]

Rigs rendered by :func:`multieye.sim.dataset.render_dataset` (eye-to-base, three cameras,
a motion-captured chessboard, mocap noise 0.03 deg / 0.1 mm, stated in rig.yaml; images with
blur and sensor noise), in variants that change what the images look like (``VARIANTS``:
image size, PNG or JPEG, board, sensor noise and so the corner noise, lens families), each
with ``--images`` images per camera.  Every rig goes through the whole pipeline
(:func:`multieye.pipeline.calibrate`: detection, pairing with the motion capture, closed
form, image-level refinement with the pixel noise estimated) twice: with the true lenses
given (``known``) and with every lens estimated from the recording in its true model
(``unknown``).

Item 1: per variant, images and lenses, the mean over every non-reference camera of
``|e_rot|^2 / tr(C_rot)`` and ``|e_t|^2 / tr(C_t)`` (squared error over predicted variance,
``e`` the error of ``T_ref_cam`` in the covariance's convention, ``C`` its reported
covariance) and the NEES per dimension ``e^T C^-1 e / 6``: 1 for an honest covariance.  The
spread: a 90 % interval of each mean by bootstrap over the rigs (the cameras of one rig
resampled together), and the median estimated corner noise.  With ``--jackknife`` also the
same three figures for the cluster-robust covariance (``RefineOptions.jackknife``: the
delete-one-instant jackknife, :mod:`multieye.optimize.clusters`; the pipeline's call of
``refine_images`` is wrapped here to ask for it) and for the larger of the two in every
direction (``C + (C_jack - C)_+``), beside the reported one.

Item 2 (lenses unknown): per camera, the projection error of the joint lens and of OpenCV's
per-camera calibration (``cv2.calibrateCamera`` in the same model, ``cv2.fisheye.calibrate``
for the fisheye) on the same detected corners, against the true lens over the observed
corners, after the best-fitting rotation (``benchmarks/peers/lens_error.py``): RMS over the
rigs, and on how many rigs the joint lens is at most OpenCV's.  This is a script: nothing is
asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

import multieye.pipeline.refine as pipeline_refine
from multieye.core.intrinsics import Intrinsics, lens_model
from multieye.core.lens import project_points, undistort_points
from multieye.estimate.uncertainty import pose_error, relative_covariance
from multieye.io.intrinsics_files import read_intrinsics
from multieye.pipeline.calibrate_dataset import calibrate
from multieye.sim.dataset import DatasetSpec, default_intrinsics, render_dataset

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
from lens_error import errors  # noqa: E402

#: name: (DatasetSpec fields, lens families by camera: "radtan" default, "rational", "fisheye")
VARIANTS = {
    "base": (dict(width=800, height=600), ("radtan", "radtan", "radtan")),
    "hd-jpeg": (dict(width=1280, height=720, image_format="jpg", noise_sigma=6.0,
                     target={"type": "chessboard", "rows": 5, "cols": 8, "spacing": 0.06}),
                ("radtan", "rational", "fisheye")),
    "noisy": (dict(width=640, height=480, noise_sigma=14.0, blur_sigma=1.0,
                   target={"type": "chessboard", "rows": 7, "cols": 10, "spacing": 0.04}),
              ("radtan", "fisheye", "radtan")),
    "full-hd": (dict(width=1920, height=1080, image_format="jpg", noise_sigma=4.0),
                ("rational", "radtan", "radtan")),
}


def _intrinsics(families, width: int, height: int, seed: int) -> list[Intrinsics]:
    rng = np.random.default_rng([seed, 77])
    fisheye = tuple(j for j, f in enumerate(families) if f == "fisheye")
    out = default_intrinsics(len(families), width, height, fisheye=fisheye, rng=rng)
    for j, f in enumerate(families):
        if f == "rational":      # the radial-tangential lens with a rational denominator
            d = out[j].dist
            rational = [d[0], d[1], d[2], d[3], 0.01, rng.uniform(0.02, 0.05),
                        rng.uniform(-0.01, 0.01), rng.uniform(-0.005, 0.005)]
            out[j] = Intrinsics(K=out[j].K, dist=rational, model="pinhole", width=width,
                                height=height)
    return out


def rendered(data: Path, variant: str, images: int, seed: int) -> Path:
    """The rig's folder (rendered once), with ``rig_unknown.yaml`` beside its rig.yaml."""
    fields, families = VARIANTS[variant]
    folder = data / f"{variant}_{images}" / f"s{seed}"
    if not (folder / "rig_unknown.yaml").exists():
        spec = DatasetSpec(n_cameras=len(families), images_per_camera=images, **fields)
        intr = _intrinsics(families, spec.width, spec.height, seed)
        render_dataset(folder, spec, seed=seed, intrinsics=intr)
        text = (folder / "rig.yaml").read_text()
        for j, lens in enumerate(intr):
            text = text.replace(f"    intrinsics: cam{j}.yaml",
                                f"    model: {lens_model(lens)}")
        (folder / "rig_unknown.yaml").write_text(text)
    return folder


def opencv_lens(obs, true: Intrinsics) -> Intrinsics:
    """OpenCV's per-camera calibration in ``true``'s model from the views ``obs``."""
    obj = [o.object_points.astype(np.float32) for o in obs]
    img = [o.image_points.astype(np.float32) for o in obs]
    size = (true.width, true.height)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    if true.model == "fisheye":
        flags = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
        _, K, d, _, _ = cv2.fisheye.calibrate([p.reshape(-1, 1, 3) for p in obj],
                                              [p.reshape(-1, 1, 2) for p in img], size, None,
                                              None, flags=flags, criteria=crit)
        return Intrinsics(K=K, dist=d.ravel(), model="fisheye", width=size[0], height=size[1])
    n = true.dist.size
    flags = {4: cv2.CALIB_FIX_K3, 5: 0, 8: cv2.CALIB_RATIONAL_MODEL}[n]
    _, K, d, _, _ = cv2.calibrateCamera(obj, img, size, None, None, flags=flags, criteria=crit)
    return Intrinsics(K=K, dist=d.ravel()[:n], model="pinhole", width=size[0], height=size[1])


def lens_error_after_rotation(est: Intrinsics, true: Intrinsics, pixels: np.ndarray) -> float:
    """RMS projection error of ``est`` against ``true`` over the rays of ``pixels``, px,
    after the best-fitting rotation."""
    xy = undistort_points(pixels, true)
    rays = np.column_stack([xy, np.ones(len(xy))])
    rays = rays[np.all(np.isfinite(rays), axis=1)]
    return errors(lambda r: project_points(r, est), rays, project_points(rays, true))[1]


def ask_for_the_jackknife() -> None:
    """Make the pipeline's image refinement also form the jackknife covariance."""
    plain = pipeline_refine.refine_images

    def with_jackknife(setup, observations, intrinsics, X0, Y0, options):
        return plain(setup, observations, intrinsics, X0, Y0, replace(options, jackknife=True))

    pipeline_refine.refine_images = with_jackknife


def _larger(C: np.ndarray, D: np.ndarray) -> np.ndarray:
    """``C + (D - C)_+``: at least C and at least D in every direction."""
    w, V = np.linalg.eigh(D - C)
    return C + (V * np.clip(w, 0.0, None)) @ V.T


def _ratios(out: dict, suffix: str, e: np.ndarray, C: np.ndarray) -> None:
    out.setdefault("rot" + suffix, []).append(e[:3] @ e[:3] / np.trace(C[:3, :3]))
    out.setdefault("trans" + suffix, []).append(e[3:] @ e[3:] / np.trace(C[3:, 3:]))
    out.setdefault("nees" + suffix, []).append(e @ np.linalg.solve(C, e) / 6)


def one_run(folder: Path, lens: str) -> dict:
    """Calibrate one rendered rig; its T_ref_cam ratios and (lenses unknown) lens errors."""
    truth = {}
    gt = json.loads((folder / "ground_truth.json").read_text())
    run = calibrate(folder / ("rig.yaml" if lens == "known" else "rig_unknown.yaml"),
                    processes=1)
    names = list(run.T_ref_cam)
    res = run.refinement.result
    jack = None if res.jackknife_covariance is None else relative_covariance(
        res.X, res.jackknife_covariance, names.index(run.reference)).covariance
    out = {"sigma": res.pixel_sigma, "joint": [], "opencv": []}
    for j, name in enumerate(names):
        if name == run.reference:
            continue
        e = pose_error(run.T_ref_cam[name], np.array(gt["cameras"][name]["T_ref_cam"]))
        C = run.T_ref_cam_covariance[name]
        _ratios(out, "", e, C)
        if jack is not None:
            _ratios(out, "_jack", e, jack[j])
            _ratios(out, "_max", e, _larger(C, jack[j]))
    if lens == "unknown":
        for name in names:
            true = truth.setdefault(name, read_intrinsics(folder / f"{name}.yaml"))
            obs = run.cameras[name].observations
            pixels = np.concatenate([o.image_points for o in obs])
            out["joint"].append(lens_error_after_rotation(run.refinement.intrinsics[name], true,
                                                          pixels))
            out["opencv"].append(lens_error_after_rotation(opencv_lens(obs, true), true,
                                                           pixels))
    return out


def interval(rows: list[list[float]], rng: np.random.Generator) -> tuple[float, float, float]:
    """Mean over every camera of every rig, and a 90 % bootstrap interval over the rigs."""
    per_rig = [np.asarray(r) for r in rows]
    mean = float(np.mean(np.concatenate(per_rig)))
    boot = []
    for _ in range(2000):
        pick = rng.integers(0, len(per_rig), len(per_rig))
        boot.append(np.mean(np.concatenate([per_rig[k] for k in pick])))
    lo, hi = np.percentile(boot, [5, 95])
    return mean, float(lo), float(hi)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rigs", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--images", type=int, nargs="+", default=[12, 100])
    ap.add_argument("--variants", default="base,hd-jpeg,noisy")
    ap.add_argument("--lens", default="known,unknown")
    ap.add_argument("--data", type=Path, default=Path("/tmp/bench_nees"))
    ap.add_argument("--jackknife", action="store_true")
    args = ap.parse_args(argv)
    if args.jackknife:
        ask_for_the_jackknife()
    kinds = [""] + (["_jack", "_max"] if args.jackknife else [])
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    print(f"{args.rigs} rigs per row (seeds {args.first_seed}.."
          f"{args.first_seed + args.rigs - 1}), {os.cpu_count()} cores\n")
    extra = "".join(f" | rot / trans / NEES {k[1:]}" for k in kinds[1:])
    print("| variant | lenses (families) | images | corner noise px (median) | rot mse/var "
          "(90 %) | trans mse/var (90 %) | NEES (90 %)" + extra + " |")
    print("|---|---|---|---|---|---|---|" + "---|" * (len(kinds) - 1))
    lens_rows = []
    for variant in args.variants.split(","):
        families = VARIANTS[variant][1]
        for images in args.images:
            for lens in args.lens.split(","):
                runs = []
                for s in range(args.first_seed, args.first_seed + args.rigs):
                    try:
                        runs.append(one_run(rendered(args.data, variant, images, s), lens))
                    except Exception as e:  # noqa: BLE001  (named in the output, left out)
                        print(f"({variant}, lenses {lens}, {images} images, seed {s}: the "
                              f"calibration failed, left out: {type(e).__name__}: {e})", flush=True)
                cells = [interval([r[k] for r in runs], rng) for k in ("rot", "trans", "nees")]
                more = [" / ".join(f"{np.mean(np.concatenate([r[q + k] for r in runs])):.2f}"
                                   for q in ("rot", "trans", "nees")) for k in kinds[1:]]
                rigs = "" if len(runs) == args.rigs else f", {len(runs)} rigs"
                print(f"| {variant} | {lens} ({', '.join(families)}{rigs}) | {images} | "
                      f"{np.median([r['sigma'] for r in runs]):.3f} | "
                      + " | ".join([f"{m:.2f} ({lo:.2f}-{hi:.2f})" for m, lo, hi in cells] + more)
                      + " |", flush=True)
                if lens == "unknown":
                    lens_rows.append((variant, images, families, runs))
    if lens_rows:
        print("\nLens error after the best-fitting rotation, px, RMS over the rigs: joint / "
              "OpenCV per camera (rigs where joint <= OpenCV)\n")
        print("| variant | images | cam0 | cam1 | cam2 |")
        print("|---|---|---|---|---|")
        for variant, images, families, runs in lens_rows:
            j = np.array([r["joint"] for r in runs])
            o = np.array([r["opencv"] for r in runs])
            cells = [f"{families[c]}: {np.sqrt(np.mean(j[:, c] ** 2)):.4f} / "
                     f"{np.sqrt(np.mean(o[:, c] ** 2)):.4f} ({int(np.sum(j[:, c] <= o[:, c]))} "
                     f"of {len(runs)})" for c in range(j.shape[1])]
            print(f"| {variant} | {images} | " + " | ".join(cells) + " |", flush=True)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
