"""Cameras whose images are a video file (rig.yaml ``video:``) or a bag's image topic, as
the pipeline lists and reads them: every frame listed with its stamp before any is decoded
(so that the selection, :mod:`multieye.pipeline.selection`, can choose among them), then the
chosen frames read in order, one at a time (:func:`multieye.imaging.video.iter_video_frames`,
:func:`multieye.io.rosbag.sample_bag_images`)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

from multieye.imaging.video import iter_video_frames, video_stamps
from multieye.io import CameraSpec, sample_bag_images
from multieye.io.frame_stamps import read_frame_stamps

__all__ = ["VideoFrame", "video_listing", "video_frames", "bag_listing", "bag_frames"]


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


def bag_listing(cam: CameraSpec) -> list[tuple[float, int, VideoFrame]]:
    """Every message of the camera's image topic as ``(stamp_s, stamp_ns, VideoFrame)`` in
    bag order, its stamp read from the header bytes without decoding the image."""
    stamps: list[int] = []
    for _ in sample_bag_images(cam.rosbag, cam.topic, (), stamps=stamps):
        pass
    return [(ns * 1e-9, ns, VideoFrame(f"{cam.topic}@{ns}", k)) for k, ns in enumerate(stamps)]


def bag_frames(cam: CameraSpec, listed, stamped: list, lost: list) -> Iterator[tuple]:
    """``(label, image)`` of the messages ``listed`` (items of :func:`bag_listing`), decoded
    in bag order one at a time; each appended to ``stamped`` as ``(stamp, label)``, each
    compressed message that could not be decoded to ``lost`` as ``(label, reason)``."""
    wanted = [f.index for _, _, f in listed]
    bad: list = []
    for _, stamp_ns, image in sample_bag_images(cam.rosbag, cam.topic, wanted, gray=True,
                                                lost=bad):
        label = f"{cam.topic}@{stamp_ns}"
        stamped.append((stamp_ns * 1e-9, label))
        yield label, image
    lost.extend((f"{cam.topic}@{ns}", why) for ns, why in bad)
