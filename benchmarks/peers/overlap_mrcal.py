"""mrcal on an overlapping rig, as ``mrcal-calibrate-cameras`` runs it (issue 23, item 4).

Run by an interpreter with mrcal (a peer, never a dependency of multieye)::

    python benchmarks/peers/overlap_mrcal.py CORNERS.npz --out result.json
        [--lensmodel LENSMODEL_OPENCV8]

``CORNERS.npz`` (written by ``bench_overlap.py``): ``cameras`` (names), per camera
``<name>_corners`` (n, rows, cols, 2) and ``<name>_instants`` (n,), ``spacing``, ``size``
(width, height).  One joint solve of every camera, as mrcal does it: ``seed_stereographic``
over all cameras and frames (mrcal's own start of the extrinsics from the shared frames), two
preliminary ``mrcal.optimize`` (geometry, then the stereographic core), then the lens model
(mrcal takes one model for all cameras; ``LENSMODEL_OPENCV8`` by default, since mrcal has no
equidistant fisheye model and the rational one covers the fisheye's field here) with every
extrinsic and board pose, outlier rejection and regularisation.  Writes per camera ``K``,
``dist`` (OpenCV order) and ``T_ref_cam`` (camera 0 the reference) as JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import mrcal
import numpy as np

from mrcal_script import calibrate_cameras  # benchmarks/peers: the same solve


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("corners", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--lensmodel", default="LENSMODEL_OPENCV8")
    ap.add_argument("--focal", type=float, default=500.0)
    args = ap.parse_args(argv)
    data = dict(np.load(args.corners))
    t0 = time.process_time()                  # from the corners in memory to the result
    names = [str(n) for n in data["cameras"]]
    spacing, size = float(data["spacing"]), [int(s) for s in data["size"]]
    rows = []                                   # (frame, camera, corners)
    for j, name in enumerate(names):
        for c, t in zip(data[f"{name}_corners"], data[f"{name}_instants"]):
            rows.append((int(t), j, c))
    rows.sort(key=lambda r: (r[0], r[1]))
    frames = sorted({r[0] for r in rows})
    frame_index = {f: i for i, f in enumerate(frames)}
    ifc = np.array([[frame_index[f], j] for f, j, _ in rows], dtype=np.int32)
    corners = np.stack([c for *_, c in rows])
    intr, rt_cam_ref, _ = calibrate_cameras(corners, ifc, [size] * len(names), spacing,
                                            args.lensmodel, args.focal)
    result = {}
    for j, name in enumerate(names):
        T = np.eye(4)
        if j > 0:
            Rt = mrcal.Rt_from_rt(rt_cam_ref[j - 1])         # T_cam_ref: R then t
            T[:3, :3], T[:3, 3] = Rt[:3], Rt[3]
            T = np.linalg.inv(T)
        fx, fy, cx, cy = intr[j, :4]
        result[name] = {"K": [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]],
                        "dist": intr[j, 4:].tolist(), "fisheye": False,
                        "T_ref_cam": T.tolist()}
    cpu = time.process_time() - t0
    args.out.write_text(json.dumps({"cameras": result, "cpu_s": cpu}))


if __name__ == "__main__":
    sys.exit(main())
