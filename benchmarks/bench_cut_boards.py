"""Chessboards cut by the image edge (issue 35): how many are returned, and how many of those
are shifted off the truth.

Run from the repository root::

    python benchmarks/bench_cut_boards.py [--seed 7] [--poses 200] [--no-saddle]

Poses are drawn around the wall rig's view where SB at full size returned a 6 x 9 grid
shifted by a column (``render_wall_dataset(out, WallSpec(boards="chessboard",
motion="6dof"), seed=0)``, ``cam0/000001.png``, its last column cut by the image's right
edge): turned by 0.08 rad and moved by (0.08, 0.08, 0.15) m (standard deviations), rendered
as the wall rig renders (blur 0.7 px, noise 2 grey levels).  Printed: the views whose board
is cut (some inner corner outside the image), those a grid was returned for and those
returned more than 2 px off the truth; the views whose board is whole and those found.
``--no-saddle`` switches :func:`multieye.imaging.chessboard_corners.saddle_grid` off, to see
what :func:`~multieye.imaging.chessboard_corners.whole_board` keeps out on its own.  Run it
with another checkout's ``src`` on ``PYTHONPATH`` to compare.  Nothing is asserted:
tests/imaging/test_cut_boards.py checks the behaviour.
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

from multieye.core import geometry as g
from multieye.core.lens import project_points
from multieye.imaging import chessboard_corners as cc
from multieye.imaging.detect import detect
from multieye.imaging.targets import target_from_spec
from multieye.sim.render import render_boards
from multieye.sim.wall_boards import WallSpec, simulate_walls


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--poses", type=int, default=200)
    ap.add_argument("--no-saddle", action="store_true")
    args = ap.parse_args()
    if args.no_saddle:
        cc.saddle_grid = lambda *a: True
    sc = simulate_walls(np.random.default_rng(0), WallSpec(n_instants=30, boards="chessboard",
                                                           motion="6dof"))
    spec = {k: v for k, v in sc.targets["north"].items() if k != "cameras"}
    board, intr = target_from_spec(spec), sc.intrinsics[0]
    T0 = g.inv(sc.T_world_ref[1] @ sc.T_ref_cam[0]) @ sc.board_pose("north")
    rng = np.random.default_rng(args.seed)
    n = {"cut": 0, "returned": 0, "shifted": 0, "whole": 0, "found": 0}
    for _ in range(args.poses):
        T = T0.copy()
        T[:3, :3] = cv2.Rodrigues(rng.normal(0, 0.08, 3))[0] @ T[:3, :3]
        T[:3, 3] += rng.normal(0, [0.08, 0.08, 0.15])
        uv = project_points(board.object_points() @ T[:3, :3].T + T[:3, 3], intr)
        inside = ((uv >= 0) & (uv < [intr.width, intr.height])).all(axis=1)
        image = render_boards([(board, T)], intr, rng=rng, blur_sigma=0.7, noise_sigma=2.0)
        found = detect(image, board)
        if inside.all():
            n["whole"] += 1
            n["found"] += found is not None
        else:
            n["cut"] += 1
            n["returned"] += found is not None
            n["shifted"] += found is not None and np.abs(found.image_points - uv).max() > 2.0
    print(f"cut boards {n['cut']}: returned {n['returned']}, shifted {n['shifted']}; "
          f"whole boards {n['whole']}: found {n['found']}")


if __name__ == "__main__":
    main()
