"""`multieye demo --rig overlap`: an overlapping rig without motion capture, every lens unknown."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from multieye.cli import main
from multieye.core.intrinsics import Intrinsics
from multieye.demo import lens_error_px, run_overlap_demo
from multieye.sim.overlap import OverlapSpec


def _lens(cx: float = 400.0) -> Intrinsics:
    K = np.array([[520.0, 0, cx], [0, 521.0, 300.0], [0, 0, 1]])
    return Intrinsics(K=K, dist=np.array([-0.2, 0.08, 1e-4, -2e-4, 0.0]), model="pinhole",
                      width=800, height=600)


def test_lens_error_is_zero_for_the_true_lens_and_a_shifted_centre_is_a_rotation():
    pixels = np.random.default_rng(3).uniform([100, 80], [700, 520], (200, 2))
    assert max(lens_error_px(_lens(), _lens(), pixels)) < 1e-9
    raw, rotated = lens_error_px(_lens(402.0), _lens(), pixels)
    assert 1.9 < raw < 2.1                        # 2 px off everywhere, near enough
    assert rotated < 0.1 * raw                    # ... which a turn of the camera absorbs


def test_overlap_demo_recovers_the_rig_and_the_lenses_within_their_uncertainty(tmp_path):
    spec = OverlapSpec(board_shift_m=0.45, n_instants=40)
    result = run_overlap_demo(tmp_path / "out", seed=1, spec=spec)
    cal = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert cal["setup"] == "overlap" and "Y" not in cal
    rot, trans = result.errors["covisibility + refinement"]
    for j, name in enumerate(["cam0", "cam1", "cam2"]):
        unc = cal["cameras"][name]["uncertainty"]["T_ref_cam"] if j else None
        if unc is None:
            assert rot[j] < 1e-9 and trans[j] < 1e-12       # the reference is the frame
            continue
        assert rot[j] < 4 * unc["std_rot_deg"], (name, rot[j], unc)
        assert trans[j] < 4 * unc["std_trans_m"], (name, trans[j], unc)
    raw, rotated = result.errors["lens"]
    assert np.all(rotated < 0.05), rotated        # pixel noise 2 grey levels, blur 0.7 px
    assert np.all(rotated <= raw + 1e-12)
    assert "every lens unknown" in result.text and "after the best-fitting rotation" in result.text


def test_the_demo_command_offers_both_rigs():
    out = CliRunner().invoke(main, ["demo", "--help"])
    assert out.exit_code == 0 and "[surround|overlap]" in out.output
    bad = CliRunner().invoke(main, ["demo", "--rig", "ring", "-o", "unused"])
    assert bad.exit_code == 2 and "ring" in bad.output
