"""The jackknife (cluster-robust) covariance against the model-based one on simulated rigs.

Run from the repository root (issue 32, item 1; docs/results/nees.md)::

    PYTHONPATH=src python benchmarks/bench_jackknife_sim.py [--images 12] [--rigs 30]
        [--shared 0.0] [--lens known]

Rigs of :func:`multieye.sim.images.simulate_images` (3 cameras, eye-to-base), corners with
independent Gaussian noise of 0.05 px plus, per image, one offset of ``--shared`` px per
axis common to all its corners; motion capture 0.03 deg / 0.1 mm, stated; the pixel noise
estimated; lenses known or estimated (``--lens unknown``).  Per covariance (the reported
model-based one, ``RefineOptions.jackknife``'s, and the larger of both in every direction,
``C + (C_jack - C)_+``): the mean over the non-reference cameras of ``|e_rot|^2 / tr(C_rot)``,
``|e_t|^2 / tr(C_t)`` and the NEES per dimension of ``T_ref_cam``.  Nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse

import numpy as np

from multieye.core.metrics import relative_extrinsics
from multieye.estimate.refine_images import refine_images
from multieye.estimate.uncertainty import pose_error, relative_covariance
from multieye.sim.images import simulate_images
from multieye.solvers import solve

ROT, TRANS, PX = np.radians(0.03), 1e-4, 0.05


def larger(C: np.ndarray, D: np.ndarray) -> np.ndarray:
    """``C + (D - C)_+``."""
    w, V = np.linalg.eigh(D - C)
    return C + (V * np.clip(w, 0.0, None)) @ V.T


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--images", type=int, default=12)
    ap.add_argument("--rigs", type=int, default=30)
    ap.add_argument("--shared", type=float, default=0.0)
    ap.add_argument("--lens", default="known", choices=("known", "unknown"))
    args = ap.parse_args(argv)
    out = {"model": [], "jackknife": [], "larger": []}
    for seed in range(args.rigs):
        sc = simulate_images(np.random.default_rng([seed, 90]), n_cameras=3, images=args.images,
                             pixel_sigma=1e-9, mocap_rot_sigma_rad=ROT, mocap_trans_sigma_m=TRANS)
        rng = np.random.default_rng([seed, 91])
        obs = [[(sc.object_points, u + rng.normal(scale=PX, size=u.shape)
                 + rng.normal(scale=args.shared, size=2), T)
                for u, T in zip(sc.image_points[j], sc.mocap[j])] for j in range(3)]
        sol = solve(list(sc.A), list(sc.B))
        res = refine_images(sc.setup, obs, sc.intrinsics, sol.X, sol.Y, mocap_rot_sigma_rad=ROT,
                            mocap_trans_sigma_m=TRANS, free_intrinsics=[args.lens == "unknown"] * 3,
                            jackknife=True)
        Cm = relative_covariance(res.X, res.covariance).covariance
        Cj = relative_covariance(res.X, res.jackknife_covariance).covariance
        true, est = relative_extrinsics(np.asarray(sc.X)), relative_extrinsics(res.X)
        for j in (1, 2):
            e = pose_error(est[j], true[j])
            for name, C in (("model", Cm[j]), ("jackknife", Cj[j]), ("larger", larger(Cm[j], Cj[j]))):
                out[name].append((e[:3] @ e[:3] / np.trace(C[:3, :3]),
                                  e[3:] @ e[3:] / np.trace(C[3:, 3:]), e @ np.linalg.solve(C, e) / 6))
    print(f"{args.rigs} rigs x 3 cameras x {args.images} images, lenses {args.lens}, shared "
          f"{args.shared} px: rot mse/var, trans mse/var, NEES")
    for name, v in out.items():
        m = np.mean(v, axis=0)
        print(f"  {name:9s} {m[0]:.2f} / {m[1]:.2f} / {m[2]:.2f}")


if __name__ == "__main__":
    main()
