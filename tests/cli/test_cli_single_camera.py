"""Single-camera hand-eye, the most common real case: the screen shows the transform people
came for (X) and the shared Y, each with its uncertainty; no relative-to-reference table."""

from __future__ import annotations

import json
import re

import numpy as np
from click.testing import CliRunner

from multieye.cli import main
from small_dataset import render_small


def test_one_camera_shows_its_answer_and_its_uncertainty(tmp_path):
    render_small(tmp_path / "ds")
    text = (tmp_path / "ds" / "rig.yaml").read_text()
    (tmp_path / "ds" / "rig.yaml").write_text(text[:text.index("  cam1:")])
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path / "ds"), "-o",
                                    str(tmp_path / "out"), "--processes", "1"])
    assert res.exit_code in (0, 3), res.output
    out = res.output
    assert "T_world_cam of every camera:" in out
    row = next(line for line in out.splitlines() if line.startswith("cam0 "))
    cells = row.split()
    assert "(ref)" not in row
    std_deg, std_mm = float(cells[12]), float(cells[13])
    assert 0 < std_deg < 1 and 0 < std_mm < 10
    assert re.search(r"T_marker_target: t = \(.*\) m, yaw pitch roll = \(.*\) deg, std "
                     r"[0-9.]+ deg / [0-9.]+ mm", out)
    assert "T_ref_cam, relative to" not in out
    data = json.loads((tmp_path / "out" / "calibration.json").read_text())
    cam = data["cameras"]["cam0"]
    assert np.isclose(cam["uncertainty"]["T_world_cam"]["std_rot_deg"], std_deg, atol=1e-3)
    # the reference camera's T_ref_cam is the identity, with zero uncertainty
    assert cam["uncertainty"]["T_ref_cam"]["std_rot_deg"] == 0.0
    assert data["uncertainty"]["T_marker_target"]["std_trans_m"] > 0
    # the report says the same: X and Y with their sigma, no relative table
    html = (tmp_path / "out" / "report.html").read_text()
    section = html[html.index('<section id="extrinsics">'):]
    section = section[:section.index("</section>")]
    assert "<code>T_world_cam</code> of every camera" in section
    assert "<code>T_marker_target</code>" in section and "σ" in section
    assert f"{std_deg:.3f}" in section
    assert "relative to" not in section

