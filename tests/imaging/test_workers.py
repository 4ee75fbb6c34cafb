"""Worker processes end with the process that started them, however it ends."""

from __future__ import annotations

import os
import multiprocessing
import subprocess
import sys
import time

import pytest
from proc_tree import needs_proc, running, wait_until

from multieye.imaging.workers import worker_pool

HOLDER = """
import multiprocessing, sys, time
from multieye.imaging.workers import worker_pool
with worker_pool(2, mp_context=multiprocessing.get_context(sys.argv[1])) as pool:
    futures = [pool.submit(time.sleep, 60) for _ in range(4)]
    while len(pool._processes) < 2 or not any(f.running() for f in futures):
        time.sleep(0.02)
    print(" ".join(map(str, pool._processes)), flush=True)
    time.sleep(60)
"""


@needs_proc
@pytest.mark.parametrize("method", ["forkserver", "fork"])
def test_workers_end_within_a_second_of_a_sigkilled_main_process(method):
    main = subprocess.Popen([sys.executable, "-c", HOLDER, method], stdout=subprocess.PIPE,
                            text=True)
    try:
        workers = [int(p) for p in main.stdout.readline().split()]
        assert len(workers) == 2 and all(running(p) for p in workers)
        main.kill()
        took = wait_until(lambda: not any(running(p) for p in workers), timeout=5.0)
        assert took is not None, "workers still running 5 s after the main process was killed"
        assert took < 2.0, took
    finally:
        main.kill()
        main.wait()


@needs_proc
def test_leaving_the_pool_by_an_exception_ends_the_workers_at_once():
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        with worker_pool(2, mp_context=multiprocessing.get_context("forkserver")) as pool:
            futures = [pool.submit(time.sleep, 30) for _ in range(6)]
            assert wait_until(lambda: any(f.running() for f in futures), timeout=20.0) is not None
            workers = list(pool._processes)
            raise KeyboardInterrupt
    assert time.monotonic() - start < 15.0          # not the 90 s of queued work
    assert wait_until(lambda: not any(running(p) for p in workers), timeout=5.0) is not None
    assert wait_until(lambda: all(f.done() for f in futures), timeout=5.0) is not None


def test_a_pool_left_normally_finishes_its_work():
    with worker_pool(2) as pool:
        assert list(pool.map(abs, [-1, -2, 3])) == [1, 2, 3]


WRITER = """
import multiprocessing, os
from concurrent.futures.process import BrokenProcessPool
from multieye.imaging.workers import worker_pool
ctx = multiprocessing.get_context("forkserver")
with worker_pool(1, mp_context=ctx) as pool:
    pool.submit(os.write, 2, b"noise of a healthy worker\\n").result()
print("first pool done", flush=True)
try:
    with worker_pool(1, mp_context=ctx) as pool:
        pool.submit(os.write, 2, b"last words of a worker\\n").result()
        pool.submit(os._exit, 3).result()
except BrokenProcessPool:
    print("broken", flush=True)
"""


@needs_proc
def test_workers_stderr_is_shown_only_when_a_worker_ends_abruptly():
    """Workers (and the fork server) write to a file of the main process, not the terminal:
    nothing of theirs reaches standard error unless a worker died, then their last words."""
    res = subprocess.run([sys.executable, "-c", WRITER], capture_output=True, text=True,
                         timeout=120)
    assert res.stdout.split() == ["first", "pool", "done", "broken"], res
    assert "noise of a healthy worker" not in res.stderr
    assert res.stderr.splitlines() == ["multieye: a worker process ended abruptly; it wrote:",
                                       "last words of a worker"], res.stderr


FAST_END = """
import sys
from multieye.imaging import forkserver_exit
from multieye.imaging.workers import mp_context, stop_helpers, worker_pool


def flag():
    return sys.modules["multieye.imaging.forkserver_exit"].ENDS_AT_ONCE


if __name__ == "__main__":
    with worker_pool(1, mp_context=mp_context()) as pool:
        in_server = pool.submit(flag).result()
    stop_helpers()
    print(in_server, forkserver_exit.ENDS_AT_ONCE)
"""


@pytest.mark.skipif("forkserver" not in multiprocessing.get_all_start_methods(),
                    reason="no fork server on this platform")
def test_the_fork_server_ends_at_its_first_exit_function_and_only_it(tmp_path):
    """The detection's fork server is told to end without freeing every module (40-90 ms of
    the command's end, issue 21): its workers, forked from it, carry the flag; the process
    that imports the module itself does not, so it ends as usual."""
    script = tmp_path / "fast_end.py"
    script.write_text(FAST_END)
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["True", "False"]


STOP_HELPERS = """
import os, sys, time
from multiprocessing import forkserver, resource_tracker
from multieye.imaging import workers
from multieye.imaging.workers import mp_context, stop_helpers, worker_pool


def no_polling(seconds):
    raise AssertionError(f"polled: time.sleep({seconds})")


if __name__ == "__main__":
    with worker_pool(1, mp_context=mp_context()) as pool:
        pool.submit(os.getpid).result()
    server = forkserver._forkserver._forkserver_pid
    tracker = resource_tracker._resource_tracker._pid
    workers.time.sleep = no_polling     # the helpers' ends are waited on, not polled for
    stop_helpers()
    gone = []
    for pid in (server, tracker):
        try:
            os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:       # collected by stop_helpers
            gone.append(pid)
    print(len(gone), forkserver._forkserver._forkserver_pid, resource_tracker._resource_tracker._pid)
"""


@pytest.mark.skipif(not hasattr(os, "pidfd_open"), reason="no pidfd on this platform")
def test_the_helpers_are_collected_as_they_end_without_polling(tmp_path):
    """stop_helpers waits on the fork server's and the resource tracker's pidfds: every
    command ended up to 10 ms later per helper while it checked every 10 ms."""
    script = tmp_path / "stop_helpers.py"
    script.write_text(STOP_HELPERS)
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["2", "None", "None"]
