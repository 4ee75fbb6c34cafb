"""Figures of the calibration report (matplotlib, Agg canvas, imported when drawing).

Four figures, each returned as PNG bytes for :mod:`multieye.outputs.report` to embed and to write:

- :func:`rig_png`: the rig in 3D and seen from above: camera frustums with names, the
  reference camera's axes, the world origin, the target at every used image and the
  motion-capture trajectory;
- :func:`residual_histograms_png`: per camera, histograms of the loop residuals of
  ``A_i X = Y B_i`` (rotation in degrees, translation in millimetres, paper section V-A);
- :func:`residuals_over_time_png`: the same residuals against the camera's time;
- :func:`camera_png`, one per camera: where the target was seen on the image, the
  reprojection residuals over the image and by radius, every image's RMS, and the
  projection's uncertainty from the estimated intrinsics (the numbers from
  :mod:`multieye.outputs.image_stats`).

A camera keeps its colour in every figure.  As in :mod:`multieye.experiments.figures`, only the Agg canvas
is used (no pyplot, no global backend switch).

Drawing conventions: the vertical of the pictures is the world axis closest to the cameras'
mean "up" (their ``-y`` axis, image up), so that a y-up motion-capture world is not drawn lying
on its side; the pictures are rotated (never mirrored) for that, and the axis labels say which
world axis is shown.  Frustums use the pinhole part of the intrinsics (distortion ignored) and
a depth proportional to the size of the rig.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from multieye.core.intrinsics import Intrinsics
from multieye.io.calibration_json import CalibrationRecord
from multieye.io.run_details import CameraDetails, RunDetails

__all__ = [
    "camera_colours",
    "frustum_corners",
    "display_rotation",
    "outliers",
    "rig_png",
    "residual_histograms_png",
    "residuals_over_time_png",
    "camera_png",
]

_AXIS_COLOURS = ("#d62728", "#2ca02c", "#1f77b4")  # x red, y green, z blue
_GREY = "#7f7f7f"


def camera_colours(n: int) -> list[str]:
    """One distinct matplotlib colour per camera (tab10, then tab20 for more than 10)."""
    if n <= 10:
        return [f"C{k}" for k in range(n)]
    from matplotlib import colormaps
    cmap = colormaps["tab20"]
    return [cmap(k % 20) for k in range(n)]


def frustum_corners(intrinsics: Intrinsics | None, depth: float) -> np.ndarray:
    """Image corners at ``depth`` in the camera frame (x right, y down, z forward).

    Parameters
    ----------
    intrinsics : Intrinsics or None
        Pinhole part only (distortion ignored).  The image is ``width x height`` pixels, or
        ``2 cx + 1`` by ``2 cy + 1`` when the size is unknown; None draws a 60 x 45 degree
        field of view.
    depth : float
        Metres along the optical axis.

    Returns
    -------
    ndarray, shape (4, 3)
        Top-left, top-right, bottom-right, bottom-left, metres.
    """
    if intrinsics is None:
        hx, hy = np.tan(np.radians(30.0)), np.tan(np.radians(22.5))
        rays = np.array([[-hx, -hy, 1], [hx, -hy, 1], [hx, hy, 1], [-hx, hy, 1]])
    else:
        K = intrinsics.K
        w = intrinsics.width if intrinsics.width is not None else 2 * K[0, 2] + 1
        h = intrinsics.height if intrinsics.height is not None else 2 * K[1, 2] + 1
        pix = np.array([[-0.5, -0.5, 1], [w - 0.5, -0.5, 1], [w - 0.5, h - 0.5, 1],
                        [-0.5, h - 0.5, 1]])
        rays = pix @ np.linalg.inv(K).T
        rays /= rays[:, 2:3]
    return rays * depth


def display_rotation(up) -> tuple[np.ndarray, list[str]]:
    """Rotation from the plotting frame to the display frame whose z is closest to ``up``.

    Parameters
    ----------
    up : array_like, shape (3,)
        The up direction in the plotting frame (need not be unit).

    Returns
    -------
    P : ndarray, shape (3, 3)
        Signed permutation with ``det P = +1`` (a rotation, never a mirror); display
        coordinates are ``P @ p``.
    labels : list of str
        Which plotting axis each display axis shows, e.g. ``["y", "z", "x"]`` or ``["-y", ...]``.
    """
    up = np.asarray(up, dtype=np.float64)
    a = int(np.argmax(np.abs(up)))
    s = 1.0 if up[a] >= 0 else -1.0
    b, c = (a + 1) % 3, (a + 2) % 3          # (b, c, a) is a cyclic order: det +1
    P = np.zeros((3, 3))
    P[0, b], P[1, c], P[2, a] = s, 1.0, s    # s * s = 1 keeps det +1
    names = "xyz"
    labels = [("-" if P[i].sum() < 0 else "") + names[int(np.flatnonzero(P[i])[0])]
              for i in range(3)]
    return P, labels


def outliers(values, factor: float = 3.0) -> np.ndarray:
    """Values above ``factor`` times their median, as a boolean mask.

    The loop residuals are norms of 3-vectors of noise (Maxwell-like for Gaussian noise), for
    which a value above three times the median is a 4.6-sigma event (probability ~1e-4):
    anything flagged deserves a look.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.size < 3:
        return np.zeros(v.shape, dtype=bool)
    return v > factor * np.median(v)


# --------------------------------------------------------------------------- the rig


@dataclass(frozen=True)
class _Scene:
    """What the rig figure draws, in the plotting frame (world, or ref without details)."""

    frame: str
    names: tuple[str, ...]
    T_cams: np.ndarray                  # (m, 4, 4) T_frame_cam
    intrinsics: tuple                   # Intrinsics or None per camera
    reference: int
    targets: tuple[np.ndarray, ...]     # per camera (n, 3) target origins
    trajectories: tuple[np.ndarray, ...]  # (k, 3) each
    trajectory_pose: str


def _scene(record: CalibrationRecord, details: RunDetails | None) -> _Scene:
    names = tuple(c.name for c in record.cameras)
    ref = names.index(record.reference_camera)
    if details is None:
        return _Scene(frame=f"ref ({record.reference_camera})", names=names,
                      T_cams=np.stack([c.T_ref_cam for c in record.cameras]),
                      intrinsics=(None,) * len(names), reference=ref, targets=(),
                      trajectories=(), trajectory_pose="")
    cams: list[CameraDetails] = [details.camera(n) for n in names]
    return _Scene(frame="world", names=names, T_cams=np.stack([c.T_world_cam for c in cams]),
                  intrinsics=tuple(c.intrinsics for c in cams), reference=ref,
                  targets=tuple(c.T_world_target[:, :3, 3] for c in cams),
                  trajectories=tuple(_break_gaps(t.stamps, t.positions)
                                     for t in details.trajectories),
                  trajectory_pose=details.trajectories[0].pose if details.trajectories else "")


def _break_gaps(stamps: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Positions with a NaN row wherever the recording pauses (a gap over 5 x the median
    sampling interval and over 0.5 s), so that a line is not drawn across the pause."""
    if len(stamps) < 3:
        return positions
    dt = np.diff(stamps)
    gaps = np.flatnonzero(dt > max(5.0 * float(np.median(dt)), 0.5))
    return np.insert(positions, gaps + 1, np.nan, axis=0)


def _frustum_depth(T_cams: np.ndarray) -> float:
    """A depth that keeps neighbouring frustums apart: a quarter of the rig's size."""
    c = T_cams[:, :3, 3]
    span = float(np.max(np.linalg.norm(c[:, None] - c[None], axis=-1))) if len(c) > 1 else 0.0
    return float(np.clip(0.25 * span, 0.05, 0.5)) if span > 0 else 0.15


def _equal_limits(ax, points: np.ndarray, dims: int) -> np.ndarray:
    """Limits with one scale on every axis; returns the (padded) ranges, for a 3D box aspect.

    A flat scene keeps a flat box (each range at least a third of the largest), instead of
    a cube that is mostly empty."""
    lo, hi = points.min(axis=0)[:dims], points.max(axis=0)[:dims]
    centre = (lo + hi) / 2
    ranges = np.maximum(hi - lo, max(float(np.max(hi - lo)), 1e-3) / 3) * 1.08
    setters = (ax.set_xlim, ax.set_ylim, ax.set_zlim)[:dims]
    for k, setter in enumerate(setters):
        setter(centre[k] - ranges[k] / 2, centre[k] + ranges[k] / 2)
    return ranges


def rig_png(record: CalibrationRecord, details: RunDetails | None = None, *,
            dpi: int = 110) -> bytes:
    """The rig in 3D (left) and from above (right), as PNG bytes.

    Parameters
    ----------
    record : CalibrationRecord
        ``calibration.json``.
    details : RunDetails, optional
        ``details.json``: with it the picture is in the world frame with frustums from the
        intrinsics, the targets and the motion capture; without it only the cameras are drawn,
        in the reference camera's frame (``T_ref_cam``).
    dpi : int
    """
    from io import BytesIO

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    sc = _scene(record, details)
    m = len(sc.names)
    colours = camera_colours(m)
    depth = _frustum_depth(sc.T_cams)
    up = -sc.T_cams[:, :3, 1].sum(axis=0)     # cameras' image-up directions
    if np.linalg.norm(up) < 0.3 * m:          # no agreement: least-spread axis of the scene
        pts = np.concatenate([sc.T_cams[:, :3, 3], *sc.trajectories])
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        up = np.eye(3)[int(np.argmin(pts.std(axis=0)))] if len(pts) > 1 else np.eye(3)[2]
    P, labels = display_rotation(up)

    def disp(p):  # plotting frame -> display frame, points (..., 3)
        return np.asarray(p) @ P.T

    fig = Figure(figsize=(12.0, 6.4), dpi=dpi)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(1, 2, width_ratios=(1.2, 1.0), wspace=0.3)
    ax3 = fig.add_subplot(grid[0], projection="3d")
    ax2 = fig.add_subplot(grid[1])
    everything = [disp(sc.T_cams[:, :3, 3] - 0.45 * depth * sc.T_cams[:, :3, 2])]
    for traj in sc.trajectories:
        if len(traj):
            d = disp(traj)  # NaN rows (pauses) break the line and are ignored by the limits
            ax3.plot(d[:, 0], d[:, 1], d[:, 2], color=_GREY, lw=0.6, alpha=0.55, zorder=1)
            ax2.plot(d[:, 0], d[:, 1], color=_GREY, lw=0.6, alpha=0.55, zorder=1)
            everything.append(d)
    for j in range(m):
        T = sc.T_cams[j]
        col = colours[j]
        if sc.targets and len(sc.targets[j]):
            d = disp(sc.targets[j])
            ax3.scatter(d[:, 0], d[:, 1], d[:, 2], s=7, color=col, alpha=0.55, depthshade=False)
            ax2.scatter(d[:, 0], d[:, 1], s=7, color=col, alpha=0.55, zorder=2)
            everything.append(d)
        corners = frustum_corners(sc.intrinsics[j], depth) @ T[:3, :3].T + T[:3, 3]
        apex = T[:3, 3]
        lw = 2.0 if j == sc.reference else 1.3
        c0, c1, c2, c3 = corners     # image rectangle and the four rays, as one polyline
        d = disp(np.stack([c0, c1, c2, c3, c0, apex, c1, np.full(3, np.nan), c2, apex, c3]))
        ax3.plot(d[:, 0], d[:, 1], d[:, 2], color=col, lw=lw)
        ax2.plot(d[:, 0], d[:, 1], color=col, lw=lw, zorder=3)
        top = disp(np.stack([corners[0], corners[1]]))          # image top edge, thick
        ax3.plot(top[:, 0], top[:, 1], top[:, 2], color=col, lw=lw * 2.6, solid_capstyle="butt")
        ax2.plot(top[:, 0], top[:, 1], color=col, lw=lw * 2.6, solid_capstyle="butt", zorder=3)
        label_at = disp(apex - 0.45 * depth * T[:3, 2])     # behind the camera
        name = sc.names[j] + (" (ref)" if j == sc.reference else "")
        for ax, pos in ((ax3, label_at), (ax2, label_at[:2])):
            ax.text(*pos, name, color=col, fontsize=9, fontweight="bold", ha="center",
                    va="center", zorder=5)
        everything.append(disp(corners))
    # reference camera axes and the frame origin
    triads = [(sc.T_cams[sc.reference], "ref", 1.2 * depth)]
    if sc.frame == "world":
        triads.append((np.eye(4), "world", 1.2 * depth))
    for T, text, length in triads:
        o = T[:3, 3]
        for k in range(3):
            d = disp(np.stack([o, o + length * T[:3, k]]))
            ax3.plot(d[:, 0], d[:, 1], d[:, 2], color=_AXIS_COLOURS[k], lw=2.2)
            ax2.plot(d[:, 0], d[:, 1], color=_AXIS_COLOURS[k], lw=2.2, zorder=4)
        if text == "world":
            do = disp(o)
            ax3.text(*do, " world", fontsize=8, color="black")
            ax2.text(*do[:2], " world", fontsize=8, color="black")
            everything.append(do[None])
    pts = np.concatenate(everything)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    ax3.set_box_aspect(tuple(_equal_limits(ax3, pts, 3)), zoom=1.0)
    ax3.view_init(elev=28, azim=-55)
    frame = sc.frame
    for ax, k in ((ax3, 3), (ax2, 2)):
        ax.set_xlabel(f"{frame} {labels[0]} (m)")
        ax.set_ylabel(f"{frame} {labels[1]} (m)")
    ax3.set_zlabel(f"{frame} {labels[2]} (m)", labelpad=2)
    ax3.tick_params(labelsize=7)
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.grid(True, alpha=0.3)
    ax2.tick_params(labelsize=8)
    ax3.set_title("perspective", fontsize=10)
    ax2.set_title(f"from above (looking down {frame} {labels[2]})", fontsize=10)
    handles = [Line2D([], [], color="black", lw=1.3,
                      label=f"camera frustum ({depth:.2f} m deep; thick edge = image top)")]
    if sc.targets:
        handles.append(Line2D([], [], color="black", marker="o", ls="", ms=3,
                              label="target origin at each used image"))
    if sc.trajectories:
        handles.append(Line2D([], [], color=_GREY, lw=1,
                              label=f"motion capture ({sc.trajectory_pose})"))
    handles.append(Line2D([], [], color=_AXIS_COLOURS[0], lw=2,
                          label="axes: x red, y green, z blue (ref camera"
                          + (", world origin)" if frame == "world" else ")")))
    fig.legend(handles=handles, loc="lower center", ncol=2, frameon=False, fontsize=9)
    fig.subplots_adjust(left=0.0, right=0.97, bottom=0.16, top=0.94)
    buffer = BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


# --------------------------------------------------------------------------- residuals


def _grid(details: RunDetails, dpi: int):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    m = len(details.cameras)
    fig = Figure(figsize=(10.0, 0.7 + 1.9 * m), dpi=dpi)
    FigureCanvasAgg(fig)
    axes = fig.subplots(m, 2, squeeze=False)
    return fig, axes


def _png(fig) -> bytes:
    from io import BytesIO

    fig.tight_layout()
    buffer = BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


_METRICS: Sequence[tuple[str, str, float, str]] = (
    ("rot_deg", "rotation residual (deg)", 1.0, "°"),
    ("trans_m", "translation residual (mm)", 1e3, " mm"),
)


def residual_histograms_png(details: RunDetails, *, dpi: int = 100) -> bytes:
    """Per camera (rows), histograms of the rotation and translation residuals (columns).

    Each column shares its bins across cameras, so a camera that fits worse than the others
    stands out; the median (solid) and the mean (dashed) are marked and printed.
    """
    fig, axes = _grid(details, dpi)
    colours = camera_colours(len(details.cameras))
    for col, (key, label, scale, unit) in enumerate(_METRICS):
        hi = max(float(np.max(getattr(c, key))) * scale for c in details.cameras)
        bins = np.linspace(0.0, hi * 1.02 if hi > 0 else 1.0, 21)
        for row, cam in enumerate(details.cameras):
            ax = axes[row, col]
            v = getattr(cam, key) * scale
            ax.hist(v, bins=bins, color=colours[row], alpha=0.8, edgecolor="white", linewidth=0.5)
            med, mean = float(np.median(v)), float(np.mean(v))
            ax.axvline(med, color="black", lw=1.1)
            ax.axvline(mean, color="black", lw=1.1, ls="--")
            ax.set_title(f"{cam.name} (n={v.size}): median {med:.3g}{unit}, mean {mean:.3g}{unit}, "
                         f"max {v.max():.3g}{unit}", fontsize=8.5, loc="left",
                         color=colours[row])
            ax.set_xlim(bins[0], bins[-1])
            ax.tick_params(labelsize=8)
            ax.set_ylabel("images", fontsize=8)
            ax.yaxis.get_major_locator().set_params(integer=True)
            if row == len(details.cameras) - 1:
                ax.set_xlabel(label)
            else:
                ax.tick_params(labelbottom=False)
    return _png(fig)


def residuals_over_time_png(details: RunDetails, *, dpi: int = 100) -> bytes:
    """Per camera (rows), rotation and translation residuals against time (columns).

    Time is the camera clock from that camera's first used image.  Measurements above three
    times their camera's median (:func:`outliers`) are circled in red.
    """
    fig, axes = _grid(details, dpi)
    colours = camera_colours(len(details.cameras))
    for col, (key, label, scale, _) in enumerate(_METRICS):
        hi = max(float(np.max(getattr(c, key))) * scale for c in details.cameras)
        for row, cam in enumerate(details.cameras):
            ax = axes[row, col]
            t = cam.stamps - cam.stamps.min()
            v = getattr(cam, key) * scale
            order = np.argsort(t)
            ax.plot(t[order], v[order], color=colours[row], lw=0.9, marker="o", ms=3)
            bad = outliers(v)
            if np.any(bad):
                ax.scatter(t[bad], v[bad], s=60, facecolors="none", edgecolors="#d62728",
                           linewidths=1.3, zorder=4)
            ax.set_ylim(0, hi * 1.1 if hi > 0 else 1.0)
            ax.text(0.01, 0.92, cam.name + (f"  ({int(bad.sum())} high)" if np.any(bad) else ""),
                    transform=ax.transAxes, ha="left", va="top", fontsize=8, fontweight="bold",
                    color=colours[row])
            ax.grid(True, alpha=0.3)
            ax.tick_params(labelsize=8)
            ax.set_ylabel(label.split(" residual")[0] + (" (deg)" if col == 0 else " (mm)"),
                          fontsize=8)
            if row == len(details.cameras) - 1:
                ax.set_xlabel("time since the camera's first used image (s)")
            if row == 0:
                ax.set_title(label.split(" (")[0].capitalize(), fontsize=10)
    return _png(fig)


# --------------------------------------------------------------------------- one camera


def _image_axes(ax, frame, title: str) -> None:
    """Image coordinates (y down), the image frame drawn, equal scale."""
    from matplotlib.patches import Rectangle

    w, h = frame.width, frame.height
    ax.add_patch(Rectangle((-0.5, -0.5), w, h, fill=False, lw=1.4, color="black", zorder=5))
    pad = 0.03 * max(w, h)
    ax.set_xlim(-0.5 - pad, w - 0.5 + pad)
    ax.set_ylim(h - 0.5 + pad, -0.5 - pad)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    ax.set_title(title, fontsize=8.5, loc="left")
    if frame.cx is not None:
        ax.plot([frame.cx], [frame.cy], marker="+", ms=9, mew=1.3, color="black", zorder=6)


def camera_png(cam: CameraDetails, colour="C0", *, dpi: int = 100) -> bytes:
    """Where one camera saw the target and how well it fits, as PNG bytes.

    Top row, on the image (principal point ``+``): the target points of every used image
    (coverage; cells of a 4 x 4 grid without any are shaded), their reprojection residuals
    as vectors (magnified, the key arrow labelled), and the standard deviation of the
    projection from the intrinsics' covariance (when estimated; else the RMS residual in
    cells of the image).  Bottom row: residual length against the distance from the
    principal point (binned RMS and median over the points), and the RMS of every image with
    the worst named.  Needs ``cam.points`` (:mod:`multieye.io.pixel_details`).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    from multieye.outputs.image_stats import (
        COVERAGE_CELLS, MAX_ARROWS, arrow_scale, coverage, image_frame, mean_vectors,
        position_bins, radial_bins, stacked, worst_images)

    pts = cam.points
    frame = image_frame(cam)
    uv, res = stacked(cam)
    w, h = frame.width, frame.height
    fig = Figure(figsize=(12.0, 6.9), dpi=dpi)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(2, 6, height_ratios=(1.1, 1.0), hspace=0.38, wspace=0.9)
    ax_cov, ax_vec, ax_map = (fig.add_subplot(grid[0, 2 * k:2 * k + 2]) for k in range(3))
    ax_rad, ax_img = fig.add_subplot(grid[1, :2]), fig.add_subplot(grid[1, 2:])
    size_note = "" if frame.known else " (image size unknown)"
    n_img = sum(len(u) > 0 for u in pts.uv)
    sub = "" if pts.kept == pts.n_points else f", {pts.kept} drawn"
    # coverage
    cells = COVERAGE_CELLS
    if len(uv):
        idx = np.clip((uv / [w, h] * cells).astype(int), 0, cells - 1)
        seen = {tuple(c) for c in np.unique(idx, axis=0)}
    else:
        seen = set()
    for a in range(cells):
        for b in range(cells):
            if (a, b) not in seen:
                ax_cov.add_patch(Rectangle((a * w / cells - 0.5, b * h / cells - 0.5), w / cells,
                                           h / cells, color="#d62728", alpha=0.08, lw=0))
    for k in range(1, cells):
        ax_cov.axvline(k * w / cells - 0.5, color=_GREY, lw=0.5, ls=":")
        ax_cov.axhline(k * h / cells - 0.5, color=_GREY, lw=0.5, ls=":")
    ax_cov.scatter(uv[:, 0], uv[:, 1], s=3, color=colour, alpha=0.6, lw=0)
    _image_axes(ax_cov, frame, f"coverage: {coverage(uv, frame):.0%} of {cells} x {cells} cells\n"
                f"{pts.n_points} points in {n_img} images{sub}{size_note}")
    # residual vectors: per point, or their mean per cell when there are many
    ax_vec.scatter(uv[:, 0], uv[:, 1], s=1, color=_GREY, alpha=0.3, lw=0)
    if len(uv) > MAX_ARROWS:
        at, vec, _ = mean_vectors(uv, res, frame)
        what = "mean per cell (>= 3 points)"
    else:
        at, vec, what = uv, res, "per point"
    key, magnify = arrow_scale(vec, frame)
    if len(at):
        q = ax_vec.quiver(at[:, 0], at[:, 1], vec[:, 0], vec[:, 1], angles="xy",
                          scale_units="xy", scale=1.0 / magnify, color=colour, width=0.004,
                          headwidth=3.5, headlength=4)
        times = f"{magnify:.0f}" if magnify >= 10 else f"{magnify:.2g}"
        ax_vec.quiverkey(q, 0.02, -0.12, key, f"{key:g} px (arrows ×{times})", labelpos="E",
                         coordinates="axes", fontproperties={"size": 7.5})
    e = np.hypot(res[:, 0], res[:, 1])
    rms = float(np.sqrt(np.nanmean(e ** 2))) if len(e) else float("nan")
    _image_axes(ax_vec, frame, f"residuals ({'refined rig' if pts.source == 'refined' else 'PnP'}"
                f"): RMS {rms:.3f} px\nprojection minus detection, {what}")
    # projection uncertainty, or the residuals binned by position
    if cam.projection_std is not None and np.any(np.isfinite(cam.projection_std.std_px)):
        ps = cam.projection_std
        s = ps.std_px
        lo, hi = float(np.nanmin(s)), float(np.nanmax(s))
        norm = LogNorm(vmin=max(lo, hi / 1e3, 1e-6), vmax=max(hi, 1e-6)) if hi > 20 * lo else None
        du, dv = (ps.u[1] - ps.u[0]) / 2, (ps.v[1] - ps.v[0]) / 2
        im = ax_map.imshow(s, extent=(ps.u[0] - du, ps.u[-1] + du, ps.v[-1] + dv, ps.v[0] - dv),
                           cmap="viridis", norm=norm, interpolation="nearest", aspect="auto")
        ax_map.scatter(uv[:, 0], uv[:, 1], s=1, color="white", alpha=0.35, lw=0)
        title = (f"projection σ from the intrinsics (px)\nmean {ps.mean_px:.3g}, "
                 f"max {ps.max_px:.3g}; dots: points")
        label = "σ (px)"
    else:
        cell, _ = position_bins(uv, res, frame)
        im = ax_map.imshow(cell, extent=(-0.5, w - 0.5, h - 0.5, -0.5), cmap="viridis",
                           interpolation="nearest", aspect="auto")
        title = ("RMS residual in cells of the image (px)\n"
                 + ("intrinsics given: no projection σ" if cam.intrinsics_estimated is False
                    else "no intrinsics covariance"))
        label = "RMS (px)"
    _image_axes(ax_map, frame, title)
    bar = fig.colorbar(im, ax=ax_map, fraction=0.046, pad=0.03)
    bar.ax.tick_params(labelsize=7)
    bar.set_label(label, fontsize=7.5)
    # residual against radius
    edges, rms_b, med_b, count = radial_bins(uv, res, frame)
    if len(uv):
        r = np.hypot(uv[:, 0] - (frame.cx if frame.cx is not None else (w - 1) / 2),
                     uv[:, 1] - (frame.cy if frame.cy is not None else (h - 1) / 2))
        ax_rad.scatter(r, e, s=2, color=colour, alpha=0.25, lw=0, label="points")
    mid = (edges[:-1] + edges[1:]) / 2
    ax_rad.plot(mid, rms_b, color="black", marker="o", ms=3.5, lw=1.2, label="RMS per bin")
    ax_rad.plot(mid, med_b, color="black", marker="s", ms=3, lw=1, ls="--", label="median")
    for x, n in zip(mid, count):
        if n:
            ax_rad.text(x, 1.0, str(n), transform=ax_rad.get_xaxis_transform(), ha="center",
                        va="bottom", fontsize=6, color=_GREY)
    ax_rad.set_xlim(0, edges[-1])
    ax_rad.set_ylim(0, None)
    ax_rad.set_xlabel("distance from the principal point (px; to the farthest corner)", fontsize=8)
    ax_rad.set_ylabel("residual length (px)", fontsize=8)
    ax_rad.set_title("residuals by radius (grey: points per bin)", fontsize=8.5, loc="left",
                     pad=12)
    ax_rad.legend(fontsize=7, loc="upper left", frameon=False)
    ax_rad.tick_params(labelsize=7)
    ax_rad.grid(True, alpha=0.3)
    # per-image RMS
    rms_i = pts.rms_px
    x = np.arange(len(rms_i))
    worst = worst_images(cam, 3)
    bad = [cam.names.index(n) for n, _ in worst]
    bars = ax_img.bar(x, np.nan_to_num(rms_i), width=0.85 if len(x) < 60 else 1.0,
                      color=colour, alpha=0.85)
    for rank, i in enumerate(bad, 1):
        bars[i].set_color("#d62728")
        ax_img.text(i, rms_i[i], str(rank), ha="center", va="bottom", fontsize=7,
                    color="#d62728", fontweight="bold")
    ax_img.axhline(np.nanmedian(rms_i) if np.any(np.isfinite(rms_i)) else 0, color="black",
                   lw=1, ls="--")
    listing = "\n".join(f"{rank}  {n}  {v:.3f} px" for rank, (n, v) in enumerate(worst, 1))
    ax_img.text(0.99, 0.97, "worst:\n" + listing, transform=ax_img.transAxes, ha="right",
                va="top", fontsize=7, family="monospace",
                bbox={"facecolor": "white", "alpha": 0.85, "edgecolor": _GREY, "lw": 0.5})
    ax_img.set_xlim(-0.6, max(len(x), 1) - 0.4)
    ax_img.set_ylim(0, max(float(np.nanmax(rms_i)) if np.any(np.isfinite(rms_i)) else 1.0,
                           1e-6) * 1.45)
    ax_img.set_xlabel("used image, in time order", fontsize=8)
    ax_img.set_ylabel("reprojection RMS (px)", fontsize=8)
    ax_img.set_title("RMS of every image (dashed: median; red: the worst)", fontsize=8.5,
                     loc="left", pad=12)
    ax_img.tick_params(labelsize=7)
    ax_img.xaxis.get_major_locator().set_params(integer=True)
    ax_img.grid(True, axis="y", alpha=0.3)
    fig.suptitle(cam.name, x=0.01, ha="left", fontsize=11, fontweight="bold", color=colour)
    fig.subplots_adjust(left=0.05, right=0.95, top=0.9, bottom=0.08)
    from io import BytesIO

    buffer = BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()
