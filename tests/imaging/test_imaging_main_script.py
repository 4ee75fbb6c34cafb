"""Worker processes and the main script: when importing it again would run it again."""

from __future__ import annotations

import ast
import subprocess
import sys

import cv2
import numpy as np
import pytest

from multieye.core.geometry import transform_from_rotvec
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.main_script import _is_main_guard, main_reimport_problem
from multieye.imaging.targets import Chessboard
from multieye.sim.render import render


@pytest.mark.parametrize("test, guard", [
    ('__name__ == "__main__"', True),
    ("'__main__' == __name__", True),
    ('__name__ == "__main__" and not quiet', True),
    ('__name__ != "__main__"', False),
    ('__name__ == "other"', False),
    ('name == "__main__"', False),
    ('__name__ == "__main__" or x', False),
])
def test_main_guard_forms(test, guard):
    assert _is_main_guard(ast.parse(test, mode="eval").body) is guard


def test_pytest_itself_may_start_workers():
    assert main_reimport_problem() is None


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    folder = tmp_path_factory.mktemp("imgs")
    camera = Intrinsics(K=[[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], dist=[0, 0, 0, 0, 0],
                        width=640, height=480)
    board = Chessboard(rows=5, cols=7, spacing=0.04)
    for k, tilt in enumerate([(0.3, -0.2, 0.05), (-0.25, 0.3, 0.0), (0.1, 0.35, -0.1)]):
        T = transform_from_rotvec(tilt, [0.0, 0.0, 0.0])
        T[:3, 3] = -T[:3, :3] @ [0.12, 0.08, 0.0] + [0.0, 0.0, 0.6]
        cv2.imwrite(str(folder / f"{k}.png"), render(board, camera, T, rng=np.random.default_rng(k)))
    return folder


SCRIPT = """\
import sys
from pathlib import Path
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.batch import detect_and_estimate, detect_and_estimate_arrays
from multieye.imaging.targets import Chessboard
import cv2

CAMERA = Intrinsics(K=[[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], dist=[0, 0, 0, 0, 0],
                    width=640, height=480)
BOARD = Chessboard(rows=5, cols=7, spacing=0.04)
paths = sorted(Path({folder!r}).glob("*.png"))
print("body", flush=True)

def run():
    files = detect_and_estimate(paths, BOARD, CAMERA, processes=2, progress=False)
    arrays = detect_and_estimate_arrays(((p.name, cv2.imread(str(p), 0)) for p in paths),
                                        BOARD, CAMERA, processes=2, progress=False, batch=2)
    print("ok", [r.ok for r in files], [r.ok for r in arrays], flush=True)

{call}
"""


@pytest.mark.parametrize("call, threads", [
    ("run()", True),                                          # top level: threads
    ('if __name__ == "__main__":\n    run()', False),         # guarded: processes
    ("import threading\nt = threading.Thread(target=run)\nt.start()\nt.join()", True),
])
def test_detection_in_a_script(images, tmp_path, call, threads):
    script = tmp_path / "detect.py"
    script.write_text(SCRIPT.format(folder=str(images), call=call))
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.count("ok [True, True, True] [True, True, True]") == 1
    # worker processes import the script again (and print its body); threads do not
    assert (res.stdout.count("body") == 1) is threads, res.stdout
    assert ("detecting in 2 threads" in res.stderr) is threads, res.stderr


def test_python_c_has_no_main_script_to_import(images):
    code = SCRIPT.format(folder=str(images), call="run()")
    res = subprocess.run([sys.executable, "-W", "error::RuntimeWarning", "-c", code],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert "ok [True, True, True] [True, True, True]" in res.stdout
