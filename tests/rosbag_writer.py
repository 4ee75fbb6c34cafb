"""ROS 1 and ROS 2 bags written with rosbags' own writers, for the reader and pipeline tests."""

from __future__ import annotations

import functools

import numpy as np
from multieye.core import geometry
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

BASE_NS = 1_700_000_000_000_000_000


@functools.cache
def _typestore(ros):
    ts = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in ts.types:  # not in rosbags' noetic store
        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                       "tf2_msgs/msg/TFMessage"))
    return ts


class Bag:
    """Writes messages to a ROS 1 or ROS 2 bag with the matching type store."""

    def __init__(self, path, ros):
        self.ros = ros
        self.ts = _typestore(ros)
        self.writer = Writer1(path) if ros == 1 else Writer2(path, version=9)
        self.conns = {}

    def __enter__(self):
        self.writer.open()
        return self

    def __exit__(self, *exc):
        self.writer.close()

    def t(self, name):
        return self.ts.types[name]

    def header(self, ns, frame):
        kw = {"seq": 0} if self.ros == 1 else {}
        stamp = self.t("builtin_interfaces/msg/Time")(sec=ns // 10**9, nanosec=ns % 10**9)
        return self.t("std_msgs/msg/Header")(stamp=stamp, frame_id=frame, **kw)

    def write(self, topic, msg, record_ns):
        if topic not in self.conns:
            self.conns[topic] = self.writer.add_connection(topic, msg.__msgtype__,
                                                           typestore=self.ts)
        serialize = self.ts.serialize_ros1 if self.ros == 1 else self.ts.serialize_cdr
        self.writer.write(self.conns[topic], record_ns, serialize(msg, msg.__msgtype__))

    def pose(self, T):
        q = geometry.quat_from_transform(T)
        point = self.t("geometry_msgs/msg/Point")(x=T[0, 3], y=T[1, 3], z=T[2, 3])
        quat = self.t("geometry_msgs/msg/Quaternion")(x=q[0], y=q[1], z=q[2], w=q[3])
        return self.t("geometry_msgs/msg/Pose")(position=point, orientation=quat)

    def transform_stamped(self, ns, parent, child, T):
        q = geometry.quat_from_transform(T)
        tr = self.t("geometry_msgs/msg/Transform")(
            translation=self.t("geometry_msgs/msg/Vector3")(x=T[0, 3], y=T[1, 3], z=T[2, 3]),
            rotation=self.t("geometry_msgs/msg/Quaternion")(x=q[0], y=q[1], z=q[2], w=q[3]))
        return self.t("geometry_msgs/msg/TransformStamped")(
            header=self.header(ns, parent), child_frame_id=child, transform=tr)


def image_msg(bag, ns, img, encoding, *, bigendian=False, pad=0):
    data = img.astype(img.dtype.newbyteorder(">" if bigendian else "<")).tobytes()
    h, w = img.shape[:2]
    row = len(data) // h
    rows = np.frombuffer(data, np.uint8).reshape(h, row)
    rows = np.concatenate([rows, np.full((h, pad), 77, np.uint8)], axis=1)
    return bag.t("sensor_msgs/msg/Image")(
        header=bag.header(ns, "cam"), height=h, width=w, encoding=encoding,
        is_bigendian=int(bigendian), step=row + pad, data=rows.reshape(-1))




def camera_into_bag(folder, camera, *, ros=2, image=None, shift_ns=0):
    """Move the images of ``camera`` of a rendered dataset in ``folder`` into the image topic
    ``/<camera>/image_raw`` (mono8) of a bag ``folder/run.bag`` (ROS 1) or ``folder/run``
    (ROS 2), and point rig.yaml at it; the image folder is removed.

    ``image(img)`` changes each image before it is written; ``shift_ns`` moves the header
    stamps (the record times stay). Returns the header stamps written (ns)."""
    import shutil

    import cv2
    from multieye.io import list_images

    topic = f"/{camera}/image_raw"
    bag_path = folder / ("run.bag" if ros == 1 else "run")
    stamps = []
    with Bag(bag_path, ros) as bag:
        for _, ns, path in list_images(folder / camera):
            img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
            img = img if image is None else image(img)
            stamps.append(ns + shift_ns)
            bag.write(topic, image_msg(bag, ns + shift_ns, img, "mono8"), ns)
    shutil.rmtree(folder / camera)
    rig = folder / "rig.yaml"
    text = rig.read_text()
    line = f"    images: {camera}/"
    assert line in text
    rig.write_text(text.replace(line, f"    rosbag: {bag_path.name}\n    topic: {topic}"))
    return stamps
