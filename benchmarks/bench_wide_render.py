"""Wide lenses (issue 33) calibrated by the pipeline from RENDERED images, boards beyond 90
degrees off the axis included.

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_wide_render.py [--seeds 10] [--variants base,hard]
        [--skip single,mixed] [--json OUT.jsonl]
    python benchmarks/bench_wide_render.py --compare BEFORE.jsonl AFTER.jsonl
    python benchmarks/bench_wide_render.py --curve-table A.jsonl [B.jsonl ...]

Each model (unified, double-sphere, eucm) at 190 and 220 degrees of field
(:func:`multieye.sim.wide_lens.wide_lens`: a 1024 x 1024 image, the field's edge on a circle
of 480 px, the truth's distortion :data:`multieye.sim.wide_lens.SHAPES`), images rendered by
:mod:`multieye.sim.render` (ray tracing through the model, 3 x 3 supersampling) with the
variant's optical blur and sensor noise (``base``: 0.7 px and 2 grey levels, ``hard``: 1.4 px
and 5 grey levels); the rig.yaml asks for the model (``model:``), so the pipeline
(:func:`multieye.pipeline.calibrate`) detects the boards, starts the lens (generic start),
accepts or rejects images and refines; nothing of the truth reaches it.

1. ``single``: one wide camera, 24 images of a 6 x 9 chessboard (30 mm squares) whose centre
   is drawn uniformly over the solid angle within the half field less 3 degrees of the axis
   (so that about a quarter of the views have corners beyond 90 degrees; random azimuth,
   0.3-0.6 m, facing the camera within 40 degrees, :func:`multieye.sim.wide_lens._pose`),
   kept when the whole board is inside the image (:func:`multieye.sim.render.visible`).
2. ``mixed``: a rig of two pinhole cameras (800 x 600, about 75 degrees, radial-tangential,
   ``model: pinhole-radtan4``) and the wide camera, eye-to-base with a motion-captured
   board (:func:`multieye.sim.dataset.render_dataset`, 30 images per camera), the wide
   camera also with 24 ``intrinsics_images`` of the board spread over its field as in 1
   (distances scaled by the board's 50 mm squares).

Figures per case, over the seeds:

- lens error: RMS over the rays of every corner the pipeline used (unprojected through the
  true lens) of ``|pi_est(R ray) - pi_true(ray)|``, pixels, after the rotation ``R`` that
  fits best (``benchmarks/peers/lens_error.py``, :func:`errors`); median and largest;
- lens NEES / dim in the parameters: ``e^T C^-1 e / dim`` with ``e`` the estimate less the
  truth (fx fy cx cy and the model's distortion) and ``C`` the pipeline's reported
  covariance (``run.refinement.intrinsics_covariance``); mean over the seeds (1 when the
  covariance is right; in [0.5, 2] is the goal);
- lens NEES / dim of its curve: calibration.json's ``lens_curve`` (the pixel radii of three
  rays at 0.3, 0.6 and 0.9 of the widest observed angle, :func:`multieye.core.lens_curve.
  observed_curve`) less the true lens' radii at the same rays, in its covariance, over 3;
- lens NEES / dim in pixels: per ray, the error of its pixel (estimated lens less true
  lens) in its covariance ``J C J^T`` (``J`` the 2 x n Jacobian of the projection in the
  parameters), over 2, for 8 fixed rays, at 30, 60, 85 degrees off the axis and at the half
  field less 3 degrees (92 or 107 degrees: beyond 90), azimuths 0/180 and 90/270; averaged
  over the 8 rays and, separately, over the 2 beyond 90 degrees, then over the seeds; no
  rotation is taken out, the principal point's error is part of it;
- mixed rig: ``T_ref_cam`` NEES / 6 of cameras 1 (pinhole) and 2 (wide) in the reported
  covariance (``run.T_ref_cam_covariance``; left perturbation, docs/conventions.md) and the
  largest |error| / sigma of any of their six coordinates;
- images of the wide camera: in (the mixed rig: its 30 motion-captured images and 24
  ``intrinsics_images``) and rejected by the pipeline, with its causes counted;
- seconds of :func:`multieye.pipeline.calibrate` (wall, 1 detection process).

This is a script, not a test: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse  # noqa: E402
import collections  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
from lens_error import errors  # noqa: E402

from multieye.core import geometry as g  # noqa: E402
from multieye.core.intrinsics import Intrinsics  # noqa: E402
from multieye.core.lens import project_points, project_with_jacobian, unproject_points  # noqa: E402
from multieye.core.lens_curve import radial_curve  # noqa: E402
from multieye.core.lie import log_so3  # noqa: E402
from multieye.imaging.targets import Chessboard, target_from_spec  # noqa: E402
from multieye.pipeline import calibrate  # noqa: E402
from multieye.sim.dataset import DatasetSpec, default_intrinsics, render_dataset  # noqa: E402
from multieye.sim.render import render, visible  # noqa: E402
from multieye.sim.wide_lens import _pose, wide_lens  # noqa: E402

MODELS = ("unified", "double-sphere", "eucm")
VARIANTS = {"base": (0.7, 2.0), "hard": (1.4, 5.0)}
SINGLE_BOARD = {"type": "chessboard", "rows": 6, "cols": 9, "spacing": 0.03}
N_SPREAD = 24


def spread_poses(lens: Intrinsics, fov: float, board: Chessboard, n: int,
                 rng: np.random.Generator) -> list[np.ndarray]:
    """``n`` poses T_cam_target of ``board`` over the lens's field (module docstring, 1)."""
    obj = board.object_points()
    scale = board.spacing / 0.03
    half = np.radians(fov / 2)
    out = []
    for _ in range(500 * n):
        if len(out) == n:
            return out
        T = _pose(rng, np.arccos(rng.uniform(np.cos(half - np.radians(3.0)), 1.0)), obj)
        T[:3, 3] = scale * (T[:3, 3] + T[:3, :3] @ obj.mean(axis=0)) - T[:3, :3] @ obj.mean(axis=0)
        if visible(board, lens, T, border_px=8):
            out.append(T)
    raise RuntimeError(f"only {len(out)} of {n} board poses fit the {fov} degree field")


def write_images(folder: Path, board: Chessboard, lens: Intrinsics, poses, seed: int,
                 variant: str) -> int:
    """Render the views into ``folder``; returns how many have a corner beyond 90 degrees."""
    blur, noise = VARIANTS[variant]
    folder.mkdir(parents=True)
    beyond = sum(bool(np.any((board.object_points() @ T[:3, :3].T + T[:3, 3])[:, 2] < 0))
                 for T in poses)
    for k, T in enumerate(poses):
        img = render(board, lens, T, rng=np.random.default_rng([seed, k]), blur_sigma=blur,
                     noise_sigma=noise)
        cv2.imwrite(str(folder / f"{k:03d}.png"), img)
    return beyond


def lens_nees(est: Intrinsics, true: Intrinsics, C: np.ndarray, fov: float
              ) -> tuple[float, float, float]:
    """NEES / dim of the lens in its parameters, and in the pixels of 8 rays, each ray's
    NEES / 2 averaged over the 8 and over the 2 beyond 90 degrees (module docstring)."""
    e = est.params - true.params
    par = float(e @ np.linalg.solve(C, e)) / len(e)
    theta = np.radians(np.repeat([30.0, 60.0, 85.0, fov / 2 - 3.0], 2))
    phi = np.radians([0.0, 180.0, 90.0, 270.0] * 2)
    rays = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                            np.cos(theta)])
    uv, _, J = project_with_jacobian(rays, est)
    d = uv - project_points(rays, true)
    per_ray = np.array([d[i] @ np.linalg.solve(J[i] @ C @ J[i].T, d[i]) / 2
                        for i in range(len(d))])
    return par, float(np.mean(per_ray)), float(np.mean(per_ray[-2:]))


def lens_error_px(est: Intrinsics, true: Intrinsics, pixels: np.ndarray) -> float:
    """RMS lens error after the best rotation over the rays of ``pixels`` (docstring)."""
    rays = unproject_points(pixels, true)
    rays = rays[np.isfinite(rays).all(axis=1)]
    return errors(lambda r: project_points(r, est), rays, project_points(rays, true))[1]


def _used_pixels(run, name: str) -> np.ndarray:
    cam = run.cameras[name]
    obs = list(run.paired[name].observations) if name in run.paired else []
    obs += list(cam.intrinsics_views)
    if not obs:
        obs = list(cam.observations)
    return np.concatenate([o.image_points for o in obs if o.image_points is not None])


def _images(run, name: str) -> dict:
    cam = run.cameras[name]
    causes = collections.Counter(str(getattr(r, "reason", r)).split(":")[0][:40]
                                 for r in cam.rejected)
    return {"inputs": cam.n_inputs, "rejected": len(cam.rejected), "causes": dict(causes)}


def _lens_figures(run, name: str, true: Intrinsics, fov: float) -> dict:
    est = run.intrinsics[name]
    out = {"lens_err_px": lens_error_px(est, true, _used_pixels(run, name)),
           "params": est.params.tolist()}
    cov = run.refinement.intrinsics_covariance.get(name) if run.refinement else None
    if cov is not None:
        out["nees_par"], out["nees_px"], out["nees_px_beyond90"] = lens_nees(est, true, cov, fov)
    curve = run.record.camera(name).intrinsics.lens_curve
    if curve is not None:
        e = curve.radii_px - radial_curve(true, cov, np.radians(curve.angles_deg)).radii_px
        out["nees_curve"] = float(e @ np.linalg.solve(curve.covariance, e)) / len(e)
        out["curve_angles_deg"] = curve.angles_deg.tolist()
    return out


def single_dataset(model: str, fov: float, seed: int, variant: str, tmp: Path
                   ) -> tuple[Path, Intrinsics, list[np.ndarray], int]:
    """The dataset of :func:`single`: its folder, the true lens, the views' true poses
    (image ``k:03d.png`` the k-th) and how many views reach beyond 90 degrees."""
    rng = np.random.default_rng([seed, int(fov), MODELS.index(model)])
    lens = wide_lens(model, fov)
    board = target_from_spec(SINGLE_BOARD)
    folder = tmp / "single"
    poses = spread_poses(lens, fov, board, N_SPREAD, rng)
    beyond = write_images(folder / "wide", board, lens, poses, seed, variant)
    spec = ", ".join(f"{k}: {v}" for k, v in SINGLE_BOARD.items())
    (folder / "rig.yaml").write_text(f"target: {{{spec}}}\ncameras:\n"
                                     f"  wide: {{model: {model}, images: wide/}}\n")
    return folder, lens, poses, beyond


def single(model: str, fov: float, seed: int, variant: str, tmp: Path) -> dict:
    """One wide camera alone (module docstring, 1)."""
    folder, lens, _, beyond = single_dataset(model, fov, seed, variant, tmp)
    t0 = time.perf_counter()
    run = calibrate(folder, processes=1)
    rec = {"seconds": time.perf_counter() - t0, "used": run.record.cameras[0].measurements_used,
           "beyond90": beyond,
           **_images(run, "wide"), **_lens_figures(run, "wide", lens, fov),
           "warnings": list(run.warnings)}
    return rec


def _pose_nees(run, truth, j: int) -> tuple[float, float]:
    T, T_true = run.record.cameras[j].T_ref_cam, truth.T_ref_cam[j]
    e = np.concatenate([log_so3(T[:3, :3] @ T_true[:3, :3].T), T[:3, 3] - T_true[:3, 3]])
    C = run.record.cameras[j].covariance
    return float(e @ np.linalg.solve(C, e)) / 6, float(np.max(np.abs(e) / np.sqrt(np.diag(C))))


def mixed_dataset(model: str, fov: float, seed: int, variant: str, tmp: Path):
    """The dataset of :func:`mixed`: its folder, the true wide lens, the rendered dataset's
    truth and how many of the wide camera's ``intrinsics_images`` reach beyond 90 degrees."""
    rng = np.random.default_rng([seed, int(fov), MODELS.index(model), 2])
    blur, noise = VARIANTS[variant]
    lens = wide_lens(model, fov)
    spec = DatasetSpec(n_cameras=3, images_per_camera=30, blur_sigma=blur, noise_sigma=noise,
                       processes=1)
    folder = tmp / "mixed"
    truth = render_dataset(folder, spec, seed=int(rng.integers(1 << 30)),
                           intrinsics=[*default_intrinsics(2, 800, 600, rng=rng), lens])
    board = target_from_spec(spec.target)
    beyond = write_images(folder / "cam2_lens", board, lens,
                          spread_poses(lens, fov, board, N_SPREAD, rng), seed, variant)
    text = (folder / "rig.yaml").read_text()
    for j in (0, 1):
        text = text.replace(f"intrinsics: cam{j}.yaml", "model: pinhole-radtan4")
    text = text.replace("intrinsics: cam2.yaml",
                        f"model: {model}\n    intrinsics_images: cam2_lens/")
    (folder / "rig.yaml").write_text(text)
    return folder, lens, truth, beyond


def mixed(model: str, fov: float, seed: int, variant: str, tmp: Path) -> dict:
    """Two pinhole cameras and the wide one, motion capture (module docstring, 2)."""
    folder, lens, truth, beyond = mixed_dataset(model, fov, seed, variant, tmp)
    t0 = time.perf_counter()
    run = calibrate(folder, processes=1)
    rec = {"seconds": time.perf_counter() - t0,
           "used": [c.measurements_used for c in run.record.cameras],
           "written": list(truth.images_written), "beyond90": beyond,
           "lens_views": len(run.cameras["cam2"].intrinsics_views), **_images(run, "cam2"),
           **_lens_figures(run, "cam2", lens, fov), "warnings": list(run.warnings)}
    if run.record.cameras[1].covariance is not None:
        rec["pose"] = [_pose_nees(run, truth, j) for j in (1, 2)]
        rec["pose_err"] = [[float(np.degrees(g.rotation_angle_between(
            run.record.cameras[j].T_ref_cam, truth.T_ref_cam[j]))),
            float(g.translation_distance(run.record.cameras[j].T_ref_cam, truth.T_ref_cam[j]))]
            for j in (1, 2)]
    return rec


def _trial(kind: str, model: str, fov: float, seed: int, variant: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        try:
            rec = (single if kind == "single" else mixed)(model, fov, seed, variant, Path(tmp))
        except Exception as exc:  # noqa: BLE001 - a failure is a finding, recorded
            rec = {"failed": f"{type(exc).__name__}: {exc}"[:300]}
    return {"kind": kind, "model": model, "fov": fov, "seed": seed, "variant": variant, **rec}


def _mean(rows, key) -> float:
    v = [r[key] for r in rows if key in r]
    return float(np.mean(v)) if v else float("nan")


def _row(rs: list[dict], kind: str) -> str:
    """One line of the table: a case's figures over its seeds."""
    ok = [r for r in rs if "failed" not in r]
    err = [r["lens_err_px"] for r in ok]
    par = [r["nees_par"] for r in ok if "nees_par" in r]
    cur = [r["nees_curve"] for r in ok if "nees_curve" in r]
    line = (f"| {len(ok)} of {len(rs)} | {np.median(err) if err else np.nan:.3f} / "
            f"{max(err, default=np.nan):.3f} | {_mean(ok, 'nees_par'):.2f} / "
            f"{np.median(par) if par else np.nan:.2f} | {_mean(ok, 'nees_curve'):.2f} / "
            f"{np.median(cur) if cur else np.nan:.2f} | {_mean(ok, 'nees_px'):.2f} | "
            f"{_mean(ok, 'nees_px_beyond90'):.2f} | {sum(r['beyond90'] for r in ok)} | "
            f"{sum(r['inputs'] + (N_SPREAD if kind == 'mixed' else 0) for r in ok)} / "
            f"{sum(r['rejected'] for r in ok)} | "
            f"{np.median([r['seconds'] for r in ok]) if ok else np.nan:.1f} |")
    if kind == "mixed":
        posed = [r for r in ok if "pose" in r]
        line += "".join(f" {np.mean([r['pose'][j][0] for r in posed]):.2f} |" for j in (0, 1))
        line += f" {max((max(p[1] for p in r['pose']) for r in posed), default=np.nan):.2f} |"
        line += f" {np.median([r['pose_err'][1][0] for r in posed]):.3f} |"
    return line


def report(rows: list[dict]) -> None:
    """The tables of docs/results/wide_render.md (markdown) from the trials' records."""
    head = ("| variant | model | field deg | runs ok | lens error px median / max | "
            "NEES/dim params mean / median | NEES/3 lens_curve mean / median | "
            "NEES/2 pixels, 8 rays | NEES/2 pixels, 2 rays beyond 90 | views beyond 90 | "
            "images in / rejected | seconds median |")
    for kind in ("single", "mixed"):
        sel = [r for r in rows if r["kind"] == kind]
        if not sel:
            continue
        print(f"\n{kind}\n")
        extra = (" T_ref_cam NEES/6 cam1 (pinhole) | cam2 (wide) | largest \\|e\\|/sigma | "
                 "cam2 rotation error deg median |") if kind == "mixed" else ""
        print(head + extra)
        print("|---" * (head.count("|") - 1 + extra.count("|")) + "|")
        keys = sorted({(r["variant"], r["model"], r["fov"]) for r in sel},
                      key=lambda k: (list(VARIANTS).index(k[0]), MODELS.index(k[1]), k[2]))
        for variant, model, fov in keys:
            rs = [r for r in sel if (r["variant"], r["model"], r["fov"]) == (variant, model, fov)]
            print(f"| {variant} | {model} | {fov:.0f} " + _row(rs, kind))
        causes = collections.Counter()
        for r in sel:
            causes.update(r.get("causes", {}))
        print("\nrejection causes:", dict(causes) or "none")
        for r in sel:
            if "failed" in r:
                print(f"  failed: {r['variant']} {r['model']} {r['fov']:.0f} seed {r['seed']}: "
                      f"{r['failed']}")


#: How a camera's warning says how many images the second look of its wide lens recovered
#: (multieye.pipeline.camera_data); "wide: 3 of 24 images recovered by ..."
_RECOVERED = "recovered by the wide lens's second look"


def _recovered(r: dict) -> int:
    """Images the second look recovered in one trial, from the warnings (only the wide
    camera has a lens wide enough for it: "wide" alone, "cam2" in the mixed rig, its motion
    images and its intrinsics_images each their own line)."""
    return sum(int(w.split(" of ")[0].split(": ")[-1]) for w in r.get("warnings", ())
               if _RECOVERED in w)


def compare(before: list[dict], after: list[dict]) -> None:
    """The wide camera's figures of the same trials before and after a change (the second
    look of issue 33: docs/results/wide_render.md, section 4), per case: images rejected,
    images the second look recovered, lens error, NEES, seconds."""
    print("| case | variant | model | field deg | rejected before / after | recovered | lens "
          "error px median before / after | NEES/dim params mean before / after | NEES/2 "
          "pixels, 8 rays, before / after | beyond 90, before / after | seconds median "
          "before / after |")
    print("|---" * 11 + "|")
    keys = sorted({(r["kind"], r["variant"], r["model"], r["fov"]) for r in after},
                  key=lambda k: (k[0] == "mixed", list(VARIANTS).index(k[1]),
                                 MODELS.index(k[2]), k[3]))
    for key in keys:
        sel = [[r for r in rows if (r["kind"], r["variant"], r["model"], r["fov"]) == key
                and "failed" not in r] for rows in (before, after)]
        seeds = {r["seed"] for r in sel[0]} & {r["seed"] for r in sel[1]}
        b, a = ([r for r in rs if r["seed"] in seeds] for rs in sel)

        def pair(f, fmt=".2f", both=(b, a)):
            return " / ".join(format(f(rs), fmt) for rs in both)

        print(f"| {key[0]} | {key[1]} | {key[2]} | {key[3]:.0f} | "
              f"{pair(lambda rs: sum(r['rejected'] for r in rs), 'd')} | "
              f"{sum(_recovered(r) for r in a)} | "
              f"{pair(lambda rs: float(np.median([r['lens_err_px'] for r in rs])), '.3f')} | "
              f"{pair(lambda rs: _mean(rs, 'nees_par'))} | {pair(lambda rs: _mean(rs, 'nees_px'))} | "
              f"{pair(lambda rs: _mean(rs, 'nees_px_beyond90'))} | "
              f"{pair(lambda rs: float(np.median([r['seconds'] for r in rs])), '.1f')} |")


def curve_table(rows: list[dict]) -> None:
    """The table of docs/results/wide_render.md, sections 5 and 6 (markdown): per case the
    lens NEES in its parameters, of calibration.json's ``lens_curve`` (mean, median,
    largest), in pixels, and the mixed rig's extrinsics (NEES / 6 of cameras 1 and 2, the
    largest |e| / sigma and how many rigs have a coordinate beyond 3 sigma)."""
    print("| case | model | field deg | runs ok | NEES/dim params mean / median | NEES/3 "
          "`lens_curve` mean / median (largest) | NEES/2 pixels, 8 rays | T_ref_cam NEES/6 "
          "cam1 / cam2 | largest \\|e\\|/sigma | rigs beyond 3 sigma |")
    print("|---" * 10 + "|")
    keys = sorted({(r["kind"], r["variant"], r["model"], r["fov"]) for r in rows},
                  key=lambda k: (k[0] == "mixed", list(VARIANTS).index(k[1]),
                                 MODELS.index(k[2]), k[3]))
    for kind, variant, model, fov in keys:
        rs = [r for r in rows if (r["kind"], r["variant"], r["model"], r["fov"])
              == (kind, variant, model, fov)]
        ok = [r for r in rs if "failed" not in r]
        par = [r["nees_par"] for r in ok if "nees_par" in r]
        cur = [r["nees_curve"] for r in ok if "nees_curve" in r]
        line = (f"| {kind} | {model} | {fov:.0f} | {len(ok)} of {len(rs)} | "
                f"{np.mean(par):.2f} / {np.median(par):.2f} | {np.mean(cur):.2f} / "
                f"{np.median(cur):.2f} ({np.max(cur):.2f}) | {_mean(ok, 'nees_px'):.2f} |")
        posed = [r for r in ok if "pose" in r]
        if posed:
            worst = [max(p[1] for p in r["pose"]) for r in posed]
            line += (" " + " / ".join(f"{np.mean([r['pose'][j][0] for r in posed]):.2f}"
                                      for j in (0, 1)) +
                     f" | {max(worst):.2f} | {sum(w > 3 for w in worst)} of {len(posed)} |")
        else:
            line += " - | - | - |"
        print(line)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--mixed-seeds", type=int, default=None, help="default: --seeds")
    ap.add_argument("--variants", default="base,hard")
    ap.add_argument("--skip", default="")
    ap.add_argument("--json", default=None, help="append every trial's record here (the "
                    "tables again: python -c 'import json,sys; sys.path.insert(0,\"benchmarks\"); "
                    "import bench_wide_render as b; b.report([json.loads(l) for l in open(F)])')")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--fields", default="190,220")
    ap.add_argument("--compare", nargs=2, metavar=("BEFORE", "AFTER"), default=None,
                    help="only compare two --json files of the same trials (section 4 of "
                    "docs/results/wide_render.md)")
    ap.add_argument("--curve-table", nargs="+", metavar="JSONL", default=None,
                    help="only print the lens_curve table (docs/results/wide_render.md, "
                    "sections 5 and 6) of these --json files")
    args = ap.parse_args()
    if args.curve_table:
        curve_table([json.loads(line) for f in args.curve_table for line in open(f)])
        return
    if args.compare:
        compare(*([json.loads(line) for line in open(f)] for f in args.compare))
        return
    skip = set(args.skip.split(","))
    rows = []
    plan = [(k, v, m, f, s) for k in ("single", "mixed") if k not in skip
            for v in args.variants.split(",") for m in args.models.split(",")
            for f in map(float, args.fields.split(","))
            for s in range(args.seeds if k == "single" else (args.mixed_seeds or args.seeds))]
    for kind, variant, model, fov, seed in plan:
        rec = _trial(kind, model, fov, seed, variant)
        rows.append(rec)
        if args.json:
            with open(args.json, "a") as fh:
                fh.write(json.dumps(rec) + "\n")
        print(f"{kind} {variant} {model} {fov:.0f} seed {seed}: "
              + (rec.get("failed") or f"lens {rec['lens_err_px']:.3f} px, NEES "
                 f"{rec.get('nees_par', np.nan):.2f} / {rec.get('nees_curve', np.nan):.2f} / "
                 f"{rec.get('nees_px', np.nan):.2f}, "
                 f"{rec['seconds']:.0f} s"), flush=True)
    report(rows)


if __name__ == "__main__":
    main()
