"""A recording as Kalibr users make it, end to end: two overlapping cameras in one ROS 1 bag
(their stamps a few microseconds apart), an AprilGrid described by Kalibr's target file, the
lenses unknown, no motion capture.  The rig comes out within its reported uncertainty."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from multieye.cli import main
from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.metrics import extrinsic_errors
from multieye.imaging.targets import target_from_spec
from multieye.sim.render import render, visible

from rosbag_writer import BASE_NS, Bag, image_msg

KALIBR_TARGET = ("target_type: 'aprilgrid' #gridtype\ntagCols: 6               #number of apriltags\n"
                 "tagRows: 6\ntagSize: 0.04           #size of apriltag, edge to edge [m]\n"
                 "tagSpacing: 0.3\n")
LENSES = [Intrinsics(K=np.array([[460.0, 0, 376], [0, 458, 240], [0, 0, 1]]),
                     dist=np.array([-0.28, 0.075, 2e-4, 1e-5]), width=752, height=480),
          Intrinsics(K=np.array([[457.0, 0, 379], [0, 456, 255], [0, 0, 1]]),
                     dist=np.array([-0.283, 0.074, 1e-4, -3e-5]), width=752, height=480)]
T_REF_CAM1 = g.transform_from_rotvec([0.01, -0.02, 0.005], [0.11, 0.0005, -0.001])


def _board_poses(board, n: int, rng) -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` instants at which both cameras see the whole grid (tilted up to 40 degrees,
    0.45-0.75 m away): (T_cam0_target, T_cam1_target)."""
    centre, out = np.array([0.14, 0.14, 0.0]), []
    while len(out) < n:
        axis = rng.normal(size=3) * [1, 1, 0.3]
        R = g.transform_from_rotvec(np.radians(rng.uniform(0, 40)) * axis / np.linalg.norm(axis),
                                    [0, 0, 0])[:3, :3] @ np.diag([1.0, -1, -1])  # facing cam
        p = [0.055 + rng.uniform(-0.1, 0.1), rng.uniform(-0.07, 0.07), rng.uniform(0.45, 0.75)]
        T0 = g.make_transform(R, p - R @ centre)
        T1 = g.inv(T_REF_CAM1) @ T0
        if visible(board, LENSES[0], T0, border_px=5) and visible(board, LENSES[1], T1,
                                                                   border_px=5):
            out.append((T0, T1))
    return out


def test_a_kalibr_style_bag_of_two_overlapping_cameras_calibrates(tmp_path):
    board = target_from_spec({"type": "aprilgrid", "rows": 6, "cols": 6, "spacing": 0.04,
                              "tag_spacing": 0.3})
    rng = np.random.default_rng(7)
    with Bag(tmp_path / "calib.bag", 1) as bag:
        for k, poses in enumerate(_board_poses(board, 14, rng)):
            for j, T in enumerate(poses):
                ns = BASE_NS + k * 200_000_000 + j * 3000     # the second camera 3 us later
                img = render(board, LENSES[j], T, rng=np.random.default_rng(1000 * k + j),
                             blur_sigma=0.8, noise_sigma=2.0)
                bag.write(f"/cam{j}/image_raw", image_msg(bag, ns, img, "mono8"), ns)
    (tmp_path / "april_6x6.yaml").write_text(KALIBR_TARGET)
    (tmp_path / "rig.yaml").write_text(
        "target: april_6x6.yaml\ncameras:\n"
        "  cam0: {model: pinhole-radtan4, rosbag: calib.bag, topic: /cam0/image_raw}\n"
        "  cam1: {model: pinhole-radtan4, rosbag: calib.bag, topic: /cam1/image_raw}\n")
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path), "-o", str(tmp_path / "out"),
                                    "--processes", "1", "--no-report"])
    assert res.exit_code == 0, res.output
    assert "cam1 linked by: overlap with cam0" in res.output
    cam1 = json.loads((tmp_path / "out" / "calibration.json").read_text())["cameras"]["cam1"]
    rot, trans = extrinsic_errors(np.array(cam1["T_ref_cam"])[None], T_REF_CAM1[None])
    assert rot[0] < 4 * cam1["std_rot_deg"] and trans[0] < 4 * cam1["std_trans_m"], (
        rot, trans, cam1["std_rot_deg"], cam1["std_trans_m"])
    assert cam1["measurements_used"] >= 12
