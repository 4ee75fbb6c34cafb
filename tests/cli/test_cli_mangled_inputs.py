"""Mangled input never hurts (issue 13, items 2 and 3): hypothesis mangles rig.yaml, the
motion capture, the intrinsics and the images of small valid datasets, runs
``multieye calibrate`` in-process and checks that every outcome is one of

- exit status 2, exactly one line on stderr naming the file (and the line where the mangling
  touched one), and no calibration.json written;
- exit status 0, with the mangled image or row listed as rejected with its reason (or, for a
  mangling that left the input valid, a result like any other);

never a traceback and never exit status 1.  Examples are derandomised (the same every run)
and few, so the module runs in about 20 seconds.
"""

from __future__ import annotations

import json
import re
import shutil
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from pose_dataset import write_pose_dataset

from multieye.cli import main
from multieye.sim.dataset import DatasetSpec, render_dataset

SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow, HealthCheck.data_too_large])

#: Values written over a YAML value: wrong types, out of range, NaN, huge, aliases, text that
#: YAML 1.1 reads as a string, control characters.
YAML_VALUES = ["-1", "0", "1.0e+300", "-.inf", ".nan", "abc", "[1, 2]", "{a: 1}", "~", "1e-3",
               "99999999999999999999999", "true", '"\\0"', "-0.0", "7.5", "*undefined",
               "!!binary aGVsbG8=", "2001-01-01", "'x' * 3", "[" * 40 + "]" * 40, "- 1"]
#: Cells written into a motion-capture row.
CELLS = ["nan", "inf", "-inf", "1e308", "1e309", "-1e5", "1e12", "abc", "0x10", "", "1,2"]
NON_FINITE = {"nan", "inf", "-inf", "1e309"}
#: Alias expansion bomb: nine aliases of the level below, nine levels deep.
BOMB = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]\n" for k in range(1, 9))


@pytest.fixture(scope="module")
def pose_dataset(tmp_path_factory):
    """Two cameras given by poses (no images): the fastest whole run."""
    return write_pose_dataset(tmp_path_factory.mktemp("poses"))[0]


@pytest.fixture(scope="module")
def image_dataset(tmp_path_factory):
    """Two cameras x 4 rendered images, 320 x 240, rendered once for the module."""
    folder = tmp_path_factory.mktemp("images") / "ds"
    render_dataset(folder, DatasetSpec(n_cameras=2, images_per_camera=4, width=320, height=240,
                                       processes=1), seed=2)
    return folder


def _run(source: Path, mangle) -> tuple:
    """Copy the dataset, mangle the copy, calibrate it; returns (result, folder, out)."""
    work = Path(tempfile.mkdtemp(prefix="mangled-"))
    ds = work / "ds"
    shutil.copytree(source, ds)
    mangle(ds)
    out = work / "out"
    res = CliRunner().invoke(main, ["calibrate", str(ds), "-o", str(out), "--processes", "1"])
    return res, ds, out, work


def _check_outcome(res, out) -> str | None:
    """The invariants of every outcome; returns the error line (exit 2) or None (exit 0)."""
    assert res.exit_code in (0, 2), (res.exit_code, res.output, res.exception)
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    assert "Traceback" not in res.output and "Traceback" not in res.stderr
    if res.exit_code == 2:
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1, res.stderr
        assert lines[0].startswith("multieye: error: "), lines[0]
        assert not (out / "calibration.json").exists()
        return lines[0]
    assert (out / "calibration.json").exists()
    return None


def _rejected(out: Path) -> dict[str, str]:
    cal = json.loads((out / "calibration.json").read_text())
    return {r["item"]: r["reason"] for c in cal["cameras"].values() for r in c.get("rejected", [])}


@st.composite
def text_mangling(draw, values=YAML_VALUES):
    """A function mangling a text file, and a description of what it did."""
    kind = draw(st.sampled_from(["value", "value", "value", "delete", "duplicate", "indent",
                                 "truncate", "garbage", "bomb", "deep", "empty"]))
    line = draw(st.integers(0, 40))
    value = draw(st.sampled_from(values))
    cut = draw(st.floats(0.0, 1.0))
    noise = draw(st.binary(min_size=1, max_size=64))

    def mangle(path: Path) -> int | None:
        """Mangle the file; returns the 1-based line touched, if one was."""
        lines = path.read_text().splitlines()
        k = line % len(lines)
        if kind == "value" and ":" in lines[k]:
            key = lines[k].split(":", 1)[0]
            lines[k] = f"{key}: {value}"
        elif kind == "value":
            lines[k] = value
        elif kind == "delete":
            del lines[k]
        elif kind == "duplicate":
            lines.insert(k, lines[k])
        elif kind == "indent":
            lines[k] = "  " + lines[k]
        elif kind == "truncate":
            text = "\n".join(lines)
            path.write_text(text[:int(cut * len(text))])
            return None
        elif kind == "garbage":
            path.write_bytes(noise + path.read_bytes()[: int(cut * 200)])
            return None
        elif kind == "bomb":
            path.write_text(BOMB + "\n".join(lines) + "\n")
            return None
        elif kind == "deep":
            lines.append("extra: " + "[" * 5000 + "]" * 5000)
        else:
            path.write_bytes(b"")
            return None
        path.write_text("\n".join(lines) + "\n")
        return k + 1

    return mangle, (kind, line, value)


@settings(max_examples=24, **SETTINGS)
@given(mangling=text_mangling())
def test_mangled_rig_yaml(pose_dataset, mangling):
    mangle, what = mangling
    res, ds, out, work = _run(pose_dataset, lambda ds: mangle(ds / "rig.yaml"))
    try:
        error = _check_outcome(res, out)
        if error is not None:
            named = ["rig.yaml", "mocap.txt", "cam0.txt", "cam1.txt", "cam.yaml"]
            assert any(n in error for n in named), (what, error)
    finally:
        shutil.rmtree(work)


@st.composite
def mocap_mangling(draw):
    kind = draw(st.sampled_from(["cell", "cell", "cell", "cell", "extra", "drop", "text",
                                 "file"]))
    row = draw(st.integers(0, 23))
    column = draw(st.integers(0, 7))
    cell = draw(st.sampled_from(CELLS))
    file_mangling = draw(text_mangling(values=["abc", "1 2 3", "nan " * 8, "0 " * 8]))
    return kind, row, column, cell, file_mangling


@settings(max_examples=12, **SETTINGS)
@given(mangling=mocap_mangling())
@example(mangling=("cell", 5, 1, "1e308", (None, None)))      # tx = 1e308 (issue 13)
def test_mangled_motion_capture(pose_dataset, mangling):
    kind, row, column, cell, (mangle_file, _) = mangling
    touched = {}

    def mangle(ds):
        path = ds / "mocap.txt"
        if kind == "file":
            touched["line"] = mangle_file(path)
            return
        lines = path.read_text().splitlines()
        data = [i for i, line in enumerate(lines) if not line.startswith("#")]
        i = data[row % len(data)]
        cells = lines[i].split()
        if kind == "cell":
            cells[column] = cell
        elif kind == "extra":
            cells.append("0.5")
        elif kind == "drop":
            del cells[column]
        else:
            cells = ["not", "a", "pose"]
        lines[i] = " ".join(c for c in cells if c)
        path.write_text("\n".join(lines) + "\n")
        touched["line"] = i + 1

    res, ds, out, work = _run(pose_dataset, mangle)
    try:
        error = _check_outcome(res, out)
        line = touched.get("line")
        if error is not None:
            assert "mocap.txt" in error or "cam0.txt" in error or "cam1.txt" in error, error
            if kind != "file" and "mocap.txt" in error and "no usable pose" not in error:
                assert f"mocap.txt:{line}:" in error, (kind, cell, error)
        elif kind == "cell" and (cell in NON_FINITE or (cell in ("1e308", "1e12")
                                                         and column <= 3)):
            reasons = _rejected(out)
            assert f"mocap.txt line {line}" in reasons, (cell, column, reasons)
            assert reasons[f"mocap.txt line {line}"].startswith("motion-capture row left out: ")
    finally:
        shutil.rmtree(work)


CAMERA_INFO = """\
image_width: 640
image_height: 480
camera_matrix: {rows: 3, cols: 3, data: [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 4, data: [0.0, 0.0, 0.0, 0.0]}
"""
CAMCHAIN = """\
cam0:
  camera_model: pinhole
  intrinsics: [500.0, 500.0, 320.0, 240.0]
  distortion_model: radtan
  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]
  resolution: [640, 480]
cam1:
  camera_model: pinhole
  intrinsics: [500.0, 500.0, 320.0, 240.0]
  distortion_model: radtan
  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]
  resolution: [640, 480]
  T_cn_cnm1: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
"""


@settings(max_examples=18, **SETTINGS)
@given(kind=st.sampled_from(["opencv", "camera_info", "kalibr"]), mangling=text_mangling())
def test_mangled_intrinsics(pose_dataset, kind, mangling):
    mangle, what = mangling

    def mangled(ds):
        path = ds / "cam.yaml"
        if kind == "camera_info":
            path.write_text(CAMERA_INFO)
        elif kind == "kalibr":
            path.write_text(CAMCHAIN)
        mangle(path)

    res, ds, out, work = _run(pose_dataset, mangled)
    try:
        error = _check_outcome(res, out)
        if error is not None:
            assert "cam.yaml" in error, (kind, what, error)
    finally:
        shutil.rmtree(work)


@settings(max_examples=5, **SETTINGS)
@given(camera=st.sampled_from(["cam0", "cam1"]), index=st.integers(0, 3),
       kind=st.sampled_from(["truncate", "empty", "noise", "resize", "blank", "text"]),
       cut=st.floats(0.05, 0.95), noise=st.binary(min_size=1, max_size=256))
@example(camera="cam1", index=1, kind="resize", cut=0.5, noise=b"x")
def test_mangled_images(image_dataset, camera, index, kind, cut, noise):
    name = {}

    def mangle(ds):
        path = sorted((ds / camera).glob("*.png"))[index]
        name["file"] = path.name
        if kind == "truncate":
            data = path.read_bytes()
            path.write_bytes(data[: int(cut * len(data))])
        elif kind == "empty":
            path.write_bytes(b"")
        elif kind == "noise":
            path.write_bytes(noise)
        elif kind == "resize":
            cv2.imwrite(str(path), cv2.resize(cv2.imread(str(path)), (200, 150)))
        elif kind == "blank":
            cv2.imwrite(str(path), np.full((240, 320), 200, np.uint8))
        else:
            path.write_text("not an image\n")

    res, ds, out, work = _run(image_dataset, mangle)
    try:
        error = _check_outcome(res, out)
        if error is not None:
            assert name["file"] in error or f"{camera}" in error, (kind, error)
        else:
            reasons = _rejected(out)
            if name["file"] in reasons:
                assert re.match(r"(unreadable file|wrong resolution|target not detected)",
                                reasons[name["file"]]), reasons
            else:   # left in: then it was still a good image (a harmless truncation)
                image = cv2.imread(str(ds / camera / name["file"]))
                assert image is not None and image.shape[:2] == (240, 320), (kind, reasons)
    finally:
        shutil.rmtree(work)


# --------------------------------------------------------------------------- issue 19


@pytest.fixture(scope="module")
def calibrated(pose_dataset, tmp_path_factory):
    """The output folder of the pose dataset, calibrated once for the module."""
    out = tmp_path_factory.mktemp("calibrated") / "out"
    res = CliRunner().invoke(main, ["calibrate", str(pose_dataset), "-o", str(out)])
    assert res.exit_code == 0, res.output
    return out


#: Values written over a JSON value of calibration.json or details.json.
JSON_VALUES = [None, True, -1, 1e308, 10 ** 400, "x", "../../x", [], {}, [[1]], [[[[1]]]],
               {"a": 1}, [["x"] * 6] * 6, [1] * 16, [[1, 2, 3, 4]] * 4, "\x00", "e" * 5000,
               "[" * 3000]


def _json_paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _json_paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj[:2]):
            yield from _json_paths(v, prefix + (i,))


@settings(max_examples=16, **SETTINGS)
@given(file=st.sampled_from(["calibration.json", "details.json"]), pick=st.integers(0, 10 ** 6),
       value=st.sampled_from(JSON_VALUES), rename=st.booleans(),
       command=st.sampled_from([["report"], ["export", "--format", "camera-info"],
                                ["export", "--format", "kalibr"], ["export", "--format", "urdf"],
                                ["export", "--format", "opencv"]]))
@example(file="calibration.json", pick=0, value="[" * 100_000, rename=False,
         command=["report"])                              # nested deeper than the stack
def test_mangled_calibration_json_for_report_and_export(calibrated, file, pick, value, rename,
                                                         command):
    """A calibration.json or details.json with a value (or a camera name) replaced: exit 0
    or 2 with one line, no traceback, and nothing written outside OUT (issue 19, item 4)."""
    work = Path(tempfile.mkdtemp(prefix="mangled-json-"))
    out = work / "out"
    shutil.copytree(calibrated, out)
    try:
        data = json.loads((out / file).read_text())
        if value == "[" * 100_000:
            text = value + "]" * 100_000
        else:
            paths = [p for p in _json_paths(data) if p]
            where = paths[pick % len(paths)]
            here = data
            for key in where[:-1]:
                here = here[key]
            if rename and isinstance(here, dict):
                here[str(value)[:6000]] = here.pop(where[-1])
            else:
                here[where[-1]] = value
            text = json.dumps(data)
        (out / file).write_text(text)
        before = sorted(p.name for p in work.iterdir())
        res = CliRunner().invoke(main, [command[0], str(out), *command[1:]])
        assert res.exit_code in (0, 2), (res.exit_code, res.output, res.exception)
        assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
        if res.exit_code == 2:
            lines = res.stderr.strip().splitlines()
            assert len(lines) == 1 and lines[0].startswith("multieye: error: "), res.stderr
        assert sorted(p.name for p in work.iterdir()) == before     # nothing beside OUT
    finally:
        shutil.rmtree(work)


NAME_PARTS = ["../", "/", "\\", "..", ".", "\x00", "\t", "\n", " ", "é", "e\u0301", "a", "CAM",
              ":", "\u202e", "c" * 60]


@settings(max_examples=8, **SETTINGS)
@given(parts=st.lists(st.sampled_from(NAME_PARTS), min_size=1, max_size=5))
@example(parts=["../", "../", "x"])
@example(parts=["c" * 60, "c" * 60])
def test_mangled_camera_names(pose_dataset, parts):
    """A camera named from hostile pieces: refused with rig.yaml's line, or (a file name on
    every system) calibrated with nothing written outside OUT (issue 19, item 1)."""
    name = "".join(parts)

    def rename(ds):
        rig = ds / "rig.yaml"
        rig.write_text(rig.read_text().replace("  cam1:", f"  ? {json.dumps(name)}\n  :"))

    res, ds, out, work = _run(pose_dataset, rename)
    try:
        error = _check_outcome(res, out)
        from multieye.core.names import camera_name_problem

        if error is not None:
            assert "rig.yaml:" in error and camera_name_problem(name) is not None, error
        else:
            assert camera_name_problem(name) is None, name
            assert sorted(p.name for p in work.iterdir()) == ["ds", "out"]
    finally:
        shutil.rmtree(work)
