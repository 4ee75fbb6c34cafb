"""A camera whose images are a video file (rig.yaml ``video:``), as the pipeline lists and
reads it: every frame listed with its stamp before any is decoded (so that the selection,
:mod:`multieye.pipeline.selection`, can choose among them), then the chosen frames read in
order, one at a time (:func:`multieye.imaging.video.iter_video_frames`)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

from multieye.imaging.video import iter_video_frames, video_stamps
from multieye.io import CameraSpec
from multieye.io.frame_stamps import read_frame_stamps

__all__ = ["VideoFrame", "video_listing", "video_frames"]


class VideoFrame(NamedTuple):
    """One frame of a camera's video: ``name`` (``<file>#<frame number>``), ``index`` (from 0)."""

    name: str
    index: int


def video_listing(cam: CameraSpec) -> list[tuple[float, int, VideoFrame]]:
    """Every frame as ``(stamp_s, stamp_ns, VideoFrame)``, in order, without decoding one:
    stamps from the camera's ``stamps`` file, else ``start_time + k / fps``."""
    ns = read_frame_stamps(cam.stamps) if cam.stamps is not None else None
    stamps = video_stamps(cam.video, start_s=cam.start_time, stamps_ns=ns)
    return [(float(t), int(round(t * 1e9)) if ns is None else int(ns[k]),
             VideoFrame(f"{cam.video.name}#{k}", k)) for k, t in enumerate(stamps)]


def video_frames(cam: CameraSpec, listed, stamped: list, lost: list) -> Iterator[tuple]:
    """``(label, image)`` of the frames ``listed`` (items of :func:`video_listing`), read in
    order; each one read is appended to ``stamped`` as ``(stamp, label)``, each that could
    not be decoded to ``lost`` as ``(label, reason)``."""
    by_index = {f.index: (stamp, f.name) for stamp, _, f in listed}
    for index, image in iter_video_frames(cam.video, keep=by_index):
        stamp, label = by_index.pop(index)
        if image is None:
            lost.append((label, "unreadable frame: the video's codec returned no image"))
            continue
        stamped.append((stamp, label))
        yield label, image
    lost.extend((label, "unreadable frame: the video ended before it")
                for _, label in by_index.values())
