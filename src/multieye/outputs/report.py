"""``report.html``: a self-contained, printable page about one calibration.

:func:`write_report` reads ``OUT/calibration.json`` (and ``OUT/details.json`` when present,
:mod:`multieye.io.run_details`) and writes ``OUT/report.html`` plus the figures as PNG files in
``OUT/figures/`` for people who work from a terminal.  The page holds, in reading order (the
picture first, the numbers after):

1. a summary (setup, method, reference camera, images used and rejected, mean residuals) and
   the warnings;
2. the rig in 3D and from above (:func:`multieye.outputs.figures_rig.rig_pngs`), with the
   user's frame names and every camera's pose uncertainty drawn;
3. per camera, its worst images with the detected points and their residuals drawn on the
   pixels (:mod:`multieye.outputs.report_images`; when the run's image folders are known);
4. the extrinsics ``T_ref_cam`` as tx ty tz yaw pitch roll with their uncertainty and time
   offsets when the run computed them, and the residuals per camera;
5. per-camera residual histograms and residuals over time;
6. per camera, where the data was (:mod:`multieye.outputs.report_cameras`): the intrinsics
   with their standard deviations when estimated, the coverage of the sensor by the target
   points, the reprojection residuals over the image and by radius, every image's RMS with
   the worst named, and the projection's uncertainty over the image (one figure per camera,
   ``figures/camera_<name>.png``, :func:`multieye.outputs.figures.camera_png`);
7. the weak-motion diagnostics (``motion_diagnostics`` of ``calibration.json``, and the
   free-form ``diagnostics`` of ``details.json``);
8. the rejected images and measurements with their reasons.

The page reads on a phone as on a desktop: nothing is wider than the screen (figures take the
full width, tables become one block per row on narrow screens).
The page needs nothing else: figures are embedded as base64 PNG, the style is inline, there is
no JavaScript, and a Content-Security-Policy forbids loading anything from anywhere, so a
browser shows exactly what the file holds (and logs any attempt to load more as an error).
Without ``details.json`` the histograms, time plots and per-camera figures are left out with a
note, and the rig is drawn from ``T_ref_cam`` alone.

Synopsis
--------
>>> from multieye.outputs.report import write_report
>>> write_report("out")            # doctest: +SKIP
PosixPath('out/report.html')
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Mapping, Sequence
from html import escape
from pathlib import Path

import numpy as np

from multieye.core.errors import DatasetError
from multieye.io.atomic import (confined_to, make_folder, remove_file, write_bytes_atomic,
                                write_text_atomic)
from multieye.io.calibration_json import (SETUP_KEYS, CalibrationRecord, PoseUncertainty,
                                         read_calibration)
from multieye.io.run_details import RunDetails, read_run_details
from multieye.core.metrics import pose_row
from multieye.outputs.folder import claim_output
from multieye.outputs.summary import link_text, lens_sigmas, loop_headline, pose_sigmas, reprojection_rms_px
from multieye.outputs.html import figure as _figure
from multieye.outputs.html import num as _num
from multieye.outputs.html import table as _table
from multieye.outputs.report_images import THUMBNAIL, image_thumbnails, images_section
from multieye.outputs.rig_legend import linked_by
from multieye.outputs.report_cameras import (
    cameras_section,
    diagnostics_section,
)
from multieye.core.version import __version__

__all__ = ["FIGURES", "write_report", "write_report_from", "report_html", "load_details"]

#: File names of the figures in ``OUT/figures/``, in page order.
FIGURES = ("rig_3d.png", "rig_top.png", "residual_histograms.png", "residuals_over_time.png",
           "image_rms.png", "residuals_by_radius.png")

#: Figures that earlier versions wrote (removed by a new report).
_EARLIER_FIGURES = ("rig.png",)

#: Names of the per-camera figures (:func:`~multieye.outputs.report_cameras.camera_figure_names`).
_CAMERA_FIGURE = re.compile(r"camera_[A-Za-z0-9._-]+\.png")

#: The page may load nothing but its own inline style and data-URI images.
_CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'"

_STYLE = """
:root { --ink:#1d232a; --muted:#5b6570; --line:#d9dee3; --soft:#f4f6f8; --accent:#1f5f99;
        --warn-bg:#fff6e0; --warn-line:#e0a800; --ok-bg:#eaf6ec; --ok-line:#3c9a50; }
* { box-sizing: border-box; }
body { margin: 0; color: var(--ink); background: #fff;
       font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif; }
main { max-width: 1120px; margin: 0 auto; padding: 28px 32px 48px; overflow-wrap: anywhere; }
h1 { font-size: 26px; margin: 0 0 4px; }
h2 { font-size: 19px; margin: 36px 0 10px; padding-bottom: 4px; border-bottom: 2px solid var(--line); }
h3 { font-size: 15px; margin: 18px 0 6px; }
p { margin: 6px 0 10px; }
.sub { color: var(--muted); margin: 0 0 18px; }
.cards { display: grid; grid-template-columns: repeat(auto-fit, minmax(150px, 1fr)); gap: 10px;
         margin: 0 0 14px; }
.card { background: var(--soft); border: 1px solid var(--line); border-radius: 6px; padding: 8px 12px; }
.card .k { font-size: 12px; color: var(--muted); text-transform: uppercase; letter-spacing: .04em; }
.card .v { font-size: 20px; font-weight: 600; font-variant-numeric: tabular-nums; }
nav { font-size: 14px; color: var(--muted); margin: 8px 0 0; display: flex; flex-wrap: wrap;
      gap: 4px 16px; }
nav a { color: var(--accent); text-decoration: none; white-space: nowrap; }
.box { border-left: 4px solid; border-radius: 4px; padding: 8px 14px; margin: 10px 0; }
.box.warn { background: var(--warn-bg); border-color: var(--warn-line); }
.box.ok { background: var(--ok-bg); border-color: var(--ok-line); }
.box ul { margin: 4px 0; padding-left: 20px; }
.note { color: var(--muted); font-size: 13.5px; }
table { border-collapse: collapse; min-width: 60%; margin: 6px 0 8px; font-size: 13.5px; }
th, td { padding: 4px 12px; border-bottom: 1px solid var(--line); text-align: right;
         font-variant-numeric: tabular-nums; vertical-align: top; }
th { background: var(--soft); font-weight: 600; white-space: nowrap; }
th.l, td.l { text-align: left; }
th.group { text-align: center; border-bottom: 1px solid #b9c1c9; }
thead tr:first-child th { padding-bottom: 0; }
tbody tr:nth-child(even) td { background: #fafbfc; }
td.ref { font-weight: 600; }
td.bad { color: #b3261e; font-weight: 600; }
.wrap { overflow-x: auto; }
figure { margin: 10px 0 18px; min-width: 0; }
.pair { display: grid; grid-template-columns: repeat(auto-fit, minmax(min(100%, 420px), 1fr));
        gap: 0 16px; }
.thumbs { display: grid; grid-template-columns: repeat(auto-fill, minmax(min(100%, 300px), 1fr));
          gap: 0 12px; }
.thumbs figure { margin: 4px 0 10px; }
.thumbs figure img { width: 100%; }
figure img { display: block; max-width: 100%; height: auto; margin: 0 auto;
             border: 1px solid var(--line); border-radius: 4px; }
figcaption { color: var(--muted); font-size: 13.5px; margin-top: 6px; }
code { font-family: "DejaVu Sans Mono", Menlo, Consolas, monospace; font-size: 12.5px; }
details { margin: 8px 0; }
summary { cursor: pointer; color: var(--accent); }
pre.matrix { background: var(--soft); padding: 6px 10px; border-radius: 4px; font-size: 12px;
             overflow-x: auto; margin: 4px 0 10px; }
footer { margin-top: 36px; padding-top: 10px; border-top: 1px solid var(--line);
         color: var(--muted); font-size: 13px; }
@media (max-width: 640px) {
  main { padding: 14px 12px 32px; }
  h1 { font-size: 22px; }
  .cards { grid-template-columns: repeat(2, minmax(0, 1fr)); }
  .card .v { font-size: 17px; }
  figure img { width: 100%; }
  table { min-width: 0; width: 100%; }
  table, tbody, tr, td { display: block; }
  thead { display: none; }
  tbody tr { border: 1px solid var(--line); border-radius: 4px; margin: 0 0 8px; }
  tbody tr:nth-child(even) td { background: none; }
  td { display: flex; justify-content: space-between; gap: 12px; text-align: right;
       padding: 2px 8px; }
  td::before { content: attr(data-label); color: var(--muted); text-align: left; }
  td:first-child { background: var(--soft); font-weight: 600; }
  td.l { text-align: right; }
}
@media print {
  body { font-size: 10.5pt; }
  main { max-width: none; padding: 0; }
  nav { display: none; }
  h2 { break-after: avoid; }
  figure, table, .box { break-inside: avoid; }
  tbody tr:nth-child(even) td { background: none; }
}
"""


# --------------------------------------------------------------------------- sections


def _headline_cards(rec: CalibrationRecord) -> tuple[list[tuple[str, str]], str]:
    """The figures that say how good the result is, by setup (:func:`multieye.outputs.
    summary.headline`): the loop residual where motion capture links the cameras; else the
    reprojection RMS and each camera's sigma, with the pose residuals as a note below."""
    loop = [("mean rotation residual", f"{rec.residuals.e_R_deg:.3f}°"),
            ("mean translation residual", f"{rec.residuals.e_t_m * 1e3:.2f} mm")]
    if loop_headline(rec):
        return loop, ""
    rms = reprojection_rms_px(rec)
    cards = [("reprojection RMS", "-" if rms is None else f"{rms:.2f} px")]
    cards += [(f"σ {n}", f"{d:.3f}° / {m * 1e3:.2f} mm") for n, d, m in pose_sigmas(rec)]
    cards += [(f"σ lens {n}", f"{s:.2f} px") for n, s in lens_sigmas(rec)]
    note = ('<p class="note">Pose residuals, a diagnostic (each view\'s target pose against the '
            f"rig's; not the accuracy): mean rotation {escape(loop[0][1])}, translation "
            f"{escape(loop[1][1])}.</p>")
    return cards, note


def _summary(rec: CalibrationRecord, out: Path) -> str:
    used = sum(c.measurements_used for c in rec.cameras)
    rejected = sum(len(c.rejected) for c in rec.cameras)
    figures, diagnostic = _headline_cards(rec)
    cards = [("cameras", str(len(rec.cameras))), ("images used", str(used)),
             ("rejected", str(rejected)), *figures, ("warnings", str(len(rec.warnings)))]
    cards_html = "".join(f'<div class="card"><div class="k">{escape(k)}</div>'
                         f'<div class="v">{escape(v)}</div></div>' for k, v in cards)
    sub = (f"{escape(rec.setup)} setup &middot; method <b>{escape(rec.method)}</b> &middot; "
           f"reference camera <b>{escape(rec.reference_camera)}</b> &middot; folder "
           f"<code>{escape(str(out))}</code>")
    links = [("warnings", "Warnings"), ("rig", "Rig"), ("images", "Images"),
             ("extrinsics", "Extrinsics"), ("residuals", "Residuals"),
             ("histograms", "Histograms"), ("over-time", "Over time"), ("cameras", "Cameras"),
             ("diagnostics", "Diagnostics"), ("rejected", "Rejected")]
    nav = " ".join(f'<a href="#{a}">{t}</a>' for a, t in links)
    shared = (f'<p class="note">No motion capture: {escape(linked_by(rec))}.</p>'
              if not rec.mocap else
              f'<p class="note">Shared unknown <code>'
              f"{escape(rec.named_keys()[0])}</code>: translation "
              f"{_vector(pose_row(rec.Y)[:3], '.4f')} m, yaw pitch roll "
              f"{_vector(pose_row(rec.Y)[3:], '.3f')} deg.</p>")
    return (f"<header><h1>Calibration report</h1><p class=\"sub\">{sub}</p>"
            f'<div class="cards">{cards_html}</div>{diagnostic}{shared}<nav>{nav}</nav></header>')


def _vector(v, fmt: str) -> str:
    return "(" + ", ".join(format(float(x), fmt) for x in v) + ")"


def _warnings(rec: CalibrationRecord, notes: Sequence[str]) -> str:
    out = ['<section id="warnings"><h2>Warnings</h2>']
    if rec.warnings:
        items = "".join(f"<li>{escape(w)}</li>" for w in rec.warnings)
        out.append(f'<div class="box warn"><ul>{items}</ul></div>')
    else:
        out.append('<div class="box ok">The calibration raised no warnings.</div>')
    out.extend(f'<p class="note">{escape(n)}</p>' for n in notes)
    out.append("</section>")
    return "".join(out)


def _pose_table(rec: CalibrationRecord, poses, key: str, ref_mark: bool) -> str:
    """tx ty tz yaw pitch roll of one transform per camera, with its σ when computed."""
    cams = rec.cameras
    unc = [None if not c.uncertainty else c.uncertainty.get(key) for c in cams]
    if key == "T_ref_cam" and not any(unc):     # files of earlier versions: the flat keys
        unc = [None if c.std_rot_deg is None or c.covariance is None else
               PoseUncertainty(c.std_rot_deg, c.std_trans_m, c.covariance) for c in cams]
    offsets = any(c.time_offset_s is not None for c in cams)
    header = ["camera", "tx (m)", "ty (m)", "tz (m)", "yaw (deg)", "pitch (deg)", "roll (deg)"]
    header += ["σ rot (deg)", "σ trans (mm)"] if any(unc) else []
    header += ["time offset (ms)"] if offsets else []
    offset_std = any(c.time_offset_std_s is not None for c in cams)
    header += ["σ offset (ms)"] if offset_std else []
    rows, classes = [], []
    for c, T, u in zip(cams, poses, unc):
        p = pose_row(T)
        ref = ref_mark and c.name == rec.reference_camera
        row = [c.name + (" (ref)" if ref else ""),
               *(format(round(v, 4) + 0.0, ".4f") for v in p[:3]),
               *(format(round(v, 3) + 0.0, ".3f") for v in p[3:])]
        if any(unc):
            row += [_num(None if u is None else u.std_rot_deg, ".3f", 1.0),
                    _num(None if u is None else u.std_trans_m, ".2f", 1e3)]
        if offsets:
            row.append(_num(c.time_offset_s, ".1f", 1e3))
        if offset_std:
            row.append(_num(c.time_offset_std_s, ".2f", 1e3))
        rows.append(row)
        classes.append(["ref" if ref else ""] + [""] * (len(header) - 1))
    return _table(header, rows, classes=classes)


def _links(rec: CalibrationRecord) -> str:
    """What links each camera, when any shares views or is linked by the rig's motion."""
    if not any(c.links is not None and (c.links.overlap or c.links.motion)
               for c in rec.cameras):
        return ""
    rows = [[c.name, link_text(rec, c)] for c in rec.cameras if c.links is not None]
    return "<h3>What links each camera</h3>" + _table(["camera", "linked by"], rows)


def _extrinsics(rec: CalibrationRecord) -> str:
    """Every camera's X and the shared Y with their σ; T_ref_cam with several cameras."""
    if not rec.mocap:
        return _extrinsics_overlap(rec)
    y_key, x_key = SETUP_KEYS[rec.setup]
    y_name, x_name = rec.named_keys()
    several = len(rec.cameras) > 1
    parts = ['<section id="extrinsics"><h2>Extrinsics and uncertainty</h2>',
             f"<h3><code>{escape(x_name)}</code> of every camera</h3>",
             _pose_table(rec, [c.X for c in rec.cameras], x_key, several)]
    y_unc = None if not rec.uncertainty else rec.uncertainty.get(y_key)
    p = pose_row(rec.Y)
    y_text = (f"t = ({', '.join(format(v, '.4f') for v in p[:3])}) m, yaw pitch roll = "
              f"({', '.join(format(v, '.3f') for v in p[3:])}) deg")
    if y_unc is not None:
        y_text += (f", σ {y_unc.std_rot_deg:.3f} deg / {1e3 * y_unc.std_trans_m:.2f} mm")
    parts.append(f"<h3><code>{escape(y_name)}</code></h3><p>{escape(y_text)}</p>")
    if several:
        parts += [f"<h3><code>T_ref_cam</code>, relative to {escape(rec.reference_camera)}</h3>",
                  _pose_table(rec, [c.T_ref_cam for c in rec.cameras], "T_ref_cam", True)]
    renamed = ("" if (y_name, x_name) == (y_key, x_key) else
               f" (in calibration.json <code>{x_key}</code> and <code>{y_key}</code>, the "
               f"frames named {escape(', '.join(f'{r} = {n}' for r, n in rec.frames.items()))} "
               "by rig.yaml's <code>pose</code>)")
    note = (f"<code>{escape(x_name)}</code> and <code>{escape(y_name)}</code> as the setup "
            f"defines them (docs/conventions.md, section 2){renamed}; <code>T_ref_cam</code> is the pose of each camera "
            "in the reference camera's frame. Yaw, pitch, roll with R = Rz(yaw) Ry(pitch) "
            "Rx(roll). σ is the root of the trace of the rotation (or translation) covariance "
            "of that transform (left perturbation; with estimated intrinsics their "
            "uncertainty is included); absent when the refinement did not run.")
    matrices = "".join(
        f"<h3>{escape(c.name)}</h3><pre class=\"matrix\">{escape(_matrix_text(c.T_ref_cam))}</pre>"
        for c in rec.cameras)
    parts += [_links(rec), f'<p class="note">{note}</p>',
              f"<details><summary>T_ref_cam matrices</summary>{matrices}</details></section>"]
    return "".join(parts)


def _extrinsics_overlap(rec: CalibrationRecord) -> str:
    """A rig without motion capture: every camera's T_ref_cam with its σ, and its links."""
    matrices = "".join(
        f"<h3>{escape(c.name)}</h3><pre class=\"matrix\">{escape(_matrix_text(c.T_ref_cam))}</pre>"
        for c in rec.cameras)
    note = ("No motion capture: <code>T_ref_cam</code>, the pose of each camera in the "
            "reference camera's frame, is estimated with the lenses and one target pose per "
            "instant from the views the cameras share (docs/outputs.md, section 2). Yaw, "
            "pitch, roll with R = Rz(yaw) Ry(pitch) Rx(roll). σ is the root of the trace of "
            "the rotation (or translation) covariance (left perturbation; with estimated "
            "intrinsics their uncertainty is included).")
    return "".join([
        '<section id="extrinsics"><h2>Extrinsics and uncertainty</h2>',
        f"<h3><code>T_ref_cam</code>, relative to {escape(rec.reference_camera)}</h3>",
        _pose_table(rec, [c.T_ref_cam for c in rec.cameras], "T_ref_cam", True), _links(rec),
        f'<p class="note">{note}</p>',
        f"<details><summary>T_ref_cam matrices</summary>{matrices}</details></section>"])


def _matrix_text(T: np.ndarray) -> str:
    return "\n".join("  ".join(f"{v: .9f}" for v in row) for row in T)


def _residuals(rec: CalibrationRecord, details: RunDetails | None) -> str:
    stats = ["mean", "median", "max"] if details is not None else ["mean", "max"]
    header = ["camera", "used", "rejected", *stats, *stats, "RMS"]
    groups = [("", 3), ("rotation (deg)", len(stats)), ("translation (mm)", len(stats)),
              ("reprojection (px)", 1)]
    rows = []
    for c in rec.cameras:
        r = c.residuals
        rot = {"mean": r and r.e_R_deg, "max": r and r.max_R_deg}
        trans = {"mean": r and r.e_t_m, "max": r and r.max_t_m}
        if details is not None:
            d = details.camera(c.name)
            rot["median"], trans["median"] = np.median(d.rot_deg), np.median(d.trans_m)
        rows.append([c.name, str(c.measurements_used), str(len(c.rejected)),
                     *(_num(rot[k], ".4f") for k in stats),
                     *(_num(trans[k], ".3f", 1e3) for k in stats),
                     _num(r and r.reprojection_rms_px, ".3f")])
    return (f'<section id="residuals"><h2>Residuals per camera</h2>'
            f"{_table(header, rows, groups=groups)}"
            + ('<p class="note">Pose residuals over the used images: the angle and distance '
               "between each image's PnP pose of the target and the solution's "
               "(<code>inv(T_ref_cam) T_ref_target</code> of its instant); reprojection RMS "
               "of the target points in the solution.</p></section>" if not loop_headline(rec) else
               '<p class="note">Loop residuals of <code>A_i X = Y B_i</code> over the used '
               "images (paper section V-A): the angle of (R_Y R_B)<sup>T</sup> R_A R_X and the "
               "distance between the two sides' translations; reprojection RMS of the target "
               "points in the PnP of each image.</p></section>"))


def _rig(rec: CalibrationRecord, details: RunDetails | None, figures: Mapping[str, bytes],
         legend: Sequence[str]) -> str:
    world = (rec.frames or {}).get("world", "world")
    frame = (f"the motion capture's frame <code>{escape(world)}</code>" if details is not None
             and rec.mocap else "the reference camera's frame" + (
                 "" if details is not None else " (no <code>details.json</code>: cameras only)"))
    if details is not None and not rec.mocap and details.frame is not None:
        frame = f"the first board's frame <code>{escape(details.frame)}</code>"
        where = ("The rig moved before boards that stand still: the cameras are drawn at the "
                 "rig's pose of its middle instant, each board at its pose (estimated, or "
                 "given in rig.yaml); the dots and the grey line are described next.")
    elif details is not None and not rec.mocap:
        where = ("The cameras are drawn where the co-observations place them; the dots are the "
                 "target (its first corner) at every instant, the grey line joins them in "
                 "time.")
    elif details is not None and details.setup == "eye-on-hand":
        where = ("The cameras move with the body and are drawn at one body pose (the reference "
                 "camera's middle image); the target estimates from every image cluster around "
                 "the static target, their spread showing the residuals in space; the grey "
                 "line is the body's motion capture.")
    elif details is not None:
        where = ("The cameras are static; the dots are the target (its first corner) at every "
                 "used image, from the motion capture and the target's pose on the marker; the "
                 "grey line is the marker's motion capture during the images.")
    else:
        where = ""
    unc = "".join(f" {escape(line[0].upper() + line[1:])}." for line in legend)
    pics = "".join(
        _figure(figures[name], alt, cap, name) for name, alt, cap in (
            ("rig_3d.png", "the camera rig in 3D", "In perspective."),
            ("rig_top.png", "the camera rig seen from above", "From above.")))
    return ('<section id="rig"><h2>Rig</h2>'
            f'<div class="pair">{pics}</div><p class="note">Camera frustums in {frame}. '
            f"{where}{unc}</p></section>")


def _residual_figures(rec: CalibrationRecord, details: RunDetails | None,
                      figures: Mapping[str, bytes]) -> str:
    if details is None:
        missing = ('<p class="note">Per-image residuals are in <code>details.json</code>, which '
                   "this output folder does not have; rerun <code>multieye calibrate</code> to "
                   "get histograms and residuals over time.</p>")
        return (f'<section id="histograms"><h2>Residual histograms</h2>{missing}</section>'
                f'<section id="over-time"><h2>Residuals over time</h2>{missing}</section>')
    return "".join([
        '<section id="histograms"><h2>Residual histograms</h2>',
        _figure(figures["residual_histograms.png"], "residual histograms per camera",
                f"{'Loop' if loop_headline(rec) else 'Pose'} residuals of every used image, one row "
                "per camera; bins are shared "
                "down each column so that cameras compare at a glance. Solid line: "
                "median, dashed: mean.", "residual_histograms.png"),
        "</section>",
        '<section id="over-time"><h2>Residuals over time</h2>',
        _figure(figures["residuals_over_time.png"], "residuals over time per camera",
                "The same residuals against each camera's time (against the image's place in "
                "name order where the images carry no time, e.g. poses matched by name). "
                "Drifts point to a clock offset or a moving mount; red circles mark images "
                "above three times their camera's median.", "residuals_over_time.png"),
        "</section>"])


def _selection(details: RunDetails | None) -> str:
    """The image selection per camera (docs/recordings.md, section 1), when it chose."""
    rows = [[c.name, str(c.selection["seen"]), str(c.selection["kept"]),
             str(c.selection["budget"]), str(c.selection["without_mocap"]), c.selection["stage"]]
            for c in (details.cameras if details is not None else ()) if c.selection]
    if not rows:
        return ""
    return ("<h3>Image selection</h3><p>Cameras with more images than the budget keep the "
            "ones that add most to the calibration; the others are listed below as not "
            "selected.</p>" + _table(["camera", "images", "kept", "budget",
                                      "without motion capture", "chosen"], rows, left=1))


def _rejected(rec: CalibrationRecord, details: RunDetails | None = None) -> str:
    head = ('<section id="rejected"><h2>Rejected images and measurements</h2>'
            + _selection(details))
    items = [(c.name, r.item, r.reason) for c in rec.cameras for r in c.rejected]
    if not items:
        return f'{head}<div class="box ok">Every image was used.</div></section>'
    counts: dict[tuple[str, str], int] = {}
    for cam, _, reason in items:
        counts[(cam, reason)] = counts.get((cam, reason), 0) + 1
    summary = _table(["camera", "reason", "count"],
                     [[cam, reason, str(n)] for (cam, reason), n in counts.items()], left=2)
    full = _table(["camera", "image or measurement", "reason"], items, left=3)
    inline = len(items) <= 40
    listing = (f"<h3>All {len(items)}</h3>{full}" if inline else
               f"<details><summary>All {len(items)}</summary>{full}</details>")
    return f"{head}<h3>By reason</h3>{summary}{listing}</section>"


# --------------------------------------------------------------------------- assembly


def load_details(out_dir: str | os.PathLike,
                 rec: CalibrationRecord) -> tuple[RunDetails | None, list[str]]:
    """``OUT/details.json`` if present and consistent with ``rec``, and notes on why not.

    Details that cannot be read, or that belong to another run (other cameras, setup,
    reference, or image counts), are left out with a note rather than mixed in.
    """
    path = Path(out_dir) / "details.json"
    if not path.exists():
        return None, []
    try:
        details = read_run_details(path)
    except DatasetError as exc:
        return None, [f"details.json left out: {exc}"]
    names = [c.name for c in rec.cameras]
    problems = []
    if [c.name for c in details.cameras] != names:
        problems.append(f"cameras {', '.join(c.name for c in details.cameras)} instead of "
                        f"{', '.join(names)}")
    elif any(len(details.camera(c.name).names) != c.measurements_used for c in rec.cameras):
        problems.append("other image counts")
    if details.setup != rec.setup or details.reference_camera != rec.reference_camera:
        problems.append("another setup or reference camera")
    if problems:
        return None, [f"details.json left out: it belongs to another run ({'; '.join(problems)})"]
    return details, []


def report_html(rec: CalibrationRecord, details: RunDetails | None,
                figures: Mapping[str, bytes], *, out_dir: str | os.PathLike = ".",
                notes: Sequence[str] = (), thumbnails: Mapping | None = None,
                rig_legend: Sequence[str] = ()) -> str:
    """The report page as a string (see the module docstring).

    Parameters
    ----------
    rec : CalibrationRecord
    details : RunDetails or None
    figures : mapping of str to bytes
        PNG bytes by file name (:data:`FIGURES` and the cameras' figures,
        :func:`~multieye.outputs.report_cameras.camera_figure_names`; only the rig's
        without details).
    out_dir : path-like
        Shown in the header.
    notes : sequence of str
        Shown under the warnings (e.g. why ``details.json`` was left out).
    thumbnails : mapping, optional
        Camera name -> its drawn images
        (:func:`~multieye.outputs.report_images.image_thumbnails`).
    rig_legend : sequence of str
        What the marks of the rig pictures mean (:class:`~multieye.outputs.figures_rig.
        RigFigures`).
    """

    body = "".join([
        _summary(rec, Path(out_dir)), _warnings(rec, notes), _rig(rec, details, figures, rig_legend),
        images_section(rec, details, thumbnails or {}), _extrinsics(rec),
        _residuals(rec, details), _residual_figures(rec, details, figures),
        cameras_section(rec, details, figures), diagnostics_section(rec, details),
        _rejected(rec, details),
        f"<footer>Written by multieye {escape(__version__)} from <code>calibration.json</code>"
        + (" and <code>details.json</code>" if details is not None else "")
        + ". Frames: <code>T_a_b</code> maps coordinates in b to a; metres, degrees in tables."
        "</footer>",
    ])
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f'<meta http-equiv="Content-Security-Policy" content="{_CSP}">'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>multieye calibration report: {escape(Path(out_dir).name or str(out_dir))}"
            f"</title><style>{_STYLE}</style></head><body><main>{body}</main></body></html>\n")


def write_report(out_dir: str | os.PathLike, *, shown_as: str | os.PathLike | None = None,
                 images: Mapping[str, str | os.PathLike] | None = None,
                 processes: int | None = None) -> Path:
    """Write ``OUT/report.html`` and ``OUT/figures/*`` from ``OUT/calibration.json``.

    Parameters
    ----------
    out_dir : path-like
        The output folder of ``multieye calibrate``.
    shown_as : path-like, optional
        The folder named on the page, when the report is built in a staging folder that is
        moved into place afterwards.
    images : mapping of str to path-like, optional
        Camera name -> the folder its images were read from
        (:func:`~multieye.outputs.report_images.image_folders` of the run); without it the
        report draws no image.
    processes : int, optional
        At most this many processes draw the figures
        (:func:`~multieye.outputs.report_draw.worker_count`; default: worker processes where
        two cores are available).

    Returns
    -------
    Path
        ``OUT/report.html``.

    Raises
    ------
    DatasetError
        ``calibration.json`` is missing or invalid, the folder is not writable, or another
        multieye run holds it (:func:`~multieye.outputs.folder.claim_output`).
    """
    from multieye.outputs.report_draw import figure_workers, submit_figures  # noqa: PLC0415 (heavy: the figure modules and OpenCV, only when figures are drawn)

    out = Path(out_dir)
    # held as a calibration holds it: refused while one runs, whose swap would remove the
    # report (issue 32); re-entrant, so a caller holding it already goes on
    with claim_output(out, replace=False):
        rec = read_calibration(out / "calibration.json")
        details, notes = load_details(out, rec)
        with figure_workers(processes) as workers:
            return write_report_from(out, rec, details, submit_figures(rec, details, workers),
                                     notes=notes, shown_as=shown_as, images=images)


def write_report_from(out_dir: str | os.PathLike, rec: CalibrationRecord,
                      details: RunDetails | None, figures: Callable, *,
                      notes: Sequence[str] = (), shown_as: str | os.PathLike | None = None,
                      images: Mapping[str, str | os.PathLike] | None = None, crops=None) -> Path:
    """:func:`write_report` of ``calibration.json`` and ``details.json`` as ``rec`` and
    ``details`` (what the files hold, not read back: :func:`multieye.outputs.write.
    write_outputs`), with ``figures`` the function that waits for the figures
    (:func:`~multieye.outputs.report_draw.submit_figures`).  The images with the detections
    are drawn here meanwhile (``crops``: :func:`~multieye.outputs.report_images.image_crops`)."""
    out = Path(out_dir)
    thumbnails = image_thumbnails(rec, details, images, crop=crops)
    figures_drawn, legend = figures()
    files_written = dict(figures_drawn)
    files_written.update({t.file: t.jpeg for thumbs in thumbnails.values() for t in thumbs})
    html = report_html(rec, details, figures_drawn, out_dir=Path(shown_as) if shown_as else out,
                       notes=notes, thumbnails=thumbnails, rig_legend=legend)
    with confined_to(out):      # never written or removed through a link (docs/outputs.md)
        folder = out / "figures"
        make_folder(folder)
        for name, data in files_written.items():
            write_bytes_atomic(folder / name, data)
        for entry in sorted(os.listdir(folder)):    # figures of an earlier report, not this one
            if entry not in files_written and (
                    entry in FIGURES or entry in _EARLIER_FIGURES
                    or _CAMERA_FIGURE.fullmatch(entry) or THUMBNAIL.fullmatch(entry)):
                remove_file(folder / entry)
        write_text_atomic(out / "report.html", html)
    return out / "report.html"
