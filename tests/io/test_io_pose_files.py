"""One pose file beside each image (issue 14, item 1): every format and rotation convention
against scipy's Rotation, and every bad file as one line naming it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from multieye.core.errors import DatasetError
from multieye.io.pose_files import (
    PoseFormat,
    check_rotation,
    check_values,
    read_pose_file,
)

R_TRUE = Rotation.from_euler("xyz", [30.0, -50.0, 120.0], degrees=True)
T_TRUE = np.eye(4)
T_TRUE[:3, :3] = R_TRUE.as_matrix()
T_TRUE[:3, 3] = [0.5, -0.2, 1.25]


def _write(tmp_path, name, content):
    p = tmp_path / name
    p.write_text(content if isinstance(content, str) else json.dumps(content))
    return p


def _text(numbers):
    return "\n".join(f"{v:.12g}" for v in numbers) + "\n"


@pytest.mark.parametrize("rotation, numbers", [
    ("quaternion-xyzw", list(R_TRUE.as_quat())),
    ("quaternion-wxyz", list(np.roll(R_TRUE.as_quat(), 1))),
    ("rotvec", list(R_TRUE.as_rotvec())),
    ("euler-xyz-deg", list(R_TRUE.as_euler("xyz", degrees=True))),
    ("euler-ZYX-rad", list(R_TRUE.as_euler("ZYX"))),
    ("euler-zyz-deg", list(R_TRUE.as_euler("zyz", degrees=True))),
])
@pytest.mark.parametrize("unit", ["m", "mm"])
def test_plain_numbers_every_rotation(tmp_path, rotation, numbers, unit):
    scale = 1000.0 if unit == "mm" else 1.0
    p = _write(tmp_path, "pos3.txt", _text(list(T_TRUE[:3, 3] * scale) + numbers))
    T = read_pose_file(p, PoseFormat(rotation=rotation, unit=unit))
    np.testing.assert_allclose(T, T_TRUE, atol=1e-9)


def test_values_give_the_order(tmp_path):
    """Open3DV's pos<k>.txt: Rx Ry Rz (degrees, extrinsic xyz) then X Y Z in millimetres."""
    angles = R_TRUE.as_euler("xyz", degrees=True)
    p = _write(tmp_path, "pos0.txt", _text(list(angles) + list(T_TRUE[:3, 3] * 1000)))
    fmt = PoseFormat(rotation="euler-xyz-deg", values=("rx", "ry", "rz", "x", "y", "z"),
                     unit="mm")
    np.testing.assert_allclose(read_pose_file(p, fmt), T_TRUE, atol=1e-9)
    # euler angles named by axis follow the axes, whatever the sequence
    zyx = R_TRUE.as_euler("zyx")                       # angles about z, y, x
    p = _write(tmp_path, "a.txt", _text([zyx[2], zyx[1], zyx[0], *T_TRUE[:3, 3]]))
    fmt = PoseFormat(rotation="euler-zyx-rad", values=("rx", "ry", "rz", "x", "y", "z"))
    np.testing.assert_allclose(read_pose_file(p, fmt), T_TRUE, atol=1e-9)
    q = R_TRUE.as_quat()
    p = _write(tmp_path, "b.csv", f"{q[3]}, {q[0]}, {q[1]}, {q[2]}, 0.5, -0.2, 1.25")
    fmt = PoseFormat(values=("qw", "qx", "qy", "qz", "x", "y", "z"))
    np.testing.assert_allclose(read_pose_file(p, fmt), T_TRUE, atol=1e-9)


def test_matrices(tmp_path):
    p = _write(tmp_path, "12.json", {"end2base": T_TRUE.tolist(), "joint_angles": [0] * 6})
    np.testing.assert_allclose(read_pose_file(p, PoseFormat(key="end2base")), T_TRUE, atol=1e-12)
    p = _write(tmp_path, "13.json", {"pose": {"matrix": T_TRUE[:3].tolist()}})
    np.testing.assert_allclose(read_pose_file(p, PoseFormat(key="pose.matrix")), T_TRUE,
                               atol=1e-12)
    p = _write(tmp_path, "14.txt", _text(T_TRUE.ravel()))        # 16 numbers: a matrix
    np.testing.assert_allclose(read_pose_file(p, PoseFormat()), T_TRUE, atol=1e-9)
    mm = T_TRUE.copy()
    mm[:3, 3] *= 1000
    p = _write(tmp_path, "15.txt", _text(mm[:3].ravel()))
    np.testing.assert_allclose(read_pose_file(p, PoseFormat(rotation="matrix", unit="mm")),
                               T_TRUE, atol=1e-9)


def test_json_object_of_named_numbers(tmp_path):
    rx, ry, rz = R_TRUE.as_euler("xyz")
    p = _write(tmp_path, "1.json", {"end_xyzrpy": {"x": 0.5, "y": -0.2, "z": 1.25, "rx": rx,
                                                   "ry": ry, "rz": rz}})
    fmt = PoseFormat(rotation="euler-xyz-rad", key="end_xyzrpy",
                     values=("x", "y", "z", "rx", "ry", "rz"))
    np.testing.assert_allclose(read_pose_file(p, fmt), T_TRUE, atol=1e-9)
    p = _write(tmp_path, "2.json", {"x": 0.5, "y": -0.2, "z": 1.25,
                                    **dict(zip(("qx", "qy", "qz", "qw"), R_TRUE.as_quat()))})
    np.testing.assert_allclose(read_pose_file(p, PoseFormat()), T_TRUE, atol=1e-9)
    p = _write(tmp_path, "3.json", list(T_TRUE[:3, 3]) + list(R_TRUE.as_quat()))
    np.testing.assert_allclose(read_pose_file(p, PoseFormat()), T_TRUE, atol=1e-9)


def test_rotation_and_values_names_are_checked():
    assert check_rotation("euler-XYZ-deg") == "euler-XYZ-deg"
    for bad in ("euler", "euler-xyz", "euler-xxz-deg", "euler-xYz-deg", "quaternion", 3):
        with pytest.raises(ValueError, match="expected|must not repeat"):
            check_rotation(bad)
    assert check_values(["rx", "ry", "rz", "x", "y", "z"], "euler-xyz-deg")
    with pytest.raises(ValueError, match="expected each of x, y, z, a1, a2, a3 once"):
        check_values(["rx", "ry", "rz", "x", "y", "z"], "euler-zyz-deg")
    with pytest.raises(ValueError, match="qw, qx, qy, qz"):
        check_values(["x", "y", "z", "qx", "qy", "qz"], "quaternion-xyzw")
    with pytest.raises(ValueError, match="leave out 'values'"):
        check_values(["x"], "matrix")


@pytest.mark.parametrize("name, content, fmt, message", [
    ("a.json", {"pose": [1, 2]}, PoseFormat(key="end2base"),
     "no key 'end2base' \\(mocap.key\\); its keys: pose"),
    ("a.json", {"end2base": [[1, 0, 0, 0]] * 3 + [[0, 0, 0, 1]]}, PoseFormat(key="end2base"),
     "expected a rotation matrix \\(orthonormal, det 1\\)"),
    ("a.json", {"end2base": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}, PoseFormat(key="end2base"),
     "expected a 4x4 \\(or 3x4\\) array, got rows of \\[3\\] numbers"),
    ("a.json", {"p": 1}, PoseFormat(key="p"), "expected the pose as numbers"),
    ("a.json", "{not json", PoseFormat(), "not a JSON file"),
    ("a.json", {"a": [1]}, PoseFormat(), "give mocap.key"),
    ("a.txt", "1 2 3 4 5 6 7\n", PoseFormat(rotation="euler-xyz-deg"),
     "expected 6 numbers \\(x y z a1 a2 a3; rotation euler-xyz-deg\\), got 7"),
    ("a.txt", "1 2 3 0 0 0 2\n", PoseFormat(), "quaternion \\(qx qy qz qw\\) must have unit norm"),
    ("a.txt", "0.7 0.1 0.1 0.7 0.9 0.8 1.4\n", PoseFormat(rotation="quaternion-wxyz"),
     "unit norm.* with the numbers read as x y z qw qx qy qz \\(values: in rig.yaml orders"),
    ("a.txt", "1 2 x 0 0 0 1\n", PoseFormat(), "expected numbers only, got 'x'"),
    ("a.txt", "1 2 nan 0 0 0 1\n", PoseFormat(), "expected finite numbers"),
    ("a.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n0 0 0 2\n", PoseFormat(), "last row is 0 0 0 1"),
    ("a.txt", "1 2 3 4 5 6 7 8 9\n", PoseFormat(rotation="matrix"),
     "expected 16 numbers \\(a 4x4 pose, row-major\\) or 12"),
    ("a.txt", "1e9 0 0 0 0 0 1\n", PoseFormat(unit="mm"), "absurd position"),
    ("a.json", {"x": 1, "y": 2, "z": 3}, PoseFormat(), "missing qx, qy, qz, qw"),
])
def test_bad_pose_files_name_the_file(tmp_path, name, content, fmt, message):
    p = _write(tmp_path, name, content)
    with pytest.raises(DatasetError, match=message) as info:
        read_pose_file(p, fmt)
    assert str(info.value).startswith(str(p)) and "\n" not in str(info.value)


def test_pose_table_matched_by_image_name(tmp_path):
    """OptiTrack-style w x y z quaternions in a table with an image column."""
    from multieye.io.pose_files import poses_by_table, read_pose_table

    q = R_TRUE.as_quat()
    t = tmp_path / "poses.csv"
    t.write_text("# exported\nImage, QW, QX, QY, QZ, X, Y, Z\n"
                 f"3.png, {q[3]}, {q[0]}, {q[1]}, {q[2]}, 500, -200, 1250\n"
                 f"4, 1, 0, 0, 0, 0, 0, 0\n"
                 f"9, 1, 0, 0, 0, 0, 0, 0\n")
    fmt = PoseFormat(rotation="quaternion-wxyz", unit="mm")
    rows = read_pose_table(t, fmt)
    np.testing.assert_allclose(rows["3.png"][0], T_TRUE, atol=1e-9)
    assert rows["4"][1] == 4
    images = [tmp_path / n for n in ("4.png", "3.png", "10.png")]
    matched, unmatched = poses_by_table(images, t, fmt)
    assert [p.name for p, _ in matched] == ["3.png", "4.png"]
    assert unmatched == [("10.png", "no row for it in poses.csv"),
                         ("poses.csv line 5", "pose row without an image: 9")]
    # without names the numbers follow values; 16 numbers a matrix
    t.write_text("image " + " ".join(f"c{i}" for i in range(16)) + "\n3 "
                 + " ".join(map(str, T_TRUE.ravel())) + "\n")
    np.testing.assert_allclose(read_pose_table(t, PoseFormat())["3"][0], T_TRUE, atol=1e-9)


def test_pose_table_in_image_order(tmp_path):
    """match: order: KUKA's RobotPosesVec.txt (no header, 16 numbers a row, mm), or a header
    naming the columns of values; rows follow the images in natural name order."""
    from multieye.io.pose_files import poses_by_order, read_order_table

    others = [Rotation.from_rotvec(v) for v in ([0.1, 0.2, 0.3], [-1.0, 0.5, 2.0])]
    poses = [T_TRUE] + [np.r_[np.c_[r.as_matrix(), [0.1 * k, 0.2, -0.3]], [[0, 0, 0, 1]]]
                        for k, r in enumerate(others)]
    mm = [T.ravel() * np.where(np.isin(np.arange(16), (3, 7, 11)), 1000, 1) for T in poses]
    t = _write(tmp_path, "RobotPosesVec.txt", "# KUKA\n" + "".join(
        " ".join(f"{v:.15g}" for v in row) + "\n" for row in mm))
    rows = read_order_table(t, PoseFormat(unit="mm"))
    assert [n for _, n in rows] == [2, 3, 4]
    for (T, _), want in zip(rows, poses):
        np.testing.assert_allclose(T, want, atol=1e-12)
    images = [tmp_path / n for n in ("pos10.png", "pos2.png", "pos9.png")]
    matched, unmatched = poses_by_order(images, t, PoseFormat(unit="mm"))
    assert [p.name for p, _ in matched] == ["pos2.png", "pos9.png", "pos10.png"]
    assert unmatched == []
    for (_, T), want in zip(matched, poses):
        np.testing.assert_allclose(T, want, atol=1e-12)
    # a header names the columns (any order); values without a header give the order
    q = [Rotation.from_matrix(T[:3, :3]).as_quat() for T in poses]
    t.write_text("qw;x;y;z;qx;qy;qz\n" + "".join(
        f"{w:.17g};{T[0, 3]:.17g};{T[1, 3]:.17g};{T[2, 3]:.17g};{x:.17g};{y:.17g};{z:.17g}\n"
        for (x, y, z, w), T in zip(q, poses)))
    for (T, _), want in zip(read_order_table(t, PoseFormat()), poses):
        np.testing.assert_allclose(T, want, atol=1e-12)
    t.write_text("".join(" ".join(repr(float(v)) for v in [*qq[[3, 0, 1, 2]], *T[:3, 3]])
                         + "\n" for qq, T in zip(q, poses)))
    fmt = PoseFormat(rotation="quaternion-wxyz", values=("qw", "qx", "qy", "qz", "x", "y", "z"))
    for (T, _), want in zip(read_order_table(t, fmt), poses):
        np.testing.assert_allclose(T, want, atol=1e-12)
    with pytest.raises(DatasetError, match="table has 3 pose rows and test_pose.*0/ 2 images") as e:
        poses_by_order(images[:2], t, fmt)
    assert "\n" not in str(e.value) and str(e.value).startswith(str(t))


@pytest.mark.parametrize("content, message, line", [
    ("name x y z qx qy qz qw\n", "expected a header with a column 'image'", 1),
    ("image x y z qx qy qz qw\na 1 2 3 0 0 0\n", "expected 8 cells", 2),
    ("image x y z qx qy qz qw\na 1 2 3 0 0 0 1\na 1 2 3 0 0 0 1\n",
     "image a has a pose on line 2 already", 3),
    ("image x y z qx qy qz qw\na 1 2 3 0 0 0 2\n", "quaternion", 2),
    ("image x y z qx qy qz qw\na 1 2 b 0 0 0 1\n", "expected numbers besides the image name", 2),
    ("image u v w\na 1 2 3\n", "expected the columns x, y, z, qx, qy, qz, qw besides image", 2),
])
def test_bad_pose_tables(tmp_path, content, message, line):
    from multieye.io.pose_files import read_pose_table

    t = _write(tmp_path, "poses.txt", content)
    with pytest.raises(DatasetError, match=message) as info:
        read_pose_table(t, PoseFormat())
    assert info.value.line == line and str(info.value).startswith(f"{t}:{line}:")


def test_stamped_table_in_any_order_and_rotation(tmp_path):
    """Rows stamped in time, e.g. OptiTrack's w x y z quaternions or Euler angles in mm."""
    from multieye.io.mocap import MocapSpec, read_mocap
    from multieye.io.stamped_table import read_stamped_table

    rots = Rotation.from_rotvec([[0.1, 0.2, 0.3], [0.5, -0.4, 0.2], [-1.0, 0.3, 2.0]])
    pos = np.array([[0.1, 0.2, 0.3], [1.0, -2.0, 0.5], [0.0, 0.4, -0.9]])
    q = rots.as_quat()
    lines = [f"{k * 0.01} {q[k, 3]} {q[k, 0]} {q[k, 1]} {q[k, 2]} "
             + " ".join(f"{v * 1000:.9f}" for v in pos[k]) for k in range(3)]
    lines.insert(1, "0.005 1 0 0 0 nan 0 0")                     # left out, listed
    p = _write(tmp_path, "take.txt", "# t qw qx qy qz x y z\n" + "\n".join(lines) + "\n")
    fmt = PoseFormat(rotation="quaternion-wxyz", values=("t", "qw", "qx", "qy", "qz", "x", "y",
                                                         "z"), unit="mm")
    traj = read_stamped_table(p, fmt)
    np.testing.assert_allclose(traj.stamps, [0, 0.01, 0.02])
    np.testing.assert_allclose(traj.T[:, :3, :3], rots.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(traj.T[:, :3, 3], pos, atol=1e-9)
    assert [(s.where, s.reason) for s in traj.skipped] == [("line 3",
                                                           "not a finite number: x = nan")]
    # the same through read_mocap, inverted on reading when stored the other way
    spec = MocapSpec(p, pose="T_marker_world", format="tum", unit="mm", values=fmt.values,
                     rotation=fmt.rotation)
    np.testing.assert_allclose(read_mocap(spec).T[1] @ traj.T[1], np.eye(4), atol=1e-9)
    e = rots.as_euler("ZYX", degrees=True)
    p = _write(tmp_path, "e.txt", "\n".join(f"{k} {pos[k, 0]} {pos[k, 1]} {pos[k, 2]} "
                                            f"{e[k, 0]} {e[k, 1]} {e[k, 2]}" for k in range(3)))
    traj = read_stamped_table(p, PoseFormat(rotation="euler-ZYX-deg"))
    np.testing.assert_allclose(traj.T[:, :3, :3], rots.as_matrix(), atol=1e-9)
    T = np.concatenate([rots.as_matrix(), pos[:, :, None]], axis=2)      # (3, 3, 4)
    p = _write(tmp_path, "m.txt", "\n".join(f"{k} " + " ".join(map(str, T[k].ravel()))
                                            for k in range(3)))
    traj = read_stamped_table(p, PoseFormat(rotation="matrix"))
    np.testing.assert_allclose(traj.T[:, :3], T, atol=1e-12)


@pytest.mark.parametrize("content, fmt, message, line", [
    ("0 1 2 3 0 0 0 0\n", PoseFormat(rotation="rotvec"), "must have 7 entries per row, got 8",
     1),
    ("0 0 0 0 1 0 0 0\n1 0 0 0 3 0 0 0\n", PoseFormat(rotation="quaternion-wxyz"),
     "quaternion", 2),
    ("0 1 0 0 0 1 0 0 0 0 1 0\n1 1 0 0 0 1 0 0 0 0 2 0\n", PoseFormat(rotation="matrix"),
     "must have 13 entries", 1),
    ("0 1 0 0 0 0 1 0 0 0 0 1 0\n1 1 0 0 0 0 2 0 0 0 0 1 0\n", PoseFormat(rotation="matrix"),
     "expected a rotation matrix", 2),
    ("1 0 0 0 0 0 0\n0 0 0 0 0 0 0\n", PoseFormat(rotation="rotvec"), "time stamp goes back", 2),
])
def test_bad_stamped_tables(tmp_path, content, fmt, message, line):
    from multieye.io.stamped_table import read_stamped_table

    p = _write(tmp_path, "take.txt", content)
    with pytest.raises(DatasetError, match=message) as info:
        read_stamped_table(p, fmt)
    assert info.value.line == line and str(info.value).startswith(f"{p}:{line}:")


def test_stamped_table_in_integer_nanoseconds(tmp_path):
    """EuRoC-style stamps (19 digits) in a table given ``values:``: read as nanoseconds, as in
    TUM files; every row was left out as an absurd stamp before."""
    from multieye.io.stamped_table import read_stamped_table

    rows = [f"{1403636579763555584 + k * 5_000_000},{k * 0.1},0,0,1,0,0,0" for k in range(4)]
    p = _write(tmp_path, "take.csv", "# t x y z qw qx qy qz\n" + "\n".join(rows) + "\n")
    fmt = PoseFormat(rotation="quaternion-wxyz",
                     values=("t", "x", "y", "z", "qw", "qx", "qy", "qz"))
    traj = read_stamped_table(p, fmt)
    np.testing.assert_allclose(np.diff(traj.stamps), 0.005, atol=1e-6)
    assert abs(traj.stamps[0] - 1403636579.763555584) < 1e-6
    np.testing.assert_allclose(traj.T[:, 0, 3], [0, 0.1, 0.2, 0.3])
    # the stamp's column is found where values put it
    rows = [f"0,0,{k * 0.1},{1403636579763555584 + k * 5_000_000},1,0,0,0" for k in range(4)]
    p = _write(tmp_path, "take2.csv", "\n".join(rows) + "\n")
    fmt = PoseFormat(rotation="quaternion-wxyz",
                     values=("x", "y", "z", "t", "qw", "qx", "qy", "qz"))
    np.testing.assert_allclose(read_stamped_table(p, fmt).stamps, traj.stamps)


@pytest.mark.parametrize("axes", ["xyz", "ZYX", "yxz"])
def test_json_euler_angles_named_by_axis_without_values(tmp_path, axes):
    """``rotation: euler-...`` alone reads a mapping's ``rx ry rz`` as the angles about x, y,
    z (docs/rig-yaml.md, section 4), as a robot toolkit's ``end_xyzrpy`` holds them; before,
    only ``a1 a2 a3`` were accepted unless ``values`` was given too."""
    angles = R_TRUE.as_euler(axes)
    by_axis = dict(zip(["r" + a for a in axes.lower()], angles))
    p = _write(tmp_path, "1.json", {"end_xyzrpy": {"x": 0.5, "y": -0.2, "z": 1.25, **by_axis}})
    fmt = PoseFormat(rotation=f"euler-{axes}-rad", key="end_xyzrpy")
    np.testing.assert_allclose(read_pose_file(p, fmt), T_TRUE, atol=1e-9)
    p = _write(tmp_path, "2.json", {"x": 0.5, "y": -0.2, "z": 1.25,
                                    **dict(zip(("a1", "a2", "a3"), angles))})
    np.testing.assert_allclose(read_pose_file(p, PoseFormat(rotation=f"euler-{axes}-rad")),
                               T_TRUE, atol=1e-9)


@pytest.mark.parametrize("match", ["order", "image"])
def test_a_pose_table_row_of_nan_or_inf_leaves_its_image_out(tmp_path, match):
    """A row of a pose table holding ``nan`` or ``inf`` (a robot's or tracker's dropout, as
    young_mocap_cam's pose_quat.txt with one value lost) leaves its image out, listed with the
    table's line, and keeps every other pairing (``match: order`` keeps the row's place), as
    TUM rows are; before, the whole run stopped (exit 2)."""
    from multieye.io.pose_files import poses_by_order, poses_by_table

    q = Rotation.from_matrix(T_TRUE[:3, :3]).as_quat()
    row = " ".join(f"{v:.17g}" for v in [*T_TRUE[:3, 3], *q])
    images = [tmp_path / f"pos{k}.png" for k in range(3)]
    if match == "order":
        t = _write(tmp_path, "poses.txt", f"{row}\n{row.replace(row.split()[1], 'nan', 1)}\n"
                   f"{row}\n")
        matched, unmatched = poses_by_order(images, t, PoseFormat(values=(
            "x", "y", "z", "qx", "qy", "qz", "qw")))
    else:
        t = _write(tmp_path, "poses.txt", "image x y z qx qy qz qw\n" + "".join(
            f"pos{k}.png {row if k != 1 else row.replace(row.split()[2], 'inf', 1)}\n"
            for k in range(3)))
        matched, unmatched = poses_by_table(images, t, PoseFormat())
    assert [p.name for p, _ in matched] == ["pos0.png", "pos2.png"]
    for _, T in matched:
        np.testing.assert_allclose(T, T_TRUE, atol=1e-12)
    assert unmatched == [("pos1.png", "pose row left out: poses.txt line 2 holds nan or inf"
                          if match == "order" else
                          "pose row left out: poses.txt line 3 holds nan or inf")]


def test_a_pose_file_of_nan_or_inf_leaves_its_image_out(tmp_path):
    """A tracking dropout written as ``nan`` in one image's pose file leaves that image out,
    named with its file, as a pose table's row of such values does (README: a single bad pose
    row does not stop the run); before, the run stopped with exit 2 on that file."""
    from multieye.io.pose_files import poses_by_name

    fmt = PoseFormat(key="end2base")
    images = []
    for k in range(4):
        T = T_TRUE.copy()
        T[0, 3] += 0.01 * k
        if k == 2:
            T[0, 3] = float("nan")
        _write(tmp_path, f"{k}.json", {"end2base": T.tolist()})
        images.append(_write(tmp_path, f"{k}.png", "x"))
    matched, unmatched = poses_by_name(images, "{stem}.json", fmt)
    assert [p.name for p, _ in matched] == ["0.png", "1.png", "3.png"]
    np.testing.assert_allclose(matched[2][1][0, 3], T_TRUE[0, 3] + 0.03)
    assert unmatched == [("2.png", "pose file 2.json holds nan or inf")]
    with pytest.raises(DatasetError, match="expected finite numbers"):     # one file alone
        read_pose_file(tmp_path / "2.json", fmt)


def test_a_kitti_pose_table_of_12_numbers_a_row_is_a_matrix(tmp_path):
    """KITTI's poses/NN.txt: the top three rows of each 4x4, 12 numbers a row, no header, no
    stamps (docs: '16 (or 12) numbers of a matrix'); 12 were refused as 'expected the numbers
    x, y, z, qx, qy, qz, qw ... or 16 numbers', unless rotation: matrix was given."""
    from multieye.io.pose_files import read_order_table, read_pose_table

    t = _write(tmp_path, "00.txt", "".join(" ".join(f"{v:.6e}" for v in T_TRUE[:3].ravel())
                                          + "\n" for _ in range(3)))
    rows = read_order_table(t, PoseFormat())
    assert [n for _, n in rows] == [1, 2, 3]
    for T, _ in rows:
        np.testing.assert_allclose(T, T_TRUE, atol=1e-6)
    # matched by image: 'image' and 12 names, any names
    t = _write(tmp_path, "poses.csv", "image," + ",".join(f"r{k}" for k in range(12)) + "\n"
               + "1.png," + ",".join(repr(float(v)) for v in T_TRUE[:3].ravel()) + "\n")
    np.testing.assert_allclose(read_pose_table(t, PoseFormat())["1.png"][0], T_TRUE, atol=1e-15)


def test_a_pose_table_with_decimal_commas_says_so(tmp_path):
    """European Excel's CSV (semicolons, decimal commas): the message named the cell only."""
    from multieye.io.pose_files import read_pose_table

    t = _write(tmp_path, "poses.csv", "image;x;y;z;qx;qy;qz;qw\n1.png;0,5;0;0;0;0;0;1\n")
    with pytest.raises(DatasetError, match=r"poses\.csv:2: expected numbers besides the image "
                                           r"name, got '0,5'; a decimal comma: write numbers "
                                           r"with a decimal point"):
        read_pose_table(t, PoseFormat())
