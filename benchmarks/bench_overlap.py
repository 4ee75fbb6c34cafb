"""An overlapping rig without motion capture: multieye against mrcal and OpenCV (issue 23).

Run from the repository root::

    python benchmarks/bench_overlap.py [--data /tmp/bench_overlap] [--seeds 40] [--runs 1]
        [--first-seed 0] [--pixel-noise PX] [--peers multieye,mrcal]
        [--mrcal-python /tmp/venv-h-bench-mrcal/bin/python]

The rig (:func:`multieye.sim.overlap.render_overlap_dataset`, seeds --first-seed ..
--first-seed + --seeds - 1): three cameras on an arc 34 degrees apart, 1.2 m from the centre
of the work volume, two radial-tangential lenses (k1 k2 p1 p2) and one equidistant fisheye,
800 x 600; a 6 x 9 chessboard shown at 50 instants, rendered (blur 0.7 px, sensor noise 2 grey
levels), no motion capture.  The corners are detected once by multieye's detector (full
boards only) and the same corners, with each image's instant (stamps within the default
``sync_tolerance``), go to every peer, each in its own process
(``benchmarks/peers/overlap_*.py``).  With ``--pixel-noise PX`` nothing is rendered: the
corners are the true ones with Gaussian noise of PX pixels per coordinate, which compares the
estimators without the renderer's and the detector's errors.  For ``multieye + mocap`` the
board's motion capture at each instant is drawn per rig (0.03 deg and 0.1 mm per axis).
Every peer is timed two ways, the same for each: the whole process (interpreter start,
imports, reading the corners, solving, writing; CPU time of the child from
``resource.getrusage``, and wall time), and in the process from the corners in memory to the
result (``time.process_time``, which the peer reports; imports excluded):

- ``multieye``: OpenCV's per-camera start, then the joint problem of every lens (the right
  model per camera), every ``T_ref_cam`` and one board pose per instant;
- ``multieye + mocap``: the same with the board's motion capture (the mixed problem);
- ``mrcal``: ``mrcal-calibrate-cameras``' joint solve (one lens model for all cameras:
  ``LENSMODEL_OPENCV8``; mrcal has no equidistant model);
- ``opencv``: ``calibrateCamera`` / ``fisheye.calibrate`` per camera, then
  ``stereoCalibrate`` of each camera with camera 0.

Reported per peer and camera: the lens's projection error over the observed corners (px, RMS;
raw and after the best-fitting rotation, ``benchmarks/peers/lens_error.py``), the error of
``T_ref_cam`` against the truth (deg, mm), RMS over the rigs, and per peer the wall and CPU
times (median over every run, the peers interleaved so that they see the same load).  Since
the lens figures differ between rigs by more than between peers, the lens error after the
rotation is also listed per rig, with each peer's paired difference from mrcal's on the same
rig (and multieye + mocap's from multieye's): mean, standard deviation and standard error
over the rigs, and on how many rigs it is below.  Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.estimate.instants import default_sync_tolerance, instants_from_stamps
from multieye.imaging.detect import detect
from multieye.imaging.image_file import read_gray
from multieye.imaging.targets import target_from_spec
from multieye.sim.overlap import OverlapSpec, pixel_views, render_overlap_dataset, simulate_overlap

PEERS = Path(__file__).resolve().parent / "peers"
sys.path.insert(0, str(PEERS))
from lens_error import errors, project, unproject  # noqa: E402

SPEC = OverlapSpec()


def corners(data: Path) -> Path:
    """Detect once; write ``corners.npz`` (the peers' input)."""
    out = data / "corners.npz"
    if out.exists():
        return out
    target = target_from_spec(SPEC.target)
    truth = json.loads((data / "ground_truth.json").read_text())
    names = list(truth["T_ref_cam"])
    rows, cols = SPEC.target["rows"], SPEC.target["cols"]
    arrays, stamps, found = {}, [], []
    for name in names:
        cs, ts = [], []
        for path in sorted((data / name).glob("*.png")):
            gray = read_gray(path)[0]
            det = detect(gray, target)
            if det is None or len(det) != rows * cols:
                continue
            cs.append(det.image_points[np.argsort(det.ids)].reshape(rows, cols, 2))
            ts.append(float(path.stem))
        arrays[f"{name}_corners"] = np.asarray(cs)
        arrays[f"{name}_model"] = np.array(truth["intrinsics"][name]["model"] == "fisheye"
                                           and "fisheye" or "pinhole-radtan")
        stamps.append(np.asarray(ts))
        found.append(len(cs))
    inst, _ = instants_from_stamps(stamps, default_sync_tolerance(stamps))
    for name, i in zip(names, inst):
        arrays[f"{name}_instants"] = i
    save_corners(out, names, arrays)
    print(f"corners: {dict(zip(names, found))} full boards")
    return out


def save_corners(out: Path, names: list[str], arrays: dict) -> None:
    """Write the peers' ``corners.npz`` (the board's motion capture: :func:`add_mocap`)."""
    np.savez(out, cameras=np.array(names), spacing=SPEC.target["spacing"],
             size=np.array([SPEC.width, SPEC.height]), **arrays)


def add_mocap(npz: Path, truth: dict, seed: int) -> None:
    """Put the board's motion capture at each instant into ``npz`` (for multieye with
    --mocap), unless it is there for this rig: 0.03 deg and 0.1 mm per axis (as the rendered
    rig of bench_peers.py), drawn for each rig from its own seed, so that the rigs also
    sample the motion capture's noise (they all shared one draw before)."""
    c = dict(np.load(npz))
    if int(c.get("mocap_seed", -1)) == seed:
        return
    T_ref_target = np.asarray(truth["T_ref_target"])
    rng = np.random.default_rng([seed, 7])
    T_world_ref = g.transform_from_rotvec([0, 0, 0.4], [0.5, -0.2, 1.0])
    T_marker_target = g.transform_from_rotvec([0.1, -0.2, 0.3], [0.05, 0.02, -0.03])
    noise = g.transform_from_rotvec(rng.normal(scale=np.radians(0.03), size=(len(T_ref_target), 3)),
                                    rng.normal(scale=1e-4, size=(len(T_ref_target), 3)))
    c["mocap_T"] = T_world_ref @ T_ref_target @ g.inv(T_marker_target) @ noise
    c["mocap_seed"] = np.array(seed)
    np.savez(npz, **c)


def simulated_corners(data: Path, seed: int, sigma_px: float) -> Path:
    """Instead of rendering and detecting: the true corners of the rig of ``seed`` with
    Gaussian noise ``sigma_px`` per coordinate (``multieye.sim.overlap.pixel_views``), so that
    the estimators are compared without the detector's errors.  Writes ``ground_truth.json``
    and ``corners.npz`` into ``data``."""
    out = data / "corners.npz"
    if out.exists():
        return out
    data.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    sc = simulate_overlap(rng, SPEC)
    views = pixel_views(sc, sigma_px, rng)
    names = [f"cam{j}" for j in range(len(views))]
    rows, cols = SPEC.target["rows"], SPEC.target["cols"]
    arrays = {}
    for name, intr, vs in zip(names, sc.intrinsics, views):
        arrays[f"{name}_corners"] = np.asarray([u.reshape(rows, cols, 2) for _, u, _ in vs])
        arrays[f"{name}_instants"] = np.asarray([t for *_, t in vs])
        arrays[f"{name}_model"] = np.array(intr.model == "fisheye" and "fisheye"
                                           or "pinhole-radtan")
    truth = {"T_ref_cam": {n: sc.T_ref_cam[j].tolist() for j, n in enumerate(names)},
             "T_ref_target": sc.T_ref_target.tolist(),
             "intrinsics": {n: {"K": sc.intrinsics[j].K.tolist(),
                                "dist": sc.intrinsics[j].dist.tolist(),
                                "model": sc.intrinsics[j].model} for j, n in enumerate(names)}}
    (data / "ground_truth.json").write_text(json.dumps(truth))
    save_corners(out, names, arrays)
    return out


def run(cmd: list[str], out: Path) -> tuple[dict, float, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd + ["--out", str(out)], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{cmd[1]} failed: {proc.stderr.strip().splitlines()[-3:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return json.loads(out.read_text()), wall, cpu


def lens_error(est: dict, true: dict, pixels: np.ndarray) -> tuple[float, float]:
    tf = true["model"] == "fisheye"
    rays = unproject(pixels, true["K"], true["dist"], tf)
    truth = project(rays, true["K"], true["dist"], tf)
    return errors(lambda r: project(r, est["K"], est["dist"], est["fisheye"]), rays, truth)


def evaluate(results: dict, truth: dict, c) -> dict:
    """peer -> camera -> (lens raw, lens after rotation, deg, mm)."""
    names = list(truth["T_ref_cam"])
    out = {}
    for peer, res in results.items():
        out[peer] = {}
        for name in names:
            est = res["cameras"][name]
            raw, rot = lens_error(est, truth["intrinsics"][name],
                                  c[f"{name}_corners"].reshape(-1, 2))
            T, Tt = np.asarray(est["T_ref_cam"]), np.asarray(truth["T_ref_cam"][name])
            out[peer][name] = (raw, rot, np.degrees(g.rotation_angle_between(T, Tt)),
                               1e3 * g.translation_distance(T, Tt))
    return out


def main(argv=None) -> None:
    global SPEC  # noqa: PLW0603 (the rig's spec, read by every helper here)
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path("/tmp/bench_overlap"))
    ap.add_argument("--seeds", type=int, default=1,
                    help="rigs (seeds --first-seed, --first-seed + 1, ...)")
    ap.add_argument("--runs", type=int, default=3, help="timed runs of each peer per rig")
    ap.add_argument("--mrcal-python", default="/tmp/venv-h-bench-mrcal/bin/python")
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0,
                    help="seeds --first-seed .. --first-seed + --seeds - 1")
    ap.add_argument("--pixel-noise", type=float, default=None, metavar="PX",
                    help="no rendering: the true corners with Gaussian noise of PX pixels")
    ap.add_argument("--peers", default="multieye,multieye + mocap,mrcal,opencv",
                    help="comma-separated subset of the peers")
    ap.add_argument("--instants", type=int, default=OverlapSpec().n_instants,
                    help="board poses per rig (OverlapSpec.n_instants)")
    ap.add_argument("--size", type=int, nargs=2, default=(OverlapSpec().width, OverlapSpec().height),
                    metavar=("WIDTH", "HEIGHT"), help="image size, pixels")
    args = ap.parse_args(argv)
    SPEC = replace(SPEC, n_instants=args.instants, width=args.size[0], height=args.size[1])
    times, errs = {}, []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        data = args.data / f"seed{seed}"
        if args.pixel_noise is not None:
            npz = simulated_corners(data, seed, args.pixel_noise)
        else:
            if not (data / "ground_truth.json").exists():
                render_overlap_dataset(data, SPEC, seed=seed, models=True,
                                       processes=args.processes)
            npz = corners(data)
        truth = json.loads((data / "ground_truth.json").read_text())
        add_mocap(npz, truth, seed)
        names = list(truth["T_ref_cam"])
        c = np.load(npz)
        peers = {"multieye": [sys.executable, str(PEERS / "overlap_multieye.py"), str(npz)],
                 "multieye + mocap": [sys.executable, str(PEERS / "overlap_multieye.py"),
                                      str(npz), "--mocap"],
                 "mrcal": [args.mrcal_python, str(PEERS / "overlap_mrcal.py"), str(npz)],
                 "opencv": [sys.executable, str(PEERS / "overlap_opencv.py"), str(npz)]}
        peers = {p: peers[p] for p in args.peers.split(",")}
        results = {}
        with tempfile.TemporaryDirectory() as tmp:
            for _ in range(args.runs):
                for peer, cmd in peers.items():
                    res, wall, cpu = run(cmd, Path(tmp) / f"{peer.replace(' + ', '_')}.json")
                    results[peer] = res
                    times.setdefault(peer, []).append((wall, cpu, res["cpu_s"]))
        shared = {n: int(np.isin(c[f"{names[0]}_instants"], c[f"{n}_instants"]).sum())
                  for n in names[1:]}
        print(f"seed {seed}: images { {n: len(c[f'{n}_instants']) for n in names} }, "
              f"shared with {names[0]}: {shared}")
        if "multieye" in results:
            std = {n: (round(v.get("std_rot_deg", 0), 4), round(1e3 * v.get("std_trans_m", 0), 3))
                   for n, v in results["multieye"]["cameras"].items()}
            print(f"  multieye predicted std (deg, mm): {std}; pixel sigma "
                  f"{results['multieye']['pixel_sigma']:.3f} px")
        errs.append(evaluate(results, truth, c))
    names = list(errs[0][next(iter(errs[0]))])
    print(f"RMS over {args.seeds} rig(s):")
    print("| peer | camera | lens px | lens px after rotation | T_ref_cam deg | T_ref_cam mm |")
    print("|---|---|---|---|---|---|")
    for peer in errs[0]:
        for name in names:
            v = np.sqrt(np.mean(np.square([e[peer][name] for e in errs]), axis=0))
            ext = ("-", "-") if name == names[0] else (f"{v[2]:.4f}", f"{v[3]:.3f}")
            print(f"| {peer} | {name} | {v[0]:.3f} | {v[1]:.4f} | {ext[0]} | {ext[1]} |")
    print_spread(errs, names)
    print("| peer | process wall s | process CPU s | CPU s from the corners |")
    print("|---|---|---|---|")
    for peer, ts in times.items():
        w, cpu, inner = np.median(np.asarray(ts), axis=0)
        print(f"| {peer} | {w:.2f} | {cpu:.2f} | {inner:.2f} |")


def print_spread(errs: list[dict], names: list[str]) -> None:
    """Per rig, each peer's lens error after the rotation; the mean, standard deviation and
    standard error over the rigs of its difference from mrcal's (and multieye + mocap's from
    multieye's), and on how many rigs it is below."""
    print("lens px after rotation, per rig; paired difference: mean +- std (standard error)")
    pairs = [(p, "mrcal") for p in errs[0] if p != "mrcal" and "mrcal" in errs[0]]
    if "multieye" in errs[0] and "multieye + mocap" in errs[0]:
        pairs.append(("multieye + mocap", "multieye"))
    for peer in errs[0]:
        print(f"  {peer}: " + "; ".join(
            f"{n} " + " ".join(f"{e[peer][n][1]:.4f}" for e in errs) for n in names))
    for peer, base in pairs:
        cells = []
        for name in names:
            d = np.array([e[peer][name][1] - e[base][name][1] for e in errs])
            sd = d.std(ddof=1) if len(d) > 1 else 0.0
            cells.append(f"{name} {d.mean():+.4f} +- {sd:.4f} ({sd / np.sqrt(len(d)):.4f}), "
                         f"below on {int(np.sum(d < 0))} of {len(d)}")
        print(f"  {peer} minus {base}: " + "; ".join(cells))


if __name__ == "__main__":
    main()
