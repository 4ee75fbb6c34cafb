"""A bag's compressed image that cannot be decoded (a recording cut one message short, a
corrupt JPEG from a USB camera) is one bad image: left out with its reason, as an unreadable
image file is, not the whole topic refused (hostile-input pass, session 17); a PNG cut short
is named before libpng writes its own line on standard error."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.imaging.image_file import checked_bytes
from multieye.io.rosbag import iter_bag_images, sample_bag_images
from multieye.pipeline.frames import bag_frames, bag_listing
from rosbag_writer import BASE_NS, Bag

CUT = "unreadable message: the PNG stream is cut short (no IEND chunk)"


def _bag(tmp_path, rng, ros):
    path = tmp_path / ("run.bag" if ros == 1 else "run")
    images = rng.integers(0, 256, (4, 32, 40), dtype=np.uint8)
    with Bag(path, ros) as bag:
        for k, img in enumerate(images):
            data = cv2.imencode(".png", img)[1].tobytes()
            if k == 1:
                data = data[: len(data) // 2]
            if k == 2:
                data = data[:8] + bytes(40)
            bag.write("/c", bag.t("sensor_msgs/msg/CompressedImage")(
                header=bag.header(BASE_NS + k, "cam"), format="png",
                data=np.frombuffer(data, np.uint8).copy()), BASE_NS + k)
    return path, images


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_undecodable_messages_are_left_out_with_their_reason(tmp_path, rng, capfd, ros):
    path, images = _bag(tmp_path, rng, ros)
    lost: list = []
    got = list(iter_bag_images(path, "/c", lost=lost))
    assert [ns - BASE_NS for ns, _ in got] == [0, 3]
    assert np.array_equal(got[1][1], images[3])
    assert [ns - BASE_NS for ns, _ in lost] == [1, 2]
    assert lost[0][1] == CUT
    assert lost[1][1].startswith("unreadable message: the compressed image (format 'png') "
                                 "is not a PNG")
    stamps, lost = [], []
    assert [i for i, _, _ in sample_bag_images(path, "/c", [1, 3], stamps=stamps,
                                               lost=lost)] == [3]
    assert len(stamps) == 4 and [ns - BASE_NS for ns, _ in lost] == [1]
    with pytest.raises(DatasetError, match="topic /c at .* ns: the PNG stream is cut short"):
        list(iter_bag_images(path, "/c"))           # without a list for them: an error
    # the pipeline's frames: the good ones decoded, the bad ones named with their reason
    cam, stamped, lost = SimpleNamespace(rosbag=path, topic="/c"), [], []
    labels = [label for label, _ in bag_frames(cam, bag_listing(cam), stamped, lost)]
    assert labels == [f"/c@{BASE_NS}", f"/c@{BASE_NS + 3}"]
    assert lost[0] == (f"/c@{BASE_NS + 1}", CUT)
    assert "libpng" not in capfd.readouterr().err


def test_a_png_file_cut_short_is_named_before_decoding(tmp_path, rng):
    data = cv2.imencode(".png", rng.integers(0, 256, (32, 40), dtype=np.uint8))[1].tobytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) * 9 // 10])
    assert checked_bytes(tmp_path / "cut.png")[2] == ("unreadable file: the PNG stream is cut "
                                                      "short (no IEND chunk)")
    (tmp_path / "whole.png").write_bytes(data)
    assert checked_bytes(tmp_path / "whole.png")[2] is None


def test_the_dry_run_names_an_unreadable_sampled_message(tmp_path):
    """multieye check samples the topic as calibrate reads it: the corrupt message is one
    problem line naming it, the rest of the camera checked (refused before: exit 2)."""
    from multieye.pipeline.dry_run import check_dataset
    from rosbag_writer import camera_into_bag
    from small_dataset import render_small

    render_small(tmp_path / "ds")
    camera_into_bag(tmp_path / "ds", "cam1")         # mono8 messages, then one made corrupt
    path = tmp_path / "ds" / "run"
    moved = tmp_path / "raw"
    path.rename(moved)
    from rosbags.highlevel import AnyReader

    with AnyReader([moved]) as reader, Bag(path, 2) as bag:
        for k, (conn, rec, raw) in enumerate(reader.messages()):
            msg = reader.deserialize(raw, conn.msgtype)
            img = msg.data.reshape(msg.height, msg.step)
            data = cv2.imencode(".png", img)[1].tobytes()
            bag.write(conn.topic, bag.t("sensor_msgs/msg/CompressedImage")(
                header=msg.header, format="png",
                data=np.frombuffer(data[:100] if k == 2 else data, np.uint8).copy()), rec)
    result = check_dataset(tmp_path / "ds", processes=1)
    assert result.ok, result.reasons
    c = result.cameras[1]
    assert (c.source, c.listed, c.found) == ("rosbag", 8, 7)
    assert any(p.endswith(CUT) and p.startswith("/cam1/image_raw@") for p in c.problems)
