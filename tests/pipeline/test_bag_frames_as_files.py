"""A bag's image messages as the pipeline reads them give the grey pixels the same bytes or
the same pixels give as image files (hostile-input pass, session 17): a colour JPEG's grey is
its decoder's luma, as for a file, not a conversion of its BGR decoding; 16-bit pixels are
scaled to 8 bits with one rounding for both sources."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from multieye.imaging.detect import to_gray
from multieye.imaging.image_file import decode_gray
from multieye.pipeline.frames import bag_frames, bag_listing
from rosbag_writer import BASE_NS, Bag, image_msg


def _colour_image(rng):
    """A smooth colour picture with noise (JPEG's luma and BGR->grey differ on it)."""
    y, x = np.mgrid[0:96, 0:128]
    base = np.stack([x * 2, y * 2, (x + y)], axis=-1).astype(np.float64)
    return np.clip(base + rng.normal(0, 20, base.shape), 0, 255).astype(np.uint8)


def _compressed(bag, ns, data, fmt):
    return bag.t("sensor_msgs/msg/CompressedImage")(
        header=bag.header(ns, "cam"), format=fmt, data=np.frombuffer(data, np.uint8).copy())


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_bag_frames_are_the_grey_pixels_of_the_same_files(tmp_path, rng, ros):
    colour = _colour_image(rng)
    grey16 = rng.integers(0, 4096, (96, 128), dtype=np.uint16)   # 12 bits in 16
    jpeg = cv2.imencode(".jpg", colour, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()
    png16 = cv2.imencode(".png", grey16)[1].tobytes()
    png = cv2.imencode(".png", colour)[1].tobytes()
    files = [jpeg, png16, png16, png]
    path = tmp_path / ("run.bag" if ros == 1 else "run")
    with Bag(path, ros) as bag:
        bag.write("/c", _compressed(bag, BASE_NS, jpeg, "bgr8; jpeg compressed bgr8"), BASE_NS)
        bag.write("/c", _compressed(bag, BASE_NS + 1, png16, "mono16; png compressed mono16"),
                  BASE_NS + 1)
        bag.write("/r", image_msg(bag, BASE_NS + 2, grey16, "mono16", pad=4), BASE_NS + 2)
        bag.write("/c", _compressed(bag, BASE_NS + 3, png, "png"), BASE_NS + 3)
    got = []
    for topic in ("/c", "/r"):
        cam = SimpleNamespace(rosbag=path, topic=topic)
        got += [(int(label.split("@")[1]), to_gray(img))
                for label, img in bag_frames(cam, bag_listing(cam), [], [])]
    got.sort(key=lambda item: item[0])
    assert [ns - BASE_NS for ns, _ in got] == [0, 1, 2, 3]
    for k, ((_, image), data) in enumerate(zip(got, files)):
        expected, reason = decode_gray(data)
        assert reason is None
        assert image.dtype == np.uint8 and image.shape == expected.shape
        assert np.array_equal(image, expected), (k, np.abs(image.astype(int) - expected).max())
