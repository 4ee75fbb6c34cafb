"""Memory of `multieye calibrate` with a 5-million-row motion-capture file (issue 19).

Run from the repository root::

    python benchmarks/bench_big_mocap.py [--rows 5000000] [--format tum|csv] [--keep FOLDER]

1. Renders a small dataset (2 cameras x 8 images, 320 x 240, start of the clock at 100 s so
   that stamps a few microseconds apart stay distinct in float64;
   :func:`multieye.sim.dataset.render_dataset`, seed 3) into a temporary folder.
2. Replaces its motion capture by ``--rows`` rows over the same time span: the rendered
   trajectory interpolated (translations linearly, rotations by spherical interpolation), so
   the rows are the true motion and the calibration must still succeed; written in chunks
   as ``t tx ty tz qx qy qz qw`` with 9 decimals (about 100 bytes a row); with
   ``--format csv`` as a CSV file ``mocap.csv`` with the header ``t,tx,ty,tz,qx,qy,qz,qw``
   (the generic CSV reader, line by line) and rig.yaml pointed at it.
3. Runs ``python -m multieye calibrate DATASET -o OUT --processes 1`` as a subprocess and
   reports its exit status, wall time and peak resident memory: ``ru_maxrss`` of
   ``resource.getrusage(RUSAGE_CHILDREN)`` (the largest resident set of a child that ended;
   with ``--processes 1`` the run is one process), checked against 1 GB.

Linux (``ru_maxrss`` in kilobytes).  Exit status 0 when the run succeeded within 1 GB.
"""

from __future__ import annotations

import argparse
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from multieye.io.tum import read_tum
from multieye.sim.dataset import DatasetSpec, render_dataset

LIMIT_BYTES = 1_000_000_000


def dense_mocap(path: Path, rows: int, chunk: int = 500_000, fmt: str = "tum") -> int:
    """Rewrite a TUM file with ``rows`` rows interpolated over its time span (as CSV beside it,
    ``mocap.csv``, with ``fmt="csv"``); returns bytes."""
    traj = read_tum(path)
    t, T = traj.stamps, traj.T
    slerp = Slerp(t, Rotation.from_matrix(T[:, :3, :3]))
    dense = np.linspace(t[0], t[-1], rows)
    tmp = path.with_suffix(".dense")
    with open(tmp, "w") as f:
        if fmt == "csv":
            f.write("t,tx,ty,tz,qx,qy,qz,qw\n")
        else:
            f.write("# t tx ty tz qx qy qz qw (interpolated, bench_big_mocap.py)\n")
        for a in range(0, rows, chunk):
            s = dense[a:a + chunk]
            xyz = np.column_stack([np.interp(s, t, T[:, i, 3]) for i in range(3)])
            q = slerp(s).as_quat()
            np.savetxt(f, np.column_stack([s, xyz, q]), fmt="%.9f",
                       delimiter="," if fmt == "csv" else " ")
    if fmt == "csv":
        target = path.with_name("mocap.csv")
        tmp.replace(target)
        path.unlink()
        rig = path.with_name("rig.yaml")
        rig.write_text(rig.read_text().replace("file: mocap.txt", "file: mocap.csv"))
        return target.stat().st_size
    tmp.replace(path)
    return path.stat().st_size


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=5_000_000)
    ap.add_argument("--format", choices=("tum", "csv"), default="tum")
    ap.add_argument("--keep", type=Path, default=None,
                    help="render into this folder and keep it (default: a temporary one)")
    args = ap.parse_args()
    work = args.keep or Path(tempfile.mkdtemp(prefix="bench-big-mocap-"))
    try:
        ds = work / "ds"
        if not (ds / "rig.yaml").exists():
            render_dataset(ds, DatasetSpec(n_cameras=2, images_per_camera=8, width=320,
                                           height=240, start_time_s=100.0, processes=1),
                           seed=3)
            size = dense_mocap(ds / "mocap.txt", args.rows, fmt=args.format)
        else:
            size = max(p.stat().st_size for p in ds.glob("mocap.*"))
        out = work / "out"
        shutil.rmtree(out, ignore_errors=True)
        cmd = [sys.executable, "-m", "multieye", "calibrate", str(ds), "-o", str(out),
               "--processes", "1"]
        start = time.perf_counter()
        res = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - start
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
        print(f"rows: {args.rows}, format: {args.format}, file: {size / 1e6:.1f} MB")
        print(f"command: {' '.join(cmd)}")
        print(f"exit status: {res.returncode}, wall time: {wall:.1f} s, "
              f"peak resident memory: {peak / 1e6:.0f} MB (limit {LIMIT_BYTES / 1e6:.0f} MB)")
        if res.returncode != 0:
            print(res.stdout[-2000:], res.stderr[-2000:], sep="\n")
        return 0 if res.returncode == 0 and peak <= LIMIT_BYTES else 1
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
