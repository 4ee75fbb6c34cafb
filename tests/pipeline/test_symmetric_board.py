"""A half-turn symmetric chessboard (6 x 8 inner corners) whose point order the image cannot
decide: cameras rolled apart (upside down, a quarter turn) and a board near the diagonal
take opposite orders of the same board.  Rendered rigs, with motion capture and without;
every view is used in the order the rig's geometry agrees with, and the rig comes out
within its noise."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.metrics import extrinsic_errors
from multieye.imaging.order_turn import half_turn
from multieye.imaging.targets import Chessboard
from multieye.io import Trajectory, load_rig, write_opencv_intrinsics, write_tum
from multieye.pipeline import calibrate, calibrate_rig, load_camera_data
from multieye.sim.render import render, visible

BOARD = Chessboard(rows=6, cols=8, spacing=0.03)
TARGET = "target: {type: chessboard, rows: 6, cols: 8, spacing: 0.03}"
CENTRE = np.array([3.5 * 0.03, 2.5 * 0.03, 0.0])
TURN = half_turn(BOARD)


def _angle_deg(Ta: np.ndarray, Tb: np.ndarray) -> float:
    R = Ta[:3, :3].T @ Tb[:3, :3]
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))


def _lens(j: int) -> Intrinsics:
    return Intrinsics(K=np.array([[520.0, 0, 319.5 + 3 * j], [0, 520.0, 239.5 - 2 * j],
                                  [0, 0, 1]]), dist=np.array([-0.05, 0.01, 0.0, 0.0]),
                      width=640, height=480)


def _board_pose(rng, roll_deg: float, distance: float = 0.55) -> np.ndarray:
    """T_cam_target: the board's centre near the optical axis, tilted 10-30 degrees, its x
    axis at ``roll_deg`` in the image (0: to the right, 90: down)."""
    axis = rng.normal(size=2)
    axis /= np.linalg.norm(axis)
    tilt = np.radians(rng.uniform(10, 30))
    R = g.transform_from_rotvec([*(tilt * axis), 0.0], [0, 0, 0])[:3, :3] @ \
        g.transform_from_rotvec([0, 0, np.radians(roll_deg)], [0, 0, 0])[:3, :3]
    t = np.array([rng.uniform(-0.04, 0.04), rng.uniform(-0.03, 0.03), distance]) - R @ CENTRE
    return g.make_transform(R, t)


def _write(folder, name: str, stamp: float, intr: Intrinsics, T: np.ndarray, seed: int) -> None:
    img = render(BOARD, intr, T, rng=np.random.default_rng(seed), blur_sigma=0.7,
                 noise_sigma=2.0)
    cv2.imwrite(str(folder / name / f"{stamp:.6f}.png"), img)


def _turned_in_detection(observations, truth) -> np.ndarray:
    """Per view: was it detected in the other order than the truth's?"""
    return np.array([_angle_deg(o.T_cam_target, truth[o.name]) > 90 for o in observations])


def render_mocap_rig(folder, rolls, counts, seed: int = 3):
    """Static cameras, the board on a motion-captured body; camera j sees it with its x axis
    at ``rolls[j]`` +- 12 degrees in the image (180: the camera upside down), ``counts[j]``
    images.  Returns per camera T_world_cam and {image name: T_cam_target}."""
    rng = np.random.default_rng(seed)
    T_marker_target = g.transform_from_rotvec([0.2, -0.1, 0.3], [0.03, -0.02, 0.05])
    stamps, T_wm, truth = [], [], {}
    lines = ["setup: eye-to-base", TARGET, "mocap:", "  file: mocap.txt",
             "  pose: T_world_marker", "  time_tolerance: 0.001", "  rotation_noise_deg: 0.02",
             "  translation_noise_m: 0.0002", "cameras:"]
    t = 100.0
    for j, (roll, n) in enumerate(zip(rolls, counts)):
        name, intr = f"cam{j}", _lens(j)
        T_world_cam = g.transform_from_rotvec([0, 0, rng.uniform(-np.pi, np.pi)],
                                              [rng.uniform(-2, 2), rng.uniform(-2, 2), 1.0])
        (folder / name).mkdir(parents=True)
        write_opencv_intrinsics(folder / f"{name}.yaml", intr)
        poses = {}
        while len(poses) < n:
            T = _board_pose(rng, roll + rng.uniform(-12, 12))
            if not visible(BOARD, intr, T, border_px=10):
                continue
            _write(folder, name, t, intr, T, int(rng.integers(1 << 31)))
            noise = g.transform_from_rotvec(rng.normal(scale=np.radians(0.02), size=3),
                                            rng.normal(scale=0.0002, size=3))
            stamps.append(t)
            T_wm.append(T_world_cam @ T @ g.inv(T_marker_target) @ noise)
            poses[f"{t:.6f}.png"] = T
            t += 0.5
        truth[name] = (T_world_cam, poses)
        lines += [f"  {name}: {{intrinsics: {name}.yaml, images: {name}/}}"]
        t += 5.0
    write_tum(folder / "mocap.txt", Trajectory(np.array(stamps), np.stack(T_wm), "world", "marker"))
    (folder / "rig.yaml").write_text("\n".join(lines) + "\n")
    return truth


@pytest.fixture(scope="module")
def mocap_rig(tmp_path_factory):
    """cam0 upright (12 images), cam1 upside down (8), cam2 with the board near the diagonal
    where the detector's rule changes its mind (x at 135 degrees: 10)."""
    folder = tmp_path_factory.mktemp("symmetric_mocap")
    truth = render_mocap_rig(folder, rolls=(0.0, 180.0, 135.0), counts=(12, 8, 10))
    cameras = load_camera_data(load_rig(folder / "rig.yaml"), processes=1)
    run = calibrate(folder, processes=1)
    return truth, cameras, run


def test_motion_captured_rig_uses_every_view_in_the_order_that_agrees(mocap_rig):
    truth, cameras, run = mocap_rig
    detected = {n: _turned_in_detection(cameras[n].observations, truth[n][1]) for n in truth}
    # the rig exercises the choice: cam1 all turned, cam2 some turned and some not
    assert detected["cam0"].sum() == 0 and detected["cam1"].all(), detected
    assert 0 < detected["cam2"].sum() < len(detected["cam2"]), detected
    for name, (_, poses) in truth.items():
        obs = cameras[name].observations
        assert len(obs) == len(poses)
        kept = run.paired[name].observations
        assert len(kept) == len(obs), [r.reason for r in run.paired[name].rejected]
        # each view in the true order: its pose, and its pixels where that order projects
        assert max(_angle_deg(o.T_cam_target, poses[o.name]) for o in kept) < 3
        intr = cameras[name].intrinsics
        for o in kept:
            T = poses[o.name]
            uv = cv2.projectPoints(o.object_points, cv2.Rodrigues(T[:3, :3])[0], T[:3, 3],
                                   intr.K, intr.dist)[0].reshape(-1, 2)
            assert np.abs(uv - o.image_points).max() < 1.0
    rec = run.record
    T_true = np.stack([truth[c.name][0] for c in rec.cameras])
    rot, trans = extrinsic_errors(np.stack([c.X for c in rec.cameras]), T_true)
    for j, c in enumerate(rec.cameras):
        u = c.uncertainty["T_world_cam"]
        assert rot[j] < 4 * u.std_rot_deg and trans[j] < 4 * u.std_trans_m, (c.name, rot, trans)
    assert not run.plausibility.findings, run.plausibility.messages
    turned = sum(int(d.sum()) for d in detected.values())
    line = [w for w in rec.warnings if w.startswith("half-turn symmetric board")]
    assert len(line) == 1 and f"{turned} of 30 views were turned" in line[0], rec.warnings


def test_motion_captured_rig_without_consensus_chooses_the_order_too(mocap_rig):
    truth, cameras, run = mocap_rig
    plain = calibrate_rig(run.rig, cameras, robust=False, refine=False)
    for name, (_, poses) in truth.items():
        kept = plain.paired[name].observations
        assert len(kept) == len(poses)
        assert max(_angle_deg(o.T_cam_target, poses[o.name]) for o in kept) < 3
    rot, trans = extrinsic_errors(np.stack([plain.X[n] for n in truth]),
                                  np.stack([truth[n][0] for n in truth]))
    assert rot.max() < 0.5 and trans.max() < 0.01, (rot, trans)


def render_overlap_rig(folder, roll_deg: float, board_deg: tuple[float, float], n: int = 10,
                       seed: int = 5):
    """Two cameras 0.12 m apart, cam1 rolled by ``roll_deg`` about its optical axis, both
    seeing the board at every instant (stamps equal, no motion capture); the board's x axis
    at ``board_deg[0] +- board_deg[1]`` degrees in cam0's image.  Returns T_ref_cam of
    cam1."""
    rng = np.random.default_rng(seed)
    T_ref_cam1 = g.transform_from_rotvec([0.0, np.radians(-6.0), 0.0], [0.12, 0.0, 0.0]) @ \
        g.transform_from_rotvec([0.0, 0.0, np.radians(roll_deg)], [0, 0, 0])
    lenses = [_lens(0), _lens(1)]
    lines = [TARGET, "cameras:"]
    for j in range(2):
        (folder / f"cam{j}").mkdir(parents=True)
        write_opencv_intrinsics(folder / f"cam{j}.yaml", lenses[j])
        lines += [f"  cam{j}: {{intrinsics: cam{j}.yaml, images: cam{j}/}}"]
    t, made = 10.0, 0
    while made < n:
        T0 = _board_pose(rng, board_deg[0] + rng.uniform(-1, 1) * board_deg[1], distance=0.6)
        T0[0, 3] += 0.06                                  # between the two cameras
        T1 = g.inv(T_ref_cam1) @ T0
        if not (visible(BOARD, lenses[0], T0, border_px=10)
                and visible(BOARD, lenses[1], T1, border_px=10)):
            continue
        for j, T in enumerate((T0, T1)):
            _write(folder, f"cam{j}", t, lenses[j], T, int(rng.integers(1 << 31)))
        t += 0.5
        made += 1
    (folder / "rig.yaml").write_text("\n".join(lines) + "\n")
    return T_ref_cam1


@pytest.mark.parametrize("roll_deg, board_deg", [(180.0, (0.0, 15.0)), (90.0, (0.0, 15.0)),
                                                 (20.0, (-35.0, 20.0))])
def test_overlapping_cameras_rolled_apart_give_the_baseline(tmp_path, roll_deg, board_deg):
    """No motion capture: cam1 upside down, a quarter turn, or rolled 20 degrees with the
    board's x axis near the image's diagonal (x towards the upper right: the rule that
    decides the order changes its mind between frames and between the cameras)."""
    T_true = render_overlap_rig(tmp_path, roll_deg, board_deg)
    rig = load_rig(tmp_path / "rig.yaml")
    cameras = load_camera_data(rig, processes=1)
    # the detections disagree on the order at some instants (what the test is about)
    rel = [_angle_deg(a.T_cam_target, T_true @ b.T_cam_target) for a, b in
           zip(cameras["cam0"].observations, cameras["cam1"].observations)]
    disagree = sum(r > 90 for r in rel)
    assert disagree >= 2, rel
    run = calibrate(tmp_path, processes=1)
    T = run.record.cameras[1].T_ref_cam
    rot, trans = extrinsic_errors(T[None], T_true[None])
    assert rot[0] < 0.2 and trans[0] < 1e-3, (rot, trans)
    assert all(len(run.paired[n].observations) == 10 for n in ("cam0", "cam1"))
    assert not run.plausibility.findings, run.plausibility.messages
    line = [w for w in run.record.warnings if w.startswith("half-turn symmetric board")]
    assert len(line) == 1 and f"{disagree} of 20 views were turned" in line[0], line


def test_half_turn_maps_point_k_to_the_last_but_k():
    assert TURN.order.tolist() == list(range(47, -1, -1))
    P = BOARD.object_points()
    moved = P @ TURN.T_target_turned[:3, :3].T + TURN.T_target_turned[:3, 3]
    np.testing.assert_allclose(moved, P[TURN.order], atol=1e-12)
    assert half_turn(Chessboard(rows=6, cols=9, spacing=0.03)) is None


def _exact_pairs(rng, flips):
    """Exact measurements ``A X = Y B`` of cameras whose views ``flips[j]`` (bool per view)
    were detected in the other order (``T_cam_target @ H``); with both orders offered."""
    from multieye.pipeline.camera_data import Observation, PairedCamera

    Y = g.transform_from_rotvec([0.3, -0.2, 0.5], [0.1, 0.2, 0.3])
    H = TURN.T_target_turned
    paired, X = {}, []
    for j, flip in enumerate(flips):
        Xj = g.transform_from_rotvec(rng.normal(scale=1.0, size=3), rng.normal(size=3))
        A = g.random_transforms(rng, len(flip))
        T = g.inv(np.linalg.inv(Y) @ A @ Xj)                 # T_cam_target = inv(B)
        T[flip] = T[flip] @ H
        obs = tuple(Observation(f"{k}.png", float(k), t, 0.1, object_points=BOARD.object_points(),
                                image_points=np.zeros((48, 2)), alternative=t @ H,
                                alternative_rms_px=0.1, alternative_order=TURN.order)
                    for k, t in enumerate(T))
        paired[f"cam{j}"] = PairedCamera(f"cam{j}", A, g.inv(T), A, obs, ())
        X.append(Xj)
    return paired, np.stack(X), Y


def test_noise_free_measurements_give_the_rig_exactly_whichever_order_was_detected():
    from multieye.estimate.consensus import consensus
    from multieye.pipeline.ambiguity import alternatives, closed_form_choice, with_choice
    from multieye.pipeline.half_turns import fewest_turns
    from multieye.solvers.checks import Measurements

    rng = np.random.default_rng(2)
    flips = [np.zeros(12, bool), np.ones(9, bool), rng.random(10) < 0.5]
    paired, X, Y = _exact_pairs(rng, flips)
    meas = Measurements.from_cameras([p.A for p in paired.values()],
                                     [p.B for p in paired.values()])
    # without consensus: the closed form chooses, every view in the true order
    got, meas2, turns = closed_form_choice(paired, meas, "joint")
    assert [t.tolist() for t in turns.values()] == [f.tolist() for f in flips]
    for j, p in enumerate(got.values()):
        np.testing.assert_allclose(g.inv(p.B), g.inv(paired[f"cam{j}"].B) @
                                   np.where(flips[j][:, None, None], TURN.T_target_turned,
                                            np.eye(4)), atol=1e-9)
    from multieye.solvers import solve
    sol = solve(meas2, method="joint")
    np.testing.assert_allclose(sol.X, X, atol=1e-8)
    np.testing.assert_allclose(sol.Y, Y, atol=1e-8)
    # the consensus: every view kept, the same choice once the fewer turns are kept
    cons = consensus(meas, threshold_rot_deg=1.0, threshold_trans_m=0.01,
                     B_alternative=alternatives(paired.values()))
    assert all(k.all() for k in cons.inliers)
    choice = fewest_turns([p.observations for p in paired.values()], cons.alternative)
    assert [c.tolist() for c in choice] == [f.tolist() for f in flips]
    chosen = [with_choice(p, c) for p, c in zip(paired.values(), choice)]
    sol = solve(Measurements.from_cameras([p.A for p in chosen], [p.B for p in chosen]),
                method="joint")
    np.testing.assert_allclose(sol.X, X, atol=1e-8)


def test_views_taken_back_are_turned_to_the_order_the_refined_rig_agrees_with():
    """Exact measurements: whichever order a view taken back was detected in, it joins in
    the order ``inv(Y) A_i X`` predicts (the consensus chose it for the views kept)."""
    from multieye.pipeline.image_acceptance import agreeing_turns

    rng = np.random.default_rng(4)
    flips = rng.random(12) < 0.5
    assert 0 < flips.sum() < 12
    paired, X, Y = _exact_pairs(rng, [flips])
    p = paired["cam0"]
    got = agreeing_turns(p.observations, p.A, X[0], Y)
    truth = g.inv(np.linalg.solve(Y, p.A @ X[0]))
    for o, T, flip, before in zip(got, truth, flips, p.observations):
        assert _angle_deg(o.T_cam_target, T) < 1e-4
        # the points follow the pose: turned views carry their points in the other order
        expected = before.image_points[TURN.order] if flip else before.image_points
        np.testing.assert_array_equal(o.image_points, expected)


def test_motion_captured_views_left_out_on_the_start_are_taken_back_in_the_order_that_agrees(
        mocap_rig):
    """cam1 (upside down: every view detected in the other order) with its lens estimated
    from a start that leaves two views out as a bad fit and a third to the consensus (its
    pose on that lens is off by 7.5 degrees): all three are taken back on the refined lens,
    turned as the consensus turned the others, and the rig is the truth's."""
    from dataclasses import replace

    from multieye.imaging.detect import Detection
    from multieye.imaging.pnp import estimate_poses
    from multieye.io import RejectedItem

    truth, cameras, run = mocap_rig
    d = cameras["cam1"]
    start = d.intrinsics.with_params(d.intrinsics.params + np.r_[0, 0, 0, 0, 1.5, 0, 0, 0])
    poses = estimate_poses([Detection(np.arange(len(o.image_points)), o.image_points,
                                      o.object_points) for o in d.observations], start)
    posed = [replace(o, T_cam_target=p.T_cam_target, rms_px=p.rms_px,
                     alternative=p.T_cam_target @ TURN.T_target_turned,
                     alternative_rms_px=p.rms_px) for o, p in zip(d.observations, poses)]
    bad = tuple(o for o in posed if o.rms_px > 2.0)
    assert 1 <= len(bad) <= 4, [o.rms_px for o in posed]
    started = replace(d, intrinsics=start, intrinsics_estimated=True, bad_fits=bad,
                      observations=tuple(o for o in posed if o.rms_px <= 2.0),
                      rejected=tuple(RejectedItem(o.name, f"bad fit: reprojection RMS "
                                                  f"{o.rms_px:.2f} px > 2 px") for o in bad))
    got = calibrate_rig(run.rig, {**cameras, "cam1": started})
    kept = got.paired["cam1"].observations
    # every view: the bad fits, and one the consensus left out on the start's poses
    assert sorted(o.name for o in kept) == sorted(truth["cam1"][1]), got.record.warnings
    (line,) = [w for w in got.record.warnings if "taken back" in w]
    assert line.startswith("cam1: 3 image(s) left out on the starting lens (2 as a bad fit, 1 by "
                           "the consensus on its poses) taken back"), line
    assert got.paired["cam1"].rejected == ()
    assert max(_angle_deg(o.T_cam_target, truth["cam1"][1][o.name]) for o in kept) < 3
    T_true = np.stack([truth[c.name][0] for c in got.record.cameras])
    rot, trans = extrinsic_errors(np.stack([c.X for c in got.record.cameras]), T_true)
    assert rot.max() < 0.1 and trans.max() < 2e-3, (rot, trans)
