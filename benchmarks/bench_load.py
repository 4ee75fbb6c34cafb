"""Load: `multieye calibrate` end to end on 16 cameras x 75, 150 and 300 images.

Run from the repository root::

    python benchmarks/bench_load.py [--sizes 75 150 300] [--repeats 2] [--processes 2]

1. Renders, once, a 16-camera surround rig with 300 images per camera (800x600, lens
   distortion, blur and noise; :func:`multieye.sim.dataset.render_dataset`, seed 0) into
   ``benchmarks/.cache/load_16x300`` (git-ignored; a few minutes on 2 cores, reused later).
   The smaller sizes are the first N images of every camera of the same rendering (links in
   ``benchmarks/.cache/load_16x300_firstN``, copies of its rig.yaml, intrinsics and motion
   capture).
2. Runs ``python -m multieye calibrate DATASET -o OUT --processes P`` as a subprocess, in its
   own process group, ``--repeats`` times per size, and reports for every run:

   - the wall time of the subprocess (interpreter start and imports included), and the
     seconds per stage that the run measured itself (``timings_s`` of ``details.json``:
     reading, detection, pairing, closed form, refinement, outputs);
   - memory of the whole process tree (the main process, the fork server, the detection
     workers, multiprocessing's resource tracker), sampled every 20 ms from /proc: the peak
     of the summed RSS (pages shared between forked processes are counted once per process,
     so this overstates the memory used) and the peak of the summed PSS (shared pages split
     between the processes sharing them: the memory the tree really occupies), plus the
     peak RSS of the main process alone as the kernel counts it (``VmHWM``, read until the
     process ends). Sampling can miss a peak shorter than 20 ms;
   - CPU seconds (user + system) of the main process and of the other processes (the
     detection workers, the fork server, the resource tracker), from /proc as well: unlike
     wall times they hardly depend on what else runs on the machine;
   - the load average at the end of the run (other work on the same cores).

3. Prints a table per run, then, per stage, a least-squares line ``seconds = a + b * images``
   over all runs: ``b`` as seconds per 1000 images and the largest deviation of a run's
   time from the line, which shows whether the time is linear in the images.

Linux only (/proc). The times depend on the machine and on what else runs on it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "benchmarks" / ".cache"
CAMERAS, IMAGES, SEED = 16, 300, 0
STAGES = ("reading", "detection", "pairing", "closed_form", "refinement", "outputs")


def rendered() -> Path:
    """The full rendering, made on first use (``.complete`` marks a finished one)."""
    folder = CACHE / f"load_{CAMERAS}x{IMAGES}"
    if (folder / ".complete").exists():
        return folder
    from multieye.sim.dataset import DatasetSpec, render_dataset

    shutil.rmtree(folder, ignore_errors=True)
    print(f"rendering {CAMERAS} x {IMAGES} images into {folder} (once) ...", flush=True)
    start = time.perf_counter()
    truth = render_dataset(folder, DatasetSpec(n_cameras=CAMERAS, images_per_camera=IMAGES),
                           seed=SEED)
    print(f"  {sum(truth.images_written)} images in {time.perf_counter() - start:.0f} s",
          flush=True)
    (folder / ".complete").write_text("complete\n")
    return folder


def subset(full: Path, n: int) -> Path:
    """The first ``n`` images of every camera of ``full``, as links; ``full`` itself for all."""
    if n >= IMAGES:
        return full
    folder = CACHE / f"{full.name}_first{n}"
    if (folder / ".complete").exists():
        return folder
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    for p in full.iterdir():
        if p.is_dir():
            (folder / p.name).mkdir()
            for image in sorted(p.iterdir(), key=lambda q: float(q.stem))[:n]:
                (folder / p.name / image.name).symlink_to(image)
        elif p.name != ".complete":        # copied: the rig's folder is where rig.yaml is
            shutil.copy2(p, folder / p.name)
    (folder / ".complete").write_text("complete\n")
    return folder


def _kb(path: str, key: str) -> int:
    try:
        with open(path) as f:
            for line in f:
                if line.startswith(key):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return 0


def _group(pgid: int) -> dict[int, int]:
    """Running processes of a process group: pid -> CPU clock ticks used so far."""
    pids = {}
    for name in os.listdir("/proc"):
        if name.isdigit():
            try:
                with open(f"/proc/{name}/stat") as f:
                    text = f.read()
            except OSError:
                continue
            fields = text[text.rindex(")") + 2:].split()
            if int(fields[2]) == pgid and fields[0] not in "ZX":
                pids[int(name)] = int(fields[11]) + int(fields[12])     # utime + stime
    return pids


class TreeMemory(threading.Thread):
    """Samples a process group: summed RSS and PSS, the main process's VmHWM, CPU time."""

    def __init__(self, pid: int, every_s: float = 0.02):
        super().__init__(daemon=True)
        self.pid, self.every_s = pid, every_s
        self.rss_kb = self.pss_kb = self.main_hwm_kb = self.processes = 0
        self.ticks: dict[int, int] = {}
        self.done = threading.Event()

    def cpu_s(self) -> tuple[float, float]:
        """CPU seconds of the main process and of all the others (up to the last sample)."""
        hz = os.sysconf("SC_CLK_TCK")
        main = self.ticks.get(self.pid, 0)
        return main / hz, (sum(self.ticks.values()) - main) / hz

    def run(self):
        while not self.done.is_set():
            pids = _group(self.pid)
            for pid, ticks in pids.items():
                self.ticks[pid] = max(self.ticks.get(pid, 0), ticks)
            self.processes = max(self.processes, len(pids))
            self.rss_kb = max(self.rss_kb, sum(_kb(f"/proc/{p}/status", "VmRSS:") for p in pids))
            self.pss_kb = max(self.pss_kb, sum(_kb(f"/proc/{p}/smaps_rollup", "Pss:")
                                               for p in pids))
            self.main_hwm_kb = max(self.main_hwm_kb, _kb(f"/proc/{self.pid}/status", "VmHWM:"))
            time.sleep(self.every_s)


def calibrate(dataset: Path, processes: int) -> dict:
    """One `multieye calibrate` subprocess: wall time, stage times, memory."""
    with tempfile.TemporaryDirectory(prefix="bench_load_") as tmp:
        out = Path(tmp) / "out"
        cmd = [sys.executable, "-m", "multieye", "calibrate", str(dataset), "-o", str(out),
               "--processes", str(processes)]
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                start_new_session=True)
        memory = TreeMemory(proc.pid)
        memory.start()
        try:
            stdout, stderr = proc.communicate()
        finally:
            if proc.poll() is None:     # this script interrupted: stop the run too
                proc.terminate()
                proc.wait()
        wall = time.perf_counter() - start
        memory.done.set()
        memory.join()
        if proc.returncode != 0:
            raise SystemExit(f"calibrate failed ({proc.returncode}): {stderr.strip()}")
        details = json.loads((out / "details.json").read_text())
        used = sum(json.loads((out / "calibration.json").read_text())["cameras"][c]
                   ["measurements_used"] for c in details["cameras"])
    cpu_main, cpu_others = memory.cpu_s()
    return {"wall_s": wall, "stages": details["timings_s"], "used": used,
            "rss_mb": memory.rss_kb / 1024, "pss_mb": memory.pss_kb / 1024,
            "main_mb": memory.main_hwm_kb / 1024, "processes": memory.processes,
            "cpu_main_s": cpu_main, "cpu_workers_s": cpu_others, "load": os.getloadavg()[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[75, 150, 300],
                        help="images per camera (at most 300)")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--processes", type=int, default=2)
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))   # stop the running run too
    if not os.path.isdir("/proc"):
        raise SystemExit("bench_load reads memory from /proc (Linux)")
    full = rendered()
    cores = len(os.sched_getaffinity(0))
    print(f"machine: {platform.processor() or platform.machine()}, {cores} cores, "
          f"Python {platform.python_version()}, load average {os.getloadavg()[0]:.2f} at start")
    rows = []
    head = (f"{'images':>6} {'used':>5} {'wall s':>7} "
            + " ".join(f"{s[:9]:>9}" for s in STAGES)
            + f" {'total':>7} {'RSS MB':>7} {'PSS MB':>7} {'main MB':>7} {'procs':>5}"
            + f" {'CPU main':>8} {'CPU wkrs':>8} {'load':>5}")
    print(head)
    for n in args.sizes:
        dataset = subset(full, n)
        for _ in range(args.repeats):
            r = calibrate(dataset, args.processes)
            r["images"] = CAMERAS * min(n, IMAGES)
            rows.append(r)
            print(f"{r['images']:>6} {r['used']:>5} {r['wall_s']:>7.1f} "
                  + " ".join(f"{r['stages'].get(s, 0.0):>9.2f}" for s in STAGES)
                  + f" {r['stages']['total']:>7.1f} {r['rss_mb']:>7.0f} {r['pss_mb']:>7.0f} "
                    f"{r['main_mb']:>7.0f} {r['processes']:>5} {r['cpu_main_s']:>8.1f} "
                    f"{r['cpu_workers_s']:>8.1f} {r['load']:>5.1f}", flush=True)
    print(f"load average {os.getloadavg()[0]:.2f} at the end")
    images = np.array([r["images"] for r in rows], dtype=float)
    if len(set(images)) < 2:
        return
    print("\nper stage: seconds = a + b * images (least squares over the runs above)")
    print(f"{'stage':>11} {'a s':>7} {'b s/1000 img':>13} {'worst deviation':>16}")
    for stage in (*STAGES, "total", "wall", "cpu_main", "cpu_workers"):
        t = np.array([r["wall_s"] if stage == "wall" else r[f"{stage}_s"]
                      if stage.startswith("cpu") else r["stages"].get(stage, 0.0)
                      for r in rows])
        b, a = np.polyfit(images, t, 1)
        worst = np.max(np.abs(t - (a + b * images)))
        print(f"{stage:>11} {a:>7.2f} {1000 * b:>13.2f} {worst:>14.2f} s")


if __name__ == "__main__":
    main()
