"""Intrinsics from the calibration recording itself, against the per-camera tools people use.

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_intrinsics.py [--trials 20] [--seed 0] [--images 50]

Each trial simulates a non-overlapping rig of four cameras with three lens models (pinhole
with OpenCV's 5 radial-tangential coefficients, pinhole with the 8-coefficient rational
model, equidistant fisheye, and a second radial-tangential camera), each seeing the
motion-captured chessboard (8 x 6 inner corners, 50 mm) in ``--images`` images, with
0.33 px Gaussian corner noise and motion capture of 0.1 deg / 0.3 mm.  The same corners go to

- ``opencv``: ``cv2.calibrateCamera`` (``cv2.fisheye.calibrate`` for the fisheye) camera by
  camera; then multieye's extrinsics (closed form and image-level refinement) with those
  intrinsics held fixed: what a user gets today when the intrinsics come from OpenCV;
- ``joint``: multieye's joint maximum-likelihood problem over every camera's intrinsics,
  every ``X``, ``Y`` and the motion-capture poses (started from OpenCV's intrinsics);
- ``true``: multieye's extrinsics with the true intrinsics held fixed (the floor);
- ``mrcal``: ``mrcal-calibrate-cameras`` on the same corners camera by camera (a corners
  cache, same lens model: ``LENSMODEL_OPENCV5`` / ``LENSMODEL_OPENCV8``; mrcal 2.2 has no
  equidistant fisheye, so that camera has no mrcal figure) when mrcal is installed (Debian:
  ``apt-get install mrcal python3-mrcal``, for ``--mrcal-python /usr/bin/python3``); its
  extrinsics are not computed (mrcal does not relate cameras that never see the board at
  the same time).

It prints, per camera and method, the projection error against the true lens over the
observed area (RMS and max over the camera-frame rays of every observed corner, pixels)
and the error of ``T_ref_cam`` (rotation degrees, translation millimetres; camera 0 is the
reference), as RMS over the trials.  Issue 12's targets: the joint projection error no worse
than OpenCV's; the joint extrinsic error at most half of ``opencv``'s and close to ``true``'s.
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
from dataclasses import replace
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics, lens_model
from multieye.core.lens import project_points
from multieye.core.metrics import relative_extrinsics
from multieye.estimate.refine_images import refine_images
from multieye.estimate.uncertainty import relative_covariance
from multieye.imaging.calibrate import initial_intrinsics
from multieye.sim.rigs import ScenarioSpec
from multieye.sim.images import default_intrinsics, simulate_images
from multieye.solvers import solve

RATIONAL = Intrinsics(K=[[700.0, 0, 640.5], [0, 702.0, 478.0], [0, 0, 1]],
                      dist=[-0.12, 0.03, 1e-3, -5e-4, -0.004, 0.02, -0.004, 0.002],
                      width=1280, height=960)
RADTAN = Intrinsics(K=[[705.0, 0, 635.0], [0, 703.0, 482.0], [0, 0, 1]],
                    dist=[-0.11, 0.025, 4e-4, 2e-4, -0.003], width=1280, height=960)
LENSES = (RADTAN, RATIONAL, default_intrinsics("fisheye"), RADTAN)
MRCAL_MODELS = {"pinhole-radtan": "LENSMODEL_OPENCV5", "pinhole-rational": "LENSMODEL_OPENCV8",
                "fisheye": None}


def projection_error(est: Intrinsics, true: Intrinsics, rays: np.ndarray) -> np.ndarray:
    """|pi_est(ray) - pi_true(ray)| over camera-frame rays, pixels."""
    return np.linalg.norm(project_points(rays, est) - project_points(rays, true), axis=1)


def extrinsic_errors(X: np.ndarray, X_true: np.ndarray) -> np.ndarray:
    """(m, 2): rotation (deg) and translation (m) error of every T_ref_cam."""
    T, Tt = relative_extrinsics(X), relative_extrinsics(X_true)
    return np.array([[np.degrees(g.rotation_angle_between(a, b)), g.translation_distance(a, b)]
                     for a, b in zip(T, Tt)])


def mrcal_intrinsics(python: str, object_points, views, size, model: str) -> Intrinsics | None:
    """``mrcal-calibrate-cameras`` on one camera's corners (a corners cache, no images), read
    back with ``python``'s mrcal; None when mrcal has no equivalent of the model or fails."""
    lensmodel = MRCAL_MODELS.get(model)
    if lensmodel is None:
        return None
    spacing = float(np.min(np.diff(np.unique(object_points[:, 0]))))
    col = np.round(object_points[:, 0] / spacing).astype(int)
    row = np.round(object_points[:, 1] / spacing).astype(int)
    order = np.lexsort((col, row))                       # row-major, x fastest
    width, height = col.max() + 1, row.max() + 1
    with tempfile.TemporaryDirectory() as tmp:
        lines = ["# filename x y level"]
        for k, u in enumerate(views):
            lines += [f"frame{k:04d}.png {x:.6f} {y:.6f} 0" for x, y in u[order]]
        (Path(tmp) / "corners.vnl").write_text("\n".join(lines) + "\n")
        cmd = ["mrcal-calibrate-cameras", "--corners-cache", "corners.vnl", "--lensmodel",
               lensmodel, "--focal", "700", "--object-spacing", f"{spacing}",
               "--object-width-n", str(width), "--object-height-n", str(height),
               "--imagersize", str(size[0]), str(size[1]), "--outdir", tmp, "frame*.png"]
        read = ("import json, mrcal; m = mrcal.cameramodel('camera-0.cameramodel'); "
                "print(json.dumps(m.intrinsics()[1].tolist()))")
        try:
            run = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True, timeout=900)
            out = subprocess.run([python, "-c", read], cwd=tmp, capture_output=True, text=True,
                                 timeout=60) if run.returncode == 0 else run
        except (OSError, subprocess.TimeoutExpired):
            return None
    if out.returncode != 0:
        print(f"   mrcal failed: {out.stderr.strip().splitlines()[-1:]}")
        return None
    p = np.array(json.loads(out.stdout))
    return Intrinsics(K=[[p[0], 0, p[2]], [0, p[1], p[3]], [0, 0, 1]], dist=p[4:],
                      width=size[0], height=size[1])


def lens_views(seed: int, n: int):
    """``n`` extra views of the board per camera without motion capture (another scene of the
    same lenses): what ``intrinsics_images`` adds, as ``intrinsics_observations`` (the
    starting board pose perturbed by a few mrad / mm)."""
    if n <= 0:
        return None
    sc = simulate_images(np.random.default_rng([seed, 7]), n_cameras=len(LENSES), images=n,
                         intrinsics=LENSES, pixel_sigma=0.33,
                         noise_rng=np.random.default_rng([seed, 8]))
    rng = np.random.default_rng([seed, 9])
    return [[(sc.object_points, u,
              g.transform_from_rotvec(rng.normal(scale=3e-3, size=3),
                                      rng.normal(scale=3e-3, size=3)) @ T)
             for u, T in zip(sc.image_points[j], sc.truth.T_cam_target[j])]
            for j in range(sc.n_cameras)]


def trial(seed: int, images: int, mrcal_python: str | None, extra: int = 0,
          scenario=None):
    rng = np.random.default_rng(seed)
    sc = simulate_images(rng, n_cameras=len(LENSES), images=images, intrinsics=LENSES,
                         pixel_sigma=0.33, noise_rng=np.random.default_rng([seed, 1]),
                         scenario=scenario)
    m = sc.n_cameras
    size = (LENSES[0].width, LENSES[0].height)
    starts = [initial_intrinsics([(sc.object_points, u) for u in sc.image_points[j]], size,
                                 lens_model(sc.intrinsics[j]), name=f"cam{j}")
              for j in range(m)]
    sigmas = dict(mocap_rot_sigma_rad=sc.mocap_rot_sigma_rad,
                  mocap_trans_sigma_m=sc.mocap_trans_sigma_m)
    # opencv: OpenCV's intrinsics and its poses, held fixed through multieye's extrinsics
    B = [g.inv(s.T_cam_target) for s in starts]
    closed = solve(list(sc.A), B)
    cv_intr = [s.intrinsics for s in starts]
    t0 = time.perf_counter()
    with_cv = refine_images(sc.setup, sc.observations, cv_intr, closed.X, closed.Y, **sigmas)
    t_cv = time.perf_counter() - t0
    t0 = time.perf_counter()
    joint = refine_images(sc.setup, sc.observations, cv_intr, with_cv.X, with_cv.Y,
                          free_intrinsics=[True] * m, **sigmas)
    t_joint = time.perf_counter() - t0
    views = lens_views(seed, extra)
    if views is not None:     # the same, with lens-only views added (intrinsics_images)
        joint_more = refine_images(sc.setup, sc.observations, cv_intr, with_cv.X, with_cv.Y,
                                   free_intrinsics=[True] * m, intrinsics_observations=views,
                                   **sigmas)
    true_closed = solve(list(sc.A), list(sc.B))
    with_true = refine_images(sc.setup, sc.observations, sc.intrinsics, true_closed.X,
                              true_closed.Y, **sigmas)
    rows = {}
    for j in range(m):
        rays = np.concatenate([sc.object_points @ T[:3, :3].T + T[:3, 3]
                               for T in sc.truth.T_cam_target[j]])
        rows[j] = {"opencv": projection_error(cv_intr[j], sc.intrinsics[j], rays),
                   "joint": projection_error(joint.intrinsics[j], sc.intrinsics[j], rays)}
        if mrcal_python:
            mi = mrcal_intrinsics(mrcal_python, sc.object_points, sc.image_points[j], size,
                                  lens_model(sc.intrinsics[j]))
            if mi is not None:
                rows[j]["mrcal"] = projection_error(mi, sc.intrinsics[j], rays)
    unc = relative_covariance(joint.X, joint.covariance, reference=0)
    predicted = np.column_stack([unc.std_rot_deg, unc.std_trans_m])
    ext = {"joint predicted": predicted,
           "opencv": extrinsic_errors(with_cv.X, sc.X),
           "joint": extrinsic_errors(joint.X, sc.X),
           "true": extrinsic_errors(with_true.X, sc.X)}
    if views is not None:
        ext[f"joint + {extra} lens views"] = extrinsic_errors(joint_more.X, sc.X)
        for j in range(m):
            rays = np.concatenate([sc.object_points @ T[:3, :3].T + T[:3, 3]
                                   for T in sc.truth.T_cam_target[j]])
            rows[j][f"joint + {extra}"] = projection_error(joint_more.intrinsics[j],
                                                            sc.intrinsics[j], rays)
    return rows, ext, (t_cv, t_joint)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--images", type=int, default=50)
    parser.add_argument("--lens-views", type=int, default=0,
                        help="also the joint problem with this many extra views per camera "
                             "without motion capture (intrinsics_images)")
    parser.add_argument("--max-tilt-deg", type=float, default=45.0,
                        help="largest angle between the board's normal and the line of sight")
    parser.add_argument("--distance", type=float, nargs=2, default=(0.5, 2.0),
                        metavar=("NEAR", "FAR"), help="board depth range, metres")
    parser.add_argument("--mrcal-python", default="/usr/bin/python3",
                        help="a Python that can import mrcal ('' to skip)")
    args = parser.parse_args(argv)
    mrcal_python = args.mrcal_python or None
    if mrcal_python and subprocess.run([mrcal_python, "-c", "import mrcal"],
                                       capture_output=True).returncode != 0:
        print(f"mrcal: not importable by {mrcal_python}; its column is left out")
        mrcal_python = None
    scenario = replace(ScenarioSpec(), max_board_tilt_rad=np.radians(args.max_tilt_deg),
                       distance_m=tuple(args.distance))
    proj, ext, times = {}, {}, []
    for t in range(args.trials):
        rows, e, tt = trial(args.seed * 1000 + t, args.images, mrcal_python,
                            args.lens_views, scenario)
        times.append(tt)
        for j, per in rows.items():
            for method, err in per.items():
                proj.setdefault((j, method), []).append(err)
        for method, err in e.items():
            ext.setdefault(method, []).append(err)
    print(f"{args.trials} rigs, {len(LENSES)} cameras x {args.images} images, 0.33 px, "
          f"mocap 0.1 deg / 0.3 mm, boards tilted up to {args.max_tilt_deg:g} deg at "
          f"{args.distance[0]:g}-{args.distance[1]:g} m, {os.cpu_count()} cores")
    print("\nprojection error against the true lens over the observed area, pixels "
          "(RMS over rays and trials; max)")
    order = ["opencv", "mrcal", "joint", f"joint + {args.lens_views}"]
    methods = sorted({m for _, m in proj}, key=order.index)
    print(f"   {'camera':<24}" + "".join(f"{m:>22}" for m in methods))
    for j, lens in enumerate(LENSES):
        cells = []
        for m in methods:
            e = np.concatenate(proj.get((j, m), [np.array([np.nan])]))
            cells.append(f"{np.sqrt(np.mean(e ** 2)):10.4f} ({np.max(e):7.4f})")
        print(f"   cam{j} {lens_model(lens):<19}" + "".join(f"{c:>22}" for c in cells))
    print("\nT_ref_cam error, RMS over trials: rotation deg / translation mm (and the joint "
          "problem's own predicted standard deviation, RMS over trials)")
    cols = ("opencv", "joint", "joint predicted", "true")
    cols = cols[:3] + ((f"joint + {args.lens_views} lens views",) if args.lens_views else ()) \
        + cols[3:]
    print(f"   {'camera':<24}" + "".join(f"{m:>22}" for m in cols))
    for j in range(1, len(LENSES)):
        cells = []
        for m in cols:
            e = np.array(ext[m])[:, j]
            r = np.sqrt(np.mean(e ** 2, axis=0))
            cells.append(f"{r[0]:9.4f} / {1e3 * r[1]:7.3f}")
        print(f"   cam{j} {lens_model(LENSES[j]):<19}" + "".join(f"{c:>22}" for c in cells))
    t = np.array(times)
    print(f"\nrefinement time: intrinsics fixed {np.median(t[:, 0]):.2f} s, joint with "
          f"intrinsics {np.median(t[:, 1]):.2f} s (median)")


if __name__ == "__main__":
    sys.exit(main())
