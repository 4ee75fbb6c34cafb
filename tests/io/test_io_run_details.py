"""details.json: the optional timings_s, validated on read; files without it still read."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.io.run_details import (
    TIMING_KEYS,
    CameraDetails,
    RunDetails,
    StageTimings,
    TrajectoryDetails,
    read_run_details,
    run_details_to_dict,
    write_details,
)


def _details(timings=None) -> RunDetails:
    n = 3
    cam = CameraDetails("cam0", np.eye(4), None, 0, ("a.png", "b.png", "c.png"),
                        np.arange(n, dtype=float), np.zeros(n), np.zeros(n), np.full(n, np.nan),
                        np.tile(np.eye(4), (n, 1, 1)))
    traj = TrajectoryDetails("T_world_marker", np.arange(4.0), np.zeros((4, 3)), 4)
    return RunDetails("eye-to-base", "cam0", (cam,), (traj,), timings=timings)


def test_timings_round_trip(tmp_path):
    timings = StageTimings(reading=0.1, detection=4.2, pairing=0.05, closed_form=0.001,
                           refinement=1.2, outputs=1.5, total=7.3)
    write_details(tmp_path / "details.json", _details(timings))
    data = json.loads((tmp_path / "details.json").read_text())
    assert data["timings_s"] == {"reading": 0.1, "detection": 4.2, "pairing": 0.05,
                                 "closed_form": 0.001, "refinement": 1.2, "outputs": 1.5,
                                 "total": 7.3}
    assert read_run_details(tmp_path / "details.json").timings == timings


def test_details_without_timings_from_older_versions_still_read(tmp_path):
    data = run_details_to_dict(_details())
    assert "timings_s" not in data
    (tmp_path / "details.json").write_text(json.dumps(data))
    assert read_run_details(tmp_path / "details.json").timings is None


@pytest.mark.parametrize("mutate, message", [
    (lambda t: t.pop("outputs"), r"missing key 'outputs' in timings_s"),
    (lambda t: t.update(detection=-1.0), r"timings_s\.detection must be a non-negative number"),
    (lambda t: t.update(total="7 s"), r"timings_s\.total must be a non-negative number of "
                                      r"seconds, got '7 s'"),
    (lambda t: t.update(pairing=None), r"timings_s\.pairing must be"),
    (lambda t: t.update(reading=True), r"timings_s\.reading must be"),
])
def test_bad_timings_are_refused_with_the_key(tmp_path, mutate, message):
    data = run_details_to_dict(_details(StageTimings(total=1.0)))
    assert list(data["timings_s"]) == list(TIMING_KEYS)
    mutate(data["timings_s"])
    (tmp_path / "details.json").write_text(json.dumps(data))
    with pytest.raises(DatasetError, match=r"details\.json: " + message):
        read_run_details(tmp_path / "details.json")
    data["timings_s"] = [1, 2]
    (tmp_path / "details.json").write_text(json.dumps(data))
    with pytest.raises(DatasetError, match="timings_s must be an object"):
        read_run_details(tmp_path / "details.json")


def test_warnings_round_trip_and_older_files_read_with_none(tmp_path):
    notes = ("cam1: 2 images read from outside the dataset folder /data: /x/a.png, /x/b.png",
             "weak motion: rotation spread 3 deg")
    write_details(tmp_path / "details.json", replace(_details(), warnings=notes))
    data = json.loads((tmp_path / "details.json").read_text())
    assert data["warnings"] == list(notes)
    assert read_run_details(tmp_path / "details.json").warnings == notes
    data.pop("warnings")
    (tmp_path / "details.json").write_text(json.dumps(data))
    assert read_run_details(tmp_path / "details.json").warnings == ()


@pytest.mark.parametrize("bad", ["one string", [1, 2], {"a": "b"}, ["ok", None]])
def test_bad_warnings_are_refused(tmp_path, bad):
    data = run_details_to_dict(_details())
    data["warnings"] = bad
    (tmp_path / "details.json").write_text(json.dumps(data))
    with pytest.raises(DatasetError, match=r"details\.json: warnings must be a list of strings"):
        read_run_details(tmp_path / "details.json")
