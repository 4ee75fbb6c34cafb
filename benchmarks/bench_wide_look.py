"""The second look of a wide lens (issue 33, :mod:`multieye.imaging.wide_look`) by itself:
which boards it finds among those the plain detector misses, how far its corners are from
the truth, and what it costs per image.

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_wide_look.py [--seeds 10] [--variants base,hard]
        [--models unified,double-sphere,eucm] [--boofcv /work/shared/data/boofcv_fisheye]

1. The single-camera views of ``bench_wide_render.py`` at 220 degrees (the same poses,
   renders, blur and noise, seed by seed), each lens given: for every view whose board
   :func:`multieye.imaging.detect.detect` does not find, :func:`~multieye.imaging.wide_look.
   second_look` with the true lens; found or not, the RMS and largest distance of its
   corners from where the lens puts the board's points (the board's order is canonical,
   rows + cols odd), and the seconds it took (one process, wall time, loaded machine).
2. Images without a board (uniform noise blurred by 3 px, one per seed) through the same
   lenses: the seconds of a second look that finds nothing.
3. ``boofcv_fisheye`` (26 real images of a lens of about 190 degrees, a 4 x 6 chessboard)
   with BoofCV's own calibration of the lens: the second look run on every image by itself
   (the plain detector finds all 26 boards, so the pipeline never looks twice there): how
   many it finds, and its corners against the plain detector's (nearest corner: the board
   looks the same after a half turn).

This is a script, not a test: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_wide_render import MODELS, N_SPREAD, SINGLE_BOARD, VARIANTS, spread_poses  # noqa: E402

from multieye.core.intrinsics import Intrinsics  # noqa: E402
from multieye.core.lens import project_points  # noqa: E402
from multieye.imaging import wide_look  # noqa: E402
from multieye.imaging.detect import detect  # noqa: E402
from multieye.imaging.targets import Chessboard, target_from_spec  # noqa: E402
from multieye.sim.render import render  # noqa: E402
from multieye.sim.wide_lens import wide_lens  # noqa: E402

FIELD = 220.0
#: BoofCV's calibration of boofcv_fisheye (its fisheye.yaml; tests/real_datasets.py)
BOOFCV_LENS = Intrinsics(K=[[398.77492706579216, 0.0, 319.17879590584187],
                            [0.0, 398.7685638672075, 319.71743712432686], [0.0, 0.0, 1.0]],
                         dist=[1.1331346732794045, -0.24972089525362837, 0.009672326567075125,
                               0.0, 0.0], model="unified", width=640, height=720)


def _timed(image, board, lens):
    t0 = time.perf_counter()
    det = wide_look.second_look(image, board, lens)
    return det, time.perf_counter() - t0


def rendered(variant: str, model: str, seeds: int) -> dict:
    """Section 1 and 2 of the module docstring for one variant and model."""
    board = target_from_spec(SINGLE_BOARD)
    lens = wide_lens(model, FIELD)
    blur, noise = VARIANTS[variant]
    wide_look.second_look(np.zeros((lens.height, lens.width), np.uint8), board, lens)  # views made
    missed, found, errs, secs, empty = 0, 0, [], [], []
    for seed in range(seeds):
        rng = np.random.default_rng([seed, int(FIELD), MODELS.index(model)])
        for k, T in enumerate(spread_poses(lens, FIELD, board, N_SPREAD, rng)):
            image = render(board, lens, T, rng=np.random.default_rng([seed, k]),
                           blur_sigma=blur, noise_sigma=noise)
            if detect(image, board) is not None:
                continue
            missed += 1
            det, s = _timed(image, board, lens)
            secs.append(s)
            if det is not None:
                found += 1
                truth = project_points(board.object_points() @ T[:3, :3].T + T[:3, 3], lens)
                errs.append(np.linalg.norm(det.image_points - truth, axis=1))
        noise_img = np.random.default_rng([seed, 99]).integers(0, 256, (lens.height, lens.width))
        blank = cv2.GaussianBlur(noise_img.astype(np.uint8), (0, 0), 3)
        empty.append(_timed(blank, board, lens)[1])
    e = np.concatenate(errs) if errs else np.full(1, np.nan)
    per_view = [np.sqrt(np.mean(x ** 2)) for x in errs] or [np.nan]
    return {"variant": variant, "model": model, "missed": missed, "found": found,
            "rms_median": float(np.median(per_view)), "rms_max": float(np.max(per_view)),
            "largest": float(e.max()), "s_median": float(np.median(secs)) if secs else np.nan,
            "s_max": max(secs, default=np.nan), "empty_median": float(np.median(empty)),
            "empty_max": max(empty)}


def boofcv(folder: Path) -> None:
    """Section 3 of the module docstring."""
    board = Chessboard(rows=6, cols=4, spacing=1.0)
    wide_look.second_look(np.zeros((720, 640), np.uint8), board, BOOFCV_LENS)
    diffs, secs = [], []
    for k in range(1, 27):
        image = cv2.imread(str(folder / f"{k}.jpg"), cv2.IMREAD_GRAYSCALE)
        plain = detect(image, board)
        det, s = _timed(image, board, BOOFCV_LENS)
        secs.append(s)
        if det is not None and plain is not None:
            diffs.append(np.linalg.norm(det.image_points[:, None] - plain.image_points[None],
                                        axis=2).min(axis=1))
    e = np.concatenate(diffs)
    print(f"\nboofcv_fisheye (field {wide_look.field_deg(BOOFCV_LENS):.0f} deg by the model "
          f"over the image): the second look alone finds {len(diffs)} of 26 boards; its "
          f"corners from the plain detector's: RMS {np.sqrt(np.mean(e ** 2)):.3f} px, median "
          f"{np.median(e):.3f}, largest {e.max():.3f}; seconds per image median "
          f"{np.median(secs):.2f}, largest {max(secs):.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--variants", default="base,hard")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--boofcv", default=None, help="the boofcv_fisheye folder")
    args = ap.parse_args()
    print("| variant | model | views missed by the detector | found by the second look | "
          "corner error px, RMS per view median / largest | largest corner error px | "
          "seconds per missed view median / largest | seconds per image without a board "
          "median / largest |")
    print("|---" * 8 + "|")
    for variant in args.variants.split(","):
        for model in args.models.split(","):
            r = rendered(variant, model, args.seeds)
            print(f"| {variant} | {model} | {r['missed']} | {r['found']} | "
                  f"{r['rms_median']:.3f} / {r['rms_max']:.3f} | {r['largest']:.3f} | "
                  f"{r['s_median']:.2f} / {r['s_max']:.2f} | {r['empty_median']:.2f} / "
                  f"{r['empty_max']:.2f} |", flush=True)
    if args.boofcv:
        boofcv(Path(args.boofcv))


if __name__ == "__main__":
    main()
