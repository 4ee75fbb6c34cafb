"""The lens doubt's thresholds against simulated cameras: detection and false-alarm rates.

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_lens_doubt.py [--seeds 3] [--mocap-seeds 2]
        [--views 12 100] [--groups overlap alone mocap] [--json OUT.json]

Every case is one camera whose given lens (the intrinsics file) is checked against its own
detections by the code the pipeline runs (:func:`multieye.estimate.lens_doubt.
given_lens_findings`, :func:`multieye.estimate.plausibility.check_plausibility`); a case is
*wrong* when the given lens lacks the distortion the pixels were made with (given as zeros,
or as a quarter or a half of the true k1, k2), *right* when it is the lens the pixels were
made with.  A wrong lens is *detected* when an ``intrinsics`` finding names the camera; a
right lens raises a *false alarm* when one does.  Corners are projected (0.1 px noise, wide
lenses 0.2 px), not rendered; PnP with the given lens gives the camera's target poses.

Groups:

- ``overlap``: a camera of a rig without motion capture; the rig's board poses in the
  reference camera (``A``) are the truth, or the truth with 0.05 deg / 0.5 mm of noise (the
  other cameras' PnP); 12 views.  Lenses: a narrow pinhole (fx 600 on 640 x 480, k1 -0.05 ..
  -0.4, k2 = 0.3 k1^2, boards 0.6-0.9 m away as in tests/estimate/test_lens_doubt.py), a wide
  pinhole (90 degrees on a 1024 square, k1 -0.05 .. -0.3) and a fisheye (Kannala-Brandt, 140
  degrees, k1 -0.2 .. 0.05: from k1 -0.4 on the model folds back inside the field) with
  boards spread over the field (:func:`multieye.sim.wide_lens.board_views`), each also
  without distortion; right only, the unified (190 deg), double-sphere (220) and eucm (190)
  lenses of :mod:`multieye.sim.wide_lens`; wrong, the unified lens with its radial-tangential
  part zero or a quarter.
- ``alone``: the same cameras as a rig of one camera (``alone=True``: the board poses are
  its own).
- ``mocap``: a camera and a motion capture (:func:`multieye.sim.images.simulate_stream`,
  eye-to-base, no camera pose noise besides the pixels'), the motion-capture noise stated
  at 0.03 deg / 0.1 mm, 0.1 deg / 0.3 mm, 0.1 deg / 1 mm (a robot) and 0.5 deg / 5 mm, with
  ``--views`` images; the narrow pinhole and a narrow fisheye (fx 230 on 640 x 480).

Printed: detection and false-alarm rates per group and lens; then, per threshold, the
statistic it is compared with on every case that reaches it: the right cases' largest and
the wrong cases' smallest value, how many fall on the wrong side, and the nearest case on
either side of the threshold (R right, W wrong) with its margin (value / threshold).

This is a script, not a test: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import json
import math
import time
from dataclasses import dataclass, replace

import numpy as np

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.estimate import hypotheses as h
from multieye.estimate import lens_doubt as ld
from multieye.estimate import lens_freed as lf
from multieye.estimate import plausibility as pl
from multieye.estimate.pairing import pair_in_time
from multieye.estimate.plausibility import CameraEvidence, check_plausibility
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import estimate_pose
from multieye.sim.images import simulate_stream
from multieye.sim.wide_lens import board_views, wide_lens

_NARROW = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])
_FISH_NARROW = np.array([[230.0, 0.0, 319.5], [0.0, 230.0, 239.5], [0.0, 0.0, 1.0]])
_SIDE = 1024
_T_REF_CAM = g.transform_from_rotvec([0.0, 0.6, 0.0], [-0.67, 0.0, 0.2])
#: Given lens = truth's k1, k2 times these (0: left out).
_SCALES = (0.0, 0.25, 0.5)
_MOCAP = {"0.03deg/0.1mm": (0.03, 0.1e-3), "0.1deg/0.3mm": (0.1, 0.3e-3),
          "0.1deg/1mm": (0.1, 1e-3), "0.5deg/5mm": (0.5, 5e-3)}
_RIG = {"exact": (0.0, 0.0), "0.05deg/0.5mm": (0.05, 0.5e-3)}


@dataclass(frozen=True)
class Lens:
    """A true lens family: its name, the lens of each k1 (None: the model's own shape)."""

    name: str
    model: str
    K: np.ndarray
    size: tuple[int, int]
    fov: float | None            # None: narrow, boards 0.6-0.9 m in front


def _lens(family: Lens, k1: float, scale: float = 1.0) -> Intrinsics:
    n = 5 if family.model == "pinhole" else 4
    dist = np.zeros(n)
    dist[:2] = scale * np.array([k1, 0.3 * k1 ** 2])
    return Intrinsics(K=family.K, dist=dist, model=family.model, width=family.size[0],
                      height=family.size[1])


def _square_K(f: float) -> np.ndarray:
    c = (_SIDE - 1) / 2.0
    return np.array([[f, 0.0, c], [0.0, f, c], [0.0, 0.0, 1.0]])


# 90 deg pinhole: 45 deg at 480 px; 140 deg fisheye: 70 deg at 480 px (equidistant)
_FAMILIES = {
    "pinhole-narrow": (Lens("pinhole-narrow", "pinhole", _NARROW, (640, 480), None),
                       (-0.05, -0.1, -0.17, -0.25, -0.4)),
    "pinhole-wide": (Lens("pinhole-wide", "pinhole", _square_K(480.0), (_SIDE, _SIDE), 90.0),
                     (-0.05, -0.1, -0.2, -0.3)),
    "fisheye-wide": (Lens("fisheye-wide", "fisheye", _square_K(480.0 / np.radians(70.0)),
                          (_SIDE, _SIDE), 140.0), (-0.05, -0.1, -0.2, 0.05)),
}
_MOCAP_FAMILIES = {
    "pinhole-narrow": _FAMILIES["pinhole-narrow"],
    "fisheye-narrow": (Lens("fisheye-narrow", "fisheye", _FISH_NARROW, (640, 480), None),
                       (-0.05, -0.1, -0.2, 0.05)),
}


def _narrow_board() -> np.ndarray:
    x, y = np.meshgrid(np.arange(9) * 0.05, np.arange(6) * 0.05)
    return np.stack([x.ravel() - 0.2, y.ravel() - 0.125, np.zeros(54)], axis=1)


def _views(truth: Intrinsics, fov: float | None, n: int, rng) -> tuple[list, np.ndarray]:
    """``n`` noisy views of a board by ``truth`` and their true poses T_cam_target."""
    if fov is not None:
        return board_views(truth, fov, n, rng)
    obj, views, poses = _narrow_board(), [], []
    for _ in range(n):
        T = g.transform_from_rotvec(rng.uniform(-0.4, 0.4, 3),
                                    [*rng.uniform(-0.15, 0.15, 2), rng.uniform(0.6, 0.9)])
        u = project_points(obj @ T[:3, :3].T + T[:3, 3], truth)
        views.append((obj, u + rng.normal(scale=0.1, size=u.shape)))
        poses.append(T)
    return views, np.stack(poses)


def _pnp(views, given: Intrinsics):
    est = [estimate_pose(Detection(np.arange(len(o)), u, o), given) for o, u in views]
    return (np.stack([e.T_cam_target for e in est]), np.array([e.rms_px for e in est]))


def _noisy(T: np.ndarray, sigma_deg: float, sigma_m: float, rng) -> np.ndarray:
    if sigma_deg == 0 and sigma_m == 0:
        return T
    d = [g.transform_from_rotvec(rng.normal(scale=np.radians(sigma_deg), size=3),
                                 rng.normal(scale=sigma_m, size=3)) for _ in range(len(T))]
    return np.stack(d) @ T


def _rig_camera(truth, given, fov, rig_sigma, seed, views=12) -> CameraEvidence:
    """A camera of a rig without motion capture (as tests/estimate/test_lens_doubt.py's)."""
    rng = np.random.default_rng(seed)
    vs, T = _views(truth, fov, views, rng)
    T_cam, rms = _pnp(vs, given)
    M = _noisy(_T_REF_CAM @ T, *rig_sigma, rng)
    return CameraEvidence("cam1", g.inv(M), g.inv(T_cam), M, intrinsics=given,
                          object_points=tuple(o for o, _ in vs),
                          image_points=tuple(u for _, u in vs), rms_px=rms)


def _mocap_camera(truth, given, mocap, views, seed) -> CameraEvidence:
    """A camera with motion capture of noise ``mocap`` (degrees, metres), ``views`` images
    over 20 s."""
    st = simulate_stream(seed, duration_s=20.0, camera_rate_hz=views / 20.0,
                         mocap_rate_hz=100.0, drop_fraction=0.0, cam_rot_sigma_rad=0.0,
                         cam_trans_sigma_m=0.0, mocap_rot_sigma_rad=np.radians(mocap[0]),
                         mocap_trans_sigma_m=mocap[1])
    rng = np.random.default_rng(1000 + seed)
    obj = _narrow_board()
    p = pair_in_time(st.mocap_stamps, st.T_world_mocap, st.cam_stamps, tolerance=0.02,
                     offset=st.time_offset_s)
    Ttrue = st.T_cam_target[p.index]
    vs = [(obj, project_points(obj @ T[:3, :3].T + T[:3, 3], truth)
           + rng.normal(scale=0.1, size=(len(obj), 2))) for T in Ttrue]
    T_cam, rms = _pnp(vs, given)
    return CameraEvidence("cam0", g.inv(p.T), g.inv(T_cam), p.T, stamps=st.cam_stamps[p.index],
                          mocap_stamps=st.mocap_stamps, mocap_T=st.T_world_mocap,
                          time_offset=st.time_offset_s, intrinsics=given,
                          object_points=tuple(o for o, _ in vs),
                          image_points=tuple(u for _, u in vs), rms_px=rms)


# --------------------------------------------------------------------------- one case


def _stats(test: lf.LensTest | None, radial: bool, cam: CameraEvidence) -> dict:
    """The statistics the thresholds are compared with."""
    out = {"path": "radial" if radial else "full", "rms_given_median": float(
        np.median(cam.rms_px)), "bare": lf.distortion_missing(cam.intrinsics)}
    if test is None:
        return {**out, "tested": False}
    ratio = test.rms_given_px / max(test.rms_freed_px, 1e-9)
    gains = [b / a for b, a in zip(test.loop_given, test.loop_freed)
             if a > 0 and np.isfinite(b)]
    return {**out, "tested": True, "ratio": ratio,
            "excess": math.sqrt(max(test.rms_given_px ** 2 - test.rms_freed_px ** 2, 0.0)),
            "pose_gain": min(gains) if len(gains) == 2 else math.nan,
            "cost_given": test.cost_given,
            "cost_gain": test.cost_given / max(test.cost_freed, 1e-12)}


def _run_rig(cam: CameraEvidence, alone: bool) -> dict:
    if alone:
        cam = replace(cam, A=cam.B.copy(), T_world_mocap=g.inv(cam.B))
    t0 = time.process_time()
    found = ld.given_lens_findings([cam], alone=alone)
    seconds = time.process_time() - t0
    close = float(np.median(cam.rms_px)) < ld.MIN_GIVEN_LENS_RMS_PX
    test = lf.lens_search(cam, h.MOCAP_NOISE, radial_only=close)
    if test is not None and alone:
        test = replace(test, loop_given=(math.nan, math.nan), loop_freed=(math.nan, math.nan))
    return {**_stats(test, close or lf.distortion_missing(cam.intrinsics), cam),
            "doubted": any(f.cause == "intrinsics" for f in found), "seconds": seconds}


def _run_mocap(cam: CameraEvidence, mocap) -> dict:
    sigma = (np.radians(mocap[0]), mocap[1])
    t0 = time.process_time()
    rep = check_plausibility([cam], clock=False, mocap_rot_sigma_rad=sigma[0],
                             mocap_trans_sigma_m=sigma[1])
    seconds = time.process_time() - t0
    bound = lf.lens_bound(cam, sigma)
    quiet = bound is not None and bound[0] < pl.MIN_LENS_EXCESS_PX and bound[1] < pl.POOR_COST
    test = lf.lens_search(cam, sigma, radial_only=quiet)
    out = _stats(test, quiet or lf.distortion_missing(cam.intrinsics), cam)
    return {**out, "bound_rms": bound[0], "bound_cost": bound[1],
            "doubted": any(f.cause == "intrinsics" for f in rep.findings),
            "others": sorted({f.cause for f in rep.findings} - {"intrinsics"}),
            "seconds": seconds}


# --------------------------------------------------------------------------- the cases


def _rig_cases(seeds: int):
    """(group, lens, k1, scale, noise, seed, truth, given, fov) of the overlap and alone
    groups."""
    for name, (fam, k1s) in _FAMILIES.items():
        for k1 in (0.0, *k1s):
            for scale in ((1.0,) if k1 == 0.0 else (1.0, *_SCALES)):
                for seed in range(seeds):
                    yield name, k1, scale, seed, _lens(fam, k1), _lens(fam, k1, scale), fam.fov
    for model, fov in (("unified", 190.0), ("double-sphere", 220.0), ("eucm", 190.0)):
        truth = wide_lens(model, fov)
        for scale in ((1.0, 0.0, 0.25) if model == "unified" else (1.0,)):
            dist = truth.dist.copy()
            dist[1:] *= scale
            for seed in range(seeds):
                yield (model, float(truth.dist[1]) if model == "unified" else math.nan, scale,
                       seed, truth, replace(truth, dist=dist), fov)


def run(args) -> list[dict]:
    rows = []

    def add(row, extra):
        row.update(extra)
        row["right"] = row["scale"] == 1.0
        rows.append(row)

    for name, k1, scale, seed, truth, given, fov in _rig_cases(args.seeds):
        for rig_name, rig_sigma in _RIG.items():
            cam = _rig_camera(truth, given, fov, rig_sigma, 100 * seed + 7)
            base = {"lens": name, "k1": k1, "scale": scale, "seed": seed, "views": 12}
            if "overlap" in args.groups:
                add({**base, "group": "overlap", "noise": rig_name}, _run_rig(cam, False))
            if "alone" in args.groups and rig_name == "exact" and name in _FAMILIES:
                add({**base, "group": "alone", "noise": "-"}, _run_rig(cam, True))
    if "mocap" in args.groups:
        for name, (fam, k1s) in _MOCAP_FAMILIES.items():
            for k1 in (0.0, *k1s):
                for scale in ((1.0,) if k1 == 0.0 else (1.0, *_SCALES)):
                    for noise, mocap in _MOCAP.items():
                        for views in args.views:
                            for seed in range(args.mocap_seeds):
                                cam = _mocap_camera(_lens(fam, k1), _lens(fam, k1, scale),
                                                    mocap, views, 50 + seed)
                                add({"group": "mocap", "lens": name, "k1": k1, "scale": scale,
                                     "seed": seed, "views": views, "noise": noise},
                                    _run_mocap(cam, mocap))
    return rows


# --------------------------------------------------------------------------- the tables


def _rates(rows: list[dict]) -> None:
    print("\nDetection (wrong lens named) and false alarms (right lens named), per case family")
    print(f"{'group':8} {'lens':15} {'given':14} {'cases':>5} {'named':>5}  rate   "
          "missed (k1 / noise / views)")
    keys = sorted({(r["group"], r["lens"], r["scale"]) for r in rows},
                  key=lambda k: (k[0], k[1], -k[2]))
    for grp, lens, scale in keys:
        sel = [r for r in rows if (r["group"], r["lens"], r["scale"]) == (grp, lens, scale)]
        named = sum(r["doubted"] for r in sel)
        given = "right" if scale == 1.0 else ("left out" if scale == 0 else f"x{scale} (weak)")
        wrong_side = [r for r in sel if r["doubted"] == r["right"]]
        what = sorted({(r["k1"], r["noise"], r["views"]) for r in wrong_side})
        shown = ", ".join(f"{k:g}/{n}/{v}" for k, n, v in what[:6])
        shown += f" +{len(what) - 6}" if len(what) > 6 else ""
        print(f"{grp:8} {lens:15} {given:14} {len(sel):5d} {named:5d}  {named / len(sel):4.2f}"
              f"   {shown if wrong_side else ''}")
    for grp in sorted({r["group"] for r in rows}):
        right = [r for r in rows if r["group"] == grp and r["right"]]
        wrong = [r for r in rows if r["group"] == grp and not r["right"]]
        print(f"{grp}: false alarms {sum(r['doubted'] for r in right)} / {len(right)} right "
              f"cameras; detected {sum(r['doubted'] for r in wrong)} / {len(wrong)} wrong "
              f"(left out: {sum(r['doubted'] for r in wrong if r['scale'] == 0)} / "
              f"{sum(r['scale'] == 0 for r in wrong)}); check CPU s per camera median "
              f"{np.median([r['seconds'] for r in rows if r['group'] == grp]):.3f}, "
              f"max {max(r['seconds'] for r in rows if r['group'] == grp):.3f}")


def _thresholds():
    """(name, value, statistic, which cases reach it)."""
    def radial(r):
        return r["tested"] and r["path"] == "radial"
    return [
        ("MIN_GIVEN_LENS_RMS_PX (path)", ld.MIN_GIVEN_LENS_RMS_PX, "rms_given_median",
         lambda r: r["group"] != "mocap"),
        ("LENS_PIXEL_GAIN (ratio)", ld.LENS_PIXEL_GAIN, "ratio", lambda r: r["tested"]),
        ("MIN_LENS_EXCESS_PX", ld.MIN_LENS_EXCESS_PX, "excess", lambda r: r["tested"]),
        ("BARE_LENS_PIXEL_GAIN", ld.BARE_LENS_PIXEL_GAIN, "ratio", radial),
        ("BARE_LENS_POSE_GAIN", ld.BARE_LENS_POSE_GAIN, "pose_gain",
         lambda r: radial(r) and r["group"] != "alone"),
        ("ALONE_PIXEL_GAIN", ld.ALONE_PIXEL_GAIN, "ratio",
         lambda r: r["tested"] and r["group"] == "alone" and r["bare"]),
        ("bare_doubt (LENS_PIXEL_GAIN)", ld.LENS_PIXEL_GAIN, "ratio",
         lambda r: r["tested"] and r["bare"] and r["group"] != "alone"),
        ("mocap: quiet bound rms (0.2)", pl.MIN_LENS_EXCESS_PX, "bound_rms",
         lambda r: r["group"] == "mocap"),
        ("mocap: quiet bound cost (POOR)", pl.POOR_COST, "bound_cost",
         lambda r: r["group"] == "mocap"),
        ("mocap: _LENS_LOOP_PIXEL_GAIN", pl._LENS_LOOP_PIXEL_GAIN, "ratio",
         lambda r: r["tested"] and r["group"] == "mocap"),
        ("mocap: POOR_COST (cost_given)", pl.POOR_COST, "cost_given",
         lambda r: r["tested"] and r["group"] == "mocap"),
        ("mocap: CONTINUOUS_GAIN (cost)", pl.CONTINUOUS_GAIN, "cost_gain",
         lambda r: r["tested"] and r["group"] == "mocap"),
    ]


def _label(r: dict) -> str:
    return (f"{'R' if r['right'] else 'W'} {r['group']} {r['lens']} k1 {r['k1']:g} "
            f"x{r['scale']:g} {r['noise']} {r['views']}v")


def _near(r: dict | None, stat: str, thr: float) -> str:
    return "-" if r is None else f"{r[stat]:.3g} ({r[stat] / thr:.2f}x) {_label(r)}"


def _margins(rows: list[dict]) -> None:
    print("\nPer threshold: the statistic on every case that reaches it (R right lens, W wrong)")
    print(f"{'threshold':31} {'value':>6} {'R n':>4} {'R max':>8} {'R>=':>4} {'W n':>4} "
          f"{'W min':>8} {'W<':>4}  nearest below / nearest at or above (value, margin)")
    for name, thr, stat, reach in _thresholds():
        sel = [r for r in rows if stat in r and reach(r) and np.isfinite(r[stat])]
        if not sel:
            continue
        right = [r[stat] for r in sel if r["right"]]
        wrong = [r[stat] for r in sel if not r["right"]]
        below = max((r for r in sel if r[stat] < thr), key=lambda r: r[stat], default=None)
        above = min((r for r in sel if r[stat] >= thr), key=lambda r: r[stat], default=None)
        print(f"{name:31} {thr:6.3g} {len(right):4d} "
              f"{max(right) if right else math.nan:8.3g} {sum(v >= thr for v in right):4d} "
              f"{len(wrong):4d} {min(wrong) if wrong else math.nan:8.3g} "
              f"{sum(v < thr for v in wrong):4d}  {_near(below, stat, thr)} / "
              f"{_near(above, stat, thr)}")


def _wrong_side(rows: list[dict]) -> None:
    bad = [r for r in rows if r["doubted"] == r["right"]]
    print(f"\nCases decided wrongly ({len(bad)}): statistics")
    for r in sorted(bad, key=_label):
        stats = " ".join(f"{k} {r[k]:.3g}" for k in ("rms_given_median", "ratio", "excess",
                                                     "pose_gain", "cost_given", "cost_gain")
                         if k in r and isinstance(r[k], float))
        others = f" (other findings: {', '.join(r['others'])})" if r.get("others") else ""
        print(f"  {_label(r)} seed {r['seed']} path {r['path']}: {stats}{others}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3, help="seeds per overlap / alone case")
    ap.add_argument("--mocap-seeds", type=int, default=2, help="seeds per mocap case")
    ap.add_argument("--views", type=int, nargs="+", default=[12, 100],
                    help="images per mocap camera")
    ap.add_argument("--groups", nargs="+", default=["overlap", "alone", "mocap"],
                    choices=["overlap", "alone", "mocap"])
    ap.add_argument("--json", help="write every case's statistics here")
    args = ap.parse_args()
    t0 = time.time()
    rows = run(args)
    _rates(rows)
    _margins(rows)
    _wrong_side(rows)
    print(f"\n{len(rows)} cases in {time.time() - t0:.0f} s")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1, default=float)


if __name__ == "__main__":
    main()
