"""multieye check: the dry run on the command line, a labelled table and the exit status."""

from __future__ import annotations

import shutil

from click.testing import CliRunner

from multieye.cli import main
from rosbag_writer import camera_into_bag
from small_dataset import render_small


def _check(*args):
    return CliRunner().invoke(main, ["check", *(str(a) for a in args)])


def test_check_ok_prints_labelled_table_and_exits_0(tmp_path):
    render_small(tmp_path / "ds")
    res = _check(tmp_path / "ds", "--processes", "1", "--sample", "5")
    assert res.exit_code == 0, (res.stdout, res.stderr)
    assert res.stderr == ""
    lines = res.stdout.splitlines()
    header = next(line for line in lines if line.startswith("camera "))
    for label in ("images", "sampled", "target found", "found %", "with mocap",
                  "rotation range deg", "RMS rot axes deg"):
        assert label in header
    row = next(line for line in lines if line.startswith("cam0 ")).split()
    assert row[1:7] == ["images", "8", "5", "5", "100", "8"]
    assert lines[-1] == "verdict: ok, calibrating can run"


def test_check_exits_2_with_one_line_per_reason(tmp_path):
    render_small(tmp_path / "ds")
    mocap = tmp_path / "ds" / "mocap.txt"
    mocap.write_text("\n".join(mocap.read_text().splitlines()[:40]) + "\n")
    res = _check(tmp_path / "ds", "--processes", "1")
    assert res.exit_code == 2, res.stdout
    assert "images have no motion capture within 0.0167 s" in res.stdout
    err = res.stderr.strip().splitlines()
    assert len(err) == 2 and all(
        line.startswith(f"multieye: calibrating would fail: cam{j}: fewer than 3 usable")
        for j, line in enumerate(err))


def test_check_wrong_target_and_bad_input(tmp_path):
    render_small(tmp_path / "ds")
    rig = tmp_path / "ds" / "rig.yaml"
    rig.write_text(rig.read_text().replace("rows: 6", "rows: 7"))
    res = _check(tmp_path / "ds", "--processes", "1")
    assert res.exit_code == 2
    assert "problem: cam0: target found in only 0 of 8 sampled images" in res.stdout
    shutil.rmtree(tmp_path / "ds" / "cam1")
    res = _check(tmp_path / "ds")
    assert res.exit_code == 2 and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert res.stderr.startswith("multieye: error:")
    res = _check(tmp_path / "ds", "--sample", "0")
    assert res.exit_code == 2


def test_check_samples_a_bag_camera_and_names_a_topic_without_target(tmp_path):
    render_small(tmp_path / "ds")
    camera_into_bag(tmp_path / "ds", "cam1")
    res = _check(tmp_path / "ds", "--processes", "1", "--sample", "5")
    assert res.exit_code == 0, (res.stdout, res.stderr)
    row = next(line for line in res.stdout.splitlines() if line.startswith("cam1 ")).split()
    assert row[1:9] == ["rosbag", "8", "5", "5", "100", "8", "5", "8"]
    assert "problem:" not in res.stdout
    render_small(tmp_path / "blank")
    camera_into_bag(tmp_path / "blank", "cam1", image=lambda img: img * 0 + 128)
    res = _check(tmp_path / "blank", "--processes", "1")
    assert res.exit_code == 2, res.stdout
    assert "cam1: sampled images without a target pose: 8 target not detected" in res.stdout
    assert "problem: cam1: target found in only 0 of 8 sampled images" in res.stdout
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        "multieye: calibrating would fail: cam1: fewer than 3 usable images would remain")
