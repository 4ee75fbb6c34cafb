"""The report's rig figure draws the boards of a rig with several (issue 34, item 2): a
rendered rig with motion capture (eye-on-hand) before boards on the walls, calibrated through
the CLI; the boards are built from calibration.json and details.json (their poses in the
motion capture's frame, their outline kept in the file), handed to the rig figure by the
drawing in this process and by the figure workers' task, and named in the report's legend.  A
rig without motion capture draws none (no one frame holds the boards and the cameras), and a
file without the boards' outline (older versions) still loads."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from multieye.cli import main
from multieye.imaging.targets import target_from_spec
from multieye.io.calibration_json import calibration_from_dict, read_calibration
from multieye.io.rig import load_rig
from multieye.io.run_details import read_run_details
from multieye.outputs import report_draw
from multieye.outputs.board_marks import record_boards
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
    real = report_draw.rig_pngs
    monkeypatch.setattr(report_draw, "rig_pngs", lambda *a, **k: given.append(
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


def test_without_motion_capture_or_details_no_boards_are_drawn(mocap_out, tmp_path):
    _, rec, details = mocap_out
    assert record_boards(rec, None) == ()
    rec, details = _run(tmp_path, mocap=False)
    assert len(rec.targets) > 1 and not rec.mocap
    assert record_boards(rec, details) == ()
    assert "boards, each with a short line" not in (tmp_path / "out" / "report.html").read_text()
