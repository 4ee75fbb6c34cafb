"""Trajectory type and TUM files: exact round trips and messages naming file and line."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from multieye.core import geometry
from multieye.core.errors import DatasetError, InputError
from multieye.io.trajectory import Trajectory
from multieye.io.tum import read_tum, write_tum


def _traj(rng, n=5, **kw):
    stamps = np.cumsum(rng.uniform(0.01, 0.5, n)) + 1.7e9
    return Trajectory(stamps, geometry.random_transforms(rng, n), "world", "marker", **kw)


# --------------------------------------------------------------------------- Trajectory


def test_trajectory_names_and_inverse(rng):
    traj = _traj(rng)
    inv = traj.inverted()
    assert (traj.name, inv.name) == ("T_world_marker", "T_marker_world")
    assert np.allclose(inv.T @ traj.T, np.eye(4), atol=1e-12)
    assert len(inv) == 5


def test_trajectory_rejects_duplicates_and_disorder(rng):
    T = geometry.random_transforms(rng, 3)
    with pytest.raises(InputError, match=r"duplicate time stamp: sample 2 at 1.0 s follows"):
        Trajectory(np.array([0.0, 1.0, 1.0]), T)
    with pytest.raises(InputError, match="out of order"):
        Trajectory(np.array([0.0, 2.0, 1.0]), T)
    with pytest.raises(InputError, match="duplicate time stamp"):
        Trajectory.from_unsorted(np.array([1.0, 0.0, 1.0]), T)


def test_from_unsorted_sorts_poses_with_their_stamps(rng):
    T = geometry.random_transforms(rng, 3)
    traj = Trajectory.from_unsorted([2.0, 0.0, 1.0], T, stamps_ns=[2_000_000_000, 0,
                                                                   1_000_000_000])
    assert traj.stamps.tolist() == [0.0, 1.0, 2.0]
    assert np.array_equal(traj.T, T[[1, 2, 0]])
    assert traj.stamps_ns.tolist() == [0, 1_000_000_000, 2_000_000_000]


def test_trajectory_rejects_non_rigid_and_bad_shapes(rng):
    T = geometry.random_transforms(rng, 2)
    T[1, :3, :3] *= 1.01
    with pytest.raises(InputError, match="pose 1 is not a rigid transform"):
        Trajectory([0.0, 1.0], T)
    with pytest.raises(InputError, match="2 stamps but 3 poses"):
        Trajectory([0.0, 1.0], geometry.random_transforms(rng, 3))
    with pytest.raises(InputError, match="stamps_ns and stamps disagree"):
        Trajectory([0.0, 1.0], geometry.random_transforms(rng, 2), stamps_ns=[0, 2])


# --------------------------------------------------------------------------- TUM reading


def test_reads_spaces_commas_comments_and_blank_lines(tmp_path):
    q = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_quat()  # x y z w
    text = ("# t tx ty tz qx qy qz qw\n\n"
            f"1.5 1 2 3 {q[0]} {q[1]} {q[2]} {q[3]}   # first\n"
            f"2.5,4,5,6,0,0,0,1\n"
            f"  3.5 ,\t7, 8 ,9, 0, 0, 0, 1\n")
    (tmp_path / "m.txt").write_text(text)
    traj = read_tum(tmp_path / "m.txt", parent="world", child="body")
    assert traj.name == "T_world_body"
    assert traj.stamps.tolist() == [1.5, 2.5, 3.5]
    assert traj.T[:, :3, 3].tolist() == [[1, 2, 3], [4, 5, 6], [7, 8, 9]]
    assert np.allclose(traj.T[0, :3, :3], Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(),
                       atol=1e-15)
    assert np.array_equal(traj.T[1, :3, :3], np.eye(3))


def test_millimetres_are_converted(tmp_path):
    (tmp_path / "m.txt").write_text("0 1000 -250 5 0 0 0 1\n")
    assert read_tum(tmp_path / "m.txt", unit="mm").T[0, :3, 3].tolist() == [1.0, -0.25, 0.005]


def test_small_quaternion_deviation_is_normalised(tmp_path):
    (tmp_path / "m.txt").write_text("0 0 0 0 0 0 0.7072 0.7072\n")  # norm 1.00014
    R = read_tum(tmp_path / "m.txt").T[0, :3, :3]
    assert np.allclose(R, Rotation.from_euler("z", 90, degrees=True).as_matrix(), atol=1e-12)


@pytest.mark.parametrize("body, line, message", [
    ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n",
     2, "TUM trajectory files must have 8 entries per row, got 7"),
    ("# c\n0 0 0 zero 0 0 0 1\n", 2, "expected a number for tz, got 'zero'"),
    ("# c\n1 0 0 0 0 0 0 nan\n2 inf 0 0 0 0 0 1\n", 2,
     r"no usable pose: all 2 rows left out; line 2: not a finite number: qw = nan"),
    ("0 0 0 0 0 0 0 1\n\n1 0 0 0 0.1 0 0 1.2\n", 3,
     r"quaternion \(qx qy qz qw\) must have unit norm, got norm 1.20416"),
    ("0 0 0 0 0 0 0 1\n0 0 0 0 0 0 0 1\n", 2, "duplicate time stamp: 0.0 s after 0.0 s on line 1"),
    ("5 0 0 0 0 0 0 1\n4 0 0 0 0 0 0 1\n", 2, "time stamp goes back"),
])
def test_malformed_files_name_file_and_line(tmp_path, body, line, message):
    path = tmp_path / "mocap.txt"
    path.write_text(body)
    with pytest.raises(DatasetError, match=message) as info:
        read_tum(path)
    assert info.value.line == line
    assert str(info.value).startswith(f"{path}:{line}: ")


def test_non_finite_and_absurd_rows_are_left_out_with_their_line(tmp_path):
    rows = ["0 0 0 0 0 0 0 1", "1 0 0 0 0 0 0 nan", "2 1e308 0 0 0 0 0 1", "3 0 -2e4 0 0 0 0 1",
            "4 0 0 0 0 0 0 1", "1e12 0 0 0 0 0 0 1", "5 0 0 inf 0 0 0 1", "6 0 0 0 0 0 0 1"]
    (tmp_path / "m.txt").write_text("# header\n" + "\n".join(rows) + "\n")
    traj = read_tum(tmp_path / "m.txt")
    assert traj.stamps.tolist() == [0.0, 4.0, 6.0]
    assert [(s.line, s.row) for s in traj.skipped] == [(3, 2), (4, 3), (5, 4), (7, 6), (8, 7)]
    assert [s.reason for s in traj.skipped] == [
        "not a finite number: qw = nan",
        "absurd position: tx = 1e+308 m, beyond 10000 m",
        "absurd position: ty = -20000 m, beyond 10000 m",
        "absurd time stamp: t = 1e+12 s, beyond 1e+10 s",
        "not a finite number: tz = inf"]
    assert traj.skipped[0].where == "line 3"
    assert traj.inverted().skipped == traj.skipped
    # in millimetres the bound applies after the conversion: 2e6 mm = 2 km is kept
    (tmp_path / "mm.txt").write_text("0 2e6 0 0 0 0 0 1\n1 2e7 0 0 0 0 0 1\n")
    traj = read_tum(tmp_path / "mm.txt", unit="mm")
    assert traj.T[:, 0, 3].tolist() == [2000.0] and len(traj.skipped) == 1


def test_duplicates_can_be_dropped_but_steps_back_cannot(tmp_path):
    (tmp_path / "d.txt").write_text("0 0 0 0 0 0 0 1\n0.01 1 0 0 0 0 0 1\n0.01 2 0 0 0 0 0 1\n"
                                    "0.02 3 0 0 0 0 0 1\n")
    traj = read_tum(tmp_path / "d.txt", duplicates="drop")
    assert traj.stamps.tolist() == [0.0, 0.01, 0.02]
    assert traj.T[:, 0, 3].tolist() == [0.0, 1.0, 3.0]  # the first of equal stamps is kept
    (tmp_path / "b.txt").write_text("0 0 0 0 0 0 0 1\n0.02 1 0 0 0 0 0 1\n0.01 2 0 0 0 0 0 1\n")
    with pytest.raises(DatasetError, match="time stamp goes back") as info:
        read_tum(tmp_path / "b.txt", duplicates="drop")
    assert info.value.line == 3


def test_real_eth_streams_read_as_tum(shared_data):
    """ETH ASL hand-eye CSV streams are TUM rows with commas (ethz_handeye/PROVENANCE.md);
    the Vicon stream of prime_sense_1 prints stamps with too few digits for its rate."""
    root = shared_data / "ethz_handeye" / "datasets" / "unzipped"
    robot = root / "robot_arm_w_color_camera_real" / "robot_arm"
    hand = read_tum(robot / "robot_arm_complete_bag_color_and_ir_base_link_sr300_hinge.csv",
                    parent="base", child="hand")
    eye = read_tum(robot / "robot_arm_complete_bag_color_and_ir_target_ir.csv",
                   parent="target", child="cam")
    assert (len(hand), len(eye)) == (2817, 1703)  # row counts stated in PROVENANCE.md
    vicon = root / "prime_sense_color_w_vicon_1" / "prime_sense_1" / \
        "2017-04-09-18-13-10_vicon_prime_sense.csv"
    with pytest.raises(DatasetError, match="duplicate time stamp"):
        read_tum(vicon)
    stamps = [line.split(",")[0] for line in vicon.read_text().splitlines() if line.strip()]
    repeats = sum(a == b for a, b in zip(stamps, stamps[1:]))
    traj = read_tum(vicon, duplicates="drop")
    assert repeats > 0 and len(traj) == 7093 - repeats
    # poses are rigid and in metres: the camera moved within a room-sized volume
    assert np.all(np.abs(traj.T[:, :3, 3]) < 10)


def test_missing_empty_and_binary_files(tmp_path):
    with pytest.raises(DatasetError, match="trajectory file not found"):
        read_tum(tmp_path / "none.txt")
    (tmp_path / "empty.txt").write_text("# only a comment\n\n")
    with pytest.raises(DatasetError, match="no rows: expected lines"):
        read_tum(tmp_path / "empty.txt")
    (tmp_path / "bin.txt").write_bytes(b"0 0 0 0 0 0 0 1\n\xff\xfe\n")
    with pytest.raises(DatasetError, match="not a UTF-8 text file") as info:
        read_tum(tmp_path / "bin.txt")
    assert info.value.line == 2
    with pytest.raises(DatasetError, match="length unit must be one of m, cm, mm"):
        read_tum(tmp_path / "empty.txt", unit="inch")


# --------------------------------------------------------------------------- round trips


def test_round_trip_keeps_nanosecond_stamps_exactly(tmp_path, rng):
    ns = np.array([1_700_000_000_000_000_001, 1_700_000_000_123_456_789, 1_700_000_001_000_000_000])
    traj = Trajectory(ns / 1e9, geometry.random_transforms(rng, 3), stamps_ns=ns)
    write_tum(tmp_path / "t.txt", traj)
    lines = (tmp_path / "t.txt").read_text().splitlines()
    assert lines[0].startswith("# T_world_marker")
    assert [line.split()[0] for line in lines[1:]] == [
        "1700000000.000000001", "1700000000.123456789", "1700000001.000000000"]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 20),
       unit=st.sampled_from(["m", "cm", "mm"]))
def test_write_read_round_trip(tmp_path_factory, seed, n, unit):
    rng = np.random.default_rng(seed)
    stamps = np.cumsum(rng.uniform(1e-6, 10.0, n)) + rng.uniform(0, 2e9)
    T = geometry.random_transforms(rng, n, translation_scale=rng.uniform(0.01, 100))
    traj = Trajectory(stamps, T, "cam", "target")
    path = tmp_path_factory.mktemp("tum") / "poses.txt"
    write_tum(path, traj, unit=unit)
    back = read_tum(path, unit=unit, parent="cam", child="target")
    assert np.array_equal(back.stamps, traj.stamps)  # repr is exact
    assert np.abs(back.T - traj.T).max() < 1e-12 * max(1.0, np.abs(T).max())
    assert back.name == "T_cam_target"


# --------------------------------------------------------------------------- lines in blocks


def _line_blocks_one_by_one(path, size):
    """The reference: :func:`text_lines` (a line at a time) gathered ``size`` at a time."""
    from multieye.io.textfile import text_lines

    contents, numbers = [], []
    for number, content in text_lines(path):
        contents.append(content)
        numbers.append(number)
        if len(contents) == size:
            yield contents, numbers
            contents, numbers = [], []
    if contents:
        yield contents, numbers


def _outcome(blocks):
    """Every block given, then the error's text (or None)."""
    got = []
    try:
        for block in blocks:
            got.append(block)
    except DatasetError as exc:
        return got, str(exc)
    return got, None


LONG = "1.5 " * 40_000     # lines of 160 kB: a file over several blocks of bytes


@pytest.mark.parametrize("body", [
    b"\xef\xbb\xbf# header\r\n1 2 3\r\n\r\n   \n4 5 6 # note\n\t7 8 9\t\n10 11 12",
    b"1 2\n# only a comment\n\n3 4\n",
    b"",
    b"\n\n#\n",
    (LONG + "\n") .encode() * 20 + b"# end\n9 9\n",
    b"1 2\n3 4\n5 \xff 6\n7 8\n",                             # not UTF-8 on line 3
    (LONG + "\n").encode() * 10 + b"1 \xe2\x82\n2\n",        # ... far into the file
    b"1 2\n\xe2\x82\xac 3 # a euro sign\n",
])
@pytest.mark.parametrize("size", [1, 2, 3, 1 << 14])
def test_line_blocks_read_in_blocks_of_bytes_give_what_line_by_line_gives(tmp_path, body,
                                                                          size):
    from multieye.io.textfile import line_blocks

    path = tmp_path / "t.txt"
    path.write_bytes(body)
    fast = _outcome(line_blocks(path, size=size))
    assert fast == _outcome(_line_blocks_one_by_one(path, size))
    if b"\xff" in body or b"\xe2\x82\n" in body:     # the error names its line
        assert fast[1] is not None and "not a UTF-8 text file" in fast[1]


def test_a_header_row_says_to_make_it_a_comment(tmp_path):
    """A poses file with a CSV-style header (t,x,y,z,qx,qy,qz,qw): the message named only
    the cell 't'; a row with a bad cell below rows of numbers keeps naming that cell."""
    path = tmp_path / "poses.csv"
    path.write_text("t,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n")
    with pytest.raises(DatasetError, match=r"first row is not numbers but names, a header "
                       r"\(t x y z qx qy qz qw\): TUM trajectory files hold numbers only; "
                       "start the line with # to make it a comment") as info:
        read_tum(path)
    assert info.value.line == 1
    path.write_text("# t,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n")
    assert len(read_tum(path).stamps) == 1
    path.write_text("0,0,0,0,0,0,0,1\n1,0,0,0,0,0,0,one\n")
    with pytest.raises(DatasetError, match="expected a number for qw, got 'one'"):
        read_tum(path)


def test_stamps_in_integer_nanoseconds_are_read_as_image_names_are(tmp_path):
    """EuRoC/Kalibr-style stamps (19 digits of nanoseconds): every row was left out as an
    absurd stamp of 1.7e18 s. 16 to 19 digits are nanoseconds, as in image names; 11 to 15
    stay refused (ambiguous)."""
    path = tmp_path / "m.txt"
    path.write_text("1700000000000000000 0 0 0 0 0 0 1\n1700000000500000000,1,0,0,0,0,0,1\n")
    traj = read_tum(path)
    np.testing.assert_allclose(traj.stamps, [1.7e9, 1.7e9 + 0.5], rtol=0, atol=1e-6)
    path.write_text("1700000000000 0 0 0 0 0 0 1\n1700000000500 1 0 0 0 0 0 1\n")
    with pytest.raises(DatasetError, match="no usable pose: all 2 rows left out; line 1: absurd "
                       "time stamp.*; every stamp in milliseconds or microseconds"):
        read_tum(path)


def test_semicolons_read_and_other_rows_say_what_they_may_be(tmp_path, rng):
    """Semicolons separate TUM numbers as commas do (European spreadsheet exports; refused
    before with 'got 1'); decimal commas, rows of 7 numbers (a rotation vector or Euler
    angles), 13 or 17 (a matrix) are one line that says what to write in rig.yaml; a stamped
    4x4 (17 numbers) is read with rotation: matrix, as the 3x4 (13) is."""
    from multieye.io.mocap import MocapSpec, read_mocap

    T = geometry.random_transforms(rng, 3)
    q = geometry.quat_from_transform(T)
    rows = [[k + 0.5, *T[k, :3, 3].tolist(), *q[k].tolist()] for k in range(3)]
    (tmp_path / "semi.txt").write_text("".join(";".join(map(repr, r)) + "\n" for r in rows))
    np.testing.assert_allclose(read_tum(tmp_path / "semi.txt").T, T, atol=1e-12)
    (tmp_path / "comma.txt").write_text("".join(
        " ".join(repr(v).replace(".", ",") for v in r) + "\n" for r in rows))
    with pytest.raises(DatasetError, match=r"comma.txt:1: .*got 16 .*decimal commas"):
        read_tum(tmp_path / "comma.txt")
    for name, numbers, hint in (("rv", [0.5, 1, 2, 3, 0.1, 0.2, 0.3], "rotation: rotvec"),
                                ("m12", [0.5, *T[0, :3].ravel().tolist()], "rotation: matrix"),
                                ("m16", [0.5, *T[0].ravel().tolist()], "rotation: matrix")):
        (tmp_path / f"{name}.txt").write_text(" ".join(map(repr, numbers)) + "\n")
        with pytest.raises(DatasetError, match=f"got {len(numbers)} .*{hint}"):
            read_tum(tmp_path / f"{name}.txt")
    (tmp_path / "m16.txt").write_text("".join(
        " ".join(map(repr, [k + 0.5, *T[k].ravel().tolist()])) + "\n" for k in range(3)))
    traj = read_mocap(MocapSpec(tmp_path / "m16.txt", format="tum", rotation="matrix"))
    np.testing.assert_allclose(traj.T, T, atol=1e-12)
