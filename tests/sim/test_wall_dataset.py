"""The rendered wall-board rig (multieye.sim.wall_dataset): it loads as a rig without motion
capture whose cameras see boards in most instants, each view under the board it truly shows."""

import json

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.lens import project_points
from multieye.io import load_rig
from multieye.pipeline.camera_data import load_camera_data
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset


def _check_identities(ds, data) -> dict:
    """Every observation's pixels are its board's points at the board's true pose (a view
    taken for another board would be off by hundreds of pixels); per camera, the share of
    instants with at least one board."""
    truth = json.loads((ds / "ground_truth.json").read_text())
    n = len(truth["frames"])
    share = {}
    for cam, d in data.items():
        for o in d.observations:
            i = int(o.name.removesuffix(".png"))
            T = g.inv(np.array(truth["T_world_ref"][i]) @ np.array(truth["T_ref_cam"][cam])) \
                @ np.array(truth["T_world_board"][o.target])
            uv = project_points(o.object_points @ T[:3, :3].T + T[:3, 3], d.intrinsics)
            assert np.abs(uv - o.image_points).max() < 1.0, (cam, o.name, o.target)
            assert o.instant == repr(float(i))
        share[cam] = len({o.name for o in d.observations}) / n
    return share


def test_charuco_walls_render_and_each_camera_sees_a_board_in_most_instants(tmp_path):
    sc = render_wall_dataset(tmp_path, WallSpec(n_instants=8), seed=0)
    rig = load_rig(tmp_path)
    assert not rig.has_mocap and list(rig.targets) == ["north", "west", "south"]
    assert [t.first_id for t in rig.targets.values()] == [0, 32, 64]
    data = load_camera_data(rig, processes=1)
    share = _check_identities(tmp_path, data)
    assert min(share.values()) >= 0.5, share
    # every camera sees more than one board over the recording (what links the rig)
    assert all(len({o.target for o in d.observations}) >= 2 for d in data.values())
    # the detections find most views the geometry predicts
    found = {(o.name, cam, o.target) for cam, d in data.items() for o in d.observations}
    predicted = {(f"{v.instant:06d}.png", sc.cameras[v.camera], v.target) for v in sc.views}
    assert len(found & predicted) >= 0.85 * len(predicted)


def test_chessboard_walls_each_board_seen_by_its_camera(tmp_path):
    render_wall_dataset(tmp_path, WallSpec(n_instants=4, boards="chessboard", motion="planar"),
                        seed=1)
    rig = load_rig(tmp_path)
    assert {n: t.cameras for n, t in rig.targets.items()} == {
        "north": ("cam0",), "west": ("cam1",), "south": ("cam2",), "east": ("cam3",)}
    data = load_camera_data(rig, processes=1)
    share = _check_identities(tmp_path, data)
    assert min(share.values()) >= 0.75, share
    assert {cam: {o.target for o in d.observations} for cam, d in data.items()} == {
        "cam0": {"north"}, "cam1": {"west"}, "cam2": {"south"}, "cam3": {"east"}}


@pytest.mark.parametrize("mocap", [False, True])
def test_rig_yaml_with_and_without_motion_capture(tmp_path, mocap):
    from multieye.sim.wall_boards import simulate_walls
    from multieye.sim.wall_dataset import wall_rig_yaml
    sc = simulate_walls(np.random.default_rng(0), WallSpec(n_instants=3))
    for cam in sc.cameras:
        (tmp_path / cam).mkdir()
        (tmp_path / f"{cam}.yaml").write_text(
            "camera_model: pinhole\nintrinsics: [400, 400, 399.5, 299.5]\n"
            "distortion_model: radtan\ndistortion_coeffs: [0, 0, 0, 0]\nresolution: [800, 600]\n")
    (tmp_path / "mocap.txt").write_text("0 0 0 0 0 0 0 1\n")
    (tmp_path / "rig.yaml").write_text(wall_rig_yaml(sc, mocap=mocap))
    rig = load_rig(tmp_path)
    assert rig.has_mocap == mocap and len(rig.targets) == 3
    assert rig.setup == "eye-on-hand" or not mocap
