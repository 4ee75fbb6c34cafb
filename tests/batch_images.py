"""Rendered views of a board as files, with a corrupt, a blank, a missing and an empty one
(test helper shared by the batch-detection tests)."""

from __future__ import annotations

import cv2
import numpy as np

from multieye.core.geometry import rotation_angle_between, transform_from_rotvec, translation_distance
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.targets import Chessboard
from multieye.sim.render import render, visible

CAMERA = Intrinsics(K=[[600, 0, 399.5], [0, 600, 299.5], [0, 0, 1]], dist=[-0.2, 0.05, 0, 0, 0],
                    width=640, height=480)


BOARD = Chessboard(rows=5, cols=7, spacing=0.04)


def render_image_files(tmp_path_factory):
    """Four rendered views, a corrupt file, a blank image and a missing path, with the truth."""
    folder = tmp_path_factory.mktemp("cam0")
    rng = np.random.default_rng(11)
    paths, truth = [], []
    tilts = [(0.3, -0.2, 0.05), (-0.25, 0.3, 0.0), (0.1, 0.35, -0.1), (-0.3, -0.25, 0.1)]
    for k, tilt in enumerate(tilts):
        T = transform_from_rotvec(tilt, [0.0, 0.0, 0.0])
        T[:3, 3] = -T[:3, :3] @ [0.12, 0.08, 0.0] + [0.0, 0.0, 0.6]    # board centre on the axis
        assert visible(BOARD, CAMERA, T)
        path = folder / f"{k}.5.png"
        cv2.imwrite(str(path), render(BOARD, CAMERA, T, rng=rng))
        paths.append(path)
        truth.append(T)
    corrupt = folder / "7.0.png"
    corrupt.write_bytes(b"\x89PNG not really")
    blank = folder / "8.0.png"
    cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    missing = folder / "9.0.png"
    empty = folder / "9.5.png"
    empty.write_bytes(b"")
    order = [paths[0], corrupt, paths[1], blank, paths[2], missing, paths[3], empty]
    return order, truth


def check(results, image_files):
    order, truth = image_files
    assert [r.path for r in results] == [str(p) for p in order]
    reasons = [r.reason for r in results]
    assert reasons == [None, "unreadable file: not a PNG, JPEG, BMP, TIFF, PGM/PPM/PBM or WebP "
                       "image (or its header is cut short)", None, "target not detected (chessboard 5x7)", None,
                       "unreadable file: not found", None, "unreadable file: empty (0 bytes)"]
    good = [r for r in results if r.ok]
    for r, T in zip(good, truth):
        assert np.degrees(rotation_angle_between(r.pose.T_cam_target, T)) < 0.1
        assert translation_distance(r.pose.T_cam_target, T) < 1e-3
        assert r.detection is not None and len(r.detection) == 35

