"""multieye check on rigs with several boards (rig.yaml ``targets:``, issue 34): every board
each camera may see is looked for, counted per camera, and the cameras that only the rig's
motion links are said to be linked so; a rig the calibration accepts is not refused."""

from click.testing import CliRunner

from multieye.cli import main
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset


def _check(ds):
    return CliRunner().invoke(main, ["check", str(ds), "--processes", "2"])


def test_check_counts_every_board_and_says_the_motion_links(tmp_path):
    render_wall_dataset(tmp_path / "ds", WallSpec(n_instants=16, width=640, height=480),
                        seed=0, processes=2)
    res = _check(tmp_path / "ds")
    assert res.exit_code == 0, (res.stdout, res.stderr)
    for cam in ("cam0", "cam1", "cam2", "cam3"):
        line = next(x for x in res.stdout.splitlines()
                    if x.startswith(f"{cam}: boards found in the 16 sampled images: "))
        counts = dict(p.split(" in ") for p in line.split(": ", 2)[2].split(", "))
        assert set(counts) == {"north", "west", "south"}
        assert sum(int(k) for k in counts.values()) >= 8, line
    assert "cam0 linked by: reference camera" in res.stdout
    links = [x for x in res.stdout.splitlines() if " linked by: " in x][1:]
    assert [x.split()[0] for x in links] == ["cam1", "cam2", "cam3"]
    assert all(": overlap with " in x or ": motion via cam0" in x for x in links), links
    assert sum(": motion via cam0, " in x and "boards north, south, west" in x
               for x in links) >= 2, links
    assert "verdict: ok" in res.stdout


def test_check_accepts_one_chessboard_per_camera_as_calibrate_does(tmp_path):
    # each camera sees only its own wall's chessboard ('cameras:' of each target)
    render_wall_dataset(tmp_path / "ds", WallSpec(n_instants=10, boards="chessboard",
                                                  motion="planar", width=640, height=480),
                        seed=0, processes=2)
    res = _check(tmp_path / "ds")
    assert res.exit_code == 0, (res.stdout, res.stderr)
    assert "verdict: ok" in res.stdout
    for cam in ("cam1", "cam2", "cam3"):
        assert f"{cam} linked by: motion via cam0" in res.stdout, res.stdout
        assert f"problem: {cam}: target found in only" not in res.stdout
