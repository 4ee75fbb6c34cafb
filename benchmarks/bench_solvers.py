"""Speed and memory of the joint solver against OpenCV 4.x, camera by camera (issue 2, item 6).

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_solvers.py [--repeats 200] [--seed 0] [--quick]

It prints, in one run on one machine:

1. the median time of ``joint`` and ``wang2022`` (:func:`multieye.solve`, input checks
   included) on a 4-camera x 40-measurement problem with 5 % noise, against OpenCV's
   ``calibrateRobotWorldHandEye`` with ``CALIB_ROBOT_WORLD_HAND_EYE_SHAH`` and ``_LI`` called
   once per camera on the same data, as ratios (OpenCV time / our time); our numpy ``shah``
   and ``li`` are timed too, and every OpenCV answer is checked against ours first.  The
   ``joint`` closed form is also timed on its own ("joint solver": from the same per-camera
   arrays, its pass over the measurements included, but without the input checks, which
   OpenCV does not make either: rigidity of every matrix and the spread of the motion), and
   the checks on their own; then the same timed as ``timeit`` does (best of rounds of many
   calls in a row);
2. the median ``joint`` time for 10, 100 and 1000 cameras x 100 measurements;
3. the peak memory (tracemalloc) of ``joint`` against the number of measurements, with the
   slope of log(peak) against log(measurements), which is 1 for linear growth.

OpenCV's notation is ``A X = Z B`` with A = world2cam, X = base2world, Z = gripper2cam,
B = base2gripper; our ``A_i X = Y B_i`` maps onto it with our A as world2cam and our B as
base2gripper, so OpenCV's X and Z are our X and Y.

Times are medians over many repetitions of ``time.perf_counter``; they depend on the machine
and its load, the ratios much less. BLAS and OpenCV run on one thread unless the environment
sets ``OMP_NUM_THREADS`` / ``OPENBLAS_NUM_THREADS`` / ``MKL_NUM_THREADS``: on these small
matrices threads only add overhead, and on a shared machine they make timings erratic.
This is a script, not a test: nothing here is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import gc
import statistics
import time
import tracemalloc
from collections.abc import Callable

import numpy as np

from multieye.sim import rigs as sim
from multieye.solvers import check_measurements, solve
from multieye.solvers.checks import Measurements
from multieye.solvers.joint import solve_joint


def round_times(fns: dict[str, Callable[[], object]], rounds: int,
                block: int) -> dict[str, list[float]]:
    """Mean time per call of each function, seconds, in each of ``rounds`` interleaved rounds.

    Each round runs every function ``block`` times in a row and records the mean per
    call, then moves to the next function, so that a change in the machine's load during
    the run affects all of them alike and their ratios stay meaningful.  A block of calls
    (as ``timeit`` does) measures the function itself; a single call right after a peer
    measures mostly the refilling of the caches and branch predictors the peer evicted,
    which penalises Python code, with its large footprint, far more than a compiled peer.
    """
    for fn in fns.values():
        fn()  # warm-up: lazy imports, caches
    times: dict[str, list[float]] = {name: [] for name in fns}
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        for _ in range(rounds):
            for name, fn in fns.items():
                start = time.perf_counter()
                for _ in range(block):
                    fn()
                times[name].append((time.perf_counter() - start) / block)
    finally:
        if gc_was_enabled:
            gc.enable()
    return times


def median_times(fns: dict[str, Callable[[], object]], repeats: int,
                 block: int = 10) -> dict[str, float]:
    """Median over ``repeats`` interleaved rounds of the time per call (`round_times`)."""
    return {name: statistics.median(t) for name, t in round_times(fns, repeats, block).items()}


def best_times(fns: dict[str, Callable[[], object]], calls: int,
               rounds: int = 10) -> dict[str, float]:
    """Best over ``rounds`` interleaved rounds of ``calls`` calls each, as ``timeit`` reports."""
    return {name: min(t) for name, t in round_times(fns, rounds, calls).items()}


def noisy_problem(seed: int, n_cameras: int, measurements: int, f: float = 0.05):
    """Per-camera lists A, B of a simulated surround rig with the paper's noise."""
    rng = np.random.default_rng(seed)
    scenario = sim.simulate_rig(rng, n_cameras=n_cameras, measurements=measurements)
    noisy = sim.add_noise(scenario, sim.MultiplicativeNoise(f), rng)
    return list(noisy.A), list(noisy.B)


def opencv_per_camera(A: list[np.ndarray], B: list[np.ndarray], flag: int):
    """A closure that runs OpenCV's robot-world/hand-eye solver once per camera.

    The conversion to OpenCV's lists of rotations and translations is done here, once,
    outside the timed closure.
    """
    import cv2

    inputs = [([a[:3, :3] for a in Aj], [a[:3, 3:] for a in Aj],
               [b[:3, :3] for b in Bj], [b[:3, 3:] for b in Bj]) for Aj, Bj in zip(A, B)]

    def run():
        return [cv2.calibrateRobotWorldHandEye(*args, method=flag) for args in inputs]

    return run


def check_opencv_agrees(A, B, flag: int, method: str) -> float:
    """Largest difference between OpenCV's X, Y and ours (per camera, before combining Y)."""
    ours = solve(A, B, method=method)
    worst = 0.0
    for j, (R_X, t_X, R_Y, t_Y) in enumerate(opencv_per_camera(A, B, flag)()):
        worst = max(worst, np.abs(R_X - ours.X[j, :3, :3]).max(),
                    np.abs(t_X.ravel() - ours.X[j, :3, 3]).max(),
                    np.abs(R_Y - ours.Y_per_camera[j, :3, :3]).max(),
                    np.abs(t_Y.ravel() - ours.Y_per_camera[j, :3, 3]).max())
    return float(worst)


def peak_memory(A, B, method: str = "joint") -> int:
    """Peak bytes traced by tracemalloc during one solve (inputs already allocated)."""
    gc.collect()
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    solve(A, B, method=method)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak - base


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=200,
                        help="repetitions per timing on 4 x 40 (median taken)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true", help="fewer repetitions, smaller sizes")
    args = parser.parse_args(argv)
    import cv2

    cv2.setNumThreads(int(os.environ["OMP_NUM_THREADS"]))
    repeats = 30 if args.quick else args.repeats
    print(f"OpenCV {cv2.__version__}, numpy {np.__version__}, "
          f"OMP_NUM_THREADS={os.environ['OMP_NUM_THREADS']}")

    # 1. 4 cameras x 40 measurements against OpenCV, camera by camera
    A, B = noisy_problem(args.seed, 4, 40)
    flags = {"shah": cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH, "li": cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI}
    for name, flag in flags.items():
        print(f"check: max |OpenCV {name} - multieye {name}| = "
              f"{check_opencv_agrees(A, B, flag, name):.1e}")
    def joint_solver():
        """The joint closed form on the same arrays, without the input checks."""
        return solve_joint(Measurements.from_cameras(A, B))

    X, Y = joint_solver()
    assert np.abs(X - solve(A, B).X).max() < 1e-12 and np.abs(Y - solve(A, B).Y).max() < 1e-12
    fns = {m: (lambda m=m: solve(A, B, method=m)) for m in ("joint", "wang2022", "shah", "li")}
    fns.update({f"opencv-{n}": opencv_per_camera(A, B, f) for n, f in flags.items()})
    fns["joint solver"] = joint_solver
    fns["input checks"] = lambda: check_measurements(A, B, per_camera_motion=False)
    times = median_times(fns, repeats)
    print(f"\n4 cameras x 40 measurements, 5 % noise, median of {repeats} interleaved rounds "
          "of 10 calls, per call:")
    for name, t in times.items():
        print(f"  {name:<13} {t * 1e3:8.3f} ms")
    print("ratios (OpenCV per camera / multieye):")
    for ours in ("joint", "wang2022", "joint solver"):
        for theirs in ("opencv-shah", "opencv-li"):
            print(f"  {theirs} / {ours:<12} {times[theirs] / times[ours]:7.2f}x")
    # the same, timed as timeit does: many calls in a row, best of the rounds
    calls = 30 if args.quick else 300
    best = best_times({k: fns[k] for k in ("joint", "joint solver", "opencv-shah")}, calls)
    print(f"timed like timeit ({calls} calls in a row, best of 10 interleaved rounds): "
          f"joint {best['joint'] * 1e3:.3f} ms, joint solver {best['joint solver'] * 1e3:.3f} "
          f"ms, OpenCV Shah {best['opencv-shah'] * 1e3:.3f} ms; OpenCV Shah / joint "
          f"{best['opencv-shah'] / best['joint']:.2f}x, / joint solver "
          f"{best['opencv-shah'] / best['joint solver']:.2f}x")

    # 2. joint on large rigs
    print("\njoint, 100 measurements per camera:")
    for m in (10, 100) if args.quick else (10, 100, 1000):
        A, B = noisy_problem(args.seed, m, 100)
        reps = max(5, repeats // (10 if m >= 1000 else 2 if m >= 100 else 1))
        t = median_times({"joint": lambda: solve(A, B, method="joint")}, reps, block=1)["joint"]
        print(f"  {m:5d} cameras x 100: {t * 1e3:9.2f} ms (median of {reps})")

    # 3. memory of joint against measurements
    print("\njoint peak memory (tracemalloc), 4 cameras:")
    counts = (250, 1000, 4000) if args.quick else (250, 1000, 4000, 16000)
    peaks = []
    for n in counts:
        A, B = noisy_problem(args.seed, 4, n)
        peaks.append(peak_memory(A, B))
        print(f"  {4 * n:6d} measurements: peak {peaks[-1] / 1e6:8.2f} MB, "
              f"{peaks[-1] / (4 * n):7.0f} bytes per measurement")
    slope = np.polyfit(np.log(np.array(counts, dtype=float)), np.log(np.array(peaks, float)), 1)[0]
    print(f"  slope of log(peak) vs log(measurements): {slope:.2f} (1 = linear; below 1 while "
          "the fixed working space of the checks still counts)")


if __name__ == "__main__":
    main()
