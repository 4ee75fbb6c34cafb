"""Several boards through the camera data (multieye.pipeline.boards): one Observation per
(image, board), the board's name in Observation.target, the same instant for both boards of
one image; several boards calibrated without motion capture."""

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from multieye.cli import main
from multieye.core import geometry as g
from multieye.core.errors import DatasetError
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.targets import target_from_spec
from multieye.io import load_rig, write_opencv_intrinsics
from multieye.pipeline.camera_data import load_camera_data
from multieye.sim.render import render_boards

SPEC = {"type": "charuco", "rows": 5, "cols": 7, "spacing": 0.05, "marker_size": 0.0375,
        "dictionary": "DICT_4X4_100"}
CAM = Intrinsics(K=[[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], dist=np.zeros(5),
                 width=640, height=480)
LEFT = g.transform_from_rotvec([0.1, 0.25, 0.0], [-0.42, -0.08, 1.2])
RIGHT = g.transform_from_rotvec([-0.05, -0.3, 0.05], [0.1, -0.1, 1.25])
TARGETS = """targets:
  - {name: left, type: charuco, rows: 5, cols: 7, spacing: 0.05, marker_size: 0.0375, dictionary: DICT_4X4_100}
  - {name: right, type: charuco, rows: 5, cols: 7, spacing: 0.05, marker_size: 0.0375,
     dictionary: DICT_4X4_100, first_id: 20}
  - {name: far, type: charuco, rows: 5, cols: 7, spacing: 0.05, marker_size: 0.0375,
     dictionary: DICT_4X4_100, first_id: 40}
"""


@pytest.fixture
def dataset(tmp_path):
    """cam0: 1.png shows left and right, 2.png right only, 3.png nothing."""
    left, right = target_from_spec(SPEC), target_from_spec({**SPEC, "first_id": 20})
    (tmp_path / "cam0").mkdir()
    scenes = {"1": [(left, LEFT), (right, RIGHT)], "2": [(right, RIGHT)], "3": []}
    for k, (stem, boards) in enumerate(scenes.items()):
        img = render_boards(boards, CAM, rng=np.random.default_rng(k), blur_sigma=0.7)
        cv2.imwrite(str(tmp_path / "cam0" / f"{stem}.png"), img)
    write_opencv_intrinsics(tmp_path / "cam0.yaml", CAM)
    (tmp_path / "rig.yaml").write_text(TARGETS + "cameras:\n  cam0: {intrinsics: cam0.yaml, "
                                       "images: cam0/}\n")
    return tmp_path


def test_one_observation_per_image_and_board(dataset):
    data = load_camera_data(load_rig(dataset), processes=1)["cam0"]
    seen = [(o.name, o.target, o.instant) for o in data.observations]
    assert seen == [("1.png", "left", "1.0"), ("1.png", "right", "1.0"), ("2.png", "right", "2.0")]
    assert data.n_inputs == 3
    assert [(r.item, r.reason) for r in data.rejected] == [
        ("3.png", "target not detected (charuco 5x7 left, charuco 5x7 right, charuco 5x7 far)")]
    poses = {(o.name, o.target): o.T_cam_target for o in data.observations}
    for key, true in {("1.png", "left"): LEFT, ("1.png", "right"): RIGHT,
                      ("2.png", "right"): RIGHT}.items():
        assert np.linalg.norm(poses[key][:3, 3] - true[:3, 3]) < 0.01, key


def test_one_target_keeps_its_name_target(dataset):
    (dataset / "rig.yaml").write_text("target: {type: charuco, rows: 5, cols: 7, spacing: 0.05, "
                                      "marker_size: 0.0375, dictionary: DICT_4X4_100}\n"
                                      "cameras:\n  cam0: {intrinsics: cam0.yaml, images: cam0/}\n")
    data = load_camera_data(load_rig(dataset), processes=1)["cam0"]
    assert [(o.name, o.target) for o in data.observations] == [("1.png", "target")]


def test_a_camera_no_board_is_for(dataset):
    text = TARGETS.replace("first_id: 40}", "first_id: 40, cameras: [cam1]}")
    text = text.replace("DICT_4X4_100}", "DICT_4X4_100, cameras: [cam1]}")
    text = text.replace("first_id: 20}", "first_id: 20, cameras: [cam1]}")
    (dataset / "cam1").mkdir()
    for f in (dataset / "cam0").iterdir():     # copies: two cameras never read one file
        (dataset / "cam1" / f.name).write_bytes(f.read_bytes())
    (dataset / "rig.yaml").write_text(text + "cameras:\n  cam0: {intrinsics: cam0.yaml, images: "
                                      "cam0/}\n  cam1: {intrinsics: cam0.yaml, images: cam1/}\n")
    with pytest.raises(DatasetError, match="no target of rig.yaml is seen by this camera") as e:
        load_camera_data(load_rig(dataset), processes=1)
    assert e.value.camera == "cam0"


def test_several_boards_without_motion_capture_are_calibrated_with_their_poses(dataset,
                                                                               tmp_path):
    """(Refused until their estimation landed: issue 34.)  The boards seen get their poses in
    the first one's frame; the board no image shows is not stated."""
    import json

    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["calibrate", str(dataset), "-o", str(out), "--processes",
                                    "1"])
    assert res.exit_code == 0, (res.stdout, res.stderr)
    rec = json.loads((out / "calibration.json").read_text())
    assert rec["method"] == "motion-links" and list(rec["targets"]) == ["left", "right"]
    T = np.array(rec["targets"]["right"]["T_world_target"])
    true = g.inv(LEFT) @ RIGHT
    assert np.linalg.norm(T[:3, 3] - true[:3, 3]) < 0.01
    assert rec["targets"]["right"]["cameras"] == {"cam0": 2}
