"""ROS 1 and ROS 2 bags written with rosbags' writers and read back through multieye.io."""

from __future__ import annotations

import struct

import cv2
import numpy as np
import pytest
from multieye.core import geometry
from multieye.core.errors import DatasetError
from multieye.io.mocap import MocapSpec, read_mocap, sniff_mocap_format
from multieye.io.rosbag import (bag_image_count, bag_topics, iter_bag_images,
                                read_bag_trajectory, sample_bag_images)

from rosbag_writer import BASE_NS, Bag, image_msg


def _bag_path(tmp_path, ros):
    return tmp_path / ("run.bag" if ros == 1 else "run")


@pytest.fixture(params=[1, 2], ids=["ros1", "ros2"])
def pose_bag(request, tmp_path, rng):
    """A bag with every pose topic type; returns (path, stamps_ns, T_world_rig, T_world_other)."""
    ros = request.param
    path = _bag_path(tmp_path, ros)
    n = 5
    stamps = BASE_NS + np.arange(n, dtype=np.int64) * 10_000_001
    T = geometry.random_transforms(rng, n)
    T_other = geometry.random_transforms(rng, n)
    with Bag(path, ros) as bag:
        cov = np.zeros(36)
        twist = bag.t("geometry_msgs/msg/TwistWithCovariance")(
            twist=bag.t("geometry_msgs/msg/Twist")(
                linear=bag.t("geometry_msgs/msg/Vector3")(x=0, y=0, z=0),
                angular=bag.t("geometry_msgs/msg/Vector3")(x=0, y=0, z=0)), covariance=cov)
        for i in reversed(range(n)):  # out of order in the bag: the reader sorts by stamp
            ns = int(stamps[i])
            rec = ns + 3_000_000
            bag.write("/vicon/rig/pose", bag.t("geometry_msgs/msg/PoseStamped")(
                header=bag.header(ns, "/world"), pose=bag.pose(T[i])), rec)
            bag.write("/rig/transform", bag.transform_stamped(ns, "world", "rig", T[i]), rec)
            bag.write("/tf", bag.t("tf2_msgs/msg/TFMessage")(transforms=[
                bag.transform_stamped(ns, "world", "rig", T[i]),
                bag.transform_stamped(ns, "world", "other", T_other[i])]), rec)
            bag.write("/rig/pose_cov", bag.t("geometry_msgs/msg/PoseWithCovarianceStamped")(
                header=bag.header(ns, "world"), pose=bag.t(
                    "geometry_msgs/msg/PoseWithCovariance")(pose=bag.pose(T[i]),
                                                            covariance=cov)), rec)
            bag.write("/odom", bag.t("nav_msgs/msg/Odometry")(
                header=bag.header(ns, "world"), child_frame_id="rig",
                pose=bag.t("geometry_msgs/msg/PoseWithCovariance")(pose=bag.pose(T[i]),
                                                                  covariance=cov),
                twist=twist), rec)
    return path, stamps, T, T_other


@pytest.mark.parametrize("topic, frames", [
    ("/vicon/rig/pose", {}),
    ("/rig/transform", {}),
    ("/rig/pose_cov", {}),
    ("/odom", {"child_frame": "rig"}),
    ("/tf", {"parent_frame": "world", "child_frame": "/rig"}),
])
def test_pose_topics_round_trip(pose_bag, topic, frames):
    path, stamps, T, _ = pose_bag
    traj = read_bag_trajectory(path, topic, parent="world", child="body", **frames)
    assert traj.name == "T_world_body"
    assert np.array_equal(traj.stamps_ns, stamps)
    assert np.abs(traj.T - T).max() < 1e-12


def test_tf_picks_the_requested_pair_and_lists_pairs(pose_bag):
    path, stamps, _, T_other = pose_bag
    traj = read_bag_trajectory(path, "/tf", child_frame="other")
    assert np.abs(traj.T - T_other).max() < 1e-12
    with pytest.raises(DatasetError, match=r"several transforms \(world -> other, world -> rig\)"):
        read_bag_trajectory(path, "/tf")
    with pytest.raises(DatasetError, match="no sample with parent frame 'map'"):
        read_bag_trajectory(path, "/tf", parent_frame="map")


def test_missing_topic_lists_topics_present(pose_bag):
    path = pose_bag[0]
    with pytest.raises(DatasetError) as info:
        read_bag_trajectory(path, "/mocap")
    msg = str(info.value)
    assert "topic '/mocap' not in the bag; topics present: /odom (nav_msgs/Odometry)" in msg
    assert "/vicon/rig/pose (geometry_msgs/PoseStamped)" in msg
    assert bag_topics(path)["/tf"] == "tf2_msgs/TFMessage"


def test_read_mocap_from_bag(pose_bag):
    path, stamps, T, _ = pose_bag
    assert sniff_mocap_format(path) == "rosbag"
    traj = read_mocap(MocapSpec(path, pose="T_world_marker", format="rosbag",
                                topic="/vicon/rig/pose"))
    assert traj.name == "T_world_marker" and np.abs(traj.T - T).max() < 1e-12


def test_duplicate_stamps_and_bad_quaternions_are_errors(tmp_path):
    path = tmp_path / "dup.bag"
    with Bag(path, 1) as bag:
        for k in range(2):
            bag.write("/p", bag.t("geometry_msgs/msg/PoseStamped")(
                header=bag.header(BASE_NS, "world"), pose=bag.pose(np.eye(4))), BASE_NS + k)
        T = np.eye(4)
        msg = bag.t("geometry_msgs/msg/PoseStamped")(header=bag.header(BASE_NS, "w"),
                                                     pose=bag.pose(T))
        msg.pose.orientation.w = 2.0
        bag.write("/q", msg, BASE_NS)
    with pytest.raises(DatasetError, match="topic /p: duplicate time stamp"):
        read_bag_trajectory(path, "/p")
    with pytest.raises(DatasetError, match="topic /q: sample 0: quaternion .* got norm 2"):
        read_bag_trajectory(path, "/q")
    with pytest.raises(DatasetError, match="bag not found"):
        read_bag_trajectory(tmp_path / "none.bag", "/p")
    (tmp_path / "junk.bag").write_bytes(b"not a bag at all")
    with pytest.raises(DatasetError, match="cannot read the bag"):
        read_bag_trajectory(tmp_path / "junk.bag", "/p")


def test_non_finite_bag_samples_are_left_out(tmp_path):
    path = tmp_path / "nan.bag"
    with Bag(path, 1) as bag:
        for k in range(3):
            T = np.eye(4)
            T[0, 3] = np.nan if k == 1 else k
            stamp = BASE_NS + k * 10_000_000
            bag.write("/p", bag.t("geometry_msgs/msg/PoseStamped")(
                header=bag.header(stamp, "world"), pose=bag.pose(T)), stamp)
    traj = read_bag_trajectory(path, "/p")
    assert traj.stamps_ns.tolist() == [BASE_NS, BASE_NS + 20_000_000]
    assert [(s.where, s.reason, s.line) for s in traj.skipped] == [
        (f"/p@{BASE_NS + 10_000_000}", "not a finite number: x = nan", None)]


# --------------------------------------------------------------------------- images


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_image_topics_decode(tmp_path, rng, ros):
    path = _bag_path(tmp_path, ros)
    bgr = rng.integers(0, 256, (6, 8, 3), dtype=np.uint8)
    grey16 = rng.integers(0, 65536, (6, 8), dtype=np.uint16)
    ok, png = cv2.imencode(".png", bgr)
    with Bag(path, ros) as bag:
        bag.write("/cam/raw", image_msg(bag, BASE_NS, bgr[..., 0], "mono8"), BASE_NS)
        bag.write("/cam/raw", image_msg(bag, BASE_NS + 1, bgr[..., ::-1], "rgb8", pad=3),
                  BASE_NS + 1)
        bag.write("/cam/raw", image_msg(bag, BASE_NS + 2, grey16, "mono16", bigendian=True),
                  BASE_NS + 2)
        bag.write("/cam/raw", image_msg(bag, BASE_NS + 3, bgr, "bgr8"), BASE_NS + 3)
        bag.write("/cam/compressed", bag.t("sensor_msgs/msg/CompressedImage")(
            header=bag.header(0, "cam"), format="png", data=png.reshape(-1)), BASE_NS + 9)
        bag.write("/cam/weird", image_msg(bag, BASE_NS, bgr, "bayer_rggb16"), BASE_NS)
    images = list(iter_bag_images(path, "/cam/raw"))
    assert [s for s, _ in images] == [BASE_NS, BASE_NS + 1, BASE_NS + 2, BASE_NS + 3]
    assert np.array_equal(images[0][1], bgr[..., 0])
    assert np.array_equal(images[1][1], bgr)  # rgb8 -> BGR, row padding dropped
    assert images[2][1].dtype == np.uint16 and np.array_equal(images[2][1], grey16)
    assert np.array_equal(images[3][1], bgr)
    (stamp, decoded), = iter_bag_images(path, "/cam/compressed")
    assert stamp == BASE_NS + 9  # zero header stamp -> record time
    assert np.array_equal(decoded, bgr)
    with pytest.raises(DatasetError, match="image encoding 'bayer_rggb16' is not supported.*"
                                           "republish the topic"):
        list(iter_bag_images(path, "/cam/weird"))
    with pytest.raises(DatasetError, match="has type sensor_msgs/Image; expected one of"):
        read_bag_trajectory(path, "/cam/raw")


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_sample_decodes_only_the_chosen_messages_with_every_stamp(tmp_path, rng, ros):
    path = _bag_path(tmp_path, ros)
    imgs = rng.integers(0, 256, (7, 4, 5), dtype=np.uint8)
    header_ns = [BASE_NS + 3 * k + (k * 999_999_937 if k % 2 else 0) for k in range(7)]
    header_ns[4] = 0                   # never filled: the record time stands in
    with Bag(path, ros) as bag:
        for k, img in enumerate(imgs):
            bag.write("/cam/raw", image_msg(bag, header_ns[k], img, "mono8"), BASE_NS + 10 * k)
            _, png = cv2.imencode(".png", img)
            bag.write("/cam/png", bag.t("sensor_msgs/msg/CompressedImage")(
                header=bag.header(header_ns[k], "cam"), format="png", data=png.reshape(-1)),
                BASE_NS + 10 * k)
    for topic in ("/cam/raw", "/cam/png"):
        every = list(iter_bag_images(path, topic))
        assert bag_image_count(path, topic) == 7
        stamps = []
        picked = list(sample_bag_images(path, topic, [6, 0, 3], stamps=stamps))
        assert stamps == [s for s, _ in every] and stamps[4] == BASE_NS + 40
        assert [i for i, _, _ in picked] == [0, 3, 6]
        for i, stamp, img in picked:
            assert stamp == every[i][0] and np.array_equal(img, imgs[i])
        # without stamps asked for, reading stops after the last wanted message
        assert [i for i, _, _ in sample_bag_images(path, topic, [1, 2])] == [1, 2]
        assert list(sample_bag_images(path, topic, [])) == []
    with pytest.raises(DatasetError, match="not in the bag"):
        list(sample_bag_images(path, "/cam/none", [0]))


def test_bayer_rggb_demosaics_to_the_right_colours(tmp_path):
    # A flat colour image, mosaicked with the ROS rggb layout (R at (0,0), B at (1,1)).
    bgr = np.empty((8, 8, 3), np.uint8)
    bgr[:] = (30, 120, 220)  # B, G, R
    mosaic = np.empty((8, 8), np.uint8)
    mosaic[0::2, 0::2] = bgr[0::2, 0::2, 2]
    mosaic[0::2, 1::2] = bgr[0::2, 1::2, 1]
    mosaic[1::2, 0::2] = bgr[1::2, 0::2, 1]
    mosaic[1::2, 1::2] = bgr[1::2, 1::2, 0]
    path = tmp_path / "bayer.bag"
    with Bag(path, 1) as bag:
        bag.write("/cam", image_msg(bag, BASE_NS, mosaic, "bayer_rggb8"), BASE_NS)
    (_, img), = iter_bag_images(path, "/cam")
    assert img.shape == (8, 8, 3)
    assert np.abs(img[2:-2, 2:-2].astype(int) - [30, 120, 220]).max() <= 1


def _exif_orientation(jpeg: bytes, orientation: int) -> bytes:
    """A JPEG with an APP1 Exif segment holding one IFD entry: Orientation (0x0112)."""
    tiff = b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", 1) + struct.pack(
        "<HHIHH", 0x0112, 3, 1, orientation, 0) + struct.pack("<I", 0)
    body = b"Exif\x00\x00" + tiff
    return jpeg[:2] + b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body + jpeg[2:]


def _compressed(bag, data, fmt):
    return bag.t("sensor_msgs/msg/CompressedImage")(
        header=bag.header(0, "cam"), format=fmt, data=np.frombuffer(data, np.uint8))


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_image_sizes_checked_before_decoding(tmp_path, rng, ros, monkeypatch):
    path = _bag_path(tmp_path, ros)
    img = rng.integers(0, 256, (6, 8), dtype=np.uint8)
    _, png = cv2.imencode(".png", img)
    huge_png = bytearray(png.tobytes())
    huge_png[16:24] = struct.pack(">II", 60000, 60000)        # IHDR width, height
    with Bag(path, ros) as bag:
        bag.write("/raw/huge", bag.t("sensor_msgs/msg/Image")(
            header=bag.header(0, "cam"), height=60000, width=60000, encoding="mono8",
            is_bigendian=0, step=60000, data=img.reshape(-1)), BASE_NS)
        bag.write("/raw/empty", bag.t("sensor_msgs/msg/Image")(
            header=bag.header(0, "cam"), height=0, width=8, encoding="mono8",
            is_bigendian=0, step=8, data=img.reshape(-1)), BASE_NS)
        bag.write("/png/huge", _compressed(bag, bytes(huge_png), "png"), BASE_NS)
        bag.write("/png/garbage", _compressed(bag, b"not an image at all", "png"), BASE_NS)

    def never(*args, **kwargs):
        raise AssertionError("decoded before the size was checked")

    monkeypatch.setattr(cv2, "imdecode", never)
    where = rf"topic /raw/huge at {BASE_NS} ns: the message states 60000 x 60000 pixels, more "
    with pytest.raises(DatasetError, match=where + r"than the 100 megapixels"):
        list(iter_bag_images(path, "/raw/huge"))
    with pytest.raises(DatasetError, match=r"the message states 8 x 0 pixels"):
        list(iter_bag_images(path, "/raw/empty"))
    with pytest.raises(DatasetError, match=r"/png/huge at .* ns: the PNG header states 60000 x "
                                           r"60000 pixels, more than the 100 megapixels"):
        list(iter_bag_images(path, "/png/huge"))
    with pytest.raises(DatasetError, match=r"the compressed image \(format 'png'\) is not a "
                                           r"PNG, JPEG, .* stream"):
        list(sample_bag_images(path, "/png/garbage", [0]))


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_exif_orientation_of_compressed_images_ignored(tmp_path, ros):
    path = _bag_path(tmp_path, ros)
    img = np.zeros((48, 64), np.uint8)
    img[:16, :16] = 255                                       # a bright top-left corner
    _, jpg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 100])
    rotated = _exif_orientation(jpg.tobytes(), 3)             # "rotate 180 deg to view"
    # OpenCV's default decoding applies the orientation: the corner moves
    shown = cv2.imdecode(np.frombuffer(rotated, np.uint8), cv2.IMREAD_GRAYSCALE)
    assert shown[-8:, -8:].mean() > 200 and shown[:8, :8].mean() < 50
    with Bag(path, ros) as bag:
        bag.write("/cam/jpeg", _compressed(bag, rotated, "jpeg"), BASE_NS)
    (_, decoded), = iter_bag_images(path, "/cam/jpeg")
    assert decoded.shape == (48, 64)
    assert decoded[:8, :8].mean() > 200 and decoded[-8:, -8:].mean() < 50   # as stored


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
def test_yuv422_images_decode_with_their_luma(tmp_path, ros):
    """ROS's ``yuv422`` (UYVY) and ``yuv422_yuy2`` (YUYV) cameras (usb_cam's defaults):
    decoded with the luma taken from the right bytes (refused before as unsupported)."""
    path = _bag_path(tmp_path, ros)
    luma = np.arange(6 * 8, dtype=np.uint8).reshape(6, 8) * 5 + 10
    chroma = np.full_like(luma, 128)
    uyvy = np.stack([chroma, luma], axis=-1)      # U Y V Y ...: chroma byte first
    yuyv = np.stack([luma, chroma], axis=-1)
    with Bag(path, ros) as bag:
        for k, (enc, pixels) in enumerate((("yuv422", uyvy), ("yuv422_yuy2", yuyv))):
            bag.write("/cam", image_msg(bag, BASE_NS + k, pixels, enc), BASE_NS + k)
    (_, a), (_, b) = iter_bag_images(path, "/cam")
    assert a.shape == (6, 8, 3) and np.array_equal(a, b)
    assert np.corrcoef(a[..., 1].ravel(), luma.ravel())[0, 1] > 0.999


def test_bag_files_that_cannot_be_read_say_what_to_do(tmp_path, rng):
    """A ROS 2 .mcap (or .db3) copied without its metadata.yaml, and a ROS 1 bag cut short:
    one line each naming the tool that repairs it (before: 'Expected metadata file <folder>
    does not exist', 'Bag index looks damaged' alone)."""
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    bag = Bag(tmp_path / "rec", 2)
    bag.writer = Writer2(tmp_path / "rec", version=9, storage_plugin=StoragePlugin.MCAP)
    img = rng.integers(0, 256, (4, 6), dtype=np.uint8)
    with bag:
        bag.write("/cam", image_msg(bag, BASE_NS, img, "mono8"), BASE_NS)
    (stamp, got), = iter_bag_images(tmp_path / "rec" / "rec.mcap", "/cam")
    assert np.array_equal(got, img)
    lone = tmp_path / "lone.mcap"
    lone.write_bytes((tmp_path / "rec" / "rec.mcap").read_bytes())
    with pytest.raises(DatasetError, match=r"lone.mcap: a ROS 2 bag's .mcap file is read with "
                                           r"the metadata.yaml .* 'ros2 bag reindex <folder>' "
                                           r"-s mcap"):
        list(iter_bag_images(lone, "/cam"))
    with Bag(tmp_path / "one.bag", 1) as bag1:
        bag1.write("/cam", image_msg(bag1, BASE_NS, img, "mono8"), BASE_NS)
    data = (tmp_path / "one.bag").read_bytes()
    (tmp_path / "cut.bag").write_bytes(data[: len(data) // 2])
    with pytest.raises(DatasetError, match=r"cut.bag: cannot read the bag: .*repaired by "
                                           r"'rosbag reindex'"):
        list(iter_bag_images(tmp_path / "cut.bag", "/cam"))
