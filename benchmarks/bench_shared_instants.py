"""Cameras triggered together: one motion-capture measurement, one prior. Is X, Y's std honest?

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_shared_instants.py [--trials 100] [--seed 0] [--quick]

A synchronised rig: ``m`` cameras take their images at the same instants, so every image of
an instant is paired with the same motion-capture sample (bitwise the same pose).
:func:`multieye.estimate.refine_images.refine_images` (no clocks) now gives those images one
shared motion-capture block with one prior (``shared``).  Before, every image had its own
block and its own prior from the same measurement, counting it ``m`` times (``per image``);
that behaviour is reproduced here by handing each camera after the first a copy of the pose
with one translation entry (its own: the camera's number, up to 4 cameras) moved by one unit
in the last place (1e-16 m: no effect on the solution, but no longer bitwise equal, so
nothing is shared).  The benchmark checked once that this gives the
old code's covariance (docs/results/shared_instants.md).

The rigs: :func:`multieye.sim.streams.simulate_rig_stream` with ``interleaved=False``
(80 images per camera at 4 Hz, 200 Hz motion capture, 1e-3 rad / 0.3 mm noise per sample),
its geometry and its noisy samples, with the pixels re-rendered from the true pose *at* the
paired sample (the stream's own images are taken up to 1 ms before it, a lag that at
0.4-0.9 m/s would add a 0.1-0.4 mm model error); pixel noise 0.5 px or 0.05 px (where the
motion capture's error dominates).  Control: the same images, each camera paired with its
own independent sample of the noise (``independent``: the priors really are independent;
both versions are the same there).

Per configuration: the mean NEES per dimension of every camera's X and of Y together,
``e^T C^-1 e / (6 (m + 1))`` (1 for an honest covariance; the 95 % band of the mean in
brackets), the RMS rotation error of X and its RMS reported std, and the median seconds per
refinement.  Least squares with the noise stated, and the pipeline's defaults (Huber, pixel
and motion-capture noise estimated).  This is a script, not a test: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import subprocess
import time

import numpy as np

from multieye.core import geometry as g
from multieye.core.lens import project_points
from multieye.estimate.refine_images import refine_images
from multieye.sim.images import default_target_points
from multieye.sim.rigs import GaussianNoise
from multieye.sim.streams import simulate_rig_stream
from multieye.estimate.uncertainty import pose_error

MOCAP = (1e-3, 0.3e-3)
RATE_HZ = 4.0
IMAGES = 80


def triggered_rig(seed: int, setup: str, m: int, pixel_sigma: float, pairing: str):
    """A rig of ``m`` cameras triggered together (module docstring).

    ``pairing``: ``"shared"`` (one sample per instant for every camera), ``"per-image"`` (the
    same, each camera's copy one ulp apart) or ``"independent"`` (fresh noise per camera).
    Returns (observations, intrinsics, X_true, Y_true).
    """
    rng = np.random.default_rng([seed, 7])
    st = simulate_rig_stream(seed, n_cameras=m, setup=setup, duration_s=IMAGES / RATE_HZ,
                             camera_rate_hz=RATE_HZ, mocap_rate_hz=200.0,
                             mocap_rot_sigma_rad=MOCAP[0], mocap_trans_sigma_m=MOCAP[1],
                             interleaved=False)
    k = np.searchsorted(st.mocap_stamps, st.image_stamps[0])          # the paired samples
    M_true, M_meas = st.T_world_mocap_true[k], st.T_world_mocap[k]
    pts = default_target_points()
    noise = GaussianNoise(*MOCAP)
    observations = []
    for j in range(m):
        if setup == "eye-to-base":
            P = g.inv(st.X[j]) @ M_true @ st.Y                       # T_cam_target
        else:
            P = g.inv(st.X[j]) @ g.inv(M_true) @ st.Y
        pc = pts @ np.swapaxes(P[:, :3, :3], 1, 2) + P[:, None, :3, 3]    # (N, n, 3)
        uv = project_points(pc.reshape(-1, 3), st.intrinsics[j]).reshape(len(P), -1, 2)
        uv = uv + rng.normal(scale=pixel_sigma, size=uv.shape)
        if pairing == "independent":
            meas = M_meas if j == 0 else noise.perturb(M_true, rng)
        else:
            meas = M_meas.copy()
            if pairing == "per-image" and j:             # camera j: its own entry moved
                meas[:, j - 1, 3] = np.nextafter(meas[:, j - 1, 3], np.inf)
        observations.append([(pts, uv[i], meas[i]) for i in range(len(k))])
    return observations, st.intrinsics, st.X, st.Y



def nees(res, X, Y) -> float:
    """Mean NEES per dimension of X and Y against the reported covariance."""
    e = np.concatenate([pose_error(res.X[j], X[j]) for j in range(len(X))] + [pose_error(res.Y, Y)])
    return float(e @ np.linalg.solve(res.covariance, e)) / e.size


def trial(seed: int, setup: str, m: int, pixel_sigma: float, pairing: str,
          defaults: bool) -> dict:
    obs, K, X, Y = triggered_rig(seed, setup, m, pixel_sigma, pairing)
    rng = np.random.default_rng([seed, 11])
    X0 = np.stack([g.transform_from_rotvec(rng.normal(scale=0.005, size=3),
                                           rng.normal(scale=0.003, size=3)) @ x for x in X])
    kw = (dict(mocap_rot_sigma_rad=None, mocap_trans_sigma_m=None) if defaults else
          dict(pixel_sigma=pixel_sigma, mocap_rot_sigma_rad=MOCAP[0],
               mocap_trans_sigma_m=MOCAP[1], loss="linear"))
    start = time.perf_counter()
    res = refine_images(setup, obs, K, X0, Y, **kw)
    seconds = time.perf_counter() - start
    rot = np.array([pose_error(res.X[j], X[j])[:3] for j in range(m)])
    std = np.sqrt(np.diag(res.covariance)).reshape(m + 1, 6)[:m, :3]
    return dict(nees=nees(res, X, Y), rot2=float(np.mean(rot ** 2)),
                std2=float(np.mean(std ** 2)), seconds=seconds, converged=res.converged)


def run(label: str, trials: int, seed: int, **kw) -> None:
    m = kw["m"]
    band = 1.96 * np.sqrt(2.0 / (trials * 6 * (m + 1)))
    cells = []
    for pairing in ("per-image", "shared", "independent"):
        rows = [trial(seed + t, pairing=pairing, **kw) for t in range(trials)]
        cells.append(f"{np.mean([r['nees'] for r in rows]):.2f}")
        if pairing == "shared":
            extra = (f"{np.degrees(np.sqrt(np.mean([r['rot2'] for r in rows]))):.4f} "
                     f"| {np.degrees(np.sqrt(np.mean([r['std2'] for r in rows]))):.4f} "
                     f"| {np.median([r['seconds'] for r in rows]):.2f} "
                     f"| {sum(r['converged'] for r in rows)}/{trials}")
    print(f"| {label} | {trials} | {cells[0]} | {cells[1]} | {cells[2]} | +-{band:.2f} "
          f"| {extra} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="10 trials per configuration")
    args = ap.parse_args()
    trials = 10 if args.quick else args.trials
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    print(f"{IMAGES} images per camera at {RATE_HZ:g} Hz, triggered together; 200 Hz motion "
          f"capture, {MOCAP[0]:g} rad / {MOCAP[1] * 1e3:g} mm; seed {args.seed}; commit "
          f"{commit}; {os.cpu_count()} cores\n")
    print("| configuration | trials | NEES X, Y per image (before) | NEES shared (now) "
          "| NEES independent samples | 95 % band | RMS rot. error of X, deg "
          "| RMS reported std, deg | median s | converged |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    t0 = time.perf_counter()
    s = args.seed
    for i, (setup, m, px, defaults) in enumerate([
            ("eye-to-base", 3, 0.5, False), ("eye-on-hand", 3, 0.5, False),
            ("eye-to-base", 4, 0.5, False), ("eye-on-hand", 4, 0.5, False),
            ("eye-to-base", 4, 0.05, False), ("eye-on-hand", 4, 0.05, False),
            ("eye-to-base", 4, 0.5, True), ("eye-on-hand", 4, 0.5, True)]):
        label = (f"{setup}, {m} cameras, {px:g} px, "
                 + ("Huber, noise estimated" if defaults else "least squares, noise stated"))
        run(label, trials, s + 10_000 * i, setup=setup, m=m, pixel_sigma=px,
            defaults=defaults)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
