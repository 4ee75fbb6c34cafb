"""Other tools' board descriptions as rig.yaml's ``target:`` (multieye.io.target_files):
Kalibr's target YAML and BoofCV's ConfigCalibrationTarget read as the keys they stand for,
and every file multieye cannot read as a board refused with one line at its line."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.imaging.targets import target_from_spec
from multieye.io.rig import load_rig

CAM = ("camera_model: pinhole\nintrinsics: [400, 400, 320, 240]\ndistortion_model: radtan\n"
       "distortion_coeffs: [0, 0, 0, 0]\nresolution: [640, 480]\n")


def _rig(tmp_path, target_line: str, files: dict[str, str]):
    (tmp_path / "cam0").mkdir(parents=True, exist_ok=True)
    (tmp_path / "cam.yaml").write_text(CAM)
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "rig.yaml").write_text(
        f"{target_line}\ncameras:\n  cam0: {{intrinsics: cam.yaml, images: cam0/}}\n")
    return load_rig(tmp_path)


KALIBR = {
    "april": ("target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 5\ntagSize: 0.088\n"
              "tagSpacing: 0.3\n",
              "{type: aprilgrid, rows: 5, cols: 6, spacing: 0.088, tag_spacing: 0.3}"),
    "checker": ("target_type: 'checkerboard'\ntargetCols: 6\ntargetRows: 7\n"
                "rowSpacingMeters: 0.06\ncolSpacingMeters: 0.06\n",
                "{type: chessboard, rows: 7, cols: 6, spacing: 0.06}"),
    "circles": ("target_type: 'circlegrid'\ntargetCols: 6\ntargetRows: 7\nspacingMeters: 0.02\n"
                "asymmetricGrid: False\n", "{type: circles, rows: 7, cols: 6, spacing: 0.02}"),
    "basalt": ('{\n  "tagCols": 6,\n  "tagRows": 5,\n  "tagSize": 0.088,\n  "tagSpacing": 0.3\n}\n',
               "{type: aprilgrid, rows: 5, cols: 6, spacing: 0.088, tag_spacing: 0.3}"),
    "asym": ("target_type: 'circlegrid'\ntargetCols: 4\ntargetRows: 11\nspacingMeters: 0.02\n"
             "asymmetricGrid: True\n",
             "{type: asymmetric-circles, rows: 11, cols: 4, spacing: 0.04}"),
}


@pytest.mark.parametrize("kind", sorted(KALIBR))
def test_a_kalibr_target_file_is_the_board_its_keys_describe(tmp_path, kind):
    text, typed = KALIBR[kind]
    got = _rig(tmp_path / "file", "target: board.yaml", {"board.yaml": text}).targets["target"]
    want = _rig(tmp_path / "typed", f"target: {typed}", {}).targets["target"]
    assert got == want


def test_kalibr_asymmetric_grid_points_are_where_kalibr_puts_them(tmp_path):
    """Kalibr: point (r, c) at x = (2c + r mod 2) s, y = r s; the same grid up to the board's
    frame (multieye's spacing is the centre distance within a row, 2 s)."""
    text, _ = KALIBR["asym"]
    spec = _rig(tmp_path, "target: board.yaml", {"board.yaml": text}).targets["target"]
    P = target_from_spec(spec).object_points()[:, :2]
    s, (rows, cols) = 0.02, (11, 4)
    kalibr = np.array([[(2 * c + r % 2) * s, r * s] for r in range(rows) for c in range(cols)])
    # same set of pairwise distances: the two layouts are one rigid grid
    d = lambda X: np.sort(np.linalg.norm(X[:, None] - X[None], axis=2).ravel())  # noqa: E731
    np.testing.assert_allclose(d(P), d(kalibr), atol=1e-12)


def test_boofcv_chessboard_counts_squares_and_needs_the_spacing_in_metres(tmp_path, shared_data):
    src = shared_data / "boofcv_stereo" / "calibration_target.yaml"
    text = src.read_text()
    with pytest.raises(DatasetError, match=r"rig.yaml:1: target: calibration_target.yaml "
                       r"\(BoofCV\) gives the board's sizes in no stated unit: give 'spacing:'"):
        _rig(tmp_path, "target: calibration_target.yaml", {"calibration_target.yaml": text})
    spec = _rig(tmp_path, "target: {file: calibration_target.yaml, spacing: 0.03}",
                {"calibration_target.yaml": text}).targets["target"]
    # info.txt of the set: 5 x 7 squares of 30 mm -> 4 x 6 inner corners
    assert (spec.type, spec.rows, spec.cols, spec.spacing) == ("chessboard", 6, 4, 0.03)


def test_boofcv_circle_grid_and_keys_beside_the_file(tmp_path):
    text = (f"{'boofcv.alg.fiducial.calib.ConfigCalibrationTarget'}:\n  type: CIRCLE_GRID\n"
            "  grid:\n    numRows: 5\n    numCols: 6\n    shapeSize: 1.0\n    shapeDistance: 2.0\n")
    spec = _rig(tmp_path, "target: {file: b.yaml, spacing: 0.05}", {"b.yaml": text}
                ).targets["target"]
    assert (spec.type, spec.rows, spec.cols, spec.spacing) == ("circles", 5, 6, 0.05)


BAD = [
    ("target_type: 'checkerboard'\ntargetCols: 6\ntargetRows: 7\nrowSpacingMeters: 0.06\n"
     "colSpacingMeters: 0.05\n", r"board.yaml:5: colSpacingMeters: rowSpacingMeters \(0.06\) and "
     r"colSpacingMeters \(0.05\) differ"),
    ("target_type: 'apriltag'\n", r"board.yaml:1: target_type: Kalibr target_type 'apriltag': "
     "expected aprilgrid, checkerboard or circlegrid"),
    ("target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 0.088\n",
     r"board.yaml:1: missing key 'tagSpacing'"),
    ("target_type: 'aprilgrid'\ntagCols: six\ntagRows: 6\ntagSize: 0.088\ntagSpacing: 0.3\n",
     r"board.yaml:2: tagCols: expected an integer, got 'six'"),
    ("boofcv.alg.fiducial.calib.ConfigCalibrationTarget:\n  type: ECOCHECK\n  grid: {numRows: 5,"
     " numCols: 6}\n", r"board.yaml:2: boofcv.alg.fiducial.calib.ConfigCalibrationTarget.type: "
     "BoofCV target type 'ECOCHECK': multieye reads CHESSBOARD and CIRCLE_GRID"),
    ("camera_model: pinhole\n", r"board.yaml:1: expected a Kalibr target file"),
    ("- 1\n- 2\n", r"board.yaml:1: expected a Kalibr target file"),
    ('{"tagCols": 6, "tagRows": 6, "tagSize": 0.088, "tagSpacing": 0.3, "tagFamily": 1}',
     r"board.yaml:1: tagFamily: not a key of Basalt's AprilGrid file"),
]


@pytest.mark.parametrize("text, message", BAD)
def test_a_target_file_multieye_cannot_read_is_refused_at_its_line(tmp_path, text, message):
    with pytest.raises(DatasetError, match=message):
        _rig(tmp_path, "target: board.yaml", {"board.yaml": text})


def test_a_type_beside_the_file_must_agree_and_a_missing_file_is_named(tmp_path):
    text, _ = KALIBR["april"]
    with pytest.raises(DatasetError, match=r"rig.yaml:1: target.type: type 'chessboard' "
                       r"disagrees with board.yaml \(Kalibr: aprilgrid\)"):
        _rig(tmp_path, "target: {file: board.yaml, type: chessboard}", {"board.yaml": text})
    with pytest.raises(DatasetError, match=r"rig.yaml:1: target: expected the board's keys "
                       r"\(\{type: chessboard, .*\) or another tool's board file \(Kalibr, "
                       r"BoofCV\); no file 'nothere.yaml' beside rig.yaml"):
        _rig(tmp_path, "target: nothere.yaml", {})
    with pytest.raises(DatasetError, match=r"rig.yaml:1: target.file: file not found: b.yaml"):
        _rig(tmp_path, "target: {file: b.yaml}", {})


def test_the_file_must_be_a_regular_file_within_the_yaml_limit(tmp_path):
    (tmp_path / "big.yaml").write_text("target_type: 'aprilgrid'\n# " + "x" * 3_000_000 + "\n")
    with pytest.raises(DatasetError, match=r"big.yaml"):
        _rig(tmp_path, "target: big.yaml", {})
    (tmp_path / "dir.yaml").mkdir()
    with pytest.raises(DatasetError, match=r"expected a file, found a folder"):
        _rig(tmp_path, "target: dir.yaml", {})
    shutil.rmtree(tmp_path / "dir.yaml")
