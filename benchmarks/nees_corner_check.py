"""Where does hd-jpeg's excess with the lenses estimated come from?  (issue 32, item 1 and 2;
docs/results/nees.md, session 14)

Run from the repository root, after benchmarks/bench_nees.py rendered its rigs::

    PYTHONPATH=src python benchmarks/nees_corner_check.py lenses --variant hd-jpeg --seeds 0-19
    PYTHONPATH=src python benchmarks/nees_corner_check.py independent --variant hd-jpeg --seeds 0-19
    PYTHONPATH=src python benchmarks/nees_corner_check.py lens-z --variant hd-jpeg --seeds 0-7,14
        [--png] [--reseed] [--no-straightening] [--nees]

``lenses``: per rig and camera with the lenses estimated, bench_nees.py's ratios, the
joint lens, its principal point's error over the reported standard deviation and what the
run reports as not determined (run at ddfefa6 for the state before session 14's fix).

``independent``: every rig through the pipeline with the lenses estimated, each detected
corner replaced (before the refinement; the pipeline's call wrapped) by its true projection
plus independent Gaussian noise of its image's RMS against the truth: the T_ref_cam ratios
of bench_nees.py (mean, 90 % bootstrap interval over the rigs) and the joint / OpenCV lens
errors per camera on the same substituted corners.  What the estimator does given
independent, unbiased corners of the same noise.

``lens-z``: per camera, the lens its detected corners alone give, linearised about the truth
(fx fy cx cy and the distortion, each image's pose free, each image weighted by its own RMS
against the truth): the error of fx, fy, cx, cy over its standard deviation (z), mean z^2
over the cameras, and the share of z^2 from each image alone (1 for errors independent
within an image) and from pairs of images 1-5 apart and all pairs.  ``--png`` renders the
rigs again as PNG (same poses and sensor noise) into ``--out``; ``--reseed`` also moves each
image's noise seed (another noise draw, same poses); ``--no-straightening`` detects with
cornerSubPix alone; ``--nees`` also calibrates each rig with the lenses given and estimated
and prints bench_nees.py's ratios per camera.  Nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import contextlib
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

import multieye.imaging.chessboard_corners as chessboard_corners
import multieye.pipeline.refine as pipeline_refine
import multieye.sim.dataset as sim_dataset
from multieye.core.lens import project_points, project_with_jacobian
from multieye.estimate.uncertainty import pose_error
from multieye.io.intrinsics_files import read_intrinsics
from multieye.pipeline.calibrate_dataset import calibrate
import bench_nees as bn  # noqa: E402  (benchmarks/ on the path)
from nees_structure import _pose_jacobian, true_poses  # noqa: E402

bn.VARIANTS["hd-png"] = (dict(bn.VARIANTS["hd-jpeg"][0], image_format="png"),
                         bn.VARIANTS["hd-jpeg"][1])
RESEED = 7777777


def _seeds(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def _corners(folder: Path, poses: dict, rig: str = "rig.yaml"):
    """Per camera: (true lens, [(object points, detected, true projection, image name)])."""
    run = calibrate(folder / rig, processes=1)
    out = {}
    for name, cam in run.cameras.items():
        true = read_intrinsics(folder / f"{name}.yaml")
        views = []
        for o in cam.observations:
            T = poses[(name, Path(o.name).stem)]
            views.append((o.object_points, o.image_points,
                          project_points(o.object_points @ T[:3, :3].T + T[:3, 3], true), o.name))
        out[name] = (true, views)
    return out, run


def independent(args) -> None:
    plain = pipeline_refine.refine_images
    ratios, lens = [], []
    for seed in _seeds(args.seeds):
        folder = bn.rendered(args.data, args.variant, 100, seed)
        cams, _ = _corners(folder, true_poses(args.variant, 100, seed))
        rng = np.random.default_rng([seed, 5])
        table = {}
        for _, views in cams.values():
            for _, u, tp, _ in views:
                table[u.tobytes()] = tp + rng.normal(0, np.sqrt(np.mean((u - tp) ** 2)), tp.shape)

        def substituted(setup, observations, *rest):
            return plain(setup, [[(P, table[u.tobytes()], T) for P, u, T in cam]
                                 for cam in observations], *rest)

        pipeline_refine.refine_images = substituted
        try:
            run = calibrate(folder / "rig_unknown.yaml", processes=1)
        finally:
            pipeline_refine.refine_images = plain
        gt = json.loads((folder / "ground_truth.json").read_text())
        row, errs = [], []
        for name in run.T_ref_cam:
            true = read_intrinsics(folder / f"{name}.yaml")
            obs = run.cameras[name].observations
            if name != run.reference:
                e = pose_error(run.T_ref_cam[name], np.array(gt["cameras"][name]["T_ref_cam"]))
                C = run.T_ref_cam_covariance[name]
                row.append((e[:3] @ e[:3] / np.trace(C[:3, :3]),
                            e[3:] @ e[3:] / np.trace(C[3:, 3:]), e @ np.linalg.solve(C, e) / 6))
            pix = np.concatenate([o.image_points for o in obs])
            fake = [SimpleNamespace(object_points=o.object_points,
                                    image_points=table[o.image_points.tobytes()]) for o in obs]
            errs.append((bn.lens_error_after_rotation(run.refinement.intrinsics[name], true, pix),
                         bn.lens_error_after_rotation(bn.opencv_lens(fake, true), true, pix)))
        print(f"seed {seed}: " + ", ".join(f"{a:.2f}/{b:.2f}/{c:.2f}" for a, b, c in row)
              + " | lens " + ", ".join(f"{j:.4f}/{o:.4f}" for j, o in errs), flush=True)
        ratios.append(np.array(row))
        lens.append(errs)
    rng = np.random.default_rng(0)
    cells = [bn.interval([r[:, k] for r in ratios], rng) for k in range(3)]
    print("\nlenses estimated, independent corners: rot / trans / NEES "
          + " | ".join(f"{m:.2f} ({lo:.2f}-{hi:.2f})" for m, lo, hi in cells))
    a = np.array(lens)
    for c in range(a.shape[1]):
        print(f"cam{c}: joint {np.sqrt(np.mean(a[:, c, 0] ** 2)):.4f} / OpenCV "
              f"{np.sqrt(np.mean(a[:, c, 1] ** 2)):.4f} (joint <= OpenCV on "
              f"{int(np.sum(a[:, c, 0] <= a[:, c, 1]))} of {len(a)})")


class _Serial:
    """A worker pool that renders in this process with each image's noise seed moved."""

    def __init__(self, shift: int):
        self.shift = shift

    def map(self, fn, jobs, chunksize=1):
        return [fn(j[:3] + (j[3] + self.shift,) + j[4:]) for j in jobs]


def _ratios(folder: Path, rig: str) -> list[tuple[float, float, float]]:
    """bench_nees.py's three ratios of every non-reference camera of one calibration."""
    run = calibrate(folder / rig, processes=1)
    gt = json.loads((folder / "ground_truth.json").read_text())
    out = []
    for name, T in run.T_ref_cam.items():
        if name != run.reference:
            e = pose_error(T, np.array(gt["cameras"][name]["T_ref_cam"]))
            C = run.T_ref_cam_covariance[name]
            out.append((e[:3] @ e[:3] / np.trace(C[:3, :3]), e[3:] @ e[3:] / np.trace(C[3:, 3:]),
                        e @ np.linalg.solve(C, e) / 6))
    return out


def _camera_z(true, views, poses, name):
    """(z of fx fy cx cy, image share, share of pairs 1..5 apart and of all pairs)."""
    nk = len(true.params)
    blocks, es, img = [], [], []
    for i, (P, u, tp, nm) in enumerate(views):
        T = poses[(name, Path(nm).stem)]
        e = (u - tp).ravel()
        s = np.sqrt(np.mean(e ** 2))
        Jk = project_with_jacobian(P @ T[:3, :3].T + T[:3, 3], true)[2].reshape(-1, nk)
        blocks.append((Jk / s, _pose_jacobian(P, T, true) / s))
        es.append(e / s)
        img.append(np.full(e.size, i))
    m, n = sum(e.size for e in es), len(views)
    J = np.zeros((m, nk + 6 * n))
    r0 = 0
    for i, (Jk, Jp) in enumerate(blocks):
        J[r0:r0 + len(Jk), :nk] = Jk
        J[r0:r0 + len(Jk), nk + 6 * i:nk + 6 * i + 6] = Jp
        r0 += len(Jk)
    e, img = np.concatenate(es), np.concatenate(img)
    N = J.T @ J
    G = np.linalg.solve(N, J.T)[:4]
    z = (G @ e) / np.sqrt(np.diag(np.linalg.inv(N))[:4])
    own, pairs = [], []
    for p in range(4):
        per = np.bincount(img, G[p] * e)
        tot = np.sum(np.bincount(img, G[p] ** 2))
        own.append(np.sum(per ** 2) / tot)
        pairs.append([2 * np.sum(per[:-k] * per[k:]) / tot for k in range(1, 6)]
                     + [(np.sum(per) ** 2 - np.sum(per ** 2)) / tot])
    return z, np.array(own), np.array(pairs)


def lens_z(args) -> None:
    variant = "hd-png" if args.png and args.variant == "hd-jpeg" else args.variant
    if args.no_straightening:
        chessboard_corners.refine_straightened = lambda gray, pts, rows, cols, half: pts
    Z, own, pairs = [], [], []
    for seed in _seeds(args.seeds):
        data = args.out / ("reseed" if args.reseed else "same") if args.png else args.data
        if args.reseed:
            plain = sim_dataset.worker_pool
            sim_dataset.worker_pool = lambda n: contextlib.nullcontext(_Serial(RESEED))
        try:
            folder = bn.rendered(data, variant, 100, seed)
        finally:
            if args.reseed:
                sim_dataset.worker_pool = plain
        poses = true_poses(variant, 100, seed)
        cams, _ = _corners(folder, poses)
        if args.nees:
            for rig in ("rig.yaml", "rig_unknown.yaml"):
                print(f"seed {seed} {rig}: rot / trans / NEES per camera "
                      + ", ".join(f"{a:.2f}/{b:.2f}/{c:.2f}" for a, b, c in _ratios(folder, rig)))
        for name, (true, views) in cams.items():
            z, o, p = _camera_z(true, views, poses, name)
            print(f"seed {seed} {name} ({true.model}): z of fx fy cx cy "
                  + " ".join(f"{v:+.2f}" for v in z), flush=True)
            Z.append(z)
            own.append(o)
            pairs.append(p)
    Z, own, pairs = np.array(Z), np.array(own), np.array(pairs)
    print(f"\n{len(Z)} cameras: mean z^2 (fx fy cx cy) " + " ".join(f"{v:.2f}" for v in
                                                                   (Z ** 2).mean(0)))
    print("share of each image alone " + " ".join(f"{v:.3f}" for v in own.mean(0)))
    print("pairs 1..5 apart, all pairs (per parameter):")
    print(pairs.mean(0).round(2))


def lenses(args) -> None:
    """Per rig and camera, lenses estimated: the ratios, the lens, the principal point's error
    over its reported standard deviation, and the families reported as not determined."""
    np.set_printoptions(precision=3, suppress=True, linewidth=150)
    for seed in _seeds(args.seeds):
        folder = bn.rendered(args.data, args.variant, 100, seed)
        run = calibrate(folder / "rig_unknown.yaml", processes=1)
        gt = json.loads((folder / "ground_truth.json").read_text())
        res = run.refinement.result
        for name in run.T_ref_cam:
            true = read_intrinsics(folder / f"{name}.yaml")
            est = run.refinement.intrinsics[name]
            sd = np.sqrt(np.diag(run.refinement.intrinsics_covariance[name]))
            d = est.params - true.params
            text = ""
            if name != run.reference:
                e = pose_error(run.T_ref_cam[name], np.array(gt["cameras"][name]["T_ref_cam"]))
                C = run.T_ref_cam_covariance[name]
                text = (f"rot {e[:3] @ e[:3] / np.trace(C[:3, :3]):.2f} trans "
                        f"{e[3:] @ e[3:] / np.trace(C[3:, 3:]):.2f} NEES "
                        f"{e @ np.linalg.solve(C, e) / 6:.2f}; ")
            print(f"seed {seed} {name}: {text}cx {d[2]:+.3f} px (sd {sd[2]:.3f}), fx sd "
                  f"{sd[0]:.3f}; distortion {est.dist}; not determined: "
                  f"{', '.join(res.undetermined) or '-'}", flush=True)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=("independent", "lens-z", "lenses"))
    ap.add_argument("--variant", default="hd-jpeg")
    ap.add_argument("--seeds", default="0-19")
    ap.add_argument("--data", type=Path, default=Path("/tmp/bench_nees"))
    ap.add_argument("--out", type=Path, default=Path("/tmp/nees_corner_check"))
    ap.add_argument("--png", action="store_true")
    ap.add_argument("--reseed", action="store_true")
    ap.add_argument("--no-straightening", action="store_true")
    ap.add_argument("--nees", action="store_true", help="lens-z: also each rig's ratios")
    args = ap.parse_args(argv)
    {"independent": independent, "lens-z": lens_z, "lenses": lenses}[args.what](args)


if __name__ == "__main__":
    main()
