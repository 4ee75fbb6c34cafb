"""Detection throughput: ``detect_and_estimate`` on 2 processes against a plain OpenCV loop.

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_detection.py [--images 80] [--processes 2] [--seed 0]

It prints, in one run on one machine:

1. the time (wall and CPU) to render the synthetic chessboard images (800x600, lens
   distortion, blur and noise; :func:`multieye.sim.render`) in this one process, and what
   that means for the demo's 4 cameras x 40 images on 2 cores;
2. for those images and, when ``../shared/data/young_mocap_cam`` is present, its 30 real
   1280x720 images: images per second of

   - the baseline: one process, ``cv2.imread`` + ``cv2.findChessboardCorners`` with default
     flags, nothing else;
   - :func:`multieye.imaging.batch.detect_and_estimate` with ``--processes`` workers (pool
     start-up included; the fork server's one-off start in a session is timed separately
     first) and with 1 process: read, ``findChessboardCornersSB`` (classic fallback),
     ``cornerSubPix``, canonical order, IPPE + Levenberg-Marquardt PnP;

   and the ratio of ours on ``--processes`` cores to the baseline, plus how many images each
   found the board in.

The two do different amounts of work: the baseline stops at integer-ish corners, ours ends at a
sub-pixel pose. Times depend on the machine and its load (other processes on the same cores
slow both); the ratio less so. This is a script, not a test: nothing here is asserted.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from multieye.core.geometry import transform_from_rotvec
from multieye.imaging.batch import detect_and_estimate
from multieye.sim.render import render, visible
from multieye.imaging.targets import Chessboard
from multieye.core.intrinsics import Intrinsics

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"

SYNTHETIC_CAMERA = Intrinsics(K=[[600.0, 0, 399.5], [0, 600.0, 299.5], [0, 0, 1]],
                              dist=[-0.28, 0.09, 0.0008, -0.0005, -0.015], width=800, height=600)
SYNTHETIC_BOARD = Chessboard(rows=6, cols=9, spacing=0.04)

YOUNG_CAMERA = Intrinsics(K=[[607.88, 0, 641.875], [0, 607.966, 365.585], [0, 0, 1]],
                          dist=[0.458331, -2.87024, 0.00048617, -9.82262e-05, 1.74446, 0.331466,
                                -2.66947, 1.65473], width=1280, height=720)
YOUNG_BOARD = Chessboard(rows=8, cols=11, spacing=0.03)


def random_views(n: int, rng: np.random.Generator) -> list[np.ndarray]:
    """``n`` poses T_cam_target of the synthetic board, whole board in view."""
    x0, x1, y0, y1 = SYNTHETIC_BOARD.bounds()
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    views = []
    while len(views) < n:
        T = transform_from_rotvec(rng.normal(0, 0.3, 3), np.zeros(3))
        T[:3, 3] = -T[:3, :3] @ centre + [*rng.normal(0, 0.08, 2), rng.uniform(0.55, 1.1)]
        if visible(SYNTHETIC_BOARD, SYNTHETIC_CAMERA, T):
            views.append(T)
    return views


def render_images(folder: Path, n: int, seed: int) -> tuple[list[Path], float, float]:
    """Write ``n`` rendered views; return the paths and the render wall and CPU time."""
    rng = np.random.default_rng(seed)
    views = random_views(n, rng)
    render(SYNTHETIC_BOARD, SYNTHETIC_CAMERA, views[0])        # ray grid of the camera, once
    paths, wall, cpu = [], 0.0, 0.0
    for k, T in enumerate(views):
        start, start_cpu = time.perf_counter(), time.process_time()
        image = render(SYNTHETIC_BOARD, SYNTHETIC_CAMERA, T, rng=rng)
        wall += time.perf_counter() - start
        cpu += time.process_time() - start_cpu
        path = folder / f"{k:04d}.png"
        cv2.imwrite(str(path), image)
        paths.append(path)
    return paths, wall, cpu


def baseline(paths: list[Path], board: Chessboard) -> tuple[float, int]:
    """Plain loop: read and findChessboardCorners, default flags, this process."""
    start = time.perf_counter()
    found = 0
    for p in paths:
        image = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        ok, _ = cv2.findChessboardCorners(image, (board.cols, board.rows))
        found += bool(ok)
    return time.perf_counter() - start, found


def ours(paths: list[Path], board: Chessboard, camera: Intrinsics, processes: int) -> tuple[float, int]:
    start = time.perf_counter()
    results = detect_and_estimate(paths, board, camera, processes=processes, progress=False)
    return time.perf_counter() - start, sum(r.ok for r in results)


def compare(name: str, paths: list[Path], board: Chessboard, camera: Intrinsics, processes: int) -> None:
    n = len(paths)
    t_base, f_base = baseline(paths, board)
    t_par, f_par = ours(paths, board, camera, processes)
    t_one, f_one = ours(paths, board, camera, 1)
    print(f"\n{name}: {n} images")
    print(f"  {'method':58s} {'img/s':>7s} {'found':>7s}")
    print(f"  {'baseline: imread + findChessboardCorners, 1 process':58s} {n / t_base:7.1f} {f_base:4d}/{n}")
    print(f"  {f'detect_and_estimate, {processes} processes (pool start included)':58s} {n / t_par:7.1f} {f_par:4d}/{n}")
    print(f"  {'detect_and_estimate, 1 process':58s} {n / t_one:7.1f} {f_one:4d}/{n}")
    print(f"  ratio ours ({processes} processes) / baseline: {t_base / t_par:.2f}   "
          f"(1 process: {t_base / t_one:.2f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--images", type=int, default=80, help="rendered images (default 80)")
    parser.add_argument("--processes", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    print(f"OpenCV {cv2.__version__}, cv2.getNumThreads() = {cv2.getNumThreads()} in this process")
    with tempfile.TemporaryDirectory() as tmp:
        paths, wall, cpu = render_images(Path(tmp), args.images, args.seed)
        per_image = wall / len(paths)
        print(f"\nrender: {len(paths)} images of 800x600, {per_image * 1e3:.0f} ms each "
              f"({cpu / len(paths) * 1e3:.0f} ms CPU; 1 process); the demo's 4 x 40 = 160 images: "
              f"{160 * per_image:.1f} s on 1 core, about {160 * per_image / 2:.1f} s on 2")
        start = time.perf_counter()
        detect_and_estimate(paths[:args.processes], SYNTHETIC_BOARD, SYNTHETIC_CAMERA,
                            processes=args.processes, progress=False)
        print(f"first pool of the session (fork server start, {args.processes} images): "
              f"{time.perf_counter() - start:.2f} s; the pools timed below start warm")
        compare("rendered chessboard 6x9, 800x600", paths, SYNTHETIC_BOARD, SYNTHETIC_CAMERA, args.processes)
    young = SHARED / "young_mocap_cam" / "example_dataset" / "rgb_images"
    if young.is_dir():
        compare("young_mocap_cam, real 1280x720, chessboard 8x11", sorted(young.glob("*.png")),
                YOUNG_BOARD, YOUNG_CAMERA, args.processes)
    else:
        print(f"\n{young} not found: real images skipped")


if __name__ == "__main__":
    main()
