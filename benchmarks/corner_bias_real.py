"""The straightened corner refinement against ``cornerSubPix`` alone, on real and rendered images.

Run from the repository root (issue 32, item 1; ``benchmarks/corner_bias.py`` isolates the
bias)::

    PYTHONPATH=src python benchmarks/corner_bias_real.py [--data ../shared/data] [--renders 40]

:func:`multieye.imaging.detect.detect` runs twice on every image: as it is
(``straight``: :func:`multieye.imaging.chessboard_corners.refine_grid` ends with
:func:`multieye.imaging.straight_corners.refine_straightened`) and with that last step left
out (``cornersubpix``).  Figures:

- real images with their published lenses (``boofcv_stereo``: BoofCV's ``stereo.yaml``,
  radial k1 = -0.36; ``young_mocap_cam``: the rational lens of its PROVENANCE.md): per
  image the RMS of the PnP residual (``cv2.solvePnP``, the lens held), median and mean over
  the images, and on how many images the straightened corners' RMS is lower; then
  ``cv2.calibrateCamera`` on all of a camera's images in the lens's model, its RMS;
- rendered images (the base variant's camera, k1 = -0.22, 800 x 600, blur 0.7 px, sensor
  noise 2 grey levels; both renderers, :mod:`multieye.sim.render` and
  :mod:`multieye.sim.warped`; ``--renders`` random poses, tilts 10-60 degrees, squares of
  20-45 px): the corners' RMS and mean outward error against the truth, and
  ``cv2.calibrateCamera`` on them against the true lens (projection error over the observed
  corners after the best-fitting rotation, as ``benchmarks/bench_nees.py``), and its focal
  length's error;
- the CPU time of ``detect`` per image on the rendered images, both ways, interleaved;
- with ``--rigs``: the rigs ``benchmarks/bench_nees.py`` rendered (``--nees-data``), their
  detected corners against the true projections, both ways: the mean outward error
  (``benchmarks/nees_structure.py``'s radial figure) and the corner RMS;
- with ``--timing N``: the CPU time of ``detect`` per image on N images of that base rig,
  both ways in turn, 3 rounds.

Nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import contextlib
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import yaml

from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.imaging import chessboard_corners as cc
from multieye.imaging.detect import detect
from multieye.imaging.targets import Chessboard
from multieye.sim.render import render
from multieye.sim.warped import render_warped

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_nees import lens_error_after_rotation  # noqa: E402
from corner_bias import Condition, camera, poses  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def without_straightening():
    """``refine_grid`` as it was before: ``cornerSubPix`` only."""
    plain = cc.refine_straightened
    cc.refine_straightened = lambda gray, points, rows, cols, half: points
    try:
        yield
    finally:
        cc.refine_straightened = plain


def both(gray: np.ndarray, board: Chessboard):
    """``detect`` as it is and without the straightening: (straight, cornersubpix)."""
    new = detect(gray, board)
    with without_straightening():
        old = detect(gray, board)
    return new, old


def real_sets(data: Path) -> list[tuple[str, Chessboard, Intrinsics, list[Path]]]:
    """(name, board, published lens, images) of each real set."""
    out = []
    ref = yaml.safe_load((data / "boofcv_stereo" / "stereo.yaml").read_text())
    for side in ("left", "right"):
        p, r = ref[side]["pinhole"], ref[side]["radial_tangential"]
        lens = Intrinsics(K=[[p["fx"], 0, p["cx"]], [0, p["fy"], p["cy"]], [0, 0, 1]],
                          dist=[r["radial"][0], r["radial"][1], r["t1"], r["t2"]],
                          width=p["width"], height=p["height"])
        out.append((f"boofcv_stereo {side}", Chessboard(rows=6, cols=4, spacing=0.03), lens,
                    sorted((data / "boofcv_stereo").glob(f"{side}*.jpg"))))
    lens = Intrinsics(K=[[607.88, 0, 641.875], [0, 607.966, 365.585], [0, 0, 1]],
                      dist=[0.458331, -2.87024, 0.00048617, -9.82262e-05, 1.74446, 0.331466,
                            -2.66947, 1.65473], width=1280, height=720)
    folder = data / "young_mocap_cam" / "example_dataset" / "rgb_images"
    out.append(("young_mocap_cam", Chessboard(rows=8, cols=11, spacing=0.03), lens,
                sorted(folder.glob("*.png"))))
    return out


def pnp_rms(det, lens: Intrinsics) -> float:
    ok, rvec, tvec = cv2.solvePnP(det.object_points, det.image_points, lens.K, lens.dist)
    back, _ = cv2.projectPoints(det.object_points, rvec, tvec, lens.K, lens.dist)
    return float(np.sqrt(np.mean(np.sum((back.reshape(-1, 2) - det.image_points) ** 2, axis=1))))


def calibrate(dets: list, lens: Intrinsics) -> tuple[float, np.ndarray, np.ndarray]:
    """``cv2.calibrateCamera`` in ``lens``'s model: RMS, K, distortion."""
    n = lens.dist.size
    flags = {4: cv2.CALIB_FIX_K3, 5: 0, 8: cv2.CALIB_RATIONAL_MODEL}[n]
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    rms, K, d, _, _ = cv2.calibrateCamera([x.object_points.astype(np.float32) for x in dets],
                                          [x.image_points.astype(np.float32) for x in dets],
                                          (lens.width, lens.height), None, None, flags=flags,
                                          criteria=crit)
    return rms, K, d.ravel()[:n]


def real(data: Path) -> None:
    print("| set | images | PnP RMS px, median: cornersubpix / straight | mean | images lower "
          "with straight | calibrateCamera RMS px: cornersubpix / straight |")
    print("|---|---|---|---|---|---|")
    for name, board, lens, files in real_sets(data):
        pairs = [both(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), board) for f in files]
        pairs = [(a, b) for a, b in pairs if a is not None and b is not None]
        new = np.array([pnp_rms(a, lens) for a, _ in pairs])
        old = np.array([pnp_rms(b, lens) for _, b in pairs])
        c_new, c_old = calibrate([a for a, _ in pairs], lens)[0], calibrate([b for _, b in pairs], lens)[0]
        print(f"| {name} | {len(pairs)} of {len(files)} | {np.median(old):.4f} / {np.median(new):.4f} | "
              f"{old.mean():.4f} / {new.mean():.4f} | {np.sum(new < old)} of {len(pairs)} | "
              f"{c_old:.4f} / {c_new:.4f} |", flush=True)


def rendered(n: int) -> None:
    board = Chessboard(rows=6, cols=9, spacing=0.05)
    lens = camera("radtan")
    rng = np.random.default_rng(5)
    views = []
    for k in range(n):
        cond = Condition(tilt_deg=rng.uniform(10, 60), square_px=rng.uniform(20, 45))
        views.append(poses(board, cond, 1, seed=100 + k)[0])
    print("\n| renderer | views | corner RMS px: cornersubpix / straight | mean outward 1e-3 px | "
          "calibrateCamera against the true lens, px | its fx error px | detect CPU ms per image |")
    print("|---|---|---|---|---|---|---|")
    for name, draw in (("rays", render), ("warp", render_warped)):
        errs, outs, dets, cpu = {0: [], 1: []}, {0: [], 1: []}, {0: [], 1: []}, {0: 0.0, 1: 0.0}
        for k, T in enumerate(views):
            gray = draw(board, lens, T, rng=np.random.default_rng(k), blur_sigma=0.7, noise_sigma=2.0)
            true = project_points(board.object_points() @ T[:3, :3].T + T[:3, 3], lens)
            for way in (0, 1):                      # 0: cornersubpix, 1: straight, interleaved
                t0 = time.process_time()
                with (without_straightening() if way == 0 else contextlib.nullcontext()):
                    det = detect(gray, board)
                cpu[way] += time.process_time() - t0
                if det is None:
                    continue
                e = det.image_points - true[det.ids]
                d = true[det.ids] - true[det.ids].mean(axis=0)
                errs[way].append(e)
                outs[way].append(np.sum(e * d / np.linalg.norm(d, axis=1)[:, None], axis=1))
                dets[way].append(det)
        cells = []
        for way in (0, 1):
            e = np.concatenate(errs[way])
            _, K, dist = calibrate(dets[way], lens)
            est = Intrinsics(K=K, dist=dist, width=lens.width, height=lens.height)
            pix = np.concatenate([x.image_points for x in dets[way]])
            cells.append((np.sqrt(np.mean(np.sum(e ** 2, axis=1))), 1e3 * np.concatenate(outs[way]).mean(),
                          lens_error_after_rotation(est, lens, pix), K[0, 0] - lens.K[0, 0],
                          1e3 * cpu[way] / len(views)))
        a, b = cells
        print(f"| {name} | {len(dets[1])} | {a[0]:.4f} / {b[0]:.4f} | {a[1]:+.2f} / {b[1]:+.2f} | "
              f"{a[2]:.4f} / {b[2]:.4f} | {a[3]:+.3f} / {b[3]:+.3f} | {a[4]:.2f} / {b[4]:.2f} |", flush=True)


def nees_rigs(data: Path, variants: list[str], n_rigs: int, images: int) -> None:
    """The detected corners of ``benchmarks/bench_nees.py``'s rendered rigs against their
    true projections (``benchmarks/nees_structure.py``'s replayed poses and its radial
    figure: along the direction from the image's corner centroid, outward > 0)."""
    from nees_structure import true_poses  # noqa: PLC0415  (imports the pipeline)

    from multieye.imaging.targets import target_from_spec
    from multieye.io.intrinsics_files import read_intrinsics
    from multieye.sim.dataset import DatasetSpec
    from bench_nees import VARIANTS, rendered  # noqa: E402

    print(f"\n| variant | rigs x cameras x images | mean outward 1e-3 px (se): cornersubpix / "
          "straight | change, paired (se) | corner RMS px |")
    print("|---|---|---|---|---|")
    for variant in variants:
        spec = DatasetSpec(**VARIANTS[variant][0])
        board = target_from_spec(spec.target)
        out, rms, n = {0: [], 1: []}, {0: [], 1: []}, 0
        for seed in range(n_rigs):
            folder = rendered(data, variant, images, seed)
            poses = true_poses(variant, images, seed)
            for (cam, stem), T in poses.items():
                lens = read_intrinsics(folder / f"{cam}.yaml")
                files = list((folder / cam).glob(stem + ".*"))
                gray = cv2.imread(str(files[0]), cv2.IMREAD_GRAYSCALE)
                new, old = both(gray, board)
                if new is None or old is None or not np.array_equal(new.ids, old.ids):
                    continue
                n += 1
                true = project_points(new.object_points @ T[:3, :3].T + T[:3, 3], lens)
                d = true - true.mean(axis=0)
                d /= np.linalg.norm(d, axis=1)[:, None]
                for way, det in ((0, old), (1, new)):
                    e = det.image_points - true
                    out[way].append(np.sum(e * d, axis=1))
                    rms[way].append(np.sum(e ** 2, axis=1))
        a, b = np.concatenate(out[0]), np.concatenate(out[1])
        se = lambda x: 1e3 * x.std() / np.sqrt(x.size)  # noqa: E731
        print(f"| {variant} | {n_rigs} x 3 x {images} ({n} detected) | {1e3 * a.mean():+.2f} ({se(a):.2f}) / "
              f"{1e3 * b.mean():+.2f} ({se(b):.2f}) | {1e3 * (b - a).mean():+.2f} ({se(b - a):.2f}) | "
              f"{np.sqrt(np.concatenate(rms[0]).mean()):.4f} / {np.sqrt(np.concatenate(rms[1]).mean()):.4f} |",
              flush=True)


def timing(data: Path, n: int, rounds: int = 3) -> None:
    """CPU time of ``detect`` per image, both ways in turn, on the first ``n`` images of
    bench_nees.py's base rig of seed 0 (decoded once, beforehand)."""
    from multieye.imaging.targets import target_from_spec
    from multieye.sim.dataset import DatasetSpec
    from bench_nees import VARIANTS, rendered  # noqa: E402

    board = target_from_spec(DatasetSpec(**VARIANTS["base"][0]).target)
    folder = rendered(data, "base", 100, 0)
    files = sorted(folder.glob("cam*/*.png"))[:n]
    grays = [cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in files]
    cpu = {0: [], 1: []}
    for _ in range(rounds):
        for way in (0, 1):
            t0 = time.process_time()
            with (without_straightening() if way == 0 else contextlib.nullcontext()):
                for g in grays:
                    detect(g, board)
            cpu[way].append(1e3 * (time.process_time() - t0) / len(grays))
    print(f"\ndetect CPU ms per image, {len(grays)} base-rig images, {rounds} rounds in turn (load "
          f"{os.getloadavg()[0]:.1f}): cornersubpix {', '.join(f'{x:.2f}' for x in cpu[0])}; "
          f"straight {', '.join(f'{x:.2f}' for x in cpu[1])}; median ratio "
          f"{np.median(cpu[1]) / np.median(cpu[0]):.3f}")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path,
                    default=Path(os.environ.get("MULTIEYE_SHARED_DATA", ROOT.parent / "shared" / "data")))
    ap.add_argument("--renders", type=int, default=40)
    ap.add_argument("--rigs", type=int, default=0,
                    help="also the rendered rigs of bench_nees.py (seeds 0..rigs-1)")
    ap.add_argument("--images", type=int, default=100)
    ap.add_argument("--variants", default="base,hd-jpeg,noisy")
    ap.add_argument("--nees-data", type=Path, default=Path("/tmp/bench_nees"))
    ap.add_argument("--timing", type=int, default=0,
                    help="time detect on this many images of bench_nees.py's base rig")
    args = ap.parse_args(argv)
    if args.data.is_dir():
        real(args.data)
    else:
        print(f"no shared data at {args.data}: real sets left out")
    if args.renders:
        rendered(args.renders)
    if args.rigs:
        nees_rigs(args.nees_data, args.variants.split(","), args.rigs, args.images)
    if args.timing:
        timing(args.nees_data, args.timing)


if __name__ == "__main__":
    main()
