"""Plain-text tables of a calibration, for the terminal.

A user must be able to judge a result from these numbers alone: measurements used and
rejected, loop residuals, reprojection RMS, the extrinsics as tx ty tz yaw pitch roll, their
uncertainty when known, and every warning.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np

from multieye.core.intrinsics import lens_model, parameter_names
from multieye.io import CalibrationRecord
from multieye.io.calibration_json import SETUP_KEYS
from multieye.io.run_details import TIMING_KEYS, StageTimings
from multieye.core.metrics import extrinsic_errors, pose_row
from multieye.pipeline.recordings import image_notes

__all__ = ["format_table", "calibration_table", "comparison_table", "timings_line",
           "check_table", "headline", "reprojection_rms_px", "pose_sigmas", "lens_sigmas",
           "loop_headline", "PIXEL_METHODS",
           "link_text"]


def timings_line(timings: StageTimings) -> str:
    """``done in 7.3 s (reading 0.1, detection 4.2, ..., outputs 1.5)``."""
    stages = ", ".join(f"{k.replace('_', ' ')} {getattr(timings, k):.1f}"
                       for k in TIMING_KEYS if k != "total")
    return f"done in {timings.total:.1f} s ({stages})"


def format_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """Columns right-aligned (the first left-aligned), separated by two spaces."""
    cols = list(zip(header, *rows))
    widths = [max(len(str(c)) for c in col) for col in cols]
    lines = []
    for r in [header, *rows]:
        cells = [str(c).ljust(w) if i == 0 else str(c).rjust(w)
                 for i, (c, w) in enumerate(zip(r, widths))]
        lines.append("  ".join(cells).rstrip())
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _f(x, fmt: str) -> str:
    return "-" if x is None else format(x, fmt)


def _pose_cells(T, unc) -> list[str]:
    p = pose_row(T)
    # round first and add 0.0: a rounding-size negative value prints 0.0000, not -0.0000
    return [*(format(round(v, 4) + 0.0, ".4f") for v in p[:3]),
            *(format(round(v, 3) + 0.0, ".3f") for v in p[3:]),
            _f(None if unc is None else unc.std_rot_deg, ".3f"),
            _f(None if unc is None else unc.std_trans_m * 1e3, ".2f")]


def _shown(key: str, name: str) -> str:
    """A transform under the user's frame names, with calibration.json's key when it differs."""
    return key if key == name else f"{name} (calibration.json: {key})"


def reprojection_rms_px(rec: CalibrationRecord) -> float | None:
    """The reprojection RMS over every camera's used images (each camera's RMS weighted by
    its images), pixels; None when no camera has one."""
    cams = [(c.measurements_used, c.residuals.reprojection_rms_px) for c in rec.cameras
            if c.residuals is not None and c.residuals.reprojection_rms_px is not None]
    n = sum(k for k, _ in cams)
    return None if not n else float(np.sqrt(sum(k * r * r for k, r in cams) / n))


#: Methods that solve the rig from the pixels (:mod:`multieye.pipeline.overlap_run`'s
#: ``METHOD`` and ``MOTION_METHOD``): their pose residuals compare each view's PnP pose with
#: the rig's, also when the rig's motion capture joins the problem (a rig linked by its
#: motion, with motion capture), so they are a diagnostic, not a hand-eye loop.
PIXEL_METHODS = ("covisibility", "motion-links")


def loop_headline(rec: CalibrationRecord) -> bool:
    """Whether the record's residuals are the loop residuals of ``A_i X = Y B_i`` (motion
    capture, solved by the hand-eye methods), the headline; else the reprojection RMS and
    each camera's sigma are (:func:`headline`)."""
    return bool(rec.mocap) and rec.method not in PIXEL_METHODS


def pose_sigmas(rec: CalibrationRecord) -> list[tuple[str, float, float]]:
    """``(camera, std deg, std m)`` of each camera's result where its uncertainty is known:
    ``T_ref_cam`` of every camera but the reference (whose pose is the identity); with
    motion capture, each camera's own unknown (``T_body_cam`` or ``T_world_cam``)."""
    key = SETUP_KEYS[rec.setup][1] if rec.mocap else "T_ref_cam"
    out = []
    for c in rec.cameras:
        unc = None if not c.uncertainty else c.uncertainty.get(key)
        if (rec.mocap or c.name != rec.reference_camera) and unc is not None:
            out.append((c.name, unc.std_rot_deg, unc.std_trans_m))
    return out


def lens_sigmas(rec: CalibrationRecord) -> list[tuple[str, float]]:
    """``(camera, px)``: the mean standard deviation of the projection of every estimated
    lens whose uncertainty is known."""
    return [(c.name, c.intrinsics.projection_std_px[0]) for c in rec.cameras
            if c.intrinsics is not None and c.intrinsics.estimated
            and c.intrinsics.projection_std_px is not None]


def link_text(rec: CalibrationRecord, cam) -> str:
    """What links camera ``cam`` (a :class:`~multieye.io.calibration_record.CameraRecord`
    with ``links``) to the rig: ``reference camera`` for the reference camera (its frame is
    the rig's), then anything it shares; else ``links.describe()``."""
    text = cam.links.describe()
    if cam.name != rec.reference_camera:
        return text
    return "reference camera" + ("" if text == "nothing" else f"; {text}")


def headline(rec: CalibrationRecord) -> list[str]:
    """The first lines of the summary: the figures that say how good the result is, by setup.

    Cameras linked by motion capture: the mean loop residual of ``A_i X = Y B_i`` (the hand-eye
    fit).  One camera, or cameras linked only by the views they share or by the rig's motion
    (with or without motion capture in the problem, :func:`loop_headline`): the reprojection
    RMS and each camera's sigma (its pose relative to the reference, its
    lens when estimated); the pose residuals there compare each view's target pose with the
    rig's, which the estimated lens and the board poses absorb, so they are a diagnostic on
    a line of their own below, not the accuracy.
    """
    head = f"{rec.setup}, method {rec.method}, reference {rec.reference_camera}: "
    loop = (f"mean e_R {rec.residuals.e_R_deg:.3f} deg, e_t {rec.residuals.e_t_m * 1e3:.2f} "
            "mm")
    if loop_headline(rec):
        return [head + "mean loop residual " + loop.removeprefix("mean ")]
    rms = reprojection_rms_px(rec)
    parts = ["reprojection RMS " + ("-" if rms is None else f"{rms:.2f} px")]
    poses = pose_sigmas(rec)
    if poses:
        key = rec.named_keys()[1] if rec.mocap else "T_ref_cam"
        parts.append(f"sigma of {key} " + ", ".join(
            f"{n} {d:.3f} deg / {m * 1e3:.2f} mm" for n, d, m in poses))
    lenses = lens_sigmas(rec)
    if lenses:
        parts.append("sigma of the projection " + ", ".join(f"{n} {s:.2f} px"
                                                           for n, s in lenses))
    return [head + "; ".join(parts),
            f"pose residuals (a diagnostic, not the accuracy): {loop}"]


def calibration_table(rec: CalibrationRecord) -> str:
    """Per-camera summary of a calibration, with the transforms people came for.

    After the :func:`headline`, every camera's own unknown ``X`` (``T_world_cam`` or ``T_body_cam``) as tx ty tz
    (metres) and yaw pitch roll (degrees, ``R = Rz(yaw) Ry(pitch) Rx(roll)``) with its
    standard deviations (root of the trace of its rotation and translation covariance) and
    the measurements used and rejected, mean loop residuals (degrees, millimetres; without
    motion capture the pose residuals, labelled so) and reprojection RMS (pixels); then the
    shared ``Y`` with its own; then, with several cameras, ``T_ref_cam`` relative to the
    reference camera; then estimated intrinsics with their standard deviations, rejected
    items and warnings.
    """
    if rec.mocap:
        y_key, x_key = SETUP_KEYS[rec.setup]
        y_name, x_name = rec.named_keys()
    else:                         # no motion capture: T_ref_cam is each camera's result
        y_key, x_key = None, "T_ref_cam"
        y_name, x_name = None, "T_ref_cam"
    pose_head = ["tx m", "ty m", "tz m", "yaw deg", "pitch deg", "roll deg", "std deg",
                 "std mm"]
    residual = "loop" if loop_headline(rec) else "pose"      # else a diagnostic
    header = ["camera", "used", "rejected", f"{residual} e_R deg", f"{residual} e_t mm",
              "reproj px", *pose_head, "offset ms", "offset std ms"]
    rows = []
    for c in rec.cameras:
        r = c.residuals
        unc = None if not c.uncertainty else c.uncertainty.get(x_key)
        rows.append([
            c.name + (" (ref)" if c.name == rec.reference_camera and len(rec.cameras) > 1
                      else ""),
            str(c.measurements_used), str(len(c.rejected)),
            _f(r.e_R_deg if r else None, ".3f"), _f(r.e_t_m * 1e3 if r else None, ".2f"),
            _f(r.reprojection_rms_px if r else None, ".2f"),
            *_pose_cells(c.T_ref_cam if c.X is None else c.X, unc),
            _f(None if c.time_offset_s is None else c.time_offset_s * 1e3, ".1f"),
            _f(None if c.time_offset_std_s is None else c.time_offset_std_s * 1e3, ".2f"),
        ])
    keep = [i for i in range(len(header)) if i < 12 or any(row[i] != "-" for row in rows)]
    lines = [*headline(rec), f"{_shown(x_key, x_name)} of every camera:",
             format_table([header[i] for i in keep], [[row[i] for i in keep] for row in rows])]
    if rec.mocap:
        y_unc = None if not rec.uncertainty else rec.uncertainty.get(y_key)
        y_row = _pose_cells(rec.Y, y_unc)
        lines.append(f"{_shown(y_key, y_name)}: t = ({', '.join(y_row[:3])}) m, yaw pitch "
                     f"roll = ({', '.join(y_row[3:6])}) deg"
                     + ("" if y_unc is None else f", std {y_row[6]} deg / {y_row[7]} mm"))
    if any(c.links is not None and (c.links.overlap or c.links.motion) for c in rec.cameras):
        lines += [f"{c.name} linked by: {link_text(rec, c)}" for c in rec.cameras
                  if c.links is not None]
    if len(rec.cameras) > 1 and rec.mocap:
        rel = [[c.name + (" (ref)" if c.name == rec.reference_camera else ""),
                *_pose_cells(c.T_ref_cam, None if not c.uncertainty
                             else c.uncertainty.get("T_ref_cam"))] for c in rec.cameras]
        keep = [i for i in range(9) if i < 7 or any(row[i] != "-" for row in rel)]
        lines += [f"T_ref_cam, relative to {rec.reference_camera}:",
                  format_table([(["camera"] + pose_head)[i] for i in keep],
                               [[row[i] for i in keep] for row in rel])]
    for c in rec.cameras:
        if c.intrinsics is not None and c.intrinsics.estimated:
            lines.append(_intrinsics_line(c))
    for c in rec.cameras:           # one line per cause (calibration.json lists each item)
        reasons = Counter(r.reason for r in c.rejected)
        once = {r.item for r in c.rejected if reasons[r.reason] == 1}
        lines.extend(f"rejected {c.name}{'/' if note.split(': ', 1)[0] in once else ': '}{note}"
                     for note in image_notes((r.item, r.reason) for r in c.rejected))
    lines.extend(f"warning: {w}" for w in rec.warnings)
    return "\n".join(lines)


def _intrinsics_line(c) -> str:
    ir = c.intrinsics
    names = parameter_names(ir.intrinsics)
    values = ir.intrinsics.params
    std = (np.sqrt(np.diag(ir.covariance)) if ir.covariance is not None
           else np.full(len(values), np.nan))
    cells = ", ".join(f"{n} {v:.4g}" + ("" if not np.isfinite(s) else f" +- {s:.2g}")
                      for n, v, s in zip(names, values, std))
    proj = ("" if ir.projection_std_px is None else
            f"; projection std {ir.projection_std_px[0]:.2f} px mean, "
            f"{ir.projection_std_px[1]:.2f} px max")
    return f"{c.name} intrinsics (estimated, {lens_model(ir.intrinsics)}): {cells}{proj}"


def comparison_table(results: dict[str, np.ndarray], truth: Mapping[str, np.ndarray]) -> str:
    """Errors of ``T_ref_cam`` against ground truth, one row per method and camera.

    Parameters
    ----------
    results : dict of str to ndarray, shape (m, 4, 4)
        ``T_ref_cam`` of every camera per method, in the order of ``truth``.
    truth : mapping of str to ndarray, shape (4, 4)
        The true ``T_ref_cam`` by camera name.
    """
    names = list(truth)
    truth = np.stack([truth[n] for n in names])
    header = ["method", *(f"{n} error deg / mm" for n in names[1:]), "mean error deg",
              "mean error mm", "max error deg", "max error mm"]
    rows = []
    for method, T in results.items():
        rot, trans = extrinsic_errors(T, truth)
        rot, trans = rot[1:], trans[1:] * 1e3
        rows.append([method, *(f"{a:.4f} / {b:.3f}" for a, b in zip(rot, trans)),
                     f"{rot.mean():.4f}", f"{trans.mean():.3f}", f"{rot.max():.4f}", f"{trans.max():.3f}"])
    return format_table(header, rows)


def check_table(check) -> str:
    """The dry run of :func:`multieye.pipeline.dry_run.check_dataset`: one row per camera
    (counts of images, the share with the target found, the rotation of the paired motion in
    degrees), then each camera's problems and the verdict."""
    header = ["camera", "source", "images", "sampled", "target found", "found %",
              "with mocap" if check.setup != "overlap" else "seen together",
              "usable in sample", "about usable", "rotation range deg", "RMS rot axes deg"]
    rows = []
    for c in check.cameras:
        spread = ("-" if c.rotation_spread_deg is None
                  else " / ".join(f"{v:.1f}" for v in c.rotation_spread_deg))
        rows.append([c.name, c.source, str(c.listed), str(c.sampled), str(c.found),
                     f"{c.found_percent:.0f}" if c.sampled else "-", str(c.with_mocap),
                     str(c.paired), str(c.expected_usable),
                     _f(c.rotation_range_deg, ".1f"), spread])
    lines = [f"{check.setup}, {check.path}: dry run, nothing solved", format_table(header, rows)]
    for c in check.cameras:
        if c.failures:
            lines.append(f"{c.name}: sampled images without a target pose: " + ", ".join(
                f"{n} {kind}" for kind, n in c.failures))
        if len(getattr(c, "boards", ())) > 1:
            lines.append(f"{c.name}: boards found in the {c.sampled} sampled images: "
                         + ", ".join(f"{n} in {k}" for n, k in c.boards))
        lines.extend(f"problem: {c.name}: {p}" for p in c.problems)
    lines.extend(getattr(check, "links", ()))
    doubts = getattr(check, "doubts", ())
    lines.append("verdict: calibrating would fail: " + "; ".join(check.reasons) if not check.ok
                 else "verdict: calibrating may fail: " + "; ".join(doubts) if doubts
                 else "verdict: ok, calibrating can run")
    return "\n".join(lines)
