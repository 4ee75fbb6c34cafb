"""The cost of the outputs (report, figures, exports) of `multieye calibrate` on 4 and 16 cameras.

Run from the repository root::

    python benchmarks/bench_report.py [--cameras 4 16] [--images 40] [--repeats 3] \
        [--src other/checkout/src]

1. Renders, once per size, a rig of ``N`` cameras with ``--images`` images each (800 x 600,
   :func:`multieye.sim.dataset.render_dataset`, seed 0) into ``benchmarks/.cache/report_Nx<images>``
   (git-ignored, reused later).
2. Runs ``python -m multieye calibrate DATASET -o OUT --processes 2`` as a subprocess with the
   sources of ``--src`` first on ``PYTHONPATH`` (default: this checkout's ``src``; pass the
   ``src`` of another checkout, e.g. the main branch, to time it on the same images),
   ``--repeats`` times per size, and prints the ``outputs`` stage of every run as the run
   measured it (``timings_s.outputs`` of ``details.json``: calibration.json, camchain, details,
   report.html and its figures) with the run's total, then the median per size.

The times depend on the machine and on what else runs on it (read the load average printed).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "benchmarks" / ".cache"
SEED = 0


def rendered(cameras: int, images: int) -> Path:
    """The rendering of ``cameras`` x ``images``, made on first use."""
    folder = CACHE / f"report_{cameras}x{images}"
    if (folder / ".complete").exists():
        return folder
    import shutil

    from multieye.sim.dataset import DatasetSpec, render_dataset

    shutil.rmtree(folder, ignore_errors=True)
    print(f"rendering {cameras} x {images} images into {folder} (once) ...", flush=True)
    render_dataset(folder, DatasetSpec(n_cameras=cameras, images_per_camera=images), seed=SEED)
    (folder / ".complete").write_text("complete\n")
    return folder


def run_once(dataset: Path, src: Path, processes: int) -> dict:
    """One ``multieye calibrate``: its timings_s and its wall time."""
    with tempfile.TemporaryDirectory(prefix="bench_report_") as tmp:
        out = Path(tmp) / "out"
        env = dict(os.environ, PYTHONPATH=str(src))
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "multieye", "calibrate", str(dataset),
                               "-o", str(out), "--processes", str(processes)],
                              capture_output=True, text=True, env=env)
        wall = time.perf_counter() - start
        if proc.returncode not in (0, 3):
            raise SystemExit(f"calibrate failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
        timings = json.loads((out / "details.json").read_text())["timings_s"]
        figures = sorted(p.name for p in (out / "figures").iterdir())
    return {"wall": wall, "timings": timings, "figures": len(figures)}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", type=int, nargs="+", default=[4, 16])
    parser.add_argument("--images", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--src", type=Path, default=ROOT / "src",
                        help="the sources to time (a checkout's src folder)")
    args = parser.parse_args(argv)
    src = args.src.resolve()
    print(f"sources: {src}")
    for m in args.cameras:
        dataset = rendered(m, args.images)
        outputs = []
        for k in range(args.repeats):
            r = run_once(dataset, src, args.processes)
            outputs.append(r["timings"]["outputs"])
            print(f"{m:2d} cameras x {args.images} images, run {k + 1}: outputs "
                  f"{r['timings']['outputs']:.2f} s of {r['timings']['total']:.2f} s measured "
                  f"({r['wall']:.1f} s wall, {r['figures']} figure files), load "
                  f"{os.getloadavg()[0]:.1f}", flush=True)
        print(f"{m:2d} cameras: outputs median {statistics.median(outputs):.2f} s "
              f"(min {min(outputs):.2f}, max {max(outputs):.2f})", flush=True)


if __name__ == "__main__":
    main()
