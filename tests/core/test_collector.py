"""Python's collector run less often in the processes multieye owns (multieye.core.collector):
the command line's and the figure workers', not a library user's.  Process-wide settings, so
each case runs in a fresh interpreter."""

from __future__ import annotations

import subprocess
import sys
import textwrap

from multieye.core.collector import YOUNG_THRESHOLD


def _run(code: str) -> str:
    run = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    return run.stdout.strip().splitlines()[-1]


def test_fewer_collections_raises_the_young_threshold_only():
    out = _run("""
        import gc
        from multieye.core.collector import fewer_collections
        gc.set_threshold(700, 10, 10)
        a = fewer_collections()
        b = fewer_collections(100)          # never more often than it is
        gc.set_threshold(0)
        c = fewer_collections()             # the collector off: left off
        print(a, b, c)
    """)
    assert out == f"({YOUNG_THRESHOLD}, 10, 10) ({YOUNG_THRESHOLD}, 10, 10) (0, 10, 10)"


def test_the_command_line_and_the_figure_workers_collect_less_often_a_library_user_not():
    out = _run("""
        import contextlib, gc, io
        import multieye, multieye.pipeline, multieye.outputs.write
        library = gc.get_threshold()[0]
        from multieye.cli import main
        with contextlib.redirect_stdout(io.StringIO()):
            main(["docs", "outputs"], standalone_mode=False)
        command = gc.get_threshold()[0]
        gc.set_threshold(700)
        from multieye.outputs.figures_rig import warm_up
        warm_up()                           # what a figure worker runs first
        print(library, command, gc.get_threshold()[0])
    """)
    assert out == f"700 {YOUNG_THRESHOLD} {YOUNG_THRESHOLD}"
