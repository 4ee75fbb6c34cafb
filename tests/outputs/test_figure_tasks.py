"""What a figure worker imports to take the report's figures (issue 32, the fixed costs).

A figure worker is forked from the detection's fork server, which imported the detection
(numpy, OpenCV) and then the figure modules (:func:`multieye.outputs.figure_workers._warm_up`).
Each figure is sent to it as a pickled task: a function by its module's name and the record
and details.  Unpickling a function imports its module: a task whose module pulled in SciPy
(``report_draw``, through the camera tables' checks) cost the worker that drew the rig
0.15-0.3 CPU-s of imports before it drew anything, on the report's critical path.
"""

from __future__ import annotations

import pickle
import subprocess
import sys

from export_runs import make_run

from multieye.imaging.workers import FORKSERVER_PRELOAD
from multieye.outputs.details import write_run_details
from multieye.outputs.figure_workers import PRELOAD
from multieye.outputs.report_draw import _tasks, figure_jobs

#: A figure worker: the fork server's preload and its warm-up, then every task unpickled as
#: the pool's worker does before it runs one; prints the heavy modules then imported.
WORKER = r"""
import importlib, pickle, sys
for name in sys.argv[2:]:
    importlib.import_module(name)
from multieye.outputs.figure_workers import _warm_up
_warm_up()
with open(sys.argv[1], "rb") as f:
    tasks = pickle.load(f)
print(len(tasks), " ".join(m for m in ("scipy", "multieye.estimate", "multieye.pipeline",
                                       "multieye.solvers") if m in sys.modules))
"""


def test_a_figure_worker_takes_every_task_without_importing_scipy(tmp_path):
    run, _ = make_run(tmp_path, "eye-to-base", noise=1e-3)
    details = write_run_details(tmp_path / "details.json", run)
    tasks = [(func, args) for _, func, args in
             _tasks(run.record, details, figure_jobs(run.record, details), 2)]
    assert len(tasks) >= 3            # the rig's pictures and the all-camera figures
    (tmp_path / "tasks.pickle").write_bytes(pickle.dumps(tasks))
    preload = [*FORKSERVER_PRELOAD[:-1], PRELOAD]
    done = subprocess.run([sys.executable, "-c", WORKER, str(tmp_path / "tasks.pickle"),
                           *preload], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    count, *heavy = done.stdout.split()
    assert int(count) == len(tasks)
    assert heavy == [], f"a figure worker imports {heavy} to take its tasks"
