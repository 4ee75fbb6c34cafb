"""Two cameras reading one video (or one bag's topic) with regions that share pixels are
refused before anything is decoded, as two cameras reading one image file are
(:func:`multieye.pipeline.recordings.check_sync`): before, overlapping crops of one
side-by-side video were calibrated as two cameras, and identical ones were caught only after
the whole detection."""

from __future__ import annotations

import pytest

from multieye.core.errors import DatasetError
from multieye.io import load_rig
from multieye.pipeline.recordings import check_sync


def _rig(tmp_path, left: str, right: str):
    (tmp_path / "sbs.mp4").write_bytes(b"\0" * 64)
    (tmp_path / "run.bag").write_bytes(b"\0" * 64)
    (tmp_path / "rig.yaml").write_text(
        "target: {type: chessboard, rows: 6, cols: 4, spacing: 0.03}\ncameras:\n"
        f"  left: {{model: pinhole-radtan4, {left}}}\n"
        f"  right: {{model: pinhole-radtan4, {right}}}\n")
    return load_rig(tmp_path)


@pytest.mark.parametrize("left, right, shown", [
    ("video: sbs.mp4, crop: [0, 0, 680, 480]", "video: sbs.mp4, crop: [640, 0, 640, 480]",
     r"read the same video \(sbs\.mp4\) with regions that share pixels \(crop: \[0, 0, 680, "
     r"480\] and \[640, 0, 640, 480\]\)"),
    ("video: sbs.mp4", "video: sbs.mp4", r"read the same video \(sbs\.mp4\) with regions "
                                         r"that share pixels \(crop: none and none\)"),
    ("rosbag: run.bag, topic: /cam/image, crop: [0, 0, 640, 480]",
     "rosbag: run.bag, topic: /cam/image", r"read the same bag's topic /cam/image"),
])
def test_regions_of_one_stream_that_share_pixels_are_refused(tmp_path, left, right, shown):
    with pytest.raises(DatasetError, match=r"rig\.yaml: cameras left and right " + shown):
        check_sync(_rig(tmp_path, left, right))


@pytest.mark.parametrize("left, right", [
    ("video: sbs.mp4, crop: [0, 0, 640, 480]", "video: sbs.mp4, crop: [640, 0, 640, 480]"),
    ("rosbag: run.bag, topic: /a", "rosbag: run.bag, topic: /b"),
])
def test_regions_side_by_side_or_other_topics_are_two_cameras(tmp_path, left, right):
    check_sync(_rig(tmp_path, left, right))


def _numbered(tmp_path, left: list[str]):
    for cam, names in (("left", left), ("right", [f"{k:04d}_cam1.jpg" for k in range(6)])):
        (tmp_path / cam).mkdir()
        for name in names:
            (tmp_path / cam / name).write_bytes(b"")
    (tmp_path / "rig.yaml").write_text(
        "sync: number\ntarget: {type: chessboard, rows: 6, cols: 4, spacing: 0.03}\n"
        "cameras:\n  left: {model: pinhole-radtan4, images: left/}\n"
        "  right: {model: pinhole-radtan4, images: right/}\n")
    return load_rig(tmp_path)


def test_sync_number_cannot_read_the_frame_of_a_single_image_with_two_numbers(tmp_path):
    """``0005_cam0.jpg`` alone: its last integer (the camera's 0) paired it with the other
    camera's frame 0, a wrong pair calibrated with exit 0 (0.44 off on BoofCV's stereo set)."""
    with pytest.raises(DatasetError, match=r"0005_cam0\.jpg: camera left: sync: number .* "
                                           r"camera left has one image, whose name holds "
                                           r"several numbers \(0005, 0\)"):
        check_sync(_numbered(tmp_path, ["0005_cam0.jpg"]))


@pytest.mark.parametrize("left", [["left05.jpg"], ["0005_cam0.jpg", "0007_cam0.jpg"]])
def test_one_number_or_more_images_tell_the_frame(tmp_path, left):
    assert check_sync(_numbered(tmp_path, left))["left"] == len(left)
