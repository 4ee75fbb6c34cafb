"""ROS 2 bag as the source of both the images and the motion capture, no ROS install."""

from __future__ import annotations

import cv2
import numpy as np
from multieye.core.metrics import extrinsic_errors
from multieye.io import list_images, read_tum
from multieye.pipeline import calibrate
from multieye.sim.dataset import DatasetSpec, render_dataset

from rosbag_writer import Bag, image_msg


def test_bag_images_and_bag_mocap_give_the_folder_result(tmp_path):
    spec = DatasetSpec(n_cameras=2, images_per_camera=8, width=640, height=480,
                       camera_rate_hz=2.0, processes=1)
    truth = render_dataset(tmp_path / "ds", spec, seed=3)
    folder_run = calibrate(tmp_path / "ds", processes=1)

    bag_path = tmp_path / "ds" / "run"
    mocap = read_tum(tmp_path / "ds" / "mocap.txt")
    with Bag(bag_path, 2) as bag:
        for t, T in zip(mocap.stamps, mocap.T):
            ns = int(round(t * 1e9))
            msg = bag.t("geometry_msgs/msg/PoseStamped")(header=bag.header(ns, "world"),
                                                        pose=bag.pose(T))
            bag.write("/mocap/marker", msg, ns)
        for _stamp, ns, path in list_images(tmp_path / "ds" / "cam1"):
            img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
            bag.write("/cam1/image_raw", image_msg(bag, ns, img, "mono8"), ns)
    rig = (tmp_path / "ds" / "rig.yaml").read_text()
    rig = rig.replace("    images: cam1/", "    rosbag: run\n    topic: /cam1/image_raw")
    rig = rig.replace("  file: mocap.txt", "  file: run\n  format: rosbag\n  topic: /mocap/marker")
    (tmp_path / "ds" / "rig.yaml").write_text(rig)

    bag_run = calibrate(tmp_path / "ds", processes=2, select=None)   # frames to the workers
    assert bag_run.record.camera("cam1").measurements_used == truth.images_written[1]
    assert bag_run.cameras["cam1"].observations[0].name.startswith("/cam1/image_raw@")
    np.testing.assert_allclose(bag_run.closed_form.X, folder_run.closed_form.X, atol=1e-6)
    T = np.stack([c.T_ref_cam for c in bag_run.record.cameras])
    rot, trans = extrinsic_errors(T, truth.T_ref_cam)
    assert rot.max() < 0.1 and trans.max() < 3e-3

    # the image selection (issue 22): the bag's stamps read from the header bytes, only the
    # chosen messages decoded, the folder camera chosen the same way
    chosen = calibrate(tmp_path / "ds", processes=1, select=4)
    cam1 = chosen.cameras["cam1"]
    assert cam1.selection.stage == "before decoding" and cam1.selection.kept == 4
    assert cam1.selection.seen == truth.images_written[1] and len(cam1.observations) == 4
    assert all(o.name.startswith("/cam1/image_raw@") for o in cam1.observations)
    left = [r.item for r in cam1.rejected if r.reason.startswith("not selected")]
    assert len(left) == truth.images_written[1] - 4
    assert not {o.name for o in cam1.observations} & set(left)
