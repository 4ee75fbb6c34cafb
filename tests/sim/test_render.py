"""Rendering: the pattern lands where the camera model says, in the right colours."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core.errors import InputError
from multieye.core.geometry import transform_from_rotvec
from multieye.core.lens import project_points
from multieye.sim.render import render, visible
from multieye.imaging.targets import AprilGrid, Chessboard, CircleGrid
from multieye.core.intrinsics import Intrinsics

CAMERA = Intrinsics(K=[[600, 0, 399.5], [0, 600, 299.5], [0, 0, 1]], dist=[-0.2, 0.05, 0, 0, 0],
                    width=800, height=600)
FISHEYE = Intrinsics(K=[[250, 0, 399.5], [0, 250, 299.5], [0, 0, 1]], dist=[0.01, -0.002, 0, 0],
                     model="fisheye", width=800, height=600)
BOARD = Chessboard(rows=5, cols=7, spacing=0.05)


def pose(rotvec=(0.2, -0.3, 0.1), t=(-0.15, -0.1, 0.7)):
    return transform_from_rotvec(np.array(rotvec), np.array(t))


def grey_at(image, camera, T, xy):
    """Grey level at the image of board point(s) xy (nearest pixel)."""
    P = np.column_stack([np.atleast_2d(xy), np.zeros(len(np.atleast_2d(xy)))])
    uv = project_points(P @ T[:3, :3].T + T[:3, 3], camera)
    return image[np.rint(uv[:, 1]).astype(int), np.rint(uv[:, 0]).astype(int)]


def test_chessboard_colours_follow_the_canonical_frame():
    T = pose()
    image = render(BOARD, CAMERA, T, noise_sigma=0)
    s = BOARD.spacing
    # the square diagonally outside the first corner is black, its neighbours white
    assert grey_at(image, CAMERA, T, [-s / 2, -s / 2])[0] < 60
    assert grey_at(image, CAMERA, T, [s / 2, -s / 2])[0] > 170
    assert grey_at(image, CAMERA, T, [-s / 2, s / 2])[0] > 170
    assert grey_at(image, CAMERA, T, [s / 2, s / 2])[0] < 60
    # white margin beyond the last row of squares
    assert grey_at(image, CAMERA, T, [3 * s, 5.5 * s])[0] > 170
    inverted = render(BOARD, CAMERA, T, noise_sigma=0, inverted=True)
    assert grey_at(inverted, CAMERA, T, [-s / 2, -s / 2])[0] > 170


def test_circles_are_dark_and_centred_on_their_points():
    board = CircleGrid(rows=4, cols=5, spacing=0.05, diameter=0.03)
    T = pose(t=(-0.1, -0.075, 0.6))
    image = render(board, CAMERA, T, noise_sigma=0)
    centres = board.object_points()[:, :2]
    assert np.all(grey_at(image, CAMERA, T, centres) < 60)
    assert np.all(grey_at(image, CAMERA, T, centres + [0.025, 0.0]) > 170)   # between circles


def test_aprilgrid_tag_zero_sits_at_the_origin_with_black_border():
    board = AprilGrid(rows=2, cols=3, spacing=0.06, tag_spacing=0.3)
    T = pose(rotvec=(np.pi - 0.2, 0.1, 0.0), t=(-0.1, 0.05, 0.6))   # printed face (z out) to the camera
    assert visible(board, CAMERA, T)
    image = render(board, CAMERA, T, noise_sigma=0)
    b = board.spacing / 10
    assert grey_at(image, CAMERA, T, [b, b])[0] < 60                  # border of tag 0
    assert grey_at(image, CAMERA, T, [-0.009, -0.009])[0] < 60        # gap square at its corner
    assert grey_at(image, CAMERA, T, [0.03, -0.009])[0] > 170         # gap strip beside it
    bits = board.tag_images()[0]                                       # row 0 at the top (+y)
    for i, j in [(2, 2), (3, 5), (7, 7), (5, 4)]:
        xy = [(j + 0.5) * b, (9 - i + 0.5) * b]
        assert (grey_at(image, CAMERA, T, xy)[0] > 128) == (bits[i, j] > 0.5)


def test_same_seed_same_image_and_noise_varies_with_seed():
    T = pose()
    a = render(BOARD, CAMERA, T, rng=np.random.default_rng(5))
    b = render(BOARD, CAMERA, T, rng=np.random.default_rng(5))
    c = render(BOARD, CAMERA, T, rng=np.random.default_rng(6))
    assert a.dtype == np.uint8 and a.shape == (600, 800)
    np.testing.assert_array_equal(a, b)
    assert np.any(a != c)


def test_fisheye_renders_beyond_its_field_of_view():
    T = pose(t=(-0.15, -0.1, 0.4))
    image = render(BOARD, FISHEYE, T, rng=np.random.default_rng(1))
    assert image.shape == (600, 800)
    assert grey_at(image, FISHEYE, T, [-0.025, -0.025])[0] < 80


def test_visible():
    T = pose()
    assert visible(BOARD, CAMERA, T)
    assert not visible(BOARD, CAMERA, pose(t=(0.3, -0.1, 0.7)))            # off to the right
    assert not visible(BOARD, CAMERA, pose(t=(-0.15, -0.1, -0.7)))         # behind the camera
    flipped = T @ np.diag([1.0, -1.0, -1.0, 1.0])                         # its back to the camera
    assert not visible(BOARD, CAMERA, flipped)
    assert not visible(BOARD, CAMERA, T, width=400, height=300)
    aprilgrid = AprilGrid(rows=2, cols=3, spacing=0.06, tag_spacing=0.3)  # z out of the face
    assert visible(aprilgrid, CAMERA, pose(rotvec=(np.pi, 0, 0), t=(-0.1, 0.05, 0.6)))
    assert not visible(aprilgrid, CAMERA, pose(rotvec=(0, 0, 0), t=(-0.1, -0.05, 0.6)))


def test_bad_input():
    no_size = Intrinsics(K=CAMERA.K)
    with pytest.raises(InputError, match="image size unknown"):
        render(BOARD, no_size, pose())
    with pytest.raises(InputError, match="not a rigid transform"):
        render(BOARD, CAMERA, np.diag([1.0, 1.0, -1.0, 1.0]))
    with pytest.raises(InputError, match="4x4"):
        visible(BOARD, CAMERA, np.eye(3))
    with pytest.raises(InputError, match="supersample"):
        render(BOARD, CAMERA, pose(), supersample=0)
