"""Convert the public data sets in ../shared/data into the rig.yaml layout (test fixtures).

The data stay in ../shared/data (no license for these two); the fixtures link the images
under time-stamp names and write the poses and intrinsics in formats multieye reads, with
the conventions their PROVENANCE.md documents.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.io import Trajectory, write_opencv_intrinsics, write_tum


def _link(src: Path, dst: Path) -> None:
    try:
        os.symlink(src, dst)
    except OSError:  # pragma: no cover - file systems without symlinks
        dst.write_bytes(src.read_bytes())


def young_mocap_cam(shared: Path, out: Path) -> Path:
    """30 chessboard images + OptiTrack pose of the camera's marker body (eye-on-hand).

    ``pose_quat.txt`` line k is ``w qx qy qz x y z`` (metres) of the body at image ``k.png``;
    the board (11 x 8 inner corners, 0.03 m) is static; rational 8-coefficient intrinsics.
    Image k is given the time stamp k seconds, the motion capture the same stamps.
    """
    src = shared / "young_mocap_cam" / "example_dataset"
    rows = np.loadtxt(src / "pose_quat.txt")
    T = g.transform_from_quat(rows[:, :4], rows[:, 4:7], scalar_first=True)
    stamps = np.arange(len(rows), dtype=float)
    out.mkdir(parents=True, exist_ok=True)
    write_tum(out / "mocap.txt", Trajectory(stamps, T, parent="world", child="body"))
    (out / "cam0").mkdir(exist_ok=True)
    for k in range(len(rows)):
        _link(src / "rgb_images" / f"{k}.png", out / "cam0" / f"{k}.000000.png")
    K = np.array([[607.88, 0, 641.875], [0, 607.966, 365.585], [0, 0, 1]])
    dist = np.array([0.458331, -2.87024, 0.00048617, -9.82262e-05, 1.74446, 0.331466,
                     -2.66947, 1.65473])
    write_opencv_intrinsics(out / "cam0.yaml", Intrinsics(K=K, dist=dist, width=1280, height=720))
    (out / "rig.yaml").write_text(
        "setup: eye-on-hand\n"
        "target: {type: chessboard, rows: 8, cols: 11, spacing: 0.03}\n"
        "mocap: {file: mocap.txt, pose: T_world_body, time_tolerance: 0.01}\n"
        "cameras:\n  cam0: {intrinsics: cam0.yaml, images: cam0/}\n")
    return out


def _yaskawa_poses(folder: Path, n: int) -> np.ndarray:
    """``pos{k}.txt``: Rx Ry Rz (degrees, extrinsic x-y-z), X Y Z (mm) of the TCP in the base."""
    T = []
    for k in range(n):
        v = np.loadtxt(folder / f"pos{k}.txt")
        R = Rotation.from_euler("xyz", v[:3], degrees=True).as_matrix()
        T.append(g.make_transform(R, v[3:] / 1000.0))
    return np.stack(T)


def _param_intrinsics(folder: Path, width: int, height: int) -> Intrinsics:
    p = np.loadtxt(folder / "param.txt")
    return Intrinsics(K=p[:9].reshape(3, 3), dist=p[9:14], width=width, height=height)


def open3dv(shared: Path, out: Path, which: str) -> Path:
    """Open3DV asymmetric circle grid (7 x 11, light circles on dark) + Yaskawa TCP poses.

    ``which="eye-in-hand"``: camera on the TCP, board static: eye-on-hand with
    ``T_world_body = T_base_tcp`` (8 images, 20 mm).  ``which="eye-to-hand"``: board on the
    TCP, camera static: eye-to-base with ``T_world_marker = T_base_tcp`` (5 images, 40 mm).
    """
    if which == "eye-in-hand":
        src, n, spacing, size, setup, pose = (shared / "open3dv_eih" / "input_EyeInHand", 8, 0.02,
                                              (1920, 1200), "eye-on-hand", "T_world_body")
    else:
        src, n, spacing, size, setup, pose = (shared / "open3dv_eih" / "input_EyeToHand", 5, 0.04,
                                              (1022, 768), "eye-to-base", "T_world_marker")
    out.mkdir(parents=True, exist_ok=True)
    T = _yaskawa_poses(src, n)
    write_tum(out / "robot.txt", Trajectory(np.arange(n, dtype=float), T, parent="world",
                                            child=pose.split("_")[2]))
    (out / "cam0").mkdir(exist_ok=True)
    for k in range(n):
        _link(src / f"pos{k}.bmp", out / "cam0" / f"{k}.000000.bmp")
    write_opencv_intrinsics(out / "cam0.yaml", _param_intrinsics(src, *size))
    (out / "rig.yaml").write_text(
        f"setup: {setup}\n"
        f"target: {{type: asymmetric-circles, rows: 11, cols: 7, spacing: {spacing}}}\n"
        f"mocap: {{file: robot.txt, pose: {pose}, time_tolerance: 0.01}}\n"
        "cameras:\n  cam0: {intrinsics: cam0.yaml, images: cam0/}\n")
    return out


def yizhong_eye_in_hand(shared: Path, out: Path) -> Path:
    """6 chessboard images (11 x 8 inner corners, 20 mm) + the robot's ``end2base`` per image
    (``k.json``: 4x4 T_base_end, metres); camera on the end effector, board static
    (eye-on-hand, ``T_world_body = T_base_end``); no intrinsics are published, so the camera
    gives ``model: pinhole-radtan``. Image k.jpg gets the time stamp k seconds."""
    import json

    src = shared / "yizhong_toolkit" / "sample_data" / "eye_in_hand_test_data"
    ks = sorted(int(p.stem) for p in src.glob("*.jpg"))
    T = np.stack([np.array(json.loads((src / f"{k}.json").read_text())["end2base"], float)
                  for k in ks])
    out.mkdir(parents=True, exist_ok=True)
    write_tum(out / "mocap.txt", Trajectory(np.array(ks, float), T, parent="world",
                                            child="body"))
    (out / "cam0").mkdir(exist_ok=True)
    for k in ks:
        _link(src / f"{k}.jpg", out / "cam0" / f"{k}.000000.jpg")
    (out / "rig.yaml").write_text(
        "setup: eye-on-hand\n"
        "target: {type: chessboard, rows: 8, cols: 11, spacing: 0.02}\n"
        "mocap: {file: mocap.txt, pose: T_world_body, time_tolerance: 0.01}\n"
        "cameras:\n  cam0: {model: pinhole-radtan, images: cam0/}\n")
    return out


#: BoofCV's calibration of ``boofcv_fisheye`` (its ``fisheye.yaml``): the unified model
#: (Mei-Rives) with two radial coefficients, tangential zero.
BOOFCV_FISHEYE_REFERENCE = Intrinsics(
    K=np.array([[398.77492706579216, 0.0, 319.17879590584187],
                [0.0, 398.7685638672075, 319.71743712432686], [0.0, 0.0, 1.0]]),
    dist=np.array([1.1331346732794045, -0.24972089525362837, 0.009672326567075125, 0.0, 0.0]),
    model="unified", width=640, height=720)


def boofcv_fisheye(shared: Path, out: Path, model: str = "fisheye") -> Path:
    """26 images of one fisheye of about 180 degrees, no stamps, no motion capture: the
    images linked under their names (1.jpg ... 26.jpg, times 1 ... 26 s) and a rig.yaml for
    one camera whose lens ``model`` is estimated; the board has 4 x 6 inner corners, the
    square is 1 unit (``calibration_target.yaml``: 5 columns x 7 rows of squares)."""
    src = shared / "boofcv_fisheye"
    (out / "images").mkdir(parents=True)
    for k in range(1, 27):
        _link(src / f"{k}.jpg", out / "images" / f"{k}.jpg")
    (out / "rig.yaml").write_text(
        "target: {type: chessboard, rows: 6, cols: 4, spacing: 1.0}\n"
        f"cameras:\n  fish: {{model: {model}, images: images/}}\n")
    return out
