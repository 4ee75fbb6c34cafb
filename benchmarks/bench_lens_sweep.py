"""Where the joint lens wins: OpenCV, mrcal and multieye's joint problem over noise, views, lenses.

Run from the repository root::

    python benchmarks/bench_lens_sweep.py [--trials 2] [--noise 0.06 0.2 0.5]
        [--views 20 50 100] [--lenses pinhole-radtan fisheye]
        [--mrcal-python /tmp/venv-mrcal/bin/python]

Issue 21, item 5. For every lens, number of views and corner noise, ``--trials`` simulated
non-overlapping rigs of four cameras with that lens (:func:`multieye.sim.images.simulate_images`;
motion capture 0.03 deg / 0.1 mm per axis, as the rendered benchmark rig of ``bench_peers.py``;
the 8 x 6 board at 0.5-2 m, tilted up to 45 degrees). The same corners go to:

- ``opencv``: ``cv2.calibrateCamera`` / ``cv2.fisheye.calibrate`` per camera
  (:func:`multieye.imaging.calibrate.initial_intrinsics`);
- ``mrcal``: mrcal 2.5 per camera, as ``mrcal-calibrate-cameras`` runs it
  (``benchmarks/peers/mrcal_script.py``, in mrcal's own interpreter), with
  ``LENSMODEL_OPENCV5`` for the radial-tangential lens and ``LENSMODEL_OPENCV8`` for the
  fisheye (mrcal has no equidistant model; the rational one covers the +-40 x +-30 degree
  field seen here); skipped when ``--mrcal-python`` cannot import mrcal;
- ``joint``: multieye's joint problem (``refine_images(..., free_intrinsics=...)``: every
  camera's lens, every X, Y and the motion-capture poses, started from OpenCV's lenses).

Extrinsics: for ``opencv`` and ``mrcal`` the lens is held fixed in multieye's image-level
refinement (the best extrinsics that lens allows: the back end is the same for all, so the
difference is the lens). Reported per configuration, RMS over the trials and cameras:

- the lens's projection error over the observed area, px, raw and after the best-fitting
  rotation between camera frames (``benchmarks/peers/lens_error.py``; mrcal's comparison);
- the error of ``T_ref_cam`` (cameras 1-3 against camera 0), deg / mm.

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

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.metrics import relative_extrinsics
from multieye.estimate.refine_images import refine_images
from multieye.imaging.calibrate import initial_intrinsics
from multieye.sim.images import default_intrinsics, simulate_images
from multieye.solvers import solve

PEERS = Path(__file__).resolve().parent / "peers"
sys.path.insert(0, str(PEERS))
from lens_error import errors, project, unproject  # noqa: E402

RADTAN = Intrinsics(K=[[705.0, 0, 635.0], [0, 703.0, 482.0], [0, 0, 1]],
                    dist=[-0.11, 0.025, 4e-4, 2e-4, -0.003], width=1280, height=960)
LENSES = {"pinhole-radtan": RADTAN, "fisheye": default_intrinsics("fisheye")}
MRCAL_MODEL = {"pinhole-radtan": "LENSMODEL_OPENCV5", "fisheye": "LENSMODEL_OPENCV8"}
ROWS, COLS = 6, 8
MOCAP = (np.radians(0.03), 1e-4)


def ext_errors(X, X_true) -> np.ndarray:
    """(m - 1, 2): rotation deg, translation mm of T_ref_cam, cameras 1..m-1."""
    T, Tt = relative_extrinsics(X), relative_extrinsics(X_true)
    return np.array([[np.degrees(g.rotation_angle_between(a, b)),
                      1e3 * g.translation_distance(a, b)] for a, b in zip(T[1:], Tt[1:])])


def mrcal_lenses(python: str, jobs: dict) -> dict:
    """mrcal's lens for every job ``key -> (corners (n, rows, cols, 2), model)``: key ->
    (K, dist), or {} with a note when mrcal cannot run."""
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.json"
        np.savez(src, **{f"{k}|{m}": c for k, (c, m) in jobs.items()})
        cmd = [python, str(PEERS / "mrcal_script.py"), "--lens-only", str(src), "--out",
               str(dst), "--spacing", "0.05"]
        try:
            run = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
        except (OSError, subprocess.TimeoutExpired) as exc:
            print(f"mrcal skipped: {exc}")
            return {}
        if run.returncode != 0:
            print(f"mrcal skipped: {run.stderr.strip().splitlines()[-1:]}")
            return {}
        return {k: (np.array(v["K"]), np.array(v["dist"]))
                for k, v in json.loads(dst.read_text()).items()}


def trial(lens_name: str, views: int, noise: float, seed: int):
    lens = LENSES[lens_name]
    sc = simulate_images(np.random.default_rng(seed), n_cameras=4, images=views,
                         intrinsics=(lens,) * 4, pixel_sigma=noise,
                         mocap_rot_sigma_rad=MOCAP[0], mocap_trans_sigma_m=MOCAP[1],
                         noise_rng=np.random.default_rng([seed, int(noise * 1000)]))
    size = (lens.width, lens.height)
    starts = [initial_intrinsics([(sc.object_points, u) for u in sc.image_points[j]], size,
                                 lens_name, name=f"cam{j}") for j in range(4)]
    closed = solve(list(sc.A), [g.inv(s.T_cam_target) for s in starts])
    return sc, starts, closed


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=2)
    ap.add_argument("--noise", type=float, nargs="+", default=[0.06, 0.2, 0.5])
    ap.add_argument("--views", type=int, nargs="+", default=[20, 50, 100])
    ap.add_argument("--lenses", nargs="+", default=list(LENSES), choices=list(LENSES))
    ap.add_argument("--mrcal-python", default="/tmp/venv-mrcal/bin/python")
    args = ap.parse_args(argv)
    start = time.perf_counter()
    configs = [(ln, v, s, t) for ln in args.lenses for v in args.views for s in args.noise
               for t in range(args.trials)]
    sims = {c: trial(c[0], c[1], c[2], seed=1000 * c[3] + c[1]) for c in configs}
    jobs = {f"{i}_{j}": (sims[c][0].image_points[j].reshape(-1, ROWS, COLS, 2),
                         MRCAL_MODEL[c[0]]) for i, c in enumerate(configs) for j in range(4)}
    mrcal = mrcal_lenses(args.mrcal_python, jobs) if args.mrcal_python else {}
    rows = {}
    for i, c in enumerate(configs):
        sc, starts, closed = sims[c]
        sig = dict(mocap_rot_sigma_rad=MOCAP[0], mocap_trans_sigma_m=MOCAP[1])
        lenses = {"opencv": [s.intrinsics for s in starts]}
        if all(f"{i}_{j}" in mrcal for j in range(4)):
            lenses["mrcal"] = [Intrinsics(K=mrcal[f"{i}_{j}"][0], dist=mrcal[f"{i}_{j}"][1],
                                          width=1280, height=960) for j in range(4)]
        out = {}
        held = {}
        for name, intr in lenses.items():
            held[name] = refine_images(sc.setup, sc.observations, intr, closed.X, closed.Y,
                                       **sig)
        joint = refine_images(sc.setup, sc.observations, lenses["opencv"], held["opencv"].X,
                              held["opencv"].Y, free_intrinsics=[True] * 4, **sig)
        for name in lenses:
            out[name] = (lenses[name], held[name].X)
        out["joint"] = (joint.intrinsics, joint.X)
        for name, (intr, X) in out.items():
            lens_e = [lens_error(intr[j], sc.intrinsics[j], sc.image_points[j].reshape(-1, 2))
                      for j in range(4)]
            rows.setdefault(c[:3], {}).setdefault(name, []).append(
                (np.array(lens_e), ext_errors(X, sc.X)))
        print(f"  {c} done ({time.perf_counter() - start:.0f} s)", flush=True)
    report(rows, args)
    print(f"\n{time.perf_counter() - start:.0f} s in all")


def lens_error(est: Intrinsics, true: Intrinsics, pixels: np.ndarray) -> tuple[float, float]:
    """Projection error (px RMS, raw and after the fitted rotation) of ``est`` against
    ``true`` over the rays of ``pixels`` (either lens pinhole or fisheye)."""
    rays = unproject(pixels, true.K, true.dist, true.model == "fisheye")
    truth = project(rays, true.K, true.dist, true.model == "fisheye")
    return errors(lambda r: project(r, est.K, est.dist, est.model == "fisheye"), rays, truth)


def rms(a) -> float:
    return float(np.sqrt(np.mean(np.square(a))))


def report(rows: dict, args) -> None:
    print(f"\n{args.trials} trials per row, 4 cameras, RMS over trials and cameras. Lens: "
          "projection error px, raw (after the fitted rotation). T_ref_cam: deg / mm.\n")
    print("| lens | views | noise px | lens opencv | lens mrcal | lens joint | "
          "T_ref_cam opencv | T_ref_cam mrcal | T_ref_cam joint |")
    print("|---|---|---|---|---|---|---|---|---|")
    for (lens, views, noise), by in rows.items():
        def lens_cell(name):
            if name not in by:
                return "-"
            e = np.concatenate([le for le, _ in by[name]])
            return f"{rms(e[:, 0]):.3f} ({rms(e[:, 1]):.3f})"

        def ext_cell(name):
            if name not in by:
                return "-"
            e = np.concatenate([ee for _, ee in by[name]])
            return f"{rms(e[:, 0]):.4f} / {rms(e[:, 1]):.3f}"

        print(f"| {lens} | {views} | {noise} | " + " | ".join(
            [lens_cell(n) for n in ("opencv", "mrcal", "joint")]
            + [ext_cell(n) for n in ("opencv", "mrcal", "joint")]) + " |")


if __name__ == "__main__":
    main()
