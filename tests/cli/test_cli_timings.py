"""`multieye calibrate` reports where the time went: details.json timings_s and the printed total."""

from __future__ import annotations

import json
import re

import pytest
from click.testing import CliRunner

from multieye.cli import main
from multieye.io.run_details import TIMING_KEYS, read_run_details
from small_dataset import render_small


def test_calibrate_writes_stage_timings_and_prints_the_total(tmp_path):
    render_small(tmp_path / "ds")
    res = CliRunner().invoke(main, ["calibrate", str(tmp_path / "ds"), "-o", str(tmp_path / "out"),
                                    "--processes", "1"])
    assert res.exit_code == 0, res.output
    timings = json.loads((tmp_path / "out" / "details.json").read_text())["timings_s"]
    assert list(timings) == list(TIMING_KEYS) == ["reading", "detection", "pairing",
                                                  "closed_form", "refinement", "outputs", "total"]
    assert all(isinstance(v, float) and v >= 0 for v in timings.values())
    stages = sum(v for k, v in timings.items() if k != "total")
    assert stages <= timings["total"] + 1e-3
    # the stages account for the run, not a fraction of it
    assert stages >= 0.9 * timings["total"]
    # detection of 16 images and writing the report take real time; pairing does work too
    assert timings["detection"] > 0 and timings["outputs"] > 0 and timings["pairing"] > 0
    assert timings["refinement"] > 0
    line = re.search(r"^done in (\d+\.\d) s \(reading \d+\.\d, detection \d+\.\d, pairing "
                     r"\d+\.\d, closed form \d+\.\d, refinement \d+\.\d, outputs \d+\.\d\)$",
                     res.output, re.M)
    assert line, res.output
    assert float(line.group(1)) == pytest.approx(timings["total"], abs=0.051)
    assert read_run_details(tmp_path / "out" / "details.json").timings.total == timings["total"]
