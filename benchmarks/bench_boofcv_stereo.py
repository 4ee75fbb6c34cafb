"""BoofCV's Bumblebee2 stereo set as published, against BoofCV's own stereo calibration.

The set (../shared/data/boofcv_stereo, PROVENANCE.md there) keeps ``left01.jpg`` ...
``right11.jpg`` in one folder.  Each run rebuilds that folder (every file linked) with the
committed ``docs/results/boofcv_stereo/rig.yaml`` (``images: "left*.jpg"``, ``sync:
number``) and calibrates it with :func:`multieye.pipeline.calibrate`; the right camera's
``T_left_right`` is compared with BoofCV's ``rightToLeft``:

- the full set, with the committed lens model (``pinhole-radtan4``), with ``pinhole-radtan``
  (k3 too), and with BoofCV's own two-coefficient lenses held fixed (its ``stereo.yaml``);
- leave-one-out (11 runs) and leave-two-out (55 runs): the spread of the estimate over the
  data, jackknife standard errors (``sqrt((n-1)/n * sum (x_i - mean)^2)`` over the
  leave-one-out runs);
- the difference from BoofCV per axis: rotation (the rotation vector of ``R_ours R_boofcv^T``,
  degrees; left perturbation, as multieye's covariance) and translation (mm), divided by our
  predicted standard deviation (``T_ref_cam_covariance``) and by the jackknife's.

Run::

    python benchmarks/bench_boofcv_stereo.py [--data ../shared/data] [--out results.json]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from multieye.pipeline import calibrate

REPO = Path(__file__).resolve().parents[1]
RIG = REPO / "docs" / "results" / "boofcv_stereo" / "rig.yaml"
PAIRS = [f"{k:02d}" for k in range(1, 12)]


def boofcv_reference(data: Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """BoofCV's ``rightToLeft`` (R, t in metres) and its lenses, from ``stereo.yaml``."""
    ref = yaml.safe_load((data / "stereo.yaml").read_text())
    r2l = ref["rightToLeft"]
    R = np.array(r2l["rotation"], dtype=float).reshape(3, 3)
    t = np.array([r2l["x"], r2l["y"], r2l["z"]], dtype=float) / 1000.0
    return R, t, {side: ref[side] for side in ("left", "right")}


def layout(data: Path, folder: Path, pairs, rig_text: str) -> Path:
    """The published folder rebuilt in ``folder`` (images of ``pairs`` linked) with a rig."""
    folder.mkdir(parents=True)
    for k in pairs:
        for side in ("left", "right"):
            os.symlink(data / f"{side}{k}.jpg", folder / f"{side}{k}.jpg")
    (folder / "rig.yaml").write_text(rig_text)
    return folder


def boofcv_lens_rig(lenses: dict, folder: Path) -> str:
    """rig.yaml text holding BoofCV's lenses fixed (k1 k2, no tangential)."""
    cams = []
    for side, lens in lenses.items():
        p, rad = lens["pinhole"], lens["radial_tangential"]["radial"]
        (folder / f"{side}.yaml").write_text(yaml.safe_dump({
            "camera_matrix": {"rows": 3, "cols": 3, "data": [p["fx"], 0.0, p["cx"], 0.0,
                                                             p["fy"], p["cy"], 0.0, 0.0, 1.0]},
            "distortion_coefficients": [rad[0], rad[1], 0.0, 0.0]}))
        cams.append(f"  {side}: {{intrinsics: {side}.yaml, images: '{side}*.jpg'}}\n")
    head = "".join(line + "\n" for line in RIG.read_text().splitlines()
                   if not line.startswith(("cameras", "  ")))
    return head + "cameras:\n" + "".join(cams)


def run(folder: Path) -> dict:
    t0 = time.perf_counter()
    res = calibrate(folder, processes=1)
    T = res.T_ref_cam["right"]
    cov = res.T_ref_cam_covariance["right"]
    rms = {c.name: c.residuals.reprojection_rms_px for c in res.record.cameras}
    intr = {n: np.asarray(i.params).tolist() for n, i in res.intrinsics.items()}
    return {"T": T.tolist(), "cov": None if cov is None else np.asarray(cov).tolist(),
            "wall_s": time.perf_counter() - t0, "rms_px": rms, "intrinsics": intr}


def difference(T: np.ndarray, R_ref: np.ndarray, t_ref: np.ndarray) -> np.ndarray:
    """(rotation vector of R R_ref^T in degrees, t - t_ref in mm), shape (6,)."""
    rv = np.degrees(Rotation.from_matrix(T[:3, :3] @ R_ref.T).as_rotvec())
    return np.concatenate([rv, (T[:3, 3] - t_ref) * 1000.0])


def summarise(results: dict, R_ref, t_ref) -> dict:
    out = {}
    loo = np.array([difference(np.array(r["T"]), R_ref, t_ref) for r in results["loo"]])
    l2o = np.array([difference(np.array(r["T"]), R_ref, t_ref) for r in results["l2o"]])
    n = len(loo)
    jack = np.sqrt((n - 1) / n * ((loo - loo.mean(axis=0)) ** 2).sum(axis=0))
    out["jackknife_std"] = jack.tolist()
    out["loo_range"] = [loo.min(axis=0).tolist(), loo.max(axis=0).tolist()]
    out["l2o_range"] = [l2o.min(axis=0).tolist(), l2o.max(axis=0).tolist()]
    out["l2o_std"] = l2o.std(axis=0, ddof=1).tolist()
    for key in ("radtan4", "radtan", "boofcv_lenses"):
        r = results[key]
        T = np.array(r["T"])
        d = difference(T, R_ref, t_ref)
        sig = (np.concatenate([np.degrees(np.sqrt(np.diag(r["cov"])[:3])),
                               np.sqrt(np.diag(r["cov"])[3:]) * 1000]) if r["cov"] else None)
        out[key] = {
            "diff": d.tolist(), "rot_diff_deg": float(np.linalg.norm(d[:3])),
            "trans_diff_mm": float(np.linalg.norm(d[3:])),
            "baseline_mm": float(np.linalg.norm(T[:3, 3]) * 1000),
            "sigma": None if sig is None else sig.tolist(),
            "diff_over_sigma": None if sig is None else (d / sig).tolist(),
            "diff_over_jackknife": (d / jack).tolist(), "wall_s": r["wall_s"],
            "rms_px": r["rms_px"], "intrinsics": r["intrinsics"]}
        if r["cov"]:
            C = np.array(r["cov"])
            x = np.concatenate([np.radians(d[:3]), d[3:] / 1000])
            out[key]["mahalanobis_6dof"] = float(np.sqrt(x @ np.linalg.solve(C, x)))
    out["boofcv_baseline_mm"] = float(np.linalg.norm(t_ref) * 1000)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=Path(os.environ.get(
        "MULTIEYE_SHARED_DATA", REPO.parent / "shared" / "data")))
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--pairs-left-out", type=int, default=2, choices=(1, 2))
    args = ap.parse_args(argv)
    data = args.data / "boofcv_stereo"
    R_ref, t_ref, lenses = boofcv_reference(data)
    committed = RIG.read_text()
    results: dict = {"loo": [], "l2o": []}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        results["radtan4"] = run(layout(data, tmp / "full", PAIRS, committed))
        results["radtan"] = run(layout(data, tmp / "radtan", PAIRS,
                                       committed.replace("pinhole-radtan4", "pinhole-radtan")))
        folder = layout(data, tmp / "boofcv", PAIRS, "")
        (folder / "rig.yaml").write_text(boofcv_lens_rig(lenses, folder))
        results["boofcv_lenses"] = run(folder)
        for k in PAIRS:
            results["loo"].append(run(layout(data, tmp / f"loo{k}",
                                             [p for p in PAIRS if p != k], committed)))
        if args.pairs_left_out == 2:
            for a, b in itertools.combinations(PAIRS, 2):
                results["l2o"].append(run(layout(data, tmp / f"l2o{a}{b}",
                                                 [p for p in PAIRS if p not in (a, b)],
                                                 committed)))
        else:
            results["l2o"] = results["loo"]
    summary = summarise(results, R_ref, t_ref)
    text = json.dumps(summary, indent=1)
    print(text)
    if args.out is not None:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
