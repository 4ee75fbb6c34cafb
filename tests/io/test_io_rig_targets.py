"""rig.yaml's ``targets:`` (several boards, each with its identity): read, and refused with one
line at the key concerned (multieye.io.rig_targets)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from click.testing import CliRunner

from multieye.cli import main
from multieye.core.errors import DatasetError
from multieye.io.rig import load_rig

CHARUCO = "{type: charuco, rows: 5, cols: 7, spacing: 0.16, marker_size: 0.12, dictionary: DICT_4X4_100"

GOOD = """\
targets:
  - name: north
    type: charuco
    rows: 5
    cols: 7
    spacing: 0.16
    marker_size: 0.12
    dictionary: DICT_4X4_100
  - name: west
    type: charuco
    rows: 5
    cols: 7
    spacing: 0.16
    marker_size: 0.12
    dictionary: DICT_4X4_100
    first_id: 20
  - name: door
    type: chessboard
    rows: 6
    cols: 9
    spacing: 0.1
    cameras: [cam1]
    pose: [[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
"""
CAMS = ("cameras:\n  cam0: {intrinsics: cam.yaml, images: cam0/}\n"
        "  cam1: {intrinsics: cam.yaml, images: cam1/}\n")
CHESS = "{type: chessboard, rows: 6, cols: 9, spacing: 0.1"


def _write(tmp_path, text: str):
    for cam in ("cam0", "cam1"):
        (tmp_path / cam).mkdir(exist_ok=True)
    (tmp_path / "cam.yaml").write_text(
        "camera_model: pinhole\nintrinsics: [400, 400, 320, 240]\ndistortion_model: radtan\n"
        "distortion_coeffs: [0, 0, 0, 0]\nresolution: [640, 480]\n")
    (tmp_path / "rig.yaml").write_text(text)
    return tmp_path


def test_targets_are_read_by_name_in_file_order(tmp_path):
    rig = load_rig(_write(tmp_path, GOOD + CAMS))
    assert list(rig.targets) == ["north", "west", "door"]
    north, west, door = rig.targets.values()
    assert rig.target is north and north.name == "north"
    assert (north.first_id, west.first_id) == (None, 20)
    assert door.type == "chessboard" and door.cameras == ("cam1",)
    assert door.pose[0] == (1.0, 0.0, 0.0, 0.5)
    assert door.sees("cam1") and not door.sees("cam0") and north.sees("cam0")
    assert north.cameras is None and north.pose is None


def test_target_stays_one_board_named_target(tmp_path):
    rig = load_rig(_write(tmp_path, "target: " + CHESS + "}\n" + CAMS))
    assert list(rig.targets) == ["target"] and rig.target is rig.targets["target"]
    assert rig.target.name == "target" and rig.target.cameras is None


def _entry(name: str, extra: str = "", kind: str = CHARUCO) -> str:
    return f"  - {{name: {name}, {kind[1:]}{extra}}}\n"



@pytest.mark.parametrize("targets, key, message", [
    (_entry("a") + _entry("b"), "targets.1",
     "targets a and b overlap in marker ids (ids 0-16 and ids 0-16 of 4X4)"),
    (_entry("a", ", first_id: 10") + _entry("b", ", first_id: 20"), "targets.1",
     "targets a and b overlap in marker ids (ids 10-26 and ids 20-36"),
    (_entry("a") + _entry("b", ", first_id: 3", "{type: aruco-grid, rows: 2, cols: 2, "
                          "marker_size: 0.1, marker_separation: 0.02, dictionary: DICT_4X4_50"),
     "targets.1", "targets a and b overlap in marker ids (ids 0-16 and ids 3-6 of 4X4)"),
    (_entry("a") + _entry("b", ", id: 16", "{type: aruco, marker_size: 0.1, dictionary: DICT_4X4_1000"),
     "targets.1", "overlap in marker ids (ids 0-16 and id 16 of 4X4)"),
    (_entry("a", "", "{type: aprilgrid, rows: 4, cols: 4, spacing: 0.05, tag_spacing: 0.3")
     + _entry("b", ", first_id: 15", "{type: aprilgrid, rows: 2, cols: 2, spacing: 0.05, "
              "tag_spacing: 0.3"), "targets.1",
     "targets a and b overlap in marker ids (ids 0-15 and ids 15-18 of APRILTAG_36h11)"),
    (_entry("a") + _entry("a", ", first_id: 20"), "targets.1.name", "target name 'a'"),
    (_entry("a") + "  - {" + CHARUCO[1:] + ", first_id: 20}\n", "targets.1", "missing key 'name'"),
    (_entry("a") + _entry("c", "", CHESS), "targets.1",
     "a chessboard has no ids to tell it from the other targets: give 'cameras'"),
    (_entry("c", ", cameras: [cam0]", CHESS) + _entry("d", ", cameras: [cam1, cam0]", CHESS),
     "targets.1.cameras", "camera cam0 sees targets c and d, neither has ids"),
    (_entry("a", ", cameras: [cam7]"), "targets.0.cameras", "no camera 'cam7' in cameras (cam0, cam1)"),
    (_entry("a", ", cameras: cam0"), "targets.0.cameras", "expected a list of camera names"),
    (_entry("a") + _entry("b", ", first_id: 20, pose: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 2, 0], "
                          "[0, 0, 0, 1]]"), "targets.1.pose", "not a rigid transform"),
    (_entry("a") + _entry("b", ", first_id: 20, pose: [1, 2, 3]"), "targets.1.pose",
     "expected the board's pose in the first board's frame as 4 rows of 4 numbers"),
    (_entry("a", ", pose: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"),
     "targets.0.pose", "the first target is the frame the others' poses are given in"),
    (_entry("a", ", colour: red"), "targets.0.colour", "unknown key"),
])
def test_bad_targets_name_the_key_and_what_was_expected(tmp_path, targets, key, message):
    path = _write(tmp_path, "targets:\n" + targets + CAMS) / "rig.yaml"
    with pytest.raises(DatasetError) as info:
        load_rig(path)
    text = str(info.value)
    assert f"{key}:" in text and message in text, text
    assert "\n" not in text and "rig.yaml:" in text


@pytest.mark.parametrize("text, message", [
    ("target: " + CHESS + "}\ntargets:\n" + _entry("a"), "give either 'target'"),
    ("targets: []\n", "expected a list of targets"),
    ("targets: {a: 1}\n", "expected a list of targets"),
    ("targets:\n  - 3\n", "expected a mapping (a target with its name)"),
])
def test_targets_key_itself(tmp_path, text, message):
    with pytest.raises(DatasetError, match="targets") as info:
        load_rig(_write(tmp_path, text + CAMS))
    assert message in str(info.value)


def test_a_single_entry_needs_no_name_and_different_families_may_share_ids(tmp_path):
    rig = load_rig(_write(tmp_path, "targets:\n  - " + CHARUCO + "}\n" + CAMS))
    assert list(rig.targets) == ["target"]
    april = "{type: aprilgrid, rows: 4, cols: 4, spacing: 0.05, tag_spacing: 0.3"
    rig = load_rig(_write(tmp_path, "targets:\n" + _entry("a") + _entry("b", "", april)
                          + _entry("c", "", "{type: charuco, rows: 5, cols: 7, spacing: 0.16, "
                                   "marker_size: 0.12, dictionary: DICT_5X5_100") + CAMS))
    assert list(rig.targets) == ["a", "b", "c"]


def test_overlapping_ids_exit_2_with_one_line_and_nothing_written(tmp_path):
    ds = _write(tmp_path, "targets:\n" + _entry("north") + _entry("west", ", first_id: 10") + CAMS)
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out)])
    assert res.exit_code == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr
    assert "north" in lines[0] and "west" in lines[0] and "rig.yaml:" in lines[0], lines[0]
    assert not out.exists() or not any(out.iterdir())


def test_the_documented_example_loads(tmp_path):
    """docs/rig-yaml.md section 3.1's example, as written there."""
    doc = (Path(__file__).parents[2] / "docs" / "rig-yaml.md").read_text()
    start = doc.index("### 3.1")
    begin = doc.index("```yaml", start) + len("```yaml")
    block = textwrap.dedent(doc[begin:doc.index("```", begin)])
    rig = load_rig(_write(tmp_path, block))
    assert list(rig.targets) == ["north", "west", "south", "door"]
