"""Generic CSV, OptiTrack Motive and Vicon Nexus exports, and the read_mocap dispatcher.

The export files are written here following the layouts documented in
multieye/io/mocap_csv.py, from poses with a known answer.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from multieye.core import geometry
from multieye.core.errors import DatasetError
from multieye.io.mocap import MocapSpec, read_mocap, sniff_mocap_format
from multieye.io.mocap_csv import read_pose_csv
from multieye.io.mocap_exports import read_optitrack_csv, read_vicon_csv


@pytest.fixture
def poses(rng):
    """(stamps s, T_world_body (N,4,4)) with translations of a metre or so."""
    n = 6
    return np.round(np.arange(n) * 0.01 + 12.0, 6), geometry.random_transforms(rng, n)


def _fmt(v):
    return repr(float(v))


# --------------------------------------------------------------------------- generic CSV


def test_generic_csv_default_and_custom_columns(tmp_path, poses):
    stamps, T = poses
    q = geometry.quat_from_transform(T)
    lines = ["timestamp,qw,qx,qy,qz,x,y,z,extra"]
    for s, Ti, qi in zip(stamps, T, q):
        lines.append(",".join(map(_fmt, [s, qi[3], *qi[:3], *Ti[:3, 3], 7])))
    (tmp_path / "a.csv").write_text("\n".join(lines) + "\n")
    traj = read_pose_csv(tmp_path / "a.csv", parent="world", child="body")
    assert np.array_equal(traj.stamps, stamps)
    assert np.abs(traj.T - T).max() < 1e-12

    renamed = ["Zeit;PX;PY;PZ;A;B;C;D"] + [
        ";".join(map(_fmt, [s, *Ti[:3, 3], *qi])) for s, Ti, qi in zip(stamps, T, q)]
    (tmp_path / "b.csv").write_text("\n".join(renamed))
    cols = {"t": "zeit", "qx": "A", "qy": "B", "qz": "C", "qw": "D"}
    traj = read_pose_csv(tmp_path / "b.csv", columns=cols)
    assert np.abs(traj.T - T).max() < 1e-12


def test_generic_csv_units_from_header_and_nanoseconds(tmp_path):
    text = ("#timestamp [ns], tx [mm], ty [mm], tz [mm], qx, qy, qz, qw\n"
            "1700000000000000001, 1000, 2000, -3, 0, 0, 0, 1\n"
            "1700000000000000002, , , , , , , \n"  # occluded sample: skipped
            "1700000000500000000, 0, 0, 0, 0, 0, 0, 1\n")
    (tmp_path / "c.csv").write_text(text)
    traj = read_pose_csv(tmp_path / "c.csv")
    assert traj.stamps_ns.tolist() == [1700000000000000001, 1700000000500000000]
    assert traj.T[0, :3, 3].tolist() == [1.0, 2.0, -0.003]
    with pytest.raises(DatasetError, match="the header says 'mm' but 'm' was requested"):
        read_pose_csv(tmp_path / "c.csv", unit="m")


def test_generic_csv_errors(tmp_path):
    (tmp_path / "a.csv").write_text("time,x,y,z,qx,qy,qz\n0,0,0,0,0,0,0\n")
    with pytest.raises(DatasetError, match=r"no column for qw \(looked for qw or q_w") as info:
        read_pose_csv(tmp_path / "a.csv")
    assert info.value.line == 1
    (tmp_path / "b.csv").write_text("t,x,tx,y,z,qx,qy,qz,qw\n")
    with pytest.raises(DatasetError, match="several columns for tx"):
        read_pose_csv(tmp_path / "b.csv")
    (tmp_path / "c.csv").write_text("t,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n1,0,0\n")
    with pytest.raises(DatasetError, match="row has 3 cells, the header has 8") as info:
        read_pose_csv(tmp_path / "c.csv")
    assert info.value.line == 3


def test_generic_csv_leaves_out_non_finite_and_absurd_rows(tmp_path):
    text = ("t,x [mm],y [mm],z [mm],qx,qy,qz,qw\n"
            "0,0,0,0,0,0,0,1\n"
            "1,NaN,0,0,0,0,0,1\n"
            "2,0,0,2e7,0,0,0,1\n"          # 20 km once in metres
            "3,0,0,0,0,0,0,1\n")
    (tmp_path / "a.csv").write_text(text)
    traj = read_pose_csv(tmp_path / "a.csv")
    assert traj.stamps.tolist() == [0.0, 3.0]
    assert [(s.where, s.reason) for s in traj.skipped] == [
        ("line 3", "not a finite number: tx = nan"),
        ("line 4", "absurd position: tz = 20000 m, beyond 10000 m")]
    (tmp_path / "b.csv").write_text("t,x,y,z,qx,qy,qz,qw\n0,inf,0,0,0,0,0,1\n")
    with pytest.raises(DatasetError, match="no usable pose: all 1 rows left out; line 2: not a "
                                           "finite number: tx = inf") as info:
        read_pose_csv(tmp_path / "b.csv")
    assert info.value.line == 2


# --------------------------------------------------------------------------- OptiTrack


def _optitrack(path, stamps, T, *, units="Millimeters", rotation="Quaternion", blank=()):
    """A Motive 1.2x-style export: rigid bodies 'Target' and 'Other', one marker."""
    scale = {"Millimeters": 1000.0, "Meters": 1.0}.get(units, 1.0)
    meta = (f"Format Version,1.23,Take Name,Take 01,Capture Frame Rate,120.000000,"
            f"Export Frame Rate,120.000000,Total Exported Frames,{len(stamps)},"
            f"Rotation Type,{rotation},Length Units,{units},Coordinate Space,Global")
    body = ["Rigid Body"] * 8
    cols = ["Other"] * 8 + ["Target"] * 8 + ["Target:Marker1"] * 3
    lines = [meta, "",
             ",Type," + ",".join(body * 2 + ["Marker"] * 3),
             ",Name," + ",".join(cols),
             ",ID," + ",".join(["1"] * 8 + ["2"] * 8 + ["3"] * 3),
             ",," + ",".join((["Rotation"] * 4 + ["Position"] * 3 + ["Mean Marker Error"]) * 2
                             + ["Position"] * 3),
             "Frame,Time (Seconds)," + ",".join(["X", "Y", "Z", "W", "X", "Y", "Z", ""] * 2
                                                + ["X", "Y", "Z"])]
    q = geometry.quat_from_transform(T)
    for i, (s, Ti, qi) in enumerate(zip(stamps, T, q)):
        other = ["0", "0", "0", "1", "5", "5", "5", "0.1"]
        target = [*map(_fmt, qi), *map(_fmt, Ti[:3, 3] * scale), "0.2"]
        if i in blank:
            target = [""] * 7 + [""]
        lines.append(",".join([str(i), _fmt(s), *other, *target, "1", "2", "3"]))
    path.write_text("\r\n".join(lines) + "\r\n")


def test_optitrack_rigid_body_millimetres_and_occlusion(tmp_path, poses):
    stamps, T = poses
    _optitrack(tmp_path / "take.csv", stamps, T, blank=(2,))
    traj = read_optitrack_csv(tmp_path / "take.csv", "Target", parent="world", child="marker")
    keep = [0, 1, 3, 4, 5]
    assert np.array_equal(traj.stamps, stamps[keep])
    assert np.abs(traj.T - T[keep]).max() < 1e-12
    assert sniff_mocap_format(tmp_path / "take.csv") == "optitrack"


def test_optitrack_errors(tmp_path, poses):
    stamps, T = poses
    _optitrack(tmp_path / "take.csv", stamps, T, units="Meters")
    with pytest.raises(DatasetError, match=r"2 rigid bodys in the file \(Other, Target\)"):
        read_optitrack_csv(tmp_path / "take.csv")
    with pytest.raises(DatasetError,
                       match="rigid body 'Nope' not found; the file has Other, Target"):
        read_optitrack_csv(tmp_path / "take.csv", "Nope")
    _optitrack(tmp_path / "euler.csv", stamps, T, rotation="XYZ")
    with pytest.raises(DatasetError, match="Rotation Type is 'XYZ'") as info:
        read_optitrack_csv(tmp_path / "euler.csv", "Target")
    assert info.value.line == 1
    _optitrack(tmp_path / "inch.csv", stamps, T, units="Inches")
    with pytest.raises(DatasetError,
                       match="Length Units must be Meters, Millimeters or Centimeters"):
        read_optitrack_csv(tmp_path / "inch.csv", "Target")
    (tmp_path / "plain.csv").write_text("Frame,Time\n0,0\n")
    with pytest.raises(DatasetError, match="not an OptiTrack Motive CSV export"):
        read_optitrack_csv(tmp_path / "plain.csv")


def test_optitrack_bad_cell_names_line(tmp_path, poses):
    stamps, T = poses
    _optitrack(tmp_path / "take.csv", stamps, T)
    lines = (tmp_path / "take.csv").read_text().splitlines()
    cells = lines[9].split(",")
    cells[12] = "oops"
    lines[9] = ",".join(cells)
    (tmp_path / "take.csv").write_text("\n".join(lines))
    with pytest.raises(DatasetError,
                       match="expected a number for Target Rotation Z, got 'oops'") as info:
        read_optitrack_csv(tmp_path / "take.csv", "Target")
    assert info.value.line == 10


def test_optitrack_leaves_out_a_non_finite_row(tmp_path, poses):
    stamps, T = poses
    _optitrack(tmp_path / "take.csv", stamps, T)
    lines = (tmp_path / "take.csv").read_text().splitlines()
    cells = lines[9].split(",")
    cells[14] = "1e400"                     # Target Position X: beyond the float range
    lines[9] = ",".join(cells)
    (tmp_path / "take.csv").write_text("\n".join(lines))
    traj = read_optitrack_csv(tmp_path / "take.csv", "Target")
    assert len(traj) == len(stamps) - 1
    assert traj.skipped[0].line == 10
    assert traj.skipped[0].reason == "not a finite number: Target Position X = inf"


# --------------------------------------------------------------------------- Vicon


def _vicon(path, frames, T, *, rate=100, angle="deg", length="mm", blank=()):
    rv = geometry.rotvec_from_transform(T) * (180 / np.pi if angle == "deg" else 1.0)
    t = T[:, :3, 3] * (1000.0 if length == "mm" else 1.0)
    lines = ["Segments", str(rate), ",,Rig:Base,,,,,,Rig:Marker,,,,,",
             "Frame,Sub Frame" + ",RX,RY,RZ,TX,TY,TZ" * 2,
             ",," + ",".join([angle] * 3 + [length] * 3) * 1 + "," +
             ",".join([angle] * 3 + [length] * 3)]
    for i, f in enumerate(frames):
        marker = ["", "", "", "", "", ""] if i in blank else [*map(_fmt, rv[i]), *map(_fmt, t[i])]
        lines.append(",".join([str(f), "0", "0", "0", "0", "1", "2", "3", *marker]))
    lines += ["", "Trajectories", str(rate), ",,Rig:M1,,", "Frame,Sub Frame,X,Y,Z",
              ",,mm,mm,mm", "1,0,1,2,3"]
    path.write_text("\n".join(lines) + "\n")


def test_vicon_segment_helical_degrees_millimetres(tmp_path, rng):
    T = geometry.random_transforms(rng, 5)
    frames = [101, 102, 103, 105, 106]
    _vicon(tmp_path / "trial.csv", frames, T, blank=(1,))
    traj = read_vicon_csv(tmp_path / "trial.csv", "Marker")  # short name after the colon
    keep = [0, 2, 3, 4]
    assert np.allclose(traj.stamps, np.array(frames)[keep] / 100.0, rtol=0, atol=1e-15)
    assert np.abs(traj.T - T[keep]).max() < 1e-12
    # the helical angles are a rotation vector, not Euler angles
    rv = geometry.rotvec_from_transform(T[0])
    assert not np.allclose(traj.T[0, :3, :3], Rotation.from_euler("xyz", rv).as_matrix())
    assert sniff_mocap_format(tmp_path / "trial.csv") == "vicon"


def test_vicon_radians_metres(tmp_path, rng):
    T = geometry.random_transforms(rng, 3)
    _vicon(tmp_path / "trial.csv", [1, 2, 3], T, rate=250, angle="rad", length="m")
    traj = read_vicon_csv(tmp_path / "trial.csv", "Rig:Marker")
    assert np.abs(traj.T - T).max() < 1e-12
    assert traj.stamps.tolist() == [1 / 250, 2 / 250, 3 / 250]


def test_vicon_errors(tmp_path, rng):
    T = geometry.random_transforms(rng, 3)
    _vicon(tmp_path / "trial.csv", [1, 2, 3], T)
    with pytest.raises(DatasetError, match=r"2 segments in the file \(Rig:Base, Rig:Marker\)"):
        read_vicon_csv(tmp_path / "trial.csv")
    text = (tmp_path / "trial.csv").read_text()
    (tmp_path / "traj.csv").write_text(text[text.index("Trajectories"):])
    with pytest.raises(DatasetError, match="only marker Trajectories"):
        read_vicon_csv(tmp_path / "traj.csv")
    (tmp_path / "grad.csv").write_text(text.replace("deg", "grad"))
    with pytest.raises(DatasetError, match="rotation units must be 'deg' or 'rad'") as info:
        read_vicon_csv(tmp_path / "grad.csv", "Marker")
    assert info.value.line == 5
    (tmp_path / "rate.csv").write_text(text.replace("Segments\n100", "Segments\nfast", 1))
    with pytest.raises(DatasetError, match=r"expected a number for the frame rate \(Hz\)") as info:
        read_vicon_csv(tmp_path / "rate.csv", "Marker")
    assert info.value.line == 2


def test_vicon_leaves_out_absurd_rows(tmp_path, rng):
    T = geometry.random_transforms(rng, 4)
    _vicon(tmp_path / "trial.csv", [1, 2, 3, 4], T, angle="rad", length="m")
    lines = (tmp_path / "trial.csv").read_text().splitlines()
    cells = lines[6].split(",")
    cells[8] = "1e300"                      # Rig:Marker RX of frame 2, radians
    lines[6] = ",".join(cells)
    (tmp_path / "trial.csv").write_text("\n".join(lines) + "\n")
    traj = read_vicon_csv(tmp_path / "trial.csv", "Marker")
    assert traj.stamps.tolist() == [1 / 100, 3 / 100, 4 / 100]
    assert traj.skipped[0].line == 7
    assert traj.skipped[0].reason == "absurd rotation: RX = 1e+300 rad, beyond 1000 rad"


# --------------------------------------------------------------------------- dispatcher


def test_read_mocap_inverts_to_world_parent(tmp_path, poses):
    stamps, T = poses
    q = geometry.quat_from_transform(geometry.inv(T))
    t = geometry.inv(T)[:, :3, 3]
    (tmp_path / "m.txt").write_text("".join(
        " ".join(map(_fmt, [s, *ti, *qi])) + "\n" for s, ti, qi in zip(stamps, t, q)))
    spec = MocapSpec(tmp_path / "m.txt", pose="T_body_world", format="tum")
    traj = read_mocap(spec)
    assert traj.name == "T_world_body"
    assert np.abs(traj.T - T).max() < 1e-12
    assert spec.moving_frame == "body"
    assert sniff_mocap_format(tmp_path / "m.txt") == "tum"


def test_read_mocap_dispatches_optitrack_and_rejects_missing_topic(tmp_path, poses):
    stamps, T = poses
    _optitrack(tmp_path / "take.csv", stamps, T)
    traj = read_mocap(MocapSpec(tmp_path / "take.csv", format="optitrack", rigid_body="Target"))
    assert traj.name == "T_world_marker" and np.abs(traj.T - T).max() < 1e-12
    with pytest.raises(DatasetError, match="rosbag motion-capture source needs a topic"):
        read_mocap(MocapSpec(tmp_path / "take.csv", format="rosbag"))
    with pytest.raises(DatasetError, match="motion-capture file not found"):
        sniff_mocap_format(tmp_path / "none.txt")


def test_read_mocap_passes_duplicates_to_csv(tmp_path):
    (tmp_path / "d.csv").write_text("t,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n0,1,0,0,0,0,0,1\n"
                                    "1,2,0,0,0,0,0,1\n")
    with pytest.raises(DatasetError, match="duplicate time stamp.*; give duplicates: drop "
                       "under mocap in rig.yaml") as info:
        read_mocap(MocapSpec(tmp_path / "d.csv", format="csv"))
    assert info.value.line == 3
    (tmp_path / "d.txt").write_text("0 0 0 0 0 0 0 1\n0 1 0 0 0 0 0 1\n")
    with pytest.raises(DatasetError, match="; give duplicates: drop under mocap"):
        read_mocap(MocapSpec(tmp_path / "d.txt", format="tum"))
    traj = read_mocap(MocapSpec(tmp_path / "d.csv", format="csv", duplicates="drop"))
    assert traj.T[:, 0, 3].tolist() == [0.0, 2.0]


@pytest.mark.parametrize("bad", [None, 5, ["mocap.txt"]])
def test_readers_refuse_what_is_not_a_path(bad):
    from multieye.core.errors import InputError
    from multieye.io import list_images, load_rig, read_intrinsics, read_tum

    for reader in (read_tum, read_pose_csv, read_optitrack_csv, read_vicon_csv, read_intrinsics,
                   load_rig, list_images, sniff_mocap_format):
        with pytest.raises(InputError, match="must be a path"):
            reader(bad)
    with pytest.raises(InputError, match="read_mocap takes a MocapSpec, got"):
        read_mocap(bad)


def test_duplicates_option_is_an_input_error(tmp_path):
    from multieye.core.errors import InputError
    from multieye.io import read_tum

    (tmp_path / "m.txt").write_text("0 0 0 0 0 0 0 1\n")
    with pytest.raises(InputError, match="duplicates must be 'error' or 'drop', got 'x'"):
        read_tum(tmp_path / "m.txt", duplicates="x")


# --------------------------------------------------------------------------- large tables


def _quaternion_rows(n, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.column_stack([12.0 + np.arange(n) * 0.001, rng.normal(size=(n, 3)), q])


def test_large_csv_is_read_line_by_line_into_arrays(tmp_path):
    """300 000 rows, more than a dozen blocks: no text held whole, no Python object per row."""
    import tracemalloc

    n = 300_000
    rows = _quaternion_rows(n)
    path = tmp_path / "big.csv"
    with open(path, "w") as f:
        f.write("t,tx,ty,tz,qx,qy,qz,qw\n")
        np.savetxt(f, rows, fmt="%.9f", delimiter=",")
    size = path.stat().st_size
    tracemalloc.start()
    traj = read_pose_csv(path)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert len(traj) == n
    np.testing.assert_allclose(traj.stamps, rows[:, 0], atol=1e-9)
    np.testing.assert_allclose(traj.T[:, :3, 3], rows[:, 1:4], atol=1e-9)
    q = geometry.quat_from_transform(traj.T)                  # sign: w >= 0 on both sides
    np.testing.assert_allclose(q * np.sign(q[:, 3:4]), rows[:, 4:8] * np.sign(rows[:, 7:8]),
                               atol=1e-8)
    # the poses are 136 bytes a row and the line numbers 4; the text alone would be about 95
    # bytes a row and a list of rows of Python floats over 400
    assert peak / n < 250 and peak < size * 2.5, (peak / n, size)


def test_large_csv_errors_name_their_line_beyond_the_first_blocks(tmp_path):
    n = 40_000
    rows = _quaternion_rows(n)
    text = ["t,tx,ty,tz,qx,qy,qz,qw"] + [",".join(f"{v:.9f}" for v in r) for r in rows]
    path = tmp_path / "big.csv"
    bad = list(text)
    bad[35_000] = bad[35_000].replace(",", ",x", 1)          # line 35 001: t then 'x...'
    path.write_text("\n".join(bad) + "\n")
    with pytest.raises(DatasetError, match=r"big\.csv:35001: expected a number for tx"):
        read_pose_csv(path)
    bad = list(text)
    bad[33_333] = bad[33_333].rsplit(",", 1)[0] + ",3.5"      # qw: not a unit quaternion
    path.write_text("\n".join(bad) + "\n")
    with pytest.raises(DatasetError, match=r"big\.csv:33334: .*quaternion"):
        read_pose_csv(path)
    bad = list(text)
    bad[20_001] = bad[20_000]                                 # a repeated stamp
    path.write_text("\n".join(bad) + "\n")
    with pytest.raises(DatasetError, match=r"big\.csv:2000[12]"):
        read_pose_csv(path)


def test_large_optitrack_export_read_in_blocks(tmp_path, rng):
    n = 40_000
    stamps = np.round(np.arange(n) / 120.0, 6)
    T = geometry.random_transforms(rng, n)
    path = tmp_path / "take.csv"
    _optitrack(path, stamps, T, blank=(17_000,))
    traj = read_optitrack_csv(path, "Target")
    assert len(traj) == n - 1 and 17_000 / 120.0 not in traj.stamps
    np.testing.assert_allclose(traj.T[:, :3, 3], np.delete(T[:, :3, 3], 17_000, 0), atol=1e-6)


def test_vicon_segments_after_a_long_section(tmp_path, rng):
    """The Segments section after 50 000 rows of another section: found, lines right."""
    frames = np.arange(1, 21)
    T = geometry.random_transforms(rng, len(frames))
    seg = tmp_path / "seg.csv"
    _vicon(seg, frames, T)
    joints = ["Joints", "100", ",,Rig:J1,,", "Frame,Sub Frame,RX,RY,RZ", ",,deg,deg,deg"]
    joints += [f"{k},0,1,2,3" for k in range(1, 50_001)] + [""]
    path = tmp_path / "nexus.csv"
    lines = seg.read_text().split("\n")
    good = lines[5 + 7]
    cells = good.split(",")
    cells[11] = "zero"                                        # the Marker's TX of frame 8
    lines[5 + 7] = ",".join(cells)
    path.write_text("\n".join(joints + lines))
    with pytest.raises(DatasetError, match=rf"nexus\.csv:{len(joints) + 13}: expected a number "
                                           r"for TX, got 'zero'"):
        read_vicon_csv(path, "Marker")
    lines[5 + 7] = good
    path.write_text("\n".join(joints + lines))
    traj = read_vicon_csv(path, "Marker")
    np.testing.assert_allclose(traj.stamps, frames / 100.0)
    np.testing.assert_allclose(traj.T[:, :3, 3], T[:, :3, 3], atol=1e-9)


def test_csv_without_a_header_says_to_read_it_as_tum(tmp_path):
    """ETH's hand_eye_calibration streams: .csv files of t, x, y, z, qx, qy, qz, qw without a
    header. The message said only which names it looked for in the 'header' of numbers."""
    (tmp_path / "v.csv").write_text("1491754390.48, 0.33, -1.01, 0.40, 0.0, 0.0, 0.0, 1.0\n"
                                    "1491754390.49, 0.33, -1.01, 0.40, 0.0, 0.0, 0.0, 1.0\n")
    with pytest.raises(DatasetError, match="this line holds numbers, not a header.*give "
                       "format: tum under mocap") as info:
        read_mocap(MocapSpec(tmp_path / "v.csv", format="csv"))
    assert info.value.line == 1
    traj = read_mocap(MocapSpec(tmp_path / "v.csv", format="tum"))
    assert traj.stamps.tolist() == [1491754390.48, 1491754390.49]
    (tmp_path / "h.csv").write_text("time,x,y,z,qx,qy,qz\n0,0,0,0,0,0,0\n")
    with pytest.raises(DatasetError) as info:
        read_mocap(MocapSpec(tmp_path / "h.csv", format="csv"))
    assert "not a header" not in str(info.value)


def test_csv_stamps_without_a_unit_in_nanoseconds(tmp_path):
    """EuRoC's ground truth names its stamp column '#timestamp' without a unit and writes
    19-digit nanoseconds: read as nanoseconds (exact), as image names are."""
    (tmp_path / "gt.csv").write_text(
        "#timestamp,p_x,p_y,p_z,q_w,q_x,q_y,q_z\n"
        "1403636579758555392,4.6,-1.8,0.8,1,0,0,0\n1403636579763555584,4.6,-1.8,0.8,1,0,0,0\n")
    cols = {"tx": "p_x", "ty": "p_y", "tz": "p_z", "qw": "q_w", "qx": "q_x", "qy": "q_y",
            "qz": "q_z"}
    traj = read_pose_csv(tmp_path / "gt.csv", columns=cols)
    assert traj.stamps_ns.tolist() == [1403636579758555392, 1403636579763555584]
    (tmp_path / "s.csv").write_text("t,x,y,z,qx,qy,qz,qw\n12.5,0,0,0,0,0,0,1\n13,0,0,0,0,0,0,1\n")
    assert read_pose_csv(tmp_path / "s.csv").stamps.tolist() == [12.5, 13.0]


def test_euroc_header_names_read_w_first(tmp_path, poses):
    """EuRoC's vicon0/data.csv and state_groundtruth_estimate0/data.csv name their columns
    ``p_RS_R_x [m]`` and ``q_RS_w []`` (w first), with velocity and bias columns after: read by
    those names without ``columns:``, the quaternion in the header's order (refused before:
    'no column for tx')."""
    stamps, T = poses
    q = geometry.quat_from_transform(T)
    head = ("#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
            "q_RS_y [],q_RS_z [],v_RS_R_x [m s^-1],v_RS_R_y [m s^-1],v_RS_R_z [m s^-1],"
            "b_w_RS_S_x [rad s^-1],b_w_RS_S_y [rad s^-1],b_w_RS_S_z [rad s^-1]")
    rows = [head] + [",".join([str(1403636579758555392 + 5_000_000 * k),
                               *map(_fmt, Ti[:3, 3]), _fmt(qi[3]), *map(_fmt, qi[:3]),
                               "0.1", "0.2", "0.3", "0", "0", "0"])
                     for k, (Ti, qi) in enumerate(zip(T, q))]
    (tmp_path / "data.csv").write_text("\n".join(rows) + "\n")
    assert sniff_mocap_format(tmp_path / "data.csv") == "csv"
    traj = read_mocap(MocapSpec(tmp_path / "data.csv", format="csv"))
    np.testing.assert_allclose(traj.T, T, atol=1e-12)
    assert traj.stamps_ns[1] - traj.stamps_ns[0] == 5_000_000


def test_a_csv_with_decimal_commas_says_so(tmp_path):
    """A spreadsheet's CSV of semicolons and decimal commas: one line naming the cell and
    the decimal comma (before: only 'expected a number for t')."""
    (tmp_path / "d.csv").write_text("time;x;y;z;qx;qy;qz;qw\n0,5;1,25;0;0;0;0;0;1\n")
    with pytest.raises(DatasetError, match=r"d.csv:2: expected a number for t, got '0,5'; "
                                           r"a decimal comma"):
        read_pose_csv(tmp_path / "d.csv")


def test_several_rigid_bodies_say_which_key_chooses(tmp_path, poses):
    """An export of several rigid bodies (or segments) names the rig.yaml key that chooses
    one (before: 'choose one by name', no key named)."""
    stamps, T = poses
    _optitrack(tmp_path / "take.csv", stamps, T)
    with pytest.raises(DatasetError, match=r"2 rigid bodys? in the file \(Other, Target\); "
                                           r"choose one with rigid_body: <name> under mocap"):
        read_optitrack_csv(tmp_path / "take.csv")


def test_a_csv_of_euler_angles_or_matrices_is_read_as_stamped_rows(tmp_path, poses):
    """A CSV export whose rotation is Euler angles, a rotation vector or a matrix: as a
    generic CSV it is one line saying how to read it (before: only 'no column for qx', and
    the header row then refused by the stamped rows); read so (format: tum with values /
    rotation), its header row is skipped, and names that are those of values give the
    columns' order; stamps in nanoseconds are still decided by the first row of numbers."""
    stamps, T = poses
    eul = Rotation.from_matrix(T[:, :3, :3]).as_euler("xyz", degrees=True)
    rows = ["time,x,y,z,roll,pitch,yaw"] + [",".join(map(_fmt, [s, *Ti[:3, 3], *e]))
                                              for s, Ti, e in zip(stamps, T, eul)]
    (tmp_path / "e.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(DatasetError, match=r"no column for qx.*rotation other than a "
                                           r"quaternion: read the file with format: tum"):
        read_mocap(MocapSpec(tmp_path / "e.csv", format="csv"))
    traj = read_mocap(MocapSpec(tmp_path / "e.csv", format="tum", rotation="euler-xyz-deg",
                                values=("t", "x", "y", "z", "rx", "ry", "rz")))
    np.testing.assert_allclose(traj.T, T, atol=1e-9)
    np.testing.assert_allclose(traj.stamps, stamps)
    q = geometry.quat_from_transform(T)
    ns = [1403636579758555392 + 5_000_000 * k for k in range(len(T))]
    rows = ["t [ns],qw,qx,qy,qz,x,y,z"] + [
        ",".join([str(n), *map(_fmt, [qi[3], *qi[:3], *Ti[:3, 3]])]) for n, Ti, qi in
        zip(ns, T, q)]
    (tmp_path / "w.csv").write_text("\n".join(rows) + "\n")
    traj = read_mocap(MocapSpec(tmp_path / "w.csv", format="tum",
                                values=("t", "x", "y", "z", "qx", "qy", "qz", "qw")))
    np.testing.assert_allclose(traj.T, T, atol=1e-12)
    assert traj.stamps_ns is None or traj.stamps_ns.tolist() == ns
    assert abs(traj.stamps[1] - traj.stamps[0] - 0.005) < 1e-6    # nanoseconds, not seconds
    rows = ["t,r11,r12,r13,x"] + ["0,1,0,0,0"]
    (tmp_path / "m.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(DatasetError, match=r"m.csv:1: the header row has 5 names"):
        read_mocap(MocapSpec(tmp_path / "m.csv", format="tum", rotation="matrix"))


def test_a_vicon_tracker_export_is_refused_saying_what_to_do(tmp_path):
    """Vicon Tracker's CSV starts 'Objects' (not a Nexus section) and its angles are helical
    or Euler by a setting it does not record: one line saying so and what to export, whether
    recognised or read as format: csv (before: 'no column for t ... header has Objects')."""
    (tmp_path / "tracker.csv").write_text(
        "Objects\n100\n,,Global Angle board:board,,,,,\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n"
        ",,rad,rad,rad,mm,mm,mm\n1,0,0.1,0.2,0.3,10,20,30\n")
    for call in (lambda: sniff_mocap_format(tmp_path / "tracker.csv"),
                 lambda: read_pose_csv(tmp_path / "tracker.csv")):
        with pytest.raises(DatasetError, match=r"tracker.csv:1: a Vicon Tracker export .* "
                                               r"does not guess; export from Nexus"):
            call()


def test_rostopic_csv_dumps_and_spaced_names_are_read(tmp_path, poses):
    """``rostopic echo -p`` dumps (field.pose.position.x, field.transform.rotation.w, the
    header stamp in nanoseconds beside the record time %time) and spreadsheet names with
    spaces (Pos X (mm), Quat W) are read by name; columns: names a spaced header as written
    (before: 'no column for tx')."""
    stamps, T = poses
    q = geometry.quat_from_transform(T)
    ns = [1_700_000_000_000_000_000 + 10_000_000 * k for k in range(len(T))]
    head = ("%time,field.header.seq,field.header.stamp,field.header.frame_id,"
            "field.child_frame_id,field.transform.translation.x,field.transform.translation.y,"
            "field.transform.translation.z,field.transform.rotation.x,"
            "field.transform.rotation.y,field.transform.rotation.z,field.transform.rotation.w")
    rows = [head] + [",".join([str(n + 3_000_000), "0", str(n), "world", "board",
                               *map(_fmt, Ti[:3, 3]), *map(_fmt, qi)])
                     for n, Ti, qi in zip(ns, T, q)]
    (tmp_path / "tf.csv").write_text("\n".join(rows) + "\n")
    traj = read_pose_csv(tmp_path / "tf.csv")
    np.testing.assert_allclose(traj.T, T, atol=1e-12)
    assert traj.stamps_ns.tolist() == ns                  # the header stamp, not %time
    rows = ["Time (s),Pos X (mm),Pos Y (mm),Pos Z (mm),Quat X,Quat Y,Quat Z,Quat W"] + [
        ",".join(map(_fmt, [s, *(Ti[:3, 3] * 1000), *qi])) for s, Ti, qi in zip(stamps, T, q)]
    (tmp_path / "s.csv").write_text("\n".join(rows) + "\n")
    np.testing.assert_allclose(read_pose_csv(tmp_path / "s.csv").T, T, atol=1e-12)
    traj = read_pose_csv(tmp_path / "s.csv", columns={"tx": "Pos X", "ty": "Pos Y",
                                                      "tz": "Pos Z"})
    np.testing.assert_allclose(traj.T, T, atol=1e-12)
