"""``multieye calibrate`` on image topics as other labs' bags hold them (hostile-input pass,
session 17), in a subprocess so that standard error is what a terminal shows (libpng and
FFmpeg write to it below Python): one corrupt compressed frame left out with its reason
(exit 0), a topic named without its leading slash read, two messages with one stamp refused
in one line naming the topic (exit 2, nothing written)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import cv2
import pytest

from multieye.io import list_images
from rosbag_writer import Bag
from small_dataset import render_small


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bag_inputs") / "ds"
    render_small(folder)
    return folder


def _bag_dataset(rendered, tmp_path, *, topic, duplicate=None, corrupt=()):
    """cam1's images as PNG CompressedImage messages of /cam1/image_raw/compressed; message
    ``duplicate`` stamped as the one before it, those in ``corrupt`` cut short."""
    ds = tmp_path / "ds"
    shutil.copytree(rendered, ds)
    with Bag(ds / "run.bag", 1) as bag:
        stamps = [ns for _, ns, _ in list_images(ds / "cam1")]
        for k, (_, ns, path) in enumerate(list_images(ds / "cam1")):
            data = cv2.imencode(".png", cv2.imread(str(path), cv2.IMREAD_GRAYSCALE))[1]
            data = data[: len(data) // 2] if k in corrupt else data
            msg = bag.t("sensor_msgs/msg/CompressedImage")(
                header=bag.header(stamps[k - 1] if k == duplicate else ns, "cam1"),
                format="mono8; png compressed ", data=data.reshape(-1))
            bag.write("/cam1/image_raw/compressed", msg, ns)
    shutil.rmtree(ds / "cam1")
    rig = ds / "rig.yaml"
    rig.write_text(rig.read_text().replace("    images: cam1/",
                                           f"    rosbag: run.bag\n    topic: {topic}"))
    return ds


def _calibrate(ds, out):
    return subprocess.run([sys.executable, "-m", "multieye", "calibrate", str(ds), "-o",
                           str(out), "--processes", "1"], capture_output=True, text=True,
                          timeout=300)


def test_a_corrupt_frame_is_left_out_and_a_relative_topic_read(rendered, tmp_path):
    ds = _bag_dataset(rendered, tmp_path, topic="cam1/image_raw/compressed", corrupt=(3,))
    done = _calibrate(ds, tmp_path / "out")
    assert done.returncode == 0, done.stderr
    assert "libpng" not in done.stderr and "Traceback" not in done.stderr
    text = (tmp_path / "out" / "calibration.json").read_text()
    assert "unreadable message: the PNG stream is cut short (no IEND chunk)" in text
    assert len(json.loads(text)["cameras"]) == 2


def test_two_messages_with_one_stamp_are_one_line_and_nothing_written(rendered, tmp_path):
    ds = _bag_dataset(rendered, tmp_path, topic="/cam1/image_raw/compressed", duplicate=5)
    done = _calibrate(ds, tmp_path / "out")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1
    assert "image topic /cam1/image_raw/compressed: two messages with the header stamp" in lines[0]
    assert not (tmp_path / "out").exists()

