"""The wall-board rig without motion capture (multieye.sim.wall_boards): its frames agree with
its pixels, its variants move and see as documented."""

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.lens import project_points
from multieye.sim.wall_boards import WallSpec, noisy_views, simulate_walls


@pytest.mark.parametrize("boards", ["charuco", "chessboard"])
def test_views_are_the_projection_of_the_stated_frames(boards):
    """Each view's pixels are the board points carried by T_world_ref, T_ref_cam and
    T_world_board (the frames a user of the generator composes), to 1e-9 px."""
    sc = simulate_walls(np.random.default_rng(3), WallSpec(n_instants=15, boards=boards))
    assert np.allclose(sc.T_ref_cam[0], np.eye(4))
    assert len(sc.views) > 20
    for v in sc.views:
        T_cam_board = (g.inv(sc.T_world_ref[v.instant] @ sc.T_ref_cam[v.camera])
                       @ sc.board_pose(v.target))
        P = v.object_points @ T_cam_board[:3, :3].T + T_cam_board[:3, 3]
        uv = project_points(P, sc.intrinsics[v.camera])
        assert np.abs(uv - v.image_points).max() < 1e-9


def test_charuco_walls_each_camera_sees_a_board_in_most_instants_some_images_two():
    sc = simulate_walls(np.random.default_rng(0), WallSpec(n_instants=60))
    assert sc.seen().mean(axis=0).min() > 0.6       # 3 walls of 4 hold a board: at most 0.75
    per_image = {}
    for v in sc.views:
        per_image.setdefault((v.instant, v.camera), []).append(v.target)
    assert any(len(t) == 2 for t in per_image.values())
    # no camera overlaps another: no board point is seen by two cameras at one instant (a
    # wide board may show its two ends to two neighbours)
    per_board = {}
    for v in sc.views:
        per_board.setdefault((v.instant, v.target), []).append(set(v.ids.tolist()))
    for seen in per_board.values():
        assert sum(len(ids) for ids in seen) == len(set().union(*seen))
    ids = {n: s["first_id"] for n, s in sc.targets.items()}
    assert len(set(ids.values())) == 3


def test_chessboards_are_seen_only_by_their_camera():
    sc = simulate_walls(np.random.default_rng(1), WallSpec(n_instants=30, boards="chessboard"))
    assert {v.target: [f"cam{v.camera}"] for v in sc.views} == {
        n: s["cameras"] for n, s in sc.targets.items()}
    assert all(len(v.ids) == 54 for v in sc.views)


def test_planar_motion_turns_about_the_vertical_only_at_one_height():
    sc = simulate_walls(np.random.default_rng(2), WallSpec(n_instants=20, motion="planar"))
    R = sc.T_world_body[:, :3, :3]
    assert np.allclose(R[:, :, 2], [0.0, 0.0, 1.0])
    assert np.ptp(sc.T_world_body[:, 2, 3]) < 1e-12
    six = simulate_walls(np.random.default_rng(2), WallSpec(n_instants=20))
    assert np.abs(six.T_world_body[:, 2, :3] - [0, 0, 1]).max() > 0.05


def test_noisy_views_have_the_stated_spread():
    sc = simulate_walls(np.random.default_rng(4), WallSpec(n_instants=30))
    noisy = noisy_views(sc, 0.5, np.random.default_rng(5))
    d = np.concatenate([n.image_points - v.image_points for n, v in zip(noisy, sc.views)])
    assert abs(d.std() - 0.5) < 0.03
