"""A camera's ``intrinsics_images`` in a rig with several boards (rig.yaml ``targets:``,
issue 34) are searched for every board the camera may see, one view per (image, board)."""

import shutil

from multieye.io import load_rig
from multieye.pipeline.camera_data import load_camera_data
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset


def test_intrinsics_images_give_a_view_of_every_board(tmp_path):
    ds = tmp_path / "ds"
    render_wall_dataset(ds, WallSpec(n_instants=10, width=640, height=480), seed=1,
                             processes=2)
    shutil.copytree(ds / "cam1", ds / "cam1_lens")
    rig = (ds / "rig.yaml").read_text().replace(
        "cam1: {intrinsics: cam1.yaml,", "cam1: {intrinsics: cam1.yaml, "
        "refine_intrinsics: true, intrinsics_images: cam1_lens/,")
    (ds / "rig.yaml").write_text(rig)
    data = load_camera_data(load_rig(ds), processes=1)
    views = data["cam1"].intrinsics_views
    by_board = {}
    for v in views:
        by_board.setdefault(v.target, set()).add(v.name.split(" ")[0])
    # the recording's own views of cam1, by board: the same images, the same boards
    seen = {}
    for o in data["cam1"].observations:
        seen.setdefault(o.target, set()).add(f"cam1_lens/{o.name}")
    assert len(seen) >= 2, seen                      # the scenario shows cam1 several boards
    assert by_board == seen
