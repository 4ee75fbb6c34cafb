"""A small dataset given by precomputed T_cam_target poses (no images): fast pipeline fixture."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.io import Trajectory, write_opencv_intrinsics, write_tum

RIG = """\
setup: eye-to-base
target: {type: chessboard, rows: 6, cols: 9, spacing: 0.05}
mocap:
  file: mocap.txt
  pose: T_world_marker
  time_tolerance: 0.01
cameras:
  cam0: {intrinsics: cam.yaml, poses: cam0.txt}
  cam1: {intrinsics: cam.yaml, poses: cam1.txt}
"""


def write_pose_dataset(folder: Path, *, seed: int = 0, per_camera_mocap: bool = False):
    """Two cameras recorded one after the other, 12 exact poses each.

    Returns the folder; ``folder.truth`` is not set, use :func:`truth` for the frames.
    """
    rng = np.random.default_rng(seed)
    T_world_cam = g.random_transforms(rng, 2, translation_scale=2.0)
    T_marker_target = g.random_transforms(rng, translation_scale=0.2)
    stamps = np.arange(24) * 0.5
    T_world_marker = g.random_transforms(rng, 24)
    if per_camera_mocap:
        for j in range(2):
            sl = slice(12 * j, 12 * j + 12)
            write_tum(folder / f"mocap{j}.txt", Trajectory(stamps[sl], T_world_marker[sl]))
    else:
        write_tum(folder / "mocap.txt", Trajectory(stamps, T_world_marker))
    for j in range(2):
        sl = slice(12 * j, 12 * j + 12)
        T_cam_target = g.inv(T_world_cam[j]) @ T_world_marker[sl] @ T_marker_target
        write_tum(folder / f"cam{j}.txt", Trajectory(stamps[sl], T_cam_target, "cam", "target"))
    write_opencv_intrinsics(folder / "cam.yaml",
                            Intrinsics(K=np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]]),
                                       dist=np.zeros(4), width=640, height=480))
    rig = RIG
    if per_camera_mocap:
        rig = rig.replace("mocap:\n  file: mocap.txt\n  pose: T_world_marker\n  time_tolerance: 0.01\n", "")
        for j in range(2):
            rig = rig.replace(f"cam{j}: {{intrinsics: cam.yaml, poses: cam{j}.txt}}",
                              f"cam{j}: {{intrinsics: cam.yaml, poses: cam{j}.txt, "
                              f"mocap: {{file: mocap{j}.txt, pose: T_world_marker, "
                              f"time_tolerance: 0.01}}}}")
    (folder / "rig.yaml").write_text(rig)
    return folder, T_world_cam, T_marker_target
