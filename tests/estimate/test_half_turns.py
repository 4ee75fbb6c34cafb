"""The views of one instant made to agree on a half-turn symmetric board's order
(estimate/half_turns.choose_turns), and a view turned to its other order
(pipeline/half_turns)."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.estimate.half_turns import choose_turns
from multieye.imaging.order_turn import half_turn
from multieye.imaging.targets import Chessboard, CircleGrid
from multieye.pipeline.camera_data import Observation
from multieye.pipeline.half_turns import fewest_turns, offer_half_turn, turned

BOARD = Chessboard(rows=6, cols=8, spacing=0.03)
H = half_turn(BOARD).T_target_turned


def _views(rng, m=4, n_inst=25, flip_share=0.3, noise_deg=0.0):
    """Cameras in a ring, each rolled at random, seeing a board at every instant; a share of
    the views given in the other order. Returns T_ref_cam, T, camera, instant, flipped."""
    T_ref_cam = np.stack([np.eye(4)] + [g.transform_from_rotvec(
        [rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-np.pi, np.pi)],
        rng.uniform(-0.3, 0.3, 3)) for _ in range(m - 1)])
    T, camera, instant, flipped = [], [], [], []
    for t in range(n_inst):
        T_ref_target = g.transform_from_rotvec(rng.normal(scale=0.4, size=3),
                                               [rng.uniform(-0.2, 0.2), 0.0, 1.0])
        for j in rng.permutation(m)[:rng.integers(2, m + 1)]:
            P = g.inv(T_ref_cam[j]) @ T_ref_target
            P = P @ g.transform_from_rotvec(np.radians(noise_deg) * rng.normal(size=3),
                                            0.001 * noise_deg * rng.normal(size=3))
            f = rng.random() < flip_share
            T.append(P @ H if f else P)
            camera.append(j)
            instant.append(t)
            flipped.append(f)
    return T_ref_cam, np.stack(T), np.array(camera), np.array(instant), np.array(flipped)


@pytest.mark.parametrize("noise_deg", [0.0, 1.0])
def test_each_instant_agrees_after_the_turns(noise_deg):
    rng = np.random.default_rng(4)
    T_ref_cam, T, camera, instant, flipped = _views(rng, noise_deg=noise_deg)
    Hs = np.broadcast_to(H, T.shape)
    turn = choose_turns(T, camera, instant, Hs, 4, 0)
    fixed = T.copy()
    fixed[turn] = fixed[turn] @ H
    for t in np.unique(instant):
        v = np.flatnonzero(instant == t)
        in_ref = T_ref_cam[camera[v]] @ fixed[v]
        R = in_ref[:, :3, :3]
        angles = g.rotation_angle(np.swapaxes(R, 1, 2)[:, None] @ R[None])
        assert angles.max() < np.radians(5 * noise_deg + 1e-6), (t, np.degrees(angles))
        # of the two agreeing choices, the one turning fewer views (ties: either)
        assert 2 * turn[v].sum() <= len(v)
        if 2 * flipped[v].sum() < len(v):
            assert np.array_equal(turn[v], flipped[v])
    assert flipped.sum() > 10                       # the choice is exercised


def test_views_without_another_order_are_kept_and_unlinked_cameras_left_alone():
    rng = np.random.default_rng(1)
    _, T, camera, instant, _ = _views(rng, m=3)
    none = np.full(T.shape, np.nan)
    assert not choose_turns(T, camera, instant, none, 3, 0).any()
    apart = camera != 2                             # camera 2 then shares nothing
    lone = np.where(apart, camera, 2)
    lone_instant = np.where(apart, instant, instant + 1000)
    assert not choose_turns(T, lone, lone_instant, np.broadcast_to(H, T.shape), 3, 0).any()


def test_a_view_turned_takes_the_other_order_and_turning_again_restores_it():
    T = g.transform_from_rotvec([0.2, -0.1, 0.4], [0.0, 0.0, 0.6])
    P = BOARD.object_points()
    uv = P[:, :2] * 1000.0 + 5.0                   # any pixels, one per point
    o = offer_half_turn(Observation("a.png", 0.0, T, 0.1, object_points=P, image_points=uv),
                        BOARD)
    np.testing.assert_allclose(o.alternative, T @ H)
    q = turned(o)
    np.testing.assert_allclose(q.T_cam_target, T @ H)
    np.testing.assert_array_equal(q.image_points, uv[::-1])
    back = turned(q)
    np.testing.assert_array_equal(back.image_points, uv)
    np.testing.assert_allclose(back.T_cam_target, T)
    # the turned pose puts object point k where the pixel list now has it
    moved = P @ (T @ H)[:3, :3].T + (T @ H)[:3, 3]
    np.testing.assert_allclose(moved, (P @ T[:3, :3].T + T[:3, 3])[::-1], atol=1e-12)
    # no other order: an asymmetric board, a partial view, a pose already doubled
    plain = Observation("b.png", 0.0, T, 0.1, object_points=P, image_points=uv)
    assert offer_half_turn(plain, Chessboard(rows=6, cols=9, spacing=0.03)) is plain
    part = Observation("c.png", 0.0, T, 0.1, object_points=P[:10], image_points=uv[:10])
    assert offer_half_turn(part, BOARD) is part
    assert offer_half_turn(o, BOARD) is o
    grid = CircleGrid(rows=4, cols=5, spacing=0.02)
    assert half_turn(grid).order.tolist() == list(range(19, -1, -1))


def test_fewest_turns_toggles_every_view_of_the_board_when_most_were_turned():
    T = np.eye(4)
    o = Observation("a.png", 0.0, T, alternative=T, alternative_order=np.arange(3))
    x = Observation("b.png", 0.0, T)                # no other order
    obs = [[o, o, x], [o, o]]
    got = fewest_turns(obs, [np.array([True, True, False]), np.array([True, False])])
    assert [a.tolist() for a in got] == [[False, False, False], [False, True]]
    kept = [np.array([True, False, True]), np.array([False, True])]
    got = fewest_turns(obs, [np.array([True, True, False]), np.array([True, False])], kept)
    assert [a.tolist() for a in got] == [[True, True, False], [True, False]]
    other = [[o, Observation("c.png", 0.0, T, alternative=T, alternative_order=np.arange(3),
                             target="b2")]]
    same = [np.array([True, True])]
    assert fewest_turns(other, same)[0].tolist() == [True, True]      # two boards: as given
