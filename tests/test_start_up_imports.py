"""What each process of `multieye calibrate` imports before it works (issue 21): a heavy
module imported where nothing uses it costs every run its import time (scipy.optimize about
0.2 CPU-s, scipy.spatial 0.2-0.3, matplotlib 0.45).  Each case runs in a fresh interpreter."""

from __future__ import annotations

import subprocess
import sys

import pytest

#: (what the process imports first, heavy modules it must not have imported then)
CASES = {
    # the main process once the command has imported the pipeline and the output writers:
    # matplotlib only when the figures are drawn, scipy.optimize only for the Tabb solvers
    "main": ("multieye.pipeline, multieye.outputs.write, multieye.outputs.summary",
             ["matplotlib", "scipy.optimize", "scipy.stats"]),
    # the command before its fork server starts (cli._prestart_workers): not even numpy, so
    # that the server's imports of numpy and OpenCV run while this process imports its own
    "fork server start": ("multieye.cli, multieye.imaging.workers",
                          ["numpy", "cv2", "multieye.pipeline", "multieye.imaging.batch",
                           "statistics"]),
    # what the command imports before it sends the first image to the workers: the later
    # stages (SciPy, the solvers, the refinement, the writers) are imported while they detect
    # (tests/pipeline/test_detection_first.py checks the order in a real run)
    "before detection": ("multieye.cli, multieye.imaging.batch, multieye.pipeline.options, "
                         "multieye.pipeline.calibrate_dataset, multieye.pipeline.camera_data, "
                         "multieye.pipeline.detection, multieye.outputs.folder, "
                         "multieye.outputs.figure_workers",
                         ["scipy", "multieye.pipeline.run", "multieye.solvers.registry",
                          "multieye.optimize", "multieye.estimate.plausibility",
                          "multieye.outputs.write", "matplotlib", "secrets"]),
    # the fork server the detection's workers come from (imaging.workers.mp_context)
    "fork server": ("multieye.imaging.batch", ["scipy", "matplotlib", "multieye.pipeline"]),
    # the report's figure worker, forked from that fork server: the figure modules
    "figure worker": ("multieye.imaging.batch, multieye.outputs.figures, "
                      "multieye.outputs.figures_rig",
                      ["scipy", "matplotlib", "multieye.pipeline", "multieye.estimate"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_process_imports_no_heavy_module_it_does_not_use(case):
    modules, banned = CASES[case]
    code = (f"import sys\nimport {modules}\n"
            f"print(' '.join(m for m in {banned!r} if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == [], f"{case} imports {run.stdout.strip()}"
