"""The growth rule of a rig linked by its motion, on the views' indices alone (the rule the
start and ``multieye check`` share): one round of chaining, the hand-eye step's views, what
the growth reaches, and what placed a camera."""

from __future__ import annotations

import numpy as np

from multieye.estimate.motion_growth import Link, chain_round, hand_eye_views, link_of, reached

# camera, instant, board: cam0 sees board 0 at instants 0, 1 and board 1 at instant 1;
# cam1 sees board 1 at instant 1 (overlap with cam0); cam2 sees board 2 at instant 0 only
# (motion); cam3 sees board 3 at instant 2, when nothing placed is seen (apart)
VIEWS = [(0, 0, 0), (0, 1, 0), (0, 1, 1), (1, 1, 1), (2, 0, 2), (3, 2, 3)]
CAM, INST, BOARD = (list(x) for x in zip(*VIEWS))


def test_one_round_places_instants_then_boards_then_cameras():
    r = chain_round(CAM, INST, BOARD, {0}, set(), {0})
    assert r.instants == {0: [0], 1: [1]}          # cam0 sees board 0 then
    assert r.boards == {1: [2]}                     # cam0 sees board 1 at instant 1 (just placed)
    assert r.cameras == {1: [3]}                    # cam1 sees board 1 (just placed) at instant 1
    assert bool(r)
    done = chain_round(CAM, INST, BOARD, {0, 1}, {0, 1}, {0, 1})
    assert not done and done.instants == done.boards == done.cameras == {}


def test_the_hand_eye_step_takes_unplaced_cameras_seeing_unplaced_boards_at_placed_instants():
    assert hand_eye_views(CAM, INST, BOARD, {0, 1}, {0, 1}, {0, 1}) == [4]
    assert reached(CAM, INST, BOARD, 0, {0}) == ({0, 1, 2}, {0, 1}, {0, 1, 2})


def test_reached_is_the_least_closure_of_the_rules_in_any_order():
    """Against an independent fixed point: a view at a placed instant places its camera, a
    placed camera's view at a placed instant places its board, a placed camera seeing a placed
    board places the instant."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        views = [tuple(int(x) for x in rng.integers(0, (4, 6, 3))) for _ in range(rng.integers(1, 15))]
        cams, insts, boards = {0}, set(), {int(views[0][2])}
        grew = True
        while grew:
            grew = False
            for c, t, b in reversed(views):
                new = ((c in cams and b in boards and t not in insts, insts, t),
                       (c in cams and t in insts and b not in boards, boards, b),
                       (c not in cams and t in insts, cams, c))
                for cond, where, what in new:
                    if cond:
                        where.add(what)
                        grew = True
        camera, instant, board = (list(x) for x in zip(*views))
        assert reached(camera, instant, board, 0, {int(views[0][2])}) == (cams, insts, boards)


def test_a_camera_is_linked_by_overlap_when_an_instants_giver_saw_its_board_else_by_motion():
    placers = {0: {(0, 0)}, 1: {(0, 0), (1, 1)}}
    assert link_of([(1, 1)], placers) == Link("overlap", (1,))
    assert link_of([(0, 2), (1, 1)], placers) == Link("overlap", (1,))
    assert link_of([(0, 2), (1, 2)], placers) == Link("motion", (0, 1), (0, 1))
    assert link_of([(0, 2)], {0: {(0, "north"), (2, "west")}}) == Link(
        "motion", (0, 2), ("north", "west"))
    assert link_of([(5, 0)], placers) == Link("motion")
