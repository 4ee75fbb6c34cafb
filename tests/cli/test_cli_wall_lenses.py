"""multieye calibrate on a rendered rig linked by its motion before three boards on the walls,
every camera's lens estimated (``model:`` without ``intrinsics:``, issue 34): each camera's
views of different boards start its lens together (some of them a single column of ChArUco
corners, on one line), and the calibration recovers the rig and the lenses."""

import json

import numpy as np
from click.testing import CliRunner

from multieye.cli import main
from multieye.core.lie import log_so3
from multieye.io import read_opencv_intrinsics
from multieye.sim.wall_boards import WallSpec
from multieye.sim.wall_dataset import render_wall_dataset


def test_lenses_estimated_from_several_boards_recover_the_rig(tmp_path):
    ds = tmp_path / "ds"
    render_wall_dataset(ds, WallSpec(n_instants=24, width=640, height=480), seed=0,
                        processes=2)
    rig = (ds / "rig.yaml").read_text()
    for j in range(4):
        rig = rig.replace(f"intrinsics: cam{j}.yaml", "model: pinhole-radtan")
    (ds / "rig.yaml").write_text(rig)
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(tmp_path / "out"),
                                    "--processes", "2"])
    assert res.exit_code == 0, (res.stdout, res.stderr)
    truth = json.loads((ds / "ground_truth.json").read_text())
    rec = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert rec["method"] == "motion-links"
    for name, cam in rec["cameras"].items():
        assert cam["intrinsics"]["estimated"]
        true_lens = read_opencv_intrinsics(ds / f"{name}.yaml")
        K, true_K = np.array(cam["intrinsics"]["K"]), true_lens.K
        got = K[[0, 1, 0, 1], [0, 1, 2, 2]]
        want = true_K[[0, 1, 0, 1], [0, 1, 2, 2]]
        sigma = np.sqrt(np.diag(np.array(cam["intrinsics"]["covariance"]))[:4])
        assert np.all(np.abs(got - want) < 4 * sigma + 1e-9), (name, got, want, sigma)
        assert np.all(np.abs(got - want) < 2.0), (name, got, want)           # pixels
        if name == "cam0":
            continue
        T, true = np.array(cam["T_ref_cam"]), np.array(truth["T_ref_cam"][name])
        e = np.concatenate([log_so3(T[:3, :3] @ true[:3, :3].T), T[:3, 3] - true[:3, 3]])
        s = np.sqrt(np.diag(np.array(cam["covariance"])))
        assert np.all(np.abs(e) < 4 * s), (name, e / s)
