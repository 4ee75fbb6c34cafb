"""multieye against its peers on the same rendered images: wall time and accuracy (issue 21).

Run from the repository root::

    python benchmarks/bench_peers.py [--runs 3] [--processes 2]
        [--mrcal-python /tmp/venv-mrcal/bin/python] [--variant NAME|all|key=value,...]

``--variant`` (repeatable) renders and times other data than the base rig below: image size,
PNG or JPEG, board size, lens family, images per camera, and the images made by a second
renderer (``renderer=warp``: a board picture warped through its homography and the lens over
a cluttered scene, :mod:`multieye.sim.warped`); the presets are :data:`VARIANTS`. With
variants a last table gives, per variant, the wall-time ratio multieye / OpenCV script
(median of the runs, and each run's own ratio: the commands run in turn) and the worst.

1. Renders, once, a 4-camera rig with 100 images per camera (800 x 600, pinhole with OpenCV's
   5 radial-tangential coefficients, blur and sensor noise, motion capture 0.03 deg / 0.1 mm;
   :func:`multieye.sim.dataset.render_dataset`, seed 0) into ``benchmarks/.cache/peers_4x100``
   (git-ignored), and a copy of its rig whose cameras have ``model: pinhole-radtan`` instead
   of ``intrinsics:`` (``peers_4x100_model``: the lenses unknown, the same images linked).
2. Byte-compiles the multieye package the commands import (as ``pip install`` does;
   :func:`compile_package`), then runs, in turn, ``--runs`` times each, every command as a
   separate process (interpreter start and imports included), and takes its wall time and
   CPU time (user + system of the process and its children):

   - ``multieye known`` / ``multieye unknown``: ``python -m multieye calibrate DATASET -o OUT
     --processes P`` (outputs included: report, figures, exports);
   - ``opencv known`` / ``opencv unknown``: ``benchmarks/peers/opencv_script.py`` (its
     docstring: findChessboardCorners + cornerSubPix, calibrateCamera when the lenses are
     unknown, solvePnP, calibrateRobotWorldHandEye per camera, one process);
   - ``mrcal unknown``: ``benchmarks/peers/mrcal_script.py`` run by ``--mrcal-python`` (mrcal
     per camera from the corners OpenCV's detector found, then the hand-eye as above); mrcal's
     detector is not on the package index, so its time starts from the corners (the
     detection time of ``opencv`` is to be added for a whole run). Skipped, with a note,
     when that interpreter cannot import mrcal.

3. Accuracy against the truth (``ground_truth.json``, the rendered ``cam*.yaml``): per camera,
   the error of ``T_ref_cam`` (rotation degrees, translation millimetres; camera 0 the
   reference), and with the lenses unknown the projection error of the estimated lens over
   the observed area: the camera-frame rays of every detected corner (unprojected through the
   true lens), projected through the estimated lens against the true pixel, RMS; also after
   the rotation between the two camera frames that fits best (what mrcal's
   ``projection_diff`` fits: a lens whose principal point is off by ``d`` px looks like the
   camera turned by ``d / f``, which the extrinsics absorb).

Prints markdown tables (docs/results/peers.md keeps the figures with the commands). Wall
times depend on the load of the machine: the load average is printed with every run.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "benchmarks" / ".cache"
PEERS = ROOT / "benchmarks" / "peers"
sys.path.insert(0, str(PEERS))
from lens_error import lens_errors  # noqa: E402  (benchmarks/peers/lens_error.py)

CAMERAS, IMAGES, SEED = 4, 100, 0

#: The data variants ``--variant`` names (``all``: every one, in this order).  Each is a
#: comma-separated ``key=value`` list over :data:`BASE`: ``renderer`` (``rays``: the sim's
#: ray tracer; ``warp``: a picture of the board resampled through its homography and the
#: lens over a cluttered scene, :mod:`multieye.sim.warped`), ``size`` (WxH), ``format``
#: (png / jpg), ``board`` (ROWSxCOLS inner corners of a chessboard; the OpenCV script reads
#: chessboards only), ``lens`` (pinhole: OpenCV's radial-tangential; fisheye: equidistant,
#: ``model: fisheye`` when unknown), ``images`` (per camera), ``blur`` (px).
BASE = {"renderer": "rays", "size": "800x600", "format": "png", "board": "6x9",
        "lens": "pinhole", "images": str(IMAGES), "blur": "0.7"}
VARIANTS = {
    "base": "",
    "warp960": "renderer=warp,size=960x720",
    "warp640jpg": "renderer=warp,size=640x480,format=jpg,board=5x7",
    "warp1920": "renderer=warp,size=1920x1080,board=8x11,blur=1.2",
    "rays1280jpg": "size=1280x720,format=jpg,board=7x10",
    "fisheye960": "renderer=warp,size=960x720,lens=fisheye",
    "warp960x12": "renderer=warp,size=960x720,images=12",
}


def variant_settings(text: str) -> dict:
    """:data:`BASE` updated by a preset name of :data:`VARIANTS` or a ``key=value`` list."""
    text = VARIANTS.get(text, text)
    out = dict(BASE)
    for item in filter(None, (t.strip() for t in text.split(","))):
        key, _, value = item.partition("=")
        if key not in BASE or not value:
            raise SystemExit(f"--variant: {item!r} is not one of {sorted(BASE)} = value")
        out[key] = value
    return out


def variant_name(v: dict) -> str:
    """The cache folder's name of a variant (the base keeps today's ``peers_4x100``)."""
    extra = "_".join(f"{k}-{v[k]}" for k in BASE if k != "images" and v[k] != BASE[k])
    return f"peers_{CAMERAS}x{v['images']}" + (f"_{extra}" if extra else "")


def rendered(variant: dict | None = None) -> tuple[Path, Path]:
    """The rendering (lenses given) and its copy with ``model:`` (lenses unknown)."""
    v = variant or dict(BASE)
    folder = CACHE / variant_name(v)
    if not (folder / ".complete").exists():
        from multieye.sim.dataset import DatasetSpec, render_dataset

        shutil.rmtree(folder, ignore_errors=True)
        rows, cols = (int(x) for x in v["board"].split("x"))
        width, height = (int(x) for x in v["size"].split("x"))
        spec = DatasetSpec(n_cameras=CAMERAS, images_per_camera=int(v["images"]), width=width,
                           height=height, image_format=v["format"], renderer=v["renderer"],
                           blur_sigma=float(v["blur"]),
                           target={"type": "chessboard", "rows": rows, "cols": cols,
                                   "spacing": 0.05 if rows * cols <= 60 else 0.035},
                           fisheye=tuple(range(CAMERAS)) if v["lens"] == "fisheye" else ())
        print(f"rendering {CAMERAS} x {v['images']} images into {folder} (once) ...", flush=True)
        render_dataset(folder, spec, seed=SEED)
        (folder / ".complete").write_text("complete\n")
    model = CACHE / f"{folder.name}_model"
    lens_model = "fisheye" if v["lens"] == "fisheye" else "pinhole-radtan"
    if not (model / ".complete").exists():
        shutil.rmtree(model, ignore_errors=True)
        model.mkdir(parents=True)
        for p in folder.iterdir():
            if p.is_dir() or p.name == "mocap.txt":
                (model / p.name).symlink_to(p)
        lines = [line.replace("intrinsics: ", f"model: {lens_model}  # was ")
                 if line.strip().startswith("intrinsics:") else line
                 for line in (folder / "rig.yaml").read_text().splitlines()]
        (model / "rig.yaml").write_text("\n".join(lines) + "\n")
        (model / ".complete").write_text("complete\n")
    return folder, model


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall and CPU seconds (user + system, children included) of one subprocess."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    run = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if run.returncode not in (0, 3):          # 3: calibrate's doubts, the outputs are written
        raise SystemExit(f"{' '.join(cmd)} failed ({run.returncode}): "
                         f"{run.stderr.strip()[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def mrcal_usable(python: str) -> str | None:
    """None when ``python`` imports mrcal and OpenCV, else why not."""
    if not python:
        return "no --mrcal-python given"
    try:
        run = subprocess.run([python, "-c", "import mrcal, cv2"], capture_output=True,
                             text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"{python}: {exc}"
    return None if run.returncode == 0 else \
        f"{python} cannot import mrcal and cv2: {run.stderr.strip().splitlines()[-1:]}"


def read_truth(folder: Path):
    from multieye.io import read_intrinsics

    truth = json.loads((folder / "ground_truth.json").read_text())
    names = sorted(truth["cameras"])
    T = {n: np.array(truth["cameras"][n]["T_ref_cam"]) for n in names}
    lens = {n: read_intrinsics(folder / f"{n}.yaml") for n in names}
    return names, T, lens


def read_multieye(out: Path) -> dict:
    cal = json.loads((out / "calibration.json").read_text())
    return {n: {"T_ref_cam": c["T_ref_cam"], "K": c["intrinsics"]["K"],
                "dist": c["intrinsics"]["distortion"]} for n, c in cal["cameras"].items()}


def pose_errors(est: dict, T_true: dict) -> dict:
    from multieye.core import geometry as g

    return {n: (float(np.degrees(g.rotation_angle_between(np.array(est[n]["T_ref_cam"]), T))),
                1e3 * float(g.translation_distance(np.array(est[n]["T_ref_cam"]), T)))
            for n, T in T_true.items()}


def stats(values) -> str:
    v = np.asarray(values)
    return f"{v.min():.2f} / {np.median(v):.2f} / {v.max():.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--mrcal-python", default="/tmp/venv-mrcal/bin/python")
    ap.add_argument("--keep", type=Path, help="keep every command's outputs in this folder "
                    "(default: a temporary folder, removed)")
    ap.add_argument("--no-report-too", action="store_true",
                    help="also time 'multieye calibrate --no-report' (lenses known and "
                    "unknown): the result without report.html and figures/")
    ap.add_argument("--accuracy-only", action="store_true",
                    help="no runs: the accuracy of the outputs already in --keep")
    ap.add_argument("--variant", action="append", default=[],
                    help="the data: a name of VARIANTS (" + ", ".join(VARIANTS) + "), 'all', "
                    "or key=value,... over " + ",".join(f"{k}={v}" for k, v in BASE.items())
                    + "; repeat for several (default: base)")
    args = ap.parse_args()
    names = [n for v in (args.variant or ["base"]) for n in (VARIANTS if v == "all" else [v])]
    summary = {}
    for name in names:
        v = variant_settings(name)
        known, unknown = rendered(v)
        print(f"\n## variant {name}: {', '.join(f'{k}={x}' for k, x in v.items())}", flush=True)
        tmp = (args.keep / variant_name(v)) if args.keep else \
            Path(tempfile.mkdtemp(prefix="bench_peers_"))
        tmp.mkdir(parents=True, exist_ok=True)
        try:
            summary[name] = run_all(args, known, unknown, tmp, fisheye=v["lens"] == "fisheye")
        finally:
            if args.keep is None:
                shutil.rmtree(tmp, ignore_errors=True)
    if len(summary) > 1 or args.variant:
        print_summary(summary)


#: The multieye commands whose wall time is compared with the OpenCV script's (lenses known,
#: unknown; with --no-report-too, the same without the report).
CASES = ("known", "unknown", "known --no-report", "unknown --no-report")


def print_summary(summary: dict) -> None:
    """Per variant: the wall-time ratio multieye / OpenCV script (median over the runs and
    each run's own ratio, the commands run side by side), lenses known and unknown."""
    print("\n| variant | images found (me / cv) | multieye / OpenCV, known: median (runs min-max) "
          "| unknown: median (runs min-max) | --no-report known | --no-report unknown |")
    print("|---|---|---|---|---|---|")
    worst = dict.fromkeys(CASES, 0.0)
    for name, res in summary.items():
        times, found = res["times"], res["found"]
        cells = []
        for case in CASES:
            me = np.array([w for w, _ in times.get(f"multieye {case}", [])])
            cv = np.array([w for w, _ in times[f"opencv {case.split()[0]}"]])
            if not len(me):
                cells.append("-")
                continue
            ratio, per_run = np.median(me) / np.median(cv), me / cv
            worst[case] = max(worst[case], ratio)
            cells.append(f"{ratio:.2f} ({per_run.min():.2f}-{per_run.max():.2f})")
        print(f"| {name} | {found} | " + " | ".join(cells) + " |")
    print("\nworst median ratio: " + ", ".join(f"{c} {w:.2f}" for c, w in worst.items() if w))


def compile_package(py: str) -> str:
    """Byte-compile the multieye package the commands import, once, as ``pip install`` does.

    Python caches a module's bytecode beside it when it first imports it, unless
    ``PYTHONDONTWRITEBYTECODE`` is set (as in the sessions these benchmarks were first run
    in): then every ``multieye calibrate`` compiled its 120-odd modules from source, about
    0.2 CPU-s in the main process and more in its workers, which an installed package (and
    numpy, scipy and OpenCV here) never pays.  Returns the package's folder."""
    where = subprocess.run([py, "-c", "import multieye, os; print(os.path.dirname("
                            "multieye.__file__))"], capture_output=True, text=True, check=True)
    folder = where.stdout.strip()
    subprocess.run([py, "-m", "compileall", "-q", folder], check=True)
    return folder


def run_all(args, known: Path, unknown: Path, tmp: Path, *, fisheye: bool = False) -> dict:
    """Times every command ``--runs`` times in turn and prints the tables of one variant;
    returns ``{"times": {command: [(wall, cpu), ...]}, "found": "me / cv"}``."""
    py = sys.executable
    if not args.accuracy_only:
        print(f"byte-compiled {compile_package(py)} (as an installed package is)", flush=True)
    # the corners mrcal starts from: OpenCV's detector on the same images (not timed)
    corners = tmp / "corners.npz"
    if not args.accuracy_only:
        subprocess.run([py, str(PEERS / "opencv_script.py"), str(known), "--out",
                        str(tmp / "warm.json"), "--corners-out", str(corners)], check=True)
    commands = {
        "multieye known": ([py, "-m", "multieye", "calibrate", str(known), "-o",
                            str(tmp / "me_known"), "--processes", str(args.processes)],
                           tmp / "me_known"),
        "multieye unknown": ([py, "-m", "multieye", "calibrate", str(unknown), "-o",
                              str(tmp / "me_unknown"), "--processes", str(args.processes)],
                             tmp / "me_unknown"),
        "opencv known": ([py, str(PEERS / "opencv_script.py"), str(known), "--out",
                          str(tmp / "cv_known.json")], tmp / "cv_known.json"),
        "opencv unknown": ([py, str(PEERS / "opencv_script.py"), str(known), "--out",
                            str(tmp / "cv_unknown.json"), "--unknown-lenses"],
                           tmp / "cv_unknown.json"),
    }
    if getattr(args, "no_report_too", False):
        for case, data in (("known", known), ("unknown", unknown)):
            out = tmp / f"me_{case}_noreport"
            commands[f"multieye {case} --no-report"] = (
                [py, "-m", "multieye", "calibrate", str(data), "-o", str(out), "--processes",
                 str(args.processes), "--no-report"], out)
    why_not = "a fisheye variant (mrcal's script fits OpenCV5)" if fisheye else \
        mrcal_usable(args.mrcal_python)
    if why_not is None:
        commands["mrcal unknown (from corners)"] = (
            [args.mrcal_python, str(PEERS / "mrcal_script.py"), str(corners),
             str(known / "mocap.txt"), "--out", str(tmp / "mrcal.json")], tmp / "mrcal.json")
    cores = len(os.sched_getaffinity(0))
    print(f"machine: {platform.machine()}, {cores} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.2f} at start; "
          f"mrcal: {'skipped: ' + why_not if why_not else args.mrcal_python}", flush=True)
    times = {k: [] for k in commands}
    for r in range(0 if args.accuracy_only else args.runs):    # in turn: A B C, A B C, ...
        for name, (cmd, out) in commands.items():
            if out.is_dir():
                shutil.rmtree(out)
            wall, cpu = timed(cmd)
            times[name].append((wall, cpu))
            print(f"  run {r + 1} {name:30s} {wall:6.2f} s wall {cpu:6.2f} CPU-s  "
                  f"load {os.getloadavg()[0]:.1f}", flush=True)
    names, T_true, lens_true = read_truth(known)
    data = np.load(corners)
    print("\n| command | wall s min / median / max | CPU s median |")
    print("|---|---|---|")
    for name, tc in times.items():
        if not tc:
            continue
        print(f"| {name} | {stats([w for w, _ in tc])} | {np.median([c for _, c in tc]):.2f} |")
    print("\nT_ref_cam error, rotation deg / translation mm (camera 0 the reference):\n")
    print("| command | " + " | ".join(names[1:]) + " |")
    print("|---" * len(names) + "|")
    results = {}
    for name, (_, out) in commands.items():
        est = read_multieye(out) if out.is_dir() else json.loads(out.read_text())["cameras"]
        results[name] = est
        err = pose_errors(est, {n: T_true[n] for n in names[1:]})
        print(f"| {name} | " + " | ".join(f"{err[n][0]:.4f} / {err[n][1]:.3f}"
                                          for n in names[1:]) + " |")
    print("\nLens projection error over the observed area, px RMS (after the fitted rotation "
          "between camera frames), lenses unknown:\n")
    print("| command | " + " | ".join(names) + " |")
    print("|---" * (len(names) + 1) + "|")
    for name, est in results.items():
        if "unknown" not in name:
            continue
        cells = []
        for n in names:
            raw, fitted = lens_errors(est[n]["K"], est[n]["dist"], lens_true[n].K,
                                      lens_true[n].dist, data[f"{n}_corners"].reshape(-1, 2),
                                      fisheye=lens_true[n].model == "fisheye")
            cells.append(f"{raw:.4f} ({fitted:.4f})")
        print(f"| {name} | " + " | ".join(cells) + " |")
    print(f"\nload average at the end: {os.getloadavg()[0]:.2f}")
    return {"times": times, "found": images_found(commands)}


def images_found(commands: dict) -> str:
    """Images used by multieye (lenses known: details.json's per-camera count) and by the
    OpenCV script (its boards found and paired), summed over the cameras."""
    me_out, cv_out = commands["multieye known"][1], commands["opencv known"][1]
    cv = sum(c["used"] for c in json.loads(cv_out.read_text())["cameras"].values())
    cal = json.loads((me_out / "calibration.json").read_text())
    me = sum(c.get("measurements_used", 0) for c in cal["cameras"].values())
    return f"{me} / {cv}"


if __name__ == "__main__":
    main()
