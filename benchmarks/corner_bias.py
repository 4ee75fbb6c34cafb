"""Where does the outward bias of the rendered corners come from?  (issue 32, item 1)

Run from the repository root::

    PYTHONPATH=src python benchmarks/corner_bias.py [--poses 24] [--rows base,blur,...]

docs/results/nees.md measured the detected corners of the rendered rigs lying 1.6-2.7
thousandths of a pixel outward of the true ones (the board looks closer).  Here one corner
refinement at a time is run on noise-free images of a chessboard at random poses, started
0.3 px off each true corner (uniform), and its error against the true projection is split
into the component along the direction from the board's image centre (the corners'
centroid) to the corner (``outward``, > 0 away from the centre) and the RMS.

Three renderers at the same poses:

- ``exact`` (written here, independent of multieye's renderers): each pixel around the
  board is the mean of ``--ss`` x ``--ss`` sub-pixels whose rays (the lens
  inverted exactly, :func:`multieye.core.lens.undistort_points`) hit the board plane where
  the printed pattern is evaluated; then the Gaussian blur (``cv2.GaussianBlur``, float);
  rounded to whole grey levels like a camera's;
- ``rays``: :func:`multieye.sim.render.render` (3 x 3 sub-pixels), noise 0;
- ``warp``: :func:`multieye.sim.warped.render_warped`, noise 0.

Conditions, one factor at a time from ``base`` (the base variant's camera: 800 x 600,
f = 520 px, k1 = -0.22, k2 = 0.08; board 6 x 9, squares about 30 px, tilted 35 degrees,
blur 0.7 px, the window of :func:`multieye.imaging.chessboard_corners.corner_window`):
the lens (``pinhole``: no distortion), the tilt, the blur, the square size in pixels,
the window (fixed half-sizes), and the refinement (``cornerSubPix`` as
:func:`~multieye.imaging.chessboard_corners.refine_corners`, and ``--methods`` others).

Per row and renderer: the mean outward error with its standard error, the mean error along
the direction from the image centre (the principal point) to the corner, and the RMS, all
1e-3 px, over every corner of every pose; in brackets, for a method after the first, the
change of its mean outward error from the first method's on the same images (paired, with
its standard error).  This is a script: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import sys
import time
from dataclasses import dataclass

import cv2
import numpy as np

from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, undistort_points
from multieye.core.lie import exp_so3
from multieye.imaging import chessboard_corners as cc
from multieye.imaging.straight_corners import refine_straightened
from multieye.imaging.targets import Chessboard
from multieye.sim.render import render
from multieye.sim.warped import render_warped

BLACK, WHITE = 25.0, 225.0


@dataclass(frozen=True)
class Condition:
    """One row's setting."""

    lens: str = "radtan"          # "radtan" (base camera), "pinhole", "strong" (k1 = -0.35)
    tilt_deg: float = 35.0
    blur: float = 0.7
    square_px: float = 30.0
    window: int | None = None     # None: corner_window's 40 % rule
    noise: float = 0.0            # sensor noise, grey levels


def camera(lens: str) -> Intrinsics:
    dist = {"radtan": [-0.22, 0.08, 0.0, 0.0], "pinhole": [0.0, 0.0, 0.0, 0.0],
            "strong": [-0.35, 0.15, 0.0, 0.0], "pincushion": [0.15, 0.0, 0.0, 0.0]}[lens]
    return Intrinsics(K=[[520.0, 0, 399.5], [0, 520.0, 299.5], [0, 0, 1]], dist=dist,
                      width=800, height=600)


def poses(board: Chessboard, cond: Condition, n: int, seed: int) -> list[np.ndarray]:
    """Random board poses: distance giving ``square_px`` pixels per square, tilted by
    ``tilt_deg`` about a random in-plane axis, turned randomly in its plane, its centre at a
    random point of the image's middle third."""
    rng = np.random.default_rng(seed)
    f, out = 520.0, []
    rows, cols = board.grid_shape()
    centre = np.array([(cols - 1) / 2, (rows - 1) / 2, 0.0]) * board.spacing
    z = f * board.spacing / cond.square_px
    while len(out) < n:
        a = rng.uniform(0, 2 * np.pi)
        R = exp_so3(np.radians(cond.tilt_deg) * np.array([np.cos(a), np.sin(a), 0.0])) \
            @ exp_so3(np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi)]))
        uv = np.array([rng.uniform(800 / 3, 1600 / 3), rng.uniform(200, 400)])
        c = np.array([(uv[0] - 399.5) / f, (uv[1] - 299.5) / f, 1.0]) * z
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, c - R @ centre
        pix = project_points(board.object_points() @ R.T + T[:3, 3], camera(cond.lens))
        if np.all((pix > 30) & (pix < [770, 570])):
            out.append(T)
    return out


def exact_image(board: Chessboard, lens: Intrinsics, T: np.ndarray, ss: int,
                blur: float, noise: float, rng: np.random.Generator,
                whole: bool = True) -> np.ndarray:
    """The whole image, uint8 (float32 unless ``whole``): the board's pattern (white around its squares) over the
    rectangle holding its corners and 1.5 squares more, a grey of 110 beyond."""
    true = project_points(board.object_points() @ T[:3, :3].T + T[:3, 3], lens)
    pad = 1.5 * cc.min_spacing(true, board) + 3 * blur + 4
    (u0, v0), (u1, v1) = np.floor(true.min(axis=0) - pad), np.ceil(true.max(axis=0) + pad)
    u0, v0, u1, v1 = int(max(u0, 0)), int(max(v0, 0)), int(min(u1, 799)), int(min(v1, 599))
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    u = (np.arange(u0, u1 + 1)[:, None] + offs).ravel()
    image = np.full((600, 800), 110.0, dtype=np.float32)
    R, t = T[:3, :3], T[:3, 3]
    o = -R.T @ t
    for va in range(v0, v1 + 1, 16):                     # 16 pixel rows at a time
        v = (np.arange(va, min(va + 16, v1 + 1))[:, None] + offs).ravel()
        uu, vv = np.meshgrid(u, v)
        xy = undistort_points(np.column_stack([uu.ravel(), vv.ravel()]), lens, tol_px=1e-7)
        d = np.column_stack([xy, np.ones(len(xy))]) @ R          # R^T ray, target frame
        lam = -o[2] / d[:, 2]
        x, y = o[0] + lam * d[:, 0], o[1] + lam * d[:, 1]
        i, j = np.floor(x / board.spacing), np.floor(y / board.spacing)
        inside = (i >= -1) & (i < board.cols) & (j >= -1) & (j < board.rows)
        grey = np.where(inside & ((i + j) % 2 == 0), BLACK, WHITE).reshape(uu.shape)
        n_v, n_u = uu.shape[0] // ss, uu.shape[1] // ss
        image[va:va + n_v, u0:u1 + 1] = grey.reshape(n_v, ss, n_u, ss).mean(axis=(1, 3))
    if blur > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur)
    image += noise * rng.standard_normal(image.shape).astype(np.float32)
    if not whole:
        return image
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def refine(gray: np.ndarray, start: np.ndarray, half: int, method: str) -> np.ndarray:
    """One method's refined corners (N, 2) from ``start``."""
    first = cc.refine_corners(gray, start, half)
    if method == "cornersubpix":
        return first
    if method == "twice":                  # a second pass from the first's result
        return cc.refine_corners(gray, first, half)
    if method == "straight":
        return refine_straightened(gray, first, 6, 9, half)
    raise ValueError(method)


def corner_errors(board, cond: Condition, Ts, renderer: str, ss: int,
                  methods: list[str]) -> tuple[dict, list]:
    """Per method and pose the refined corners' errors, and per pose the corners' directions
    from the board's centre (each image rendered once for every method)."""
    lens = camera(cond.lens)
    errs, dirs = {m: [] for m in methods}, []
    start_rng = np.random.default_rng(2)
    for k, T in enumerate(Ts):
        true = project_points(board.object_points() @ T[:3, :3].T + T[:3, 3], lens)
        half = cond.window or cc.corner_window(true, board)
        r = np.random.default_rng(k)
        if renderer == "exact":
            gray = exact_image(board, lens, T, ss, cond.blur, cond.noise, r)
        elif renderer == "rays":
            gray = render(board, lens, T, rng=r, blur_sigma=cond.blur, noise_sigma=cond.noise)
        else:
            gray = render_warped(board, lens, T, rng=r, blur_sigma=cond.blur, noise_sigma=cond.noise)
        start = true + start_rng.uniform(-0.3, 0.3, true.shape)
        for m in methods:
            errs[m].append(refine(gray, start, half, m) - true)
        dirs.append(true - true.mean(axis=0))
    return errs, dirs


def summary(errs: list, dirs: list, radii: list) -> tuple[float, float, float, float]:
    """Mean outward error, its standard error, the mean error along the direction from the
    image centre and the RMS, 1e-3 px."""
    e, d, c = np.concatenate(errs), np.concatenate(dirs), np.concatenate(radii)
    out = np.sum(e * d / np.linalg.norm(d, axis=1)[:, None], axis=1)
    rad = np.sum(e * c / np.linalg.norm(c, axis=1)[:, None], axis=1)
    return (1e3 * out.mean(), 1e3 * out.std() / np.sqrt(out.size), 1e3 * rad.mean(),
            1e3 * np.sqrt(np.mean(e ** 2) * 2))


ROWS = {
    "base": Condition(),
    "pinhole": Condition(lens="pinhole"),
    "strong": Condition(lens="strong"),
    "pincushion": Condition(lens="pincushion"),
    "tilt0": Condition(tilt_deg=0.0),
    "tilt0-pinhole": Condition(tilt_deg=0.0, lens="pinhole"),
    "tilt55": Condition(tilt_deg=55.0),
    "blur0": Condition(blur=0.0),
    "blur1.0": Condition(blur=1.0),
    "blur1.5": Condition(blur=1.5),
    "sq15": Condition(square_px=15.0),
    "sq60": Condition(square_px=60.0),
    "win5": Condition(window=5),
    "win11": Condition(window=11),
    "noise": Condition(noise=2.0),
    "noise14": Condition(noise=14.0, blur=1.0, square_px=15.0),
}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", type=int, default=24)
    ap.add_argument("--ss", type=int, default=12, help="sub-pixels per side, exact renderer")
    ap.add_argument("--rows", default=",".join(ROWS))
    ap.add_argument("--renderers", default="exact,rays,warp")
    ap.add_argument("--methods", default="cornersubpix,straight",
                    help="cornersubpix (refine_corners), twice (it again from its result), "
                         "straight (refine_straightened after it)")
    args = ap.parse_args(argv)
    board = Chessboard(rows=6, cols=9, spacing=0.05)
    renderers = args.renderers.split(",")
    print("| condition | method | " + " | ".join(f"{r}: outward (se) / from image centre / RMS" for r in renderers) + " |")
    print("|---|---|" + "---|" * len(renderers))
    methods = args.methods.split(",")
    for name in args.rows.split(","):
        cond = ROWS[name]
        Ts = poses(board, cond, args.poses, seed=1)
        lens = camera(cond.lens)
        centres = [project_points(board.object_points() @ T[:3, :3].T + T[:3, 3], lens).mean(axis=0)
                   - [399.5, 299.5] for T in Ts]
        cells, t0 = {m: [] for m in methods}, time.time()
        for r in renderers:
            e, d = corner_errors(board, cond, Ts, r, args.ss, methods)
            for m in methods:
                mean, se, rad, rms = summary(e[m], d, [x + y for x, y in zip(d, centres)])
                cells[m].append(f"{mean:+.2f} ({se:.2f}) / {rad:+.2f} / {rms:.1f}")
                if m != methods[0]:        # paired: the same images, the same start
                    change = [a - b for a, b in zip(e[m], e[methods[0]])]
                    dm, dse, _, _ = summary(change, d, [x + y for x, y in zip(d, centres)])
                    cells[m][-1] += f" [{dm:+.2f} ({dse:.2f})]"
        for m in methods:
            print(f"| {name} | {m} | " + " | ".join(cells[m]) + " |", flush=True)
        print(f"({name}: {time.time() - t0:.0f} s)", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
