"""multieye calibrate on a rendered rig without motion capture and without overlap (issue 34):
four cameras facing different ways, moved before boards on the walls.  Moved in 6 DoF it is
calibrated (exit status 0, each T_ref_cam within its predicted uncertainty); driven on a floor
with one board per camera, it is written but doubted (exit status 3) naming every camera's
height."""

import json

import numpy as np
from click.testing import CliRunner

from multieye.cli import main
from multieye.core import geometry as g
from multieye.core.lie import log_so3
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset


def _calibrate(ds, out):
    return CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1"])


def test_a_rig_moved_before_boards_on_the_walls_is_calibrated(tmp_path):
    render_wall_dataset(tmp_path / "ds", WallSpec(n_instants=14), seed=0)
    res = _calibrate(tmp_path / "ds", tmp_path / "out")
    assert res.exit_code == 0, (res.stdout, res.stderr)
    assert "cam1 linked by: motion via cam0" in res.stdout
    assert "cam0 linked by: reference camera\n" in res.stdout       # not "nothing"
    html = (tmp_path / "out" / "report.html").read_text()
    assert "What links each camera" in html and "motion via cam0" in html
    truth = json.loads((tmp_path / "ds" / "ground_truth.json").read_text())
    rec = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert rec["method"] == "motion-links" and rec["plausibility"] == []
    for name in ("cam1", "cam2", "cam3"):
        cam = rec["cameras"][name]
        T, true = np.array(cam["T_ref_cam"]), np.array(truth["T_ref_cam"][name])
        e = np.concatenate([log_so3(T[:3, :3] @ true[:3, :3].T), T[:3, 3] - true[:3, 3]])
        assert float(e @ np.linalg.solve(np.array(cam["covariance"]), e)) < 30   # chi2(6)
        assert cam["links"]["motion"]["cameras"][0] == "cam0"
    T_first = np.array(truth["T_world_board"]["north"])
    for board, t in rec["targets"].items():
        true = g.inv(T_first) @ np.array(truth["T_world_board"][board])
        assert g.translation_distance(np.array(t["T_world_target"]), true) < 0.005, board


def test_a_rig_driven_on_a_floor_is_written_and_doubted_naming_each_height(tmp_path):
    render_wall_dataset(tmp_path / "ds", WallSpec(n_instants=10, boards="chessboard",
                                                  motion="planar"), seed=0)
    res = _calibrate(tmp_path / "ds", tmp_path / "out")
    assert res.exit_code == 3, (res.stdout, res.stderr)
    doubts = [line for line in res.stderr.splitlines() if "implausible" in line]
    assert len(doubts) == 3
    for cam, line in zip(("cam1", "cam2", "cam3"), doubts):
        assert (f"observability: {cam}: translation along the axis the rig turned about "
                "(y of the rig)") in line and "tilt the rig" in line
    rec = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert [p["cause"] for p in rec["plausibility"]] == ["observability"] * 3
