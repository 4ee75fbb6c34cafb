"""Where the wall time of one ``multieye calibrate`` goes, process by process (issue 32).

Run from the repository root::

    python benchmarks/bench_timeline.py DATASET [--src SRC] [--against OTHER_SRC]
        [--runs 3] [--processes 2] [--no-report] [--free-core] [--show]

Every Python process of the command (the main process, the detection's fork server,
multiprocessing's resource tracker, the detection workers and the figure workers) writes a
line with a wall-clock stamp at its start, when it begins and ends importing numpy, OpenCV,
SciPy, matplotlib and the pipeline's later stages, when it forks, signals or writes a file,
and at its end with its CPU seconds: a ``sitecustomize`` module put first on ``PYTHONPATH``
for the measured command only (written to a temporary folder; it changes nothing the
command does, apart from ``--free-core``).  Printed per run: the wall time, each process's
CPU seconds by role, and the moments the detection and the figures start and end; with
``--show``, every line.

``--free-core`` makes the figure workers start as on a machine with a core free (the load
check of :mod:`multieye.outputs.figure_workers` answers yes): on a shared machine the main
process would draw the figures itself, and the figure workers' costs would not be seen.
``--against`` runs OTHER_SRC's code in turn with SRC's (A B A B ...), for a before/after.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SITECUSTOMIZE = r'''
import os, sys, time
_LOG = os.environ.get("MULTIEYE_TIMELINE_LOG")
if _LOG:
    _fd = os.open(_LOG, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    def _w(what):
        os.write(_fd, f"{time.time():.4f} {os.getpid()} {what}\n".encode())
    def _started():
        with open("/proc/self/stat") as f:
            st = f.read()
        ticks = int(st[st.rindex(")") + 2:].split()[19])
        with open("/proc/uptime") as f:
            up = float(f.read().split()[0])
        return time.time() - (up - ticks / os.sysconf("SC_CLK_TCK"))
    _w(f"start {_started():.4f} {os.getppid()} {' '.join(sys.argv)[:60]!r}")
    WATCH = {"numpy", "cv2", "scipy", "matplotlib", "multieye.pipeline.run",
             "multieye.outputs.figures_rig", "multieye.outputs.report_draw",
             "multieye.outputs.figure_workers"}
    import importlib.abc, importlib.machinery
    class _Timed(importlib.abc.MetaPathFinder):
        busy = set()
        def find_spec(self, name, path=None, target=None):
            if name not in WATCH or name in self.busy:
                return None
            self.busy.add(name)
            try:
                spec = importlib.machinery.PathFinder.find_spec(name, path)
            finally:
                self.busy.discard(name)
            if spec is None or spec.loader is None:
                return None
            run = spec.loader.exec_module
            def exec_module(module, run=run, name=name):
                _w(f"import+ {name}")
                run(module)
                if name == "multieye.outputs.figure_workers" and os.environ.get(
                        "MULTIEYE_TIMELINE_FREE_CORE"):
                    module._free_core = lambda: True
                _w(f"import- {name}")
            spec.loader.exec_module = exec_module
            return spec
    sys.meta_path.insert(0, _Timed())
    def _hook(event, args):
        if event == "open" and isinstance(args[0], str) and (
                isinstance(args[1], str) and any(c in args[1] for c in "wxa")
                or args[1] is None and isinstance(args[2], int)
                and args[2] & (os.O_WRONLY | os.O_RDWR)):
            _w(f"write {os.path.basename(args[0])[:40]}")
        elif event == "os.kill" and args[1] != 0:
            _w(f"signal {args[1]} to {args[0]}")
    sys.addaudithook(_hook)
    os.register_at_fork(after_in_child=lambda: _w(f"forked {os.getppid()}"))
    _exit = os._exit
    def _ending(code, _exit=_exit):
        _w(f"end {sum(os.times()[:2]):.3f}")
        _exit(code)
    os._exit = _ending
    import atexit
    atexit.register(lambda: _w(f"end {sum(os.times()[:2]):.3f}"))
'''


def read_log(path: Path) -> dict:
    """The timeline of one run: per process its events, role and CPU seconds."""
    rows = [line.rstrip("\n").split(" ", 2) for line in path.read_text().splitlines()]
    procs: dict[str, dict] = {}
    for t, pid, what in rows:
        p = procs.setdefault(pid, {"events": [], "cpu": 0.0, "t0": float(t), "parent": None})
        if what.startswith("start "):
            p["t0"] = float(what.split()[1])
            p["parent"] = what.split()[2]
            p["argv"] = what
        elif what.startswith("forked "):
            p["parent"] = what.split()[1]
            p["forked"] = float(t)
        elif what.startswith("end "):
            p["cpu"] = max(p["cpu"], float(what.split()[1]))
            p["end"] = float(t)
        p["events"].append((float(t), what))
    main = next(pid for pid, p in procs.items() if "'-m calibrate" in p.get("argv", ""))
    t0 = procs[main]["t0"]
    children = [pid for pid, p in procs.items() if "forked" in p]
    server = {procs[pid]["parent"] for pid in children}
    first_end = min((procs[pid].get("end", 1e30) for pid in children), default=1e30)
    for pid, p in procs.items():
        if pid == main:
            p["role"] = "main"
        elif pid in server:
            p["role"] = "fork server"
        elif "forked" in p:
            p["role"] = ("detection worker" if p["forked"] < first_end else "figure worker")
        else:
            p["role"] = "resource tracker"
    return {"procs": procs, "t0": t0, "wall": procs[main].get("end", t0) - t0}


def summary(run: dict) -> dict:
    """CPU seconds by role and the moments (s from the main process's start) that matter."""
    out = {"wall": run["wall"]}
    procs = run["procs"].values()
    for role in ("main", "fork server", "resource tracker", "detection worker",
                 "figure worker"):
        out[f"CPU {role}"] = sum(p["cpu"] for p in procs if p["role"] == role)
    det = [p for p in procs if p["role"] == "detection worker"]
    fig = [p for p in procs if p["role"] == "figure worker"]
    if det:
        out["detection from"] = min(p["forked"] for p in det) - run["t0"]
        out["detection to"] = max(p.get("end", 0) for p in det) - run["t0"]
    if fig:
        out["figures from"] = min(p["forked"] for p in fig) - run["t0"]
        out["figures to"] = max(p.get("end", 0) for p in fig) - run["t0"]
    out["figure workers"] = len(fig)
    main = next(p for p in procs if p["role"] == "main")
    wrote = [t for t, what in main["events"] if what.startswith("write .calibration.json")]
    manifest = [t for t, what in main["events"] if what.startswith("write .multieye-manifest")]
    if wrote and manifest:      # the files written and synced (and drawn, by this process)
        out["files from"] = wrote[0] - run["t0"]
        out["files to"] = manifest[-1] - run["t0"]
    return out


def one_run(dataset: Path, src: Path, args, folder: Path, k: int) -> dict:
    log = folder / f"log{k}"
    env = dict(os.environ, PYTHONPATH=f"{folder}{os.pathsep}{src}",
               MULTIEYE_TIMELINE_LOG=str(log))
    if args.free_core:
        env["MULTIEYE_TIMELINE_FREE_CORE"] = "1"
    cmd = [sys.executable, "-m", "multieye", "calibrate", str(dataset), "-o",
           str(folder / f"out{k}"), "--processes", str(args.processes)]
    done = subprocess.run(cmd + (["--no-report"] if args.no_report else []), env=env,
                          capture_output=True, text=True, cwd=ROOT)
    if done.returncode not in (0, 3):
        raise SystemExit(f"the command failed ({done.returncode}):\n{done.stderr[-2000:]}")
    run = read_log(log)
    if args.show:
        for pid, p in sorted(run["procs"].items(), key=lambda kv: kv[1]["t0"]):
            for t, what in p["events"]:
                print(f"  {t - run['t0']:7.3f} {p['role']:17s} {pid:>7} {what[:90]}")
    return summary(run)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--src", type=Path, default=ROOT / "src")
    ap.add_argument("--against", type=Path, default=None, metavar="OTHER_SRC")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--no-report", action="store_true")
    ap.add_argument("--free-core", action="store_true")
    ap.add_argument("--show", action="store_true")
    args = ap.parse_args(argv)
    srcs = {"this": args.src.resolve()}
    if args.against is not None:
        srcs["other"] = args.against.resolve()
    rows: dict[str, list[dict]] = {name: [] for name in srcs}
    with tempfile.TemporaryDirectory(prefix="bench_timeline_") as tmp:
        folder = Path(tmp)
        (folder / "sitecustomize.py").write_text(SITECUSTOMIZE)
        for k in range(args.runs):
            for name in (list(srcs) if k % 2 == 0 else list(srcs)[::-1]):
                load = os.getloadavg()[0]
                r = one_run(args.dataset, srcs[name], args, folder, len(rows[name]) + 10 * k
                            + (name == "other"))
                rows[name].append(r)
                print(f"{name} run {k + 1}: " + ", ".join(
                    f"{key} {v:.2f}" if isinstance(v, float) else f"{key} {v}"
                    for key, v in r.items()) + f", load {load:.1f}", flush=True)
                time.sleep(0.2)
    print(f"medians of {args.runs}: " + " | ".join(f"{n} ({srcs[n]})" for n in srcs))
    for key in rows["this"][0]:
        vals = [f"{statistics.median(r[key] for r in rows[n] if key in r):8.3f}"
                if any(key in r for r in rows[n]) else "       -" for n in srcs]
        print(f"  {key:24s} " + "  ".join(vals))


if __name__ == "__main__":
    main()
