"""A rig linked by its own motion, without motion capture and without overlap (issue 34).

Run from the repository root::

    python benchmarks/bench_motion_links.py [--rigs 20] [--first-seed 0] [--pixel-noise 0.3]
        [--instants 40] [--rendered DIR]

The rigs (:func:`multieye.sim.wall_boards.simulate_walls`, seeds --first-seed ..
--first-seed + --rigs - 1): four cameras 90 degrees apart about the vertical (none
overlapping, 80 degree field of view, 800 x 600, slight radial distortion), moved in front of
three ChArUco boards on the north, west and south walls of a 4 m room, --instants poses.
Array level: the boards' true corners seen at each instant with Gaussian pixel noise
(--pixel-noise per coordinate), no rendering, no detection; with ``--rendered DIR`` each rig
is rendered (:func:`multieye.sim.wall_dataset.render_wall_dataset`: blur, sensor noise) and
its boards detected by multieye (``load_camera_data``), and those corners are used (the
observability part is then skipped).  Every view's starting pose is
OpenCV's PnP (IPPE, then iterative) with the starting lens.  Per rig, four solves on the same
pixels (the rigs whose start left views unprojectable, re-posed, and those whose first
refinement left views far off at a local optimum, looked at again, by
:mod:`multieye.estimate.motion_repose`, are listed after the table):

- ``motion``: :func:`multieye.estimate.refine_motion.refine_motion` (the start from the
  loops the views close and the joint hand-eye problem with the rig's own poses, then the
  joint maximum likelihood), lenses given (the true ones);
- ``motion, lenses estimated``: the same with every lens estimated, started from OpenCV's
  ``calibrateCamera`` on each camera's own views (k1 k2 p1 p2; the pipeline's lens start),
  the PnP poses with that lens;
- ``+ mocap`` of each: the same pixels plus the rig's motion capture (a marker body at a
  random offset, in a random motion-capture frame, 0.03 degrees and 0.1 mm of noise per
  axis) in the same problem (:mod:`multieye.estimate.motion_mocap`).

Reported: the error of each camera's ``T_ref_cam`` against the truth (RMS over rigs and
cameras, degrees and mm), the NEES per degree of freedom (``e^T C^-1 e / 6``; 1 when the
covariance is honest), how many cameras fall within 3 sigma (``e^T C^-1 e`` below the 99.73 %
quantile of chi-square with 6 degrees of freedom), and the ratio of the errors without motion
capture to those with it.  Then the observability: the same rigs driven on the floor, once
with one chessboard per camera on the wall it faces (the rig turning 20 degrees either way,
so each camera sees only its own board) and once with the ChArUco boards and free turns
(each camera sees every board over the recording): which cameras
:func:`multieye.estimate.observability.observability` names, in which direction, how far
beyond the camera's best-determined direction.  No peer: MC-Calib and Kalibr are C++/ROS,
with no package on the index; this setup has none to install from it.  Nothing is asserted.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np
from scipy.stats import chi2

from multieye.core import geometry as g
from multieye.core.lens import undistort_points
from multieye.core.lie import log_so3
from multieye.estimate.motion_mocap import RigMocap
from multieye.estimate.motion_residuals import MotionViews
from multieye.estimate.observability import observability
from multieye.estimate.refine_motion import refine_motion
from multieye.io import load_rig
from multieye.pipeline.camera_data import load_camera_data
from multieye.sim.wall_boards import WallSpec, WallView, noisy_views, simulate_walls
from multieye.sim.wall_dataset import render_wall_dataset

LIMIT = float(chi2.ppf(0.9973, 6))


def _pnp(obj, uv, intr):
    """The board's pose from its pixels: IPPE on the undistorted points, then iterative."""
    xy = undistort_points(uv, intr)
    ok, rvec, tvec = cv2.solvePnP(obj, xy, np.eye(3), None, flags=cv2.SOLVEPNP_IPPE)
    ok, rvec, tvec = cv2.solvePnP(obj, xy, np.eye(3), None, rvec, tvec, True,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
    return g.transform_from_rotvec(rvec.ravel(), tvec.ravel())


def _views(sc, views, lenses):
    """MotionViews and PnP starts; instants renumbered over those with a view."""
    boards = list(sc.targets)
    used = {t: k for k, t in enumerate(sorted({v.instant for v in views}))}
    per = {n: [] for n in sc.cameras}
    T0 = []
    for v in sorted(views, key=lambda v: v.camera):
        per[sc.cameras[v.camera]].append((v.object_points, v.image_points, used[v.instant],
                                          boards.index(v.target)))
        T0.append(_pnp(v.object_points, v.image_points, lenses[v.camera]))
    return per, np.stack(T0), np.array(sorted(used))


def _lens_starts(sc, views):
    """Each camera's lens from its own views alone (OpenCV's calibrateCamera, k1 k2 p1 p2,
    as the pipeline's lens start), from the true one's principal point and focal length
    guessed to within 5 %."""
    out = []
    for j, intr in enumerate(sc.intrinsics):
        mine = [v for v in views if v.camera == j]
        K0 = intr.K.copy()
        K0[0, 0] *= 1.05
        K0[1, 1] *= 1.05
        _, K, dist, _, _ = cv2.calibrateCamera(
            [v.object_points.astype(np.float32) for v in mine],
            [v.image_points.astype(np.float32) for v in mine], (intr.width, intr.height), K0,
            np.zeros(5), flags=cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_K3)
        out.append(intr.with_params(np.concatenate([[K[0, 0], K[1, 1], K[0, 2], K[1, 2]],
                                                    dist.ravel()[:4]])))
    return out


def _mocap(sc, instants, rng):
    Ym, Xm = g.random_transforms(rng, 2)
    M = Ym @ sc.T_world_ref[instants] @ Xm
    rot, trans = np.radians(0.03), 1e-4
    M = M @ g.transform_from_rotvec(rng.normal(scale=rot, size=(len(M), 3)),
                                    np.zeros((len(M), 3)))
    M[:, :3, 3] += rng.normal(scale=trans, size=(len(M), 3))
    return RigMocap(np.arange(len(M)), M, rot, trans)


def _errors(res, sc):
    out = []
    for j in range(1, len(sc.cameras)):
        e = np.concatenate([log_so3(res.T_ref_cam[j, :3, :3] @ sc.T_ref_cam[j, :3, :3].T),
                            res.T_ref_cam[j, :3, 3] - sc.T_ref_cam[j, :3, 3]])
        m2 = float(e @ np.linalg.solve(res.covariance[j], e))
        sd = np.sqrt(np.diag(res.covariance[j]))
        out.append((np.degrees(np.linalg.norm(e[:3])), 1e3 * np.linalg.norm(e[3:]), m2,
                    np.degrees(np.linalg.norm(sd[:3])), 1e3 * np.linalg.norm(sd[3:])))
    return out


def _detected(folder: Path, seed: int, n: int):
    """Render the rig (once) and detect its boards as the pipeline does: the truth and the
    views (``WallView`` of the detected corners, instant from the frame-numbered name)."""
    ds = folder / f"rig{seed:03d}"
    sc = render_wall_dataset(ds, WallSpec(n_instants=n), seed=seed) if not (
        ds / "rig.yaml").exists() else simulate_walls(np.random.default_rng(seed),
                                                      WallSpec(n_instants=n))
    data = load_camera_data(load_rig(ds), processes=1)
    views = [WallView(sc.cameras.index(cam), int(o.name.removesuffix(".png")), o.target,
                      np.arange(len(o.object_points)), o.object_points, o.image_points)
             for cam, d in data.items() for o in d.observations]
    return sc, views


def _rig(seed: int, noise: float, n: int, rendered: Path | None = None) -> dict:
    if rendered is None:
        sc = simulate_walls(np.random.default_rng(seed), WallSpec(n_instants=n))
        views = noisy_views(sc, noise, np.random.default_rng(10_000 + seed))
    else:
        sc, views = _detected(rendered, seed, n)
    mocap_rng = np.random.default_rng(20_000 + seed)
    out = {}
    for free in (False, True):
        lenses = _lens_starts(sc, views) if free else list(sc.intrinsics)
        per, T0, instants = _views(sc, views, lenses)
        mv = MotionViews(per, lenses, free_intrinsics=[free] * len(lenses))
        mocap = _mocap(sc, instants, mocap_rng)
        for with_mocap in (False, True):
            t0 = time.process_time()
            res = refine_motion(mv, T0, mocap=mocap if with_mocap else None)
            key = ("lenses estimated" if free else "lenses given", with_mocap)
            out[key] = (_errors(res, sc), time.process_time() - t0, res.pixel_sigma,
                        len(res.reposed), len(res.second_look))
    return out


def _summary(rows: list, label: str) -> tuple[float, float]:
    e = np.array([r for rig in rows for r in rig])
    nees = e[:, 2] / 6
    rms_r, rms_t = np.sqrt(np.mean(e[:, 0] ** 2)), np.sqrt(np.mean(e[:, 1] ** 2))
    print(f"| {label} | {rms_r:.4f} | {rms_t:.3f} | {np.sqrt(np.mean(e[:, 3] ** 2)):.4f} | "
          f"{np.sqrt(np.mean(e[:, 4] ** 2)):.3f} | {nees.mean():.2f} "
          f"[{np.percentile(nees, 10):.2f}, {np.percentile(nees, 90):.2f}] | "
          f"{int(np.sum(e[:, 2] < LIMIT))}/{len(e)} |")
    return rms_r, rms_t


def _planar(seeds, noise: float, n: int) -> None:
    for boards, what in (("chessboard", "one chessboard per camera, turned +-20 deg"),
                         ("charuco", "three ChArUco boards, turned freely")):
        named, ratios, dirs, nees = {}, [], [], []
        for seed in seeds:
            sc = simulate_walls(np.random.default_rng(seed),
                                WallSpec(n_instants=n, boards=boards, motion="planar"))
            per, T0, _ = _views(sc, noisy_views(sc, noise, np.random.default_rng(seed + 7)),
                                sc.intrinsics)
            mv = MotionViews(per, sc.intrinsics)
            res = refine_motion(mv, T0)
            if res.reposed or res.second_look:
                print(f"  planar {boards} seed {seed}: {len(res.reposed)} views re-posed at "
                      f"the start, {len(res.second_look)} in a second look")
            obs = observability(res, mv)
            for u in obs.undetermined:
                named[(u.camera, u.kind, u.along_turn_axis)] = named.get(
                    (u.camera, u.kind, u.along_turn_axis), 0) + 1
                ratios.append(u.sigma / u.best_sigma)
                dirs.append(abs(u.direction_rig[1]))
            if not obs.undetermined:
                nees += [m2 / 6 for *_, m2, _, _ in _errors(res, sc)]
        print(f"\nplanar, {what}: {len(seeds)} rigs")
        for (cam, kind, along), k in sorted(named.items()):
            print(f"  {cam}: {kind} {'along the turn axis' if along else 'elsewhere'}: "
                  f"named on {k} rigs")
        if ratios:
            print(f"  sigma / best-determined: {min(ratios):.0f} .. {max(ratios):.0f}; "
                  f"|component along the rig's vertical| >= {min(dirs):.4f}")
        if nees:
            print(f"  rigs with nothing undetermined: NEES {np.mean(nees):.2f} over "
                  f"{len(nees)} cameras")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rigs", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--pixel-noise", type=float, default=0.3)
    ap.add_argument("--instants", type=int, default=40)
    ap.add_argument("--rendered", type=Path, default=None,
                    help="render each rig into this folder (kept) and use the corners "
                         "multieye detects instead of the true ones with noise")
    a = ap.parse_args()
    seeds = range(a.first_seed, a.first_seed + a.rigs)
    runs = [_rig(s, a.pixel_noise, a.instants, a.rendered) for s in seeds]
    print(f"{a.rigs} rigs, {a.instants} instants, "
          + (f"rendered into {a.rendered}" if a.rendered else f"{a.pixel_noise} px")
          + "; 3 cameras per rig (cam1..cam3 against cam0)\n")
    print("| solve | rot RMS (deg) | trans RMS (mm) | predicted rot (deg) | predicted trans "
          "(mm) | NEES mean [10 %, 90 %] | within 3 sigma |")
    print("|---|---|---|---|---|---|---|")
    for lens in ("lenses given", "lenses estimated"):
        no = _summary([r[(lens, False)][0] for r in runs], f"motion, {lens}")
        yes = _summary([r[(lens, True)][0] for r in runs], f"motion + mocap, {lens}")
        cpu = np.median([r[(lens, False)][1] for r in runs])
        print(f"| ratio without / with mocap, {lens} | {no[0] / yes[0]:.2f} | "
              f"{no[1] / yes[1]:.2f} | | | median CPU {cpu:.2f} s | |")
    for key in [(lens, m) for lens in ("lenses given", "lenses estimated") for m in (False, True)]:
        for col, what in ((3, "starts re-posed"), (4, "second looks kept")):
            hit = [(s, r[key][col]) for s, r in zip(seeds, runs) if r[key][col]]
            if hit:
                print(f"{what} ({key[0]}{', mocap' if key[1] else ''}): "
                      + ", ".join(f"seed {s} ({k} views)" for s, k in hit))
    if a.rendered is None:
        _planar(seeds, a.pixel_noise, a.instants)


if __name__ == "__main__":
    main()
