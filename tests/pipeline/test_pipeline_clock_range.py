"""`--time-offset auto` searches a range the user can widen (`--max-time-offset`)."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

import multieye
from multieye.cli import main
from multieye.sim.images import simulate_stream
from multieye.io import Trajectory, write_tum
from multieye.pipeline import calibrate

RIG = """\
setup: eye-to-base
target: {type: chessboard, rows: 6, cols: 9, spacing: 0.05}
mocap: {file: mocap.txt, pose: T_world_marker, time_tolerance: 0.01}
cameras:
  cam0: {poses: cam0.txt}
"""


@pytest.fixture(scope="module")
def late_mocap(tmp_path_factory):
    """A camera pose stream whose motion-capture clock runs 0.7 s ahead (beyond 0.5 s)."""
    folder = tmp_path_factory.mktemp("late")
    st = simulate_stream(43, time_offset_s=0.7, duration_s=30.0)
    write_tum(folder / "mocap.txt", Trajectory(st.mocap_stamps, st.T_world_mocap))
    write_tum(folder / "cam0.txt", Trajectory(st.cam_stamps, st.T_cam_target, "cam", "target"))
    (folder / "rig.yaml").write_text(RIG)
    return folder


def test_offset_beyond_the_default_range_is_refused_with_the_option_to_widen_it(late_mocap):
    with pytest.raises(multieye.CalibrationError,
                       match=r"edge of the search range -0\.5\.\.\+0\.5 s.*--max-time-offset"):
        calibrate(late_mocap, time_offset="auto", refine=False)


def test_widened_range_finds_the_offset(late_mocap):
    run = calibrate(late_mocap, time_offset="auto", max_time_offset=1.0, refine=False)
    assert run.record.cameras[0].time_offset_s == pytest.approx(0.7, abs=0.003)


def test_cli_option(late_mocap, tmp_path):
    runner = CliRunner()
    ok = runner.invoke(main, ["calibrate", str(late_mocap), "-o", str(tmp_path / "out"),
                              "--time-offset", "auto", "--max-time-offset", "1", "--no-refine"])
    assert ok.exit_code == 0, ok.output
    assert (tmp_path / "out" / "calibration.json").exists()
    bad = runner.invoke(main, ["calibrate", str(late_mocap), "-o", str(tmp_path / "bad"),
                               "--time-offset", "auto", "--max-time-offset", "0"])
    assert bad.exit_code == 2 and "--max-time-offset" in bad.output
    assert not (tmp_path / "bad").exists()
    with pytest.raises(multieye.InputError, match="max_time_offset must be a positive"):
        calibrate(late_mocap, time_offset="auto", max_time_offset=float("nan"))


def test_an_edge_reached_by_the_correlation_only_says_where_it_peaked(late_mocap, monkeypatch):
    """ETH's 5_falcon camera e: refined to +0.434 s, refused as 'at the edge' of +-0.5 s
    because the correlation peaked at the edge; the line said only +0.434."""
    from multieye.estimate.clock import ClockOffset
    from multieye.pipeline import clock_offsets

    found = ClockOffset(offset_s=0.434, std_s=0.01, score=0.9, coarse_offset_s=0.5,
                        method="loop", n_used=50, rot_rms_deg=1.0, trans_rms_m=0.01)
    monkeypatch.setattr(clock_offsets, "estimate_offset", lambda *a, **k: found)
    with pytest.raises(multieye.CalibrationError, match=r"offset \(\+0\.434 s; the angular "
                       r"speeds correlate best at \+0\.500 s\) is at the edge"):
        calibrate(late_mocap, time_offset="auto", refine=False)


def test_an_offset_its_loop_residuals_do_not_determine_is_refused(late_mocap, monkeypatch):
    """estimate_offset's note (residuals still falling at the end of the offsets examined)
    stops the run with the reason, instead of pairing at a number without a minimum."""
    from multieye.estimate.clock import ClockOffset
    from multieye.pipeline import clock_offsets

    found = ClockOffset(offset_s=0.05, std_s=float("nan"), score=0.9, coarse_offset_s=0.3,
                        method="loop", n_used=50, rot_rms_deg=1.0, trans_rms_m=0.01,
                        note="the loop residuals still fall at +0.050 s, ...: the offset is "
                             "not determined by them")
    monkeypatch.setattr(clock_offsets, "estimate_offset", lambda *a, **k: found)
    with pytest.raises(multieye.CalibrationError,
                       match=r"camera cam0: the clock offset cannot be estimated: the loop "
                             r"residuals still fall .* not determined by them; give "
                             r"--time-offset"):
        calibrate(late_mocap, time_offset="auto", refine=False)
