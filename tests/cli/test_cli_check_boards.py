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
        # driven on the floor, each camera seeing only its own board: calibrating doubts its
        # height (exit status 3); check says so beforehand
        assert (f"problem: {cam}: the sampled views show the rig turned about one axis only"
                in res.stdout and "not only about y of the rig" in res.stdout), res.stdout


def test_one_axis_problems_name_only_cameras_apart_from_the_references_boards():
    """A rig turned about its y axis only: cameras whose boards no joined camera sees are
    named, one sharing a board with the reference is not; turned about two axes, none."""
    import numpy as np  # noqa: PLC0415 (this test only)
    from multieye.core.geometry import transform_from_rotvec  # noqa: PLC0415 (this test only)
    from multieye.pipeline.dry_run_boards import one_axis_problems  # noqa: PLC0415 (this test only)
    views = [(0, 0, "a"), (1, 0, "a"), (0, 1, "b"), (2, 1, "c"), (3, 2, "d"), (2, 3, "d")]
    yaw = [transform_from_rotvec([0, a, 0], [0.1 * a, 0, 2]) for a in np.linspace(-0.4, 0.4, 6)]
    poses = [(k, "a", T) for k, T in enumerate(yaw)]
    named = one_axis_problems(["c0", "c1", "c2", "c3"], views, poses)
    assert sorted(named) == ["c2", "c3"] and "about y of the rig" in named["c2"][0]
    # a board whose pose rig.yaml gives is held in the world: the cameras seeing it are placed
    assert sorted(one_axis_problems(["c0", "c1", "c2", "c3"], views, poses, frozenset({"d"}))) == []
    tilted = [(k, "a", transform_from_rotvec([0.2 * (-1) ** k, a, 0.1 * a], [0, 0, 2]))
              for k, a in enumerate(np.linspace(-0.4, 0.4, 6))]
    assert one_axis_problems(["c0", "c1", "c2", "c3"], views, tilted) == {}
