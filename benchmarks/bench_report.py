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
   only), taken in turn so that both see the same load.  For each it prints the wall time of
   the command, its CPU seconds (the command and every process it waited for: detection
   workers, the figure worker and the fork server) and ``timings_s.outputs``; the medians'
   differences are what the report adds, matplotlib's import included.  ``--dataset`` adds
   another rendered folder (e.g. ``benchmarks/.cache/peers_4x100``).

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
    try:
        import multieye.outputs.report_draw as draw
        draw._cores = lambda: 1
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
import sys
import multieye.outputs.write as w
if sys.argv.pop(1) == "no-report":
    plain = w.write_outputs
    w.write_outputs = lambda run, out, **kw: plain(run, out, **{**kw, "report": False})
from multieye.cli import main
main()
"""


def _command(dataset: Path, src: Path, out: Path, report: bool) -> dict:
    """One ``multieye calibrate`` (with or without the report): wall, CPU-s, outputs stage."""
    def children() -> float:
        u = resource.getrusage(resource.RUSAGE_CHILDREN)
        return u.ru_utime + u.ru_stime

    shutil.rmtree(out, ignore_errors=True)
    env = dict(os.environ, PYTHONPATH=str(src))
    c, w = children(), time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _COMMAND, "report" if report else "no-report",
                           "calibrate", str(dataset), "-o", str(out)],
                          capture_output=True, text=True, env=env)
    wall, cpu = time.perf_counter() - w, children() - c
    if proc.returncode not in (0, 3):
        raise SystemExit(f"the command failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    outputs = json.loads((out / "details.json").read_text())["timings_s"]["outputs"]
    return {"wall": wall, "cpu": cpu, "outputs": outputs, "load": os.getloadavg()[0]}


def run_commands(dataset: Path, src: Path, repeats: int) -> None:
    """The whole command with and without the report, in turn; prints what the report adds."""
    rows: dict[bool, list[dict]] = {True: [], False: []}
    with tempfile.TemporaryDirectory(prefix="bench_report_cmd_") as tmp:
        for k in range(repeats):
            for report in ((True, False) if k % 2 == 0 else (False, True)):
                r = _command(dataset, src, Path(tmp) / "out", report)
                rows[report].append(r)
                print(f"{dataset.name}: {'with' if report else 'without'} the report: "
                      f"{r['wall']:.2f} s wall, {r['cpu']:.2f} CPU-s, outputs stage "
                      f"{r['outputs']:.2f} s, load {r['load']:.1f}", flush=True)
    med = {k: {q: statistics.median(r[q] for r in v) for q in ("wall", "cpu", "outputs")}
           for k, v in rows.items()}
    print(f"{dataset.name}: the report adds {med[True]['wall'] - med[False]['wall']:.2f} s wall "
          f"(medians {med[True]['wall']:.2f} / {med[False]['wall']:.2f}), "
          f"{med[True]['cpu'] - med[False]['cpu']:.2f} CPU-s "
          f"({med[True]['cpu']:.2f} / {med[False]['cpu']:.2f}), outputs stage "
          f"{med[True]['outputs']:.2f} / {med[False]['outputs']:.2f} s", flush=True)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cameras", type=int, nargs="*", default=[4, 16])
    parser.add_argument("--images", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--serial", action="store_true",
                        help="draw every figure in the main process (its CPU seconds are then "
                             "all of the drawing: a worker's are not counted)")
    parser.add_argument("--src", type=Path, default=ROOT / "src",
                        help="the sources to time (a checkout's src folder)")
    parser.add_argument("--command", action="store_true",
                        help="time the whole `multieye calibrate` with and without the report")
    parser.add_argument("--dataset", type=Path, nargs="*", default=[],
                        help="with --command: more rendered datasets to time")
    args = parser.parse_args(argv)
    src = args.src.resolve()
    print(f"sources: {src}")
    if args.command:
        for dataset in [rendered(m, args.images) for m in args.cameras] + args.dataset:
            run_commands(dataset, src, args.repeats)
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
