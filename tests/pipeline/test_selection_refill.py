"""Issue 32: images chosen before decoding that prove unusable (here the wrong size) are
chosen again from the rest until the camera has its budget of usable images or none is left,
for a folder and a bag; a recording where half the frames are usable needs few more."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest
from rosbag_writer import camera_into_bag
from click.testing import CliRunner
from small_dataset import render_small

from multieye.cli import main
from multieye.core.errors import DatasetError
from multieye.io import list_images
from multieye.io.run_details import read_run_details
from multieye.pipeline import calibrate

WRONG_SIZE = "wrong resolution (8 x 8, intrinsics say 640 x 480)"
TINY = np.full((8, 8), 128, np.uint8)


def _recording(folder, n_unusable: int, unusable=TINY):
    """The small rendered dataset (2 cameras x 12 images) with ``n_unusable`` images
    ``unusable`` (8 x 8: the wrong size) in cam0 at motion-capture stamps away from its
    rendered images (paired, so choosable)."""
    render_small(folder, images_per_camera=12)
    mocap = np.loadtxt(folder / "mocap.txt", usecols=0)
    images = np.array([t for t, _, _ in list_images(folder / "cam0")])
    free = mocap[np.min(np.abs(mocap[:, None] - images[None]), axis=1) > 0.05]
    for t in free[np.linspace(0, len(free) - 1, n_unusable).round().astype(int)]:
        cv2.imwrite(str(folder / "cam0" / f"{t:.6f}.png"), unusable)
    return folder


def _usable(run, name):
    return run.cameras[name].observations


@pytest.fixture(scope="module")
def mostly_unusable(tmp_path_factory):
    return _recording(tmp_path_factory.mktemp("refill") / "d", 150)


def test_a_camera_with_few_usable_images_among_many_unusable_calibrates(mostly_unusable):
    run = calibrate(mostly_unusable, select=8)
    sel = run.cameras["cam0"].selection
    assert len(_usable(run, "cam0")) >= 8          # its budget of usable images was met
    listed = len(list_images(mostly_unusable / "cam0"))
    assert sel.refilled > 0 and sel.unusable > 0 and sel.seen == listed
    rejected = run.cameras["cam0"].rejected
    assert sum(r.reason == WRONG_SIZE for r in rejected) == sel.unusable
    assert sum(r.reason.startswith("not selected") for r in rejected) == listed - sel.kept
    assert sel.kept == 8 + sel.refilled
    assert (f"{sel.unusable} of the images chosen proved unusable, so {sel.refilled} more were "
            "chosen from the rest") in sel.line("cam0")
    assert run.cameras["cam1"].selection.refilled == 0     # every chosen image was usable
    every = calibrate(mostly_unusable, select=None)       # every usable image is decoded
    assert 8 <= len(_usable(run, "cam0")) <= len(every.cameras["cam0"].observations)


def test_the_command_calibrates_and_says_so(mostly_unusable, tmp_path):
    """Exit 2 before (the camera's few usable images were not among those chosen); now exit
    0, the counts on screen and in details.json (read back by the report)."""
    res = CliRunner().invoke(main, ["calibrate", str(mostly_unusable), "-o", str(tmp_path / "o"),
                                    "--select", "8", "--processes", "1"])
    assert res.exit_code == 0, res.output
    sel = json.loads((tmp_path / "o" / "details.json").read_text())["cameras"]["cam0"]["selection"]
    assert sel["refilled"] > 0 and sel["unusable"] > 0 and sel["kept"] == 8 + sel["refilled"]
    assert (f"selected: cam0: {sel['kept']} of {sel['seen']} images selected before decoding "
            f"(budget 8; {sel['unusable']} of the images chosen proved unusable, so "
            f"{sel['refilled']} more were chosen from the rest)\n") in res.output
    # details.json of an earlier version (without the two counts) is read as before
    details = json.loads((tmp_path / "o" / "details.json").read_text())
    for c in details["cameras"].values():
        for key in ("unusable", "refilled"):
            (c.get("selection") or {}).pop(key, None)
    (tmp_path / "old.json").write_text(json.dumps(details))
    assert read_run_details(tmp_path / "old.json").camera("cam0").selection["kept"] == sel["kept"]
    details["cameras"]["cam0"]["selection"]["refilled"] = "many"
    (tmp_path / "bad.json").write_text(json.dumps(details))
    with pytest.raises(DatasetError, match="selection must be an object"):
        read_run_details(tmp_path / "bad.json")


def test_half_usable_needs_a_refill_not_the_whole_recording(tmp_path):
    run = calibrate(_recording(tmp_path / "d", 12), select=8)
    sel = run.cameras["cam0"].selection
    assert len(_usable(run, "cam0")) >= 8 and sel.refilled > 0
    assert sel.kept < sel.seen                      # images left undecoded
    assert sum(r.reason.startswith("not selected") for r in run.cameras["cam0"].rejected) > 0


def test_a_bag_camera_is_refilled_too(tmp_path):
    folder = _recording(tmp_path / "d", 60)
    camera_into_bag(folder, "cam0")
    run = calibrate(folder, select=8)
    sel = run.cameras["cam0"].selection
    assert len(_usable(run, "cam0")) >= 8 and sel.refilled > 0
    assert sum(r.reason == WRONG_SIZE for r in run.cameras["cam0"].rejected) == sel.unusable


def test_a_video_camera_is_refilled_when_its_frames_show_no_target(tmp_path):
    """Frames without the target (a blank view of the right size) in a video's stream."""
    folder = _recording(tmp_path / "d", 40, unusable=np.full((480, 640), 128, np.uint8))
    listed = list_images(folder / "cam0")
    writer = cv2.VideoWriter(str(folder / "cam0.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 30.0,
                             (640, 480), False)
    for _, _, path in listed:
        writer.write(cv2.imread(str(path), cv2.IMREAD_GRAYSCALE))
    writer.release()
    (folder / "cam0_stamps.txt").write_text("".join(f"{p.stem}\n" for _, _, p in listed))
    rig = (folder / "rig.yaml").read_text()
    (folder / "rig.yaml").write_text(rig.replace("    images: cam0/", "    video: cam0.avi\n"
                                                 "    stamps: cam0_stamps.txt"))
    run = calibrate(folder, select=8)
    sel = run.cameras["cam0"].selection
    assert len(_usable(run, "cam0")) >= 8 and sel.refilled > 0
    assert sum(r.reason.startswith("target not detected")
               for r in run.cameras["cam0"].rejected) == sel.unusable > 0


def test_a_camera_whose_lens_is_estimated_is_refilled_and_its_lens_started_from_all(tmp_path):
    """The lens started from the detections of every image tried (the chosen ones and those
    added), not from the first choice the workers started it on."""
    folder = _recording(tmp_path / "d", 6, unusable=np.full((480, 640), 128, np.uint8))
    rig = (folder / "rig.yaml").read_text()
    (folder / "rig.yaml").write_text(rig.replace("    intrinsics: cam0.yaml\n",
                                                 "    model: pinhole-radtan\n", 1))
    run = calibrate(folder, select=4)            # twice the budget for a lens to estimate
    sel = run.cameras["cam0"].selection
    assert run.cameras["cam0"].intrinsics_estimated
    assert sel.stage == "before decoding and after detection" and sel.kept == 4
    assert len(_usable(run, "cam0")) >= 8 and sel.refilled > 0
    assert sum(r.reason.startswith("target not detected") for r in run.cameras["cam0"].rejected
               ) == sel.unusable > 0


def test_images_of_another_size_leave_a_camera_whose_lens_is_estimated_calibrated(tmp_path):
    """No intrinsics give the size of a camera whose lens is estimated: its 8 x 8 frames
    among the 640 x 480 ones refused the whole camera ('images of different sizes'), with
    the selection and without; now they are left out as of the wrong resolution, as given
    intrinsics leave them out, and the selection, its budget holding every usable image,
    gives --no-select's result."""
    folder = _recording(tmp_path / "d", 40)
    rig = (folder / "rig.yaml").read_text()
    (folder / "rig.yaml").write_text(rig.replace("    intrinsics: cam0.yaml\n",
                                                 "    model: pinhole-radtan\n", 1))
    runs = [calibrate(folder, select=s) for s in (20, None)]
    for run in runs:
        cam = run.cameras["cam0"]
        assert cam.intrinsics_estimated and len(cam.observations) >= 10
        assert sum(r.reason == "wrong resolution (8 x 8, the images showing the target are "
                   "640 x 480)" for r in cam.rejected) == 40
    assert runs[0].cameras["cam0"].selection.refilled > 0
    np.testing.assert_allclose(runs[0].T_ref_cam["cam1"], runs[1].T_ref_cam["cam1"], atol=1e-6)
    np.testing.assert_allclose(runs[0].intrinsics["cam0"].params, runs[1].intrinsics["cam0"].params,
                               rtol=1e-6)


def test_a_listing_error_of_the_selection_names_the_camera(mostly_unusable, tmp_path):
    """The images listed for the choice before decoding refused a name that is not a time
    stamp without naming the camera, which the same error names without the selection."""
    folder = tmp_path / "d"
    shutil.copytree(mostly_unusable, folder)
    cv2.imwrite(str(folder / "cam0" / "IMG_0001.png"), TINY)
    for select in (8, None):
        with pytest.raises(DatasetError, match="IMG_0001.png: camera cam0: image name is not a "
                                               "time stamp") as info:
            calibrate(folder, select=select)
        assert info.value.camera == "cam0"


def test_the_line_says_when_every_image_left_fewer_usable_than_the_budget():
    from multieye.pipeline.selection import SelectionSummary

    short = SelectionSummary(budget=8, seen=154, kept=154, stage="before decoding",
                             unusable=150, refilled=146)
    assert short.line("cam0") == (
        "cam0: 154 of 154 images selected before decoding (budget 8; 150 of the images chosen "
        "proved unusable, so 146 more were chosen from the rest; 4 usable in all, fewer than "
        "the budget)")
    met = SelectionSummary(budget=8, seen=161, kept=113, stage="before decoding",
                           unusable=105, refilled=105)
    assert met.line("cam0").endswith("so 105 more were chosen from the rest)")
    none_left = SelectionSummary(budget=8, seen=9, kept=9, stage="before decoding", unusable=3)
    assert none_left.line("cam0").endswith(
        "3 of the images chosen proved unusable, none left to add; 6 usable in all, fewer than "
        "the budget)")
