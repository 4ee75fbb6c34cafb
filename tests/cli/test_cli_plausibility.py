"""Exit statuses of `multieye calibrate` (docs/conventions.md, section 8): 0 when no
plausibility check doubts the result, 3 when one does (the result written all the same, the
cause on stderr and in calibration.json), 2 when nothing can be written, with the likely
cause named instead of only the consensus that failed."""

from __future__ import annotations

import json
import re
import shutil

import numpy as np

import pytest
from click.testing import CliRunner
from pose_dataset import write_pose_dataset
from small_dataset import render_small

from multieye.cli import EXIT_IMPLAUSIBLE, main
from multieye.core import geometry as g
from multieye.io import Trajectory, read_tum, write_tum


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rendered") / "ds"
    render_small(folder, images_per_camera=12)
    return folder


def _copy(src, dst):
    shutil.copytree(src, dst)
    return dst


def _calibrate(ds, out, *extra):
    return CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1",
                                     *extra])


def _doubted(res, out, cause, *words):
    """Exit 3, the result written, the doubt on stderr, in the table and in the file."""
    assert res.exit_code == EXIT_IMPLAUSIBLE == 3, (res.exit_code, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert lines and all(line.startswith("multieye: written, but implausible: ")
                         for line in lines), res.stderr
    for word in words:
        assert word in lines[0], lines[0]
    data = json.loads((out / "calibration.json").read_text())
    assert [d["cause"] for d in data["plausibility"]] == [cause] * len(lines)
    assert all(d["message"] in data["warnings"] for d in data["plausibility"])
    assert f"warning: {data['plausibility'][0]['message']}" in res.stdout
    return data


def _refused(res, out, *words):
    """Exit 2, one line naming the cause, nothing written."""
    assert res.exit_code == 2, (res.exit_code, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    for word in words:
        assert word in lines[0], lines[0]
    assert not (out / "calibration.json").exists()
    return lines[0]


def test_good_rendered_dataset_exits_0_without_doubts(rendered, tmp_path):
    res = _calibrate(rendered, tmp_path / "out")
    assert res.exit_code == 0, res.stderr
    assert res.stderr == ""
    assert json.loads((tmp_path / "out" / "calibration.json").read_text())["plausibility"] == []


def test_target_spacing_off_is_written_and_exits_3(rendered, tmp_path):
    ds = _copy(rendered, tmp_path / "ds")
    rig = ds / "rig.yaml"
    rig.write_text(rig.read_text().replace("spacing: 0.05", "spacing: 0.04"))
    _doubted(_calibrate(ds, tmp_path / "out"), tmp_path / "out", "scale", "scale:", "spacing",
             "x1.25", "0.05 fits")


def test_motion_capture_in_millimetres_exits_2_naming_the_unit(rendered, tmp_path):
    ds = _copy(rendered, tmp_path / "ds")
    write_tum(ds / "mocap.txt", read_tum(ds / "mocap.txt"), unit="mm")   # rig.yaml says m
    line = _refused(_calibrate(ds, tmp_path / "out"), tmp_path / "out", "unit", "unit: mm")
    assert re.search(r"only \d+ of \d+ measurements agree", line)    # what failed, after why


def test_quaternions_written_w_first_exit_2_naming_the_order(tmp_path):
    ds, _, _ = write_pose_dataset(tmp_path)
    rows = []
    for line in (ds / "mocap.txt").read_text().splitlines():
        v = line.split()
        rows.append(line if line.startswith("#") else " ".join(v[:4] + [v[7]] + v[4:7]))
    (ds / "mocap.txt").write_text("\n".join(rows) + "\n")
    _refused(_calibrate(ds, tmp_path / "out"), tmp_path / "out", "quaternion order")
    # without the consensus the result is written and doubted
    _doubted(_calibrate(ds, tmp_path / "out", "--no-robust"), tmp_path / "out",
             "quaternion-order", "quaternion order")


def test_inverted_target_poses_of_one_camera(tmp_path):
    ds, _, _ = write_pose_dataset(tmp_path)
    poses = read_tum(ds / "cam1.txt", parent="cam", child="target")
    write_tum(ds / "cam1.txt", Trajectory(poses.stamps, g.inv(poses.T), "cam", "target"))
    _doubted(_calibrate(ds, tmp_path / "out", "--no-robust"), tmp_path / "out",
             "inverted-poses", "inverted poses", "cam1", "T_target_cam",
             "poses: {file: ..., pose: T_target_cam}")
    # what the doubt says to do: rig.yaml states the file's direction, and the run is clean
    # with the result of the file written the right way round
    (tmp_path / "good").mkdir()
    good, _, _ = write_pose_dataset(tmp_path / "good")
    rig = (ds / "rig.yaml").read_text()
    (ds / "rig.yaml").write_text(rig.replace(
        "poses: cam1.txt}", "poses: {file: cam1.txt, pose: T_target_cam}}"))
    res, ref = _calibrate(ds, tmp_path / "said"), _calibrate(good, tmp_path / "ref")
    assert res.exit_code == 0 == ref.exit_code, res.stderr
    got, want = (json.loads((d / "calibration.json").read_text())["cameras"]["cam1"]["T_ref_cam"]
                 for d in (tmp_path / "said", tmp_path / "ref"))
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_good_pose_dataset_exits_0(tmp_path):
    ds, _, _ = write_pose_dataset(tmp_path)
    res = _calibrate(ds, tmp_path / "out")
    assert res.exit_code == 0 and res.stderr == "", res.stderr
