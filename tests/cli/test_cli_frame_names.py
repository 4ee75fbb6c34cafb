"""rig.yaml's ``pose: T_<parent>_<child>`` with the user's own frame names: the names reach the
screen, the report, ``calibration.json``'s ``frames`` and the exports; the numbers do not move."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
from click.testing import CliRunner

from multieye.cli import main
from multieye.outputs.export_readers import read_tf_static
from small_dataset import render_small


def _run(ds, out):
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1"])
    assert res.exit_code in (0, 3), res.output
    return res.output


def test_own_frame_names_reach_every_output_and_change_no_number(tmp_path):
    render_small(tmp_path / "ds")
    plain = _run(tmp_path / "ds", tmp_path / "plain")
    rig = tmp_path / "ds" / "rig.yaml"
    text = rig.read_text()
    assert "pose: T_world_marker" in text
    rig.write_text(text.replace("pose: T_world_marker", "pose: T_mocap_board"))
    named = _run(tmp_path / "ds", tmp_path / "named")

    assert "T_world_cam of every camera:" in plain
    assert "T_mocap_cam (calibration.json: T_world_cam) of every camera:" in named
    assert "T_board_target (calibration.json: T_marker_target): t = (" in named
    a = json.loads((tmp_path / "plain" / "calibration.json").read_text())
    b = json.loads((tmp_path / "named" / "calibration.json").read_text())
    assert a["frames"] == {"world": "world", "marker": "marker"}
    assert b["frames"] == {"world": "mocap", "marker": "board"}
    # the keys keep the names of docs/conventions.md, and the numbers are the same
    for cam in a["cameras"]:
        np.testing.assert_array_equal(a["cameras"][cam]["T_world_cam"],
                                      b["cameras"][cam]["T_world_cam"])
    np.testing.assert_array_equal(a["T_marker_target"], b["T_marker_target"])

    html = (tmp_path / "named" / "report.html").read_text()
    section = html[html.index('<section id="extrinsics">'):]
    assert "<code>T_mocap_cam</code> of every camera" in section
    assert "<code>T_board_target</code>" in section

    res = CliRunner().invoke(main, ["export", str(tmp_path / "named"), "--format", "urdf"])
    assert res.exit_code == 0, res.output
    root = ET.parse(tmp_path / "named" / "export" / "cameras.urdf").getroot()
    assert root.find("link").get("name") == "mocap"
    res = CliRunner().invoke(main, ["export", str(tmp_path / "named"), "--format", "tf-static"])
    assert res.exit_code == 0, res.output
    tf = read_tf_static(tmp_path / "named" / "export" / "static_transforms.sh")
    assert {p for p, _ in tf} == {"mocap"}
    for cam in b["cameras"]:
        np.testing.assert_allclose(tf[("mocap", f"{cam}_optical_frame")],
                                   b["cameras"][cam]["T_world_cam"], atol=1e-12)
    res = CliRunner().invoke(main, ["export", str(tmp_path / "named"), "--format", "opencv"])
    assert res.exit_code == 0, res.output
    yml = (tmp_path / "named" / "export" / "extrinsics.yaml").read_text()
    assert 'base_frame: "mocap"' in yml and "T_mocap_cam:" in yml and "T_board_target:" in yml


def test_frame_names_that_contradict_each_other_are_refused_with_their_line(tmp_path):
    render_small(tmp_path / "ds")
    rig = tmp_path / "ds" / "rig.yaml"
    text = rig.read_text()
    rig.write_text(text.replace("pose: T_world_marker", "pose: T_base_link_board"))
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path / "ds"), "-o",
                                    str(tmp_path / "out")])
    assert res.exit_code == 2
    assert "rig.yaml:" in res.output and "frames: [parent, child]" in res.output
    assert "[base, link_board] or [base_link, board]" in res.output
    assert not (tmp_path / "out").exists()
    rig.write_text(text.replace("pose: T_world_marker",
                                "pose: T_base_link_board\n  frames: [base_link, board]"))
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path / "ds"), "-o",
                                    str(tmp_path / "out"), "--processes", "1"])
    assert res.exit_code in (0, 3), res.output
    assert json.loads((tmp_path / "out" / "calibration.json").read_text())["frames"] == {
        "world": "base_link", "marker": "board"}


def test_inverted_poses_are_named_in_the_users_frame_names(tmp_path):
    """rig.yaml claims the file holds the inverse (the mocap frame in the board): the run
    fails, and the plausibility check says why in the user's names, with the keys that fix
    it."""
    render_small(tmp_path / "ds")
    rig = tmp_path / "ds" / "rig.yaml"
    rig.write_text(rig.read_text().replace("pose: T_world_marker",
                                           "pose: T_board_mocap\n  fixed_frame: mocap"))
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path / "ds"), "-o",
                                    str(tmp_path / "out"), "--processes", "1"])
    assert res.exit_code == 2, res.output          # nothing agrees: the calibration fails
    assert not (tmp_path / "out").exists()
    # the parent of the fix is the fixed frame: no fixed_frame needed for it
    assert "(T_mocap_board, not T_board_mocap: pose: T_mocap_board under mocap)" in res.output
