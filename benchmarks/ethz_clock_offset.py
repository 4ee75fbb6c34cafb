"""Clock offsets and hand-eye results on the unsynchronised ETH Zurich hand-eye streams.

Reproduce from the repository root (about a minute)::

    PYTHONPATH=src python benchmarks/ethz_clock_offset.py \\
        --data ../shared/data/ethz_handeye --out docs/results/ethz_clock_offset.md

For every data set (robot arm; PrimeSense with Vicon, two runs; the three-camera "falcon"
platform with Vicon, runs 3-5) and camera stream it

1. estimates the clock offset with :func:`multieye.estimate.clock.estimate_offset` (eye-on-hand:
   the "hand" stream is ``T_world_body``, the camera stream gives ``T_cam_target``);
2. pairs every image with the motion-capture pose at its stamp plus the offset
   (:func:`multieye.estimate.pairing.pair_in_time`, SLERP between bracketing samples), leaves out gross
   outliers with :func:`multieye.estimate.consensus.consensus`, and solves ``A_i X = Y B_i`` with the
   closed form followed by the pose-level maximum-likelihood refinement
   (``multieye.solve(..., refine=True)``), all cameras of a platform jointly;
3. reports the offset, the residuals at that offset and without any offset, and the
   extrinsics ``T_body_cam`` with their standard deviations, as a Markdown file.

Frame directions follow ``PROVENANCE.md`` of the data: for the robot arm and PrimeSense
sets the rows are used as the source's README documents them (hand stream ``B_H`` =
``T_base_hand``, camera stream ``W_E`` = ``T_target_cam``); for the falcon sets the fit that
PROVENANCE.md found best (Vicon rows as ``T_world_body``, camera rows as ``T_cam_target``).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.estimate.clock import estimate_offset
from multieye.core.errors import CalibrationError
from multieye.io import read_tum
from multieye.io.atomic import write_text_atomic
from multieye.core.metrics import loop_residuals, pose_row
from multieye.estimate.pairing import pair_in_time
from multieye.estimate.consensus import consensus
from multieye.solvers import solve
from multieye.estimate.uncertainty import pose_std

ROOT = "datasets/unzipped"


@dataclass(frozen=True)
class Stream:
    """One camera stream of a data set and how its rows are read."""

    name: str
    file: str
    rows_are_T_target_cam: bool


@dataclass(frozen=True)
class DataSet:
    name: str
    hand_file: str
    cameras: tuple[Stream, ...]
    note: str


DATASETS = (
    DataSet("robot_arm", "robot_arm_w_color_camera_real/robot_arm/"
            "robot_arm_complete_bag_color_and_ir_base_link_sr300_hinge.csv",
            (Stream("sr300_ir", "robot_arm_w_color_camera_real/robot_arm/"
                    "robot_arm_complete_bag_color_and_ir_target_ir.csv", True),),
            "robot forward kinematics base_link -> sr300_hinge; SR300 infrared camera"),
    DataSet("prime_sense_1", "prime_sense_color_w_vicon_1/prime_sense_1/"
            "2017-04-09-18-13-10_vicon_prime_sense.csv",
            (Stream("rgb", "prime_sense_color_w_vicon_1/prime_sense_1/"
                    "2017-04-09-18-13-10_W_camera_rgb_image_raw.csv", True),),
            "Vicon markers on a PrimeSense; its RGB camera"),
    DataSet("prime_sense_2", "prime_sense_color_w_vicon_2/prime_sense_2/"
            "2017-04-09-18-14-38_vicon_prime_sense.csv",
            (Stream("rgb", "prime_sense_color_w_vicon_2/prime_sense_2/"
                    "2017-04-09-18-14-38_W_camera_rgb_image_raw.csv", True),),
            "same rig, second run"),
) + tuple(
    DataSet(f"{k}_falcon", f"{k}_falcon/{k}_falcon_merged-{stamp}_falcon_vicon.csv",
            tuple(Stream(f"W_{c}", f"{k}_falcon/{k}_falcon_merged-{stamp}_W_{c}.csv", False)
                  for c in "rde"),
            "Vicon on the falcon platform; three cameras (r, d, e; e is the fisheye)")
    for k, stamp in ((3, "2017-04-07-12-22-23"), (4, "2017-04-07-12-26-36"),
                     (5, "2017-04-07-12-36-38")))


def _fmt(v: float, digits: int = 1) -> str:
    return "n/a" if not np.isfinite(v) else f"{v:.{digits}f}"


def _pairs(hand, stamps, T_cam_target, offset: float, tolerance: float):
    """A = T_world_body at the images, B = T_target_cam."""
    p = pair_in_time(hand.stamps, hand.T, stamps, tolerance=tolerance, offset=offset)
    return p.T, g.inv(T_cam_target[p.index])


def process(data: Path, ds: DataSet, search: tuple[float, float]
            ) -> tuple[list[str], list[str], np.ndarray | None]:
    """Markdown of one data set, its rows of the summary table, and its solved X."""
    hand = read_tum(data / ROOT / ds.hand_file, duplicates="drop")
    hand_dt = float(np.median(np.diff(hand.stamps)))
    tolerance = 1.5 * hand_dt
    lines = [f"### {ds.name}", "",
             f"Hand stream `{Path(ds.hand_file).name}`: {len(hand)} poses, "
             f"{1 / hand_dt:.0f} Hz, {hand.stamps[-1] - hand.stamps[0]:.0f} s ({ds.note}).", "",
             "| camera | images | offset (ms) | std (ms) | coarse (ms) | correlation | "
             "paired | rejected | median rot / trans residual at offset (deg / mm) | "
             "same without offset |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    A_all, B_all, names, summary, notes = [], [], [], [], []
    for cam in ds.cameras:
        path = data / ROOT / cam.file
        try:
            E = read_tum(path, duplicates="drop")
        except CalibrationError as exc:
            lines.append(f"| {cam.name} | - | skipped: {exc} |||||||| ")
            continue
        P = g.inv(E.T) if cam.rows_are_T_target_cam else E.T
        try:
            off = estimate_offset(E.stamps, P, hand.stamps, hand.T, setup="eye-on-hand",
                                  search_s=search)
        except CalibrationError as exc:
            lines.append(f"| {cam.name} | {len(E)} | failed: {exc} |||||||| ")
            continue
        A, B = _pairs(hand, E.stamps, P, off.offset_s, tolerance)
        A0, B0 = _pairs(hand, E.stamps, P, 0.0, tolerance)
        res = []
        try:
            cons = consensus([A], [B], names=[cam.name])
            keep = cons.inliers[0]
            for a, b in ((A, B), (A0, B0)):
                sol = solve([a], [b], method="joint")
                rot, trans = loop_residuals(a, b, sol.X[0], sol.Y)
                res.append(f"{np.median(rot):.2f} / {1e3 * np.median(trans):.1f}")
            rejected = str(int((~keep).sum()))
            A_all.append(A[keep])
            B_all.append(B[keep])
            names.append(cam.name)
        except CalibrationError as exc:
            rejected = f"consensus failed: {exc}"
            res = ["-", "-"]
        if off.note:
            notes.append(f"- {cam.name}: {off.note}.")
        lines.append(f"| {cam.name} | {len(E)} | {1e3 * off.offset_s:.1f} | "
                     f"{_fmt(1e3 * off.std_s, 2)} | {1e3 * off.coarse_offset_s:.1f} | "
                     f"{off.score:.3f} | {len(A)} | {rejected} | {res[0]} | {res[1]} |")
        summary.append(f"| {ds.name} | {cam.name} | {1e3 * off.offset_s:.1f} +- "
                       f"{_fmt(1e3 * off.std_s, 2)} | {off.score:.2f} | {res[0]} | {res[1]} |")
    lines += ["", *notes, ""] if notes else [""]
    X = None
    if A_all:
        table, X = _extrinsics(A_all, B_all, names)
        lines += table
    return lines, summary, X


def _extrinsics(A, B, names) -> tuple[list[str], np.ndarray | None]:
    """Markdown table of the joint solution, and its X (m, 4, 4)."""
    try:
        sol = solve(A, B, method="joint", refine=True, names=names)
    except CalibrationError as exc:
        return [f"No joint solution: {exc}", ""], None
    out = ["Result, all cameras of the platform jointly (inliers, closed form then pose-level "
           "refinement; the std is the root of the trace of the rotation / translation "
           "covariance of `T_body_cam`):", "",
           "| camera | tx (m) | ty (m) | tz (m) | yaw (deg) | pitch (deg) | roll (deg) | "
           "std rot (deg) | std trans (mm) | median rot / trans residual (deg / mm) |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for j, name in enumerate(names):
        row = pose_row(sol.X[j])
        s_rot, s_t = pose_std(sol.covariance[6 * j:6 * j + 6, 6 * j:6 * j + 6])
        rot, trans = loop_residuals(A[j], B[j], sol.X[j], sol.Y)
        out.append(f"| {name} | " + " | ".join(f"{v:.4f}" for v in row[:3]) + " | "
                   + " | ".join(f"{v:.2f}" for v in row[3:]) + f" | {s_rot:.3f} | "
                   f"{1e3 * s_t:.2f} | {np.median(rot):.2f} / {1e3 * np.median(trans):.1f} |")
    return out + [""], sol.X


def direction_check(data: Path, ds: DataSet, search) -> list[str]:
    """Offset and loop residuals of each stream of ``ds`` for the four frame directions."""
    hand = read_tum(data / ROOT / ds.hand_file, duplicates="drop")
    out = [f"### Frame directions, {ds.name}", "",
           "Each stream with the hand rows and the camera rows taken as given or inverted "
           "(eye-on-hand); RMS loop residuals of the closed form at the estimated offset.", "",
           "| camera | hand rows | camera rows | offset (ms) | RMS rot (deg) | RMS trans (mm) |",
           "|---|---|---|---|---|---|"]
    for cam in ds.cameras:
        E = read_tum(data / ROOT / cam.file, duplicates="drop")
        for hand_inv in (False, True):
            for cam_inv in (False, True):
                H = g.inv(hand.T) if hand_inv else hand.T
                P = g.inv(E.T) if cam_inv else E.T
                off = estimate_offset(E.stamps, P, hand.stamps, H, setup="eye-on-hand",
                                      search_s=search)
                used = "**used**" if cam_inv == cam.rows_are_T_target_cam and not hand_inv else ""
                out.append(f"| {cam.name} | {'T_body_world' if hand_inv else 'T_world_body'} | "
                           f"{'T_target_cam' if cam_inv else 'T_cam_target'} {used} | "
                           f"{1e3 * off.offset_s:.1f} | {off.rot_rms_deg:.2f} | "
                           f"{1e3 * off.trans_rms_m:.1f} |")
    return out + [""]


HEADER = """# Clock offsets on the ETH Zurich hand-eye streams (unsynchronised, real)

Reproduce from the repository root (about a minute):

```
PYTHONPATH=src python benchmarks/ethz_clock_offset.py --data ../shared/data/ethz_handeye --out docs/results/ethz_clock_offset.md
```

Data: ethz-asl/hand_eye_calibration (BSD-3-Clause), the CSV pose streams of Furrer et al.,
"Evaluation of Combined Time-Offset Estimation and Hand-Eye Calibration on Robotic Datasets"
(FSR 2017), read in place from `../shared/data/ethz_handeye`.  Each set has a "hand" stream
(robot forward kinematics or Vicon) and camera-from-target streams, stamped by different
clocks at different rates.  These are eye-on-hand data: `A = T_world_body` (the hand
stream), `B = T_target_cam`, `X = T_body_cam`, `Y = T_world_target`.

Method (`multieye.estimate.clock.estimate_offset`): the mean angular speed over 0.5 s of the target
seen by the camera is correlated with that of the hand stream (both are independent of the
unknown `X` and `Y`), then the offset is refined by minimising the loop residuals of the
closed form with the hand poses interpolated (SLERP) at the image stamps plus the offset.
The offset is *hand (motion-capture) clock minus camera clock*: the image stamped `c` was
taken when the hand clock read `c + offset`.  The standard deviation comes from the
curvature of the residual profile and covers the pose noise only; residuals correlated in
time make it optimistic.  Gross outliers are left out by `multieye.estimate.consensus.consensus`
(5 deg / 5 cm) before solving.  No ground truth exists for these data: the evidence is the
drop in residuals against pairing without an offset, and the agreement between runs.

PROVENANCE.md of the data, which matched nearest stamps within 50 ms over a coarse search,
reported about -0.05 s (robot arm), about 0 s (PrimeSense) and +0.4 to +0.6 s (falcon); its
sign convention is not stated.
"""


READING = """Reading the results:

- Robot arm and PrimeSense (one camera each): small offsets (tens of milliseconds), found
  with a correlation near 0.98 and a standard deviation under 1 ms; the two PrimeSense runs
  of the same rig agree within a few milliseconds, and their `T_body_cam` differ by {ps}.
  At these slow motions the residuals drop only a little against pairing without an offset:
  the offset matters less here than the pose noise.
- Falcon: the offset is large (about half a second, the motion-capture clock ahead), and
  correcting it is what makes the data usable at all: the median residual of the depth
  camera `W_d` drops from several degrees and tens of centimetres without the offset to
  one or two degrees and a few centimetres with it.  Streams `W_r` and `W_e` keep
  residuals of several degrees at any offset (PROVENANCE.md found the same; for set 5 the
  last table below tries all four combinations of frame directions: the one used here has
  the smallest translation residuals, and its rotation residuals tie with inverting both
  streams), so consensus rejects most of their measurements and their offsets and
  extrinsics are not trustworthy; `W_e` in sets 3 and 4 has too few images to time.
  Offsets differ between runs (separate recordings) and, within a run, between `W_d` and
  `W_r` by more than their standard deviations, which are optimistic for streams this poor.
- 5_falcon `W_r` and `W_e`: the angular-speed peak (331 and 584 ms) misses the minimum of the
  loop residuals by about +75 and -130 ms.  From commit 96c56b3 to session 16 the fine
  step stopped at the end of its first interval (peak +-33 and +-66 ms) and reported 364.5
  and 517.8 ms with standard deviations of 5-10 ms, as if determined; it now widens the
  interval to half the 0.5 s baseline when the residuals still fall at its end, and says so
  (no standard deviation) when they fall all the way.  Both profiles have one smooth minimum
  (`PYTHONPATH=src python benchmarks/ethz_clock_profile.py --data
  ../shared/data/ethz_handeye W_r`: chi-square 3204 at 400 ms against 3289 at 360 ms, 3226
  at 380, 3217 at 420; `W_e`: lowest at 460 ms), and the offsets found (about 405 and
  455 ms) lie near `W_d`'s well-timed 418 ms.  For `W_r` the rotation residuals alone are
  lowest near 380 ms and the translation residuals near 460 ms: the stream's misfit, not the
  timing, limits it, so its offset is uncertain by tens of milliseconds, not the 5 ms of its
  curvature.
"""


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data/ethz_handeye"))
    parser.add_argument("--out", type=Path, default=Path("docs/results/ethz_clock_offset.md"))
    parser.add_argument("--search", type=float, nargs=2, default=(-1.0, 1.0),
                        metavar=("LOW", "HIGH"), help="offsets searched, seconds")
    args = parser.parse_args(argv)
    body, summary, X = [], [], {}
    for ds in DATASETS:
        lines, rows, X[ds.name] = process(args.data, ds, tuple(args.search))
        body += lines
        summary += rows
        print(f"{ds.name}: done")
    a, b = X["prime_sense_1"], X["prime_sense_2"]
    ps = ("(not solved)" if a is None or b is None else
          f"{1e3 * float(np.linalg.norm(a[0, :3, 3] - b[0, :3, 3])):.1f} mm and "
          f"{float(np.degrees(g.rotation_angle_between(a[0], b[0]))):.2f} degrees")
    table = ["## Summary", "",
             "| data set | camera | offset (ms) | correlation | median rot / trans residual "
             "at the offset (deg / mm) | without offset |", "|---|---|---|---|---|---|"]
    text = ([HEADER] + table + summary + ["", READING.format(ps=ps), "## Details per data set",
                                           ""] + body)
    text += direction_check(args.data, DATASETS[-1], tuple(args.search))
    write_text_atomic(args.out, "\n".join(text).rstrip() + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
