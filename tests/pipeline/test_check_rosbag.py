"""The dry run (multieye check) of a camera whose images are an image topic of a ROS bag:
sampled as a folder is, only the sampled messages decoded, the same counts and problems."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import multieye.io.rosbag as rosbag_io
from multieye.pipeline.dry_run import check_dataset
from rosbag_writer import camera_into_bag
from small_dataset import render_small


def bag_dataset(folder, *, ros=2, images_per_camera=8, image=None, shift_ns=0):
    """The small rendered dataset with cam1's images moved into a bag's image topic
    (:func:`rosbag_writer.camera_into_bag`); the header stamps written (ns)."""
    render_small(folder, images_per_camera=images_per_camera)
    return camera_into_bag(folder, "cam1", ros=ros, image=image, shift_ns=shift_ns)


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_bag_camera_is_sampled_like_its_folder(tmp_path, ros):
    render_small(tmp_path / "ds")
    folder_check = check_dataset(tmp_path / "ds", processes=1)
    camera_into_bag(tmp_path / "ds", "cam1", ros=ros)
    result = check_dataset(tmp_path / "ds", processes=1)
    assert result.ok, result.reasons
    before, after = folder_check.cameras[1], result.cameras[1]
    assert (after.name, after.source) == ("cam1", "rosbag")
    assert (after.listed, after.sampled, after.found, after.with_mocap, after.paired,
            after.expected_usable) == (8, 8, 8, 8, 8, 8)
    assert after.failures == () and after.problems == ()
    # the same images, the same stamps: the same numbers as from the folder
    for field in ("listed", "sampled", "found", "with_mocap", "paired", "expected_usable"):
        assert getattr(after, field) == getattr(before, field)
    assert after.rotation_range_deg == pytest.approx(before.rotation_range_deg, abs=1e-3)
    np.testing.assert_allclose(after.rotation_spread_deg, before.rotation_spread_deg,
                               atol=1e-3)
    # the sample size is the folder's option
    small = check_dataset(tmp_path / "ds", sample=3, processes=1).cameras[1]
    assert (small.listed, small.sampled, small.found, small.paired,
            small.expected_usable) == (8, 3, 3, 3, 8)


def test_only_the_sampled_messages_are_decoded(tmp_path, monkeypatch):
    stamps = bag_dataset(tmp_path / "ds", images_per_camera=24)
    decoded, deserialized = [], []
    decode = rosbag_io._decode

    def counting_decode(reader, conn, raw, record_ns, topic, path, **kw):
        stamp, img = decode(reader, conn, raw, record_ns, topic, path, **kw)
        decoded.append(stamp)
        return stamp, img

    from rosbags.highlevel import AnyReader

    deserialize = AnyReader.deserialize

    def counting_deserialize(self, raw, typ):
        deserialized.append(typ)
        return deserialize(self, raw, typ)

    monkeypatch.setattr(rosbag_io, "_decode", counting_decode)
    monkeypatch.setattr(AnyReader, "deserialize", counting_deserialize)
    c = check_dataset(tmp_path / "ds", sample=5, processes=1).cameras[1]
    assert (c.source, c.listed, c.sampled, c.found, c.with_mocap, c.paired,
            c.expected_usable) == ("rosbag", 24, 5, 5, 24, 5, 24)
    assert len(decoded) == 5
    assert deserialized.count("sensor_msgs/msg/Image") == 5
    # evenly spaced over the topic's messages, first and last included, as for a folder
    assert decoded == [stamps[i] for i in (0, 6, 12, 17, 23)]


def test_topic_without_target_is_named_and_fatal(tmp_path):
    bag_dataset(tmp_path / "ds", image=lambda img: np.full_like(img, 128))
    result = check_dataset(tmp_path / "ds", processes=1)
    assert not result.ok
    c = result.cameras[1]
    assert (c.source, c.listed, c.sampled, c.found) == ("rosbag", 8, 8, 0)
    assert c.failures == (("target not detected", 8),)
    assert any(p.startswith("target found in only 0 of 8 sampled images; check the target")
               for p in c.problems)
    assert c.fatal and "fewer than 3 usable images would remain" in c.fatal[0]
    assert [r.split(":")[0] for r in result.reasons] == ["cam1"]


def test_wrong_image_size_and_no_mocap_near_in_time(tmp_path):
    bag_dataset(tmp_path / "ds", image=lambda img: cv2.resize(img, (320, 240)),
                shift_ns=100 * 10**9)
    c = check_dataset(tmp_path / "ds", processes=1).cameras[1]
    assert c.failures == (("wrong resolution", 8),)
    assert c.with_mocap == 0
    assert any(p.startswith("target found in only 0 of 8") for p in c.problems)
    assert any(p.startswith("8 of 8 images have no motion capture within 0.0167 s")
               for p in c.problems)
    assert c.fatal


def test_a_topic_whose_target_is_in_a_small_minority_is_sampled_on(tmp_path):
    """As for a folder (issue 32): the sample of 3 messages held fewer than 3 with the
    target, so the bag is read again for more, evenly over the rest, until 3 show it."""
    from multieye.io import list_images

    folder = tmp_path / "ds"
    render_small(folder)
    mocap = np.loadtxt(folder / "mocap.txt", usecols=0)
    images = np.array([t for t, _, _ in list_images(folder / "cam1")])
    free = mocap[np.min(np.abs(mocap[:, None] - images[None]), axis=1) > 0.05]
    for t in free[np.linspace(0, len(free) - 1, 40).round().astype(int)]:
        cv2.imwrite(str(folder / "cam1" / f"{t:.6f}.png"), np.full((480, 640), 128, np.uint8))
    camera_into_bag(folder, "cam1")
    result = check_dataset(folder, sample=3, processes=1)
    assert result.ok, result.reasons
    c = result.cameras[1]
    assert (c.source, c.listed) == ("rosbag", 48) and 3 < c.sampled < 48
    assert 3 <= c.found == c.paired <= 8
    assert c.failures == (("target not detected", c.sampled - c.found),)
