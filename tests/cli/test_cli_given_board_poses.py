"""Boards at given poses (rig.yaml ``targets: ... pose:``, issue 34 item 2) through the CLI: a
rendered rig without motion capture before three boards on the walls, calibrated with the
boards' true poses given (in the first board's frame), with them estimated, and with one of
them given 5 cm off.  Given true poses stay exactly as given (marked given, no covariance),
the extrinsics stay within their uncertainty of the truth and that uncertainty is no larger
than with the poses estimated; a pose the views refute is written but doubted (exit status
3, cause given-pose, naming the board).  ``multieye check`` takes the poses too."""

import json
import shutil

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from multieye.cli import main
from multieye.core import geometry as g
from multieye.core.lie import log_so3
from multieye.pipeline.overlap_mocap import board_jacobians
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset


def _with_poses(ds, out, shift_m=0.0):
    """``ds`` copied as ``out`` with every board's true pose but the first's given; the
    second board's moved ``shift_m`` along its x."""
    shutil.copytree(ds, out)
    truth = json.loads((ds / "ground_truth.json").read_text())
    rig = yaml.safe_load((ds / "rig.yaml").read_text())
    first = np.array(truth["T_world_board"][rig["targets"][0]["name"]])
    poses = {}
    for k, t in enumerate(rig["targets"][1:]):
        T = g.inv(first) @ np.array(truth["T_world_board"][t["name"]])
        T[0, 3] += shift_m if k == 0 else 0.0
        t["pose"] = [[float(x) for x in r] for r in T]
        poses[t["name"]] = np.array(t["pose"])
    (out / "rig.yaml").write_text(yaml.safe_dump(rig))
    return poses


def _calibrate(ds, out):
    return CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1"])


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("given")
    render_wall_dataset(tmp / "ds", WallSpec(n_instants=14), seed=0)
    poses = _with_poses(tmp / "ds", tmp / "given")
    _with_poses(tmp / "ds", tmp / "wrong", shift_m=0.05)
    res = {name: _calibrate(tmp / name, tmp / f"out_{name}") for name in ("ds", "given", "wrong")}
    return tmp, poses, res


def _rec(tmp, name):
    return json.loads((tmp / f"out_{name}" / "calibration.json").read_text())


def test_true_given_poses_stay_as_given_and_the_extrinsics_are_no_less_certain(runs):
    tmp, poses, res = runs
    assert res["ds"].exit_code == 0 and res["given"].exit_code == 0, res["given"].stderr
    truth = json.loads((tmp / "ds" / "ground_truth.json").read_text())
    free, given = _rec(tmp, "ds"), _rec(tmp, "given")
    assert given["plausibility"] == [] and given["method"] == "motion-links"
    for name, T in poses.items():
        board = given["targets"][name]
        assert board["given"] is True and "covariance" not in board
        np.testing.assert_array_equal(np.array(board["T_world_target"]), T)
        assert free["targets"][name]["given"] is False and "covariance" in free["targets"][name]
    for name in ("cam1", "cam2", "cam3"):
        cam, true = given["cameras"][name], np.array(truth["T_ref_cam"][name])
        T = np.array(cam["T_ref_cam"])
        e = np.concatenate([log_so3(T[:3, :3] @ true[:3, :3].T), T[:3, 3] - true[:3, 3]])
        assert float(e @ np.linalg.solve(np.array(cam["covariance"]), e)) < 30   # chi2(6)
        assert cam["std_rot_deg"] <= free["cameras"][name]["std_rot_deg"]
        assert cam["std_trans_m"] <= free["cameras"][name]["std_trans_m"]
    page = (tmp / "out_given" / "report.html").read_text()
    assert "thin: given in rig.yaml (west, south)" in page


def test_a_given_pose_the_views_refute_is_written_and_doubted_naming_the_board(runs):
    tmp, poses, res = runs
    assert res["wrong"].exit_code == 3, (res["wrong"].stdout, res["wrong"].stderr)
    doubts = [line for line in res["wrong"].stderr.splitlines() if "implausible" in line]
    assert len(doubts) == 1 and "given-pose: target west's pose given in rig.yaml" in doubts[0]
    assert "50." in doubts[0] and " mm from where the views place it" in doubts[0]
    rec = _rec(tmp, "wrong")
    assert [p["cause"] for p in rec["plausibility"]] == ["given-pose"]
    held = poses["west"].copy()
    held[0, 3] += 0.05                       # written as given, not moved to the views
    np.testing.assert_array_equal(np.array(rec["targets"]["west"]["T_world_target"]), held)


def test_check_takes_given_poses(runs):
    tmp, _, _ = runs
    res = CliRunner().invoke(main, ["check", str(tmp / "given")])
    assert res.exit_code == 0, (res.stdout, res.stderr)


def test_given_poses_with_motion_capture_stay_as_given_in_the_mocap_frame(tmp_path):
    """With the rig's motion capture too (eye-on-hand): the given boards are held, so each
    sits at ``T_world_target`` of the first board times its given pose, to rounding, marked
    given; its uncertainty there is the first board's carried through the given pose (the
    motion capture's frame), and the extrinsics stay within their uncertainty of the truth."""
    render_wall_dataset(tmp_path / "ds", WallSpec(n_instants=16, width=640, height=480),
                        seed=1, mocap=True)
    poses = _with_poses(tmp_path / "ds", tmp_path / "given")
    res = _calibrate(tmp_path / "given", tmp_path / "out")
    assert res.exit_code == 0, (res.stdout, res.stderr)
    rec = json.loads((tmp_path / "out" / "calibration.json").read_text())
    truth = json.loads((tmp_path / "ds" / "ground_truth.json").read_text())
    first = next(iter(rec["targets"]))
    Y = np.array(rec["targets"][first]["T_world_target"])
    for name, T in poses.items():
        t = rec["targets"][name]
        assert t["given"] is True
        np.testing.assert_allclose(np.array(t["T_world_target"]), Y @ T, atol=1e-9)
        # the first board's uncertainty carried to the given one (board_jacobians: checked
        # against central differences in tests/pipeline/test_overlap_mocap.py)
        j_y, _ = board_jacobians(Y, T)
        np.testing.assert_allclose(np.array(t["covariance"]),
                                   j_y @ np.array(rec["targets"][first]["covariance"]) @ j_y.T,
                                   rtol=1e-6, atol=1e-15)
    for name, cam in rec["cameras"].items():
        if name == rec["reference_camera"]:
            continue
        T, true = np.array(cam["T_ref_cam"]), np.array(truth["T_ref_cam"][name])
        e = np.concatenate([log_so3(T[:3, :3] @ true[:3, :3].T), T[:3, 3] - true[:3, 3]])
        assert float(e @ np.linalg.solve(np.array(cam["covariance"]), e)) < 30, name
