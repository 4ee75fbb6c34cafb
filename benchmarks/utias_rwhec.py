"""The real 8-camera / 16-tag UTIAS rig solved jointly, with a leave-one-pair-out check (issue 5).

Run from the repository root::

    PYTHONPATH=src python benchmarks/utias_rwhec.py \\
        [--data ../shared/data/utias_rwhec] [--out docs/results/utias_rwhec.md]

Reads the A/B pose pairs of Wise et al. (2025) (``A_i X_tag = Y_cam B_i``, 73 tag-camera
pairs, 3230 rows; see the data set's PROVENANCE.md), solves all 8 cameras and 16 tags at once
with the general closed form and with the maximum-likelihood refinement (sigmas estimated,
Huber loss), and writes a Markdown report:

- per camera, the extrinsic relative to camera 0, ``T_cam0_cam = inv(Y_cam0) Y_cam``, as
  tx ty tz (m) and yaw pitch roll (deg), with its standard deviation (root of the trace of the
  rotation and translation blocks of its covariance, propagated from the refinement);
- per camera, the median loop residuals (rotation deg, translation cm) of its rows;
- leave one pair out: for every tag-camera pair, solve without that pair's rows and predict
  them; the held-out median translation residual of ``A_i X_tag - Y_cam B_i`` against the
  in-sample one, per pair and as the median over pairs.  Pairs whose removal leaves an
  unknown without measurements (or disconnects the graph) cannot be predicted and are listed.

The data carry no license: they are read in place, never copied.  Takes a few minutes
(73 refinements); shows progress on a terminal.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported: small matrices, shared machine

import argparse
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from multieye.core import geometry as g
from multieye.core.errors import CalibrationError
from multieye.solvers.general import GeneralSolution, MeasurementGroup, solve_general
from multieye.io.atomic import write_text_atomic
from multieye.io.utias import read_utias_rwhec
from multieye.core.metrics import loop_residuals, pose_row
from multieye.solvers.refine_poses import relative_pose_covariance

REPO = Path(__file__).resolve().parents[1]
COMMAND = ("PYTHONPATH=src python benchmarks/utias_rwhec.py "
           "--data ../shared/data/utias_rwhec --out docs/results/utias_rwhec.md")
TARGET_HELD_OUT_M = 0.04
TARGET_RATIO = 1.5


@dataclass(frozen=True)
class HeldOut:
    """One pair of the leave-one-pair-out check (translation medians in metres)."""

    x_name: str
    y_name: str
    n: int
    in_closed: float
    in_refined: float
    out_closed: float | None = None
    out_refined: float | None = None
    reason: str = ""


def _residuals(gr: MeasurementGroup, sol: GeneralSolution) -> tuple[np.ndarray, np.ndarray]:
    return loop_residuals(gr.A, gr.B, sol.X[gr.x_name], sol.Y[gr.y_name])


def _cam_key(name: str) -> int:
    return int(name[3:])


def leave_one_pair_out(groups: list[MeasurementGroup], closed: GeneralSolution,
                       refined: GeneralSolution) -> list[HeldOut]:
    rows = []
    bar = tqdm(groups, desc="leave one pair out", disable=not sys.stderr.isatty())
    for k, gr in enumerate(bar):
        base = HeldOut(gr.x_name, gr.y_name, len(gr.A),
                       float(np.median(_residuals(gr, closed)[1])),
                       float(np.median(_residuals(gr, refined)[1])))
        rest = groups[:k] + groups[k + 1:]
        alone = [name for name, names in ((gr.x_name, {r.x_name for r in rest}),
                                          (gr.y_name, {r.y_name for r in rest}))
                 if name not in names]
        if alone:
            rows.append(replace(base, reason=f"{' and '.join(alone)} seen only in this pair"))
            continue
        try:
            sol_c = solve_general(rest)
            sol_r = solve_general(rest, refine=True)
        except CalibrationError as exc:
            rows.append(replace(base, reason=f"{type(exc).__name__}: {exc}"))
            continue
        rows.append(replace(base, out_closed=float(np.median(_residuals(gr, sol_c)[1])),
                            out_refined=float(np.median(_residuals(gr, sol_r)[1]))))
    return rows


def camera_table(groups, closed: GeneralSolution, refined: GeneralSolution) -> list[str]:
    cams = sorted(refined.Y, key=_cam_key)
    ref = cams[0]
    k_ref = refined.unknowns.index(("Y", ref))
    lines = [f"| camera | tx (m) | ty (m) | tz (m) | yaw (deg) | pitch (deg) | roll (deg) | "
             f"std rot (deg) | std trans (m) | closed form vs refined (deg / mm) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for cam in cams:
        T = g.inv(refined.Y[ref]) @ refined.Y[cam]
        T_closed = g.inv(closed.Y[ref]) @ closed.Y[cam]
        k = refined.unknowns.index(("Y", cam))
        idx = np.r_[6 * k_ref:6 * k_ref + 6, 6 * k:6 * k + 6]
        if cam == ref:
            std_rot = std_trans = 0.0
        else:
            cov = relative_pose_covariance(refined.Y[ref], refined.Y[cam],
                                           refined.covariance[np.ix_(idx, idx)])
            std_rot = float(np.degrees(np.sqrt(np.trace(cov[:3, :3]))))
            std_trans = float(np.sqrt(np.trace(cov[3:, 3:])))
        p = pose_row(T)
        d_rot = np.degrees(g.rotation_angle_between(T, T_closed))
        d_trans = 1000 * g.translation_distance(T, T_closed)
        lines.append(f"| {cam} | {p[0]:.4f} | {p[1]:.4f} | {p[2]:.4f} | {p[3]:.2f} | "
                     f"{p[4]:.2f} | {p[5]:.2f} | {std_rot:.3f} | {std_trans:.4f} | "
                     f"{d_rot:.2f} / {d_trans:.1f} |")
    return lines


def residual_table(groups, closed: GeneralSolution, refined: GeneralSolution) -> list[str]:
    lines = ["| camera | pairs | rows | closed: median rot (deg) | closed: median trans (cm) | "
             "refined: median rot (deg) | refined: median trans (cm) |",
             "|---|---|---|---|---|---|---|"]
    for cam in sorted(refined.Y, key=_cam_key):
        mine = [gr for gr in groups if gr.y_name == cam]
        cells = []
        for sol in (closed, refined):
            rot, trans = (np.concatenate(a) for a in zip(*(_residuals(gr, sol) for gr in mine)))
            cells += [f"{np.median(rot):.2f}", f"{100 * np.median(trans):.2f}"]
        lines.append(f"| {cam} | {len(mine)} | {sum(len(gr.A) for gr in mine)} | "
                     + " | ".join(cells) + " |")
    return lines


def report(groups, closed, refined, held: list[HeldOut], seconds: float) -> str:
    medians = {}
    for kind, sol in (("closed", closed), ("refined", refined)):
        rot, trans = (np.concatenate(a) for a in zip(*(_residuals(gr, sol) for gr in groups)))
        medians[kind] = (float(np.median(rot)), float(np.median(trans)))
    ok = [h for h in held if h.out_closed is not None]
    lost = [h for h in held if h.out_closed is None]
    summary = {}
    for kind in ("closed", "refined"):
        out = float(np.median([getattr(h, f"out_{kind}") for h in ok]))
        ins = float(np.median([getattr(h, f"in_{kind}") for h in ok]))
        summary[kind] = (out, ins, out / ins)
    out_r, _, ratio_r = summary["refined"]
    met = out_r <= TARGET_HELD_OUT_M and ratio_r <= TARGET_RATIO
    n_rows = sum(len(gr.A) for gr in groups)
    lines = [
        "# UTIAS 8-camera rig: all cameras and tags solved together",
        "",
        "Reproduce from the repository root (a few minutes):",
        "",
        "```",
        COMMAND,
        "```",
        "",
        f"Data: Wise et al. (2025), certifiable-rwhe-calibration, `data/real-world/combined`: "
        f"{len(groups)} tag-camera pairs, {n_rows} rows, {len(refined.Y)} cameras, "
        f"{len(refined.X)} tags, `A_i X_tag = Y_cam B_i` (read in place from "
        "`../shared/data/utias_rwhec`; no license, not copied here).  The source does not name "
        "the frames; following the data set's PROVENANCE.md, `Y_cam` is taken as the rig-to-"
        "camera extrinsic, so the extrinsic of a camera relative to camera 0 is "
        "`T_cam0_cam = inv(Y_cam0) Y_cam`.  No ground truth exists for these data.",
        "",
        "Solvers: `multieye.solvers.general.solve_general` (closed form: one sparse Kronecker system "
        "over all 24 rotations, then one linear least squares over all translations) and "
        "`solve_general(..., refine=True)` (maximum-likelihood refinement of the rotation and "
        "translation pose residuals, Huber loss at 1.345 sigma, sigmas estimated from the "
        f"residuals: {np.degrees(refined.sigma_rot_rad):.3f} deg and "
        f"{100 * refined.sigma_trans_m:.2f} cm per component).",
        "",
        "## Summary",
        "",
        "| | closed form | refined |",
        "|---|---|---|",
        f"| median rotation residual, all rows (deg) | {medians['closed'][0]:.3f} | "
        f"{medians['refined'][0]:.3f} |",
        f"| median translation residual, all rows (cm) | {100 * medians['closed'][1]:.2f} | "
        f"{100 * medians['refined'][1]:.2f} |",
        f"| leave one pair out: median over pairs of the held-out median translation residual "
        f"(cm) | {100 * summary['closed'][0]:.2f} | {100 * summary['refined'][0]:.2f} |",
        f"| same pairs, median over pairs of the in-sample median (cm) | "
        f"{100 * summary['closed'][1]:.2f} | {100 * summary['refined'][1]:.2f} |",
        f"| held-out / in-sample | {summary['closed'][2]:.2f} | {summary['refined'][2]:.2f} |",
        "",
        f"Target of issue 5 (refined held-out median of medians at most "
        f"{100 * TARGET_HELD_OUT_M:.0f} cm and at most {TARGET_RATIO}x in-sample): "
        f"**{'met' if met else 'not met'}** ({100 * out_r:.2f} cm, {ratio_r:.2f}x).  "
        f"{len(ok)} of {len(held)} pairs could be predicted; "
        + (", ".join(f"{h.x_name}-{h.y_name} ({h.reason})" for h in lost) if lost else "none lost")
        + ".",
        "",
        "## Extrinsics relative to camera 0 (refined)",
        "",
        "Yaw, pitch, roll with `R = Rz(yaw) Ry(pitch) Rx(roll)`.  Standard deviations: root of "
        "the trace of the rotation (deg) and translation (m) blocks of the covariance of "
        "`T_cam0_cam`, propagated from the joint covariance of the refinement; they cover the "
        "measurement noise the residuals show, not model error.  The last column is the "
        "difference between the closed-form and the refined `T_cam0_cam`: several centimetres, "
        "ten times the standard deviations, which says how far the unweighted closed form "
        "(rotation first, translations given those rotations) is from the maximum-likelihood "
        "answer on these data; the refined solution fits the rows better both in sample and "
        "held out (tables below).",
        "",
        *camera_table(groups, closed, refined),
        "",
        "## Residuals per camera",
        "",
        "Median over the camera's rows of angle((R_Y R_B)^T (R_A R_X)) and "
        "||(R_A t_X + t_A) - (R_Y t_B + t_Y)|| (paper section V-A metrics).",
        "",
        *residual_table(groups, closed, refined),
        "",
        "## Leave one pair out, per pair",
        "",
        "Median translation residual (cm) of the pair's rows: in-sample from the solve on all "
        "pairs, held-out from the solve without the pair.",
        "",
        "| tag | camera | rows | in-sample closed | held-out closed | in-sample refined | "
        "held-out refined |",
        "|---|---|---|---|---|---|---|",
    ]
    for h in held:
        if h.out_closed is None:
            out_c = out_r_ = f"not predictable: {h.reason}"
        else:
            out_c, out_r_ = f"{100 * h.out_closed:.2f}", f"{100 * h.out_refined:.2f}"
        lines.append(f"| {h.x_name} | {h.y_name} | {h.n} | {100 * h.in_closed:.2f} | {out_c} | "
                     f"{100 * h.in_refined:.2f} | {out_r_} |")
    lines += ["", f"Run time: {seconds:.0f} s.", ""]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data" / "utias_rwhec")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "results" / "utias_rwhec.md")
    args = parser.parse_args()

    start = time.perf_counter()
    groups = read_utias_rwhec(args.data)
    closed = solve_general(groups)
    refined = solve_general(groups, refine=True)
    held = leave_one_pair_out(groups, closed, refined)
    text = report(groups, closed, refined, held, time.perf_counter() - start)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out, text)
    print(text.split("## Extrinsics")[0])
    print(f"written: {args.out}")


if __name__ == "__main__":
    main()
