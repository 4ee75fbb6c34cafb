"""The per-image chessboard path's faster forms give the former forms' numbers bit for bit
(issue 32: speed without changing results).  Each former form is written out here as it
was (main 8ef1055) and compared on random inputs: the straightened patches
(:func:`multieye.imaging.straight_corners.refine_straightened`), the saddle check's
radius and correlations, the points one square beyond the grid (``whole_board``), the
smallest spacing, the board-colour greys and affine map of ``canonical_order`` and the
Newton polish of ``undistort_points``."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from multieye.core import lens
from multieye.core.intrinsics import Intrinsics
from multieye.imaging import chessboard_corners as cc
from multieye.imaging import detect
from multieye.imaging import straight_corners as sc
from multieye.imaging.targets import Chessboard


# --------------------------------------------------------------- former forms (8ef1055)

def _former_edge_frames(points, rows, cols):
    g = points.reshape(rows, cols, 2)
    da, ha = _former_differences(g, 0)
    db, hb = _former_differences(g, 1)
    da, db, ha, hb = (x.reshape(-1, 2) for x in (da, db, ha, hb))
    jac = np.stack([da, db], axis=-1)
    return np.linalg.inv(jac), ha, hb, np.stack([np.hypot(*da.T), np.hypot(*db.T)], axis=1)


def _former_differences(g, axis):
    if axis == 1:
        d, h = _former_differences(g.transpose(1, 0, 2), 0)
        return d.transpose(1, 0, 2), h.transpose(1, 0, 2)
    d, h = np.empty_like(g), np.empty_like(g)
    d[1:-1] = 0.5 * (g[2:] - g[:-2])
    d[0] = -1.5 * g[0] + 2.0 * g[1] - 0.5 * g[2]
    d[-1] = 1.5 * g[-1] - 2.0 * g[-2] + 0.5 * g[-3]
    h[1:-1] = g[2:] - 2.0 * g[1:-1] + g[:-2]
    h[0], h[-1] = h[1], h[-2]
    return d, h


def _former_bend(ux, uy, frames):
    inv, ha, hb, lengths = frames
    c = lambda x: x[:, None, None]  # noqa: E731
    a = c(inv[:, 0, 0]) * ux + c(inv[:, 0, 1]) * uy
    b = c(inv[:, 1, 0]) * ux + c(inv[:, 1, 1]) * uy
    near_row = np.abs(a) * c(lengths[:, 0]) < np.abs(b) * c(lengths[:, 1])
    a2, b2 = 0.5 * a * a, 0.5 * b * b
    return (np.where(near_row, c(hb[:, 0]) * b2, c(ha[:, 0]) * a2),
            np.where(near_row, c(hb[:, 1]) * b2, c(ha[:, 1]) * a2))


def _former_blocks(gray, centres, r):
    h, w = gray.shape
    x, y = centres[:, 0], centres[:, 1]
    if x.min() >= r and y.min() >= r and x.max() < w - r and y.max() < h - r:
        windows = np.lib.stride_tricks.sliding_window_view(gray, (2 * r + 1, 2 * r + 1))
        return windows[y - r, x - r]
    reach = np.arange(-r, r + 1)
    iy = np.clip(y[:, None] + reach, 0, h - 1)
    ix = np.clip(x[:, None] + reach, 0, w - 1)
    return gray[iy[:, :, None], ix[:, None, :]]


def _former_refine_straightened(gray, points, rows, cols, half):
    n = len(points)
    frames = tuple(x.astype(np.float32) for x in _former_edge_frames(points, rows, cols))
    t = half + sc.MARGIN_PX
    side = 2 * t + 1
    base = np.rint(points).astype(np.int64)
    shift = (base - points).astype(np.float32)
    off = np.arange(-t, t + 1, dtype=np.float32)
    ux = (off + shift[:, 0, None])[:, None, :]
    uy = (off + shift[:, 1, None])[:, :, None]
    bx, by = _former_bend(ux, uy, frames)
    block = _former_blocks(gray, base, t + 1).astype(np.float32)
    tiles = block[:, 1:-1, 1:-1] + 0.5 * bx * (block[:, 1:-1, 2:] - block[:, 1:-1, :-2])
    tiles += 0.5 * by * (block[:, 2:, 1:-1] - block[:, :-2, 1:-1])
    per_row = int(np.ceil(np.sqrt(n)))
    mosaic_rows = int(np.ceil(n / per_row))
    full = np.empty((mosaic_rows * per_row, side, side), np.float32)
    full[:n], full[n:] = tiles, tiles[:1]
    mosaic = full.reshape(mosaic_rows, per_row, side, side).transpose(0, 2, 1, 3)
    mosaic = np.ascontiguousarray(mosaic.reshape(mosaic_rows * side, per_row * side))
    k = np.arange(n)
    centre = np.column_stack([(k % per_row) * side, (k // per_row) * side]) + float(t)
    pts = (centre - shift).astype(np.float32).reshape(-1, 1, 2)
    cv2.cornerSubPix(mosaic, pts, (half, half), (-1, -1), sc.SUBPIX_CRITERIA)
    u = pts.reshape(-1, 2).astype(np.float64) - centre + shift
    back = _former_bend(u[:, :1, None], u[:, 1:, None], tuple(x.astype(np.float64) for x in frames))
    return points + u + np.column_stack([back[0].ravel(), back[1].ravel()])


def _former_saddle(gray, points, target):
    """The radii and correlations :func:`cc.saddle_grid` computed."""
    rows, cols = target.grid_shape()
    grid = points.reshape(rows, cols, 2)
    length = lambda v: np.sqrt(np.einsum("...i,...i->...", v, v))  # noqa: E731
    near = np.full((rows, cols), np.inf)
    down, right = length(grid[1:] - grid[:-1]), length(grid[:, 1:] - grid[:, :-1])
    near[1:], near[:-1] = np.minimum(near[1:], down), np.minimum(near[:-1], down)
    near[:, 1:], near[:, :-1] = np.minimum(near[:, 1:], right), np.minimum(near[:, :-1], right)
    radius = np.maximum(cc.SADDLE_RADIUS * near.ravel(), cc.SADDLE_MIN_RADIUS_PX)
    phi = np.linspace(0.0, 2 * np.pi, cc.SADDLE_SAMPLES, endpoint=False)
    u = (points[:, :1] + radius[:, None] * np.cos(phi)).astype(np.float32)
    v = (points[:, 1:] + radius[:, None] * np.sin(phi)).astype(np.float32)
    ring = cv2.remap(gray, u, v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
    ring -= ring.mean(axis=1, keepdims=True)
    turned = np.roll(ring, cc.SADDLE_SAMPLES // 2, axis=1)
    power = np.maximum(np.einsum("ij,ij->i", ring, ring), 1e-9)
    return radius, np.einsum("ij,ij->i", ring, turned) / power


def _former_beyond(points, target):
    """The points one square beyond the grid and the squares they extend, as
    :func:`cc.whole_board` computed them."""
    rows, cols = target.grid_shape()
    grid = points.reshape(rows, cols, 2)
    beyond, steps = [], []
    for g in (grid, grid.transpose(1, 0, 2)):
        for edge, inner, third in ((g[0], g[1], g[min(2, len(g) - 1)]),
                                   (g[-1], g[-2], g[max(-3, -len(g))])):
            beyond.append(3 * edge - 3 * inner + third if len(g) >= 3 else 2 * edge - inner)
            steps.append(np.sqrt(np.einsum("...i,...i->...", edge - inner, edge - inner)))
    return np.concatenate(beyond), np.concatenate(steps)


def _former_undistort(uv, intrinsics, tol_px=1e-6, max_newton=8):
    """:func:`lens.undistort_points`' Newton polish as it was: five lens evaluations per
    step, one more at the end."""
    xy = lens._initial_undistort(uv, intrinsics)
    h = 1e-7
    for _ in range(max_newton):
        f0 = lens._project_normalised(xy, intrinsics)
        r = uv - f0
        err = np.hypot(r[:, 0], r[:, 1])
        active = np.isfinite(err) & (err > 0.01 * tol_px)
        if not np.any(active):
            break
        xa = xy[active]
        fx1 = lens._project_normalised(xa + [h, 0.0], intrinsics)
        fx0 = lens._project_normalised(xa - [h, 0.0], intrinsics)
        fy1 = lens._project_normalised(xa + [0.0, h], intrinsics)
        fy0 = lens._project_normalised(xa - [0.0, h], intrinsics)
        a, c = ((fx1 - fx0) / (2 * h)).T
        b, d = ((fy1 - fy0) / (2 * h)).T
        det = a * d - b * c
        ra = r[active]
        with np.errstate(divide="ignore", invalid="ignore"):
            dx = (d * ra[:, 0] - b * ra[:, 1]) / det
            dy = (-c * ra[:, 0] + a * ra[:, 1]) / det
        xy[active] = xa + np.column_stack([dx, dy])
    err = np.hypot(*(uv - lens._project_normalised(xy, intrinsics)).T)
    xy[~(err <= tol_px)] = np.nan
    return xy


# --------------------------------------------------------------- inputs

def _image(rng, shape=(150, 200)) -> np.ndarray:
    """Blurred noise: every patch has gradients, so cornerSubPix moves and every branch of
    the bend (both edges nearer somewhere) is taken."""
    return cv2.GaussianBlur(rng.integers(0, 256, size=shape, dtype=np.uint8), (0, 0), 1.5)


def _bent_grid(rng, rows, cols, shape=(150, 200), margin=-5.0) -> np.ndarray:
    """A grid of ``rows`` x ``cols`` points with perspective, a quadratic bend and noise,
    placed so that some points come within ``-margin`` px of the image's edge (or beyond)."""
    j, i = np.meshgrid(np.arange(cols), np.arange(rows))
    step = rng.uniform(6, 20)
    x = j * step * (1 + 0.02 * i) + 0.4 * rng.normal() * (i - rows / 2) ** 2
    y = i * step * rng.uniform(0.7, 1.3) + 0.4 * rng.normal() * (j - cols / 2) ** 2
    pts = np.column_stack([x.ravel(), y.ravel()]) + rng.normal(scale=0.4, size=(rows * cols, 2))
    span = pts.max(axis=0) - pts.min(axis=0)
    room = np.array(shape[::-1]) - span - 2 * margin
    return pts - pts.min(axis=0) + margin + rng.uniform(0, 1, 2) * np.maximum(room, 0)


# --------------------------------------------------------------- the comparisons

@pytest.mark.parametrize("seed", range(4))
def test_straightened_patches_as_before(seed):
    rng = np.random.default_rng(seed)
    gray = _image(rng)
    for k in range(12):
        rows, cols = (int(v) for v in rng.integers(3, 9, size=2))
        pts = _bent_grid(rng, rows, cols, margin=(-3.0 if k % 3 == 0 else 12.0))
        half = int(rng.integers(2, 9))
        image = gray if k % 4 else np.asfortranarray(gray)          # a non-contiguous image too
        np.testing.assert_array_equal(sc.refine_straightened(image, pts, rows, cols, half),
                                      _former_refine_straightened(gray, pts, rows, cols, half))


def test_squares_gathered_as_before():
    rng = np.random.default_rng(7)
    for k in range(200):
        gray = rng.integers(0, 256, size=tuple(rng.integers(20, 60, size=2)), dtype=np.uint8)
        if k % 5 == 0:                          # other image types and layouts too
            gray = gray.astype(np.float32) if k % 10 else gray[:, ::-1]
        r = int(rng.integers(1, 8))
        h, w = gray.shape
        lo = -3 if k % 2 else r
        centres = np.column_stack([rng.integers(lo, w - lo, 25), rng.integers(lo, h - lo, 25)])
        np.testing.assert_array_equal(sc._gather(gray, centres, r),
                                      _former_blocks(gray, centres, r).astype(np.float32))


def test_grid_checks_compute_as_before():
    """saddle_grid's radii and correlations, whole_board's points beyond the grid and the
    smallest spacing, on bent grids partly outside the image."""
    rng = np.random.default_rng(3)
    gray = _image(rng, (120, 160))
    seen = {}
    former_correlations = cc._saddle_correlations

    def spy(image, points, radius):
        seen["radius"], seen["points"] = radius, points
        seen["r"] = former_correlations(image, points, radius)
        return seen["r"]

    for _ in range(300):
        rows, cols = (int(v) for v in rng.integers(3, 9, size=2))
        board = Chessboard(rows=rows, cols=cols, spacing=0.05)
        R, C = board.grid_shape()
        pts = _bent_grid(rng, R, C, (120, 160), margin=-8.0)
        cc._saddle_correlations = spy
        try:
            cc.saddle_grid(gray, pts, board)
            radius, r = seen["radius"], seen["r"]
            whole = cc.whole_board(gray, pts, board)
        finally:
            cc._saddle_correlations = former_correlations
        want_radius, want_r = _former_saddle(gray, pts, board)
        np.testing.assert_array_equal(radius, want_radius)
        np.testing.assert_array_equal(r, want_r)
        p, step = _former_beyond(pts, board)
        edge, inner, third, linear = cc._beyond_indices(R, C)
        got = 3 * pts[edge] - 3 * pts[inner] + pts[third]
        np.testing.assert_array_equal(got, p)
        np.testing.assert_array_equal(cc._lengths(pts[edge] - pts[inner]), step)
        assert not linear.any()
        length = lambda v: np.sqrt(np.einsum("...i,...i->...", v, v))  # noqa: E731
        g = pts.reshape(R, C, 2)
        spacing = float(min(length(g[1:] - g[:-1]).min(), length(g[:, 1:] - g[:, :-1]).min()))
        assert cc.min_spacing(pts, board) == spacing
        assert cc.corner_window(pts, board) == int(np.clip(0.4 * spacing, 2, 11))
        assert isinstance(whole, bool)


def test_canonical_order_arithmetic_as_before():
    rng = np.random.default_rng(11)
    gray = _image(rng, (120, 160))
    board = Chessboard(rows=5, cols=7, spacing=0.05)
    orders = detect._orders(board)
    for _ in range(50):
        pts = _bent_grid(rng, 5, 7, (120, 160), margin=4.0)
        np.testing.assert_array_equal(detect._affine(orders, pts),
                                      (orders.pinv @ (pts - pts.mean(axis=0))).T)
        centres = pts[orders.squares].mean(axis=1)
        box = (centres[:, None, :] + detect._BOX_OFFSETS[None]).reshape(1, -1, 2).astype(np.float32)
        samples = cv2.remap(gray, box[..., 0], box[..., 1], cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_REPLICATE)
        np.testing.assert_array_equal(detect._square_greys(gray, pts, orders.squares),
                                      samples.reshape(len(centres), 9).astype(np.float64).mean(axis=1))


@pytest.mark.parametrize("model, dist", [
    ("pinhole", (-0.35, 0.15, 1e-3, -2e-3, -0.03)),
    ("pinhole", (0.0, 0.0, 0.0, 0.0, 0.0)),
    ("fisheye", (0.05, -0.02, 0.01, -0.003)),
])
def test_undistortion_polish_as_before(model, dist):
    lens_ = Intrinsics(K=np.array([[500.0, 0, 319.5], [0, 505.0, 239.5], [0, 0, 1]]),
                       dist=np.array(dist), width=640, height=480, model=model)
    rng = np.random.default_rng(5)
    uv = rng.uniform([-40, -40], [680, 520], size=(400, 2))
    np.testing.assert_array_equal(lens.undistort_points(uv, lens_),
                                  _former_undistort(uv.copy(), lens_))


def _former_turn_order(object_points, T_target_turned):
    P = np.asarray(object_points, dtype=np.float64).reshape(-1, 3)
    if len(P) < 2:
        return None
    H = np.asarray(T_target_turned, dtype=np.float64)
    moved = P @ H[:3, :3].T + H[:3, 3]
    d = np.linalg.norm(moved[:, None, :] - P[None, :, :], axis=2)
    idx = np.argmin(d, axis=1)
    scale = float(np.ptp(P[:, :2], axis=0).max())
    if np.any(d[np.arange(len(P)), idx] > 1e-6 * max(scale, 1e-9)):
        return None
    if len(np.unique(idx)) != len(P):
        return None
    return idx.astype(np.int64)


def test_turn_orders_kept_by_value_as_before():
    """The half turn's point order, kept per board and turn: the former answer for whole
    and partial views, symmetric or not, and every call its own writable copy."""
    from multieye.imaging.order_turn import half_turn, turn_order

    rng = np.random.default_rng(13)
    for rows, cols in ((5, 7), (6, 9), (4, 6), (3, 3)):
        board = Chessboard(rows=rows, cols=cols, spacing=0.04)
        turn = half_turn(board)
        assert (turn is None) == ((rows + cols) % 2 == 1)
        if turn is None:
            continue
        assert half_turn(board) is turn and not turn.order.flags.writeable
        P = board.object_points()
        for view in (P, P[: len(P) // 2], P[rng.permutation(len(P))], P + [0.01, 0.0, 0.0]):
            for H in (turn.T_target_turned, np.eye(4)):
                want = _former_turn_order(view, H)
                got = turn_order(view, H)
                assert (got is None) == (want is None)
                if got is not None:
                    np.testing.assert_array_equal(got, want)
                    got[:] = -1                                 # a copy: the next is whole
                    np.testing.assert_array_equal(turn_order(view, H), want)
