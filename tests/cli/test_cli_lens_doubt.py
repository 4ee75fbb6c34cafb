"""Issue 33, item 4, end to end without motion capture: a rendered overlap rig whose camera
cam1 is given its camera matrix without the distortion (k1 -0.17) in a ROS CameraInfo file
(``D: []``) exits 3 naming cam1, the missing distortion, the pose residuals before and after
and how to estimate the lens (before: exit 0, cam1 8 mm from the truth with a sigma of
0.4 mm); the same rig with every lens as rendered exits 0 without doubt."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from multieye.cli import main
from multieye.io.intrinsics_files import read_intrinsics
from multieye.sim.overlap import OverlapSpec, render_overlap_dataset


@pytest.fixture(scope="module")
def rig(tmp_path_factory) -> Path:
    ds = tmp_path_factory.mktemp("lens_doubt") / "ds"
    render_overlap_dataset(ds, OverlapSpec(n_instants=12, width=640, height=480, fisheye=()),
                           seed=0)
    return ds


def _calibrate(ds: Path, out: Path):
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1",
                                    "--no-report"])
    return res, json.loads((out / "calibration.json").read_text())


def test_the_rendered_lenses_raise_no_doubt(rig, tmp_path):
    res, cal = _calibrate(rig, tmp_path / "out")
    assert res.exit_code == 0, res.output
    assert cal["plausibility"] == []


def test_camera_info_without_distortion_is_named(rig, tmp_path):
    intr = read_intrinsics(rig / "cam1.yaml")
    assert intr.dist[0] < -0.1
    K = intr.K
    (rig / "cam1_info.yaml").write_text(
        f"height: 480\nwidth: 640\ndistortion_model: plumb_bob\nD: []\n"
        f"K: [{K[0, 0]}, 0, {K[0, 2]}, 0, {K[1, 1]}, {K[1, 2]}, 0, 0, 1]\n"
        "R: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
        f"P: [{K[0, 0]}, 0, {K[0, 2]}, 0, 0, {K[1, 1]}, {K[1, 2]}, 0, 0, 0, 1, 0]\n")
    text = (rig / "rig.yaml").read_text()
    (rig / "rig_info.yaml").write_text(text.replace("intrinsics: cam1.yaml",
                                                    "intrinsics: cam1_info.yaml"))
    res, cal = _calibrate(rig / "rig_info.yaml", tmp_path / "out")
    assert res.exit_code == 3, res.output
    doubts = cal["plausibility"]
    assert [(d["cause"], d["camera"]) for d in doubts if d["cause"] == "intrinsics"] == [
        ("intrinsics", "cam1")], doubts
    m = next(d["message"] for d in doubts if d["cause"] == "intrinsics")
    for w in ("left out of the intrinsics file", "distortion none -> k1",
              "mean pose residual against the rig", "model: instead of intrinsics:"):
        assert w in m, m
    assert "intrinsics: camera cam1's lens freed" in res.output


def test_fisheye_in_basalt_json_without_distortion_is_named(tmp_path):
    """The rig's fisheye camera (k1 0.05) given as Basalt's kb4 with k1..k4 zero: its PnP
    poses absorb the distortion (RMS 0.096 -> 0.095 px with k1, k2 freed) while its pose
    residuals against the rig halve (0.23 -> 0.11 deg, 5.2 -> 2.4 mm): exit 3 naming cam2
    (before: exit 0)."""
    ds = tmp_path / "ds"
    render_overlap_dataset(ds, OverlapSpec(n_instants=14, width=640, height=480), seed=0)
    intr = read_intrinsics(ds / "cam2.yaml")
    assert intr.model == "fisheye" and intr.dist[0] > 0.03
    (fx, _, cx), (_, fy, cy) = intr.K[0], intr.K[1]
    (ds / "basalt.json").write_text(json.dumps({"value0": {
        "intrinsics": [{"camera_type": "kb4", "intrinsics": {
            "fx": fx, "fy": fy, "cx": cx, "cy": cy, "k1": 0, "k2": 0, "k3": 0, "k4": 0}}],
        "resolution": [[640, 480]]}}))
    text = (ds / "rig.yaml").read_text()
    (ds / "rig.yaml").write_text(text.replace("intrinsics: cam2.yaml",
                                              "intrinsics: {file: basalt.json, camera: cam0}"))
    res, cal = _calibrate(ds, tmp_path / "out")
    assert res.exit_code == 3, res.output
    (doubt,) = [d for d in cal["plausibility"] if d["cause"] == "intrinsics"]
    assert doubt["camera"] == "cam2"
    assert "left out of the intrinsics file" in doubt["message"], doubt["message"]


def test_distortion_left_out_under_noisy_motion_capture_is_named(tmp_path):
    """Motion capture of 0.5 deg / 5 mm (stated) hides k1 -0.1 left out in the loop (0.80 ->
    0.48 deg: less than 1.5 times) and its pixels leave 0.1 px of systematic part (under the
    0.2 px floor): exit 0 before. The k1, k2 freed lower the RMS 3.3 times: the images show a
    distortion the file lacks, exit 3 naming cam1; the lens as rendered exits 0."""
    import numpy as np

    from multieye.core.intrinsics import Intrinsics
    from multieye.sim.dataset import DatasetSpec, default_intrinsics, render_dataset

    ds = tmp_path / "ds"
    lenses = [Intrinsics(K=i.K, dist=np.array([-0.1, 0.003, 0.0, 0.0]), width=640, height=480)
              for i in default_intrinsics(2, 640, 480, rng=np.random.default_rng(1))]
    render_dataset(ds, DatasetSpec(n_cameras=2, images_per_camera=12, width=640, height=480,
                                   processes=1, mocap_noise=(np.radians(0.5), 0.005)),
                   seed=0, intrinsics=lenses)
    res, cal = _calibrate(ds, tmp_path / "right")
    assert res.exit_code == 0 and cal["plausibility"] == [], res.output
    text = (ds / "cam1.yaml").read_text()
    zeroed = re.sub(r"(distortion_coefficients:.*?data: )\[[^\]]*\]", r"\g<1>[0, 0, 0, 0]", text,
                    flags=re.S)
    assert zeroed != text
    (ds / "cam1.yaml").write_text(zeroed)
    res, cal = _calibrate(ds, tmp_path / "out")
    assert res.exit_code == 3, res.output
    (doubt,) = cal["plausibility"]
    assert doubt["cause"] == "intrinsics" and doubt["camera"] == "cam1"
    assert "left out of the intrinsics file" in doubt["message"]
    assert "mean loop residual" in doubt["message"] and "distortion none ->" in doubt["message"]
