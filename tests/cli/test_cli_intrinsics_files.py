"""Intrinsics files through ``multieye calibrate``: a mrcal .cameramodel and a JSON ``K``/``dist``
file calibrate as the OpenCV YAML they were made from; a skew or an unknown key in one is exit
2 with one line naming the file and the key, and nothing written (issues 19, 20, 24)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from multieye.cli import main
from multieye.io.cameramodel import cameramodel_text
from multieye.io.intrinsics_files import read_intrinsics
from small_dataset import render_small


def _calibrate(dataset, out):
    return CliRunner().invoke(main, ["calibrate", str(dataset), "-o", str(out),
                                     "--processes", "1"])


def _use(dataset, camera, name, text):
    (dataset / name).write_text(text)
    rig = dataset / "rig.yaml"
    rig.write_text(rig.read_text().replace(f"intrinsics: {camera}.yaml", f"intrinsics: {name}"))


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("intr") / "ds"
    render_small(folder)
    return folder


def test_cameramodel_and_json_calibrate_as_the_opencv_yaml(dataset, tmp_path):
    ref = _calibrate(dataset, tmp_path / "ref")
    assert ref.exit_code == 0, (ref.stdout, ref.stderr)
    other = tmp_path / "ds"
    other.mkdir()
    for f in dataset.iterdir():
        (other / f.name).symlink_to(f)
    (other / "rig.yaml").unlink()
    (other / "rig.yaml").write_text((dataset / "rig.yaml").read_text())
    cam0, cam1 = (read_intrinsics(dataset / f"cam{j}.yaml") for j in (0, 1))
    _use(other, "cam0", "cam0.cameramodel", cameramodel_text(cam0))
    _use(other, "cam1", "cam1.json", json.dumps({"K": cam1.K.tolist(), "dist": cam1.dist.tolist(),
                                                 "width": cam1.width, "height": cam1.height}))
    res = _calibrate(other, tmp_path / "out")
    assert res.exit_code == 0, (res.stdout, res.stderr)
    a, b = (json.loads((tmp_path / d / "calibration.json").read_text()) for d in ("ref", "out"))
    for name in ("cam0", "cam1"):
        np.testing.assert_allclose(b["cameras"][name]["T_world_cam"],
                                   a["cameras"][name]["T_world_cam"], rtol=0, atol=1e-9)


@pytest.mark.parametrize("change, expected", [
    ({"K": [[407.1, 999999.0, 315.5], [0, 408.4, 231.3], [0, 0, 1]]},
     "cam0.json:1: camera cam0: K: camera matrix has skew 999999 px"),
    ({"distortion": [-0.21, 0.1, 0.0, 0.0]},
     "cam0.json:1: camera cam0: distortion: not a key multieye reads"),
    ({"dist": [-0.21, 1e7, 0.0, 0.0]},
     "cam0.json:1: camera cam0: dist: distortion coefficient k2 = 1e+07"),
])
def test_a_refused_intrinsics_file_is_exit_2_one_line_nothing_written(dataset, tmp_path, change,
                                                                         expected):
    other = tmp_path / "ds"
    other.mkdir()
    for f in dataset.iterdir():
        if f.name != "rig.yaml":
            (other / f.name).symlink_to(f)
    (other / "rig.yaml").write_text((dataset / "rig.yaml").read_text())
    data = {"K": [[407.1, 0.0, 315.5], [0, 408.4, 231.3], [0, 0, 1]], "width": 640, "height": 480,
            **change}
    _use(other, "cam0", "cam0.json", json.dumps(data))
    res = _calibrate(other, tmp_path / "out")
    assert res.exit_code == 2, (res.stdout, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], res.stderr
    assert not (tmp_path / "out").exists()
