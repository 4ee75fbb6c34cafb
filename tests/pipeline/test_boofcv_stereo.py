"""BoofCV's stereo set as published (``left01.jpg`` ... ``right11.jpg`` in one folder) with the
committed docs/results/boofcv_stereo/rig.yaml (``images: "left*.jpg"``, ``sync: number``),
through ``multieye calibrate`` and ``multieye check``, against BoofCV's ``stereo.yaml``.
The bounds are docs/results/boofcv_stereo.md's figures with margin; every ``sync`` that can
pair this layout gives the same instants and so the same result."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import yaml
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from multieye.cli import main
from multieye.pipeline import calibrate

REPO = Path(__file__).resolve().parents[2]
RIG = REPO / "docs" / "results" / "boofcv_stereo" / "rig.yaml"


def _published(shared: Path, out: Path, rig_text: str | None = None) -> Path:
    """The published folder rebuilt under ``out`` (every file linked) plus a rig.yaml."""
    src = shared / "boofcv_stereo"
    out.mkdir(parents=True)
    for f in sorted(src.iterdir()):
        os.symlink(f, out / f.name)
    (out / "rig.yaml").write_text(RIG.read_text() if rig_text is None else rig_text)
    return out


def _reference(shared: Path) -> tuple[np.ndarray, np.ndarray]:
    r2l = yaml.safe_load((shared / "boofcv_stereo" / "stereo.yaml").read_text())["rightToLeft"]
    return (np.array(r2l["rotation"], float).reshape(3, 3),
            np.array([r2l["x"], r2l["y"], r2l["z"]], float) / 1000)


def test_published_layout_against_boofcv(shared_data, tmp_path):
    """boofcv_stereo.md: 0.25 deg and 0.71 mm from BoofCV's T_left_right, baseline 120.21 mm
    (BoofCV 120.05), our predicted std 0.09 deg / 0.32 mm; the 22 symmetric-board notes in
    one line."""
    dataset = _published(shared_data, tmp_path / "data")
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["calibrate", str(dataset), "-o", str(out),
                                    "--processes", "1"])
    assert res.exit_code == 0, res.output
    cal = json.loads((out / "calibration.json").read_text())
    right = cal["cameras"]["right"]
    assert right["links"]["overlap"] == {"left": 11} and right["measurements_used"] == 11
    T = np.array(right["T_ref_cam"])
    R_ref, t_ref = _reference(shared_data)
    rot = np.degrees(Rotation.from_matrix(T[:3, :3] @ R_ref.T).magnitude())
    assert rot < 0.35, rot
    assert np.linalg.norm(T[:3, 3] - t_ref) < 1.0e-3
    assert abs(np.linalg.norm(T[:3, 3]) - np.linalg.norm(t_ref)) < 0.4e-3
    assert right["std_rot_deg"] < 0.15 and right["std_trans_m"] < 0.5e-3
    symmetric = [w for w in cal["warnings"] if "looks the same after a turn" in w]
    assert len(symmetric) == 1 and "(22 images: left01.jpg, left02.jpg" in symmetric[0]
    assert res.output.count("looks the same after a turn") == 1


def test_check_prints_instants_and_links(shared_data, tmp_path):
    dataset = _published(shared_data, tmp_path / "data")
    res = CliRunner().invoke(main, ["check", str(dataset), "--processes", "1", "--sample", "3"])
    assert res.exit_code == 0, res.output
    assert ("instants: 11 found by sync: number, the same frame number in their names; 11 of "
            "them seen by more than one camera") in res.output
    assert "left linked by: right (11 instants)" in res.output
    assert "right linked by: left (11 instants)" in res.output


def test_every_sync_that_pairs_the_layout_gives_one_result(shared_data, tmp_path):
    """number and order on the published folder, name on images copied into one folder per
    camera under equal names, time on the same named by stamps: one result."""
    base = calibrate(_published(shared_data, tmp_path / "number"), processes=1)
    order = calibrate(_published(shared_data, tmp_path / "order",
                                 RIG.read_text().replace("sync: number", "sync: order")),
                      processes=1)
    by_folder = {}
    for sync, name in (("name", "{k}.jpg"), ("time", "{n}.0.jpg")):
        folder = tmp_path / sync
        for side in ("left", "right"):
            (folder / side).mkdir(parents=True)
            for n in range(1, 12):
                shutil.copy(shared_data / "boofcv_stereo" / f"{side}{n:02d}.jpg",
                            folder / side / name.format(k=f"{n:02d}", n=n))
        (folder / "rig.yaml").write_text(
            RIG.read_text().replace("sync: number", f"sync: {sync}")
            .replace('"left*.jpg"', "left/").replace('"right*.jpg"', "right/"))
        by_folder[sync] = calibrate(folder, processes=1)
    for other in (order, *by_folder.values()):
        np.testing.assert_allclose(other.T_ref_cam["right"], base.T_ref_cam["right"],
                                   atol=1e-9)
