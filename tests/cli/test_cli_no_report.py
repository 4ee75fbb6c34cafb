"""``multieye calibrate --no-report``: the result and its evidence without report.html and
figures/ (a second less on small recordings, where the figures are most of the run), and
``multieye report OUT`` makes the same report from them later."""

import json

from click.testing import CliRunner

from multieye.cli import main
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset


def test_no_report_writes_the_result_and_report_makes_it_later(tmp_path):
    render_wall_dataset(tmp_path / "ds", WallSpec(n_instants=12, width=640, height=480),
                        seed=0, processes=2)
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path / "ds"), "-o", str(out),
                                    "--no-report", "--processes", "1"])
    assert res.exit_code == 0, (res.stdout, res.stderr)
    assert sorted(p.name for p in out.iterdir()) == [
        ".multieye-manifest.json", "calibration.json", "camchain.yaml", "details.json"]
    manifest = json.loads((out / ".multieye-manifest.json").read_text())
    assert "report.html" not in manifest["files"]
    assert "report.html" not in res.stdout
    res = CliRunner().invoke(main, ["report", str(out)])
    assert res.exit_code == 0, (res.stdout, res.stderr)
    assert (out / "report.html").stat().st_size > 1000
    assert any((out / "figures").glob("rig_*.png"))
