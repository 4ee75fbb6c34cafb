"""The calibration script an OpenCV user writes for the job multieye does (issue 21, item 4).

Run::

    python benchmarks/peers/opencv_script.py DATASET --out result.json [--unknown-lenses]
        [--corners-out corners.npz]

``DATASET`` is a folder rendered by :func:`multieye.sim.dataset.render_dataset` (eye-to-base:
fixed cameras, a motion-captured chessboard): ``cam*/<seconds>.png`` (or ``.jpg``), ``cam*.yaml`` (OpenCV
FileStorage intrinsics), ``mocap.txt`` (TUM: ``t tx ty tz qx qy qz qw``, ``T_world_marker``)
and ``rig.yaml`` (read here only for the board's size). Per camera, in one process:

1. every image: ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix``; the corner order made
   the board's (first corner the upper-left one: the boards face the camera upright within
   about 30 degrees, so this fixes the half turn of OpenCV's ordering);
2. with ``--unknown-lenses``: ``cv2.calibrateCamera`` (pinhole, 5 radial-tangential
   coefficients; ``cv2.fisheye.calibrate``, 4, where ``cam*.yaml`` says the lens is a
   fisheye) on those corners; otherwise the lens is read from ``cam*.yaml``;
3. ``cv2.solvePnP`` (``cv2.fisheye.solvePnP``) per image (iterative), the motion-capture pose nearest in time (within
   half a sample period, no interpolation: what such a script does);
4. ``cv2.calibrateRobotWorldHandEye`` (Shah's method) on the pairs: the camera in the
   motion-capture world, ``T_world_cam``.

Writes ``T_ref_cam`` of every camera (camera 0 the reference) and the lens used, as JSON.
Depends on numpy and OpenCV only: this file is what the benchmark times (imports included);
``mrcal_script.py`` imports its helpers.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import cv2
import numpy as np


def board(rig_yaml: Path) -> tuple[int, int, float]:
    """(rows, cols, spacing) of the chessboard's inner corners in ``rig.yaml``."""
    text = rig_yaml.read_text()
    get = lambda key: re.search(rf"^\s+{key}:\s*([0-9.]+)", text, re.M).group(1)  # noqa: E731
    return int(get("rows")), int(get("cols")), float(get("spacing"))


def object_points(rows: int, cols: int, spacing: float) -> np.ndarray:
    """(rows * cols, 3) board points, row by row, x along the columns."""
    grid = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * spacing
    return np.column_stack([grid, np.zeros(len(grid))]).astype(np.float32)


def read_lens(path: Path) -> tuple[np.ndarray, np.ndarray, bool]:
    """K, the distortion coefficients and whether the lens is a fisheye
    (``distortion_model: fisheye``, OpenCV's equidistant model)."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    K, dist = fs.getNode("camera_matrix").mat(), fs.getNode("distortion_coefficients").mat()
    fisheye = fs.getNode("distortion_model").string() == "fisheye"
    fs.release()
    return K, dist.ravel(), fisheye


def read_mocap(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times (n,) and T_world_marker (n, 4, 4) of a TUM file."""
    d = np.loadtxt(path, comments="#")
    x, y, z, w = d[:, 4:8].T
    R = np.stack([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    T = np.tile(np.eye(4), (len(d), 1, 1))
    T[:, :3, :3] = np.moveaxis(R, -1, 0)
    T[:, :3, 3] = d[:, 1:4]
    return d[:, 0], T


def detect(paths: list[Path], rows: int, cols: int):
    """Corners (k, rows * cols, 2) of the images where the board is found, their stamps (k,)
    and the image size."""
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 1e-3)
    corners, stamps, size = [], [], None
    for p in paths:
        gray = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        size = gray.shape[::-1]
        found, c = cv2.findChessboardCorners(gray, (cols, rows), cv2.CALIB_CB_ADAPTIVE_THRESH
                                             + cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not found:
            continue
        c = cv2.cornerSubPix(gray, c, (5, 5), (-1, -1), criteria).reshape(-1, 2)
        if c[0].sum() > c[-1].sum():          # OpenCV started from the other end
            c = c[::-1].copy()
        corners.append(c)
        stamps.append(float(p.stem))
    return np.array(corners, np.float32).reshape(-1, rows * cols, 2), np.array(stamps), size


def nearest(t_mocap: np.ndarray, stamps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the nearest motion-capture sample per stamp, and whether it is within half a
    sample period."""
    i = np.clip(np.searchsorted(t_mocap, stamps), 1, len(t_mocap) - 1)
    i = np.where(np.abs(t_mocap[i - 1] - stamps) < np.abs(t_mocap[i] - stamps), i - 1, i)
    half = 0.5 * np.median(np.diff(t_mocap))
    return i, np.abs(t_mocap[i] - stamps) <= half


def hand_eye(T_world_marker: np.ndarray, T_cam_target: np.ndarray) -> np.ndarray:
    """``T_world_cam`` from pairs (eye-to-base): ``T_cam_target = T_cam_world T_world_marker
    T_marker_target``, OpenCV's robot-world/hand-eye problem with OpenCV's "world" the board,
    its "gripper" the motion-capture world and its "base" the marker."""
    R_b, t_b, R_g, t_g = cv2.calibrateRobotWorldHandEye(
        [T[:3, :3] for T in T_cam_target], [T[:3, 3] for T in T_cam_target],
        [T[:3, :3] for T in T_world_marker], [T[:3, 3] for T in T_world_marker],
        method=cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH)[:4]
    T_cam_world = np.eye(4)
    T_cam_world[:3, :3], T_cam_world[:3, 3] = R_g, np.ravel(t_g)
    return np.linalg.inv(T_cam_world)


def pose(rvec, tvec) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(rvec)[0]
    T[:3, 3] = np.ravel(tvec)
    return T


def calibrate(obj: np.ndarray, corners: np.ndarray, size, fisheye: bool):
    """``cv2.calibrateCamera`` (5 coefficients) or ``cv2.fisheye.calibrate`` (4): K, the
    coefficients and the board poses ``T_cam_target``."""
    if fisheye:
        flags = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
        _, K, dist, rvecs, tvecs = cv2.fisheye.calibrate(
            [obj.reshape(-1, 1, 3).astype(np.float64)] * len(corners),
            [c.reshape(-1, 1, 2).astype(np.float64) for c in corners], size, None, None,
            flags=flags)
    else:
        _, K, dist, rvecs, tvecs = cv2.calibrateCamera([obj] * len(corners), list(corners),
                                                       size, None, None)
    return K, dist.ravel(), np.array([pose(r, t) for r, t in zip(rvecs, tvecs)])


def solve_pnp(obj: np.ndarray, c: np.ndarray, K, dist, fisheye: bool) -> np.ndarray:
    """``T_cam_target`` of one view: ``cv2.solvePnP`` or ``cv2.fisheye.solvePnP``."""
    if fisheye:
        return pose(*cv2.fisheye.solvePnP(obj.reshape(-1, 1, 3), c.reshape(-1, 1, 2), K,
                                          dist)[1:3])
    return pose(*cv2.solvePnP(obj, c, K, dist)[1:])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--unknown-lenses", action="store_true")
    ap.add_argument("--corners-out", type=Path)
    args = ap.parse_args(argv)
    rows, cols, spacing = board(args.dataset / "rig.yaml")
    obj = object_points(rows, cols, spacing)
    t_mocap, T_mocap = read_mocap(args.dataset / "mocap.txt")
    cameras = sorted(p.name for p in args.dataset.iterdir() if p.is_dir() and
                     re.fullmatch(r"cam\d+", p.name))
    result, saved = {}, {}
    for name in cameras:
        paths = sorted(p for p in (args.dataset / name).iterdir()
                       if p.suffix in (".png", ".jpg"))
        corners, stamps, size = detect(paths, rows, cols)
        saved[f"{name}_corners"], saved[f"{name}_stamps"] = corners, stamps
        K, dist, fisheye = read_lens(args.dataset / f"{name}.yaml")   # the model's name
        if args.unknown_lenses:
            K, dist, T_cam_target = calibrate(obj, corners, size, fisheye)
        else:
            T_cam_target = np.array([solve_pnp(obj, c, K, dist, fisheye) for c in corners])
        i, ok = nearest(t_mocap, stamps)
        T_world_cam = hand_eye(T_mocap[i[ok]], T_cam_target[ok])
        result[name] = {"T_world_cam": T_world_cam, "K": K.tolist(), "fisheye": fisheye,
                        "dist": np.ravel(dist).tolist(), "size": list(size),
                        "used": int(ok.sum())}
    T_ref = np.linalg.inv(result[cameras[0]]["T_world_cam"])
    for name in cameras:
        result[name]["T_ref_cam"] = (T_ref @ result[name].pop("T_world_cam")).tolist()
    args.out.write_text(json.dumps({"cameras": result}, indent=1))
    if args.corners_out:
        np.savez(args.corners_out, rows=rows, cols=cols, spacing=spacing, size=size,
                 cameras=np.array(cameras), **saved)


if __name__ == "__main__":
    sys.exit(main())
