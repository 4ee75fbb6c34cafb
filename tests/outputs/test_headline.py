"""Issue 33: the headline figures mean something for the setup. Cameras linked by motion
capture: the mean loop residual of the hand-eye fit. One camera, or cameras linked only by the
views they share: the reprojection RMS and each camera's sigma, the pose residuals a diagnostic
on a line below (they were the headline, 8.4 deg / 46 mm for one camera)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from export_runs import make_run
from small_dataset import render_small

from multieye.outputs.report import FIGURES, report_html
from multieye.outputs.summary import calibration_table
from multieye.pipeline import calibrate
from multieye.sim.overlap import OverlapSpec, render_overlap_dataset


#: Stand-ins for the figures (the page is what is tested, not them).
_NO_FIGURES = dict.fromkeys(FIGURES, b"png")


def reprojection_rms_px(rec) -> float:
    """Every camera's RMS weighted by its images used."""
    n = np.array([c.measurements_used for c in rec.cameras])
    r = np.array([c.residuals.reprojection_rms_px for c in rec.cameras])
    return float(np.sqrt(n @ r ** 2 / n.sum()))


def _cards(html: str) -> dict[str, str]:
    head = html[html.index('<div class="cards">'):html.index("<nav>")]
    return dict(re.findall(r'<div class="k">([^<]*)</div><div class="v">([^<]*)</div>', head))


def _checks_no_motion_capture(rec, tmp_path):
    lines = calibration_table(rec).splitlines()
    rms = reprojection_rms_px(rec)
    assert lines[0].startswith(f"overlap, method covisibility, reference {rec.reference_camera}:"
                               f" reprojection RMS {rms:.2f} px")
    assert "loop" not in lines[0]
    assert re.fullmatch(r"pose residuals \(a diagnostic, not the accuracy\): mean e_R "
                        r"[0-9.]+ deg, e_t [0-9.]+ mm", lines[1]), lines[1]
    html = report_html(rec, None, _NO_FIGURES, out_dir=tmp_path)
    cards = _cards(html)
    assert cards["reprojection RMS"] == f"{rms:.2f} px"
    assert "mean rotation residual" not in cards and "mean translation residual" not in cards
    assert "Pose residuals, a diagnostic" in html
    return lines, cards


@pytest.fixture(scope="module")
def one_camera(tmp_path_factory):
    """One rendered camera, its lens given, no motion capture."""
    ds = tmp_path_factory.mktemp("one") / "ds"
    render_small(ds)
    text = (ds / "rig.yaml").read_text()
    text = text[:text.index("mocap:")] + text[text.index("cameras:"):text.index("  cam1:")]
    (ds / "rig.yaml").write_text(text)
    return calibrate(ds)


def test_one_camera_headline_is_the_reprojection_rms(one_camera, tmp_path):
    rec = one_camera.record
    assert len(rec.cameras) == 1 and not rec.mocap
    lines, cards = _checks_no_motion_capture(rec, tmp_path)
    cam = rec.cameras[0]
    assert reprojection_rms_px(rec) == pytest.approx(cam.residuals.reprojection_rms_px)
    assert "sigma" not in lines[0]           # the reference camera has no pose to be unsure of


def test_overlap_headline_gives_each_cameras_sigma(tmp_path):
    ds = tmp_path / "ds"
    render_overlap_dataset(ds, OverlapSpec(n_instants=16, width=640, height=480), seed=1,
                           models=True)
    rec = calibrate(ds).record
    lines, cards = _checks_no_motion_capture(rec, tmp_path)
    for cam in rec.cameras[1:]:
        unc = cam.uncertainty["T_ref_cam"]
        shown = f"{unc.std_rot_deg:.3f} deg / {unc.std_trans_m * 1e3:.2f} mm"
        assert f"{cam.name} {shown}" in lines[0]
        assert cards[f"σ {cam.name}"] == f"{unc.std_rot_deg:.3f}° / {unc.std_trans_m * 1e3:.2f} mm"
    for cam in rec.cameras:                  # every lens estimated: its projection's sigma
        mean = cam.intrinsics.projection_std_px[0]
        assert f"{cam.name} {mean:.2f} px" in lines[0].split("sigma of the projection")[1]
        assert cards[f"σ lens {cam.name}"] == f"{mean:.2f} px"
    from multieye.outputs import summary

    assert summary.reprojection_rms_px(rec) == pytest.approx(reprojection_rms_px(rec))


def test_motion_capture_headline_stays_the_loop_residual(tmp_path):
    rec = make_run(tmp_path, "eye-to-base")[0].record
    lines = calibration_table(rec).splitlines()
    assert lines[0] == (f"eye-to-base, method {rec.method}, reference {rec.reference_camera}: "
                        f"mean loop residual e_R {rec.residuals.e_R_deg:.3f} deg, e_t "
                        f"{rec.residuals.e_t_m * 1e3:.2f} mm")
    assert not lines[1].startswith("pose residuals")
    cards = _cards(report_html(rec, None, _NO_FIGURES, out_dir=tmp_path))
    assert "mean rotation residual" in cards and "reprojection RMS" not in cards


def test_pose_residual_columns_say_pose_without_motion_capture(one_camera, tmp_path):
    """The table's residual columns were labelled 'loop' under a headline calling them pose
    residuals; with motion capture they stay 'loop'."""
    table = calibration_table(one_camera.record).splitlines()
    header = next(line for line in table if line.startswith("camera "))
    assert "pose e_R deg" in header and "pose e_t mm" in header and "loop" not in header
    rec = make_run(tmp_path, "eye-to-base")[0].record
    header = next(line for line in calibration_table(rec).splitlines()
                  if line.startswith("camera "))
    assert "loop e_R deg" in header


def test_calibrate_many_gives_each_datasets_headline(tmp_path):
    """calibrate-many printed 'ok (s) -> folder' with no figure; each line now carries the
    headline of its setup (here a rig without motion capture: the reprojection RMS and each
    camera's sigma)."""
    from click.testing import CliRunner

    from multieye.cli import main

    ds = tmp_path / "ov"
    render_overlap_dataset(ds, OverlapSpec(n_instants=10, width=640, height=480), seed=2)
    res = CliRunner().invoke(main, ["calibrate-many", str(ds), "--out-root",
                                    str(tmp_path / "out"), "--workers", "1"])
    assert res.exit_code == 0, res.output
    line = next(x for x in res.output.splitlines() if x.startswith(f"{ds}: ok ("))
    head = line.split("; ", 1)[1]
    assert head.startswith("overlap, method covisibility, reference cam0: reprojection RMS ")
    assert "sigma of T_ref_cam cam1 " in head and "loop" not in head


def test_pixel_methods_are_the_pipelines_names():
    from multieye.outputs.summary import PIXEL_METHODS
    from multieye.pipeline.overlap_run import METHOD, MOTION_METHOD

    assert set(PIXEL_METHODS) == {METHOD, MOTION_METHOD}
