"""Which wide-lens starts keep rivals: other optima of the model's valley the views do not
exclude (issue 33; :attr:`multieye.imaging.generic_start.LensFit.rivals`).

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_valley_rivals.py [--seeds 4] [--views 20]

Per model and field of view (:func:`multieye.sim.wide_lens.wide_lens`), ``--seeds`` sets of
``--views`` board views with 0.2 px of noise (:func:`multieye.sim.wide_lens.board_views`,
``np.random.default_rng(seed)``), each started as the pipeline starts a wide lens
(:func:`multieye.imaging.generic_start.generic_start`).  Printed per set: the kept lens'
focal length and valley parameter, the truth's, and each rival's focal length and its sum of
squares above the kept one's in units of the pixel noise variance.  A script, not a test.
"""

from __future__ import annotations

import argparse

import numpy as np

from multieye.imaging.generic_start import RIVAL_SIGMA2, generic_start
from multieye.sim.wide_lens import IMAGE_SIDE, board_views, wide_lens

CASES = (("double-sphere", 190.0), ("double-sphere", 220.0), ("unified", 190.0),
         ("unified", 220.0), ("eucm", 190.0), ("fisheye", 170.0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--views", type=int, default=20)
    args = ap.parse_args()
    print(f"rivals within {RIVAL_SIGMA2:g} sigma^2; {args.views} views, 0.2 px")
    print("model          field  seed  truth fx  kept fx  kept dist[0]  rivals (fx: sigma^2)")
    for model, fov in CASES:
        true = wide_lens(model, fov)
        named = 0
        for seed in range(args.seeds):
            views, _ = board_views(true, fov, args.views, np.random.default_rng(seed),
                                   noise_px=0.2)
            fit = generic_start(views, (IMAGE_SIDE, IMAGE_SIDE), model)
            rivals = ", ".join(f"{r.intrinsics.K[0, 0]:.0f}: {r.delta_sigma2:.2f}"
                               for r in fit.rivals) or "-"
            named += bool(fit.rivals)
            print(f"{model:<14} {fov:5.0f}  {seed:4d}  {true.K[0, 0]:8.1f}  "
                  f"{fit.intrinsics.K[0, 0]:7.1f}  {fit.intrinsics.dist[0]:12.3f}  {rivals}")
        print(f"{model:<14} {fov:5.0f}  sets with rivals: {named} of {args.seeds}")


if __name__ == "__main__":
    main()
