"""Output folders whose names are too long for the file system are refused before the run
starts (the hostile cases of each writing command: tests/long_out_cases.py, run by
tests/cli/test_cli_hostile_writes.py), and the longest name allowed is used."""

from __future__ import annotations

from click.testing import CliRunner
from long_out_cases import LONG_NAME
from pose_dataset import write_pose_dataset

from multieye.cli import main
from multieye.outputs.folder_names import SIBLING_BYTES


def test_the_output_folder_is_checked_before_the_dataset(tmp_path):
    """Refused before the run starts: with a missing dataset the line names OUT, not it."""
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path / "missing"), "-o",
                                    str(tmp_path / LONG_NAME)])
    assert res.exit_code == 2
    assert res.stderr.strip().splitlines() == [
        f"multieye: error: {tmp_path / LONG_NAME}: the output folder's name is 240 bytes long; "
        "expected at most 222 bytes (NAME_MAX 255 less 33 for the staging and lock names "
        "beside it, <name>.multieye-tmp-<pid>-<hex>)"]
    assert list(tmp_path.iterdir()) == []


def test_the_longest_name_allowed_is_written(tmp_path):
    """Not refused too early: OUT named with the most bytes the check allows is calibrated
    into (its staging and backup names beside it fit in NAME_MAX)."""
    (tmp_path / "ds").mkdir()
    write_pose_dataset(tmp_path / "ds")
    out = tmp_path / ("n" * (255 - SIBLING_BYTES))
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path / "ds"), "-o", str(out),
                                    "--no-report"])
    assert res.exit_code == 0, res.output
    assert (out / "calibration.json").is_file()
