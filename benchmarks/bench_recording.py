"""Long recordings: time, peak memory and accuracy at 1k, 5k and 54k images (issue 22).

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_recording.py render [--cache DIR] [--sizes 1000,5000,54000]
    PYTHONPATH=src python benchmarks/bench_recording.py run [--cache DIR] [--sizes ...] [--modes on,off]

``render`` writes one rendered dataset per size (``multieye.sim.dataset.render_dataset``):
10 cameras, SIZE / 10 images each at 30 Hz, 640 x 480 pixels, a 6 x 9 chessboard of 50 mm
squares, blur 0.7 px and sensor noise 2 grey levels, JPEG at quality 92 (every frame
rendered on its own: no image reused), motion capture at 120 Hz with 0.03 deg / 0.1 mm
noise.  ``run`` calibrates each with ``multieye calibrate DATASET -o OUT`` in a child
process, with the image selection on (the default) and off (``--no-select``), and prints
per run: wall seconds, CPU seconds of the process tree (``getrusage`` of the children, and
the sum over the tree's processes sampled from ``/proc``),
peak resident memory of the process tree (the sum of the RSS of the process and its
descendants, sampled every 0.05 s from ``/proc``), images detected, and the ``T_ref_cam``
error against ``ground_truth.json`` (RMS over the non-reference cameras, degrees and
millimetres) next to the reported standard deviations.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.sim.dataset import DatasetSpec, render_dataset

CAMERAS = 10


def render(cache: Path, sizes: list[int], processes: int | None) -> None:
    for size in sizes:
        folder = cache / f"rec{size}"
        if (folder / "ground_truth.json").is_file():
            print(f"{folder}: already rendered")
            continue
        spec = DatasetSpec(n_cameras=CAMERAS, images_per_camera=size // CAMERAS, width=640,
                           height=480, camera_rate_hz=30.0, processes=processes,
                           image_format="jpg")
        t0 = time.perf_counter()
        truth = render_dataset(folder, spec, seed=size)
        print(f"{folder}: {sum(truth.images_written)} images in {time.perf_counter() - t0:.0f} s")


def _tree_rss(pid: int, cpu: dict[int, float] | None = None) -> int:
    """Resident bytes of ``pid`` and its descendants (from /proc); ``cpu``: each one's CPU
    seconds so far (user + system), updated."""
    parents: dict[int, int] = {}
    rss: dict[int, int] = {}
    ticks: dict[int, float] = {}
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", "rb") as f:
                stat = f.read()
            fields = stat[stat.rindex(b")") + 2:].split()
            parents[int(name)] = int(fields[1])
            rss[int(name)] = int(fields[21]) * os.sysconf("SC_PAGE_SIZE")
            ticks[int(name)] = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, ValueError, IndexError):
            continue
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        total += rss.get(p, 0)
        if cpu is not None and p in ticks:
            cpu[p] = max(cpu.get(p, 0.0), ticks[p])
        todo.extend(c for c, q in parents.items() if q == p)
    return total


def _errors(out: Path, dataset: Path) -> tuple[float, float, float, float]:
    cal = json.loads((out / "calibration.json").read_text())
    truth = json.loads((dataset / "ground_truth.json").read_text())
    rot, trans, srot, strans = [], [], [], []
    for name, cam in list(cal["cameras"].items())[1:]:
        D = g.inv(np.array(truth["cameras"][name]["T_ref_cam"])) @ np.array(cam["T_ref_cam"])
        rot.append(np.degrees(np.linalg.norm(g.rotvec_from_transform(D))))
        trans.append(np.linalg.norm(D[:3, 3]) * 1e3)
        srot.append(cam.get("std_rot_deg", np.nan))
        strans.append(cam.get("std_trans_m", np.nan) * 1e3)
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))  # noqa: E731
    return rms(rot), rms(trans), rms(srot), rms(strans)


def run_one(dataset: Path, out: Path, select: bool) -> dict:
    cmd = [sys.executable, "-m", "multieye", "calibrate", str(dataset), "-o", str(out)]
    if not select:
        cmd.append("--no-select")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peak = [0]
    tree_cpu: dict[int, float] = {}
    stop = threading.Event()

    def sample():
        while not stop.is_set():
            peak[0] = max(peak[0], _tree_rss(proc.pid, tree_cpu))
            stop.wait(0.05)

    watcher = threading.Thread(target=sample, daemon=True)
    watcher.start()
    stdout, stderr = proc.communicate()
    stop.set()
    watcher.join()
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    # CPU: the children's rusage, and the tree's sampled from /proc (workers whose end the
    # rusage does not see are counted there; the last 0.05 s of each process may be missed)
    row = {"dataset": dataset.name, "select": select, "status": proc.returncode, "wall_s": wall,
           "cpu_s": cpu, "cpu_tree_s": sum(tree_cpu.values()), "peak_rss_mb": peak[0] / 2**20}
    if proc.returncode in (0, 3):
        details = json.loads((out / "details.json").read_text())
        row["timings_s"] = details.get("timings_s", {})
        row["selection"] = {n: c.get("selection") for n, c in details["cameras"].items()}
        row["images_used"] = sum(len(c["measurements"]["name"]) for c in details["cameras"].values())
        row.update(zip(("err_rot_deg", "err_trans_mm", "std_rot_deg", "std_trans_mm"),
                       _errors(out, dataset)))
    else:
        row["stderr"] = stderr.strip().splitlines()[-1:] if stderr else []
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stage", choices=["render", "run"])
    ap.add_argument("--cache", type=Path, default=Path("benchmarks/.cache/recordings"))
    ap.add_argument("--sizes", default="1000,5000,54000")
    ap.add_argument("--modes", default="on,off")
    ap.add_argument("--processes", type=int, default=None)
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    if args.stage == "render":
        render(args.cache, sizes, args.processes)
        return
    for size in sizes:
        for mode in args.modes.split(","):
            row = run_one(args.cache / f"rec{size}", args.cache / f"out{size}-{mode}", mode == "on")
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
