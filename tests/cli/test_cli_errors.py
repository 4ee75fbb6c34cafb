"""Bad input: one clear line on stderr, exit status 2, and no calibration.json written."""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from pose_dataset import RIG, write_pose_dataset

from multieye.cli import main


@pytest.fixture
def dataset(tmp_path):
    return write_pose_dataset(tmp_path)[0]


def _run(args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _fails(ds, out, *expected):
    res = _run(["calibrate", ds, "-o", out])
    assert res.exit_code == 2, (res.exit_code, res.stdout, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert "Traceback" not in res.stderr
    for text in expected:
        assert text in lines[0], lines[0]
    assert not (out / "calibration.json").exists()
    assert not (out / "camchain.yaml").exists()
    return lines[0]


def test_good_dataset_exits_0(dataset, tmp_path):
    res = _run(["calibrate", dataset, "-o", tmp_path / "out"])
    assert res.exit_code == 0, res.stderr
    assert (tmp_path / "out" / "calibration.json").exists()
    assert "cam1" in res.stdout


def test_missing_dataset(tmp_path):
    _fails(tmp_path / "nope", tmp_path / "out", "nope", "rig.yaml")


def test_missing_motion_capture_file(dataset, tmp_path):
    (dataset / "mocap.txt").unlink()
    _fails(dataset, tmp_path / "out", "mocap.txt")


def test_malformed_line_names_file_and_line(dataset, tmp_path):
    lines = (dataset / "mocap.txt").read_text().splitlines()
    k = next(i for i, l in enumerate(lines) if not l.startswith("#")) + 3
    lines[k] = " ".join(lines[k].split()[:7])
    (dataset / "mocap.txt").write_text("\n".join(lines) + "\n")
    _fails(dataset, tmp_path / "out", f"mocap.txt:{k + 1}:", "8 entries")


def test_non_unit_quaternion(dataset, tmp_path):
    lines = (dataset / "cam1.txt").read_text().splitlines()
    k = next(i for i, l in enumerate(lines) if not l.startswith("#")) + 1
    parts = lines[k].split()
    parts[4:8] = ["0.5", "0.5", "0.5", "0.9"]
    lines[k] = " ".join(parts)
    (dataset / "cam1.txt").write_text("\n".join(lines) + "\n")
    _fails(dataset, tmp_path / "out", f"cam1.txt:{k + 1}:", "quaternion")


def test_unknown_key_and_wrong_type_in_rig_yaml(dataset, tmp_path):
    (dataset / "rig.yaml").write_text(RIG.replace("  time_tolerance: 0.01", "  time_tolerence: 0.01"))
    _fails(dataset, tmp_path / "out", "rig.yaml:6", "time_tolerence")
    (dataset / "rig.yaml").write_text(RIG.replace("rows: 6", "rows: six"))
    _fails(dataset, tmp_path / "out", "rig.yaml:2", "rows")
    (dataset / "rig.yaml").write_text(RIG.replace("eye-to-base", "eye-in-the-sky"))
    _fails(dataset, tmp_path / "out", "rig.yaml:1", "eye-to-base")


def test_camera_with_fewer_than_3_paired_images(dataset, tmp_path):
    # move cam1's time stamps away from the motion capture except for two of them
    lines = (dataset / "cam1.txt").read_text().splitlines()
    data = [i for i, l in enumerate(lines) if not l.startswith("#")]
    for i in data[2:]:
        parts = lines[i].split()
        parts[0] = str(float(parts[0]) + 0.25)
        lines[i] = " ".join(parts)
    (dataset / "cam1.txt").write_text("\n".join(lines) + "\n")
    msg = _fails(dataset, tmp_path / "out", "camera cam1", "only 2 of 12", "at least 3")
    assert "10 without motion capture" in msg


def test_target_never_detected_in_one_camera(dataset, tmp_path):
    (dataset / "cam1").mkdir()
    for k in range(4):
        cv2.imwrite(str(dataset / "cam1" / f"{k}.000000.png"), np.full((480, 640), 128, np.uint8))
    (dataset / "rig.yaml").write_text(RIG.replace("cam1: {intrinsics: cam.yaml, poses: cam1.txt}",
                                                  "cam1: {intrinsics: cam.yaml, images: cam1/}"))
    _fails(dataset, tmp_path / "out", "camera cam1", "not detected in any of the 4 images")


def test_unknown_method_and_reference(dataset, tmp_path):
    res = _run(["calibrate", dataset, "-o", tmp_path / "out", "--method", "magic"])
    assert res.exit_code == 2 and "magic" in res.stderr
    _ = _run(["calibrate", dataset, "-o", tmp_path / "out", "--reference", "cam9"])
    assert _.exit_code == 2 and "cam9" in _.stderr
    assert not (tmp_path / "out" / "calibration.json").exists()


def test_failed_run_leaves_previous_result_untouched(dataset, tmp_path):
    out = tmp_path / "out"
    assert _run(["calibrate", dataset, "-o", out]).exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert {"calibration.json", "camchain.yaml", "details.json", "report.html"} <= set(before)
    (dataset / "mocap.txt").write_text("garbage\n")
    res = _run(["calibrate", dataset, "-o", out])
    assert res.exit_code == 2
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert after == before


def test_console_script_help_is_instant_and_lists_commands():
    res = subprocess.run([sys.executable, "-m", "multieye.cli", "--help"], capture_output=True,
                         text=True, timeout=60)
    assert res.returncode == 0
    for cmd in ("calibrate", "demo", "experiment"):
        assert cmd in res.stdout


def test_export_formats_listed_in_cli_match_the_library():
    from multieye.cli import EXPORT_FORMATS
    from multieye.outputs.export import FORMATS

    assert set(EXPORT_FORMATS) == set(FORMATS)


def test_calibrate_writes_details_and_report_then_export_and_report_commands(dataset, tmp_path):
    out = tmp_path / "out"
    assert _run(["calibrate", dataset, "-o", out]).exit_code == 0
    assert (out / "details.json").exists() and (out / "report.html").exists()
    (out / "report.html").unlink()
    res = _run(["report", out])
    assert res.exit_code == 0 and (out / "report.html").exists()
    for fmt in ("kalibr", "opencv", "urdf", "tf-static", "json"):
        res = _run(["export", out, "--format", fmt])
        assert res.exit_code == 0, res.stderr
        assert all((tmp_path / p).exists() or __import__("pathlib").Path(p).exists()
                   for p in res.stdout.split())
    res = _run(["report", tmp_path / "empty"])
    assert res.exit_code == 2 and "calibration.json" in res.stderr


def test_run_is_all_or_nothing_when_an_output_cannot_be_written(dataset, tmp_path):
    out = tmp_path / "out"
    (out / "report.html").mkdir(parents=True)          # a folder where a file must go
    res = _run(["calibrate", dataset, "-o", out])
    assert res.exit_code == 2 and len(res.stderr.strip().splitlines()) == 1
    assert "report.html" in res.stderr
    assert sorted(p.name for p in out.iterdir()) == ["report.html"]   # nothing new, no temp


def test_output_below_a_file_is_one_line(dataset, tmp_path):
    (tmp_path / "afile").write_text("x")
    res = _run(["calibrate", dataset, "-o", tmp_path / "afile" / "sub"])
    assert res.exit_code == 2 and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_time_offset_is_applied_with_the_documented_sign(tmp_path):
    """time_offset = motion-capture clock minus camera clock: shifting the camera stamps by
    -0.2 s and declaring time_offset 0.2 gives the exact answer back."""
    from multieye.pipeline import calibrate

    (tmp_path / "d").mkdir()
    folder, T_world_cam, _ = write_pose_dataset(tmp_path / "d")
    for j in range(2):
        lines = (folder / f"cam{j}.txt").read_text().splitlines()
        shifted = [l if l.startswith("#") else " ".join([repr(float(l.split()[0]) - 0.2)] + l.split()[1:])
                   for l in lines]
        (folder / f"cam{j}.txt").write_text("\n".join(shifted) + "\n")
    rig = (folder / "rig.yaml").read_text()
    (folder / "rig.yaml").write_text(rig.replace("poses: cam0.txt}", "poses: cam0.txt, time_offset: 0.2}")
                                        .replace("poses: cam1.txt}", "poses: cam1.txt, time_offset: 0.2}"))
    run = calibrate(folder)
    np.testing.assert_allclose(run.closed_form.X, T_world_cam, atol=1e-9)
    (folder / "rig.yaml").write_text(rig.replace("poses: cam0.txt}", "poses: cam0.txt, time_offset: -0.2}"))
    res = _run(["calibrate", folder, "-o", tmp_path / "o"])
    assert res.exit_code == 2 and "without motion capture" in res.stderr


def test_poses_camera_may_omit_intrinsics_and_non_finite_numbers_are_refused(dataset, tmp_path):
    rig = (dataset / "rig.yaml").read_text()
    (dataset / "rig.yaml").write_text(rig.replace("cam1: {intrinsics: cam.yaml, poses: cam1.txt}",
                                                  "cam1: {poses: cam1.txt}"))
    res = _run(["calibrate", dataset, "-o", tmp_path / "out"])
    assert res.exit_code == 0, res.stderr
    assert "camchain.yaml holds cam0 only; left out: cam1 (no intrinsics)" in res.stdout
    assert (tmp_path / "out" / "camchain.yaml").read_text().startswith(
        "# left out of this camchain: cam1 (no intrinsics)\ncam0:")
    (dataset / "rig.yaml").write_text(rig.replace("time_tolerance: 0.01", "time_tolerance: .inf"))
    _fails(dataset, tmp_path / "out2", "rig.yaml:6", "time_tolerance")


def test_experiment_command_writes_csv_and_png(tmp_path):
    res = _run(["experiment", "measurements", "--trials", "1", "-o", tmp_path])
    assert res.exit_code == 0, res.stderr
    assert (tmp_path / "measurements.csv").exists() and (tmp_path / "measurements.png").exists()
    header = (tmp_path / "measurements.csv").read_text().splitlines()[0]
    for col in ("param", "method", "e_R_deg", "e_t_m"):
        assert col in header


def test_experiment_is_refused_while_another_run_holds_its_folder(tmp_path):
    """Issue 32: every command that writes into an existing folder takes its lock (a
    calibration holding the folder would refuse to replace it, or remove what was written)."""
    out = tmp_path / "out"
    out.mkdir()
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys; from multieye.outputs.folder import claim_output\n"
         "with claim_output(sys.argv[1]):\n print('held', flush=True)\n sys.stdin.read()",
         str(out)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        res = _run(["experiment", "measurements", "--trials", "1", "-o", out])
    finally:
        holder.communicate("")
    assert res.exit_code == 2
    assert res.stderr.startswith(f"multieye: error: {out}: in use by another multieye run "
                                 f"(process {holder.pid}: "), res.stderr
    assert list(out.iterdir()) == []


def test_import_and_help_do_not_load_the_numerical_stack():
    code = ("import sys, multieye, multieye.cli; "
            "heavy = [m for m in ('numpy', 'scipy', 'cv2', 'matplotlib') if m in sys.modules]; "
            "print(heavy); assert not heavy, heavy; "
            "assert callable(multieye.solve) and callable(multieye.calibrate)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stdout + res.stderr
