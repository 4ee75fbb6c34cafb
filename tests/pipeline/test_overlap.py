"""The no-mocap stage of the pipeline (issue 23): instants from stamps, links, refusal of
groups nothing links, the rig within its predicted uncertainty, and the fit check."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import DatasetError, DisconnectedError
from multieye.core.lie import log_so3
from multieye.io import Rig
from multieye.pipeline.camera_data import CameraData, Observation
from multieye.pipeline.overlap import solve_overlap
from multieye.sim.overlap import OverlapSpec, pixel_views, simulate_overlap

SIGMA = 0.3


def _cameras(seed=0, shift=None, n=20, jitter=0.001):
    sc = simulate_overlap(np.random.default_rng(seed), OverlapSpec(n_instants=n))
    rng = np.random.default_rng(seed + 1)
    views = pixel_views(sc, SIGMA, rng)
    shift = shift or {}
    cams = {}
    for j, vs in enumerate(views):
        obs = []
        for o, u, t in vs:
            tt = shift.get(j, lambda x: x)(t)
            T = g.inv(sc.T_ref_cam[j]) @ sc.T_ref_target[t]
            T = T @ g.transform_from_rotvec(rng.normal(scale=0.01, size=3),
                                            rng.normal(scale=0.005, size=3))
            obs.append(Observation(name=f"{t}.png", stamp=100 + 0.25 * tt
                                   + rng.uniform(-jitter, jitter), T_cam_target=T,
                                   rms_px=SIGMA, object_points=o, image_points=u))
        cams[f"cam{j}"] = CameraData(name=f"cam{j}", intrinsics=sc.intrinsics[j],
                                     observations=tuple(obs), rejected=(), n_inputs=len(obs),
                                     mocap=None, time_offset=0.0, time_tolerance=0.03)
    return sc, cams


def test_the_rig_is_recovered_within_its_uncertainty_with_its_links():
    sc, cams = _cameras()
    sol = solve_overlap(cams, "cam0")
    assert sol.sync_tolerance == 0.01          # a quarter of 0.25 s, capped at 0.01 s
    res = sol.result
    for j in (1, 2):
        e = np.concatenate([log_so3(res.T_ref_cam[j, :3, :3] @ sc.T_ref_cam[j, :3, :3].T),
                            res.T_ref_cam[j, :3, 3] - sc.T_ref_cam[j, :3, 3]])
        assert float(e @ np.linalg.solve(res.covariance[j], e)) < 30      # chi2(6) tail
    both = int(np.sum(sc.seen[:, 0] & sc.seen[:, 1]))
    assert sol.links["cam0"].overlap["cam1"] == both == sol.links["cam1"].overlap["cam0"]
    assert "overlap with cam1" in sol.links["cam0"].describe()
    assert sol.findings == ()
    assert abs(res.pixel_sigma - SIGMA) < 0.05


def test_cameras_nothing_links_are_refused_naming_the_groups():
    # cam2's clock 10 s away: its images share no instant with the others
    _, cams = _cameras(shift={2: lambda t: t + 40})
    with pytest.raises(DisconnectedError, match=r"2 groups .*\{cam0, cam1\} and \{cam2\}.*"
                                                r"sync_tolerance.*mocap"):
        solve_overlap(cams, "cam0")


def test_a_camera_off_by_one_frame_is_doubted():
    # cam2's images stamped one frame late: its views pair with the wrong instants
    _, cams = _cameras(shift={2: lambda t: t + 1}, n=30)
    sol = solve_overlap(cams, "cam0")
    assert [(f.cause, f.camera) for f in sol.findings] == [("fit", "cam2")]
    assert "synchronised" in sol.findings[0].message
    assert "the other cameras fit together without it" in sol.findings[0].message


def test_a_camera_off_by_one_place_under_sync_order_is_doubted_naming_the_pairing():
    """sync: order, cam2's images one place late (an image missing in two cameras' names
    without numbers): the doubt names the k-th-image pairing, not the clocks, which such a
    rig has none of."""
    _, cams = _cameras(shift={2: lambda t: t + 1}, n=30)
    cams = {n: CameraData(**{**d.__dict__, "observations": tuple(
        Observation(**{**o.__dict__, "instant": str(int(round((o.stamp - 100) / 0.25)))})
        for o in d.observations)}) for n, d in cams.items()}
    sol = solve_overlap(cams, "cam0", sync="order")
    assert [(f.cause, f.camera) for f in sol.findings] == [("fit", "cam2")]
    assert "the k-th images of the cameras were taken together (sync: order" in \
        sol.findings[0].message
    assert "synchronised" not in sol.findings[0].message


def test_a_camera_given_by_poses_is_refused():
    _, cams = _cameras()
    d = cams["cam1"]
    cams["cam1"] = CameraData(name="cam1", intrinsics=None, observations=tuple(
        Observation(o.name, o.stamp, o.T_cam_target) for o in d.observations), rejected=(),
        n_inputs=d.n_inputs, mocap=None, time_offset=0.0, time_tolerance=0.03)
    with pytest.raises(DatasetError, match="gives poses, not images"):
        solve_overlap(cams, "cam0")


def test_images_of_one_instant_share_the_motion_capture_pose_only_when_it_agrees():
    from multieye.pipeline.camera_data import PairedCamera
    from multieye.pipeline.overlap import paired_instants, share_instants

    rng = np.random.default_rng(4)
    M = g.random_transforms(rng, 3)
    near = M[0] @ g.transform_from_rotvec([1e-5, 0, 0], [2e-5, 0, 0])   # 1 ms later, still
    far = M[1] @ g.transform_from_rotvec([0.01, 0, 0], [0.004, 0, 0])    # moved meanwhile

    def cam(name, stamps, poses):
        obs = tuple(Observation(f"{t}.png", t, np.eye(4)) for t in stamps)
        paired = PairedCamera(name=name, A=g.inv(poses), B=np.tile(np.eye(4), (len(obs), 1, 1)),
                              T_world_mocap=np.asarray(poses), observations=obs, rejected=())
        data = CameraData(name=name, intrinsics=None, observations=obs, rejected=(),
                          n_inputs=len(obs), mocap=None, time_offset=0.0, time_tolerance=0.01)
        return paired, data

    a = cam("a", [1.0, 2.0, 3.0], M)
    b = cam("b", [1.001, 2.002, 5.0], np.stack([near, far, M[2]]))
    paired, data = {"a": a[0], "b": b[0]}, {"a": a[1], "b": b[1]}
    inst, links = paired_instants(paired, data, {"a": 0.0, "b": 0.0}, None)
    assert inst["a"].tolist() == [0, 1, 2] and inst["b"].tolist() == [0, 1, 3]
    assert links["a"].overlap == {"b": 2} and links["a"].mocap
    rig = Rig(path=Path("rig.yaml"), setup="eye-to-base", cameras={})
    shared = share_instants(rig, paired, inst, (np.radians(0.1), 3e-4))
    assert np.array_equal(shared["b"].T_world_mocap[0], M[0])        # one pose, one block
    assert np.array_equal(shared["b"].A[0], g.inv(M[0]))
    assert np.array_equal(shared["b"].T_world_mocap[1], far)         # kept its own
    assert np.array_equal(shared["b"].T_world_mocap[2], M[2])


def test_the_python_face_of_a_run_without_motion_capture(tmp_path):
    """multieye.calibrate on a rendered rig without motion capture: every per-camera result by
    name, no X and no Y, links."""
    import multieye
    from multieye.sim.overlap import render_overlap_dataset

    sc = render_overlap_dataset(tmp_path / "ds", OverlapSpec(n_instants=12, width=640,
                                                             height=480), seed=5)
    run = multieye.calibrate(tmp_path / "ds", processes=1)
    assert run.X == {"cam0": None, "cam1": None, "cam2": None} and run.Y is None
    assert run.closed_form is None and run.Y_std is None and run.X_std["cam1"] is None
    for j, n in enumerate(("cam1", "cam2"), 1):
        assert g.rotation_angle_between(run.T_ref_cam[n], sc.T_ref_cam[j]) < np.radians(0.5)
        assert 0 < run.T_ref_cam_std[n][0] < 0.5
    assert run.links["cam0"].overlap and not run.links["cam0"].mocap
    assert run.doubts == ()


def test_an_image_with_points_off_is_named_among_the_warnings():
    from dataclasses import replace

    _, cams = _cameras(seed=6)
    obs = list(cams["cam1"].observations)
    uv = obs[2].image_points.copy()
    uv[:len(uv) // 2 + 1] += 4.0                      # most of its corners 13 sigma off
    obs[2] = replace(obs[2], image_points=uv)
    cams["cam1"] = replace(cams["cam1"], observations=tuple(obs))
    sol = solve_overlap(cams, "cam0")
    poor = [w for w in sol.warnings if "fit the rig poorly" in w]
    assert poor == [f"cam1: 1 image(s) fit the rig poorly: {obs[2].name}"]


def test_cameras_whose_images_share_instants_but_not_the_board_are_refused_by_check_and_calibrate(
        tmp_path):
    """Two cameras with an image at every instant, the board in cam0's first half and cam1's
    second (grey images elsewhere): ``multieye check`` linked them by the listed images and
    said 'ok, calibrating can run' while calibrating refused them; both now exit 2 saying
    the board was never seen together."""
    import shutil

    from click.testing import CliRunner

    from apart_views import render_apart
    from multieye.cli import main

    ds = render_apart(tmp_path / "ds")
    check = CliRunner().invoke(main, ["check", str(ds), "--processes", "1"])
    assert check.exit_code == 2, check.output
    assert "cam0: the board is in 4 of its images, but never at an instant when another " \
           "camera's image shows it (8 instants in both)" in check.output
    out = tmp_path / "out"
    run = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1"])
    assert run.exit_code == 2 and not out.exists(), run.output
    assert "give them views of the board at the same instants" in run.output
    shutil.rmtree(ds)
