"""The cost of the outputs (report, figures, exports) of `multieye calibrate` on 4 and 16 cameras.

Run from the repository root::

    python benchmarks/bench_report.py [--cameras 4 16] [--images 40] [--repeats 3] \
        [--src other/checkout/src]

1. Renders, once per size, a rig of ``N`` cameras with ``--images`` images each (800 x 600,
   :func:`multieye.sim.dataset.render_dataset`, seed 0) into
   ``benchmarks/.cache/report_<N>x<images>`` (git-ignored, reused later).
2. In a fresh interpreter with the sources of ``--src`` first on ``PYTHONPATH`` (default: this
   checkout's ``src``; pass the ``src`` of another checkout, e.g. the main branch, to time it
   on the same images): ``multieye.pipeline.calibrate(DATASET, processes=2)`` once, then
   ``multieye.outputs.write.write_outputs(run, OUT)`` ``--repeats`` times into fresh folders,
   as ``multieye calibrate`` does.  For each it prints the ``outputs`` stage as the run
   measured it (``timings_s.outputs`` of ``details.json``: calibration.json, camchain,
   details, report.html and its figures), the wall time and the CPU seconds of the call (this
   process and the worker processes it waited for; not a figure-drawing worker, which the
   fork server waits for: ``--serial`` draws everything in the main process, to count it
   all).  The first call imports matplotlib, as a
   ``multieye calibrate`` command does; the later ones show the cost without that import.

3. With ``--command`` (what issue 21 asks about): the whole command, ``multieye calibrate
   DATASET -o OUT`` in a fresh interpreter, ``--repeats`` times with the report and as many
   without it (``write_outputs(..., report=False)``: calibration.json, camchain, details.json
   only) and, with ``--serial``, with every figure drawn in the main process and with the
   figure workers started at the detection's end whatever the load (by default only with a
   core free); in turn so that all see the same load.  For each it prints the command's
   wall time and CPU seconds (the command and every process it waited for), and the outputs
   stage's wall time and CPU seconds (the main process, and the figure workers' own, read
   from /proc before they end: their imports included, also when they ran during the
   refinement).  The medians' differences are what the report adds, matplotlib's import
   included; the outputs stage's are the precise ones (the whole command's also vary with
   the detection).  ``--dataset`` adds another rendered folder (e.g.
   ``benchmarks/.cache/peers_4x100``).

4. With ``--against OTHER_SRC`` (issue 21's goal: the time from the detection's end to the
   command's): the plain command ``python -m multieye calibrate DATASET -o OUT --processes
   2`` with this checkout's sources and with ``OTHER_SRC``, alternately (A B B A ...),
   ``--repeats`` times each, on every ``--dataset`` (default ``benchmarks/.cache/
   peers_4x100``).  For each it prints the command's wall time and CPU seconds (it and every
   process it waited for), and from ``details.json`` the ``outputs`` stage and the tail:
   ``total - reading - detection`` (pairing, closed form, refinement and outputs: from the
   end of the detection to the outputs written), then the medians.

5. With ``--figures OUT`` (an output folder of a finished run: its calibration.json and
   details.json): the CPU seconds (``time.process_time``) of every figure, in a fresh
   interpreter that imports what the detection's fork server has (numpy, OpenCV, the
   imaging modules), then matplotlib's modules and :func:`multieye.outputs.figures_rig.
   warm_up`, then draws each job of :func:`multieye.outputs.report_draw.figure_jobs` and
   the rig's pictures once (``job:``, each camera's figure on its own), then the figure
   workers' tasks (``task:``, :func:`multieye.outputs.report_draw._tasks` with 2 batches
   of cameras: what the two workers draw, in one process here) twice, and the images with
   their detections (``thumbnails``, from the folders of ``--dataset``).  ``--repeats``
   interpreters per source, alternately with ``--against OTHER_SRC``; medians.

The wall times depend on what else runs on the machine (the load average is printed); the
CPU seconds much less.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
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
    from multieye.sim.dataset import DatasetSpec, render_dataset

    shutil.rmtree(folder, ignore_errors=True)
    print(f"rendering {cameras} x {images} images into {folder} (once) ...", flush=True)
    render_dataset(folder, DatasetSpec(n_cameras=cameras, images_per_camera=images), seed=SEED)
    (folder / ".complete").write_text("complete\n")
    return folder


_DRIVER = r"""
import json, resource, sys, tempfile, time
from pathlib import Path
from multieye.pipeline import calibrate
from multieye.outputs.write import write_outputs

def cpu():
    own, waited = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + waited.ru_utime + waited.ru_stime

if sys.argv[4] == "serial":   # figures drawn by this process alone (sources that can share them)
    for name in ("multieye.outputs.figure_workers", "multieye.outputs.report_draw"):
        try:
            __import__(name)
            sys.modules[name].worker_count = lambda processes=None: 0
        except ImportError:
            pass
run = calibrate(sys.argv[1], processes=int(sys.argv[2]))
with tempfile.TemporaryDirectory(prefix="bench_report_") as tmp:
    for k in range(int(sys.argv[3])):
        out = Path(tmp) / f"out{k}"
        c, w = cpu(), time.perf_counter()
        write_outputs(run, out)
        wall, used = time.perf_counter() - w, cpu() - c
        details = json.loads((out / "details.json").read_text())
        print(json.dumps({"outputs": details["timings_s"]["outputs"], "wall": wall, "cpu": used,
                          "files": len(list((out / "figures").iterdir()))}), flush=True)
"""


def run_sizes(dataset: Path, src: Path, processes: int, repeats: int, serial: bool) -> list[dict]:
    """The outputs of one calibration of ``dataset`` written ``repeats`` times."""
    env = dict(os.environ, PYTHONPATH=str(src))
    proc = subprocess.run([sys.executable, "-c", _DRIVER, str(dataset), str(processes),
                           str(repeats), "serial" if serial else "default"],
                          capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise SystemExit(f"the run failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]


_COMMAND = r"""
import contextlib, json, os, resource, sys, time
import multieye.outputs.write as w
try:                            # where the figure workers are managed (since session 8)
    import multieye.outputs.figure_workers as draw
except ImportError:
    import multieye.outputs.report_draw as draw

def cpu():
    own, waited = (resource.getrusage(k) for k in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + waited.ru_utime + waited.ru_stime

worker_cpu = []
real_pool = draw.worker_pool

def proc_cpu(pid):          # CPU-s of a running process, from /proc (Linux)
    with open(f"/proc/{pid}/stat") as fh:
        fields = fh.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

live = []

def workers_cpu():          # of the pools still running
    return sum(proc_cpu(pid) for pool in live for pid in list(pool._processes))

@contextlib.contextmanager
def counted_pool(*args, **kwargs):    # the figure workers' CPU-s, read before they end
    with real_pool(*args, **kwargs) as pool:
        live.append(pool)
        yield pool
        worker_cpu.append(workers_cpu())
        live.remove(pool)

draw.worker_pool = counted_pool
mode = sys.argv.pop(1)
if mode == "serial":        # every figure in this process
    draw.worker_count = lambda processes=None: 0
elif mode == "worker":      # a figure worker whatever the load
    draw._free_core = lambda: True
plain = w.write_outputs

def timed(run, out, **kw):
    c, t = cpu(), time.perf_counter()
    written = plain(run, out, **{**kw, "report": mode != "no-report"})
    print("BENCH " + json.dumps({"stage_wall": time.perf_counter() - t, "stage_cpu": cpu() - c,
                                 "worker_cpu": sum(worker_cpu) + workers_cpu()}),
          file=sys.stderr)
    return written

w.write_outputs = timed
from multieye.cli import main
main()
"""


def _command(dataset: Path, src: Path, out: Path, mode: str) -> dict:
    """One ``multieye calibrate`` (``mode``: report, no-report, serial or worker): wall,
    CPU-s, the outputs stage."""
    def children() -> float:
        u = resource.getrusage(resource.RUSAGE_CHILDREN)
        return u.ru_utime + u.ru_stime

    shutil.rmtree(out, ignore_errors=True)
    env = dict(os.environ, PYTHONPATH=str(src))
    c, w = children(), time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _COMMAND, mode,
                           "calibrate", str(dataset), "-o", str(out)],
                          capture_output=True, text=True, env=env)
    wall, cpu = time.perf_counter() - w, children() - c
    if proc.returncode not in (0, 3):
        raise SystemExit(f"the command failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    stage = [json.loads(line[6:]) for line in proc.stderr.splitlines()
             if line.startswith("BENCH ")][-1]
    return {"wall": wall, "cpu": cpu, "stage_wall": stage["stage_wall"],
            "stage_cpu": stage["stage_cpu"] + stage["worker_cpu"],
            "worker_cpu": stage["worker_cpu"], "load": os.getloadavg()[0]}


def run_commands(dataset: Path, src: Path, repeats: int, serial: bool) -> None:
    """The whole command with and without the report (and with its figures drawn in one
    process, ``serial``), in turn; prints what the report adds."""
    modes = ["report", "no-report"] + (["serial", "worker"] if serial else [])
    rows: dict[str, list[dict]] = {m: [] for m in modes}
    with tempfile.TemporaryDirectory(prefix="bench_report_cmd_") as tmp:
        for k in range(repeats):
            for mode in (modes if k % 2 == 0 else modes[::-1]):
                r = _command(dataset, src, Path(tmp) / "out", mode)
                rows[mode].append(r)
                print(f"{dataset.name} {mode}: command {r['wall']:.2f} s wall, "
                      f"{r['cpu']:.2f} CPU-s; outputs stage {r['stage_wall']:.2f} s wall, "
                      f"{r['stage_cpu']:.2f} CPU-s (figure worker {r['worker_cpu']:.2f}), "
                      f"load {r['load']:.1f}", flush=True)
    keys = ("wall", "cpu", "stage_wall", "stage_cpu")
    med = {m: {q: statistics.median(r[q] for r in v) for q in keys} for m, v in rows.items()}
    base = med["no-report"]
    for mode in modes:
        if mode != "no-report":
            d = {q: med[mode][q] - base[q] for q in keys}
            print(f"{dataset.name}: the report ({mode}) adds, medians of {repeats}: outputs "
                  f"stage {d['stage_wall']:.2f} s wall ({med[mode]['stage_wall']:.2f} - "
                  f"{base['stage_wall']:.2f}), {d['stage_cpu']:.2f} CPU-s "
                  f"({med[mode]['stage_cpu']:.2f} - {base['stage_cpu']:.2f}); whole command "
                  f"{d['wall']:.2f} s wall ({med[mode]['wall']:.2f} - {base['wall']:.2f}), "
                  f"{d['cpu']:.2f} CPU-s ({med[mode]['cpu']:.2f} - {base['cpu']:.2f})",
                  flush=True)


def _plain_command(dataset: Path, src: Path, out: Path) -> dict:
    """One plain ``multieye calibrate DATASET -o OUT --processes 2``: wall, CPU-s, and the
    stages of its ``details.json``."""
    shutil.rmtree(out, ignore_errors=True)
    env = dict(os.environ, PYTHONPATH=str(src))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    w = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "multieye", "calibrate", str(dataset), "-o",
                           str(out), "--processes", "2"], capture_output=True, text=True,
                          env=env)
    wall = time.perf_counter() - w
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 3):
        raise SystemExit(f"the command failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    t = json.loads((out / "details.json").read_text())["timings_s"]
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return {"wall": wall, "cpu": cpu, "outputs": t["outputs"], "refinement": t["refinement"],
            "tail": t["total"] - t["reading"] - t["detection"], "load": os.getloadavg()[0]}


def run_against(datasets: list[Path], srcs: dict[str, Path], repeats: int) -> None:
    """The plain command with each of ``srcs``, alternately; prints each run and the medians."""
    keys = ("wall", "cpu", "tail", "refinement", "outputs")
    with tempfile.TemporaryDirectory(prefix="bench_report_ab_") as tmp:
        for dataset in datasets:
            rows: dict[str, list[dict]] = {name: [] for name in srcs}
            for k in range(repeats):
                for name in (list(srcs) if k % 2 == 0 else list(srcs)[::-1]):
                    r = _plain_command(dataset, srcs[name], Path(tmp) / "out")
                    rows[name].append(r)
                    print(f"{dataset.name} {name}: command {r['wall']:.2f} s, {r['cpu']:.2f} "
                          f"CPU-s; tail {r['tail']:.2f} s (refinement {r['refinement']:.2f}, "
                          f"outputs {r['outputs']:.2f}); load {r['load']:.1f}", flush=True)
            for name, v in rows.items():
                med = {q: statistics.median(r[q] for r in v) for q in keys}
                print(f"{dataset.name} {name}, medians of {repeats}: command {med['wall']:.2f} s, "
                      f"{med['cpu']:.2f} CPU-s; tail {med['tail']:.2f} s (refinement "
                      f"{med['refinement']:.2f}, outputs {med['outputs']:.2f})", flush=True)


_FIGURES = r"""
import json, sys, time
import multieye.imaging.batch                   # what the detection's fork server imported
from multieye.io.calibration_json import read_calibration
from multieye.io.run_details import read_run_details
from multieye.outputs import report_draw, report_images
out, dataset = sys.argv[1], sys.argv[2]
t = {}
c = time.process_time()
import matplotlib.figure, matplotlib.backends.backend_agg  # noqa: F401
t["import matplotlib"] = time.process_time() - c
from multieye.outputs import figures_rig
c = time.process_time()
figures_rig.warm_up()
t["warm_up"] = time.process_time() - c
rec = read_calibration(f"{out}/calibration.json")
details = read_run_details(f"{out}/details.json")
jobs = report_draw.figure_jobs(rec, details)
for name, func, args, _ in jobs:
    c = time.process_time(); func(*args); t["job: " + name] = time.process_time() - c
c = time.process_time(); figures_rig.rig_pngs(rec, details)
t["job: rig_3d.png + rig_top.png"] = time.process_time() - c
t["job: all"] = sum(v for k, v in t.items() if k.startswith("job: "))
for rerun in ("", " again"):
    for k, (_, func, args) in enumerate(report_draw._tasks(rec, details, jobs, 2)):
        c = time.process_time(); drawn = func(*args)
        names = " + ".join(drawn) if isinstance(drawn, dict) else "rig"
        t[f"task{rerun}: {k} {names}"] = time.process_time() - c
    t[f"task{rerun}: all"] = sum(v for k, v in t.items() if k.startswith(f"task{rerun}: "))
folders = {c.name: f"{dataset}/{c.name}" for c in rec.cameras}
c = time.process_time(); report_images.image_thumbnails(rec, details, folders)
t["thumbnails"] = time.process_time() - c
print(json.dumps(t))
"""


def run_figures(out: Path, dataset: Path, srcs: dict[str, Path], repeats: int) -> None:
    """Every figure's CPU seconds (``--figures``), each source in a fresh interpreter in
    turn; prints each run's total and every figure's median."""
    rows: dict[str, list[dict]] = {name: [] for name in srcs}
    for k in range(repeats):
        for name in (list(srcs) if k % 2 == 0 else list(srcs)[::-1]):
            env = dict(os.environ, PYTHONPATH=str(srcs[name]))
            proc = subprocess.run([sys.executable, "-c", _FIGURES, str(out), str(dataset)],
                                  capture_output=True, text=True, env=env, cwd=ROOT)
            if proc.returncode != 0:
                raise SystemExit(f"drawing failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
            rows[name].append(json.loads(proc.stdout.splitlines()[-1]))
            r = rows[name][-1]
            print(f"{name}: jobs {r['job: all']:.3f} CPU-s, tasks {r['task: all']:.3f} "
                  f"(again {r['task again: all']:.3f}), warm_up {r['warm_up']:.3f}, "
                  f"load {os.getloadavg()[0]:.1f}", flush=True)
    print(f"CPU-s, medians of {repeats}: " + " | ".join(srcs))
    for key in rows[next(iter(srcs))][-1]:
        print(f"  {key:60s} " + "  ".join(
            f"{statistics.median(r.get(key, float('nan')) for r in rows[n]):7.3f}" for n in srcs))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", type=int, nargs="*", default=[4, 16])
    parser.add_argument("--images", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--serial", action="store_true",
                        help="draw every figure in the main process (its CPU seconds are then "
                             "all of the drawing: a worker's are not counted); with "
                             "--command, time that and a worker whatever the load too")
    parser.add_argument("--src", type=Path, default=ROOT / "src",
                        help="the sources to time (a checkout's src folder)")
    parser.add_argument("--command", action="store_true",
                        help="time the whole `multieye calibrate` with and without the report")
    parser.add_argument("--dataset", type=Path, nargs="*", default=[],
                        help="with --command: more rendered datasets to time")
    parser.add_argument("--against", type=Path, default=None, metavar="OTHER_SRC",
                        help="time the plain command with --src and with OTHER_SRC, "
                             "alternately, on --dataset (default peers_4x100)")
    parser.add_argument("--figures", type=Path, default=None, metavar="OUT",
                        help="every figure's CPU seconds, from OUT's calibration.json and "
                             "details.json (the images of --dataset, default peers_4x100)")
    args = parser.parse_args(argv)
    src = args.src.resolve()
    print(f"sources: {src}")
    if args.figures is not None:
        srcs = {"this": src} if args.against is None else {"this": src,
                                                            "other": args.against.resolve()}
        run_figures(args.figures.resolve(), (args.dataset or [CACHE / "peers_4x100"])[0],
                    srcs, args.repeats)
        return
    if args.against is not None:
        run_against(args.dataset or [CACHE / "peers_4x100"],
                    {"this": src, "other": args.against.resolve()}, args.repeats)
        return
    if args.command:
        for dataset in [rendered(m, args.images) for m in args.cameras] + args.dataset:
            run_commands(dataset, src, args.repeats, args.serial)
        return
    for m in args.cameras:
        dataset = rendered(m, args.images)
        rows = run_sizes(dataset, src, args.processes, args.repeats, args.serial)
        for k, r in enumerate(rows):
            print(f"{m:2d} cameras x {args.images} images, write {k + 1}"
                  f"{' (imports matplotlib)' if k == 0 else ''}: outputs {r['outputs']:.2f} s "
                  f"(call {r['wall']:.2f} s wall, {r['cpu']:.2f} CPU-s, {r['files']} figure "
                  f"files), load {os.getloadavg()[0]:.1f}", flush=True)
        print(f"{m:2d} cameras: first {rows[0]['outputs']:.2f} s / {rows[0]['cpu']:.2f} CPU-s; "
              f"later median {statistics.median(r['outputs'] for r in rows[1:]):.2f} s / "
              f"{statistics.median(r['cpu'] for r in rows[1:]):.2f} CPU-s" if len(rows) > 1
              else "", flush=True)


if __name__ == "__main__":
    main()
