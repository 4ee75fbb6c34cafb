"""multieye on an overlapping rig from the same corners (issue 23, item 4).

Run::

    python benchmarks/peers/overlap_multieye.py CORNERS.npz --out result.json

``CORNERS.npz`` as for ``overlap_opencv.py``.  The library calls the pipeline makes for a rig
without motion capture: each lens started by OpenCV
(:func:`multieye.imaging.calibrate.initial_intrinsics`, which also gives each view's
``T_cam_target``), then the joint problem of every lens, every ``T_ref_cam`` and one board pose
per instant (:func:`multieye.estimate.refine_rig.refine_rig`, started from the co-visibility
graph).  Writes per camera ``K``, ``dist``, ``fisheye``, ``T_ref_cam`` and its ``std``, and ``cpu_s``:
the CPU time from the corners in memory to the result (imports and file reading excluded).

With ``--mocap`` the board's motion capture (``mocap_T``: ``T_world_marker`` per instant, in
the npz) is added: the mixed problem of the image-level refinement
(:func:`multieye.estimate.refine_images.refine_images`), where every image of one instant
shares that instant's motion-capture pose, started from the closed form
(:func:`multieye.solve`) on the PnP poses.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.estimate.refine_rig import refine_rig
from multieye.estimate.rig_residuals import RigViews
from multieye.imaging.calibrate import initial_intrinsics


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("corners", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--mocap", action="store_true", help="use the npz's motion capture too")
    args = ap.parse_args(argv)
    if args.mocap:      # its imports before the clock starts, as the others' (module doc)
        import multieye.estimate.refine_images  # noqa: F401, PLC0415 (only with --mocap)
        import multieye.estimate.uncertainty  # noqa: F401, PLC0415 (only with --mocap)
        import multieye.solvers  # noqa: F401, PLC0415 (only with --mocap)
    data = dict(np.load(args.corners))
    t0 = time.process_time()                  # from the corners in memory to the result
    names = [str(n) for n in data["cameras"]]
    spacing, size = float(data["spacing"]), tuple(int(s) for s in data["size"])
    rows, cols = data[f"{names[0]}_corners"].shape[1:3]
    grid = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * spacing
    obj = np.column_stack([grid, np.zeros(len(grid))])
    lenses, views, poses = [], [], []
    for name in names:
        c = data[f"{name}_corners"].reshape(len(data[f"{name}_corners"]), -1, 2)
        start = initial_intrinsics([(obj, u) for u in c], size, str(data[f"{name}_model"]),
                                   name=name)
        lenses.append(start.intrinsics)
        views.append([(obj, u, int(t)) for u, t in zip(c, data[f"{name}_instants"])])
        poses.append(start.T_cam_target)
    if args.mocap:
        res = with_mocap(data, names, views, lenses, poses)
    else:
        rv = RigViews(dict(zip(names, views)), lenses, free_intrinsics=[True] * len(names))
        res = refine_rig(rv, np.concatenate(poses))
    out = {}
    for j, name in enumerate(names):
        lens = res.intrinsics[j]
        cov = res.covariance[j]
        out[name] = {"K": lens.K.tolist(), "dist": lens.dist.tolist(),
                     "fisheye": lens.model == "fisheye", "T_ref_cam": res.T_ref_cam[j].tolist(),
                     "std_rot_deg": float(np.degrees(np.sqrt(np.trace(cov[:3, :3])))),
                     "std_trans_m": float(np.sqrt(np.trace(cov[3:, 3:])))}
    cpu = time.process_time() - t0
    args.out.write_text(json.dumps({"cameras": out, "pixel_sigma": res.pixel_sigma, "cpu_s": cpu}))


class _Mixed:
    """refine_images' result in refine_rig's names."""

    def __init__(self, ref, names):
        from multieye.estimate.uncertainty import relative_covariance  # noqa: PLC0415 (only with --mocap)
        X = np.asarray(ref.X)
        self.T_ref_cam = g.inv(X[0]) @ X
        self.intrinsics = [ref.intrinsics[j] for j in range(len(names))]
        self.covariance = relative_covariance(X, ref.covariance).covariance
        self.pixel_sigma = ref.pixel_sigma


def with_mocap(data, names, views, lenses, poses):
    """The mixed problem: pixels and motion capture, one mocap pose per instant."""
    from multieye.estimate.refine_images import refine_images  # noqa: PLC0415 (only with --mocap)
    from multieye.solvers import solve  # noqa: PLC0415 (only with --mocap)
    M = data["mocap_T"]
    A = [g.inv(M[[t for *_, t in v]]) for v in views]
    B = [g.inv(T) for T in poses]
    sol = solve(A, B, method="joint")
    obs = [[(o, u, M[t]) for o, u, t in v] for v in views]
    ref = refine_images("eye-to-base", obs, lenses, sol.X, sol.Y, mocap_rot_sigma_rad=None,
                        mocap_trans_sigma_m=None, free_intrinsics=[True] * len(names))
    return _Mixed(ref, names)


if __name__ == "__main__":
    sys.exit(main())
