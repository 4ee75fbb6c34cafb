"""The image selection in the pipeline: images chosen before decoding (those without motion
capture never decoded), the reasons in calibration.json, the summary in details.json and on
screen, after detection when the clock is estimated, and off with --no-select."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from small_dataset import render_small

from multieye.cli import main
from multieye.core.errors import InputError
from multieye.pipeline import Options, calibrate


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """2 cameras x 12 rendered images, and in cam0 three files stamped far from any motion
    capture holding no image at all: decoding them would reject them as unreadable."""
    folder = tmp_path_factory.mktemp("sel") / "d"
    render_small(folder, images_per_camera=12)
    last = max(float(p.stem) for p in (folder / "cam0").glob("*.png"))
    for k in range(3):
        (folder / "cam0" / f"{last + 500 + k:.6f}.png").write_bytes(b"not an image")
    return folder


def test_before_decoding(dataset):
    run = calibrate(dataset, select=6)
    for name in ("cam0", "cam1"):
        data = run.cameras[name]
        sel = data.selection
        assert sel is not None and sel.stage == "before decoding" and sel.budget == 6
        assert sel.kept == 6 and sel.seen == data.n_inputs
        assert len(data.observations) <= 6           # only the chosen images were detected
        left = [r for r in data.rejected if r.reason.startswith("not selected")]
        assert len(left) == sel.seen - 6 - sel.without_mocap
    cam0 = run.cameras["cam0"]
    assert cam0.selection.without_mocap == 3
    never = [r for r in cam0.rejected if "not decoded" in r.reason]
    assert len(never) == 3 and all("no motion capture within" in r.reason for r in never)
    assert not any("unreadable" in r.reason for r in cam0.rejected)


def test_off_detects_every_image(dataset):
    run = calibrate(dataset, select=None)
    assert run.cameras["cam0"].selection is None
    assert sum(r.reason.startswith("unreadable") for r in run.cameras["cam0"].rejected) == 3
    assert len(run.cameras["cam1"].observations) > 6


def test_after_detection_with_the_clock_estimated(dataset):
    """time_offset auto needs the continuous stream: every image is detected, and the
    paired images are chosen among afterwards."""
    run = calibrate(dataset, select=5, time_offset=0.0)     # a number: before decoding
    assert run.cameras["cam1"].selection.stage == "before decoding"
    from multieye.io import load_rig
    from multieye.pipeline import calibrate_rig, load_camera_data

    rig = load_rig(dataset / "rig.yaml")
    cams = load_camera_data(rig, processes=1, select=5, time_offset="auto")
    assert all(c.selection is None for c in cams.values())
    run = calibrate_rig(rig, cams, Options(select=5))
    for name in ("cam0", "cam1"):
        sel = run.cameras[name].selection
        assert sel.stage == "after detection" and sel.kept == 5
        assert len(run.paired[name].observations) <= 5
        assert sum(r.reason.startswith("not selected") for r in run.paired[name].rejected) == \
            sel.seen - 5


def test_written_and_shown(dataset, tmp_path):
    res = CliRunner().invoke(main, ["calibrate", str(dataset), "-o", str(tmp_path / "out"),
                                    "--select", "6", "--processes", "1"])
    assert res.exit_code in (0, 3), res.output
    n0 = len(list((dataset / "cam0").glob("*.png")))
    n1 = len(list((dataset / "cam1").glob("*.png")))
    assert (f"selected: cam0: 6 of {n0} images selected before decoding (budget 6; 3 without "
            "motion capture not decoded)") in res.output
    details = json.loads((tmp_path / "out" / "details.json").read_text())
    assert details["cameras"]["cam0"]["selection"] == {
        "budget": 6, "seen": n0, "kept": 6, "stage": "before decoding", "without_mocap": 3,
        "unusable": 0, "refilled": 0}
    cal = json.loads((tmp_path / "out" / "calibration.json").read_text())
    reasons = [r["reason"] for r in cal["cameras"]["cam1"]["rejected"]]
    assert sum(r.startswith("not selected: adds little") for r in reasons) == n1 - 6
    html = (tmp_path / "out" / "report.html").read_text()
    assert "<h3>Image selection</h3>" in html and "before decoding" in html
    from multieye.io.run_details import read_run_details

    assert read_run_details(tmp_path / "out" / "details.json").camera("cam0").selection["kept"] == 6


def test_no_select_flag_and_bad_budget(dataset, tmp_path):
    res = CliRunner().invoke(main, ["calibrate", str(dataset), "-o", str(tmp_path / "o2"),
                                    "--no-select", "--processes", "1"])
    assert res.exit_code in (0, 3) and "selected:" not in res.output
    assert "Image selection" not in (tmp_path / "o2" / "report.html").read_text()
    with pytest.raises(InputError, match="select must be a whole number"):
        Options(select=2)
    with pytest.raises(InputError, match="select must be a whole number"):
        Options(select=np.float64(10.0))


def test_a_camera_without_motion_capture_fails_as_without_selection(dataset):
    """Every image out of the motion capture's reach (a wrong clock offset): the selection
    leaves the camera alone and the pairing names the cause, as without it."""
    from multieye.core.errors import TooFewMeasurementsError

    with pytest.raises(TooFewMeasurementsError, match="without motion capture") as chosen:
        calibrate(dataset, select=6, time_offset=300.0)
    with pytest.raises(TooFewMeasurementsError, match="without motion capture") as every:
        calibrate(dataset, select=None, time_offset=300.0)
    assert str(chosen.value) == str(every.value)


def test_the_motion_capture_comes_first_only_where_the_detection_needs_it(tmp_path):
    """``motion_first``: a camera paired by name, or images the budget may choose among
    (more in a folder than the budget, twice it for a lens to estimate; any bag or video)."""
    from types import SimpleNamespace

    from multieye.core.errors import DatasetError
    from multieye.pipeline.selection import motion_first

    folder = tmp_path / "cam0"
    folder.mkdir()
    for k in range(6):
        (folder / f"{1700000000 + k}.png").write_bytes(b"")
    (folder / "notes.txt").write_text("")       # an entry, not an image

    def rig(source="images", by_name=False, lens=False, mocap=True):
        cam = SimpleNamespace(source=source, images=folder, images_pattern=None, estimate_intrinsics=lens,
                              stamps=None)
        return SimpleNamespace(has_mocap=mocap, cameras={"cam0": cam}, sync="time",
                               mocap_for=lambda name: SimpleNamespace(by_name=by_name))

    assert motion_first(rig(), 5, "rig")                      # 6 images, budget 5
    assert not motion_first(rig(), 6, 0.0)                    # 7 entries, 6 images: not over
    assert not motion_first(rig(lens=True), 5, "rig")         # a lens: budget 10
    assert not motion_first(rig(), None, "rig") and not motion_first(rig(), 5, "auto")
    assert motion_first(rig(source="rosbag"), 500, "rig")
    assert motion_first(rig(by_name=True), None, "rig")
    assert not motion_first(rig(by_name=True, mocap=False), 5, "rig")
    (folder / "x.png").write_bytes(b"")                       # not a stamp: the listing's error
    with pytest.raises(DatasetError, match="camera cam0: image name is not a time stamp"):
        motion_first(rig(), 5, "rig")
