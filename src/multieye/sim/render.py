"""Synthetic grayscale images of a calibration target seen by a camera.

Inverse mapping per pixel: each output pixel is split into ``supersample`` x ``supersample``
sub-pixels; the viewing ray of every sub-pixel (through the full distortion model, see
:mod:`.camera_model`) is intersected with the board plane ``z = 0`` of the target frame, the
printed pattern is evaluated exactly there (squares, circles, marker bits, all analytic),
and the sub-pixels are averaged (box anti-aliasing). Around the pattern the board has a
white margin; outside the board a smooth random background texture. A Gaussian blur
(optics) and Gaussian sensor noise follow; the result is uint8.

Geometry is exact up to the box filter: corners rendered here land where
:func:`multieye.core.lens.project_points` puts them, which is what the detection
and PnP tests rely on.

Synopsis
--------
>>> import numpy as np
>>> from multieye.core.intrinsics import Intrinsics
>>> from multieye.imaging.targets import Chessboard
>>> from multieye.sim.render import render, visible
>>> cam = Intrinsics(K=[[600, 0, 399.5], [0, 600, 299.5], [0, 0, 1]], width=800, height=600)
>>> board = Chessboard(rows=6, cols=9, spacing=0.04)
>>> T_cam_target = np.eye(4); T_cam_target[:3, 3] = [-0.16, -0.1, 0.8]
>>> visible(board, cam, T_cam_target)
True
>>> render(board, cam, T_cam_target, rng=np.random.default_rng(0)).shape
(600, 800)
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache, singledispatch

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse

from multieye.core.arguments import transform, with_fields
from multieye.core.errors import InputError
from multieye.core.intrinsics import WIDE_MODELS, Intrinsics
from multieye.core.lens import project_points, projectable, undistort_points, unproject_points
from multieye.imaging.targets import (AprilGrid, ArucoMarker, AsymmetricCircleGrid, Charuco, Chessboard,
                                     CircleGrid, Target)

__all__ = ["render", "render_boards", "visible", "board_outline"]

F64 = NDArray[np.float64]

#: Pixel step of the exactly undistorted grid that the sub-pixel rays are interpolated from.
_RAY_GRID_STEP = 4
#: Grid nodes around those without a ray (outside the lens's region) whose sub-pixels are
#: traced exactly instead of interpolated (:func:`_subpixel_rays`).
_EXACT_NODES = 3


def _image_size(intrinsics: Intrinsics, width, height) -> tuple[int, int]:
    w = intrinsics.width if width is None else width
    h = intrinsics.height if height is None else height
    if w is None or h is None:
        raise InputError("image size unknown: give width and height (the intrinsics carry none)")
    if int(w) <= 0 or int(h) <= 0:
        raise InputError(f"image size must be positive, got {w}x{h}")
    return int(w), int(h)


def _default_margin(target: Target) -> float:
    """White border around the printed pattern, metres: one spacing (at least 5 mm)."""
    return max(target.spacing, 0.005)


def board_outline(target: Target, *, margin: float | None = None, per_edge: int = 16) -> F64:
    """Points along the edge of the board (pattern plus white margin), target frame.

    Returns
    -------
    ndarray, shape (4 * per_edge, 3)
        Metres, z = 0, going round the rectangle.
    """
    m = _default_margin(target) if margin is None else float(margin)
    x0, x1, y0, y1 = target.bounds()
    x0, x1, y0, y1 = x0 - m, x1 + m, y0 - m, y1 + m
    s = np.linspace(0.0, 1.0, per_edge, endpoint=False)
    edges = [
        np.column_stack([x0 + s * (x1 - x0), np.full_like(s, y0)]),
        np.column_stack([np.full_like(s, x1), y0 + s * (y1 - y0)]),
        np.column_stack([x1 - s * (x1 - x0), np.full_like(s, y1)]),
        np.column_stack([np.full_like(s, x0), y1 - s * (y1 - y0)]),
    ]
    xy = np.vstack(edges)
    return np.column_stack([xy, np.zeros(len(xy))])


def visible(target: Target, intrinsics: Intrinsics, T_cam_target: ArrayLike, *,
            width: int | None = None, height: int | None = None, margin: float | None = None,
            border_px: float = 5.0) -> bool:
    """Whether the whole board (pattern and margin) is seen, front side, inside the image.

    True when every point of :func:`board_outline` is in front of the camera and projects
    at least ``border_px`` inside the image, and the camera is on the printed side of the
    board. The board is convex and the projection continuous, so its outline inside means
    the board inside, except for lenses whose distortion folds (outline points whose ray
    cannot be traced back are then counted as outside).
    """
    T = transform(T_cam_target, "T_cam_target", rigid=True)
    w, h = _image_size(intrinsics, width, height)
    outline = board_outline(target, margin=margin)
    P = outline @ T[:3, :3].T + T[:3, 3]
    if not np.all(projectable(P, intrinsics)):      # pinhole, fisheye: z > 0
        return False
    # camera centre in the target frame: its z sign says which face it sees
    cam_z = -(T[:3, :3].T @ T[:3, 3])[2]
    if (cam_z < 0) != target.z_into_board:
        return False
    uv = project_points(P, intrinsics)
    inside = ((uv[:, 0] >= border_px - 0.5) & (uv[:, 0] <= w - 0.5 - border_px)
              & (uv[:, 1] >= border_px - 0.5) & (uv[:, 1] <= h - 0.5 - border_px))
    if not np.all(inside):
        return False
    if intrinsics.model in WIDE_MODELS:             # rays beyond 90 degrees: compare rays
        back = unproject_points(uv, intrinsics, tol_px=1e-3)
        return bool(np.allclose(back, P / np.linalg.norm(P, axis=1)[:, None], atol=1e-6))
    back = undistort_points(uv, intrinsics, tol_px=1e-3)
    return bool(np.allclose(back, P[:, :2] / P[:, 2:3], atol=1e-6))


# --------------------------------------------------------------------------- rays

def _ray_key(intrinsics: Intrinsics, w: int, h: int) -> tuple:
    """Hashable identity of a camera for the ray cache (Intrinsics holds arrays)."""
    return (intrinsics.K.tobytes(), intrinsics.dist.tobytes(), intrinsics.model, w, h)


@lru_cache(maxsize=8)
def _coarse_rays(key: tuple) -> tuple[NDArray[np.float32], float, float]:
    """Unit viewing rays every _RAY_GRID_STEP pixels, shape (gh, gw, 3), and the grid origin.

    NaN where the lens model cannot be inverted.
    """
    K, dist, model, w, h = key
    intrinsics = Intrinsics(K=np.frombuffer(K).reshape(3, 3), dist=np.frombuffer(dist), model=model)
    g = _RAY_GRID_STEP
    u0 = v0 = -0.5 - 2 * g
    us = u0 + g * np.arange(int(np.ceil((w + 4 * g) / g)) + 1)
    vs = v0 + g * np.arange(int(np.ceil((h + 4 * g) / g)) + 1)
    uu, vv = np.meshgrid(us, vs)
    rays = unproject_points(np.column_stack([uu.ravel(), vv.ravel()]), intrinsics, tol_px=1e-4)
    return rays.reshape(len(vs), len(us), 3).astype(np.float32), u0, v0


def _cubic_weights(pos: F64, n: int) -> F64:
    """Catmull-Rom interpolation matrix (sparse), shape (len(pos), n), from grid positions.

    Row k holds the weights of the 4 grid nodes around ``pos[k]``; the kernel reproduces
    quadratics, so the error on the smooth ray field is third order in the grid step.
    """
    i = np.floor(pos).astype(np.int64)
    t = pos - i
    t2, t3 = t * t, t * t * t
    w = np.column_stack([(-t3 + 2 * t2 - t) / 2, (3 * t3 - 5 * t2 + 2) / 2,
                         (-3 * t3 + 4 * t2 + t) / 2, (t3 - t2) / 2])
    cols = np.clip(i[:, None] + np.arange(-1, 3)[None, :], 0, n - 1)
    rows = np.repeat(np.arange(len(pos)), 4)
    return sparse.csr_matrix((w.ravel().astype(np.float32), (rows, cols.ravel())), shape=(len(pos), n))


def _subpixel_rays(intrinsics: Intrinsics, w: int, h: int, ss: int,
                   roi: tuple[int, int, int, int]) -> tuple[list[F64], NDArray[np.bool_]]:
    """Unit rays (x, y, z arrays) of the sub-pixels of the pixel rectangle ``roi``.

    ``roi = (u_min, v_min, u_max, v_max)``, pixel indices, end exclusive; arrays of shape
    ((v_max - v_min) * ss, (u_max - u_min) * ss), interpolated (separable Catmull-Rom, exact
    weights) from the exactly undistorted coarse grid, and a mask of the sub-pixels whose
    ray is defined (the lens model can be inverted at all grid nodes around them).
    """
    grid, u0, v0 = _coarse_rays(_ray_key(intrinsics, w, h))
    ua, va, ub, vb = roi
    g = _RAY_GRID_STEP
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    pu = ((np.arange(ua, ub)[:, None] + offs[None, :]).ravel() - u0) / g
    pv = ((np.arange(va, vb)[:, None] + offs[None, :]).ravel() - v0) / g
    # only the block of grid nodes that the rectangle needs
    ja, jb = int(np.floor(pu.min())) - 1, int(np.floor(pu.max())) + 3
    ia, ib = int(np.floor(pv.min())) - 1, int(np.floor(pv.max())) + 3
    block = grid[ia:ib, ja:jb].copy()
    Wu = _cubic_weights(pu - ja, jb - ja)
    Wv = _cubic_weights(pv - ia, ib - ia)
    bad = np.isnan(block[:, :, 0])
    block[bad] = 0.0
    # columns first on the small grid block, then rows: the big result comes out C-ordered
    rays = [Wv @ np.ascontiguousarray((Wu @ block[:, :, k].T).T) for k in range(3)]
    if not bad.any():
        return rays, np.ones(rays[0].shape, dtype=bool)
    # near the edge of the lens's region the ray field steepens (a square root for the
    # double-sphere and eucm models) and the interpolation errs by up to 0.15 px: there,
    # and on the edge itself, every sub-pixel's ray is computed exactly
    band = cv2.dilate(bad.astype(np.uint8), np.ones((2 * _EXACT_NODES + 1,) * 2, np.uint8))
    near = (abs(Wv) @ np.ascontiguousarray((abs(Wu) @ band.T.astype(np.float32)).T)) > 0
    iv, iu = np.nonzero(near)
    exact = unproject_points(np.column_stack([ua + (iu + 0.5) / ss - 0.5,
                                              va + (iv + 0.5) / ss - 0.5]), intrinsics)
    valid = np.ones(near.shape, dtype=bool)
    valid[iv, iu] = np.isfinite(exact[:, 0])
    for k in range(3):
        rays[k][iv, iu] = np.nan_to_num(exact[:, k])
    return rays, valid


# --------------------------------------------------------------------------- patterns

@singledispatch
def _reflectance(target: Target, x: NDArray, y: NDArray) -> NDArray[np.float32]:
    """Reflectance (0 black .. 1 white) of the printed pattern at target-frame points.

    ``x``, ``y``: arrays of one shape, metres (float32 is plenty: 1e-7 relative).
    """
    raise InputError(f"no renderer for target type {type(target).__name__}")


@_reflectance.register
def _(target: Chessboard, x, y):
    i = np.floor(x * (1.0 / target.spacing)).astype(np.int32)
    j = np.floor(y * (1.0 / target.spacing)).astype(np.int32)
    inside = (i >= -1) & (i < target.cols) & (j >= -1) & (j < target.rows)
    black = inside & (((i + j) & 1) == 0)
    return (~black).astype(np.float32)


def _circle_reflectance(dx2: NDArray, radius: float) -> NDArray[np.float32]:
    return (dx2 >= radius * radius).astype(np.float32)


@_reflectance.register
def _(target: CircleGrid, x, y):
    s = target.spacing
    c = np.clip(np.rint(x / s), 0, target.cols - 1)
    r = np.clip(np.rint(y / s), 0, target.rows - 1)
    return _circle_reflectance((x - c * s) ** 2 + (y - r * s) ** 2, target.circle_diameter / 2)


@_reflectance.register
def _(target: AsymmetricCircleGrid, x, y):
    s = target.spacing
    best = np.full(x.shape, np.inf)
    r_low = np.floor(y / (s / 2))
    for r in (r_low, r_low + 1):
        r = np.clip(r, 0, target.rows - 1)
        shift = 0.5 * (r % 2)
        c = np.clip(np.rint(x / s - shift), 0, target.cols - 1)
        best = np.minimum(best, (x - (c + shift) * s) ** 2 + (y - r * s / 2) ** 2)
    return _circle_reflectance(best, target.circle_diameter / 2)


@dataclass(frozen=True)
class _CharucoLayout:
    """Where a ChArUco board's markers are, in the canonical frame.

    Attributes
    ----------
    square_marker : ndarray, shape (rows, cols), int
        Per square the index of its marker; -1 for a black square.
    corner0 : ndarray, shape (k, 2)
        Per marker its corner 0, metres.
    axis_u, axis_v : ndarray, shape (k, 2)
        Per marker the unit vectors of its bit columns and rows.
    bits : ndarray, shape (k, n, n), float32
        Per marker its image (border included), 0 black, 1 white.
    """

    square_marker: np.ndarray
    corner0: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray
    bits: np.ndarray


@lru_cache(maxsize=16)
def _charuco_layout(target: Charuco) -> _CharucoLayout:
    """The marker layout of a ChArUco board (:class:`_CharucoLayout`)."""
    board = target.opencv_board()
    dictionary = board.getDictionary()
    nbits = dictionary.markerSize
    s = target.spacing
    square_marker = np.full((target.rows, target.cols), -1, dtype=np.int64)
    obj = np.asarray(board.getObjPoints(), dtype=np.float64)[:, :, :2]  # OpenCV board frame
    ids = np.asarray(board.getIds()).ravel()
    c0 = obj[:, 0] - s                                                  # canonical frame
    eu = (obj[:, 1] - obj[:, 0]) / np.linalg.norm(obj[:, 1] - obj[:, 0], axis=1, keepdims=True)
    ev = (obj[:, 3] - obj[:, 0]) / np.linalg.norm(obj[:, 3] - obj[:, 0], axis=1, keepdims=True)
    centres = obj.mean(axis=1)
    for k, (cx, cy) in enumerate(centres):
        square_marker[int(cy // s), int(cx // s)] = k
    bits = np.stack([cv2.aruco.generateImageMarker(dictionary, int(i), nbits + 2, borderBits=1)
                     for i in ids]).astype(np.float32) / 255.0
    return _CharucoLayout(square_marker=square_marker, corner0=c0, axis_u=eu, axis_v=ev, bits=bits)


@_reflectance.register
def _(target: Charuco, x, y):
    lay = _charuco_layout(target)
    square_marker, c0, bits = lay.square_marker, lay.corner0, lay.bits
    eu, ev = lay.axis_u, lay.axis_v
    s, m = target.spacing, target.marker_size
    n = bits.shape[1]
    i = np.floor(x / s).astype(np.int64) + 1
    j = np.floor(y / s).astype(np.int64) + 1
    inside = (i >= 0) & (i < target.cols) & (j >= 0) & (j < target.rows)
    k = np.where(inside, square_marker[np.clip(j, 0, target.rows - 1), np.clip(i, 0, target.cols - 1)], -2)
    out = np.ones(x.shape, dtype=np.float32)
    out[k == -1] = 0.0
    sel = k >= 0
    ks = k[sel]
    dx = x[sel] - c0[ks, 0]
    dy = y[sel] - c0[ks, 1]
    u = np.floor((dx * eu[ks, 0] + dy * eu[ks, 1]) / m * n).astype(np.int64)
    v = np.floor((dx * ev[ks, 0] + dy * ev[ks, 1]) / m * n).astype(np.int64)
    in_marker = (u >= 0) & (u < n) & (v >= 0) & (v < n)
    val = np.ones(ks.shape, dtype=np.float32)
    val[in_marker] = bits[ks[in_marker], v[in_marker], u[in_marker]]
    out[sel] = val
    return out


@lru_cache(maxsize=16)
def _aruco_bits(dictionary: str, marker_id: int) -> np.ndarray:
    """One ArUco marker's cells (border included), 0 black, 1 white, float32."""
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    return cv2.aruco.generateImageMarker(d, int(marker_id), d.markerSize + 2,
                                         borderBits=1).astype(np.float32) / 255.0


@_reflectance.register
def _(target: ArucoMarker, x, y):
    bits = _aruco_bits(target.dictionary, target.id)
    n = bits.shape[0]
    u = np.floor(x / target.spacing * n).astype(np.int64)
    v = np.floor(y / target.spacing * n).astype(np.int64)
    inside = (u >= 0) & (u < n) & (v >= 0) & (v < n)
    out = np.ones(x.shape, dtype=np.float32)
    out[inside] = bits[v[inside], u[inside]]
    return out


@_reflectance.register
def _(target: AprilGrid, x, y):
    size, pitch = target.spacing, target.pitch
    bits = target.tag_images()
    tc = np.floor(x / pitch).astype(np.int64)
    tr = np.floor(y / pitch).astype(np.int64)
    lx = x - tc * pitch
    ly = y - tr * pitch
    out = np.ones(x.shape, dtype=np.float32)
    # black squares in the gaps at every tag corner (also outside the outer tags)
    corner = (lx >= size) & (ly >= size) & (tc >= -1) & (tc < target.cols) & (tr >= -1) & (tr < target.rows)
    out[corner] = 0.0
    in_tag = (lx < size) & (ly < size) & (tc >= 0) & (tc < target.cols) & (tr >= 0) & (tr < target.rows)
    b = size / 10
    col = np.clip(np.floor(lx[in_tag] / b).astype(np.int64), 0, 9)
    row = 9 - np.clip(np.floor(ly[in_tag] / b).astype(np.int64), 0, 9)
    tag = tr[in_tag] * target.cols + tc[in_tag]
    out[in_tag] = bits[tag, row, col]
    return out


# --------------------------------------------------------------------------- image

def _background(rng: np.random.Generator, w: int, h: int) -> NDArray[np.float32]:
    """Smooth random texture, grey levels about 50..170, no sharp corners.

    Three octaves of uniform noise (4, 16 and 64 cells across) summed on the finest cell
    grid, then one bicubic enlargement to the image.
    """
    fine = (max(2, 64 * h // max(w, h)), 64)
    img = np.full(fine, 110.0, dtype=np.float32)
    for cells, amp in ((4, 45.0), (16, 20.0), (64, 8.0)):
        small = rng.uniform(-amp, amp, size=(max(2, cells * h // max(w, h)), cells)).astype(np.float32)
        img += cv2.resize(small, fine[::-1], interpolation=cv2.INTER_CUBIC)
    return cv2.resize(img, (w, h), interpolation=cv2.INTER_CUBIC)


def _board_roi(target: Target, intrinsics: Intrinsics, T: F64, w: int, h: int, margin: float):
    """Pixel rectangle that holds the board's image, or None when it is not in view."""
    outline = board_outline(target, margin=margin, per_edge=64)
    P = outline @ T[:3, :3].T + T[:3, 3]
    if not np.all(projectable(P, intrinsics)):
        return (0, 0, w, h)       # board leaves the lens's valid region: trace every pixel
    uv = project_points(P, intrinsics)
    if not np.all(np.isfinite(uv)):
        return (0, 0, w, h)
    ua = int(np.clip(np.floor(uv[:, 0].min()) - 2, 0, w))
    ub = int(np.clip(np.ceil(uv[:, 0].max()) + 3, 0, w))
    va = int(np.clip(np.floor(uv[:, 1].min()) - 2, 0, h))
    vb = int(np.clip(np.ceil(uv[:, 1].max()) + 3, 0, h))
    if ua >= ub or va >= vb:
        return None
    return (ua, va, ub, vb)


@dataclass(frozen=True)
class RenderStyle:
    """The options of :func:`render` (see there), taken as one argument or as
    keyword arguments."""

    width: int | None = None
    height: int | None = None
    rng: np.random.Generator | None = None
    supersample: int = 3
    blur_sigma: float = 0.6
    noise_sigma: float = 1.5
    margin: float | None = None
    inverted: bool = False
    black: float = 25.0
    white: float = 225.0


def render(target: Target, intrinsics: Intrinsics, T_cam_target: ArrayLike,
           style: RenderStyle = RenderStyle(), **kw) -> NDArray[np.uint8]:
    """Render a grayscale image of ``target`` at pose ``T_cam_target``.

    Parameters
    ----------
    target : Target
    intrinsics : Intrinsics
        Pinhole (any OpenCV distortion) or fisheye.
    T_cam_target : array_like, shape (4, 4)
        Pose of the target in the camera frame, metres.
    width, height : int, optional
        Image size; default from the intrinsics.
    rng : numpy.random.Generator, optional
        Background texture, illumination and noise; default a fixed seed (same image twice).
    supersample : int
        Sub-pixels per pixel side (anti-aliasing by box filter). 3 keeps corner positions to
        a few hundredths of a pixel.
    blur_sigma : float
        Gaussian blur of the optics, pixels (0: none).
    noise_sigma : float
        Standard deviation of additive Gaussian sensor noise, grey levels (0: none).
    margin : float, optional
        White border of the board around the pattern, metres (default one spacing).
    inverted : bool
        Print the board in negative (light pattern on a dark board), e.g. the light circles
        on dark of the Open3DV board.
    black, white : float
        Grey levels of black and white print under full illumination.

    Returns
    -------
    ndarray, shape (height, width), uint8

    Notes
    -----
    Degenerate cases: a board seen edge-on or from behind is still rendered (seen from
    behind it appears mirrored, as through a transparent sheet; use :func:`visible` to
    avoid it); a board crossing the camera plane is rendered where its rays hit it; pixels
    whose ray cannot be traced back through the lens model (outside the field of a fisheye,
    or where a polynomial model folds) show background.
    """
    return render_boards([(target, T_cam_target)], intrinsics, style, **kw)


def render_boards(boards, intrinsics: Intrinsics, style: RenderStyle = RenderStyle(),
                  **kw) -> NDArray[np.uint8]:
    """:func:`render` of several boards in one image (boards on the walls of a room).

    Parameters
    ----------
    boards : sequence of (Target, array_like (4, 4))
        Each board and its ``T_cam_target``; drawn farthest first, so a nearer board hides
        a farther one.
    intrinsics, style, **kw
        As for :func:`render`.

    Returns
    -------
    ndarray, shape (height, width), uint8
    """
    o = with_fields(style, kw, RenderStyle, "style")
    w, h = _image_size(intrinsics, o.width, o.height)
    if int(o.supersample) < 1:
        raise InputError(f"supersample must be a positive integer, got {o.supersample}")
    rng = np.random.default_rng(0) if o.rng is None else o.rng
    posed = [(t, transform(T, "T_cam_target", rigid=True)) for t, T in boards]
    posed.sort(key=lambda tT: -np.linalg.norm(tT[1][:3, 3]))
    image = _background(rng, w, h)
    for target, T in posed:
        _draw_board(image, target, intrinsics, T, o, rng)
    if o.blur_sigma > 0:
        image = cv2.GaussianBlur(image, (0, 0), o.blur_sigma)
    if o.noise_sigma > 0:
        image += o.noise_sigma * rng.standard_normal(size=image.shape, dtype=np.float32)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def _draw_board(image: NDArray[np.float32], target: Target, intrinsics: Intrinsics, T: F64,
                style: RenderStyle, rng: np.random.Generator) -> None:
    """Draw one board into ``image`` (in place), its illumination drawn from ``rng``."""
    h, w = image.shape
    ss = int(style.supersample)
    m = _default_margin(target) if style.margin is None else float(style.margin)
    black, white = style.black, style.white
    roi = _board_roi(target, intrinsics, T, w, h, m)
    if roi is not None:
        ua, va, ub, vb = roi
        (rx, ry, rz), valid = _subpixel_rays(intrinsics, w, h, ss, roi)
        R = T[:3, :3].astype(np.float32)
        o = (-(T[:3, :3].T @ T[:3, 3])).astype(np.float32)   # camera centre, target frame
        # ray direction in the target frame, R^T d; hit z = 0 at o + lam * R^T d
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = -o[2] / (R[0, 2] * rx + R[1, 2] * ry + R[2, 2] * rz)
            x = o[0] + lam * (R[0, 0] * rx + R[1, 0] * ry + R[2, 0] * rz)
            y = o[1] + lam * (R[0, 1] * rx + R[1, 1] * ry + R[2, 1] * rz)
        x0, x1, y0, y1 = target.bounds()
        on_board = valid & (lam > 0) & (x >= x0 - m) & (x <= x1 + m) & (y >= y0 - m) & (y <= y1 + m)
        with np.errstate(invalid="ignore"):    # NaN off the board: masked out just below
            refl = _reflectance(target, x, y)
        refl *= on_board
        size = (ub - ua, vb - va)
        # box filter over the sub-pixels: exact block means for an integer factor
        cover = cv2.resize(on_board.astype(np.float32), size, interpolation=cv2.INTER_AREA)
        white_part = cv2.resize(refl, size, interpolation=cv2.INTER_AREA)
        if style.inverted:
            white_part = cover - white_part
        # illumination: a gentle gradient across the image
        gx, gy = rng.uniform(-0.1, 0.1, size=2) / max(w, h)
        uu, vv = np.meshgrid(np.arange(ua, ub) - w / 2, np.arange(va, vb) - h / 2)
        light = (0.95 + gx * uu + gy * vv).astype(np.float32)
        board = (black * cover + (white - black) * white_part) * light
        image[va:vb, ua:ub] = board + (1.0 - cover) * image[va:vb, ua:ub]
