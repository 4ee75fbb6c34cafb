"""The rig figures of the report: the cameras in 3D and seen from above (matplotlib, Agg).

:func:`rig_pngs` draws two pictures, ``rig_3d.png`` and ``rig_top.png`` (side by side on a
wide screen, one above the other on a phone): camera frustums labelled with the camera names
(placed so that they do not overlap each other or the frustums' apexes, with a leader line when
moved away), the reference camera's axes, the origin of the fixed frame under the user's name
for it (rig.yaml's ``pose:``, ``calibration.json``'s ``frames``), the target at every used
image, the motion-capture trajectory, and the uncertainty of every camera's pose: its
translation as a 3-sigma ellipsoid (an ellipse from above) and the direction of its optical
axis as a 3-sigma cone (a wedge from above), both magnified by one stated factor so that they
can be seen at the scale of the rig.

Drawing conventions: the vertical of the pictures is the world axis closest to the cameras'
mean "up" (their ``-y`` axis, image up), so that a y-up motion-capture world is not drawn lying
on its side; the pictures are rotated (never mirrored) for that, and the axis labels say which
world axis is shown (:func:`display_rotation`).  Frustums use the pinhole part of the
intrinsics (distortion ignored) and a depth proportional to the size of the rig
(:func:`frustum_corners`).
"""

from __future__ import annotations

import gc
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from multieye.core.collector import fewer_collections
from multieye.core.intrinsics import Intrinsics
from multieye.io.calibration_json import ROLE_NAMES, SETUP_KEYS, CalibrationRecord
from multieye.io.run_details import CameraDetails, RunDetails
from multieye.outputs.board_marks import BoardMark, board_legend, board_lines, record_boards
from multieye.outputs.rig_legend import rig_legend
from multieye.outputs.figures import _AXIS_COLOURS, _GREY, _locator, _png, camera_colours

__all__ = ["RIG_FIGURES", "RigFigures", "rig_pngs", "record_rig_pngs", "uncertainty_magnification",
           "place_labels", "warm_up", "frustum_corners", "display_rotation"]

#: File names of the two rig pictures, in page order.
RIG_FIGURES = ("rig_3d.png", "rig_top.png")
#: Size of each picture (inches) and its resolution.
_SIZE = (5.6, 4.9)
#: At most this many target dots per camera (evenly spread over its images): above some
#: thousands they only overlap, and drawing them costs in proportion.
MAX_DOTS = 2000
_DPI = 100


@dataclass(frozen=True)
class _Scene:
    """What the rig figures draw, in the plotting frame (the fixed frame, or ref)."""

    frame: str                          # the user's name of the plotting frame
    names: tuple[str, ...]
    T_cams: np.ndarray                  # (m, 4, 4) T_frame_cam
    intrinsics: tuple                   # Intrinsics or None per camera
    reference: int
    targets: tuple[np.ndarray, ...]     # per camera (n, 3) target origins
    trajectories: tuple[np.ndarray, ...]  # (k, 3) each
    trajectory_pose: str
    covariances: tuple                  # per camera (6, 6) in the plotting frame, or None
    by_motion: bool = False             # a rig linked by its motion, in the first board's frame


def _rename_pose(pose: str, frames) -> str:
    """``T_world_body`` with the user's names for the roles (``T_base_tool0``)."""
    if not frames or not pose.startswith("T_") or pose.count("_") != 2:
        return pose
    _, a, b = pose.split("_")
    return f"T_{frames.get(a, a)}_{frames.get(b, b)}"


def _scene(record: CalibrationRecord, details: RunDetails | None) -> _Scene:
    names = tuple(c.name for c in record.cameras)
    ref = names.index(record.reference_camera)
    if details is None:
        covs = tuple(None if not c.uncertainty or "T_ref_cam" not in c.uncertainty
                     else c.uncertainty["T_ref_cam"].covariance for c in record.cameras)
        return _Scene(frame=f"{record.reference_camera} (ref)", names=names,
                      T_cams=np.stack([c.T_ref_cam for c in record.cameras]),
                      intrinsics=(None,) * len(names), reference=ref, targets=(),
                      trajectories=(), trajectory_pose="", covariances=covs)
    frames = record.frames or {}
    if record.mocap:
        world = frames.get(ROLE_NAMES[record.setup][0], "world")
        x_key = SETUP_KEYS[record.setup][1]
    elif details.frame is not None:     # linked by its motion: the first board's frame
        world, x_key = details.frame, "T_ref_cam"
    else:                  # no motion capture: drawn in the reference camera's frame
        world, x_key = f"{record.reference_camera} (ref)", "T_ref_cam"
    # X's covariance is in the frame X maps into: the world (eye-to-base) or the body (the
    # rig), drawn at T_world_body_shown (eye-on-hand, motion links): rotate it into the world
    R = np.eye(6)
    if details.T_world_body_shown is not None:
        Rb = details.T_world_body_shown[:3, :3]
        R[:3, :3], R[3:, 3:] = Rb, Rb
    covs = tuple(None if not c.uncertainty or x_key not in c.uncertainty
                 else R @ c.uncertainty[x_key].covariance @ R.T for c in record.cameras)
    cams: list[CameraDetails] = [details.camera(n) for n in names]
    pose = details.trajectories[0].pose if details.trajectories else ""
    return _Scene(frame=world, names=names, T_cams=np.stack([c.T_world_cam for c in cams]),
                  intrinsics=tuple(c.intrinsics for c in cams), reference=ref,
                  targets=tuple(c.T_world_target[:, :3, 3] for c in cams),
                  trajectories=tuple(_break_gaps(t.stamps, t.positions)
                                     for t in details.trajectories),
                  trajectory_pose=_rename_pose(pose, frames), covariances=covs,
                  by_motion=not record.mocap and details.frame is not None)


def _break_gaps(stamps: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Positions with a NaN row wherever the recording pauses (a gap over 5 x the median
    sampling interval and over 0.5 s), so that a line is not drawn across the pause."""
    if len(stamps) < 3:
        return positions
    dt = np.diff(stamps)
    gaps = np.flatnonzero(dt > max(5.0 * float(np.median(dt)), 0.5))
    return np.insert(positions, gaps + 1, np.nan, axis=0)


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


def _frustum_depth(T_cams: np.ndarray) -> float:
    """A depth that keeps neighbouring frustums apart: a quarter of the rig's size."""
    c = T_cams[:, :3, 3]
    span = float(np.max(np.linalg.norm(c[:, None] - c[None], axis=-1))) if len(c) > 1 else 0.0
    return float(np.clip(0.25 * span, 0.05, 0.5)) if span > 0 else 0.15


def _equal_limits(ax, points: np.ndarray, dims: int) -> np.ndarray:
    """Limits with one scale on every axis; returns the (padded) ranges, for a 3D box aspect.

    A flat scene keeps a flat box (each range at least a third of the largest)."""
    lo, hi = points.min(axis=0)[:dims], points.max(axis=0)[:dims]
    centre = (lo + hi) / 2
    ranges = np.maximum(hi - lo, max(float(np.max(hi - lo)), 1e-3) / 3) * 1.1
    setters = ("set_xlim", "set_ylim", "set_zlim")[:dims]
    for k, setter in enumerate(setters):
        getattr(ax, setter)(centre[k] - ranges[k] / 2, centre[k] + ranges[k] / 2)
    return ranges


def uncertainty_magnification(covariances, depth: float) -> tuple[float, float, float] | None:
    """How much to magnify the 3-sigma translation ellipsoids and axis cones to be seen.

    Parameters
    ----------
    covariances : sequence of (6, 6) ndarray or None
        Rotation (rad) then translation (m) covariance of each camera's pose.
    depth : float
        Frustum depth, metres.

    Returns
    -------
    (factor, largest_3sigma_m, largest_3sigma_deg) or None
        ``factor`` is a round number (1, 2 or 5 times a power of ten, at least 1) that makes
        the largest 3-sigma semi-axis about a third of the frustum depth; None when no camera
        has a covariance or every one is zero.
    """
    trans = [3.0 * math.sqrt(max(float(np.linalg.eigvalsh(C[3:, 3:]).max()), 0.0))
             for C in covariances if C is not None]
    rot = [3.0 * math.sqrt(max(float(np.linalg.eigvalsh(C[:3, :3]).max()), 0.0))
           for C in covariances if C is not None]
    if not trans or max(trans) <= 0:
        return None
    want = 0.33 * depth / max(trans)
    if want <= 1:
        factor = 1.0
    else:
        decade = 10.0 ** math.floor(math.log10(want))
        factor = max(k * decade for k in (1, 2, 5, 10) if k * decade <= want)
    return factor, max(trans), math.degrees(max(rot))


def place_labels(anchors: np.ndarray, sizes: np.ndarray, box: tuple[float, float, float, float],
                 obstacles: np.ndarray | None = None, gap: float = 6.0) -> np.ndarray:
    """Positions of text labels near their anchors without overlaps (greedy, display units).

    Parameters
    ----------
    anchors : ndarray, shape (n, 2)
        The point each label names, display units (e.g. points).
    sizes : ndarray, shape (n, 2)
        Width and height of each label.
    box : (x0, y0, x1, y1)
        Where the labels must stay (the axes, below its title).
    obstacles : ndarray, shape (k, 2), optional
        Points no label may cover (the anchors are always obstacles).
    gap : float
        Distance between an anchor and the nearest edge of its label.

    Returns
    -------
    ndarray, shape (n, 2)
        Centres of the labels.  Candidates go round each anchor at growing distances; the
        first that overlaps no placed label and covers no obstacle wins, else the one with
        the least overlap.
    """
    anchors = np.asarray(anchors, dtype=np.float64)
    sizes = np.asarray(sizes, dtype=np.float64)
    pts = anchors if obstacles is None else np.concatenate([anchors, obstacles])
    x0, y0, x1, y1 = box
    placed: list[np.ndarray] = []            # (4,) boxes
    centres = np.zeros_like(anchors)
    middle = anchors.mean(axis=0)
    for i in range(len(anchors)):
        w, h = sizes[i]
        best, best_cost = None, np.inf
        out = anchors[i] - middle            # outward from the middle of the rig first
        first = math.atan2(out[1], out[0]) if np.hypot(*out) > 1e-9 else math.pi / 2
        angles = first + np.radians([0, 30, -30, 60, -60, 90, -90, 120, -120, 150, -150, 180])
        for radius in (1.0, 2.0, 3.2, 4.6, 6.4, 8.5):
            for a in angles:
                d = np.array([math.cos(a), math.sin(a)])
                # distance so that the label's edge is `gap * radius` from the anchor
                reach = gap * radius + 0.5 * (abs(d[0]) * w + abs(d[1]) * h)
                c = anchors[i] + reach * d
                c = np.array([min(max(c[0], x0 + w / 2), x1 - w / 2),
                              min(max(c[1], y0 + h / 2), y1 - h / 2)])
                b = np.array([c[0] - w / 2, c[1] - h / 2, c[0] + w / 2, c[1] + h / 2])
                cost = sum(_overlap(b, q) for q in placed)
                inside = ((pts[:, 0] > b[0] - 2) & (pts[:, 0] < b[2] + 2)
                          & (pts[:, 1] > b[1] - 2) & (pts[:, 1] < b[3] + 2))
                cost += 50.0 * float(inside.sum()) + 0.01 * radius
                cost += 0.5 * float(b[0] < x0 or b[2] > x1 or b[1] < y0 or b[3] > y1)
                if cost < best_cost:
                    best, best_cost = (c, b), cost
            if best_cost < 1.0:
                break
        centres[i] = best[0]
        placed.append(best[1])
    return centres


def _overlap(a: np.ndarray, b: np.ndarray) -> float:
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    return max(w, 0.0) * max(h, 0.0)


def _ellipse_rings(C3: np.ndarray, scale: float, n: int = 40) -> np.ndarray:
    """The three principal ellipses of the 3-sigma ellipsoid of ``C3`` (3 x 3, m^2) times
    ``scale``, as one polyline with NaN breaks, shape (3 (n + 1), 3), centred on 0."""
    vals, vecs = np.linalg.eigh(C3)
    axes = vecs * (3.0 * scale * np.sqrt(np.clip(vals, 0.0, None)))
    t = np.linspace(0, 2 * np.pi, n)
    rings = []
    for a, b in ((0, 1), (1, 2), (0, 2)):
        ring = np.outer(np.cos(t), axes[:, a]) + np.outer(np.sin(t), axes[:, b])
        rings += [ring, np.full((1, 3), np.nan)]
    return np.concatenate(rings)


def _pieces(polyline: np.ndarray) -> list[np.ndarray]:
    """The parts of a polyline between its NaN rows."""
    ok = np.all(np.isfinite(polyline), axis=1)
    breaks = np.flatnonzero(~ok)
    parts = np.split(polyline, breaks)
    return [p[np.all(np.isfinite(p), axis=1)] for p in parts
            if np.sum(np.all(np.isfinite(p), axis=1)) >= 2]


def _axis_angle_std(C: np.ndarray, z: np.ndarray) -> float:
    """Standard deviation of the direction of the optical axis ``z`` (radians, RMS over the
    two directions across it) from the rotation block of ``C``."""
    P = np.eye(3) - np.outer(z, z)
    return math.sqrt(max(float(np.trace(P @ C[:3, :3] @ P)) / 2.0, 0.0))


@dataclass(frozen=True)
class RigFigures:
    """The rig pictures and what their marks mean.

    Attributes
    ----------
    pngs : dict of str to bytes
        PNG bytes by file name (:data:`RIG_FIGURES`).
    legend : tuple of str
        One sentence per kind of mark, for the caption.
    """

    pngs: dict
    legend: tuple[str, ...]


def rig_pngs(record: CalibrationRecord, details: RunDetails | None = None, *,
             dpi: int = _DPI, boards: Sequence[BoardMark] = ()) -> RigFigures:
    """The rig in 3D and from above, with the legend as text (:class:`RigFigures`).

    Parameters
    ----------
    record : CalibrationRecord
        ``calibration.json``.
    details : RunDetails, optional
        ``details.json``: with it the pictures are in the fixed frame of the motion capture
        (under the user's name for it), with frustums from the intrinsics, the targets and the
        motion capture; without it only the cameras are drawn, in the reference camera's frame
        (``T_ref_cam``).
    dpi : int
    boards : sequence of BoardMark
        A rig with several boards (:mod:`multieye.outputs.board_marks`): each board, posed in
        the frame the pictures are drawn in, drawn and named.
    """

    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy: loads when a figure is drawn)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy: loads when a figure is drawn)
    from matplotlib.collections import LineCollection, PolyCollection  # noqa: PLC0415 (heavy: loads when a figure is drawn)
    from mpl_toolkits.mplot3d.art3d import Line3DCollection  # noqa: PLC0415 (heavy: loads when a figure is drawn)

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
    magnified = uncertainty_magnification([*sc.covariances, *(b.covariance for b in boards)], depth)

    def disp(p):  # plotting frame -> display frame, points (..., 3)
        return np.asarray(p) @ P.T

    figs = {name: Figure(figsize=_SIZE, dpi=dpi) for name in RIG_FIGURES}
    for fig in figs.values():
        FigureCanvasAgg(fig)
    ax3 = figs["rig_3d.png"].add_subplot(projection="3d")
    ax2 = figs["rig_top.png"].add_subplot()
    everything = [disp(sc.T_cams[:, :3, 3])]
    for traj in sc.trajectories:
        if len(traj):
            d = disp(traj)  # NaN rows (pauses) break the line and are ignored by the limits
            ax3.plot(d[:, 0], d[:, 1], d[:, 2], color=_GREY, lw=0.6, alpha=0.55, zorder=1)
            ax2.plot(d[:, 0], d[:, 1], color=_GREY, lw=0.6, alpha=0.55, zorder=1)
            everything.append(d)
    apexes = disp(sc.T_cams[:, :3, 3])
    lines, dots, dot_colours, shapes, shape_colours = _camera_marks(
        sc, colours, depth, magnified, P, everything)
    marks, shown = board_lines(boards, disp, None if magnified is None else
                               (lambda C: _ellipse_rings(C, magnified[0])))
    lines, everything = lines + marks, everything + shown
    if dots:
        d = np.concatenate(dots)
        ax3.scatter(d[:, 0], d[:, 1], d[:, 2], s=5, c=dot_colours, alpha=0.5, depthshade=False)
        ax2.scatter(d[:, 0], d[:, 1], s=5, c=dot_colours, alpha=0.5, zorder=2, lw=0)
    if shapes:
        ax2.add_collection(PolyCollection(shapes, facecolors=shape_colours, edgecolors="none",
                                          alpha=0.3, zorder=2))
    # the reference camera's axes and the frame origin's, drawn over the cameras' lines in
    # the same collection (a line each cost more than drawing them)
    triads = [sc.T_cams[sc.reference]] + ([np.eye(4)] if details is not None else [])
    if details is not None:
        everything.append(disp(np.zeros((1, 3))))
    lines += [(disp(np.stack([T[:3, 3], T[:3, 3] + depth * T[:3, k]])), _AXIS_COLOURS[k], 2.0)
              for T in triads for k in range(3)]
    ax3.add_collection3d(Line3DCollection([p for p, _, _ in lines], colors=[c for _, c, _ in lines],
                                          linewidths=[w for _, _, w in lines]))
    ax2.add_collection(LineCollection([p[:, :2] for p, _, _ in lines],
                                      colors=[c for _, c, _ in lines],
                                      linewidths=[w for _, _, w in lines], zorder=3))
    pts = np.concatenate(everything)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    ax3.set_box_aspect(tuple(_equal_limits(ax3, pts, 3)), zoom=0.92)
    ax3.view_init(elev=28, azim=-55)
    frame = sc.frame
    _label_axes(figs, ax3, ax2, frame, labels)
    legend = rig_legend(sc, depth, magnified, details is not None, MAX_DOTS) + board_legend(boards)
    figs["rig_3d.png"].subplots_adjust(left=0.0, right=0.97, bottom=0.03, top=1.0)
    figs["rig_top.png"].subplots_adjust(left=0.13, right=0.98, bottom=0.1, top=0.93)
    names = [n + (" (ref)" if j == sc.reference else "") for j, n in enumerate(sc.names)]
    texts = names + ([f"{frame}"] if details is not None else []) + [b.name for b in boards]
    origin = disp(np.zeros(3))
    anchors = np.concatenate([apexes, origin[None], disp(np.array([b.centre() for b in boards]))
                              if boards else np.zeros((0, 3))])
    if details is None:
        anchors = np.delete(anchors, m, axis=0)     # no frame origin named
    _label_marks(ax3, ax2, anchors, texts, colours[:m], dpi)
    return RigFigures({name: _png(fig) for name, fig in figs.items()}, tuple(legend))


def _label_marks(ax3, ax2, anchors: np.ndarray, texts: list[str], colours, dpi: int) -> None:
    """The cameras', the frame origin's and the boards' names at ``anchors`` (display frame)
    in both pictures (:func:`_annotate`)."""
    from mpl_toolkits.mplot3d import proj3d  # noqa: PLC0415 (heavy: loads when a figure is drawn)

    x, y, _ = proj3d.proj_transform(*anchors.T, ax3.get_proj())
    _annotate(ax3, np.column_stack([x, y]), texts, colours, dpi)
    ax2.apply_aspect()
    _annotate(ax2, anchors[:, :2], texts, colours, dpi)


def _label_axes(figs: dict, ax3, ax2, frame: str, labels) -> None:
    """Axis names in the fixed frame, ticks, the top view's equal aspect, grid and title."""
    for ax in (ax3, ax2):
        ax.set_xlabel(f"{frame} {labels[0]} (m)", fontsize=8, labelpad=1)
        ax.set_ylabel(f"{frame} {labels[1]} (m)", fontsize=8, labelpad=1)
        ax.tick_params(labelsize=7, pad=0)
    ax3.set_zlabel(f"{frame} {labels[2]} (m)", fontsize=8, labelpad=1)
    for axis, nbins in ((ax3.xaxis, 4), (ax3.yaxis, 4), (ax3.zaxis, 4), (ax2.xaxis, 5),
                        (ax2.yaxis, 5)):
        axis.set_major_locator(_locator(nbins))      # a tick costs artists: 4-6 of them
    ax2.autoscale_view()
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.grid(True, alpha=0.3)
    figs["rig_top.png"].suptitle(f"from above (looking down {frame} {labels[2]})", fontsize=10,
                                 y=0.99)


def _camera_marks(sc, colours, depth: float, magnified, P: np.ndarray, everything: list):
    """Per camera its frustum (lines), the target's origin at its images (dots) and its
    uncertainty (rings, and from above an ellipse and a wedge): every camera's lines in one
    collection per picture (an artist per line costs more than drawing it), as (polyline in
    display coordinates, colour, width).  The points drawn are added to ``everything``."""

    from matplotlib.colors import to_rgba_array  # noqa: PLC0415 (heavy: loads when a figure is drawn)

    def disp(p):  # plotting frame -> display frame, points (..., 3)
        return np.asarray(p) @ P.T

    m = len(sc.names)
    apexes = disp(sc.T_cams[:, :3, 3])
    lines: list[tuple[np.ndarray, object, float]] = []
    dots, dot_colours, shapes, shape_colours = [], [], [], []
    for j in range(m):
        T = sc.T_cams[j]
        col = colours[j]
        if sc.targets and len(sc.targets[j]):
            d = disp(sc.targets[j])
            everything.append(d)                    # the limits: every image
            d = d[_even_sample(len(d), MAX_DOTS)]   # the dots: a bounded cost
            dots.append(d)
            dot_colours.append(np.full(len(d), j))       # the camera of each dot
        corners = frustum_corners(sc.intrinsics[j], depth) @ T[:3, :3].T + T[:3, 3]
        apex = T[:3, 3]
        lw = 2.0 if j == sc.reference else 1.3
        c0, c1, c2, c3 = corners     # image rectangle and the four rays
        for poly in ([c0, c1, c2, c3, c0], [apex, c0], [apex, c1], [apex, c2], [apex, c3]):
            lines.append((disp(np.stack(poly)), col, lw))
        lines.append((disp(np.stack([c0, c1])), col, lw * 2.6))    # image top edge, thick
        everything.append(disp(corners))
        C = sc.covariances[j]
        if magnified is not None and C is not None:
            factor = magnified[0]
            ring = disp(_ellipse_rings(C[3:, 3:], factor) + apex)
            lines += [(piece, col, 0.9) for piece in _pieces(ring)]
            C2 = (P @ C[3:, 3:] @ P.T)[:2, :2]
            vals, vecs = np.linalg.eigh(C2)
            t = np.linspace(0, 2 * np.pi, 48)
            e = (vecs * (3.0 * factor * np.sqrt(np.clip(vals, 0, None)))) @ np.stack(
                [np.cos(t), np.sin(t)])
            a2 = apexes[j]
            shapes.append(np.column_stack([a2[0] + e[0], a2[1] + e[1]]))
            shape_colours.append(col)
            half = math.degrees(min(3.0 * factor * _axis_angle_std(C, T[:3, 2]), math.pi / 2))
            z2 = (P @ T[:3, 2])[:2]
            if half > 0 and np.linalg.norm(z2) > 1e-6:
                heading = math.radians(math.degrees(math.atan2(z2[1], z2[0])))
                r = 0.8 * depth * float(np.linalg.norm(z2))
                arc = heading + np.radians(np.linspace(-half, half, 16))
                shapes.append(np.vstack([a2[:2], a2[:2] + r * np.column_stack(
                    [np.cos(arc), np.sin(arc)])]))
                shape_colours.append(col)
    if dots:        # RGBA per dot: a colour name per dot costs a parse each
        dot_colours = to_rgba_array(colours)[np.concatenate(dot_colours)]
    return lines, dots, dot_colours, shapes, shape_colours


def _even_sample(n: int, k: int) -> np.ndarray:
    """Indices of ``min(n, k)`` of ``n`` items spread evenly, first and last included."""
    return np.arange(n) if n <= k else np.unique(np.linspace(0, n - 1, k).round().astype(int))


def _annotate(ax, where: np.ndarray, texts: list[str], colours, dpi: int) -> None:
    """Label the cameras (then the frame origin, in black) at ``where`` (data coordinates),
    moved apart where they would overlap, with a thin line back when moved far."""
    m = len(colours)
    to_display = ax.transData
    anchors_d = to_display.transform(where)
    bb = ax.bbox
    obstacles = to_display.transform(where[:m])
    fs = 8.0
    k = dpi / 72.0
    sizes = np.array([[0.7 * fs * k * len(t) + 6, 1.45 * fs * k] for t in texts])
    centres = place_labels(anchors_d[:len(texts)], sizes, (bb.x0, bb.y0, bb.x1, bb.y1),
                           obstacles=obstacles, gap=4.0 * k)
    inverse = to_display.inverted()
    for i, text in enumerate(texts):
        col = colours[i] if i < m else "black"
        target = inverse.transform(centres[i])
        moved = np.linalg.norm(centres[i] - anchors_d[i]) > 0.5 * sizes[i].max() + 10 * k
        ax.annotate(text, xy=tuple(where[i]), xytext=tuple(target), textcoords="data",
                    xycoords="data", color=col, fontsize=fs, ha="center", va="center",
                    fontweight="bold" if i < m else "normal", zorder=6,
                    annotation_clip=False,
                    arrowprops=({"arrowstyle": "-", "color": col, "lw": 0.6, "alpha": 0.7,
                                 "shrinkA": 0, "shrinkB": 2} if moved else None),
                    bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none",
                          "alpha": 0.7})


def record_rig_pngs(record: CalibrationRecord, details: RunDetails | None) -> RigFigures:
    """:func:`rig_pngs` with the boards the files place in their frame
    (:func:`multieye.outputs.board_marks.record_boards`): the report's rig task, here so
    that a figure worker takes it with the modules it warmed up (no SciPy, which the
    report's other modules import: 0.15-0.3 CPU-s of the rig's worker)."""
    return rig_pngs(record, details, boards=record_boards(record, details))


def warm_up() -> None:
    """Import and load what drawing needs, once for the figures a process draws after it
    (and for the processes it forks: call it in the fork server of the figure workers).

    matplotlib's modules, the 3D axes of the rig, the fonts and the PNG writer, by drawing a
    tiny figure (the figures drawn next are then no slower the first time than later:
    docs/results/report_speed.md); then :func:`gc.freeze`: everything made so far (modules,
    classes, fonts, caches: about 10^5 objects) is left out of the garbage collector's full
    collections, which then look only at what the figures make (60-100 ms a full collection
    before, a few after; a forked worker also keeps sharing those pages with its parent
    instead of copying them when the collector would touch them).
    :mod:`multieye.outputs.report_draw`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy: matplotlib, imported ahead of drawing)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy: matplotlib, imported ahead of drawing)

    fewer_collections()         # matplotlib's artists: the collector every 50,000 allocations
    fig = Figure(figsize=(1.0, 1.0), dpi=10)
    FigureCanvasAgg(fig)
    fig.add_subplot(projection="3d").set_title("x", fontweight="bold")
    _png(fig)
    gc.freeze()
