"""Chessboards bent by a lens near 180 degrees (issue 33): every corner checked to be a saddle
of the image, so that SB's grids are checked too and a classic grid refused only for its
bends is still found; the corners as accurate as on a flat view."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core.geometry import transform_from_rotvec
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.imaging import chessboard_corners as cc
from multieye.imaging.detect import detect
from multieye.imaging.targets import Chessboard
from multieye.sim.render import render

#: boofcv_fisheye's lens (BoofCV's unified model, xi 1.13: about 190 degrees), and its board
LENS = Intrinsics(K=[[398.77, 0.0, 318.68], [0.0, 398.77, 319.22], [0.0, 0.0, 1.0]],
                  dist=[1.1331, -0.24972, 0.009672, 0.0, 0.0], model="unified", width=640,
                  height=720)
BOARD = Chessboard(rows=6, cols=4, spacing=1.0)
#: a view at the rim, board strongly bent (boofcv_fisheye's 22.jpg posed under LENS): SB's
#: half-size search puts a row of corners on the edge of the board's margin there
RIM = transform_from_rotvec([1.892, -1.7576, 0.6327], [3.4958, 2.0464, 1.1155])
#: a view near the centre, as flat as this lens shows a board
CENTRE = transform_from_rotvec([0.0, 0.0, 0.3], [-1.5, -2.5, 3.0])


def _image_and_truth(T, seed: int):
    image = render(BOARD, LENS, T, rng=np.random.default_rng(seed), blur_sigma=1.0,
                   noise_sigma=2.0)
    return image, project_points(BOARD.object_points() @ T[:3, :3].T + T[:3, 3], LENS)


def _nearest(found, truth):
    """Each found corner's distance to the nearest true one (the 6 x 4 board looks the same
    after a half turn, so the order is the image's)."""
    return np.linalg.norm(found[:, None] - truth[None], axis=2).min(axis=1)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_board_bent_at_the_rim_is_found_where_it_is(seed):
    image, truth = _image_and_truth(RIM, seed)
    det = detect(image, BOARD)
    assert det is not None
    err = _nearest(det.image_points, truth)
    assert err.max() < 0.5, err.max()          # before: SB's row on the margin, 59 px off
    assert np.sqrt(np.mean(err ** 2)) < 0.15


def test_corners_on_a_bent_board_are_as_accurate_as_near_the_centre():
    errs = []
    for T in (RIM, CENTRE):
        image, truth = _image_and_truth(T, 3)
        det = detect(image, BOARD)
        errs.append(float(np.sqrt(np.mean(_nearest(det.image_points, truth) ** 2))))
    assert max(errs) < 0.15, errs


def test_saddle_check_refuses_points_on_an_edge_or_inside_a_square():
    image, truth = _image_and_truth(CENTRE, 4)
    assert cc.saddle_grid(image, truth, BOARD)
    # a board point half a square along a grid line (on the edge between two squares) and
    # one in the middle of a square, projected: neither is a corner
    for shift in ([0.5, 0.0], [0.5, 0.5]):
        P = BOARD.object_points().copy()
        P[9, :2] += shift
        moved = project_points(P @ CENTRE[:3, :3].T + CENTRE[:3, 3], LENS)
        assert not cc.saddle_grid(image, moved, BOARD), shift
