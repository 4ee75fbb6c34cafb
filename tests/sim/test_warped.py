"""The second renderer (issue 32): a board picture warped through its homography and the
lens, so that the detection is checked on images made another way than the ray tracer's."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.lens import project_points
from multieye.imaging.detect import detect
from multieye.imaging.targets import Charuco, Chessboard
from multieye.sim.dataset import DatasetSpec, default_intrinsics
from multieye.sim.render import visible
from multieye.sim.warped import render_warped

BOARD = Chessboard(rows=6, cols=9, spacing=0.05)


def _views(intr, n):
    rng = np.random.default_rng(5)
    centre = np.array([0.2, 0.125, 0.0])
    out = []
    while len(out) < n:
        T = g.transform_from_rotvec(rng.normal(scale=0.3, size=3), [0.0, 0.0, 0.0])
        T[:3, 3] = [rng.normal(scale=0.08), rng.normal(scale=0.06), rng.uniform(0.9, 1.2)] \
            - T[:3, :3] @ centre
        if visible(BOARD, intr, T, border_px=8):
            out.append(T)
    return out


@pytest.mark.parametrize("fisheye", [False, True], ids=["pinhole", "fisheye"])
def test_corners_land_where_the_lens_projects_them(fisheye):
    """Detected on the warped images, every corner within 0.3 px of the projection of the
    true corner (RMS under 0.1 px): the picture, the homography and the lens agree."""
    intr = default_intrinsics(1, 640, 480, fisheye=(0,) if fisheye else (),
                              rng=np.random.default_rng(2))[0]
    errors = []
    for k, T in enumerate(_views(intr, 4)):
        image = render_warped(BOARD, intr, T, rng=np.random.default_rng(k))
        assert image.shape == (480, 640) and image.dtype == np.uint8
        det = detect(image, BOARD)
        assert det is not None
        truth = project_points(BOARD.object_points() @ T[:3, :3].T + T[:3, 3], intr)
        errors.append(np.linalg.norm(det.image_points - truth[det.ids], axis=1))
    e = np.concatenate(errors)
    assert e.max() < 0.3 and np.sqrt(np.mean(e ** 2)) < 0.1, (e.max(), np.sqrt(np.mean(e ** 2)))


def test_only_chessboards_and_known_renderers():
    intr = default_intrinsics(1, 320, 240)[0]
    with pytest.raises(InputError, match="chessboards only"):
        render_warped(Charuco(rows=5, cols=7, spacing=0.04, marker_size=0.03,
                              dictionary="DICT_4X4_50"), intr, np.eye(4))
    with pytest.raises(InputError, match="renderer"):
        DatasetSpec(renderer="paint")
