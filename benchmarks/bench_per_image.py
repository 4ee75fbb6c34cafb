"""CPU time per image of the chessboard path after the decode, in one process (issue 32).

Run from the repository root, once per source tree to compare (the ``multieye`` imported is
the one on ``PYTHONPATH``), in turn::

    PYTHONPATH=OTHER/src python benchmarks/bench_per_image.py --variant warp640jpg
    PYTHONPATH=src       python benchmarks/bench_per_image.py --variant warp640jpg

Every image of a rendering of ``benchmarks/bench_peers.py`` (``--variant``: its presets,
rendered once into ``benchmarks/.cache``) is read and decoded once
(:func:`multieye.imaging.image_file.read_gray`, timed apart), then
:func:`multieye.imaging.batch.process_array` runs on every decoded image, ``--runs`` times
over the whole set, with the camera's lens given (detection, canonical order, PnP) and,
with ``--unknown``, without it (detection only, as with ``model:`` in rig.yaml), OpenCV on
one thread as in multieye's workers.  Printed: CPU ms per image
(``time.process_time``: the load of the machine moves it less than the wall time), the
least and the median of the runs, and the load average; with ``--stages``, one more run
with the main steps timed apart (their own CPU, a few microseconds of timing included).

What it leaves out: the pool (pickling the results, about 30 us per image), the bounded
read and the decode (printed apart), the later stages of ``multieye calibrate``.  This is a
script, not a test: nothing is asserted.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time
from collections import Counter
from pathlib import Path

import cv2

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from bench_peers import rendered, variant_settings  # noqa: E402  (cached renders)

import multieye  # noqa: E402
from multieye.imaging import batch, chessboard_corners as cc, detect, pnp  # noqa: E402
from multieye.imaging.image_file import read_gray  # noqa: E402
from multieye.imaging.targets import target_from_spec  # noqa: E402
from multieye.io import read_intrinsics  # noqa: E402
from multieye.io.rig import load_rig  # noqa: E402

#: The steps ``--stages`` times apart: (module, function); nested ones are inside others.
STAGES = ((cc, "find_chessboard"), (cc, "refine_corners"), (cc, "refine_straightened"),
          (cc, "whole_board"), (cc, "saddle_grid"), (cc, "consistent_grid"),
          (detect, "canonical_order"), (batch, "estimate_pose"), (pnp, "bearings"),
          (pnp, "_ippe_candidates"), (pnp, "_refine"))


def images(variant: str, known: bool) -> tuple[list, object, float]:
    """(decoded image, name, lens or None) of every image of the variant, its board, and
    the CPU seconds the reads and decodes took."""
    folder = rendered(variant_settings(variant))[0]
    rig = load_rig(folder / "rig.yaml")
    out, start = [], time.process_time()
    for cam in rig.cameras.values():
        lens = read_intrinsics(cam.intrinsics) if known else None
        for path in sorted(cam.images.iterdir()):
            out.append((read_gray(str(path))[0], str(path), lens))
    return out, target_from_spec(rig.target), time.process_time() - start


def staged(items, target) -> Counter:
    """CPU seconds per step of :data:`STAGES` over one pass (the functions wrapped)."""
    spent: Counter = Counter()
    saved = [(m, n, getattr(m, n)) for m, n in STAGES]

    def timed(name, f):
        @functools.wraps(f)
        def wrapper(*a, **k):
            t = time.process_time()
            try:
                return f(*a, **k)
            finally:
                spent[name] += time.process_time() - t
        return wrapper

    for m, n, f in saved:
        setattr(m, n, timed(n, f))
    try:
        for image, name, lens in items:
            batch.process_array(image, name, target, lens)
    finally:
        for m, n, f in saved:
            setattr(m, n, f)
    return spent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", default="warp640jpg")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--unknown", action="store_true", help="detection only (no lens)")
    ap.add_argument("--stages", action="store_true")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    items, target, read_s = images(args.variant, not args.unknown)
    n = len(items)
    for image, name, lens in items:                     # warm the caches once
        batch.process_array(image, name, target, lens)
    times = []
    for _ in range(args.runs):
        start = time.process_time()
        results = [batch.process_array(image, name, target, lens) for image, name, lens in items]
        times.append(time.process_time() - start)
    times.sort()
    found = sum(r.detection is not None for r in results)
    print(f"multieye {Path(multieye.__file__).parent}  variant {args.variant}, "
          f"lens {'unknown' if args.unknown else 'known'}: {found} / {n} found; read + decode "
          f"{1e3 * read_s / n:.3f} CPU ms per image; process_array {1e3 * times[0] / n:.3f} "
          f"(least of {args.runs}) / {1e3 * times[len(times) // 2] / n:.3f} (median) CPU ms per "
          f"image; load average {os.getloadavg()[0]:.1f}")
    if args.stages:
        for name, s in staged(items, target).most_common():
            print(f"  {name:22s} {1e3 * s / n:.3f}")


if __name__ == "__main__":
    main()
