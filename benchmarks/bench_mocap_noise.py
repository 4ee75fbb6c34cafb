"""Motion-capture (robot) noise estimated from the data: does it collapse, is X's std honest?

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_mocap_noise.py [--trials 100] [--seed 0] [--quick]

When rig.yaml does not state the motion-capture noise, :func:`multieye.estimate.
refine_images.refine_images` estimates it.  Two estimators side by side on the same simulated
rigs (:func:`multieye.sim.images.simulate_images`, pixel noise 0.3 px, true pose noise per
configuration, Huber loss, pixel noise estimated too):

- ``corrections`` (multieye before this benchmark): the RMS of how far the refinement moves
  the measured poses, iterated with the refinement (:func:`estimate_mocap_noise`, run here
  in the loop the refinement used to run: up to 6 passes);
- ``VCE``: variance-component estimation with each component's redundancy (what
  ``refine_images`` does now).

Per configuration it prints the median estimated rotation and position noise over the true
one, the share of trials where an estimate collapsed (below a tenth of the truth), and the
mean NEES per dimension of every camera's X and of Y together (``e^T C^-1 e / (6 (m + 1))``, 1
for an honest covariance), with the same NEES for the noise stated (the truth) as reference.
Configurations: a robot cell (one camera, 8 and 15 images, eye-on-hand, 0.03 deg / 0.2 mm per
pose) and a motion-capture rig (4 cameras x 40 images, eye-to-base, 0.1 deg / 0.3 mm).
This is a script, not a test: nothing here is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import time

import numpy as np

from multieye.estimate.refine_images import estimate_mocap_noise, refine_images
from multieye.sim.images import simulate_images
from multieye.solvers import solve
from multieye.estimate.uncertainty import pose_error

CONFIGS = (  # label, setup, cameras, images, rot noise (deg), trans noise (m)
    ("robot cell, 1 x 8, eye-on-hand", "eye-on-hand", 1, 8, 0.03, 0.2e-3),
    ("robot cell, 1 x 15, eye-on-hand", "eye-on-hand", 1, 15, 0.03, 0.2e-3),
    ("mocap rig, 4 x 40, eye-to-base", "eye-to-base", 4, 40, 0.1, 0.3e-3),
)



def _nees(res, sc) -> float:
    e = np.concatenate([pose_error(res.X[j], sc.truth.X[j]) for j in range(sc.n_cameras)]
                       + [pose_error(res.Y, sc.truth.Y)])
    return float(e @ np.linalg.solve(res.covariance, e)) / e.size


def _corrections(sc, X0, Y0, s_rot, s_t):
    """The former estimator: refine, set the noise to the RMS correction, repeat."""
    measured = np.concatenate(sc.mocap)
    for _ in range(6):
        res = refine_images(sc.setup, sc.observations, sc.intrinsics, X0, Y0,
                            mocap_rot_sigma_rad=s_rot, mocap_trans_sigma_m=s_t)
        new = estimate_mocap_noise(measured, np.concatenate(res.T_world_mocap))
        if max(abs(new[0] / s_rot - 1), abs(new[1] / s_t - 1)) < 0.1:
            s_rot, s_t = new
            break
        s_rot, s_t = new
    return refine_images(sc.setup, sc.observations, sc.intrinsics, X0, Y0,
                         mocap_rot_sigma_rad=s_rot, mocap_trans_sigma_m=s_t)


def run(label, setup, m, n, rot_deg, trans_m, trials, seed) -> None:
    rot = np.radians(rot_deg)
    rows = {"stated": [], "corrections": [], "VCE": []}
    seconds = []
    for t in range(trials):
        sc = simulate_images(np.random.default_rng([seed, t]), n_cameras=m, images=n,
                             setup=setup, pixel_sigma=0.3, mocap_rot_sigma_rad=rot,
                             mocap_trans_sigma_m=trans_m)
        sol = solve(sc.A, sc.B)
        stated = refine_images(sc.setup, sc.observations, sc.intrinsics, sol.X, sol.Y,
                               mocap_rot_sigma_rad=rot, mocap_trans_sigma_m=trans_m)
        start = time.perf_counter()
        vce = refine_images(sc.setup, sc.observations, sc.intrinsics, sol.X, sol.Y,
                            mocap_rot_sigma_rad=None, mocap_trans_sigma_m=None)
        seconds.append(time.perf_counter() - start)
        old = _corrections(sc, sol.X, sol.Y, 1e-3, 1e-3)
        for key, res in (("stated", stated), ("corrections", old), ("VCE", vce)):
            rows[key].append((res.mocap_rot_sigma_rad / rot, res.mocap_trans_sigma_m / trans_m,
                              _nees(res, sc)))
    for key, r in rows.items():
        r = np.array(r)
        collapsed = np.mean((r[:, 0] < 0.1) | (r[:, 1] < 0.1))
        print(f"| {label} | {key} | {trials} | {np.median(r[:, 0]):.2f} | "
              f"{np.median(r[:, 1]):.2f} | {100 * collapsed:.0f} % | {np.mean(r[:, 2]):.2f} |"
              + (f" {np.median(seconds):.2f} |" if key == "VCE" else " |"), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="10 trials per configuration")
    args = ap.parse_args()
    trials = 10 if args.quick else args.trials
    print(f"seed {args.seed}, {os.cpu_count()} cores; NEES of X and Y per dimension, 95 % band "
          f"of an honest mean about +-{1.96 * np.sqrt(2 / (trials * 12)):.2f} (1 camera)\n")
    print("| configuration | pose noise | trials | rotation estimate / truth (median) "
          "| position estimate / truth (median) | collapsed | NEES X, Y | median s (VCE) |")
    print("|---|---|---|---|---|---|---|---|")
    t0 = time.perf_counter()
    for k, c in enumerate(CONFIGS):
        run(*c, trials, args.seed + 1000 * k)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
