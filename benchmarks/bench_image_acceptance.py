"""Images judged on the jointly refined lens (issue 33, item 2): how many are taken back or
left out, what it does to the rig and the lens, and that clean rigs are left as they were.

Run from the repository root (``--before`` names a source tree without the judgement, to
print its figures on the same cases)::

    MULTIEYE_SHARED_DATA=../shared/data PYTHONPATH=src python benchmarks/bench_image_acceptance.py \
        [--seeds 5] [--skip rendered,boofcv]

1. ``rendered``: per seed an eye-to-base rig of two cameras rendered by
   :func:`multieye.sim.dataset.render_dataset` (640 x 480, 20 images each, motion capture),
   lenses estimated (``model: pinhole-radtan4``), loaded once, then calibrated
   (:func:`multieye.pipeline.calibrate_rig`) in three cases:

   - ``clean``: as loaded;
   - ``start``: camera 1's lens started with k1 + 1.0 (every image posed by PnP on it, those
     over 2 px left out as a bad fit, as the pipeline does with a poor start), no consensus
     (so that only the bad fits are at stake);
   - ``corrupt``: one image of camera 1 (the sixth) with every other corner shifted by
     (2, -1.5) px, about 1 px of PnP RMS (within the 2 px limit).

   Figures: camera 1's images used, taken back and left out (with the outlier's name when
   it is the corrupted one), the rotation and translation error of its ``T_ref_cam`` against
   the truth, and of its lens (largest pixel error over a grid of rays within the views).
2. ``boofcv``: ``boofcv_fisheye`` (26 images, one camera, no motion capture) with
   ``model: fisheye`` and ``model: unified``, detected once, calibrated as detected and from
   poorer starts of the lens (one parameter of the start moved, :data:`STARTS`; every image
   posed on it, those over 2 px left out as a bad fit): images left out on the start, used,
   taken back, left out as outliers, the reprojection RMS, and the lens against the one
   calibrated as detected (largest absolute difference of its parameters).

This is a script, not a test: nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import re
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.core.intrinsics import parameter_names
from multieye.core.lens import project_points
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import estimate_poses, refit_pose
from multieye.io import RejectedItem, load_rig
from multieye.pipeline import calibrate_rig, load_camera_data
from multieye.sim.dataset import DatasetSpec, render_dataset


def _started_on(data, lens):
    """Camera data as the pipeline leaves it with its lens started at ``lens``."""
    poses = estimate_poses([Detection(np.arange(len(o.image_points)), o.image_points,
                                      o.object_points) for o in data.observations], lens)
    posed = [replace(o, T_cam_target=p.T_cam_target, rms_px=p.rms_px)
             for o, p in zip(data.observations, poses)]
    bad = tuple(o for o in posed if o.rms_px > 2.0)
    return replace(data, intrinsics=lens, observations=tuple(o for o in posed
                                                             if o.rms_px <= 2.0),
                   **({"bad_fits": bad} if hasattr(data, "bad_fits") else {}),
                   rejected=tuple(RejectedItem(o.name, f"bad fit: reprojection RMS "
                                               f"{o.rms_px:.2f} px > 2 px") for o in bad))


def _corrupted(data, k):
    obs = list(data.observations)
    uv = obs[k].image_points.copy()
    uv[::2] += [2.0, -1.5]
    pose = refit_pose(obs[k].T_cam_target, obs[k].object_points, uv, data.intrinsics)
    obs[k] = replace(obs[k], image_points=uv, T_cam_target=pose.T_cam_target,
                     rms_px=pose.rms_px)
    return replace(data, observations=tuple(obs)), pose.rms_px


def _lens_error(est, true) -> float:
    grid = np.stack(np.meshgrid(np.linspace(-0.4, 0.4, 9), np.linspace(-0.3, 0.3, 7)),
                    axis=-1).reshape(-1, 2)
    rays = np.column_stack([grid, np.ones(len(grid))])
    return float(np.max(np.linalg.norm(project_points(rays, est) - project_points(rays, true),
                                       axis=1)))


def _taken_back(warnings, camera: str) -> int:
    """How many images the camera's warning says were taken back (0 without one)."""
    for w in warnings:
        m = re.match(rf"{camera}: (\d+) image\(s\) left out as a bad fit on the starting "
                     "lens taken back", w)
        if m:
            return int(m.group(1))
    return 0


def _row(case, seed, run, truth, extra=""):
    cam = next(c for c in run.record.cameras if c.name == "cam1")
    taken = _taken_back(run.record.warnings, "cam1")
    out = [r.item for r in cam.rejected if r.reason.startswith("outlier of the joint")]
    bad = sum(r.reason.startswith("bad fit") for r in cam.rejected)
    T = truth.T_ref_cam[1]
    e_r = np.degrees(g.rotation_angle_between(cam.T_ref_cam, T))
    e_t = g.translation_distance(cam.T_ref_cam, T) * 1e3
    print(f"| {case} | {seed} | {cam.measurements_used} | {bad} | {taken} | "
          f"{', '.join(out) or '-'} | {e_r:.4f} | {e_t:.3f} | "
          f"{_lens_error(run.cameras['cam1'].intrinsics, truth.intrinsics[1]):.3f} |{extra}")


def rendered(seeds: int) -> None:
    print("| case | seed | cam1 images used | left out as bad fit | taken back | left out as "
          "outlier | T_ref_cam error deg | mm | lens error px (largest) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for seed in range(seeds):
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp) / "ds"
            truth = render_dataset(folder, DatasetSpec(n_cameras=2, images_per_camera=20,
                                                       width=640, height=480, processes=1),
                                   seed=seed)
            text = re.sub(r"intrinsics: (cam\d)\.yaml", "model: pinhole-radtan4",
                          (folder / "rig.yaml").read_text())
            (folder / "rig_model.yaml").write_text(text)
            rig = load_rig(folder / "rig_model.yaml")
            cams = load_camera_data(rig, processes=1)
        _row("clean", seed, calibrate_rig(rig, cams), truth)
        d = cams["cam1"]
        lens = d.intrinsics.with_params(d.intrinsics.params
                                        + np.r_[0, 0, 0, 0, 1.0, np.zeros(3)])
        started = _started_on(d, lens)
        _row("start", seed, calibrate_rig(rig, {**cams, "cam1": started}, robust=False),
             truth)
        bad, rms = _corrupted(d, 5)
        _row("corrupt", seed, calibrate_rig(rig, {**cams, "cam1": bad}), truth,
             f" corrupted {d.observations[5].name}: PnP {rms:.2f} px")


def _boofcv_cameras(shared: Path, model: str):
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "set"
        (out / "images").mkdir(parents=True)
        for k in range(1, 27):
            os.symlink(shared / "boofcv_fisheye" / f"{k}.jpg", out / "images" / f"{k}.jpg")
        (out / "rig.yaml").write_text(
            "target: {type: chessboard, rows: 6, cols: 4, spacing: 1.0}\n"
            f"cameras:\n  fish: {{model: {model}, images: images/}}\n")
        rig = load_rig(out / "rig.yaml")
        return rig, load_camera_data(rig, processes=1)


#: The starts of ``boofcv``'s cases: (parameter index, added value), per model.
STARTS = {"fisheye": ((4, 0.02), (4, 0.05), (5, 0.02), (0, 10.0)),
          "unified": ((4, 0.05), (0, 10.0))}


def boofcv(shared: Path) -> None:
    print("\n| model | start | left out as bad fit on the start | images used | rejected | "
          "taken back | left out as outlier | reprojection RMS px | lens params vs clean, "
          "largest abs |")
    print("|---|---|---|---|---|---|---|---|---|")
    for model, starts in STARTS.items():
        rig, cams = _boofcv_cameras(shared, model)
        d = cams["fish"]
        clean = calibrate_rig(rig, cams)
        ref = clean.cameras["fish"].intrinsics.params
        cases = [("as detected", cams)]
        for k, dk in starts:
            delta = np.zeros(ref.size)
            delta[k] = dk
            name = parameter_names(d.intrinsics)[k]
            cases.append((f"{name} + {dk:g}", {"fish": _started_on(
                d, d.intrinsics.with_params(d.intrinsics.params + delta))}))
        for label, cameras in cases:
            run = clean if label == "as detected" else calibrate_rig(rig, cameras)
            cam = run.record.cameras[0]
            early = sum(r.reason.startswith("bad fit") for r in cameras["fish"].rejected)
            outl = [r.item for r in cam.rejected if r.reason.startswith("outlier of the joint")]
            diff = np.max(np.abs(run.cameras["fish"].intrinsics.params - ref))
            print(f"| {model} | {label} | {early} | {cam.measurements_used} | "
                  f"{len(cam.rejected)} | {_taken_back(run.record.warnings, 'fish')} | "
                  f"{', '.join(outl) or '-'} | {cam.residuals.reprojection_rms_px:.4f} | "
                  f"{diff:.2g} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--skip", default="")
    args = ap.parse_args()
    skip = set(filter(None, args.skip.split(",")))
    if "rendered" not in skip:
        rendered(args.seeds)
    shared = Path(os.environ.get("MULTIEYE_SHARED_DATA", "../shared/data"))
    if "boofcv" not in skip:
        if (shared / "boofcv_fisheye").is_dir():
            boofcv(shared)
        else:
            print(f"boofcv_fisheye: not found under {shared} (set MULTIEYE_SHARED_DATA)")


if __name__ == "__main__":
    main()
