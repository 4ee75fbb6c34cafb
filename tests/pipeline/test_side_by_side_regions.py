"""A camera's ``crop:`` is applied in one place (multieye.imaging.image_file: ``read_region``
for files, ``cropped_frames`` for a video's or a bag's frames), on every path that reads its
images: detection of files, of a bag's frames, the dry run's sampling on, and the dry run's
target hint, which read the whole side-by-side file (the other camera's half included)."""

from __future__ import annotations

import shutil

import cv2
import numpy as np

from multieye.imaging.batch import detect_and_estimate, detect_and_estimate_arrays
from multieye.imaging.targets import target_from_spec
from multieye.io import list_images
from multieye.pipeline.dry_run import check_dataset
from rosbag_writer import camera_into_bag
from small_dataset import render_small

W, H = 640, 480


def _side_by_side(folder, camera: str, *, left_blank: bool):
    """``camera``'s images made side-by-side frames, [its image | blank] or [blank | its
    image], and rig.yaml's ``crop:`` set to the left half."""
    for _, _, path in list_images(folder / camera):
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        blank = np.full_like(img, 128)
        cv2.imwrite(str(path), np.concatenate([blank, img] if left_blank else [img, blank], 1))
    rig = folder / "rig.yaml"
    rig.write_text(rig.read_text().replace(f"    images: {camera}/",
                                           f"    images: {camera}/\n    crop: [0, 0, {W}, {H}]"))


def test_the_target_hint_looks_only_at_the_cameras_half(tmp_path):
    """cam0's half of its frames is blank, the board is in the other half: the dry run says
    the target is in none of its images and suggests nothing (it suggested, from the
    other half, a board that cam0 does not see)."""
    folder = tmp_path / "ds"
    render_small(folder)
    _side_by_side(folder, "cam0", left_blank=True)
    c = check_dataset(folder, processes=1).cameras[0]
    assert c.found == 0
    line = next(p for p in c.problems if p.startswith("target found in only 0 of 8"))
    assert line.endswith("and the images"), line       # no hint: the half holds no board
    # the hint still sees what the half holds: the board there, rows and cols misstated
    shutil.rmtree(folder)
    render_small(folder)
    _side_by_side(folder, "cam0", left_blank=False)
    rig = folder / "rig.yaml"
    rig.write_text(rig.read_text().replace("  cols: 9", "  cols: 10"))
    c = check_dataset(folder, processes=1).cameras[0]
    line = next(p for p in c.problems if p.startswith("target found in only 0 of 8"))
    assert "cols: 9" in line, line


def test_a_side_by_side_bag_is_cut_once(tmp_path):
    """A bag's side-by-side frames: the dry run and calibrate's detection cut each frame to
    the camera's half once (a frame cut twice would be a quarter: every frame refused)."""
    folder = tmp_path / "ds"
    render_small(folder)
    _side_by_side(folder, "cam1", left_blank=False)
    camera_into_bag(folder, "cam1")
    result = check_dataset(folder, processes=1)
    assert result.ok, result.reasons
    assert (result.cameras[1].source, result.cameras[1].found) == ("rosbag", 8)


def test_files_and_frames_give_the_same_detections(tmp_path):
    """The same side-by-side pixels as files and as frames in memory: the same results."""
    folder = tmp_path / "ds"
    render_small(folder, images_per_camera=3)
    _side_by_side(folder, "cam0", left_blank=False)
    paths = [p for _, _, p in list_images(folder / "cam0")]
    target = target_from_spec({"type": "chessboard", "rows": 6, "cols": 9, "spacing": 0.05})
    files = detect_and_estimate(paths, target, None, processes=1, crop=(0, 0, W, H))
    frames = detect_and_estimate_arrays(
        ((str(p), cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)) for p in paths), target, None,
        processes=1, crop=(0, 0, W, H))
    assert [r.image_size for r in files] == [r.image_size for r in frames] == [(W, H)] * 3
    for a, b in zip(files, frames):
        np.testing.assert_array_equal(a.detection.image_points, b.detection.image_points)
