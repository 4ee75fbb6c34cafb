"""Poses and images from ROS 1 (``.bag``) and ROS 2 (folder, ``.db3`` or ``.mcap``) bags,
read with the ``rosbags`` package: no ROS installation needed.

Pose topics -> :class:`Trajectory` (:func:`read_bag_trajectory`):

- ``geometry_msgs/PoseStamped``: ``T_<header.frame_id>_<body>`` from ``pose``.
- ``geometry_msgs/TransformStamped``: ``T_<header.frame_id>_<child_frame_id>``.
- ``tf2_msgs/TFMessage`` (``/tf``): every transform in every message; the pair of frames is
  chosen with ``parent_frame`` / ``child_frame`` (needed when the topic carries several).
- ``nav_msgs/Odometry``: ``pose.pose`` as ``T_<header.frame_id>_<child_frame_id>``.
- ``geometry_msgs/PoseWithCovarianceStamped``: ``pose.pose`` as ``PoseStamped``'s pose (the
  covariance is not read).

The stamp of a sample is its ``header.stamp`` (exact integer nanoseconds, kept in
``stamps_ns``); a zero header stamp (a publisher that never filled it) falls back to the bag's
record time.  Samples are sorted by stamp; two samples with the same stamp are an error.

Image topics -> ``(stamp_ns, image)`` pairs (:func:`iter_bag_images`): ``sensor_msgs/Image``
with the encodings in :data:`IMAGE_ENCODINGS` and ``sensor_msgs/CompressedImage`` (decoded
with ``cv2.imdecode``).  The size an image states is checked before it is decoded or
converted (:func:`multieye.core.image_header.size_problem`): ``width``, ``height`` and
``step`` of a ``sensor_msgs/Image`` against its data length, and the header of a compressed
image's bytes (:func:`multieye.core.image_header.image_header`); an EXIF orientation in a
compressed image is ignored (the pixels as the sensor wrote them, like image files).
Images follow OpenCV's layout: ``(H, W)`` for grey, ``(H, W, 3)`` BGR
for colour (``rgb8``/``rgba8``/Bayer are converted, alpha dropped).  A sample of a long topic
(:func:`sample_bag_images`, with :func:`bag_image_count`) decodes only the chosen messages and
reads the stamp of every other one from its serialized header, one message in memory at a time.

>>> from multieye.io.rosbag import read_bag_trajectory
>>> traj = read_bag_trajectory("run.bag", "/vicon/rig/pose")   # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import functools
import os
import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from multieye.core.arguments import as_path
from multieye.core.errors import DatasetError, InputError
from multieye.core.image_header import FORMATS, cut_short, image_header, size_problem
from multieye.core.limits import MAX_YAML_BYTES
from multieye.io.poserows import RowPlace, quaternion_poses, usable_rows
from multieye.io.textfile import length_scale
from multieye.io.trajectory import Trajectory
from multieye.core.regular_files import check_regular

__all__ = [
    "POSE_TYPES",
    "IMAGE_TYPES",
    "IMAGE_ENCODINGS",
    "bag_topics",
    "read_bag_trajectory",
    "iter_bag_images",
    "bag_image_count",
    "sample_bag_images",
]

POSE_TYPES = ("geometry_msgs/PoseStamped", "geometry_msgs/TransformStamped",
              "tf2_msgs/TFMessage", "nav_msgs/Odometry", "geometry_msgs/PoseWithCovarianceStamped")
IMAGE_TYPES = ("sensor_msgs/Image", "sensor_msgs/CompressedImage")

# encoding -> (numpy dtype, channels, conversion to OpenCV layout)
_PLAIN = {
    "mono8": ("u1", 1, None), "8UC1": ("u1", 1, None),
    "mono16": ("u2", 1, None), "16UC1": ("u2", 1, None),
    "bgr8": ("u1", 3, None), "8UC3": ("u1", 3, None), "rgb8": ("u1", 3, "rgb"),
    "bgra8": ("u1", 4, "bgra"), "8UC4": ("u1", 4, "bgra"), "rgba8": ("u1", 4, "rgba"),
}
# ROS Bayer names give the colours of the top-left 2x2 block; OpenCV names its conversion
# codes after the second row's pattern, so ROS rggb is OpenCV's BayerBG (checked in the tests
# by demosaicing a mosaic of a known colour image).
_BAYER = {"bayer_rggb8": "COLOR_BayerBG2BGR", "bayer_bggr8": "COLOR_BayerRG2BGR",
          "bayer_gbrg8": "COLOR_BayerGR2BGR", "bayer_grbg8": "COLOR_BayerGB2BGR"}
# YUV 4:2:2, two bytes a pixel: ROS's yuv422 is UYVY, yuv422_yuy2 is YUYV.
_YUV = {"yuv422": "COLOR_YUV2BGR_UYVY", "uyvy": "COLOR_YUV2BGR_UYVY",
        "yuv422_yuy2": "COLOR_YUV2BGR_YUY2", "yuyv": "COLOR_YUV2BGR_YUY2"}
#: Encodings of ``sensor_msgs/Image`` that :func:`iter_bag_images` decodes.
IMAGE_ENCODINGS = tuple(_PLAIN) + tuple(_BAYER) + tuple(_YUV)


def _short_type(msgtype: str) -> str:
    return msgtype.replace("/msg/", "/")


@functools.lru_cache(maxsize=1)
def _default_typestore():
    """Message types for ROS 2 bags that do not store their definitions (built once)."""
    from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415 (heavy: rosbags, only for bag files)

    return get_typestore(Stores.LATEST)


def _check_bag_files(p: Path) -> None:
    """A bag file, or every file of a ROS 2 bag folder, is a regular file of bounded size:
    the bag library opens them by path (no device, FIFO or socket is handed to it)."""

    if p.is_dir():
        check_regular(p / "metadata.yaml", what="bag metadata", max_bytes=MAX_YAML_BYTES)
        for entry in sorted(p.iterdir()):
            if entry.suffix in (".db3", ".mcap", ".yaml"):
                check_regular(entry, what="bag file")
    else:
        check_regular(p, what="bag")


@contextlib.contextmanager
def _reader(path: str | os.PathLike):
    from rosbags.highlevel import AnyReader, AnyReaderError  # noqa: PLC0415 (heavy: rosbags, only for bag files)

    p = as_path(path, "bag")
    if not p.exists():
        raise DatasetError("bag not found", path=p)
    _check_bag_files(p)
    if p.is_file() and p.suffix in (".db3", ".mcap"):
        if not (p.parent / "metadata.yaml").is_file():
            raise DatasetError(f"a ROS 2 bag's {p.suffix} file is read with the metadata.yaml "
                               "that ros2 bag record writes beside it, and its folder has none: "
                               "give the bag's folder as recorded, or write metadata.yaml again "
                               f"with 'ros2 bag reindex <folder>'"
                               f"{' -s mcap' if p.suffix == '.mcap' else ''}", path=p)
        p = p.parent  # a ROS 2 bag is its folder (with metadata.yaml)
    elif p.is_file() and p.name == "metadata.yaml":
        p = p.parent  # the bag's metadata names it too
        _check_bag_files(p)
    try:
        reader = AnyReader([p], default_typestore=_default_typestore())
        reader.open()
    except (AnyReaderError, OSError, ValueError) as exc:
        hint = ("; a ROS 1 bag cut short (a recording stopped abruptly, a .bag.active) is "
                "repaired by 'rosbag reindex'" if p.is_file() and p.suffix != ".yaml" else
                "; an MCAP file cut short (a recording stopped abruptly) is repaired by 'mcap "
                "recover FILE -o NEW', a .db3 by sqlite3's '.recover'")
        why = str(exc).rstrip(".")
        raise DatasetError(f"cannot read the bag: {why}{hint}", path=path) from exc
    try:
        yield reader
    finally:
        reader.close()


def bag_topics(path: str | os.PathLike) -> dict[str, str]:
    """Topics of a bag and their message types (``"geometry_msgs/PoseStamped"``)."""
    with _reader(path) as reader:
        return {t: _short_type(info.msgtype) for t, info in sorted(reader.topics.items())}


def _connections(reader, topic: str, allowed: tuple[str, ...], path):
    present = {t: _short_type(i.msgtype) for t, i in sorted(reader.topics.items())}
    # a recorded topic's name is absolute ('/cam0/image_raw'); 'cam0/image_raw' (a relative
    # name, as a launch file or Kalibr's camchain may write it) names the same topic
    same = [t for t in present if t.lstrip("/") == topic.lstrip("/")]
    if topic not in present and len(same) == 1:
        topic = same[0]
    if topic not in present:
        listing = ", ".join(f"{t} ({m})" for t, m in present.items()) or "none"
        raise DatasetError(f"topic {topic!r} not in the bag; topics present: {listing}",
                           path=path)
    if present[topic] not in allowed:
        others = [f"{t} ({m})" for t, m in present.items() if m in allowed]
        hint = (f"; topics of those types in this bag: {', '.join(others)}" if others else
                "; republish it as one of them, or export it to a TUM file (t x y z qx qy qz "
                "qw) and give that as the file")
        raise DatasetError(f"topic {topic!r} has type {present[topic]}; expected one of "
                           f"{', '.join(allowed)}{hint}", path=path)
    return [c for c in reader.connections if c.topic == topic], present[topic]


def _stamp_ns(header, record_ns: int) -> int:
    ns = int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
    return ns if ns != 0 else int(record_ns)


def _frame(name: str) -> str:
    return name.lstrip("/")


def _samples(msg, msgtype: str, record_ns: int):
    """(parent frame, child frame or None, stamp ns, translation, quaternion xyzw)."""
    if msgtype == "tf2_msgs/TFMessage":
        for tf in msg.transforms:
            yield from _samples(tf, "geometry_msgs/TransformStamped", record_ns)
        return
    if msgtype == "geometry_msgs/PoseStamped":
        pose, child = msg.pose, None
    elif msgtype == "geometry_msgs/PoseWithCovarianceStamped":
        pose, child = msg.pose.pose, None
    elif msgtype == "nav_msgs/Odometry":
        pose, child = msg.pose.pose, msg.child_frame_id
    else:  # TransformStamped
        tr = msg.transform
        yield (_frame(msg.header.frame_id), _frame(msg.child_frame_id),
               _stamp_ns(msg.header, record_ns),
               (tr.translation.x, tr.translation.y, tr.translation.z),
               (tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w))
        return
    p, q = pose.position, pose.orientation
    yield (_frame(msg.header.frame_id), None if child is None else _frame(child),
           _stamp_ns(msg.header, record_ns), (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))


def read_bag_trajectory(path: str | os.PathLike, topic: str, *,
                        parent_frame: str | None = None, child_frame: str | None = None,
                        unit: str = "m", parent: str = "world",
                        child: str = "marker") -> Trajectory:
    """Read a pose topic of a ROS 1 or ROS 2 bag.

    Parameters
    ----------
    path : path-like
        ``.bag`` file (ROS 1), or ROS 2 bag folder (or its ``.db3`` / ``.mcap`` file).
    topic : str
        A topic of one of the :data:`POSE_TYPES`.
    parent_frame, child_frame : str, optional
        Keep only samples with this ``header.frame_id`` / ``child_frame_id`` (a leading ``/``
        is ignored).  Needed for ``/tf`` topics that carry several pairs of frames.
    unit : {"m", "cm", "mm"}
        Unit of the translations in the bag.
    parent, child : str
        Frame names of the returned ``T_parent_child`` (multieye's names, e.g. ``world`` and
        ``marker``; the ROS frame ids select the samples but do not rename them).

    Raises
    ------
    DatasetError
        Missing bag, topic missing (listing the topics present) or of another type, no sample
        for the frames asked (listing the pairs present), several pairs and none chosen,
        non-unit quaternion, duplicate stamps.
    """
    scale = length_scale(unit)
    rows = []
    with _reader(path) as reader:
        connections, msgtype = _connections(reader, topic, POSE_TYPES, path)
        for conn, record_ns, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, conn.msgtype)
            rows.extend(_samples(msg, msgtype, record_ns))
    pairs = sorted({(r[0], r[1]) for r in rows}, key=str)
    keep = [r for r in rows if (parent_frame is None or r[0] == _frame(parent_frame))
            and (child_frame is None or r[1] is None or r[1] == _frame(child_frame))]
    listing = ", ".join(f"{a} -> {b}" if b else a for a, b in pairs) or "none"
    if not keep:
        raise DatasetError(f"topic {topic!r}: no sample with parent frame {parent_frame!r} and "
                           f"child frame {child_frame!r}; frames present: {listing}", path=path)
    kept_pairs = {(r[0], r[1]) for r in keep}
    if len(kept_pairs) > 1:
        raise DatasetError(f"topic {topic!r} carries several transforms ({listing}); choose one "
                           "with parent_frame and child_frame", path=path)
    ns = np.array([r[2] for r in keep], dtype=np.int64)
    with np.errstate(over="ignore", invalid="ignore"):
        t = np.array([r[3] for r in keep], dtype=np.float64).reshape(-1, 3) * scale
    q = np.array([r[4] for r in keep], dtype=np.float64).reshape(-1, 4)
    ok, skipped, _ = usable_rows(ns / 1e9, t, q, where=RowPlace(
        path, labels=[f"{topic}@{n}" for n in ns], what=f"topic {topic}: "),
        columns=("stamp", "x", "y", "z", "qx", "qy", "qz", "qw"))
    T = quaternion_poses(t[ok], q[ok], path=path, lines=None, what=f"topic {topic}: ")
    try:
        return Trajectory.from_unsorted(ns[ok] / 1e9, T, parent, child, stamps_ns=ns[ok],
                                        skipped=skipped)
    except InputError as exc:
        raise DatasetError(f"topic {topic}: {exc}", path=path) from None


def _decode_raw(msg, where: str, path) -> np.ndarray:
    enc = msg.encoding
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    problem = size_problem(w, h, "message")
    if problem is not None:
        raise DatasetError(f"{where}: {problem}", path=path)
    data = np.asarray(msg.data, dtype=np.uint8)
    if enc in _BAYER:
        dtype, channels, convert = "u1", 1, enc
    elif enc in _YUV:
        dtype, channels, convert = "u1", 2, enc
    elif enc in _PLAIN:
        dtype, channels, convert = _PLAIN[enc]
    else:
        raise DatasetError(f"{where}: image encoding {enc!r} is not supported; supported: "
                           f"{', '.join(IMAGE_ENCODINGS)}; republish the topic in one of "
                           "them (or as a CompressedImage of PNG), or save its images to a "
                           "folder and give images:", path=path)
    dt = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    row_bytes = w * channels * dt.itemsize
    if step < row_bytes or data.size < h * step:
        raise DatasetError(f"{where}: {data.size} data bytes do not hold {h}x{w} {enc} rows "
                           f"of step {step}", path=path)
    rows = data[: h * step].reshape(h, step)[:, :row_bytes]
    img = np.ascontiguousarray(rows).view(dt).reshape((h, w, channels) if channels > 1 else (h, w))
    img = img.astype(dt.newbyteorder("="), copy=False)
    if convert == "rgb":
        return np.ascontiguousarray(img[..., ::-1])
    if convert == "rgba":
        return np.ascontiguousarray(img[..., 2::-1])
    if convert == "bgra":
        return np.ascontiguousarray(img[..., :3])
    if convert in _BAYER or convert in _YUV:
        import cv2  # noqa: PLC0415 (heavy: OpenCV, only to demosaic Bayer or YUV images)

        if convert in _YUV and w % 2:
            raise DatasetError(f"{where}: a {enc} image needs an even width, got {w}", path=path)
        return cv2.cvtColor(img, getattr(cv2, {**_BAYER, **_YUV}[convert]))
    return img


class _Undecodable(DatasetError):
    """One compressed message whose bytes are not decoded (cut short, corrupt, a size beyond
    the bounds): one bad image, as an unreadable image file is, not a bad topic."""

    def __init__(self, where: str, reason: str, path):
        super().__init__(f"{where}: {reason}", path=path)
        self.why = reason


def _decode_compressed(msg, where: str, path, gray: bool = False) -> np.ndarray:
    import cv2  # noqa: PLC0415 (heavy: OpenCV, only to decode compressed images)

    if "compresseddepth" in msg.format.replace(" ", "").lower():
        raise DatasetError(f"{where}: the topic holds depth images (format {msg.format!r}), "
                           "not a camera's picture of the board; give the camera's image "
                           "topic (its colour, grey or infrared images)", path=path)
    buf = np.asarray(msg.data, dtype=np.uint8)
    data = buf.tobytes()
    header = image_header(data) if buf.size else None
    if header is None:
        raise _Undecodable(where, f"the compressed image (format {msg.format!r}) is not a "
                           f"{FORMATS} stream, or its header is cut short", path)
    problem = (size_problem(header.width, header.height, f"{header.format} header")
               or cut_short(data, header))
    if problem is not None:
        raise _Undecodable(where, problem, path)
    # IMREAD_UNCHANGED (-1) includes IMREAD_IGNORE_ORIENTATION: the pixels as stored; grey:
    # the flags image files are read with (multieye.imaging.image_file.decode_gray), so that
    # the same JPEG or PNG bytes give the same grey pixels from a bag as from a file (a colour
    # JPEG's grey is its decoder's luma, not a conversion of its BGR decoding)
    flags = (cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH if gray else cv2.IMREAD_UNCHANGED)
    img = cv2.imdecode(buf, flags | cv2.IMREAD_IGNORE_ORIENTATION)
    if img is None:
        raise _Undecodable(where, f"cannot decode the compressed image (format "
                           f"{msg.format!r}): corrupt, or not a JPEG or PNG stream", path)
    if img.ndim == 3 and img.shape[2] == 4:
        img = np.ascontiguousarray(img[..., :3])
    return img


def _decode(reader, conn, raw, record_ns: int, topic: str, path, *, gray: bool = False,
            lost: list | None = None):
    """``(stamp, image)``; image None for a compressed message that is not decoded when
    ``lost`` is given, ``(stamp, reason)`` appended to it."""
    msg = reader.deserialize(raw, conn.msgtype)
    stamp = _stamp_ns(msg.header, record_ns)
    where = f"topic {topic} at {stamp} ns"
    if _short_type(conn.msgtype) == "sensor_msgs/Image":
        return stamp, _decode_raw(msg, where, path)
    try:
        return stamp, _decode_compressed(msg, where, path, gray)
    except _Undecodable as exc:
        if lost is None:
            raise
        lost.append((stamp, f"unreadable message: {exc.why}"))
        return stamp, None


def _new_stamp(seen: set, stamp: int, topic: str, path) -> int:
    """``stamp``, added to ``seen``; a stamp seen before is an error (two images of one
    instant of one camera: which motion-capture pose or which view is each?)."""
    if stamp in seen:
        raise DatasetError(f"image topic {topic}: two messages with the header stamp {stamp} "
                           "ns; each image needs its own stamp (republish the topic with each "
                           "image's capture time in header.stamp, or save its images to a "
                           "folder named by their times)", path=path)
    seen.add(stamp)
    return stamp


def iter_bag_images(path: str | os.PathLike, topic: str, *, gray: bool = False,
                    lost: list | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """Images of a ``sensor_msgs/Image`` or ``sensor_msgs/CompressedImage`` topic.

    Parameters
    ----------
    path : path-like
        ROS 1 ``.bag`` or ROS 2 bag.
    topic : str
    gray : bool
        Compressed images decoded to grey as image files are (``cv2.IMREAD_GRAYSCALE`` with
        ``IMREAD_ANYDEPTH``: a colour JPEG's luma as its decoder gives it), so that the same
        bytes give the same pixels from a bag and from a file; ``sensor_msgs/Image`` messages
        are returned as without it.
    lost : list, optional
        When given, a compressed message whose bytes are not decoded (cut short, corrupt,
        a size beyond the bounds) is appended to it as ``(stamp_ns, reason)`` and left out,
        as an unreadable image file is; without it, it is an error.

    Yields
    ------
    stamp_ns : int
        ``header.stamp`` in nanoseconds (the record time when the header stamp is zero).
    image : ndarray, shape (H, W) or (H, W, 3)
        OpenCV layout (BGR); dtype uint8, or uint16 for 16-bit encodings.  In bag order.

    Raises
    ------
    DatasetError
        Missing bag or topic (listing those present), unsupported encoding, undecodable data,
        two messages with one stamp.
    """
    seen: set[int] = set()
    with _reader(path) as reader:
        connections, _ = _connections(reader, topic, IMAGE_TYPES, path)
        for conn, record_ns, raw in reader.messages(connections=connections):
            stamp, image = _decode(reader, conn, raw, record_ns, topic, path,
                                   gray=gray, lost=lost)
            _new_stamp(seen, stamp, topic, path)
            if image is not None:
                yield stamp, image


def bag_image_count(path: str | os.PathLike, topic: str) -> int:
    """Messages of an image topic, as the bag's index (ROS 1) or metadata (ROS 2) states,
    without reading a message.

    Raises
    ------
    DatasetError
        As :func:`iter_bag_images` for a missing bag or topic, or a topic of another type.
    """
    with _reader(path) as reader:
        connections, _ = _connections(reader, topic, IMAGE_TYPES, path)
        return sum(int(c.msgcount) for c in connections)


def _header_stamp_ns(raw, ros2: bool) -> int | None:
    """``header.stamp`` of a serialized message that starts with a ``std_msgs/Header``, read
    from its first bytes (ROS 1: ``uint32 seq, uint32 secs, uint32 nsecs``, little-endian; CDR:
    a 4-byte encapsulation header whose second byte is 1 for little-endian, then ``int32 sec,
    uint32 nanosec``); None when the bytes are too short or of an unknown encapsulation."""
    if len(raw) < 12:
        return None
    if ros2:
        if bytes(raw[:2]) not in (b"\x00\x00", b"\x00\x01"):
            return None
        sec, nsec = struct.unpack_from("<iI" if raw[1] else ">iI", raw, 4)
    else:
        sec, nsec = struct.unpack_from("<II", raw, 4)
    return int(sec) * 1_000_000_000 + int(nsec)


def sample_bag_images(path: str | os.PathLike, topic: str, indices, *, stamps: list | None = None,
                      gray: bool = False, lost: list | None = None
                      ) -> Iterator[tuple[int, int, np.ndarray]]:
    """The images at some positions of an image topic, decoding only those.

    Every message of the topic is read in bag order, one at a time; only the messages at
    ``indices`` are deserialized and decoded.  The stamp of each other message is read from
    the first bytes of its serialized header (as :func:`iter_bag_images` would give it).

    Parameters
    ----------
    path : path-like
        ROS 1 ``.bag`` or ROS 2 bag.
    topic : str
        An image topic (:data:`IMAGE_TYPES`).
    indices : iterable of int
        Positions of the wanted messages in bag order (0 is the first message of the topic),
        e.g. spread over :func:`bag_image_count`.
    stamps : list, optional
        When given, the stamp (ns) of every message of the topic is appended to it in bag
        order, the decoded ones included; the bag is then read to its end, else reading stops
        after the last wanted message.
    gray, lost : bool, list
        As :func:`iter_bag_images` (a message left out is not yielded).

    Yields
    ------
    index : int
        Position of the message in bag order.
    stamp_ns, image
        As :func:`iter_bag_images`.

    Raises
    ------
    DatasetError
        As :func:`iter_bag_images`, for the decoded messages (two with one stamp: among all
        messages when ``stamps`` is given).
    """
    wanted = {int(i) for i in indices}
    last = max(wanted, default=-1)
    if not wanted and stamps is None:
        return
    seen: set[int] = set()
    with _reader(path) as reader:
        connections, _ = _connections(reader, topic, IMAGE_TYPES, path)
        for index, (conn, record_ns, raw) in enumerate(
                reader.messages(connections=connections)):
            if index in wanted:
                stamp, image = _decode(reader, conn, raw, record_ns, topic, path,
                                       gray=gray, lost=lost)
                if stamps is not None:
                    stamps.append(_new_stamp(seen, stamp, topic, path))
                if image is not None:
                    yield index, stamp, image
                if stamps is None and index >= last:
                    return
            elif stamps is not None:
                ns = _header_stamp_ns(raw, reader.is2)
                if ns is None:      # not a plain header: deserialize the message for it
                    ns = _stamp_ns(reader.deserialize(raw, conn.msgtype).header, record_ns)
                stamps.append(_new_stamp(seen, ns if ns != 0 else int(record_ns), topic, path))
