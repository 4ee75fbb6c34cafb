"""Marker boards whose markers are too small for OpenCV's contour detector, found in the image
upsampled twice (multieye.imaging.small_markers): a Kalibr AprilGrid of 4 cm tags 0.85 m from
a 460 px lens (tags of about 21 px), which the detector misses in the image itself, is found
whole, its corners as close to the truth as those of grids found directly (no bias from the
mapping back to the image's pixels)."""

from __future__ import annotations

import numpy as np

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.imaging.detect import _detect_aprilgrid, detect
from multieye.imaging.targets import target_from_spec
from multieye.sim.render import render

BOARD = target_from_spec({"type": "aprilgrid", "rows": 6, "cols": 6, "spacing": 0.04,
                          "tag_spacing": 0.3})
LENS = Intrinsics(K=np.array([[460.0, 0, 376], [0, 458, 240], [0, 0, 1]]),
                  dist=np.array([-0.28, 0.075, 2e-4, 1e-5]), width=752, height=480)


def _view(distance: float, tilt_deg: float, seed: int):
    R = g.transform_from_rotvec([np.radians(tilt_deg), np.radians(tilt_deg / 2), 0.1 + 0.3 * seed],
                                [0, 0, 0])[:3, :3] @ np.diag([1.0, -1, -1])   # facing the camera
    T = g.make_transform(R, np.array([0.02, -0.01, distance]) - R @ [0.14, 0.14, 0.0])
    img = render(BOARD, LENS, T, rng=np.random.default_rng(seed), blur_sigma=0.8,
                 noise_sigma=2.0)
    return img, T


def _errors(found, T) -> np.ndarray:
    P = BOARD.object_points()[found.ids] @ T[:3, :3].T + T[:3, 3]
    return found.image_points - project_points(P, LENS)


def test_an_aprilgrid_of_small_tags_is_found_in_the_image_upsampled_twice():
    img, T = _view(0.85, 20.0, 0)
    assert _detect_aprilgrid(img, BOARD) is None         # missed in the image itself
    found = detect(img, BOARD)
    assert found is not None and len(found.ids) == 144
    e = _errors(found, T)
    assert np.sqrt(np.mean(np.sum(e ** 2, axis=1))) < 0.15, e
    assert np.all(np.abs(e.mean(axis=0)) < 0.03), e.mean(axis=0)   # a wrong map: 0.25 px


def test_a_grid_found_directly_is_not_looked_at_again():
    img, T = _view(0.8, 15.0, 5)
    direct = _detect_aprilgrid(img, BOARD)
    assert direct is not None
    found = detect(img, BOARD)
    np.testing.assert_array_equal(found.image_points, direct.image_points)
    assert np.sqrt(np.mean(np.sum(_errors(found, T) ** 2, axis=1))) < 0.15
