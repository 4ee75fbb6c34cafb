"""Rigs linked by what the cameras see together, end to end (issue 23): a rendered rig of three
cameras without motion capture, the same rig with the board's motion capture (a mixed rig),
and a rig whose cameras nothing links."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from multieye.cli import main
from multieye.core import geometry as g
from multieye.core.lie import log_so3
from multieye.io.run_details import read_run_details
from multieye.sim.overlap import OverlapSpec, render_overlap_dataset

SPEC = OverlapSpec(n_instants=16, width=640, height=480)


def _calibrate(ds: Path, out: Path, *extra: str):
    return CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1",
                                     *extra])


def _truth(ds: Path) -> dict:
    return json.loads((ds / "ground_truth.json").read_text())


def _within_uncertainty(data: dict, truth: dict) -> None:
    """Every T_ref_cam within 4 sigma of the truth in each of rotation and translation (the
    covariance the run reports, from the pixel noise it estimated)."""
    for name, cam in data["cameras"].items():
        T, Tt = np.asarray(cam["T_ref_cam"]), np.asarray(truth["T_ref_cam"][name])
        if name == data["reference_camera"]:
            assert np.allclose(T, np.eye(4))
            continue
        cov = np.asarray(cam["covariance"])
        e = np.concatenate([log_so3(T[:3, :3] @ Tt[:3, :3].T), T[:3, 3] - Tt[:3, 3]])
        assert float(e @ np.linalg.solve(cov, e)) < 30, name          # chi2(6) far tail
        assert np.degrees(g.rotation_angle_between(T, Tt)) < 0.5
        assert g.translation_distance(T, Tt) < 0.005


@pytest.mark.parametrize("models", [False, True], ids=["lenses-given", "lenses-estimated"])
def test_a_rig_without_motion_capture_is_calibrated_from_its_shared_views(tmp_path, models):
    ds = tmp_path / "ds"
    sc = render_overlap_dataset(ds, SPEC, seed=1, models=models)
    assert "mocap" not in (ds / "rig.yaml").read_text()
    res = _calibrate(ds, tmp_path / "out")
    assert res.exit_code == 0, res.output
    data = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert data["format_version"] == 2 and data["setup"] == "overlap"
    assert "T_marker_target" not in data and "T_world_target" not in data
    truth = _truth(ds)
    _within_uncertainty(data, truth)
    shared = (sc.seen[:, :, None] & sc.seen[:, None, :]).sum(axis=0)
    for j, cam in enumerate(data["cameras"].values()):
        assert "T_world_cam" not in cam
        assert cam["links"]["mocap"] is False
        assert cam["links"]["overlap"] == {f"cam{k}": int(shared[j, k]) for k in range(3)
                                          if k != j and shared[j, k]}
        assert cam["intrinsics"]["estimated"] is models
    # the screen says what links each camera, and a clean rendered rig raises no doubt
    assert "overlap with cam1" in res.output
    assert "fit the rig poorly" not in res.output
    # the evidence: every used image's points fit the solution to a fraction of a pixel
    details = read_run_details(tmp_path / "out" / "details.json")
    for cam in details.cameras:
        assert cam.points is not None and cam.points.source == "refined"
        assert np.all(np.isfinite(cam.points.rms_px)) and np.max(cam.points.rms_px) < 0.5
        assert np.all(cam.rot_deg < 0.5) and np.all(cam.trans_m < 0.01)
    assert details.trajectories[0].pose == "T_ref_target"
    html = (tmp_path / "out" / "report.html").read_text()
    assert "What links each camera" in html and "No motion capture" in html
    # what is drawn and linked, said as it is: no motion capture is drawn, cam1 and cam2
    # share views (issue 34 report wording)
    assert "the motion capture (T_ref_target)" not in html
    assert ("Grey line: the target&#x27;s origin from instant to instant, in the reference "
            "camera&#x27;s frame (T_ref_target; no motion capture)") in html
    assert ("No motion capture: linked to the reference camera cam0: cam1 and cam2 by the "
            "views they share with another camera (one board at one instant).") in html
    # exports: the pinhole pair (cam0, cam1) rectified, cam2 (fisheye with pinholes) not
    res = CliRunner().invoke(main, ["export", str(tmp_path / "out"), "--format", "camera-info"])
    assert res.exit_code == 0, res.output
    assert "no stereo rectification for" not in res.output or "cam2" in res.output
    info = {n: yaml.safe_load((tmp_path / "out" / "export" / "camera_info" / f"{n}.yaml")
                              .read_text()) for n in ("cam0", "cam1")}
    R0 = np.reshape(info["cam0"]["rectification_matrix"]["data"], (3, 3))
    P1 = np.reshape(info["cam1"]["projection_matrix"]["data"], (3, 4))
    P0 = np.reshape(info["cam0"]["projection_matrix"]["data"], (3, 4))
    assert not np.allclose(R0, np.eye(3))
    baseline = g.translation_distance(np.asarray(truth["T_ref_cam"]["cam0"]),
                                      np.asarray(truth["T_ref_cam"]["cam1"]))
    assert abs(-min(P0[0, 3], P1[0, 3]) / P1[0, 0] - baseline) < 0.005


def test_a_mixed_rig_is_one_problem_with_both_links(tmp_path):
    ds = tmp_path / "ds"
    render_overlap_dataset(ds, SPEC, seed=2, mocap=True)
    res = _calibrate(ds, tmp_path / "out")
    assert res.exit_code == 0, res.output
    data = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert data["setup"] == "eye-to-base" and "T_marker_target" in data
    _within_uncertainty(data, _truth(ds))
    for cam in data["cameras"].values():
        assert cam["links"]["mocap"] is True
        assert cam["links"]["overlap"]


def test_cameras_that_nothing_links_are_refused_in_one_line(tmp_path):
    ds = tmp_path / "ds"
    render_overlap_dataset(ds, SPEC, seed=3)
    for p in sorted((ds / "cam2").iterdir()):          # cam2's clock 100 s late
        p.rename(p.with_name(f"{float(p.stem) + 100:.6f}.png"))
    res = _calibrate(ds, tmp_path / "out")
    assert res.exit_code == 2, res.output
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert len(lines) == 1, res.output
    assert "{cam0, cam1} and {cam2}" in lines[0]
    assert "sync_tolerance" in lines[0] and "mocap" in lines[0]
    assert not (tmp_path / "out").exists()
    res = CliRunner().invoke(main, ["check", str(ds), "--processes", "1"])
    assert res.exit_code == 2, res.output
    assert "{cam0, cam1} and {cam2}" in res.output


def test_check_works_on_a_rig_without_motion_capture(tmp_path):
    ds = tmp_path / "ds"
    render_overlap_dataset(ds, SPEC, seed=1)
    res = CliRunner().invoke(main, ["check", str(ds), "--processes", "1"])
    assert res.exit_code == 0, res.output
    assert "verdict" in res.output


def test_a_camera_a_frame_late_is_written_but_doubted(tmp_path):
    """cam2's stamps one frame late: its images pair with the wrong board poses; the result is
    written, the fit check names cam2 and the exit status is 3."""
    ds = tmp_path / "ds"
    render_overlap_dataset(ds, SPEC, seed=1)
    for p in sorted((ds / "cam2").iterdir(), reverse=True):
        p.rename(p.with_name(f"{float(p.stem) + SPEC.frame_interval_s:.6f}.png"))
    res = _calibrate(ds, tmp_path / "out")
    assert res.exit_code == 3, res.output
    data = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert [(d["cause"], d.get("camera")) for d in data["plausibility"]] == [("fit", "cam2")]
    assert "synchronised" in res.output


def test_a_camera_recorded_in_a_bag_is_linked_by_its_stamps(tmp_path):
    """Kalibr's input: one camera's images in a ROS bag topic, the others in folders; the
    bag's header stamps make the instants."""
    from rosbag_writer import camera_into_bag

    ds = tmp_path / "ds"
    render_overlap_dataset(ds, SPEC, seed=1)
    camera_into_bag(ds, "cam1", ros=1)
    res = _calibrate(ds, tmp_path / "out")
    assert res.exit_code == 0, res.output
    data = json.loads((tmp_path / "out" / "calibration.json").read_text())
    _within_uncertainty(data, _truth(ds))
    assert data["cameras"]["cam1"]["links"]["overlap"]["cam0"] > 5
