"""``multieye calibrate`` on the rendered wall-board rig with motion capture (eye-on-hand)
and three still ChArUco boards (issue 34, item 1): the image views, the rig's motion and the
motion capture in one problem.  Per seed: the exit status, per camera the error of
``T_ref_cam`` and of ``X = T_body_cam`` against the truth with their squared Mahalanobis
distances under the reported covariance, and each board's position error.

The rendered ``mocap.txt`` is the true body pose (no noise), so X's covariance reflects the
motion-capture noise the run assumes (rig.yaml's, else the defaults), not the real one.

Run: ``python benchmarks/bench_motion_mocap_pipeline.py [SEEDS...]`` (default seeds 1 2 3;
20 instants, 640 x 480, 4 cameras; about 10 s per seed).
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from multieye.core.lie import log_so3
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset


def _error(T, true):
    return np.concatenate([log_so3(T[:3, :3] @ true[:3, :3].T), T[:3, 3] - true[:3, 3]])


def _mahal(e, cov):
    return float(e @ np.linalg.solve(np.asarray(cov), e))


def run(seed: int, root: Path) -> None:
    ds, out = root / f"ds{seed}", root / f"out{seed}"
    render_wall_dataset(ds, WallSpec(n_instants=20, width=640, height=480), seed=seed,
                        mocap=True)
    r = subprocess.run(["multieye", "calibrate", str(ds), "-o", str(out), "--processes", "1"],
                       capture_output=True, text=True)
    print(f"seed {seed}: exit {r.returncode}")
    if r.returncode not in (0, 3):
        print(r.stderr.strip().splitlines()[-1])
        return
    truth = json.loads((ds / "ground_truth.json").read_text())
    rec = json.loads((out / "calibration.json").read_text())
    body_ref = np.array(truth["T_body_ref"])
    for n, cam in rec["cameras"].items():
        true = np.array(truth["T_ref_cam"][n])
        e = _error(np.array(cam["T_ref_cam"]), true)
        m = 0.0 if n == rec["reference_camera"] else _mahal(e, cam["covariance"])
        ux = cam["uncertainty"]["T_body_cam"]
        ex = _error(np.array(cam["T_body_cam"]), body_ref @ true)
        print(f"  {n}: T_ref_cam {np.degrees(np.linalg.norm(e[:3])):.4f} deg "
              f"{1e3 * np.linalg.norm(e[3:]):.2f} mm (d2 {m:.1f}); X "
              f"{np.degrees(np.linalg.norm(ex[:3])):.4f} deg {1e3 * np.linalg.norm(ex[3:]):.2f} mm"
              f" (sd {ux['std_rot_deg']:.4f} deg {1e3 * ux['std_trans_m']:.2f} mm, "
              f"d2 {_mahal(ex, ux['covariance']):.1f})")
    for b, t in rec["targets"].items():
        e = _error(np.array(t["T_world_target"]), np.array(truth["T_world_board"][b]))
        print(f"  board {b}: {1e3 * np.linalg.norm(e[3:]):.2f} mm "
              f"(sd {1e3 * t['std_trans_m']:.2f} mm, d2 {_mahal(e, t['covariance']):.1f})")


if __name__ == "__main__":
    seeds = [int(s) for s in sys.argv[1:]] or [1, 2, 3]
    with tempfile.TemporaryDirectory() as tmp:
        for s in seeds:
            run(s, Path(tmp))
