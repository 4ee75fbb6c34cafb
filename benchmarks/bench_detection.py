"""Detection + PnP throughput against the decode floor and the OpenCV script (issue 21, item 1).

Run from the repository root::

    python benchmarks/bench_detection.py [--runs 3] [--processes 2] [--variant NAME ...]
        [--no-real]

On the 4 x 100 rendered images of ``benchmarks/bench_peers.py`` (800 x 600 PNG, rendered once
into ``benchmarks/.cache/peers_4x100``; ``--variant`` names its other renderings: sizes,
JPEG, boards, lenses, a second renderer), and on the 30 real 1280 x 720 images of
``young_mocap_cam`` when the shared data are there (``MULTIEYE_SHARED_DATA`` or
``../shared/data``), it times, in turn (A B C D, A B C D, ...), ``--runs`` times each:

A. ``imread``: ``cv2.imread(path, cv2.IMREAD_GRAYSCALE)`` alone, on ``--processes`` worker
   processes from the same pool as B (:func:`multieye.imaging.workers.worker_pool`, the same
   fork server, the same chunks, pool start included): the floor, since every image must be
   decoded once;
B. ``multieye``: :func:`multieye.imaging.batch.detect_and_estimate_jobs`, one job per camera
   on one pool of ``--processes`` workers (pool start included): bounded read, gray decode,
   ``findChessboardCorners`` (SB where it fails), ``cornerSubPix``, canonical order, PnP
   (IPPE + Levenberg-Marquardt) with the camera's lens;
C. ``opencv loop``: the detection loop of ``benchmarks/peers/opencv_script.py`` (``imread``,
   ``findChessboardCorners``, ``cornerSubPix``), in this one process as the script runs it;
D. ``opencv loop, N processes``: the same loop split over ``--processes`` workers of the pool.

For each: images per second (median of the runs, wall), CPU seconds (this process, and its
workers once the pool has joined them: they are the fork server's children, whose collected
CPU time ``/proc/<fork server>/stat`` gives), how many images gave a result; and the ratio B / A of the time per
image, the goal of issue 21 being at most 1.5. The first pool of a session also starts the
fork server (imports numpy and OpenCV): timed once, separately, before the runs.

Times depend on the load of the machine (other processes on the same cores): the load
average is printed with each run. This is a script, not a test: nothing here is asserted.
"""

from __future__ import annotations

import argparse
import os
from multiprocessing import forkserver
import platform
import resource
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from multieye.core.intrinsics import Intrinsics
from multieye.imaging.batch import ImageJob, _mp_context, detect_and_estimate_jobs
from multieye.imaging.targets import Chessboard, target_from_spec
from multieye.imaging.workers import worker_pool
from multieye.io import read_intrinsics

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from bench_peers import VARIANTS, rendered, variant_settings  # noqa: E402  (cached renders)

SHARED = Path(os.environ.get("MULTIEYE_SHARED_DATA", ROOT.parent / "shared" / "data"))
YOUNG = SHARED / "young_mocap_cam" / "example_dataset"
YOUNG_BOARD = Chessboard(rows=8, cols=11, spacing=0.03)


def _cpu() -> float:
    """CPU seconds of this process, its collected children and the fork server's collected
    children (the workers are the fork server's children, not ours)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
    pid = getattr(getattr(forkserver, "_forkserver", None), "_forkserver_pid", None)
    if pid is not None:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        # fields 14-17 of proc(5): utime, stime, cutime, cstime (fields[0] is field 3)
        total += sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")
    return total


def _imread(path: str) -> bool:
    return cv2.imread(path, cv2.IMREAD_GRAYSCALE) is not None


_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 1e-3)


def _opencv_one(item: tuple[str, int, int]) -> bool:
    """One image of opencv_script.py's detection loop."""
    path, rows, cols = item
    gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    found, c = cv2.findChessboardCorners(gray, (cols, rows), cv2.CALIB_CB_ADAPTIVE_THRESH
                                         + cv2.CALIB_CB_NORMALIZE_IMAGE)
    if found:
        cv2.cornerSubPix(gray, c, (5, 5), (-1, -1), _CRITERIA)
    return bool(found)


def _single_thread() -> None:
    cv2.setNumThreads(1)


def _pool_map(fn, items: list, processes: int) -> list:
    """``fn`` over ``items`` on a fresh pool from multieye's fork server, chunked as
    multieye chunks (about four chunks per worker)."""
    chunk = max(1, -(-len(items) // (processes * 4)))
    with worker_pool(processes, mp_context=_mp_context(), initializer=_single_thread) as pool:
        return list(pool.map(fn, items, chunksize=chunk))


def dataset_jobs(variants: list[str], real: bool = True) -> list[tuple[str, list[ImageJob]]]:
    """The image sets: per camera one job (paths, target, lens); ``variants`` name the
    renderings of ``bench_peers.py`` (its ``VARIANTS`` or ``key=value`` lists)."""
    sets = []
    for name in variants:
        v = variant_settings(name)
        folder, _ = rendered(v)
        rows, cols = (int(x) for x in v["board"].split("x"))
        board = target_from_spec({"type": "chessboard", "rows": rows, "cols": cols,
                                  "spacing": 0.05 if rows * cols <= 60 else 0.035})
        jobs = [ImageJob(tuple(str(p) for p in sorted((folder / cam).iterdir())
                               if p.suffix in (".png", ".jpg")), board,
                         read_intrinsics(folder / f"{cam}.yaml"))
                for cam in sorted(p.name for p in folder.iterdir() if p.is_dir())]
        sets.append((f"rendered {name}: {v['images']} images x 4, {v['size']} {v['format']}, "
                     f"{v['renderer']}, chessboard {v['board']}, {v['lens']}", jobs))
    images = YOUNG / "rgb_images"
    if not real:
        return sets
    if images.is_dir():
        lens = Intrinsics(K=[[607.88, 0, 641.875], [0, 607.966, 365.585], [0, 0, 1]],
                          dist=[0.458331, -2.87024, 0.00048617, -9.82262e-05, 1.74446,
                                0.331466, -2.66947, 1.65473], width=1280, height=720)
        sets.append(("young_mocap_cam, 30 real 1280 x 720 PNG, chessboard 8x11",
                     [ImageJob(tuple(str(p) for p in sorted(images.glob("*.png"))),
                               YOUNG_BOARD, lens)]))
    else:
        print(f"{images} not found: the real images are skipped")
    return sets


def measure(name: str, jobs: list[ImageJob], runs: int, processes: int) -> None:
    paths = [p for job in jobs for p in job.paths]
    n = len(paths)
    board = jobs[0].target
    loop_items = [(p, board.rows, board.cols) for p in paths]
    methods = {
        "imread (gray), the floor": lambda: _pool_map(_imread, paths, processes),
        "multieye: detection + PnP": lambda: [
            r.ok for rs in detect_and_estimate_jobs(jobs, processes=processes, progress=False)
            for r in rs],
        "OpenCV script's loop, 1 process": lambda: [_opencv_one(i) for i in loop_items],
        "OpenCV script's loop": lambda: _pool_map(_opencv_one, loop_items, processes),
    }
    procs = {"OpenCV script's loop, 1 process": 1}
    times = {k: [] for k in methods}
    cpus = {k: [] for k in methods}
    found = {}
    for r in range(runs):
        for key, fn in methods.items():
            cpu0, t0 = _cpu(), time.perf_counter()
            out = fn()
            times[key].append(time.perf_counter() - t0)
            cpus[key].append(_cpu() - cpu0)
            found[key] = sum(bool(x) for x in out)
        print(f"  run {r + 1}/{runs} done, load average {os.getloadavg()[0]:.2f}", flush=True)
    print(f"\n{name}: {n} images, {runs} runs each, in turn\n")
    print("| method | processes | ms per image (wall, median) | images/s | CPU ms per image "
          "(median) | with a result | time / imread's |")
    print("|---|---|---|---|---|---|---|")
    floor = float(np.median(times["imread (gray), the floor"]))
    for key in methods:
        wall = float(np.median(times[key]))
        print(f"| {key} | {procs.get(key, processes)} | {1e3 * wall / n:.2f} | {n / wall:.0f} | "
              f"{1e3 * float(np.median(cpus[key])) / n:.2f} | {found[key]}/{n} | "
              f"{wall / floor:.2f} |")
    ours = np.array(times["multieye: detection + PnP"])
    base = np.array(times["imread (gray), the floor"])
    print(f"\nmultieye / imread, run by run: {', '.join(f'{x:.2f}' for x in ours / base)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--variant", action="append", default=[],
                    help="renderings of bench_peers.py: " + ", ".join(VARIANTS) + ", 'all' or "
                    "key=value,... (repeat; default: base)")
    ap.add_argument("--no-real", action="store_true", help="leave out the real images")
    args = ap.parse_args()
    names = [n for v in (args.variant or ["base"]) for n in (VARIANTS if v == "all" else [v])]
    sets = dataset_jobs(names, real=not args.no_real)
    print(f"machine: {platform.machine()}, {len(os.sched_getaffinity(0))} cores, Python "
          f"{platform.python_version()}, OpenCV {cv2.__version__}, numpy {np.__version__}; "
          f"load average {os.getloadavg()[0]:.2f} at start")
    t0 = time.perf_counter()
    _pool_map(_imread, list(sets[0][1][0].paths[:args.processes]), args.processes)
    print(f"first pool of the session (fork server start: numpy, OpenCV, multieye.imaging): "
          f"{time.perf_counter() - t0:.2f} s; the pools timed below start warm")
    for name, jobs in sets:
        measure(name, jobs, args.runs, args.processes)


if __name__ == "__main__":
    main()
