"""multieye from Python as people write it: plain scripts, and the README's example as shown."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from small_dataset import render_small

README = Path(__file__).resolve().parents[2] / "README.md"


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("python_use") / "ds"
    render_small(folder)
    return folder


def _run_script(folder: Path, code: str) -> subprocess.CompletedProcess:
    script = folder / "script.py"
    script.write_text(code)
    return subprocess.run([sys.executable, str(script)], cwd=folder, capture_output=True,
                          text=True, timeout=300)


def test_plain_script_without_main_guard_calibrates_with_two_processes(dataset, tmp_path):
    res = _run_script(tmp_path, textwrap.dedent(f"""\
        import multieye

        print("script body", flush=True)
        run = multieye.calibrate({str(dataset)!r}, processes=2)
        print("T_ref_cam cam1", run.T_ref_cam["cam1"][:3, 3].tolist())
        """))
    assert res.returncode == 0, res.stderr
    # the script ran once: no worker process imported it again
    assert res.stdout.count("script body") == 1
    translation = re.search(r"^T_ref_cam cam1 \[(.*)\]$", res.stdout, re.M)
    assert translation, res.stdout
    truth = json.loads((dataset / "ground_truth.json").read_text())
    T_truth = np.array(truth["cameras"]["cam1"]["T_ref_cam"])
    t = np.array([float(v) for v in translation.group(1).split(",")])
    assert np.linalg.norm(t - T_truth[:3, 3]) < 5e-3
    # why detection ran in threads, pointing at the script's line
    assert "script.py:4: RuntimeWarning: multieye: detecting in 2 threads" in res.stderr
    assert 'outside `if __name__ == "__main__":`' in res.stderr


def test_guarded_script_detects_in_worker_processes_without_a_warning(dataset, tmp_path):
    res = _run_script(tmp_path, textwrap.dedent(f"""\
        import warnings
        import multieye

        def main():
            warnings.simplefilter("error", RuntimeWarning)
            run = multieye.calibrate({str(dataset)!r}, processes=2)
            print("cameras", list(run.T_ref_cam))

        if __name__ == "__main__":
            main()
        """))
    assert res.returncode == 0, res.stderr
    assert "cameras ['cam0', 'cam1']" in res.stdout
    assert "RuntimeWarning" not in res.stderr


def _readme_python_example() -> str:
    text = README.read_text()
    section = text.split("## Use it from Python", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


@pytest.mark.parametrize("cameras", [2, 1])
def test_readme_python_example_runs_as_shown(dataset, tmp_path, cameras):
    """The README's example on the two-camera rig and on a one-camera rig (where T_ref_cam is
    the identity, X is the answer): it prints each camera's X with its std."""
    if cameras == 1:
        shutil.copytree(dataset, tmp_path / "ds")
        text = (tmp_path / "ds" / "rig.yaml").read_text()
        (tmp_path / "ds" / "rig.yaml").write_text(text[:text.index("  cam1:")])
        dataset = tmp_path / "ds"
    code = _readme_python_example()
    assert code.count('"DATASET"') == 1 and code.count('"OUT"') == 1
    out = tmp_path / "out"
    res = _run_script(tmp_path, code.replace('"DATASET"', repr(str(dataset)))
                      .replace('"OUT"', repr(str(out))))
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    names = ["cam0", "cam1"][:cameras]
    assert [ln.split()[0] for ln in lines[:cameras]] == names
    truth = json.loads((dataset / "ground_truth.json").read_text())
    data = json.loads((out / "calibration.json").read_text())
    for line, name in zip(lines, names):
        t = re.search(r"X: t = \[(.*?)\] m, std \((.*?)\)", line)
        assert t, line
        X_truth = np.array(truth["cameras"][name]["T_world_cam"])
        assert np.linalg.norm(np.array(t.group(1).split(), float) - X_truth[:3, 3]) < 5e-3
        std = [float(v) for v in t.group(2).split(",")]
        x_unc = data["cameras"][name]["uncertainty"]["T_world_cam"]
        assert std == pytest.approx([x_unc["std_rot_deg"], x_unc["std_trans_m"]], abs=1e-4)
        assert 0 < std[0] < 1 and 0 < std[1] < 0.01
    assert lines[cameras].startswith("Y: t = [")
    assert [ln[len("warning: "):] for ln in lines if ln.startswith("warning: ")] == data["warnings"]
    assert lines[-1].startswith(f"solve: ({cameras}, 4, 4) (4, 4) [")
    assert (out / "calibration.json").is_file() and (out / "details.json").is_file()


def test_help_of_the_package_is_short_and_starts_with_the_functions():
    """``help(multieye)``: at most 300 lines, the functions within the first 120, the classes
    and errors named in its description (each has its own help)."""
    res = subprocess.run([sys.executable, "-c", "import pydoc, multieye; print(pydoc.render_doc("
                          "multieye, renderer=pydoc.plaintext))"], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert len(lines) <= 300
    first = "\n".join(lines[:120])
    for function in ("calibrate(", "solve(", "solve_general("):
        assert f"\n    {function}" in first
    for name in ("Options", "CalibrationRun", "Solution", "CalibrationError", "InputError",
                 "DatasetError", "TooFewMeasurementsError", "DegenerateMotionError",
                 "DisconnectedError"):
        assert name in first
    import multieye

    assert issubclass(multieye.DatasetError, multieye.CalibrationError)
    assert multieye.Options is multieye.pipeline.Options
