"""A camera given as a video file (rig.yaml ``video:``): frames read one at a time, stamps
from a stamps file or the frame rate, the selection choosing frames before any is decoded,
and what rig.yaml refuses."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from small_dataset import render_small

from multieye.core import geometry as g
from multieye.core.errors import DatasetError
from multieye.imaging.video import iter_video_frames, video_stamps
from multieye.io import load_rig
from multieye.io.frame_stamps import read_frame_stamps
from multieye.pipeline import calibrate


def _write_video(path: Path, images, fps: float = 30.0) -> None:
    h, w = images[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h), False)
    assert writer.isOpened()
    for img in images:
        writer.write(img)
    writer.release()


@pytest.fixture(scope="module")
def video_dataset(tmp_path_factory):
    """The small rendered rig with cam1's images turned into an MJPG video and a stamps file
    (the image names), rig.yaml pointing at them."""
    folder = tmp_path_factory.mktemp("video") / "d"
    truth = render_small(folder, images_per_camera=12)
    files = sorted((folder / "cam1").glob("*.png"), key=lambda p: float(p.stem))
    _write_video(folder / "cam1.avi", [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE) for p in files])
    (folder / "cam1_stamps.txt").write_text("# frame stamps\n" + "".join(f"{p.stem}\n" for p in files))
    rig = (folder / "rig.yaml").read_text().replace(
        "    images: cam1/", "    video: cam1.avi\n    stamps: cam1_stamps.txt")
    (folder / "rig.yaml").write_text(rig)
    for p in files:
        p.unlink()
    return folder, truth, len(files)


def test_calibrates_from_the_video(video_dataset):
    folder, truth, n = video_dataset
    run = calibrate(folder, select=None)
    cam1 = run.cameras["cam1"]
    assert cam1.n_inputs == n and len(cam1.observations) >= n - 2
    assert all(o.name.startswith("cam1.avi#") for o in cam1.observations)
    D = g.inv(truth.T_ref_cam[1]) @ run.T_ref_cam["cam1"]
    assert np.degrees(np.linalg.norm(g.rotvec_from_transform(D))) < 0.3
    assert np.linalg.norm(D[:3, 3]) < 0.01


def test_selection_chooses_frames_before_decoding(video_dataset):
    folder, _, n = video_dataset
    run = calibrate(folder, select=5)
    cam1 = run.cameras["cam1"]
    assert cam1.selection.kept == 5 and cam1.selection.seen == n
    assert len(cam1.observations) <= 5
    assert sum(r.reason.startswith("not selected") for r in cam1.rejected) == n - 5


def test_frames_are_read_one_at_a_time_and_stop_after_the_last_kept(tmp_path):
    images = [np.full((48, 64), 10 * k, np.uint8) for k in range(20)]
    _write_video(tmp_path / "v.avi", images, fps=25.0)
    got = list(iter_video_frames(tmp_path / "v.avi", keep={3, 7}))
    assert [k for k, _ in got] == [3, 7]
    assert abs(float(got[1][1].mean()) - 70) < 3
    np.testing.assert_allclose(video_stamps(tmp_path / "v.avi", start_s=100.0),
                               100.0 + np.arange(20) / 25.0)
    with pytest.raises(DatasetError, match="3 stamps for the video's 20 frames"):
        video_stamps(tmp_path / "v.avi", stamps_ns=np.arange(3))
    (tmp_path / "junk.avi").write_bytes(b"not a video at all")
    with pytest.raises(DatasetError, match="cannot open the video file"):
        video_stamps(tmp_path / "junk.avi")


def test_stamps_file_errors_name_the_line(tmp_path):
    p = tmp_path / "s.txt"
    p.write_text("1700000000.1\n1700000000.0\n")
    with pytest.raises(DatasetError, match="must increase") as e:
        read_frame_stamps(p)
    assert ":2" in str(e.value) or "line 2" in str(e.value)
    p.write_text("1700000000.1\nabc\n")
    with pytest.raises(DatasetError, match="one time stamp per line"):
        read_frame_stamps(p)


@pytest.mark.parametrize("extra, message", [
    ("    images: cam1/\n    start_time: 3\n", "'start_time' goes with 'video'"),
    ("    poses: s.txt\n    stamps: s.txt\n", "'stamps' goes with 'video' or 'images'"),
    ("    video: v.avi\n    stamps: s.txt\n    start_time: 3\n", "either 'stamps'"),
    ("    video: v.avi\n    start_time: -1\n", ">= 0 seconds"),
])
def test_rig_yaml_refuses(tmp_path, extra, message):
    (tmp_path / "cam1").mkdir()
    for name in ("v.avi", "s.txt", "mocap.txt", "c.yaml"):
        (tmp_path / name).write_text("x")
    (tmp_path / "rig.yaml").write_text(
        "setup: eye-to-base\ntarget: {type: chessboard, rows: 6, cols: 9, spacing: 0.05}\n"
        "mocap: {file: mocap.txt}\ncameras:\n  cam1:\n    intrinsics: c.yaml\n" + extra)
    with pytest.raises(DatasetError, match=message):
        load_rig(tmp_path / "rig.yaml")


def test_check_samples_the_video(video_dataset):
    from multieye.pipeline.dry_run import check_dataset

    folder, _, n = video_dataset
    result = check_dataset(folder, sample=4, processes=1)
    cam1 = next(c for c in result.cameras if c.name == "cam1")
    assert cam1.source == "video" and cam1.listed == n and cam1.sampled == 4
    assert cam1.found >= 3 and result.ok


def test_check_samples_on_when_few_frames_show_the_target(tmp_path):
    """Frames without the board (blank) around the 12 with it: the sample of 3 held fewer
    than 3 with the target and the check said calibrating would fail; it reads more frames,
    evenly over the rest, until 3 show it (issue 32), as for a folder or a bag."""
    from multieye.pipeline.dry_run import check_dataset

    folder = tmp_path / "d"
    render_small(folder, images_per_camera=12)
    files = sorted((folder / "cam1").glob("*.png"), key=lambda p: float(p.stem))
    blank = np.full((480, 640), 128, np.uint8)
    frames, stamps = [], []
    for p in files:                     # 5 blank frames around each rendered one
        frames += [blank] * 2 + [cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)] + [blank] * 3
        stamps += [float(p.stem) + 0.002 * (k - 2) for k in range(6)]
    _write_video(folder / "cam1.avi", frames)
    (folder / "cam1_stamps.txt").write_text("".join(f"{t:.6f}\n" for t in stamps))
    (folder / "rig.yaml").write_text((folder / "rig.yaml").read_text().replace(
        "    images: cam1/", "    video: cam1.avi\n    stamps: cam1_stamps.txt"))
    result = check_dataset(folder, sample=3, processes=1)
    cam1 = next(c for c in result.cameras if c.name == "cam1")
    assert result.ok, result.reasons
    assert cam1.source == "video" and cam1.listed == 72 and 3 < cam1.sampled < 72
    assert cam1.found >= 3
