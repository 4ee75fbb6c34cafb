"""The detection's fork server does registered work when asked, for the workers it forks
afterwards (:mod:`multieye.imaging.forkserver_later`; issue 21: the figure modules imported
once for both figure workers)."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif("forkserver" not in multiprocessing.get_all_start_methods(),
                                reason="no fork server on this platform")

#: A preload module: registers work that records the process it ran in.
LATER = """
import os
from multieye.imaging.forkserver_later import when_asked

DONE = []
REGISTERED = when_asked(lambda: DONE.append(os.getpid()))
"""

#: argv[1]: the preload module to ask for ("later_work", or one the server never imported).
ASKING = """
import os, sys
import later_work
from multieye.imaging.workers import (ask_fork_server, mp_context, start_forkserver,
                                      stop_helpers, worker_pool)


def state():
    import later_work
    return later_work.DONE, later_work.REGISTERED, os.getppid()


if __name__ == "__main__":
    ctx = mp_context(("later_work",))
    assert start_forkserver(ctx)
    with worker_pool(1, mp_context=ctx) as pool:
        before = pool.submit(state).result()
    asked = ask_fork_server(sys.argv[1])
    with worker_pool(1, mp_context=ctx) as pool:
        after = pool.submit(state).result()
    stop_helpers()
    server = before[2]
    print(asked, before[0] == [], after[0] == ([server] if asked else []), before[1],
          later_work.REGISTERED, later_work.DONE == [])
"""


def _run(tmp_path, *args):
    (tmp_path / "later_work.py").write_text(LATER)
    (tmp_path / "asking.py").write_text(ASKING)
    paths = [os.path.abspath(p) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), *paths]))
    run = subprocess.run([sys.executable, str(tmp_path / "asking.py"), *args],
                         capture_output=True, text=True, timeout=120, env=env, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    return run.stdout.split()


def test_the_fork_server_does_its_registered_work_once_asked_and_only_then(tmp_path):
    """Before the request the workers it forks see no work done; after it, they see it done
    once, in the server (their parent); the server registered it at its preload, the
    asking process (which imported the module too) did not, and did no work."""
    assert _run(tmp_path, "later_work") == ["True", "True", "True", "True", "False", "True"]


def test_a_module_the_server_never_imported_is_not_asked_for(tmp_path):
    """Asking for work of a module outside the server's preload sends nothing and does
    nothing; the server goes on forking workers."""
    assert _run(tmp_path, "never_preloaded") == ["False", "True", "True", "True", "False",
                                                 "True"]


UNREGISTERED = """
import os, sys
from multiprocessing import forkserver
from multieye.imaging.forkserver_later import ask
from multieye.imaging.workers import mp_context, start_forkserver, stop_helpers, worker_pool

if __name__ == "__main__":
    ctx = mp_context()
    assert start_forkserver(ctx)
    with worker_pool(1, mp_context=ctx) as pool:
        pool.submit(os.getpid).result()
    print(ask(forkserver._forkserver._forkserver_pid))
    with worker_pool(1, mp_context=ctx) as pool:
        print(pool.submit(os.getpid).result() > 0)
    stop_helpers()
"""


def test_a_fork_server_with_no_registered_work_ignores_the_request(tmp_path):
    """The request is a signal whose default action is to ignore it: a fork server whose
    preload registered nothing goes on as before (it would end on SIGUSR1)."""
    script = tmp_path / "unregistered.py"
    script.write_text(UNREGISTERED)
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["True", "True"]
