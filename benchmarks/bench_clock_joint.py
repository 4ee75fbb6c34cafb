"""Clock offsets in the joint image-level problem: is the reported uncertainty honest?

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_clock_joint.py [--trials 100] [--seed 0] [--quick]

Over ``--trials`` simulated rigs (:func:`multieye.sim.streams.simulate_rig_stream`: 3 cameras
with their own clocks, offsets uniform in +-0.1 s, 4 images per second each, interleaved,
20 s; one motion-capture stream at 200 Hz with 1e-3 rad / 0.3 mm noise per sample; 0.5 px
pixel noise), :func:`multieye.estimate.refine_images.refine_images` with ``clocks`` frees
every camera's offset (started 2 ms off, about what :func:`multieye.estimate.clock.
estimate_offset` leaves) and the rig (started a few mrad / mm off).  Per configuration it
prints the mean normalised estimation error squared (NEES) per dimension:

- of the offsets, ``((delta_hat - delta) / std)^2`` averaged over cameras and trials
  (chi-square with 1 degree of freedom for an honest std: mean 1);
- of X and Y, ``e^T C^-1 e / (6 (m + 1))`` with ``e`` the rotation-vector and translation
  errors in the covariance's convention and ``C`` the reported covariance (includes the
  offsets' uncertainty);
- of everything jointly (X, Y and the offsets);

with the 95 % band of the mean for an honest estimator, the mean offset error and std, and
the median seconds per refinement.  Configurations: least squares with the noise stated
(eye-to-base and eye-on-hand), the pipeline's defaults (Huber loss, pixel noise and
motion-capture noise estimated from the data), and where the fits' errors are not
independent (the model's assumption): cameras at 20 Hz (each image's +-50 ms window shares
samples with its neighbours'), and the three cameras triggered at the same instants (with
0.5 px and with nearly noise-free 0.05 px pixels, where the motion capture's error
dominates).  The same triggered-together rigs with the cameras on ONE clock (one true offset,
bitwise equal stamps, ``ClockData.shared``: one offset, one pose block and one prior per
instant), also eye-on-hand with the pipeline's defaults, and 4 cameras at 30 Hz triggered
together with their own clocks and on one clock (each camera's windows then also overlap
its own neighbours').  With a shared clock the offsets' NEES counts one offset per trial.
Target: every mean NEES within 0.5-2.
This is a script, not a test: nothing here is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import time

import numpy as np

from multieye.core import geometry as g
from multieye.estimate.clock_residuals import DEFAULT_HALF_WINDOW_S, ClockData, offset_family
from multieye.estimate.refine_images import refine_images
from multieye.sim.streams import simulate_rig_stream
from multieye.estimate.uncertainty import pose_error

N_CAMERAS = 3
PIXEL_SIGMA = 0.5
MOCAP = (1e-3, 0.3e-3)



def trial(seed, setup: str, defaults: bool, interleaved: bool = True,
          pixel_sigma: float = PIXEL_SIGMA, rate_hz: float = 4.0,
          half_window_s: float | None = None, shared: bool = False,
          n_cameras: int = N_CAMERAS) -> dict:
    """One simulated rig refined with free offsets; errors normalised by the covariance.
    ``shared``: the cameras are on one clock (one offset, ``ClockData.shared``)."""
    rng = np.random.default_rng([seed, 1])
    offsets = rng.uniform(-0.1, 0.1, n_cameras)
    if shared:
        offsets[:] = offsets[0]                     # one clock: bitwise equal image stamps
    st = simulate_rig_stream(seed, n_cameras=n_cameras, setup=setup, duration_s=80.0 / rate_hz,
                             camera_rate_hz=rate_hz, time_offsets_s=offsets,
                             pixel_sigma=pixel_sigma, mocap_rot_sigma_rad=MOCAP[0],
                             mocap_trans_sigma_m=MOCAP[1], interleaved=interleaved)
    clocks = [ClockData(st.image_stamps[j], st.mocap_stamps, st.T_world_mocap,
                        offset=offsets[j] + rng.normal(scale=0.002),
                        half_window_s=half_window_s or DEFAULT_HALF_WINDOW_S,
                        shared="rig" if shared else None)
              for j in range(n_cameras)]
    X0 = np.stack([g.transform_from_rotvec(rng.normal(scale=0.005, size=3),
                                           rng.normal(scale=0.003, size=3)) @ x for x in st.X])
    if defaults:
        kw = dict(mocap_rot_sigma_rad=None, mocap_trans_sigma_m=None)
    else:
        kw = dict(pixel_sigma=pixel_sigma, mocap_rot_sigma_rad=MOCAP[0],
                  mocap_trans_sigma_m=MOCAP[1], loss="linear")
    start = time.perf_counter()
    res = refine_images(setup, st.observations, st.intrinsics, X0, st.Y, clocks=clocks, **kw)
    seconds = time.perf_counter() - start
    e = np.concatenate([pose_error(res.X[j], st.X[j]) for j in range(n_cameras)] + [pose_error(res.Y, st.Y)])
    used = [0] if shared else list(range(n_cameras))     # one offset per clock
    d = (np.array(res.time_offsets) - offsets)[used]
    std = np.array(res.time_offset_std_s)[used]
    k = e.size
    idx = list(range(k)) + [res.layout.offset[offset_family(f"cam{j}")] for j in used]
    C = res.full_covariance[np.ix_(idx, idx)]
    ed = np.concatenate([e, d])
    return dict(z=d / std, err=d, std=std, seconds=seconds,
                nees_xy=float(e @ np.linalg.solve(res.covariance, e)) / k,
                nees_all=float(ed @ np.linalg.solve(C, ed)) / ed.size,
                sigma=(res.pixel_sigma, res.mocap_rot_sigma_rad, res.mocap_trans_sigma_m),
                converged=res.converged)


def run(label: str, setup: str, defaults: bool, trials: int, seed: int, **kw) -> None:
    rows = [trial(seed + t, setup, defaults, **kw) for t in range(trials)]
    z = np.concatenate([r["z"] for r in rows])
    nd = len(z)
    nxy = trials * 6 * (kw.get("n_cameras", N_CAMERAS) + 1)
    band = lambda n: 1.96 * np.sqrt(2.0 / n)                              # noqa: E731
    sig = np.mean([r["sigma"] for r in rows], axis=0)
    print(f"| {label} | {trials} | {np.mean(z ** 2):.2f} (+-{band(nd):.2f}) "
          f"| {np.mean([r['nees_xy'] for r in rows]):.2f} (+-{band(nxy):.2f}) "
          f"| {np.mean([r['nees_all'] for r in rows]):.2f} "
          f"| {np.sqrt(np.mean(np.concatenate([r['err'] for r in rows]) ** 2)) * 1e3:.3f} "
          f"| {np.sqrt(np.mean(np.concatenate([r['std'] for r in rows]) ** 2)) * 1e3:.3f} "
          f"| {np.mean(z):+.2f} | {sig[0]:.3f} / {sig[1]:.2e} / {sig[2] * 1e3:.3f} "
          f"| {np.median([r['seconds'] for r in rows]):.2f} "
          f"| {sum(r['converged'] for r in rows)}/{trials} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="10 trials per configuration")
    args = ap.parse_args()
    trials = 10 if args.quick else args.trials
    print(f"{N_CAMERAS} cameras x 80 images, 200 Hz motion capture, seed {args.seed}, "
          f"{os.cpu_count()} cores\n")
    print("| configuration | trials | NEES offsets | NEES X, Y (per dim) | NEES all (per dim) "
          "| RMS offset error, ms | RMS reported std, ms | mean z | sigma px / rad / mm "
          "| median s | converged |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    t0 = time.perf_counter()
    run("eye-to-base, least squares, noise stated", "eye-to-base", False, trials, args.seed)
    run("eye-on-hand, least squares, noise stated", "eye-on-hand", False, trials,
        args.seed + 10_000)
    run("eye-to-base, Huber, noise estimated", "eye-to-base", True, trials, args.seed + 20_000)
    run("eye-on-hand, Huber, noise estimated", "eye-on-hand", True, trials, args.seed + 30_000)
    run("eye-to-base, least squares, cameras at 20 Hz (windows overlap)", "eye-to-base", False,
        trials, args.seed + 40_000, rate_hz=20.0)
    run("eye-to-base, least squares, cameras triggered together", "eye-to-base", False,
        trials, args.seed + 50_000, interleaved=False)
    run("eye-to-base, least squares, triggered together, 0.05 px", "eye-to-base", False,
        trials, args.seed + 60_000, interleaved=False, pixel_sigma=0.05)
    run("eye-to-base, least squares, triggered together, one shared clock", "eye-to-base",
        False, trials, args.seed + 50_000, interleaved=False, shared=True)
    run("eye-to-base, least squares, triggered together, 0.05 px, one shared clock",
        "eye-to-base", False, trials, args.seed + 60_000, interleaved=False, pixel_sigma=0.05,
        shared=True)
    run("eye-on-hand, Huber, noise estimated, triggered together, one shared clock",
        "eye-on-hand", True, trials, args.seed + 70_000, interleaved=False, shared=True)
    run("eye-to-base, least squares, 4 cameras at 30 Hz triggered together, own clocks",
        "eye-to-base", False, trials, args.seed + 80_000, interleaved=False, n_cameras=4,
        rate_hz=30.0)
    run("eye-to-base, least squares, 4 cameras at 30 Hz triggered together, one shared clock",
        "eye-to-base", False, trials, args.seed + 80_000, interleaved=False, n_cameras=4,
        rate_hz=30.0, shared=True)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
