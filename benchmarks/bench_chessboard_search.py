"""The chessboard search on rendered views of many kinds: time per image and corner error
against the truth, this checkout against another, side by side (issue 32, item 3).

Run from the repository root::

    python benchmarks/bench_chessboard_search.py [--views 40] [--before /work/main/src]

For every variant (image size 640 x 480 to 1920 x 1080, the sim's ray tracer or a board
picture warped through its homography and the lens over a cluttered scene
(:mod:`multieye.sim.warped`), boards 5 x 7 to 8 x 11, blur 0.8-1.5 px, the board near
(squares up to 50 px, seen steeply) or far (squares of 7-15 px), PNG or JPEG at quality 85),
``--views`` board poses in view (turned up to about 35 degrees, seeded), rendered once. Each
image is handed to :func:`multieye.imaging.chessboard_corners.locate` of this checkout and,
with ``--before``, to the same function of the checkout whose ``src`` folder is given
(loaded from its file), in turn image by image (A B A B), and timed with
``time.process_time`` (CPU time: the load of the machine moves it less than the wall time) in this one process.  Printed per variant and code: images found, the
time per image (mean, median, max: the mean carries the slow fallbacks), and the corner
error against the projection of the true corners (RMS and max over the found boards).

Times depend on the load of the machine; the alternation keeps the two codes' figures
comparable.  Nothing is asserted: tests/imaging/test_chessboard_detectors.py checks the
behaviour.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from multieye.core import geometry as g
from multieye.core.lens import project_points
from multieye.imaging import chessboard_corners as cc
from multieye.imaging.targets import Chessboard
from multieye.sim.dataset import default_intrinsics
from multieye.sim.render import render, visible
from multieye.sim.warped import render_warped

#: name: (width, height, renderer, rows, cols, blur px, distance scale, format)
VARIANTS = {
    "rays 800x600 6x9": (800, 600, "rays", 6, 9, 0.7, 1.0, "png"),
    "warp 960x720 6x9": (960, 720, "warp", 6, 9, 0.8, 1.0, "png"),
    "warp 960x720 6x9 blur 1.5": (960, 720, "warp", 6, 9, 1.5, 1.0, "png"),
    "rays 960x720 6x9 near": (960, 720, "rays", 6, 9, 0.8, 0.6, "png"),
    "warp 960x720 6x9 far": (960, 720, "warp", 6, 9, 0.8, 2.0, "png"),
    "rays 960x720 6x9 far jpg": (960, 720, "rays", 6, 9, 0.8, 2.0, "jpg"),
    "warp 640x480 5x7 jpg": (640, 480, "warp", 5, 7, 0.8, 1.0, "jpg"),
    "rays 640x480 6x9": (640, 480, "rays", 6, 9, 0.8, 1.0, "png"),
    "warp 1280x720 8x11": (1280, 720, "warp", 8, 11, 0.8, 1.0, "png"),
    "warp 1920x1080 8x11 blur 1.2": (1920, 1080, "warp", 8, 11, 1.2, 1.0, "png"),
}


def views(variant: tuple, n: int, seed: int = 1):
    """``n`` rendered images of one variant with the board's true corners: [(gray, truth)]."""
    w, h, renderer, rows, cols, blur, distance, fmt = variant
    rng = np.random.default_rng(seed)
    board = Chessboard(rows=rows, cols=cols, spacing=0.05)
    intr = default_intrinsics(1, w, h, rng=rng)[0]
    centre = np.array([(cols - 1) * 0.025, (rows - 1) * 0.025, 0.0])
    out = []
    for k in range(20 * n):
        if len(out) == n:
            break
        T = g.transform_from_rotvec(rng.normal(scale=0.35, size=3), [0.0, 0.0, 0.0])
        T[:3, 3] = [rng.normal(scale=0.1), rng.normal(scale=0.08),
                    distance * rng.uniform(0.8, 1.2)] - T[:3, :3] @ centre
        if not visible(board, intr, T, border_px=8):
            continue
        if renderer == "warp":
            img = render_warped(board, intr, T, rng=np.random.default_rng(k), blur_sigma=blur)
        else:
            img = render(board, intr, T, rng=np.random.default_rng(k), blur_sigma=blur,
                         noise_sigma=2.0)
        if fmt == "jpg":
            img = cv2.imdecode(cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 85])[1],
                               cv2.IMREAD_GRAYSCALE)
        out.append((img, project_points(board.object_points() @ T[:3, :3].T + T[:3, 3], intr)))
    return board, out


def load_before(src: Path):
    """``chessboard_corners`` of another checkout, loaded from its file."""
    spec = importlib.util.spec_from_file_location(
        "before_chessboard_corners", src / "multieye" / "imaging" / "chessboard_corners.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def error(corners, truth) -> np.ndarray:
    """Per-corner error in the detector's order or its half turn, whichever fits."""
    e = [np.linalg.norm(c - truth, axis=1) for c in (corners, corners[::-1])]
    return min(e, key=lambda x: x.max())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--views", type=int, default=40)
    ap.add_argument("--before", type=Path, help="src folder of the checkout to compare with")
    ap.add_argument("--variant", action="append", help="only these (names of VARIANTS)")
    ap.add_argument("--dataset", type=Path, action="append", default=[],
                    help="also the images of a rendered dataset folder (bench_peers.py's "
                         "cache): time and the two codes' corner difference (no truth here)")
    args = ap.parse_args()
    codes = {"this": cc}
    if args.before:
        codes = {"before": load_before(args.before), "this": cc}
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}, OpenCV "
          f"{cv2.__version__}; {args.views} views per variant\n")
    print("| variant | code | found | CPU ms per image: mean / median / max | corner error px: "
          "RMS / max |")
    print("|---|---|---|---|---|")
    for name in args.variant or VARIANTS:
        board, images = views(VARIANTS[name], args.views)
        times = {c: [] for c in codes}
        errs = {c: [] for c in codes}
        for img, truth in images:
            for code, module in codes.items():          # A B, A B, ...
                start = time.process_time()
                corners = module.locate(img, board)
                times[code].append(1e3 * (time.process_time() - start))
                if corners is not None:
                    errs[code].append(error(corners, truth))
        for code in codes:
            t = np.array(times[code])
            e = np.concatenate(errs[code]) if errs[code] else np.array([np.nan])
            print(f"| {name} | {code} | {len(errs[code])}/{len(images)} | {t.mean():.1f} / "
                  f"{np.median(t):.1f} / {t.max():.0f} | {np.sqrt(np.mean(e ** 2)):.3f} / "
                  f"{e.max():.2f} |", flush=True)
    for folder in args.dataset:
        dataset(folder, codes)
    print(f"\nload average at the end: {os.getloadavg()[0]:.2f}")


def dataset(folder: Path, codes: dict) -> None:
    """Every image of a rendered dataset through each code's ``locate``, in turn: CPU ms per
    image and the largest difference between the codes' corners (either order)."""
    import re

    text = (folder / "rig.yaml").read_text()
    rows, cols = (int(re.search(rf"{k}: (\d+)", text).group(1)) for k in ("rows", "cols"))
    board = Chessboard(rows=rows, cols=cols, spacing=0.05)
    paths = sorted(p for p in folder.glob("cam*/*") if p.suffix in (".png", ".jpg"))
    times = {c: [] for c in codes}
    found = {c: 0 for c in codes}
    apart = 0.0
    for path in paths:
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        out = {}
        for code, module in codes.items():
            start = time.process_time()
            out[code] = module.locate(img, board)
            times[code].append(1e3 * (time.process_time() - start))
            found[code] += out[code] is not None
        got = [c for c in out.values() if c is not None]
        if len(got) == 2:
            apart = max(apart, float(error(got[0], got[1]).max()))
    for code in codes:
        t = np.array(times[code])
        print(f"| {folder.name} | {code} | {found[code]}/{len(paths)} | {t.mean():.1f} / "
              f"{np.median(t):.1f} / {t.max():.0f} | corners of the two codes {apart:.3f} px "
              "apart at most |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
