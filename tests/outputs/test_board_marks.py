"""The boards of a rig with several targets in the rig figures (multieye.outputs.board_marks)."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from multieye.core import geometry as g
from multieye.core.target_spec import TargetSpec
from multieye.io.calibration_json import PoseUncertainty
from multieye.outputs.board_marks import board_legend, board_lines, board_mark
from multieye.outputs.details import write_run_details
from multieye.outputs.figures_rig import rig_pngs
from test_export import make_run

CHESS = TargetSpec("chessboard", 6, 9, 0.1)
APRIL = TargetSpec("aprilgrid", 4, 5, 0.05, tag_spacing=0.3)


def test_a_board_is_its_pattern_at_its_pose_facing_its_camera_side():
    T = g.transform_from_rotvec([0.3, -0.2, 1.0], [1.0, 2.0, 0.5])
    mark = board_mark("north", CHESS, T)
    x0, x1, y0, y1 = (-0.1, 0.9, -0.1, 0.6)             # chessboard 6x9 of 0.1 m squares
    local = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0], [x0, y0, 0]])
    assert np.allclose(mark.corners(), local @ T[:3, :3].T + T[:3, 3])
    assert np.allclose(mark.normal(), -T[:3, 2])          # z into the board: seen from -z
    assert np.allclose(board_mark("a", APRIL, T).normal(), T[:3, 2])   # Kalibr: z out of it


def test_board_lines_with_and_without_uncertainty():
    marks = [board_mark("north", CHESS, np.eye(4)),
             board_mark("west", CHESS, g.transform_from_rotvec([0, 1.57, 0], [2, 0, 0]),
                        covariance=np.diag([1e-6] * 3 + [1e-4] * 3), given=False)]
    lines, points = board_lines(marks, lambda p: p, None)
    assert len(lines) == 4 and len(points) == 2          # a rectangle and a normal each
    ringed, _ = board_lines(marks, lambda p: p, lambda C: np.array(
        [[0.0, 0, 0], [0.03, 0, 0], [np.nan] * 3, [0, 0.03, 0], [0, 0, 0.03]]))
    assert len(ringed) == 6                             # west's two ring pieces
    assert board_legend([]) == []
    assert "3σ ellipsoid" in board_legend(marks)[0] and "2 boards" in board_legend(marks)[0]
    given = [dataclasses.replace(marks[0], given=True)]
    assert "given in rig.yaml (north)" in board_legend(given)[0]


def test_rig_figures_draw_and_name_the_boards(tmp_path):
    run, _ = make_run(tmp_path, "eye-on-hand", noise=1e-3)
    details = write_run_details(tmp_path / "details.json", run)
    rec = run.record
    C = np.diag([1e-6, 1e-6, 1e-6, 1e-7, 1e-7, 1e-7])
    rec = dataclasses.replace(rec, cameras=tuple(dataclasses.replace(
        c, uncertainty={"T_body_cam": PoseUncertainty(0.1, 0.5e-3, C)}) for c in rec.cameras))
    plain = rig_pngs(rec, details)
    centre = np.mean([c.T_world_cam[:3, 3] for c in details.cameras], axis=0)
    marks = [board_mark(n, CHESS, g.transform_from_rotvec([0, 0, a], centre + [0.0, 0.0, -0.5]),
                        covariance=np.diag([1e-6] * 3 + [1e-5] * 3))
             for n, a in (("north", 0.0), ("west", 1.57))]
    with_boards = rig_pngs(rec, details, boards=marks)
    assert board_legend(marks)[0] in with_boards.legend
    for name in plain.pngs:
        a = cv2.imdecode(np.frombuffer(plain.pngs[name], np.uint8), cv2.IMREAD_GRAYSCALE)
        b = cv2.imdecode(np.frombuffer(with_boards.pngs[name], np.uint8), cv2.IMREAD_GRAYSCALE)
        assert a.shape == b.shape and np.mean(a != b) > 0.002, name
    # without details.json: drawn in the reference camera's frame, named too
    only = rig_pngs(rec, None, boards=marks)
    assert board_legend(marks)[0] in only.legend
