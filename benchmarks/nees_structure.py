"""What structure have the rendered rigs' corner errors?  (issue 32, item 1; docs/results/nees.md)

Run from the repository root, after benchmarks/bench_nees.py rendered its rigs::

    PYTHONPATH=src python benchmarks/nees_structure.py [--rigs 20] [--images 100]
        [--variants base,hd-jpeg,noisy] [--data /tmp/bench_nees]

Each rig's detected corners (the pipeline's detection, :func:`multieye.pipeline.calibrate`)
are compared with the true projections: the true board pose of every image is replayed from
:func:`multieye.sim.dataset.render_dataset`'s random draws with the rendering skipped (its
worker pool replaced by one that only collects the jobs), through the true lens.  Per
camera, over its images in time order (``e`` a corner's error, pixels):

- ``rms``: RMS of ``e``; ``spread``: largest over smallest image RMS; ``rms lag 1``: the
  correlation of consecutive images' RMS (smooth in time: heteroscedastic images);
- within an image: ``mean``: the squared mean of its errors over what independent errors of
  its RMS give (1 when independent); ``pose``: the same for the part of ``e`` a change of the
  board's pose explains (the 6 columns of ``d pixels / d T_cam_target``);
- across images: ``lag 1`` / ``lag 4``: correlation of consecutive (and 4 apart) images'
  whitened pose-like components;
- systematic: ``radial``: the mean error along the direction from the image's corner centroid
  to the corner (outward > 0), 1e-3 px, and its t statistic over the camera's corners;
  ``depth z``: the pose-like error pooled over the camera's images, whitened, along the
  optical axis (N(0, 1) for an unbiased detector).

Then the causal check: the per-corner mean radial error measured on the first half of the
rigs is subtracted from the detected corners of the second half before the refinement (the
pipeline's call wrapped), and the NEES per dimension of ``T_ref_cam`` (lenses known) is
given with and without it.  Nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import contextlib
import json
import tempfile
from pathlib import Path

import numpy as np

import multieye.pipeline.refine as pipeline_refine
import multieye.sim.dataset as sim_dataset
from multieye.core.lens import project_points
from multieye.core.lie import exp_so3
from multieye.estimate.uncertainty import pose_error
from multieye.io.intrinsics_files import read_intrinsics
from multieye.pipeline.calibrate_dataset import calibrate
from bench_nees import VARIANTS, _intrinsics, rendered  # noqa: E402  (benchmarks/ on the path)


def true_poses(variant: str, images: int, seed: int) -> dict:
    """``{(camera, image stem): T_cam_target}`` of a rendered rig, replayed without rendering."""
    fields, families = VARIANTS[variant]
    spec = sim_dataset.DatasetSpec(n_cameras=len(families), images_per_camera=images, **fields)
    intr = _intrinsics(families, spec.width, spec.height, seed)
    jobs = []

    class Collect:
        def map(self, fn, js, chunksize=1):
            jobs.extend(js)
            return []

    plain = sim_dataset.worker_pool
    sim_dataset.worker_pool = lambda n: contextlib.nullcontext(Collect())
    try:
        with tempfile.TemporaryDirectory() as d:
            sim_dataset.render_dataset(d, spec, seed=seed, intrinsics=intr)
    finally:
        sim_dataset.worker_pool = plain
    return {(job[6].parent.name, job[6].stem): job[2] for job in jobs}


def _pose_jacobian(P: np.ndarray, T: np.ndarray, lens) -> np.ndarray:
    """d pixels / d (rotation vector, translation) of ``T_cam_target``, left perturbation."""
    def proj(d):
        R = exp_so3(d[:3]) @ T[:3, :3]
        return project_points(P @ R.T + T[:3, 3] + d[3:], lens).ravel()
    h, J = 1e-6, np.zeros((2 * len(P), 6))
    for k in range(6):
        d = np.zeros(6)
        d[k] = h
        J[:, k] = (proj(d) - proj(-d)) / (2 * h)
    return J


def _lag(x: np.ndarray, lag: int) -> float:
    a, b = x[:-lag] - x[:-lag].mean(0), x[lag:] - x[lag:].mean(0)
    return float(np.mean(np.sum(a * b, 0) / np.sqrt(np.sum(a * a, 0) * np.sum(b * b, 0))))


def camera_structure(obs: list, poses: dict, name: str, lens) -> tuple[dict, dict]:
    """The figures of one camera (module docstring), and its corners' radial errors by
    board point."""
    rms, mean, pose, coef, radial, by_point = [], [], [], [], [], {}
    A, b = np.zeros((6, 6)), np.zeros(6)
    for o in sorted(obs, key=lambda o: o.stamp):
        T = poses[(name, Path(o.name).stem)]
        P, u = o.object_points, o.image_points
        e = u - project_points(P @ T[:3, :3].T + T[:3, 3], lens)
        s2 = float(np.mean(e ** 2))
        J = _pose_jacobian(P, T, lens)
        c = np.linalg.lstsq(J, e.ravel(), rcond=None)[0]
        rms.append(np.sqrt(s2))
        mean.append(np.sum(e.mean(0) ** 2) / (2 * s2 / len(e)))
        pose.append((J @ c) @ (J @ c) / 6 / s2)
        coef.append(np.linalg.cholesky(J.T @ J).T @ c / np.sqrt(s2))
        A += J.T @ J / s2
        b += J.T @ e.ravel() / s2
        d = u - u.mean(0)
        r = np.sum(e * d / np.linalg.norm(d, axis=1)[:, None], axis=1)
        radial.append(r)
        for p, ri in zip(P, r):
            by_point.setdefault((round(p[0], 5), round(p[1], 5)), []).append(ri)
    rms, coef, radial = np.array(rms), np.array(coef), np.concatenate(radial)
    z = np.linalg.cholesky(A).T @ np.linalg.solve(A, b)
    return dict(rms=rms.mean(), spread=rms.max() / rms.min(), rms_lag1=_lag(rms[:, None], 1),
                mean=np.mean(mean), pose=np.mean(pose), lag1=_lag(coef, 1), lag4=_lag(coef, 4),
                radial=1e3 * radial.mean(), t=radial.mean() / radial.std() * np.sqrt(radial.size),
                depth_z=z[5]), by_point


def nees(folder: Path, correction: dict | None) -> list[float]:
    """NEES per dimension of every non-reference T_ref_cam, lenses known, the detected
    corners moved inward by ``correction`` (per board point, px) before the refinement."""
    plain = pipeline_refine.refine_images

    def corrected(setup, observations, *args):
        moved = []
        for cam in observations:
            views = []
            for P, u, T in cam:
                d = u - u.mean(0)
                r = np.array([correction.get((round(p[0], 5), round(p[1], 5)), 0.0) for p in P])
                views.append((P, u - r[:, None] * d / np.linalg.norm(d, axis=1)[:, None], T))
            moved.append(views)
        return plain(setup, moved, *args)

    if correction is not None:
        pipeline_refine.refine_images = corrected
    try:
        run = calibrate(folder / "rig.yaml", processes=1)
    finally:
        pipeline_refine.refine_images = plain
    gt = json.loads((folder / "ground_truth.json").read_text())
    out = []
    for name, T in run.T_ref_cam.items():
        if name != run.reference:
            e = pose_error(T, np.array(gt["cameras"][name]["T_ref_cam"]))
            out.append(float(e @ np.linalg.solve(run.T_ref_cam_covariance[name], e)) / 6)
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rigs", type=int, default=20)
    ap.add_argument("--images", type=int, default=100)
    ap.add_argument("--variants", default="base,hd-jpeg,noisy")
    ap.add_argument("--data", type=Path, default=Path("/tmp/bench_nees"))
    args = ap.parse_args(argv)
    keys = ("rms", "spread", "rms_lag1", "mean", "pose", "lag1", "lag4", "radial", "t", "depth_z")
    print(f"{args.rigs} rigs x 3 cameras x {args.images} images; per figure the median over the "
          "cameras [smallest, largest]\n")
    print("| variant | " + " | ".join(keys) + " | NEES | NEES corrected |")
    print("|---|" + "---|" * (len(keys) + 2))
    for variant in args.variants.split(","):
        rows, points, half = [], [], args.rigs // 2
        nees_plain, nees_corr = [], []
        for seed in range(args.rigs):
            folder = rendered(args.data, variant, args.images, seed)
            poses = true_poses(variant, args.images, seed)
            run = calibrate(folder / "rig.yaml", processes=1)
            for name, cam in run.cameras.items():
                figures, by_point = camera_structure(cam.observations, poses, name,
                                                     read_intrinsics(folder / f"{name}.yaml"))
                rows.append(figures)
                if seed < half:
                    points.append(by_point)
        correction = {}
        for by_point in points:
            for p, r in by_point.items():
                correction.setdefault(p, []).extend(r)
        correction = {p: float(np.mean(r)) for p, r in correction.items()}
        for seed in range(half, args.rigs):
            folder = rendered(args.data, variant, args.images, seed)
            nees_plain += nees(folder, None)
            nees_corr += nees(folder, correction)
        cells = []
        for k in keys:
            v = np.array([r[k] for r in rows])
            f = ".3f" if k == "rms" else ".2f"
            cells.append(f"{np.median(v):{f}} [{v.min():{f}}, {v.max():{f}}]")
        print(f"| {variant} | " + " | ".join(cells)
              + f" | {np.mean(nees_plain):.2f} | {np.mean(nees_corr):.2f} |", flush=True)


if __name__ == "__main__":
    main()
