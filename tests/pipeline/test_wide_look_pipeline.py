"""The second look of a wide lens in the pipeline (issue 33): a camera with a 220-degree lens,
two of its boards at the rim bent beyond what the detectors find in the image; with the lens
given (while detecting) or estimated (after its start) they are found through perspective
views of its field, used, and the camera's warnings say how many."""

from __future__ import annotations

import cv2
import numpy as np

from multieye.core.geometry import transform_from_rotvec
from multieye.io import load_rig
from multieye.io.intrinsics_files import write_intrinsics_file
from multieye.pipeline import calibrate
from multieye.pipeline.camera_data import load_camera_data
from multieye.sim.render import render, visible
from multieye.sim.wide_lens import _pose, wide_lens
from multieye.imaging.targets import Chessboard

LENS = wide_lens("double-sphere", 220)
BOARD = Chessboard(rows=6, cols=9, spacing=0.03)
#: the rim views of tests/imaging/test_wide_look.py (board centres 106 and 99 degrees off
#: the axis), which the detectors miss in the image
RIM = [transform_from_rotvec([-2.0541, 0.5517, 2.1428], [-0.2909, 0.4566, -0.0378]),
       transform_from_rotvec([1.0508, -1.001, 0.3576], [-0.2976, -0.3281, -0.207])]


def _views(n: int, rng) -> list:
    """``n`` whole boards spread over the field up to 95 degrees off the axis."""
    out = []
    while len(out) < n:
        T = _pose(rng, np.arccos(rng.uniform(np.cos(np.radians(95.0)), 1.0)),
                  BOARD.object_points())
        if visible(BOARD, LENS, T, border_px=8):
            out.append(T)
    return out


def _write(folder, n: int) -> None:
    """``n`` views spread over the field, then the two rim views, as PNG files."""
    (folder / "wide").mkdir()
    for k, T in enumerate(_views(n, np.random.default_rng(7)) + RIM):
        image = render(BOARD, LENS, T, rng=np.random.default_rng([7, k]), blur_sigma=0.7,
                       noise_sigma=2.0)
        cv2.imwrite(str(folder / "wide" / f"{k:03d}.png"), image)


def test_a_given_wide_lens_uses_the_rim_boards_its_second_look_finds(tmp_path):
    """The given lens's path: the second look runs in the detection's workers."""
    _write(tmp_path, 2)
    write_intrinsics_file(tmp_path / "wide.yaml", LENS)
    (tmp_path / "rig.yaml").write_text(
        "target: {type: chessboard, rows: 6, cols: 9, spacing: 0.03}\n"
        "cameras:\n  wide: {intrinsics: wide.yaml, images: wide/}\n")
    data = load_camera_data(load_rig(tmp_path), processes=1)["wide"]
    assert [o.name for o in data.observations] == ["000.png", "001.png", "002.png", "003.png"]
    assert not data.rejected                        # before: 002 and 003 not detected
    assert data.warnings == ("wide: 2 of 4 images recovered by the wide lens's second look "
                             "(the board, not found in the image itself, found in a "
                             "perspective view of the lens's field)",)
    assert max(o.rms_px for o in data.observations) < 0.3


def test_an_estimated_wide_lens_uses_the_rim_boards_its_second_look_finds(tmp_path):
    _write(tmp_path, 12)
    (tmp_path / "rig.yaml").write_text(
        "target: {type: chessboard, rows: 6, cols: 9, spacing: 0.03}\n"
        "cameras:\n  wide: {model: double-sphere, images: wide/}\n")
    run = calibrate(tmp_path, processes=1)
    cam = run.record.cameras[0]
    assert cam.measurements_used == 14 and not cam.rejected, cam.rejected  # before: 12, 2 "target not detected"
    assert any(w.startswith("wide: 2 of 14 images recovered by the wide lens's second look")
               for w in run.record.warnings), run.record.warnings
    used = {o.name for o in run.paired["wide"].observations}
    assert {"012.png", "013.png"} <= used
