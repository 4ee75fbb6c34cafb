"""The calibration table on screen: named transforms, uncertainty columns, no negative zeros."""

from __future__ import annotations

import numpy as np

from multieye.core import geometry as g
from multieye.io.calibration_json import CalibrationRecord, CameraRecord, Residuals
from multieye.outputs.summary import calibration_table


def _record(frames=None) -> CalibrationRecord:
    tiny = g.transform_from_rotvec([-1e-9, 0, 0], [-1e-9, 2e-9, -3e-9])   # rounding noise
    X1 = g.transform_from_rotvec([0, 0.3, 0], [0.5, -0.2, 0.1])
    cams = (CameraRecord("cam0", tiny, tiny, 10), CameraRecord("cam1", X1, X1, 12))
    return CalibrationRecord("eye-on-hand", "joint", "cam0", np.eye(4), cams,
                             Residuals(e_R_deg=0.1, e_t_m=1e-3), frames=frames)


def test_values_that_round_to_zero_print_without_a_sign():
    text = calibration_table(_record())
    assert "-0.0000" not in text and "-0.000 " not in text
    row = next(line for line in text.splitlines() if line.startswith("cam0 (ref)"))
    assert row.split()[7:13] == ["0.0000", "0.0000", "0.0000", "0.000", "0.000", "0.000"]


def test_transforms_are_named_in_the_users_frames_with_the_json_key():
    plain = calibration_table(_record())
    named = calibration_table(_record({"world": "base", "body": "tool0"}))
    assert "T_body_cam of every camera:" in plain and "T_world_target: t = (" in plain
    assert "T_tool0_cam (calibration.json: T_body_cam) of every camera:" in named
    assert "T_base_target (calibration.json: T_world_target): t = (" in named
    # the numbers are the same
    assert [ln for ln in plain.splitlines() if ln.startswith("cam1")] == \
        [ln for ln in named.splitlines() if ln.startswith("cam1")]


def test_rejections_are_one_line_per_cause():
    """A recording where most frames miss the board prints one line per cause and camera,
    with the count and the first images named (issue 34, item 4), not a line per frame;
    a cause of one image keeps ``camera/image: reason``."""
    from dataclasses import replace  # noqa: PLC0415 (this test only)
    from multieye.io import RejectedItem  # noqa: PLC0415 (this test only)
    from multieye.pipeline.recordings import FIRST_NAMED  # noqa: PLC0415 (this test only)
    rec = _record()
    lost = tuple(RejectedItem(f"{k:06d}.png", "target not detected (chessboard 6x9)")
                 for k in range(500))
    odd = (RejectedItem("000777.png", "PnP failed: the 5 points lie on one line"),)
    rec = replace(rec, cameras=(replace(rec.cameras[0], rejected=lost + odd),) + rec.cameras[1:])
    lines = [x for x in calibration_table(rec).splitlines() if x.startswith("rejected ")]
    assert lines == [
        "rejected cam0: target not detected (chessboard 6x9) (500 images: "
        + ", ".join(f"{k:06d}.png" for k in range(FIRST_NAMED)) + f" and {500 - FIRST_NAMED} more)",
        "rejected cam0/000777.png: PnP failed: the 5 points lie on one line"]
