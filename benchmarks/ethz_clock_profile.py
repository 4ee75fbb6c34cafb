"""Loop-residual profile of one ETH 5_falcon camera stream against the clock offset.

Reproduce from the repository root (a few seconds)::

    PYTHONPATH=src python benchmarks/ethz_clock_profile.py --data ../shared/data/ethz_handeye W_r

Prints, every 20 ms from 200 to 680 ms, the chi-square that
:func:`multieye.estimate.clock.estimate_offset` minimises in its fine step (noise scales and
outliers fixed at the estimated offset) and the RMS rotation / translation loop residuals,
then the estimate itself: whether the profile has one minimum, and where the rotation and
the translation residuals alone are lowest (docs/results/ethz_clock_offset.md).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.estimate import clock
from multieye.io import read_tum

STEM = "datasets/unzipped/5_falcon/5_falcon_merged-2017-04-07-12-36-38"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=Path("../shared/data/ethz_handeye"))
    parser.add_argument("camera", choices=("W_r", "W_d", "W_e"))
    args = parser.parse_args(argv)
    hand = read_tum(args.data / f"{STEM}_falcon_vicon.csv", duplicates="drop")
    E = read_tum(args.data / f"{STEM}_{args.camera}.csv", duplicates="drop")
    est = clock.estimate_offset(E.stamps, E.T, hand.stamps, hand.T, setup="eye-on-hand",
                                search_s=(-1.0, 1.0))
    profile = clock._LoopProfile(E.stamps, g.inv(E.T), hand.stamps, hand.T,
                                 clock.OffsetSearch(setup="eye-on-hand"), (0.0, 0.9))
    profile.set_scales(est.offset_s)
    print("offset (ms) | chi2 | RMS rot (deg) | RMS trans (mm)")
    for d in np.arange(0.200, 0.6801, 0.020):
        rot, trans = profile.residuals(d)
        print(f"{1e3 * d:.0f} | {profile.chi2(d):.0f} | {np.degrees(np.sqrt(np.mean(rot ** 2))):.2f}"
              f" | {1e3 * np.sqrt(np.mean(trans ** 2)):.1f}")
    print(f"estimate {1e3 * est.offset_s:.1f} +- {1e3 * est.std_s:.2f} ms, angular-speed peak "
          f"{1e3 * est.coarse_offset_s:.1f} ms, correlation {est.score:.3f}"
          + (f"; note: {est.note}" if est.note else ""))


if __name__ == "__main__":
    main()
