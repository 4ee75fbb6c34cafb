"""The former motion-capture noise estimator itself, on bench_mocap_noise.py's rigs.

bench_mocap_noise.py's "corrections" rows emulate the former estimator (the RMS of the
refinement's corrections of the measured poses, iterated) in a loop outside
``refine_images``.  This script runs whatever ``refine_images`` is importable with the noise
left to be estimated, on the same simulated rigs and seeds, so that pointed at the source
before the variance components (commit 1344814~1) it measures the former code as it was::

    mkdir -p /tmp/oldsrc && git archive 1344814~1 src | tar -x -C /tmp/oldsrc
    PYTHONPATH=/tmp/oldsrc/src python benchmarks/bench_mocap_noise_former.py [--trials 100]

(and with ``PYTHONPATH=src`` it gives bench_mocap_noise.py's "VCE" rows again).  It prints
the rows of bench_mocap_noise.py's table.  A script, not a test: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import time

import numpy as np

from multieye.core.lie import log_so3
from multieye.estimate.refine_images import refine_images
from multieye.sim.images import simulate_images
from multieye.solvers import solve

#: bench_mocap_noise.CONFIGS, repeated so that this script runs against an older source.
CONFIGS = (
    ("robot cell, 1 x 8, eye-on-hand", "eye-on-hand", 1, 8, 0.03, 0.2e-3),
    ("robot cell, 1 x 15, eye-on-hand", "eye-on-hand", 1, 15, 0.03, 0.2e-3),
    ("mocap rig, 4 x 40, eye-to-base", "eye-to-base", 4, 40, 0.1, 0.3e-3),
)


def _err(T, T_true):
    return np.concatenate([log_so3(T[:3, :3] @ T_true[:3, :3].T), T[:3, 3] - T_true[:3, 3]])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    import multieye

    print(f"refine_images from {os.path.dirname(multieye.__file__)}, seed {args.seed}")
    t0 = time.perf_counter()
    for k, (label, setup, m, n, rot_deg, trans_m) in enumerate(CONFIGS):
        rot, rows = np.radians(rot_deg), []
        for t in range(args.trials):
            sc = simulate_images(np.random.default_rng([args.seed + 1000 * k, t]), n_cameras=m,
                                 images=n, setup=setup, pixel_sigma=0.3,
                                 mocap_rot_sigma_rad=rot, mocap_trans_sigma_m=trans_m)
            sol = solve(sc.A, sc.B)
            res = refine_images(sc.setup, sc.observations, sc.intrinsics, sol.X, sol.Y,
                                mocap_rot_sigma_rad=None, mocap_trans_sigma_m=None)
            e = np.concatenate([_err(res.X[j], sc.truth.X[j]) for j in range(m)]
                               + [_err(res.Y, sc.truth.Y)])
            rows.append((res.mocap_rot_sigma_rad / rot, res.mocap_trans_sigma_m / trans_m,
                         float(e @ np.linalg.solve(res.covariance, e)) / e.size))
        r = np.array(rows)
        collapsed = np.mean((r[:, 0] < 0.1) | (r[:, 1] < 0.1))
        print(f"| {label} | refine_images as imported | {args.trials} | {np.median(r[:, 0]):.2f} "
              f"| {np.median(r[:, 1]):.2f} | {100 * collapsed:.0f} % | {np.mean(r[:, 2]):.2f} |",
              flush=True)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
