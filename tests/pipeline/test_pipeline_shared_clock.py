"""End to end: two cameras triggered together, stamped by one clock 40 ms behind the motion
capture, rendered at the same instants; ``time_offset="auto"`` puts them on one clock (one
offset, estimated in the joint refinement) and recovers it."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.io import Trajectory, write_opencv_intrinsics, write_text_atomic, write_tum
from multieye.imaging.targets import target_from_spec
from multieye.pipeline import calibrate
from multieye.sim.dataset import _centered_board, _motion, default_intrinsics
from multieye.sim.render import render, visible

TARGET = {"type": "chessboard", "rows": 6, "cols": 9, "spacing": 0.05}
OFFSET = 0.040                  # motion-capture clock minus the cameras' clock, seconds


def _render_triggered_together(out, seed=3, n=30, rate_hz=3.0, mocap_hz=120.0):
    rng = np.random.default_rng(seed)
    out.mkdir()
    target = target_from_spec(TARGET)
    intr = default_intrinsics(2, 640, 480, rng=rng)
    T_world_cam0 = g.transform_from_rotvec([0.0, 0.0, 0.4], [0.3, -0.2, 0.6])
    D = g.transform_from_rotvec([0.0, np.radians(-3.0), 0.0], [0.12, 0.0, 0.0])  # cam0 -> cam1
    T_marker_target = g.transform_from_rotvec(rng.normal(scale=0.3, size=3),
                                              rng.uniform(-0.15, 0.15, 3))
    duration = n / rate_hz
    centre = _centered_board(target, 1.1) @ g.transform_from_rotvec([0, 0, 0], [0.06, 0, 0])
    pose = _motion(rng, centre, duration)                               # T_cam0_target(t)
    t0 = 1_700_000_000.0
    t_img = (np.arange(n) + 0.5) / rate_hz + rng.uniform(-0.01, 0.01, n)   # one trigger
    kept = 0
    for name in ("cam0", "cam1"):
        (out / name).mkdir()
    for k, (t, T0) in enumerate(zip(t_img, pose(t_img))):
        T = (T0, g.inv(D) @ T0)
        if not all(visible(target, intr[j], T[j], border_px=8) for j in range(2)):
            continue
        kept += 1
        for j in range(2):       # one clock: the same stamp in both cameras' names
            img = render(target, intr[j], T[j], rng=np.random.default_rng([seed, j, k]),
                         blur_sigma=0.7, noise_sigma=2.0)
            cv2.imwrite(str(out / f"cam{j}" / f"{t0 + t - OFFSET:.6f}.png"), img)
    t_m = np.arange(-0.3, duration + 0.3, 1.0 / mocap_hz) + rng.uniform(0, 1.0 / mocap_hz)
    T_wm = T_world_cam0 @ pose(t_m) @ g.inv(T_marker_target)
    T_wm = T_wm @ g.transform_from_rotvec(rng.normal(scale=np.radians(0.03), size=(len(t_m), 3)),
                                          rng.normal(scale=1e-4, size=(len(t_m), 3)))
    write_tum(out / "mocap.txt", Trajectory(t0 + t_m, T_wm, parent="world", child="marker"))
    lines = ["setup: eye-to-base", "target:"] + [f"  {k}: {v}" for k, v in TARGET.items()]
    lines += ["mocap:", "  file: mocap.txt", "  pose: T_world_marker",
              f"  time_tolerance: {2.0 / mocap_hz:.4f}", "  rotation_noise_deg: 0.03",
              "  translation_noise_m: 0.0001", "cameras:"]
    for j in range(2):
        write_opencv_intrinsics(out / f"cam{j}.yaml", intr[j])
        lines += [f"  cam{j}:", f"    intrinsics: cam{j}.yaml", f"    images: cam{j}/"]
    write_text_atomic(out / "rig.yaml", "\n".join(lines) + "\n")
    return kept


def test_cameras_triggered_together_get_one_clock_offset_end_to_end(tmp_path):
    kept = _render_triggered_together(tmp_path / "ds")
    assert kept >= 20
    run = calibrate(tmp_path / "ds", processes=1, time_offset="auto")
    cams = run.record.cameras
    # one clock: one offset (and one std) for both cameras, from the joint refinement
    assert cams[0].time_offset_s == cams[1].time_offset_s
    assert cams[0].time_offset_std_s == cams[1].time_offset_std_s
    std = cams[0].time_offset_std_s
    assert 0 < std < 0.002
    assert abs(cams[0].time_offset_s - OFFSET) < 5 * std, (cams[0].time_offset_s, std)
    assert any("cam0, cam1: image stamps equal" in w and "one clock" in w
               for w in run.record.warnings)
    res = run.refinement.result
    assert [f for f in res.layout.offset if f.startswith("dt:")] == ["dt:cam0"]
    assert cams[0].time_offset_s == pytest.approx(OFFSET, abs=0.002)
