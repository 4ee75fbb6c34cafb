"""Video files as other tools leave them (hostile-input pass, session 17): a container whose
frame count is an estimate or absent, a video without a frame, an .mp4 cut short; each read
right or refused with multieye's one line, FFmpeg's own lines kept off stderr."""

from __future__ import annotations

import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.imaging.video import iter_video_frames, video_frame_count, video_stamps


def _write(path, fourcc, n, fps=30.0):
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (64, 48), True)
    if not writer.isOpened():
        pytest.skip(f"OpenCV here cannot write {fourcc} to {path.suffix}")
    for k in range(n):
        writer.write(np.full((48, 64, 3), 25 * k % 256, np.uint8))
    writer.release()


@pytest.mark.parametrize("fourcc,suffix", [("MPEG", ".mpg"), ("MJPG", ".mjpeg")])
def test_a_stamps_file_is_matched_to_the_frames_counted(tmp_path, fourcc, suffix):
    """MPEG-PS states 1 frame for 5, a raw MJPEG stream states none: the stamps file's 5
    stamps are the 5 frames the video holds (refused before: '5 stamps for the video's 1
    frames', 'the video states no frame count; give its frame stamps')."""
    path = tmp_path / f"v{suffix}"
    _write(path, fourcc, 5)
    assert len([i for i, _ in iter_video_frames(path)]) == 5
    stamps = np.arange(5, dtype=np.int64) * 40_000_000 + 10**18
    np.testing.assert_array_equal(video_stamps(path, stamps_ns=stamps), stamps / 1e9)
    with pytest.raises(DatasetError, match="4 stamps for the video's 5 frames"):
        video_stamps(path, stamps_ns=stamps[:4])


def test_a_video_without_a_frame_is_named_as_such(tmp_path):
    path = tmp_path / "empty.avi"
    _write(path, "MJPG", 0)
    for call in (lambda: video_frame_count(path),
                 lambda: video_stamps(path, stamps_ns=np.array([10**18]))):
        with pytest.raises(DatasetError, match="the video holds no frame") as info:
            call()
        assert "give its frame stamps" not in str(info.value)


def test_an_mp4_cut_short_is_one_line_without_ffmpeg_noise(tmp_path):
    path = tmp_path / "cut.mp4"
    _write(path, "mp4v", 10)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 6 // 10])
    env = {k: v for k, v in os.environ.items() if k != "OPENCV_FFMPEG_LOGLEVEL"}
    code = ("import sys\nfrom multieye.imaging.video import video_frame_count\n"
            "from multieye.core.errors import DatasetError\n"
            "try:\n    video_frame_count(sys.argv[1])\n"
            "except DatasetError as exc:\n    print(exc)\n")
    done = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                          text=True, timeout=120, env=env)
    assert done.returncode == 0
    assert done.stderr == ""            # FFmpeg's 'moov atom not found' not printed
    assert "cut short" in done.stdout and str(path) in done.stdout
