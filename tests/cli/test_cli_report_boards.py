"""The report's rig figure draws the boards of a rig with several (issue 34, item 2): a
rendered rig with motion capture (eye-on-hand) before boards on the walls, calibrated through
the CLI; the boards are built from calibration.json and details.json (their poses in the
motion capture's frame, their outline kept in the file), handed to the rig figure by the
drawing in this process and by the figure workers' task, and named in the report's legend.  A
rig without motion capture, linked by its motion, draws them in the first board's frame with
the rig's trajectory (details.json: the rig's pose per instant); a run without details.json
draws none, and a file without the boards' outline (older versions) still loads."""

import json
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from multieye.cli import main
from multieye.imaging.targets import target_from_spec
from multieye.io.calibration_json import calibration_from_dict, read_calibration
from multieye.io.rig import load_rig
from multieye.io.run_details import read_run_details
from multieye.outputs import figures_rig, report_draw
from multieye.outputs.board_marks import record_boards
from multieye.outputs.rig_legend import linked_by
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset


def _run(tmp, mocap):
    render_wall_dataset(tmp / "ds", WallSpec(n_instants=16, width=480, height=360),
                        seed=1, mocap=mocap)
    res = CliRunner().invoke(main, ["calibrate", str(tmp / "ds"), "-o", str(tmp / "out"),
                                    "--processes", "1"])
    assert res.exit_code in (0, 3), (res.stdout, res.stderr)
    return (read_calibration(tmp / "out" / "calibration.json"),
            read_run_details(tmp / "out" / "details.json"))


@pytest.fixture(scope="module")
def mocap_out(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("boards")
    return tmp, *_run(tmp, mocap=True)


def test_each_board_is_built_from_the_files_in_the_figures_frame(mocap_out):
    tmp, rec, details = mocap_out
    rig = load_rig(tmp / "ds" / "rig.yaml")
    marks = record_boards(rec, details)
    assert rec.mocap and len(rig.targets) > 1
    assert [m.name for m in marks] == list(rig.targets) == list(rec.targets)
    for m in marks:
        board, spec = rec.targets[m.name], target_from_spec(rig.targets[m.name])
        assert m.bounds == pytest.approx(spec.bounds()) and m.z_into_board == spec.z_into_board
        np.testing.assert_array_equal(m.T_frame_board, board.T_world_target)  # the mocap frame
        np.testing.assert_array_equal(m.covariance, board.uncertainty.covariance)
    # the boards stand where the cameras (drawn at T_world_body_shown) look: each board's
    # centre is in front of a camera that saw it
    for m in marks:
        seen = [c for c in details.cameras if c.name in rec.targets[m.name].cameras]
        ahead = [(np.linalg.inv(c.T_world_cam) @ np.append(m.centre(), 1))[2] for c in seen]
        assert max(ahead) > 0.2, m.name


def test_the_report_and_both_drawing_paths_draw_the_boards(mocap_out, monkeypatch):
    tmp, rec, details = mocap_out
    n = len(rec.targets)
    sentence = f"the {n} boards, each with a short line towards the side it is seen from"
    page = (tmp / "out" / "report.html").read_text()
    assert f"Dark rectangles: {sentence}" in page        # the CLI's report
    given = []
    real = figures_rig.rig_pngs          # the rig's task, record_rig_pngs, calls it there
    monkeypatch.setattr(figures_rig, "rig_pngs", lambda *a, **k: given.append(
        k["boards"]) or real(*a, **k))
    _, legend = report_draw.submit_figures(rec, details, None)()      # in this process
    assert [b.name for b in given[-1]] == list(rec.targets)
    assert any(sentence in line for line in legend)
    rig_task = report_draw._tasks(rec, details, [], 1)[0]             # the workers' task
    figures = rig_task[1](*rig_task[2])
    assert [b.name for b in given[-1]] == list(rec.targets)
    assert any(sentence in line for line in figures.legend)


def test_older_files_without_the_outline_load_and_draw_no_boards(mocap_out):
    tmp, rec, details = mocap_out
    data = json.loads((tmp / "out" / "calibration.json").read_text())
    assert all("bounds" in t for t in data["targets"].values())
    for t in data["targets"].values():
        del t["bounds"], t["z_into_board"]
    old = calibration_from_dict(data)
    assert all(b.bounds is None for b in old.targets.values())
    assert record_boards(old, details) == ()


def test_without_details_no_boards_are_drawn(mocap_out):
    _, rec, details = mocap_out
    assert record_boards(rec, None) == ()


@pytest.fixture(scope="module")
def plain_out(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("plain")
    return tmp, *_run(tmp, mocap=False)


def test_without_motion_capture_the_boards_and_the_rig_path_are_in_the_first_boards_frame(
        plain_out):
    tmp, rec, details = plain_out
    assert len(rec.targets) > 1 and not rec.mocap and rec.method == "motion-links"
    first = next(iter(rec.targets))
    assert details.frame == first
    (path,) = details.trajectories
    assert path.pose == f"T_{first}_rig" and path.T.shape == (len(path.stamps), 4, 4)
    np.testing.assert_array_equal(path.positions, path.T[:, :3, 3])
    assert np.all(np.diff(path.stamps) >= 0)
    # the cameras are drawn at the rig's pose of its middle instant
    np.testing.assert_array_equal(details.T_world_body_shown, path.T[len(path.T) // 2])
    for c in rec.cameras:
        np.testing.assert_allclose(details.camera(c.name).T_world_cam,
                                   details.T_world_body_shown @ c.T_ref_cam, atol=1e-12)
    marks = record_boards(rec, details)
    assert [m.name for m in marks] == list(rec.targets)
    np.testing.assert_array_equal(marks[0].T_frame_board, np.eye(4))   # the world
    assert marks[0].covariance is None                                 # held: none drawn
    for m in marks[1:]:
        np.testing.assert_array_equal(m.covariance, rec.targets[m.name].uncertainty.covariance)
    # each board stands before a camera that saw it, at an instant of the rig's path; each
    # view's board, placed through the rig's pose and the camera, is at its board
    for m in marks:
        cam = next(c.name for c in rec.cameras if c.name in rec.targets[m.name].cameras)
        T_ref_cam = next(c.T_ref_cam for c in rec.cameras if c.name == cam)
        ahead = [(np.linalg.inv(T @ T_ref_cam) @ np.append(m.centre(), 1))[2] for T in path.T]
        assert max(ahead) > 0.5, m.name
    origins = np.concatenate([c.T_world_target[:, :3, 3] for c in details.cameras])
    board_origins = np.array([m.T_frame_board[:3, 3] for m in marks])
    assert np.max(np.min(np.linalg.norm(origins[:, None] - board_origins[None], axis=2),
                         axis=1)) < 0.02


def test_without_motion_capture_the_report_draws_the_boards_and_says_what_it_draws(plain_out):
    tmp, rec, _ = plain_out
    page = (tmp / "out" / "report.html").read_text()
    first = next(iter(rec.targets))
    assert f"Dark rectangles: the {len(rec.targets)} boards" in page
    assert f"Camera frustums in the first board's frame <code>{first}</code>" in page
    assert (f"Grey line: the rig&#x27;s trajectory, the reference camera&#x27;s position at "
            f"every instant (T_{first}_rig") in page
    assert "the motion capture (T_" not in page
    assert "by the rig&#x27;s motion before the boards" in page


def test_one_camera_is_said_to_need_no_link(plain_out):
    _, rec, _ = plain_out
    one = replace(rec, cameras=rec.cameras[:1])
    assert linked_by(one) == (f"one camera, {rec.cameras[0].name}, whose frame is the rig's: "
                              "nothing to link")
