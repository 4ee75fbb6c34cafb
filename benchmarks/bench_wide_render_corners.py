"""Is a rendered wide lens's excess NEES the detected corners' or the estimation's? (issue 33;
docs/results/wide_render.md, section 6)

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_wide_render_corners.py [--rig mixed] [--model unified]
        [--field 190] [--seeds 0-9] [--corners detected|ideal|unstraightened]
        [--sigma 0.04] [--noise-seed 12345] [--mocap-scale F] [--json OUT.jsonl]

The trials of ``bench_wide_render.py`` (the same rendered images, the same pipeline run,
:func:`bench_wide_render.mixed` or :func:`~bench_wide_render.single`), with the corners the
detector returns for every image (every camera) taken in one of three ways:

- ``detected``: as detected (the pipeline as it is; the trial of ``bench_wide_render.py``);
- ``ideal``: replaced by the true projection of the same board points (the pose and lens
  each image was rendered with) plus independent Gaussian noise of ``--sigma`` pixels (one
  generator, seeded ``--noise-seed``, default 12345, for the whole run): the corners the estimation's model assumes,
  so what is left of an excess NEES is the estimation's own (its covariance, its bias);
- ``unstraightened``: detected without the straightened refinement of session 13
  (:func:`multieye.imaging.straight_corners.refine_straightened` left out of
  :func:`multieye.imaging.chessboard_corners.refine_grid`): the corners of main before it.

The script changes only what the detection returns, by wrapping
:func:`multieye.imaging.batch.detect_with_second_look` in this process (``processes=1``, as
``bench_wide_render.py`` runs it), and records what each image was rendered with by wrapping
the renderers' callers (:func:`multieye.sim.dataset.render_dataset`'s pool and
:func:`bench_wide_render.write_images`).  Per seed it prints and records the trial's figures
(``bench_wide_render.py``'s: lens NEES in the parameters, of the curve, in pixels, the
extrinsics' NEES / 6 and largest |e| / sigma), and besides:

- ``curve_z``: the ``lens_curve`` radii less the truth's, each over its standard deviation
  (a bias shows as one sign over the seeds: the same true lens in every seed);
- ``corner_err``: the detected corners of the wide lens less their true projection
  (always the detected ones, before any replacement), by angle off the axis (bins of
  degrees): count, mean radial component (outward positive) and RMS, pixels; and the same
  of the other cameras' corners (``corner_err_other``).

This is a script, not a test: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse  # noqa: E402
import contextlib  # noqa: E402
import functools  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_wide_render as b  # noqa: E402

import multieye.imaging.batch as batch  # noqa: E402
import multieye.imaging.chessboard_corners as chessboard_corners  # noqa: E402
import multieye.sim.dataset as sim_dataset  # noqa: E402
from multieye.core.lens import project_points  # noqa: E402
from multieye.core.lens_curve import radial_curve  # noqa: E402

#: Bins of the angle off the axis (degrees) of the corner errors.
BINS = (0, 20, 40, 60, 80, 90, 100, 130)


class Recorder:
    """What each image file was rendered with (its ``T_cam_target`` and lens), the detected
    corners' errors, and the detection's replacement (``mode``)."""

    def __init__(self, mode: str, sigma: float, noise_seed: int = 12345):
        self.mode, self.sigma = mode, sigma
        self.rng = np.random.default_rng(noise_seed)
        self.truth: dict[str, tuple] = {}
        self.errors: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]] = []
        self.current: str | None = None

    def reset(self) -> None:
        self.truth.clear()
        self.errors.clear()

    def detected(self, detection):
        """The detection of the current image as the mode has it (errors recorded)."""
        truth = self.truth.get(self.current)
        if detection is None or truth is None:
            return detection
        T, lens = truth
        pc = detection.object_points @ T[:3, :3].T + T[:3, 3]
        uv = project_points(pc, lens)
        err = detection.image_points - uv
        if not np.all(np.abs(err) < 2.0):            # another order, or not this board
            return detection
        theta = np.degrees(np.arctan2(np.hypot(pc[:, 0], pc[:, 1]), pc[:, 2]))
        self.errors.append((lens.model, err, theta, uv - lens.params[2:4]))
        if self.mode == "ideal":
            return replace(detection, image_points=uv + self.rng.normal(scale=self.sigma,
                                                                          size=uv.shape))
        return detection


def install(rec: Recorder) -> None:
    """Wrap the renderers' callers and the detection (module docstring)."""
    @contextlib.contextmanager
    def pool(_n):
        class InProcess:
            @staticmethod
            def map(f, jobs, chunksize=1):
                out = []
                for job in jobs:   # (target, intrinsics, T, seed, blur, noise, path, renderer)
                    rec.truth[str(Path(job[6]).resolve())] = (job[2], job[1])
                    out.append(f(job))
                return out
        yield InProcess()

    write_images = b.write_images

    def writing(folder, board, lens, poses, seed, variant):
        for k, T in enumerate(poses):
            rec.truth[str((folder / f"{k:03d}.png").resolve())] = (T, lens)
        return write_images(folder, board, lens, poses, seed, variant)

    process_array, detect = batch.process_array, batch.detect_with_second_look

    def processing(image, name, *args, **kw):
        rec.current = str(Path(name).resolve())
        return process_array(image, name, *args, **kw)

    def detecting(image, target, intrinsics):
        detection, why, looked = detect(image, target, intrinsics)
        return rec.detected(detection), why, looked

    sim_dataset.worker_pool = pool
    b.write_images = writing
    batch.process_array = processing
    batch.detect_with_second_look = detecting
    if rec.mode == "unstraightened":
        chessboard_corners.refine_straightened = lambda gray, refined, rows, cols, window: refined


def _by_angle(errors: list) -> list:
    """Per bin of the angle off the axis: count, mean radial error (outward positive) and
    RMS of the errors of ``errors`` (the recorder's tuples), pixels."""
    err, theta, off = (np.concatenate([e[i] for e in errors]) for i in (1, 2, 3))
    radial = np.sum(err * off, axis=1) / np.maximum(np.linalg.norm(off, axis=1), 1e-9)
    return [[lo, int(m.sum()), float(radial[m].mean()), float(np.sqrt(np.mean(err[m] ** 2)))]
            for lo, hi in zip(BINS[:-1], BINS[1:]) for m in [(theta >= lo) & (theta < hi)]
            if m.any()]


def corner_figures(rec: Recorder, model: str) -> dict:
    """``corner_err`` of the module docstring (``corner_err_other``: the same of the other
    cameras' corners)."""
    wide = [e for e in rec.errors if e[0] == model]
    other = [e for e in rec.errors if e[0] != model]
    out = {}
    if wide:
        out["corner_err"] = _by_angle(wide)
        out["corner_rms_wide"] = float(np.sqrt(np.mean(np.concatenate([e[1] for e in wide]) ** 2)))
    if other:
        out["corner_err_other"] = _by_angle(other)
        out["corner_rms_other"] = float(np.sqrt(np.mean(np.concatenate([e[1] for e in other])
                                                        ** 2)))
    return out


def trial(rig: str, model: str, fov: float, seed: int, rec: Recorder) -> dict:
    """One trial of ``bench_wide_render.py`` with the recorder's corners."""
    rec.reset()
    kept = {}
    lens_figures = b._lens_figures

    def figures(run, name, true, fov_):
        out = lens_figures(run, name, true, fov_)
        curve = run.record.camera(name).intrinsics.lens_curve
        cov = run.refinement.intrinsics_covariance.get(name)
        if curve is not None:
            e = curve.radii_px - radial_curve(true, cov, np.radians(curve.angles_deg)).radii_px
            kept["curve_z"] = (e / np.sqrt(np.diag(curve.covariance))).tolist()
            kept["curve_err_px"] = e.tolist()
        kept["pixel_sigma"] = run.refinement.result.pixel_sigma
        return out

    b._lens_figures = figures
    try:
        with tempfile.TemporaryDirectory() as tmp:
            out = (b.mixed if rig == "mixed" else b.single)(model, fov, seed, "base", Path(tmp))
    finally:
        b._lens_figures = lens_figures
    keys = ("nees_par", "nees_curve", "nees_px", "nees_px_beyond90", "pose", "lens_err_px")
    return {"rig": rig, "model": model, "fov": fov, "seed": seed, "corners": rec.mode,
            **{k: out[k] for k in keys if k in out}, **kept, **corner_figures(rec, model)}


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rig", default="mixed", choices=("single", "mixed"))
    ap.add_argument("--model", default="unified")
    ap.add_argument("--field", type=float, default=190.0)
    ap.add_argument("--seeds", default="0-9")
    ap.add_argument("--corners", default="detected",
                    choices=("detected", "ideal", "unstraightened"))
    ap.add_argument("--sigma", type=float, default=0.04, help="pixels, --corners ideal")
    ap.add_argument("--noise-seed", type=int, default=12345, help="--corners ideal")
    ap.add_argument("--mocap-scale", type=float, default=None,
                    help="state the motion capture's noise this many times the truth's "
                    "(calibrate's mocap_rot_sigma_rad, mocap_trans_sigma_m): a large factor "
                    "leaves the rig's poses to the pixels alone")
    ap.add_argument("--json", default=None, help="append every seed's record here")
    args = ap.parse_args()
    rec = Recorder(args.corners, args.sigma, args.noise_seed)
    install(rec)
    if args.mocap_scale is not None:
        rot, trans = sim_dataset.DatasetSpec().mocap_noise
        b.calibrate = functools.partial(b.calibrate, mocap_rot_sigma_rad=rot * args.mocap_scale,
                                        mocap_trans_sigma_m=trans * args.mocap_scale)
    rows = []
    for seed in _seeds(args.seeds):
        r = trial(args.rig, args.model, args.field, seed, rec)
        rows.append(r)
        if args.json:
            with open(args.json, "a") as fh:
                fh.write(json.dumps(r) + "\n")
        pose = r.get("pose") or [[np.nan, np.nan]] * 2
        print(f"seed {seed}: NEES params {r.get('nees_par', np.nan):.2f} curve "
              f"{r.get('nees_curve', np.nan):.2f} pixels {r.get('nees_px', np.nan):.2f}; curve "
              f"z {np.round(r.get('curve_z', []), 2).tolist()}; T_ref_cam NEES/6 "
              f"{pose[0][0]:.2f} {pose[1][0]:.2f}, largest {max(p[1] for p in pose):.2f}; "
              f"corners RMS {r.get('corner_rms_wide', np.nan):.4f} px (others "
              f"{r.get('corner_rms_other', np.nan):.4f})", flush=True)
    report(rows)


def report(rows: list[dict]) -> None:
    """Means over the seeds (printed)."""
    z = np.array([r["curve_z"] for r in rows if "curve_z" in r])
    cur = [r["nees_curve"] for r in rows if "nees_curve" in r]
    print(f"\n{len(rows)} seeds, corners {rows[0]['corners']}: NEES/3 lens_curve mean "
          f"{np.mean(cur):.2f} median {np.median(cur):.2f} largest {np.max(cur):.2f}; "
          f"NEES/2 pixels {np.mean([r['nees_px'] for r in rows if 'nees_px' in r]):.2f}; "
          f"curve z mean {np.round(z.mean(axis=0), 2).tolist()} sd "
          f"{np.round(z.std(axis=0, ddof=1), 2).tolist()}")
    posed = [r for r in rows if r.get("pose")]
    if posed:
        print("T_ref_cam NEES/6 mean " + " / ".join(
            f"{np.mean([r['pose'][j][0] for r in posed]):.2f}" for j in (0, 1)) +
            f", largest |e|/sigma {max(max(p[1] for p in r['pose']) for r in posed):.2f}")
    for key, what in (("corner_err", "wide lens"), ("corner_err_other", "other cameras")):
        bins: dict[int, list] = {}
        for r in rows:
            for lo, n, mean, rms in r.get(key, ()):
                bins.setdefault(lo, []).append((n, mean, rms))
        for lo, v in sorted(bins.items()):
            n = np.array([x[0] for x in v], float)
            mean = float(np.sum(n * [x[1] for x in v]) / n.sum())
            rms = float(np.sqrt(np.sum(n * np.square([x[2] for x in v])) / n.sum()))
            print(f"  {what}, corners from {lo} deg: {int(n.sum())}, radial mean {mean:+.4f} "
                  f"px, RMS {rms:.4f} px")

if __name__ == "__main__":
    main()
