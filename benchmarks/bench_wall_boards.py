"""The rendered wall-board rig (issue 34): what its images give the detection.

Run from the repository root::

    python benchmarks/bench_wall_boards.py [--data /tmp/bench_walls] [--seeds 2]
        [--instants 30] [--processes 2]

Per variant of :mod:`multieye.sim.wall_boards` (three ChArUco boards of one dictionary with
disjoint id ranges, the rig turning freely; one chessboard per camera, the rig turning 20
degrees either way; each with 6-DoF or planar motion) and seed, the dataset is rendered
(:func:`multieye.sim.wall_dataset.render_wall_dataset`: four cameras 90 degrees apart, 80
degrees of horizontal field, 800 x 600, blur 0.7 px, noise 2 grey levels) and loaded as
``multieye calibrate`` loads it (:func:`multieye.pipeline.camera_data.load_camera_data`).
Reported: the smallest share, over the cameras, of instants with at least one board found;
the images with two boards found; the share of the views the geometry predicts (at least 8
points in the image, within 65 degrees of the board's normal) that were found; the views
whose corners are off their board's true pose by more than 2 px (a board taken for another
would be off by hundreds); the RMS corner error against the truth; the (instant, board)
pairs two cameras saw (each a different end of a wide board); the rendering and the
detection seconds.  Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.core.lens import project_points
from multieye.io import load_rig
from multieye.pipeline.camera_data import load_camera_data
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset

VARIANTS = (("charuco", "6dof"), ("charuco", "planar"), ("chessboard", "6dof"),
            ("chessboard", "planar"))


def _measure(ds: Path, sc, data) -> dict:
    truth = json.loads((ds / "ground_truth.json").read_text())
    n = len(truth["frames"])
    errors, wrong, per_image = [], 0, {}
    for cam, d in data.items():
        for o in d.observations:
            i = int(o.name.removesuffix(".png"))
            T = (g.inv(np.array(truth["T_world_ref"][i]) @ np.array(truth["T_ref_cam"][cam]))
                 @ np.array(truth["T_world_board"][o.target]))
            uv = project_points(o.object_points @ T[:3, :3].T + T[:3, 3], d.intrinsics)
            err = np.linalg.norm(uv - o.image_points, axis=1)
            wrong += int(err.max() > 2.0)
            errors.append(err)
            per_image.setdefault((cam, o.name), []).append(o.target)
    found = {(o.name, cam, o.target) for cam, d in data.items() for o in d.observations}
    predicted = {(f"{v.instant:06d}.png", sc.cameras[v.camera], v.target) for v in sc.views}
    share = min(len({o.name for o in d.observations}) / n for d in data.values())
    by_board: dict = {}
    for cam, d in data.items():
        for o in d.observations:
            by_board.setdefault((o.name, o.target), set()).add(cam)
    e = np.concatenate(errors)
    return {"share": share, "two": sum(len(t) > 1 for t in per_image.values()),
            "found": len(found & predicted) / max(len(predicted), 1), "wrong": wrong,
            "views": len(found), "rms_px": float(np.sqrt(np.mean(e ** 2))),
            "shared": sum(len(c) > 1 for c in by_board.values())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path("/tmp/bench_walls"))
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--instants", type=int, default=30)
    ap.add_argument("--processes", type=int, default=2)
    args = ap.parse_args()
    print(f"{'variant':<20} {'seed':>4} {'min share':>9} {'2 boards':>8} {'views':>5} "
          f"{'found':>6} {'wrong':>5} {'RMS px':>7} {'shared':>6} {'render s':>8} {'detect s':>8}")
    for boards, motion in VARIANTS:
        for seed in range(args.seeds):
            ds = args.data / f"{boards}_{motion}_{seed}"
            spec = WallSpec(n_instants=args.instants, boards=boards, motion=motion)
            t0 = time.perf_counter()
            sc = render_wall_dataset(ds, spec, seed=seed, processes=args.processes,
                                     mocap=seed == 0)
            t1 = time.perf_counter()
            data = load_camera_data(load_rig(ds), processes=args.processes)
            t2 = time.perf_counter()
            r = _measure(ds, sc, data)
            print(f"{boards + ' ' + motion:<20} {seed:>4} {r['share']:>9.2f} {r['two']:>8} "
                  f"{r['views']:>5} {r['found']:>6.2f} {r['wrong']:>5} {r['rms_px']:>7.3f} {r['shared']:>6} "
                  f"{t1 - t0:>8.1f} {t2 - t1:>8.1f}")


if __name__ == "__main__":
    main()
