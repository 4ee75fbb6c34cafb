"""Informative image selection against a fixed stride and against all images.

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_selection.py [IMAGES BUDGET SEEDS [RICH_PERCENT]]
    # default 900 100 5 20

On uneven recordings (``multieye.sim.recordings.simulate_recording``: 3 cameras x IMAGES at
30 Hz, the board waved richly in RICH_PERCENT (20) % of each camera's segment, slowly the
rest of the time; 0.3 px pixel noise, motion capture 0.1 deg / 0.3 mm), each of SEEDS recordings is
calibrated (closed form, then the image-level refinement with the noise given) from all
images, from BUDGET images per camera chosen before decoding
(``multieye.estimate.selection.select_before_decoding``, motion-capture poses only) and from
every k-th image of the same count.  Prints a Markdown table: per run and seed the RMS over
the non-reference cameras of the ``T_ref_cam`` error against the truth (rotation degrees,
translation millimetres) and of the predicted standard deviation (root of the trace), then
the means over the seeds.
"""
from __future__ import annotations

import sys

import numpy as np

import multieye
from multieye.core import geometry as g
from multieye.core.metrics import relative_extrinsics
from multieye.estimate.refine_images import refine_images
from multieye.estimate.selection import select_before_decoding, stride_selection
from multieye.estimate.uncertainty import relative_covariance
from multieye.sim.recordings import simulate_recording

NAMES = ("cam0", "cam1", "cam2")


def calibrated(rec, keep):
    """RMS over the non-reference cameras: error rot (deg), trans (mm); predicted std of both."""
    A, B = rec.AB(keep)
    sol = multieye.solve(A, B)
    r = refine_images("eye-to-base", rec.observations(keep), rec.intrinsics, sol.X, sol.Y,
                      mocap_rot_sigma_rad=rec.mocap_rot_sigma_rad,
                      mocap_trans_sigma_m=rec.mocap_trans_sigma_m, pixel_sigma=rec.pixel_sigma)
    u = relative_covariance(r.X, r.covariance)
    D = g.inv(rec.T_ref_cam) @ relative_extrinsics(r.X)
    parts = (np.degrees(np.linalg.norm(g.rotvec_from_transform(D), axis=1))[1:],
             np.linalg.norm(D[:, :3, 3], axis=1)[1:] * 1e3,
             np.asarray(u.std_rot_deg[1:]), np.asarray(u.std_trans_m[1:]) * 1e3)
    return [float(np.sqrt(np.mean(x ** 2))) for x in parts]


def main(n: int, budget: int, seeds: int, rich_percent: int = 20) -> None:
    rows = []
    for seed in range(seeds):
        rec = simulate_recording(seed, n_cameras=len(NAMES), images=n,
                                 rich_fraction=rich_percent / 100)
        sel = select_before_decoding({c: rec.stamps[j] for j, c in enumerate(NAMES)},
                                     {c: np.arange(n) for c in NAMES},
                                     {c: rec.T_world_mocap[j] for j, c in enumerate(NAMES)}, budget)
        runs = (("all", None), ("selected", [sel[c].keep for c in NAMES]),
                ("stride", [stride_selection(n, budget)] * len(NAMES)))
        for label, keep in runs:
            rows.append((seed, label, *calibrated(rec, keep)))
    print(f"{len(NAMES)} cameras x {n} images, {budget} per camera selected or strided, "
          f"{rich_percent} % rich")
    print("| run | seed | error rot deg | error trans mm | predicted std rot deg | predicted std trans mm |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[1]} | {r[0]} | {r[2]:.4f} | {r[3]:.3f} | {r[4]:.4f} | {r[5]:.3f} |")
    for label in ("all", "selected", "stride"):
        sub = np.array([r[2:] for r in rows if r[1] == label])
        rms = np.sqrt(np.mean(sub[:, :2] ** 2, axis=0))
        print(f"| {label} | RMS over {seeds} | {rms[0]:.4f} | {rms[1]:.3f} | "
              f"{np.mean(sub[:, 2]):.4f} | {np.mean(sub[:, 3]):.3f} |")


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:5]] or [900, 100, 5]
    main(*args)
