"""Other labs' motion-capture exports written as the tools write them (layouts from the
OptiTrack Motive, Vicon Nexus, Qualisys QTM, EuRoC and ``rostopic echo -p`` documentation),
from one trajectory with a known answer: each is read as the TUM original, or refused with one
line naming the file, the line and what was expected -- never read from the wrong column."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry
from multieye.core.errors import DatasetError
from multieye.io.mocap import MocapSpec, read_mocap, sniff_mocap_format
from multieye.io.mocap_exports import read_optitrack_csv, read_vicon_csv


@pytest.fixture
def truth(rng):
    """(frames at 120 Hz with a drop, stamps s, T_world_board (N,4,4))."""
    frames = np.array([1, 2, 3, 5, 6, 7])
    return frames, frames / 120.0, geometry.random_transforms(rng, len(frames))


def _cells(v, scale=1.0):
    return [repr(float(x) * scale) for x in v]


def _vicon(path, frames, T, names_row):
    """A Nexus ``Segments`` section: helical RX RY RZ in degrees, TX TY TZ in mm; the board's
    columns first, then another segment's (0, 0, 0, 10, 20, 30)."""
    rv = np.degrees(geometry.rotvec_from_transform(T))
    units = ["deg"] * 3 + ["mm"] * 3
    lines = ["Segments", "120", names_row, "Frame,Sub Frame" + ",RX,RY,RZ,TX,TY,TZ" * 2,
             ",," + ",".join(units * 2)]
    lines += [",".join([str(f), "0", *_cells(r), *_cells(Ti[:3, 3], 1000.0), "0", "0", "0", "10",
                        "20", "30"]) for f, r, Ti in zip(frames, rv, T)]
    path.write_text("\n".join(lines) + "\n")


def test_vicon_export_reads_as_the_truth(tmp_path, truth):
    frames, stamps, T = truth
    _vicon(tmp_path / "run.csv", frames, T, ",,Board:Board,,,,,,Other:Other,,,,,")
    traj = read_vicon_csv(tmp_path / "run.csv", "Board")
    assert np.allclose(traj.stamps, stamps, rtol=0, atol=1e-15)
    assert np.abs(traj.T - T).max() < 1e-12


def test_vicon_names_row_shifted_is_refused_naming_both_columns(tmp_path, truth):
    """'Other' one cell too far right: the board's block then holds the other segment's RX;
    it was read from there (a pose 100 degrees off, no message)."""
    frames, _, T = truth
    _vicon(tmp_path / "run.csv", frames, T, ",,Board:Board,,,,,,,Other:Other,,,,")
    with pytest.raises(DatasetError, match=r"run\.csv:4: segment 'Board:Board' has two RX "
                                           r"columns \(3 and 9\).*expected each once"):
        read_vicon_csv(tmp_path / "run.csv", "Board")


def _motive(path, stamps, T, names):
    """A Motive export (Format Version 1.23, Quaternion, Meters) with a Parent row and the
    rigid bodies' markers; rigid bodies named ``names``, all with the poses ``T``."""
    meta = ("Format Version,1.23,Take Name,Take 1,Capture Frame Rate,120.000000,Export Frame "
            "Rate,120.000000,Rotation Type,Quaternion,Length Units,Meters,Coordinate Space,Global")
    kinds, ids, parents, qty, axes, name_cells = [], [], [], [], [], []
    for i, n in enumerate(names):
        kinds += ["Rigid Body"] * 8 + ["Rigid Body Marker"] * 3
        name_cells += [n] * 8 + [f"{n}:Marker1"] * 3
        ids += [str(i + 1)] * 11
        parents += [""] * 8 + [n] * 3
        qty += ["Rotation"] * 4 + ["Position"] * 3 + ["Mean Marker Error"] + ["Position"] * 3
        axes += ["X", "Y", "Z", "W", "X", "Y", "Z", "", "X", "Y", "Z"]
    lines = [meta, "", ",Type," + ",".join(kinds), ",Name," + ",".join(name_cells),
             ",ID," + ",".join(ids), ",Parent," + ",".join(parents), ",," + ",".join(qty),
             "Frame,Time (Seconds)," + ",".join(axes)]
    q = geometry.quat_from_transform(T)
    for k, (s, Ti, qi) in enumerate(zip(stamps, T, q)):
        body = [*_cells(qi), *_cells(Ti[:3, 3]), "0.0001", "", "", ""]   # a marker not seen
        lines.append(",".join([str(k), f"{s:.6f}", *body * len(names)]))
    path.write_text("\r\n".join(lines) + "\r\n", encoding="utf-8-sig")   # Excel's BOM


def test_motive_export_reads_as_the_truth(tmp_path, truth):
    _, stamps, T = truth
    _motive(tmp_path / "take.csv", stamps, T, ["board", "wand"])
    traj = read_optitrack_csv(tmp_path / "take.csv", "board")
    assert np.allclose(traj.stamps, np.round(stamps, 6), rtol=0, atol=1e-12)
    assert np.abs(traj.T - T).max() < 1e-12


def test_motive_two_rigid_bodies_of_one_name_are_refused(tmp_path, truth):
    """Two rigid bodies named alike: the last one's columns were read for both, silently."""
    _, stamps, T = truth
    _motive(tmp_path / "take.csv", stamps, T, ["board", "board"])
    with pytest.raises(DatasetError, match=r"take\.csv:8: rigid body 'board' has two Rotation X "
                                           r"columns \(3 and 14\)"):
        read_optitrack_csv(tmp_path / "take.csv", "board")


def test_qualisys_tsv_is_refused_naming_it(tmp_path, truth):
    """A QTM 6DOF export was read as TUM rows and refused as 'rows must have 8 entries'."""
    _, stamps, T = truth
    head = ["NO_OF_FRAMES\t6", "NO_OF_CAMERAS\t8", "NO_OF_BODIES\t1", "FREQUENCY\t120",
            "NO_OF_ANALOG\t0", "ANALOG_FREQUENCY\t0", "DESCRIPTION\t--",
            "TIME_STAMP\t2026-11-29, 22:00:00\t0.0", "DATA_INCLUDED\t6D", "BODY_NAMES\tboard",
            "Frame\tTime\tboard\tX\tY\tZ\tRoll\tPitch\tYaw\tResidual"]
    rows = [f"{k + 1}\t{s:.5f}\t\t1.0\t2.0\t3.0\t0.0\t0.0\t0.0\t0.5" for k, s in enumerate(stamps)]
    path = tmp_path / "take_6D.tsv"
    path.write_text("\n".join(head + rows) + "\n")
    assert sniff_mocap_format(path) == "tum"
    with pytest.raises(DatasetError, match=r"take_6D\.tsv:1: a Qualisys Track Manager TSV "
                                           r"export.*convert the body's poses to a TUM file"):
        read_mocap(MocapSpec(file=path, format="tum"))


@pytest.mark.parametrize("fmt", ["optitrack", "vicon"])
def test_a_repeated_frame_of_an_export_is_dropped_as_the_message_advises(tmp_path, truth, fmt):
    """A frame exported twice: the error advised ``duplicates: drop``, which rig.yaml then
    refused for these formats ('applies to tum, csv sources only')."""
    from multieye.io.rig import load_rig

    frames, stamps, T = truth
    path = tmp_path / "take.csv"
    if fmt == "optitrack":
        _motive(path, stamps, T, ["board"])
    else:
        _vicon(path, frames, T, ",,Board:Board,,,,,,Other:Other,,,,,")
    lines = path.read_text(encoding="utf-8-sig").splitlines()
    lines.insert(len(lines) - 2, lines[-3])          # the 4th frame twice
    path.write_text("\n".join(lines) + "\n")
    body = "board" if fmt == "optitrack" else "Board"
    with pytest.raises(DatasetError, match="duplicate time stamp.*give duplicates: drop"):
        read_mocap(MocapSpec(file=path, format=fmt, rigid_body=body))
    (tmp_path / "rig.yaml").write_text(
        "setup: eye-to-base\ntarget: {type: chessboard, rows: 6, cols: 9, spacing: 0.05}\n"
        f"mocap: {{file: take.csv, duplicates: drop, rigid_body: {body}}}\n"
        "cameras:\n  cam0: {poses: cam0.txt}\n")
    (tmp_path / "cam0.txt").write_text("0 0 0 1 0 0 0 1\n")
    spec = load_rig(tmp_path / "rig.yaml").mocap
    assert spec.format == fmt and spec.duplicates == "drop"
    traj = read_mocap(spec)
    assert np.abs(traj.T - T).max() < 1e-12      # the repeated row left out, every frame once
    assert np.allclose(traj.stamps, stamps if fmt == "vicon" else np.round(stamps, 6), rtol=0,
                       atol=1e-12)
