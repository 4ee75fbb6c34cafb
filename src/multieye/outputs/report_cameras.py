"""Sections of ``report.html`` about each camera's data: where it was, and how the motion was.

- :func:`cameras_section`: per camera, the intrinsics (with their standard deviations when
  estimated, "given" otherwise), the figure of :func:`multieye.outputs.figures.camera_png`
  (coverage over the sensor, residual vectors, projection uncertainty) and the worst images,
  after two figures of all cameras (every image's RMS, residuals by radius);
- :func:`diagnostics_section`: the weak-motion diagnostics of ``calibration.json``
  (``motion_diagnostics``), flagged where the calibration warns, and any free-form
  ``diagnostics`` of ``details.json``.

Synopsis
--------
>>> from multieye.outputs.report_cameras import camera_figure_names
>>> from multieye.io.calibration_record import CameraRecord
>>> camera_figure_names([CameraRecord(n, None, np.eye(4), 3) for n in ("cam0", "front left")])
{'cam0': 'camera_cam0.png', 'front left': 'camera_front_left.png'}
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from html import escape

import numpy as np

from multieye.core.intrinsics import Intrinsics, lens_model, parameter_names
from multieye.estimate.diagnostics import (
    MAX_CONDITION,
    MIN_AXIS_RATIO,
    MIN_ROTATION_RANGE_DEG,
    MIN_SECOND_AXIS_DEG,
)
from multieye.io.calibration_json import CalibrationRecord, CameraRecord
from multieye.io.run_details import CameraDetails, RunDetails
from multieye.outputs.html import figure, num, table, value_text
from multieye.outputs.image_stats import MAX_ARROWS, worst_images

__all__ = ["camera_figure_names", "cameras_section", "diagnostics_section", "intrinsics_table",
           "WORST_IMAGES", "ALL_CAMERA_FIGURES"]

#: Images listed per camera under "worst images".
WORST_IMAGES = 5


def camera_figure_names(cameras: Iterable[CameraRecord]) -> dict[str, str]:
    """File name in ``OUT/figures/`` of each camera's figure (by camera name):
    ``camera_<name>.png`` with characters other than letters, digits, ``.``, ``_`` and ``-``
    replaced by ``_`` (and a number added when two names become the same; at most 100
    characters of the name)."""
    out: dict[str, str] = {}
    for name in (c.name for c in cameras):
        base = "camera_" + re.sub(r"[^A-Za-z0-9._-]", "_", name[:100])
        stem, k = base, 2
        while f"{stem}.png" in out.values():
            stem, k = f"{base}_{k}", k + 1
        out[name] = f"{stem}.png"
    return out


def intrinsics_table(intr: Intrinsics, estimated: bool | None,
                     covariance: np.ndarray | None) -> str:
    """fx fy cx cy and the distortion, with their standard deviations when estimated
    (``estimated`` None: not known, from an older ``details.json``)."""
    def row(label, values, sigma=False):
        return [label, *(num(v, (".3f" if sigma else ".2f") if k < 4 else
                             ".5f" if v == 0 or not abs(v) < 1e-3 else ".3e")   # not 0.00000
                         for k, v in enumerate(values))]

    if covariance is not None:
        sigma = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
        rows = [row("estimated", intr.params), row("σ", sigma, True)]
    elif estimated:
        rows = [row("estimated (no covariance)", intr.params)]
    else:
        rows = [row("given" if estimated is False else "value", intr.params)]
    return table(["", *parameter_names(intr)], rows)


def _lens(rec_cam, cam: CameraDetails | None):
    """The camera's intrinsics, whether estimated, and their covariance: from details.json
    when it has them, else from calibration.json (None when neither has intrinsics)."""
    ir = getattr(rec_cam, "intrinsics", None)
    if cam is not None and cam.intrinsics is not None:
        estimated = cam.intrinsics_estimated
        if estimated is None and ir is not None:
            estimated = ir.estimated
        cov = cam.intrinsics_covariance
        return cam.intrinsics, estimated, cov if cov is not None or ir is None else ir.covariance
    if ir is not None:
        return ir.intrinsics, ir.estimated, ir.covariance
    return None


def _lens_note(rec_cam, cam: CameraDetails | None, intr: Intrinsics, estimated, cov) -> str:
    size = (f"{intr.width} x {intr.height} px" if intr.width and intr.height
            else "image size not given")
    if cov is not None:
        how = ("estimated by the joint refinement with the rig; σ: standard deviations from "
               "its covariance (measurement noise only)")
        at_points = getattr(getattr(rec_cam, "intrinsics", None), "projection_std_px", None)
        if cam is not None and cam.projection_std is not None:
            how += (f". Standard deviation of the projection over the image: mean "
                    f"{cam.projection_std.mean_px:.3g} px, max {cam.projection_std.max_px:.3g} px")
            if at_points is not None:
                how += (f"; at the observed target points: mean {at_points[0]:.3g} px, max "
                        f"{at_points[1]:.3g} px")
        elif at_points is not None:
            how += (f". Standard deviation of the projection at the observed target points: "
                    f"mean {at_points[0]:.3g} px, max {at_points[1]:.3g} px")
    elif estimated:
        how = ("estimated by OpenCV's calibration of this camera's views alone (the joint "
               "refinement did not run): no uncertainty")
    elif estimated is False:
        how = "given in rig.yaml and held fixed"
    else:
        how = "as used by the run (details.json does not say whether given or estimated)"
    return f"Lens {escape(lens_model(intr))}, {escape(size)}; {escape(how)}."


def _camera_block(rec_cam, cam: CameraDetails | None, png: bytes | None, name: str) -> str:
    out = [f'<h3 id="camera-{escape(re.sub(r"[^A-Za-z0-9_-]", "-", rec_cam.name))}">'
           f"{escape(rec_cam.name)}</h3>"]
    lens = _lens(rec_cam, cam)
    if lens is None:
        out.append('<p class="note">Given by precomputed target poses: no intrinsics and no '
                   "target points.</p>")
        return "".join(out)
    out.append(f'<p class="note">{_lens_note(rec_cam, cam, *lens)}</p>{intrinsics_table(*lens)}')
    if png is None or cam is None or cam.points is None:
        why = ("this output folder has no <code>details.json</code>" if cam is None else
               "<code>details.json</code> holds none (a camera given by poses, or a file of "
               "an earlier version)")
        out.append(f'<p class="note">No target points: {why}; rerun <code>multieye '
                   "calibrate</code> for the coverage and the residuals over the image.</p>")
        return "".join(out)
    pts = cam.points
    source = ("the refined rig: the camera's final intrinsics and pose, the target and each "
              "image's refined motion-capture pose" if pts.source == "refined"
              else "each image's PnP pose")
    sub = ("" if pts.kept == pts.n_points else
           f" {pts.kept} of the {pts.n_points} points are drawn (evenly subsampled).")
    caption = (
        f"Where {escape(cam.name)} saw the target. Left: the detected target points on the "
        "image (+: principal point; shaded: cells of a 4 x 4 grid without any point) and "
        f"their residuals (projection by {source} minus detection) as magnified vectors, one "
        f"per point or, above {MAX_ARROWS} points, their mean in each cell of a 16-column "
        "grid. Right: "
        + ("the standard deviation of the projection of a fixed camera-frame ray from the "
           "intrinsics' covariance, √(tr(J Σ Jᵀ)/2) with J the derivative of the pixel by "
           "the intrinsics (white: outside the lens model's invertible range)"
           if cam.projection_std is not None else "the RMS residual in cells of the image")
        + f".{sub}")
    out.append(figure(png, f"target coverage and residuals of {cam.name}", caption, name))
    worst = worst_images(cam, WORST_IMAGES)
    if worst:
        index = {n: i for i, n in enumerate(cam.names)}
        rows = [[n, num(v, ".3f"), num(cam.rms_px[index[n]], ".3f"),
                 num(cam.rot_deg[index[n]], ".4f"), num(cam.trans_m[index[n]], ".3f", 1e3)]
                for n, v in worst]
        out.append(f"<p class=\"note\">Worst images by reprojection RMS ({escape(pts.source)} "
                   "residuals), with their PnP RMS and loop residuals:</p>")
        out.append(table(["image", "RMS (px)", "PnP RMS (px)", "rotation (deg)",
                          "translation (mm)"], rows))
    return "".join(out)


#: Figures of the cameras section about every camera at once, in page order.
ALL_CAMERA_FIGURES = ("image_rms.png", "residuals_by_radius.png")


def cameras_section(rec: CalibrationRecord, details: RunDetails | None,
                    figures: Mapping[str, bytes]) -> str:
    """The per-camera section (module docstring); ``figures`` by file name
    (:data:`ALL_CAMERA_FIGURES` and :func:`camera_figure_names`)."""
    head = '<section id="cameras"><h2>Cameras: intrinsics and where the target was seen</h2>'
    together = ""
    if "image_rms.png" in figures:
        together += figure(figures["image_rms.png"], "reprojection RMS of every image",
                           "Every used image's reprojection RMS, one lane per camera, in time (or name) "
                           "order; red and numbered: each camera's worst images (drawn above, "
                           "listed below).", "image_rms.png")
    if "residuals_by_radius.png" in figures:
        together += figure(figures["residuals_by_radius.png"], "residuals by radius",
                           "Reprojection residuals against the distance from the principal "
                           "point: a lens model that does not fit grows them towards the "
                           "corners.", "residuals_by_radius.png")
    files = camera_figure_names(rec.cameras)
    blocks = [_camera_block(c, None if details is None else details.camera(c.name),
                            figures.get(files[c.name]), files[c.name]) for c in rec.cameras]
    return head + together + "".join(blocks) + "</section>"


# --------------------------------------------------------------------------- diagnostics


def _number(v) -> float | None:
    """A diagnostics value as a float; None (infinite, in calibration.json) stays None."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        return float(v)
    except OverflowError:       # an integer beyond the float range: not a diagnostics value
        return None


def _motion_table(rec: CalibrationRecord) -> str:
    motion = rec.motion_diagnostics or {}
    header = ["camera", "images", "rotation range (deg)", "axis 1", "axis 2", "axis 3",
              "rotation", "translation"]
    groups = [("", 3), ("RMS rotation about the principal axes (deg)", 3), ("condition", 2)]
    rows, classes = [], []
    for c in rec.cameras:
        d = motion.get(c.name)
        if not isinstance(d, Mapping):
            continue
        spread = d.get("rotation_spread_deg")
        spread = [_number(v) for v in spread] if isinstance(spread, list) else []
        spread = (spread + [None] * 3)[:3]
        rng = _number(d.get("rotation_range_deg"))
        conds = [_number(d.get("rotation_condition")), _number(d.get("translation_condition"))]
        one_axis = (spread[0] is not None and spread[1] is not None
                    and (spread[1] < MIN_SECOND_AXIS_DEG or spread[1] < MIN_AXIS_RATIO * spread[0]))
        rows.append([c.name, value_text(d.get("measurements")), num(rng, ".1f"),
                     *(num(v, ".2f") for v in spread),
                     *("∞" if v is None else num(v, ".3g") for v in conds)])
        classes.append(["", "", "bad" if rng is not None and rng < MIN_ROTATION_RANGE_DEG else "",
                        "", "bad" if one_axis else "", "",
                        *("bad" if v is None or v > MAX_CONDITION else "" for v in conds)])
    if not rows:
        return ""
    note = (f"How well each camera's motion determines its extrinsic (computed before the "
            f"solve, on the measurements kept). Red: below the thresholds at which the "
            f"calibration warns (rotation range under {MIN_ROTATION_RANGE_DEG:g} deg; second "
            f"axis under {MIN_SECOND_AXIS_DEG:g} deg or {MIN_AXIS_RATIO:g} of the first: "
            f"rotations about one axis; condition over {MAX_CONDITION:g} or infinite). A "
            "condition is n / λ of the camera's reduced rotation (or translation) system: 1 at "
            "best, growing like 1/θ² for rotations of RMS angle θ; roughly the factor by which "
            "the motion amplifies the noise in the worst direction.")
    return (f"{table(header, rows, classes=classes, groups=groups)}"
            f'<p class="note">{escape(note)}</p>')


def diagnostics_section(rec: CalibrationRecord, details: RunDetails | None) -> str:
    """The weak-motion diagnostics (module docstring)."""
    head = '<section id="diagnostics"><h2>Weak-motion diagnostics</h2>'
    parts = [_motion_table(rec)]
    extra = details is not None and any(details.camera(c.name).diagnostics for c in rec.cameras)
    if extra:
        keys = list(dict.fromkeys(k for c in rec.cameras
                                  for k in details.camera(c.name).diagnostics))
        rows = [[c.name, *(value_text(details.camera(c.name).diagnostics.get(k)) for k in keys)]
                for c in rec.cameras]
        parts.append("<h3>Further diagnostics</h3>"
                     + table(["camera", *(k.replace("_", " ") for k in keys)], rows)
                     + '<p class="note">Passed to the writer with the run (the '
                       "<code>diagnostics</code> of <code>details.json</code>).</p>")
    if not any(parts):
        why = ("calibration.json has no motion_diagnostics (written by an earlier version) and "
               + ("there is no details.json" if details is None else "details.json has none"))
        parts = [f'<p class="note">Not available: {escape(why)}.</p>']
    return head + "".join(parts) + "</section>"
