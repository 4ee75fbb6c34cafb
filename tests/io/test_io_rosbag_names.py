"""Image topics as other labs' bags hold them (hostile-input pass, session 17): a topic named
without its leading slash, two messages of one topic with the same header stamp."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.io.rosbag import (bag_image_count, iter_bag_images, read_bag_trajectory,
                                sample_bag_images)
from rosbag_writer import BASE_NS, Bag, image_msg


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_a_relative_topic_name_is_the_recorded_absolute_one(tmp_path, rng, ros):
    path = tmp_path / ("run.bag" if ros == 1 else "run")
    images = rng.integers(0, 256, (3, 16, 24), dtype=np.uint8)
    with Bag(path, ros) as bag:
        for k, img in enumerate(images):
            ns = BASE_NS + k * 10**7
            bag.write("/cam0/image_raw", image_msg(bag, ns, img, "mono8"), ns)
            bag.write("/vicon/rig", bag.t("geometry_msgs/msg/PoseStamped")(
                header=bag.header(ns, "world"), pose=bag.pose(np.eye(4))), ns)
    for topic in ("cam0/image_raw", "/cam0/image_raw"):
        got = list(iter_bag_images(path, topic))
        expected = [BASE_NS + k * 10**7 for k in range(3)]
        assert [ns for ns, _ in got] == expected
        assert all(np.array_equal(a, b) for (_, a), b in zip(got, images))
        assert bag_image_count(path, topic) == 3
        stamps: list = []
        assert [i for i, _, _ in sample_bag_images(path, topic, [1], stamps=stamps)] == [1]
        assert stamps == expected
    assert len(read_bag_trajectory(path, "vicon/rig").T) == 3
    with pytest.raises(DatasetError, match="topic 'cam1/image_raw' not in the bag; topics "
                                           "present: /cam0/image_raw"):
        bag_image_count(path, "cam1/image_raw")


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_two_messages_with_one_stamp_are_refused_naming_the_topic(tmp_path, rng, ros):
    """A driver that stamps every image alike: refused by the reader, naming the topic and
    the stamp (before: 'camera cam1: two images named ...' from the pairing by name, or two
    images paired with one motion-capture pose)."""
    path = tmp_path / ("run.bag" if ros == 1 else "run")
    img = rng.integers(0, 256, (16, 24), dtype=np.uint8)
    with Bag(path, ros) as bag:
        for k in range(3):
            stamp = BASE_NS + (k > 0)
            bag.write("/cam/img", image_msg(bag, stamp, img, "mono8"), BASE_NS + 10 * k)
    expected = f"image topic /cam/img: two messages with the header stamp {BASE_NS + 1} ns"
    with pytest.raises(DatasetError, match=expected):
        list(iter_bag_images(path, "/cam/img"))
    with pytest.raises(DatasetError, match=expected):     # the listing, no image decoded
        list(sample_bag_images(path, "/cam/img", [], stamps=[]))
    with pytest.raises(DatasetError, match=expected):     # the last one decoded
        list(sample_bag_images(path, "/cam/img", [2], stamps=[]))


def test_a_depth_topic_and_an_mcap_cut_short_are_named(tmp_path, rng):
    """A compressedDepth topic is refused as depth images (was: 'not a PNG ... stream', now
    that one undecodable message is left out it would have been every message left out); an
    MCAP file cut short names 'mcap recover'."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    import rosbag_writer

    png = cv2.imencode(".png", rng.integers(0, 4000, (16, 24), dtype=np.uint16))[1].tobytes()
    path = tmp_path / "run"
    bag = Bag.__new__(Bag)
    bag.ros, bag.ts, bag.conns = 2, rosbag_writer._typestore(2), {}
    bag.writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    with bag:
        for k in range(3):
            bag.write("/depth/compressedDepth", bag.t("sensor_msgs/msg/CompressedImage")(
                header=bag.header(BASE_NS + k, "cam"), format="16UC1; compressedDepth",
                data=np.frombuffer(bytes(12) + png, np.uint8).copy()), BASE_NS + k)
    with pytest.raises(DatasetError, match="the topic holds depth images"):
        list(iter_bag_images(path, "/depth/compressedDepth", lost=[]))
    mcap = next(path.glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[:-40])
    with pytest.raises(DatasetError, match="cannot read the bag: .*'mcap recover"):
        bag_image_count(path, "/depth/compressedDepth")


def test_a_ros2_bag_is_named_by_its_metadata_too(tmp_path, rng):
    path = tmp_path / "run"
    with Bag(path, 2) as bag:
        bag.write("/c", image_msg(bag, BASE_NS, rng.integers(0, 256, (16, 24), dtype=np.uint8),
                                  "mono8"), BASE_NS)
    assert bag_image_count(path / "metadata.yaml", "/c") == 1   # was 'rosbag reindex'
    assert bag_image_count(path, "/c") == 1
