"""Figures of the calibration report (matplotlib, Agg canvas, imported when drawing); the
same kind of module as :mod:`multieye.experiments.figures`, which draws the experiments'.

Figures returned as PNG bytes for :mod:`multieye.outputs.report` to embed and to write (the
rig's are in :mod:`multieye.outputs.figures_rig`).  Figures about every camera draw one lane
per camera in one axes (an axes per camera would cost most of the time of the report):

- :func:`residual_histograms_png`: per camera, histograms of the loop residuals of
  ``A_i X = Y B_i`` (rotation in degrees, translation in millimetres, paper section V-A);
- :func:`residuals_over_time_png`: the same residuals against the camera's time;
- :func:`image_rms_png`: every used image's reprojection RMS, the worst marked;
- :func:`radial_png`: the reprojection residuals by distance from the principal point;
- :func:`camera_png`, one per camera: where the target was seen on the image and the
  reprojection residuals over it, and the projection's uncertainty from the estimated
  intrinsics (the numbers from :mod:`multieye.outputs.image_stats`).

A camera keeps its colour in every figure.  As in :mod:`multieye.experiments.figures`, only the Agg canvas
is used (no pyplot, no global backend switch).
"""

from __future__ import annotations

import functools
import struct
import zlib
from collections.abc import Sequence

import numpy as np

from multieye.io.run_details import CameraDetails, RunDetails
from multieye.outputs.image_stats import (
    COVERAGE_CELLS, MAX_ARROWS, arrow_scale, coverage, image_frame, mean_vectors,
    position_bins, radial_bins, stacked, worst_images)

__all__ = ["camera_colours", "outliers", "stamps_are_indices", "HIGHLIGHT",
           "residual_histograms_png", "residuals_over_time_png", "camera_png", "camera_pngs",
           "draw_jobs", "image_rms_png", "radial_png"]

_AXIS_COLOURS = ("#d62728", "#2ca02c", "#1f77b4")  # x red, y green, z blue
_GREY = "#7f7f7f"


#: Camera colours: tab10 without its red (the "worst" highlight and the x axis) and grey
#: (the motion capture), then the light tab20 shades of the same hues.
_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#bcbd22",
            "#17becf", "#aec7e8", "#ffbb78", "#98df8a", "#c5b0d5", "#c49c94", "#f7b6d2",
            "#dbdb8d", "#9edae5")
#: Colour of what is flagged (worst images, high residuals, empty cells).
HIGHLIGHT = "#d62728"


def camera_colours(n: int) -> list[str]:
    """One colour per camera, none of them the red of :data:`HIGHLIGHT` or a grey (16
    distinct, then repeated)."""
    return [_PALETTE[k % len(_PALETTE)] for k in range(n)]


def stamps_are_indices(stamps) -> bool:
    """Whether a camera's stamps are the places of its images rather than times: whole
    numbers from 0 below 10^6 (poses matched to images by name are stamped 0, 1, 2, ...;
    a clock in seconds starts far from 0 or has fractions)."""
    s = np.asarray(stamps, dtype=np.float64)
    return bool(s.size) and bool(np.all(s == np.round(s))) and s.min() >= 0 and s.max() < 1e6


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


# --------------------------------------------------------------------------- residuals


def _lanes(details: RunDetails, dpi: int, titles: Sequence[str]):
    """A figure of an axes per title (rotation, translation), one lane per camera, top to
    bottom: as many axes whatever the number of cameras (small multiples cost an axes each).

    Ticks cost three artists each (and their labels a glyph per character): the cameras'
    names are texts left of the first axes, and every axes has at most 6 ticks across
    (:data:`_TICKS`), none up."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)
    from matplotlib.collections import LineCollection  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    m = len(details.cameras)
    fig = Figure(figsize=(10.0, 1.2 + 0.5 * max(m, 2)), dpi=dpi)
    FigureCanvasAgg(fig)
    axes = list(fig.subplots(1, len(titles), squeeze=False)[0])
    colours = camera_colours(m)
    for ax, title in zip(axes, titles):
        ax.set_ylim(-0.15, m)
        ax.set_yticks([])
        ax.xaxis.set_major_locator(_locator())
        ax.set_title(title, fontsize=9, loc="left", y=1.0)
        ax.tick_params(labelsize=8, length=2)
        ax.grid(True, axis="x", alpha=0.3)
        # the lines between lanes, across the axes: one collection (an artist each costs)
        ax.add_collection(LineCollection([[(0, y - 0.07), (1, y - 0.07)] for y in range(1, m)],
                                         transform=ax.get_yaxis_transform(), colors=_GREY,
                                         lw=0.4, alpha=0.5, zorder=2), autolim=False)
    for row, (cam, colour) in enumerate(zip(details.cameras, colours)):   # texts, not ticks
        axes[0].text(-0.005, m - 0.6 - row, cam.name, transform=axes[0].get_yaxis_transform(),
                     ha="right", va="center", fontsize=8, fontweight="bold", color=colour)
    fig.subplots_adjust(left=0.1, right=0.98, wspace=0.06, top=1 - 0.45 / fig.get_figheight(),
                        bottom=0.55 / fig.get_figheight())
    return fig, axes, colours


#: At most this many intervals between the ticks of an axis (MaxNLocator's ``nbins``).
_TICKS = 5


def _locator(nbins: int = _TICKS):
    """At most ``nbins + 1`` ticks at round numbers (1, 2, 2.5 or 5 times a power of ten, as
    matplotlib's default): a tick costs two artists and its label a glyph per character."""
    from matplotlib.ticker import MaxNLocator  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    return MaxNLocator(nbins=nbins, steps=[1, 2, 2.5, 5, 10])


#: matplotlib settings of the report's figures while they are drawn (:func:`_png`): glyphs
#: rendered without hinting (matplotlib renders text glyph by glyph, hinted glyphs cost 1.6x
#: as much; at 90-100 dpi the text looks the same, docs/results/report_speed.md).
_RC = {"text.hinting": "no_hinting"}


def _png(fig) -> bytes:
    """The figure drawn on an Agg canvas with the settings :data:`_RC`, as PNG
    (:func:`png_bytes`: the same pixels as ``fig.savefig(format="png")``, in half the
    encoding time)."""
    from matplotlib import rc_context  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (as above)

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    with rc_context(_RC):
        canvas.draw()
    return png_bytes(np.asarray(canvas.buffer_rgba()))


def png_bytes(rgba: np.ndarray, level: int = 3) -> bytes:
    """A PNG of an image, ``(h, w, 4)`` uint8 RGBA (RGB in the file when it is opaque).

    Rows unfiltered (PNG filter 0) and zlib ``level``: on the report's figures (flat colours,
    thin lines) that is smaller than Pillow's adaptive filtering, which matplotlib's
    ``savefig`` uses, and takes half its CPU time (docs/results/report_speed.md).
    """
    h, w = rgba.shape[:2]
    opaque = bool(np.all(rgba[..., 3] == 255))
    pixels = rgba[..., :3] if opaque else rgba
    rows = np.zeros((h, 1 + w * pixels.shape[2]), dtype=np.uint8)     # byte 0: filter 0
    rows[:, 1:] = pixels.reshape(h, -1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data)))

    header = struct.pack(">IIBBBBB", w, h, 8, 2 if opaque else 6, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(rows.tobytes(), level)) + chunk(b"IEND", b""))


_METRICS: Sequence[tuple[str, str, float, str]] = (
    ("rot_deg", "rotation residual (deg)", 1.0, "°"),
    ("trans_m", "translation residual (mm)", 1e3, " mm"),
)
#: At most this many bars per lane of :func:`image_rms_png` (about its width in pixels).
_MAX_BARS = 800
#: Height of a camera's lane that its histogram or curve may fill.
_LANE = 0.82


def residual_histograms_png(details: RunDetails, *, dpi: int = 90) -> bytes:
    """Per camera (lanes), histograms of the rotation and translation residuals (columns).

    Each column shares its bins across cameras, so a camera that fits worse than the others
    stands out; bar heights are scaled to the fullest bin of the column.  The median (solid)
    and the mean (dashed) are marked and printed.
    """
    from matplotlib.collections import PolyCollection  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    m = len(details.cameras)
    fig, axes, colours = _lanes(details, dpi, [f"{label}: histogram per camera"
                                               for _, label, _, _ in _METRICS])
    for ax, (key, label, scale, unit) in zip(axes, _METRICS):
        hi = max(float(np.max(getattr(c, key))) * scale for c in details.cameras)
        bins = np.linspace(0.0, hi * 1.02 if hi > 0 else 1.0, 26)
        counts = [np.histogram(getattr(c, key) * scale, bins=bins)[0] for c in details.cameras]
        top = max(max(int(c.max()) for c in counts), 1)
        medians, means, outlines = [], [], []
        for row, (cam, n) in enumerate(zip(details.cameras, counts)):
            y0 = m - 1 - row
            v = getattr(cam, key) * scale
            outlines.append(np.column_stack([np.repeat(bins, 2), np.concatenate(
                [[y0], np.repeat(y0 + _LANE * n / top, 2), [y0]])]))   # the bars' outline
            med, mean = float(np.median(v)), float(np.mean(v))
            medians.append((med, y0))
            means.append((mean, y0))
            ax.text(bins[-1], y0 + _LANE, f"n={v.size}  median {med:.3g}{unit}  mean "
                    f"{mean:.3g}{unit}  max {v.max():.3g}{unit}", ha="right", va="top",
                    fontsize=6.5, color="black",
                    bbox={"facecolor": "white", "alpha": 0.7, "lw": 0, "pad": 0.5})
        # every camera's bars as one collection (a patch each costs ~2 ms to make)
        ax.add_collection(PolyCollection(outlines, facecolors=colours, edgecolors="none",
                                         lw=0, alpha=0.8), autolim=False)
        for marks, style in ((medians, "-"), (means, "--")):
            ax.vlines([x for x, _ in marks], [y for _, y in marks],
                      [y + _LANE for _, y in marks], colors="black", lw=1.0, linestyles=style)
        ax.set_xlim(bins[0], bins[-1])
        ax.set_xlabel(label + f"; bar height: images, full lane = {top}", fontsize=8)
    return _png(fig)


def residuals_over_time_png(details: RunDetails, *, dpi: int = 90) -> bytes:
    """Per camera (lanes), rotation and translation residuals against time (columns).

    Time is the camera clock from that camera's first used image; when no camera's images
    carry a time (:func:`stamps_are_indices`: poses matched to images by name), the images'
    places in name order instead.  Every lane of a column has the same scale (a full lane is
    the largest residual of the column).  Measurements above three times their camera's
    median (:func:`outliers`) are circled in red.
    """
    from matplotlib.collections import LineCollection  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)
    from matplotlib.colors import to_rgba_array  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    m = len(details.cameras)
    times = not all(stamps_are_indices(c.stamps) for c in details.cameras)
    fig, axes, colours = _lanes(details, dpi, [f"{label}: over time per camera"
                                               for _, label, _, _ in _METRICS])
    for ax, (key, label, scale, unit) in zip(axes, _METRICS):
        hi = max(float(np.max(getattr(c, key))) * scale for c in details.cameras)
        hi = hi if hi > 0 else 1.0
        curves, bad_x, bad_y = [], [], []
        for row, cam in enumerate(details.cameras):
            y0 = m - 1 - row
            t = cam.stamps - cam.stamps.min() if times else np.argsort(
                np.argsort(cam.stamps)).astype(np.float64)
            v = getattr(cam, key) * scale
            order = np.argsort(t)
            y = y0 + _LANE * v / hi
            curves.append(np.column_stack([t[order], y[order]]))
            bad = outliers(v)
            bad_x += list(t[bad])
            bad_y += list(y[bad])
            if np.any(bad):
                ax.text(0.995, (y0 + _LANE) / m, f"{int(bad.sum())} high", ha="right",
                        va="top", fontsize=6.5, color=HIGHLIGHT, transform=ax.transAxes)
        # every camera's line, and its dots, as one collection (a line each costs more)
        ax.add_collection(LineCollection(curves, colors=colours, lw=0.9))
        dots = np.concatenate(curves)
        ax.scatter(dots[:, 0], dots[:, 1], s=12, lw=0, c=np.repeat(
            to_rgba_array(colours), [len(c) for c in curves], axis=0))
        if bad_x:
            ax.scatter(bad_x, bad_y, s=40, facecolors="none", edgecolors=HIGHLIGHT,
                       linewidths=1.2, zorder=4)
        ax.set_xlabel(("time since the camera's first used image (s)" if times else
                       "used image, in name order (the images carry no time)")
                      + f"; full lane = {hi:.3g}{unit}", fontsize=8)
    return _png(fig)


# --------------------------------------------------------------------------- one camera


def _image_axes(ax, frame, title: str) -> None:
    """Image coordinates (y down), the image frame drawn, equal scale."""
    from matplotlib.patches import Rectangle  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    w, h = frame.width, frame.height
    ax.add_artist(Rectangle((-0.5, -0.5), w, h, fill=False, lw=1.4, color="black", zorder=5))
    pad = 0.03 * max(w, h)
    ax.set_xlim(-0.5 - pad, w - 0.5 + pad)
    ax.set_ylim(h - 0.5 + pad, -0.5 - pad)
    ax.set_aspect("equal")
    ax.set_axis_off()           # the image frame is drawn; ticks cost more than they tell
    ax.set_title(title, fontsize=8.5, loc="left", y=1.0)
    if frame.cx is not None:
        ax.plot([frame.cx], [frame.cy], marker="+", ms=9, mew=1.3, color="black", zorder=6)


def camera_png(cam: CameraDetails, colour="C0", *, dpi: int = 90) -> bytes:
    """Where one camera saw the target and how well it fits, as PNG bytes.

    Two panels on the image (principal point ``+``): left, the target points of every used
    image (coverage: cells of a 4 x 4 grid without any are shaded) and their reprojection
    residuals as vectors (magnified, the key arrow labelled; their mean per cell above
    :data:`~multieye.outputs.image_stats.MAX_ARROWS` points); right, the standard deviation
    of the projection from the intrinsics' covariance (when estimated; else the RMS residual
    in cells of the image).  The residuals by radius and every image's RMS are drawn for all
    cameras at once (:func:`radial_png`, :func:`image_rms_png`).  Needs ``cam.points``
    (:mod:`multieye.io.pixel_details`).
    """
    return camera_pngs([cam], [colour], dpi=dpi)[0]


def camera_pngs(cams: Sequence[CameraDetails], colours: Sequence, *, dpi: int = 90
                ) -> list[bytes]:
    """:func:`camera_png` of each camera (same bytes), drawn on one figure while the images
    keep their shape: the axes and the colour bar are made once and only the data is
    replaced (making an axes costs more than drawing the camera's data)."""
    out = []
    for cam, colour in zip(cams, colours):
        frame = image_frame(cam)
        out.append(_camera_canvas((10.0, 0.9 + 4.6 * frame.height / frame.width), dpi)
                   .png(cam, colour))
    return out


@functools.lru_cache(maxsize=1)
def _camera_canvas(size: tuple[float, float], dpi: int) -> _CameraCanvas:
    """The figure of :func:`camera_png` for images of one shape, kept for the next camera
    drawn by this process (making it, its axes and its colour bar, costs a third of a
    camera's figure): one figure, whatever the calls (:func:`camera_pngs` per batch,
    :func:`camera_png` per camera).  Not for threads (nor is matplotlib)."""
    return _CameraCanvas(size, dpi)


class _CameraCanvas:
    """The figure of :func:`camera_png` for images of one shape, drawn again per camera."""

    def __init__(self, size: tuple[float, float], dpi: int):
        from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)
        from matplotlib.figure import Figure  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

        self.size = size
        self.fig = Figure(figsize=size, dpi=dpi)
        FigureCanvasAgg(self.fig)
        self.ax_vec, self.ax_map = self.fig.subplots(1, 2)
        self.bar = None

    def png(self, cam: CameraDetails, colour) -> bytes:
        """The camera's figure: the last camera's data removed, this one's drawn."""
        fig, ax_vec, ax_map = self.fig, self.ax_vec, self.ax_map
        for ax in (ax_vec, ax_map):
            for artist in [*ax.patches, *ax.lines, *ax.collections, *ax.images, *ax.texts,
                           *ax.artists]:
                artist.remove()
        frame = image_frame(cam)
        uv, res = stacked(cam)
        _vectors_panel(ax_vec, cam, frame, uv, res, colour)
        im, label = _map_panel(ax_map, cam, frame, uv, res)
        if self.bar is None:
            self.bar = fig.colorbar(im, ax=ax_map, fraction=0.046, pad=0.02)
        else:
            self.bar.update_normal(im)
        _colour_bar_ticks(self.bar)
        self.bar.ax.tick_params(labelsize=7)
        self.bar.set_label(label, fontsize=7.5)
        fig.suptitle(cam.name, x=0.01, ha="left", fontsize=11, fontweight="bold",
                     color=colour)
        fig.subplots_adjust(left=0.01, right=0.94, top=1 - 0.75 / fig.get_figheight(),
                            bottom=0.4 / fig.get_figheight(), wspace=0.08)
        return _png(fig)


def _colour_bar_ticks(bar) -> None:
    """At most 6 ticks on a linear colour bar; on a logarithmic one 1, 2 and 5 times the
    powers of ten as plain numbers, no minor ticks (matplotlib's ``10^k`` in mathtext with
    unlabelled minor ticks costs as much as the rest of the figure the first time)."""
    from matplotlib.colors import LogNorm  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)
    from matplotlib.ticker import FormatStrFormatter, LogLocator  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    if isinstance(bar.norm, LogNorm):
        bar.locator = LogLocator(subs=(1.0, 2.0, 5.0))
        bar.formatter = FormatStrFormatter("%g")
        bar.minorticks_off()
    else:
        bar.locator = _locator()


def _vectors_panel(ax_vec, cam: CameraDetails, frame, uv: np.ndarray, res: np.ndarray,
                   colour) -> None:
    """The left panel of :func:`camera_png`: coverage, points and residual vectors."""
    from matplotlib.collections import LineCollection, PolyCollection  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    pts = cam.points
    w, h = frame.width, frame.height
    size_note = "" if frame.known else " (image size unknown)"
    n_img = sum(len(u) > 0 for u in pts.uv)
    sub = "" if pts.kept == pts.n_points else f", {pts.kept} drawn"
    # coverage: empty cells shaded
    cells = COVERAGE_CELLS
    seen = np.zeros((cells, cells), dtype=bool)         # [column, row] of the grid
    if len(uv):
        idx = np.clip((uv / [w, h] * cells).astype(int), 0, cells - 1)
        seen[idx[:, 0], idx[:, 1]] = True
    # the empty cells and the grid as one collection each (an artist each costs ~1 ms)
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) * [w / cells, h / cells] - 0.5
    empty = [corners + [a * w / cells, b * h / cells]
             for a in range(cells) for b in range(cells) if not seen[a, b]]
    if empty:
        ax_vec.add_collection(PolyCollection(empty, facecolors=HIGHLIGHT, alpha=0.08, lw=0,
                                             edgecolors="none"), autolim=False)
    pad = 0.03 * max(w, h)
    grid = [[(k * w / cells - 0.5, -0.5 - pad), (k * w / cells - 0.5, h - 0.5 + pad)]
            for k in range(1, cells)]
    grid += [[(-0.5 - pad, k * h / cells - 0.5), (w - 0.5 + pad, k * h / cells - 0.5)]
             for k in range(1, cells)]
    ax_vec.add_collection(LineCollection(grid, colors=_GREY, lw=0.5, linestyles=":", zorder=2),
                          autolim=False)
    ax_vec.scatter(uv[:, 0], uv[:, 1], s=2, color=_GREY, alpha=0.5, lw=0)
    # residual vectors: per point, or their mean per cell when there are many
    if len(uv) > MAX_ARROWS:
        at, vec, _ = mean_vectors(uv, res, frame)
        what = "mean per cell"
    else:
        at, vec, what = uv, res, "per point"
    key, magnify = arrow_scale(vec, frame)
    if len(at):
        q = ax_vec.quiver(at[:, 0], at[:, 1], vec[:, 0], vec[:, 1], angles="xy",
                          scale_units="xy", scale=1.0 / magnify, color=colour, width=0.004,
                          headwidth=3.5, headlength=4)
        times = f"{magnify:.0f}" if magnify >= 10 else f"{magnify:.2g}"
        ax_vec.quiverkey(q, 0.02, -0.06, key, f"{key:g} px (arrows ×{times})", labelpos="E",
                         coordinates="axes", fontproperties={"size": 7.5})
    e = np.hypot(res[:, 0], res[:, 1])
    rms = float(np.sqrt(np.nanmean(e ** 2))) if len(e) else float("nan")
    _image_axes(ax_vec, frame,
                f"{pts.n_points} points in {n_img} images{sub}{size_note}; coverage "
                f"{coverage(uv, frame):.0%} of {cells} x {cells} cells\nresiduals "
                f"({'refined rig' if pts.source == 'refined' else 'PnP'}, {what}): RMS "
                f"{rms:.3f} px")


def _map_panel(ax_map, cam: CameraDetails, frame, uv: np.ndarray, res: np.ndarray):
    """The right panel of :func:`camera_png`: the projection's σ from the intrinsics (or the
    residuals binned by position).  Returns the image drawn and its colour bar's label."""
    from matplotlib.colors import LogNorm  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    w, h = frame.width, frame.height
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
    return im, label


def image_rms_png(details: RunDetails, *, dpi: int = 90, worst: int = 3) -> bytes:
    """Per camera (lanes), the reprojection RMS of every used image, the ``worst`` marked.

    One lane per camera with a bar per image in time order, heights scaled to the largest
    RMS of all cameras (stated); the worst images of each camera red and numbered.  Cameras
    without target points have an empty lane.  A camera with more than ``_MAX_BARS`` images
    (bars narrower than a pixel) has a bar for each run of consecutive images as tall as
    the tallest of them, so that the cost is bounded and no peak is lost.
    """

    from matplotlib.collections import PolyCollection  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)
    from matplotlib.colors import to_rgba  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    fig, (ax,), colours = _lanes(details, dpi, [""])
    m = len(details.cameras)
    rms = [c.points.rms_px if c.points is not None else np.zeros(0) for c in details.cameras]
    hi = max([float(np.nanmax(r)) for r in rms if np.any(np.isfinite(r))] + [1e-9])
    longest = max([len(r) for r in rms] + [1])
    bars, bar_colours = [], []      # every bar in one collection: a patch each costs ~1 ms
    for row, (cam, r) in enumerate(zip(details.cameras, rms)):
        if not len(r):
            continue
        y0 = m - 1 - row
        x = np.arange(len(r)) * (longest / len(r))     # every lane spans the axis
        width = 0.85 * longest / len(r)
        heights = _LANE * np.nan_to_num(r) / hi
        bad = [cam.names.index(n) for n, _ in worst_images(cam, worst)]
        ok = np.setdiff1d(np.arange(len(r)), bad)
        spans = [(x[ok], x[ok] + width, heights[ok], to_rgba(colours[row], 0.85))]
        if len(r) > _MAX_BARS:      # narrower than a pixel: the tallest of each 1/_MAX_BARS,
            groups = np.array_split(np.arange(len(r)), _MAX_BARS)       # as one outline
            edges = np.append(x[[g[0] for g in groups]], longest)
            tops = y0 + np.repeat([heights[g].max() for g in groups], 2)
            bars.append(np.vstack([[edges[0], y0], np.column_stack(
                [np.repeat(edges, 2)[1:-1], tops]), [edges[-1], y0]]))
            bar_colours.append(spans.pop()[3])
            width = max(width, longest / _MAX_BARS)
        spans.append((x[bad], x[bad] + width, heights[bad], HIGHLIGHT))
        for left, right, top, colour in spans:
            top = y0 + top
            bars += list(np.stack([np.column_stack([left, np.full(len(left), y0)]),
                                   np.column_stack([right, np.full(len(left), y0)]),
                                   np.column_stack([right, top]),
                                   np.column_stack([left, top])], axis=1))
            bar_colours += [colour] * len(left)
        for rank, i in enumerate(bad, 1):
            ax.text(x[i] + width / 2, y0 + heights[i], str(rank), ha="center", va="bottom",
                    fontsize=6.5, color=HIGHLIGHT, fontweight="bold")
        med = float(np.nanmedian(r)) if np.any(np.isfinite(r)) else 0.0
        ax.plot([0, longest], [y0 + _LANE * med / hi] * 2, color="black", lw=0.8, ls="--")
    if bars:
        ax.add_collection(PolyCollection(bars, facecolors=bar_colours, edgecolors="none",
                                         lw=0), autolim=False)
    ax.set_xlim(0, longest)
    ax.set_xticks([])
    ax.set_title("reprojection RMS of every used image, in their order (dashed: the camera's "
                 "median; red: its worst, numbered)", fontsize=9, loc="left", y=1.0)
    ax.set_xlabel(f"used images of each camera, spread over the lane; full lane = {hi:.3g} px",
                  fontsize=8)
    return _png(fig)


def radial_png(details: RunDetails, *, dpi: int = 90) -> bytes:
    """Residual length against the distance from the principal point, every camera on one
    axes: the RMS of the residual lengths in 10 rings from the centre to the farthest corner
    (:func:`multieye.outputs.image_stats.radial_bins`), a line per camera in its colour."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy: matplotlib, only when a figure is drawn)

    fig = Figure(figsize=(10.0, 3.2), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    colours = camera_colours(len(details.cameras))
    for cam, col in zip(details.cameras, colours):
        if cam.points is None:
            continue
        uv, res = stacked(cam)
        edges, rms, _, _ = radial_bins(uv, res, image_frame(cam))
        ax.plot((edges[:-1] + edges[1:]) / 2, rms, color=col, marker="o", ms=3, lw=1.2,
                label=cam.name)
    ax.set_ylim(0, None)
    ax.set_xlim(0, None)
    ax.xaxis.set_major_locator(_locator())
    ax.yaxis.set_major_locator(_locator(4))
    ax.grid(True, alpha=0.3)
    ax.tick_params(labelsize=8)
    ax.set_xlabel("distance from the principal point (px)", fontsize=8)
    ax.set_ylabel("RMS residual (px)", fontsize=8)
    ax.set_title("reprojection residuals by radius (RMS in 10 rings to the farthest corner)",
                 fontsize=9, loc="left", y=1.0)
    ax.legend(fontsize=7, ncol=min(len(details.cameras), 8), frameon=False, loc="upper left")
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.16, top=0.9)
    return _png(fig)


# --------------------------------------------------------------------------- in a worker


def draw_jobs(jobs: Sequence[tuple]) -> dict[str, bytes]:
    """PNG bytes by file name of ``(file name, function of this module, arguments, cost)``
    jobs (:func:`multieye.outputs.report_draw.figure_jobs`), drawn in this process (the
    cameras' figures on one figure reused, :func:`_camera_canvas`).  Here rather than in
    :mod:`~multieye.outputs.report_draw` so that a worker imports only this module."""
    return {name: func(*args) for name, func, args, _ in jobs}
