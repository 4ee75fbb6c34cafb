"""Video files read frame by frame (``cv2.VideoCapture``), never held whole.

A camera may give its images as a video file (rig.yaml ``video:``; docs/rig-yaml.md).  The
stamp of frame k is ``start_time + k / fps`` with the container's frame rate, or line k of a
stamps file (:func:`multieye.io.frame_stamps.read_frame_stamps`; needed for a variable frame
rate).  Frames are read in order, one at a time: :func:`iter_video_frames` grabs every frame
(the codec needs the frames between two kept ones) but converts and yields only the kept
ones, and stops after the last of them.  Bounds: :data:`MAX_VIDEO_BYTES` per file and
:data:`MAX_VIDEO_FRAMES` frames.

Synopsis
--------
>>> from multieye.imaging.video import iter_video_frames, video_frame_count
>>> for index, image in iter_video_frames("cam0.mp4", keep={0, 10, 20}):   # doctest: +SKIP
...     pass
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import cv2
import numpy as np

from multieye.core.errors import DatasetError
from multieye.core.regular_files import check_regular

__all__ = ["MAX_VIDEO_BYTES", "MAX_VIDEO_FRAMES", "video_frame_count", "video_stamps",
           "iter_video_frames"]

#: Largest video file read, bytes.
MAX_VIDEO_BYTES = 64 * 2**30
#: Most frames read from one video (10 hours at 30 Hz).
MAX_VIDEO_FRAMES = 1_080_000


def _open(path) -> cv2.VideoCapture:
    check_regular(path, what="video file", max_bytes=MAX_VIDEO_BYTES)
    # FFmpeg's own lines ('moov atom not found', 'overread 8') kept off stderr, where the
    # reason is multieye's one line; OpenCV reads this when it opens its first video (a level
    # the user set is kept)
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    cap = cv2.VideoCapture(os.fspath(path))
    if not cap.isOpened():
        cap.release()
        raise DatasetError("cannot open the video file: not a video OpenCV's FFmpeg reads, or "
                           "one cut short (an .mp4 or .mov whose recording stopped before its "
                           "index was written)", path=path)
    return cap


def _grabbed_frames(path) -> int:
    """Frames of a video counted by grabbing each (the codec decodes them)."""
    cap = _open(path)
    try:
        n = 0
        while cap.grab():
            n += 1
            if n > MAX_VIDEO_FRAMES:
                raise DatasetError(f"more than the {MAX_VIDEO_FRAMES} frames accepted",
                                   path=path)
        return n
    finally:
        cap.release()


def video_frame_count(path: str | os.PathLike, *, counted: bool = False) -> tuple[int, float]:
    """Frames and frame rate (Hz) as the container states them, without reading a frame;
    the frames counted by grabbing each when ``counted`` or when the container states no
    count (a raw MJPEG or H.264 stream).  Many containers' count is an estimate from their
    duration (an MPEG-PS ``.mpg`` of 5 frames states 1).

    Raises
    ------
    DatasetError
        Missing, too large or unreadable file; a video without a frame; more than
        :data:`MAX_VIDEO_FRAMES` frames.
    """
    cap = _open(path)
    try:
        n, fps = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)), float(cap.get(cv2.CAP_PROP_FPS))
    finally:
        cap.release()
    if n <= 0 or counted:
        n = _grabbed_frames(path)
    if n == 0:
        raise DatasetError("the video holds no frame", path=path)
    if n > MAX_VIDEO_FRAMES:
        raise DatasetError(f"{n} frames, more than the {MAX_VIDEO_FRAMES} accepted", path=path)
    return n, fps


def video_stamps(path: str | os.PathLike, *, start_s: float = 0.0,
                 stamps_ns: np.ndarray | None = None) -> np.ndarray:
    """Stamp of every frame, seconds, (n,): ``stamps_ns`` (from a stamps file, one per frame)
    or ``start_s + k / fps``.

    Raises
    ------
    DatasetError
        As :func:`video_frame_count`; a stamps file whose count is not the video's frames
        (counted by grabbing each when the container states another); no frame rate and no
        stamps file.
    """
    n, fps = video_frame_count(path)
    if stamps_ns is not None:
        if len(stamps_ns) != n:     # the stated count may be an estimate: count the frames
            n = video_frame_count(path, counted=True)[0]
        if len(stamps_ns) != n:
            raise DatasetError(f"the stamps file has {len(stamps_ns)} stamps for the video's "
                               f"{n} frames (one per frame, in order; counted)", path=path)
        return np.asarray(stamps_ns, dtype=np.int64) / 1e9
    if not (np.isfinite(fps) and fps > 0):
        raise DatasetError("the video states no frame rate; give its frame stamps as "
                           "'stamps: FILE' in rig.yaml", path=path)
    return start_s + np.arange(n) / fps


def iter_video_frames(path: str | os.PathLike, keep=None) -> Iterator[tuple[int, np.ndarray]]:
    """The frames of a video, in order, one at a time.

    Parameters
    ----------
    path : path-like
    keep : collection of int, optional
        Frame numbers (from 0) to yield; the others are grabbed (decoded by the codec) but
        not converted; reading stops after the last kept frame.  Default: every frame.

    Yields
    ------
    index : int
    image : ndarray, shape (H, W) or (H, W, 3), uint8, or None
        As OpenCV returns it (BGR); None when the frame could not be decoded.

    Raises
    ------
    DatasetError
        As :func:`video_frame_count` when opening; more frames than
        :data:`MAX_VIDEO_FRAMES`.
    """
    wanted = None if keep is None else {int(k) for k in keep}
    last = None if wanted is None else max(wanted, default=-1)
    cap = _open(path)
    try:
        index = 0
        while (last is None or index <= last) and cap.grab():
            if index >= MAX_VIDEO_FRAMES:
                raise DatasetError(f"more than the {MAX_VIDEO_FRAMES} frames accepted",
                                   path=path)
            if wanted is None or index in wanted:
                ok, frame = cap.retrieve()
                yield index, (frame if ok else None)
            index += 1
    finally:
        cap.release()
