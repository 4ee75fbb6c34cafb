"""Worker processes that never outlive the process that started them.

A worker of a ``concurrent.futures.ProcessPoolExecutor`` waits for work on a pipe whose
writing end it holds itself, so when the main process dies without shutting the pool down
(``SIGKILL``, a crash, an unhandled signal) the worker waits for ever; with the
``forkserver`` start method the fork server waits too, since every worker it forked holds
the pipe whose end it waits for.  Every pool of multieye comes from :func:`worker_pool`,
whose workers first call :func:`die_with`: a daemon thread that ends the worker as soon as
the main process has ended.  On Linux (5.3 and later) it waits on a pidfd of the main
process, which becomes readable the moment that process ends (a zombie counts as ended);
elsewhere it checks every 0.5 s (not on Windows, where nothing here is set up).  Once the
workers are gone, the fork server and multiprocessing's resource tracker see the end of
their pipes and end too.

So workers end within a second of the main process ending by any signal, ``SIGKILL``
included.  When the main process leaves a pool because of an exception (``KeyboardInterrupt``
from ``SIGINT``, the exception the command line raises on ``SIGTERM``, an error), the pool's
queued work is cancelled and its workers are terminated at once instead of finishing the
work already queued.

When this process ends (normally, by ``sys.exit``, on an exception, ``KeyboardInterrupt``
included), :func:`stop_helpers` stops multiprocessing's helper processes, the fork server
and the resource tracker, and waits for them (at most :data:`HELPER_WAIT_S` each): left to
themselves they end only after this process, which then cannot collect them, so they and
the workers they had not yet collected lingered as defunct processes after the command
returned, and their processor time was missing from this process's accounting
(``getrusage(RUSAGE_CHILDREN)`` of whoever ran it).

A worker's standard error is not the terminal's.  A worker forked by the fork server runs
before any code of multieye does: it unpickles its queues, whose semaphores the main
process removes when it ends.  A ``SIGINT`` while the pool is still starting workers (or a
``Ctrl-C``, which reaches every process of the terminal's group, a starting worker
included) thus made a starting worker print a traceback (``FileNotFoundError`` from
``SemLock._rebuild``, or ``KeyboardInterrupt``) under the main process's one line.  So the
fork server, and every worker it forks, is started with its standard error on an unnamed
temporary file that the main process owns (:func:`_quiet_forkserver`); what workers wrote
there is shown only when a worker ended abruptly (``BrokenProcessPool``), after the pool
is torn down.

This module imports neither numpy nor OpenCV, so that a command can start the detection's
fork server (:func:`prestart_workers`, :data:`FORKSERVER_PRELOAD`) before it imports them
itself, and both import at once on two cores (issue 21); :class:`Alongside` runs work (the
later stages' imports) on a thread of this process while the workers detect.

Synopsis
--------
>>> from multieye.imaging.workers import worker_pool
>>> with worker_pool(2) as pool:                    # doctest: +SKIP
...     results = list(pool.map(work, items))
"""

from __future__ import annotations

import atexit
import contextlib
import multiprocessing
import os
import select
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from multieye.core.cpus import available_cores
from multieye.imaging.main_script import main_reimport_problem

__all__ = ["worker_pool", "die_with", "stop_workers", "stop_helpers", "start_forkserver",
           "Alongside", "FORKSERVER_PRELOAD", "mp_context", "prestart_workers", "available_cores",
           "ask_fork_server", "progress_bar", "call_once"]

#: Seconds between two checks where the main process cannot be waited for (no pidfd).
POLL_S = 0.5


def _alive(pid: int) -> bool:
    """Whether process ``pid`` is running (a zombie, ended but not yet collected, is not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:             # exists, but belongs to someone else
        return True
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            stat = f.read()
    except OSError:             # no /proc (macOS, Windows)
        return True
    return stat[stat.rindex(b")") + 2:][:1] not in (b"Z", b"X")


def die_with(main_pid: int, *, poll_s: float = POLL_S) -> None:
    """End this process as soon as process ``main_pid`` ends (call it first in a worker).

    Parameters
    ----------
    main_pid : int
        The process that started the pool.  When it has already ended, this process ends
        at once.
    poll_s : float
        Seconds between two checks where no pidfd can be opened.
    """
    if main_pid == os.getpid() or os.name == "nt":   # Windows: os.kill(pid, 0) is Ctrl-C there
        return
    pidfd = None
    if hasattr(os, "pidfd_open"):
        try:
            pidfd = os.pidfd_open(main_pid)
        except ProcessLookupError:
            os._exit(1)
        except OSError:         # a kernel before 5.3: poll instead
            pidfd = None
    if not _alive(main_pid):
        os._exit(1)

    def watch():
        if pidfd is not None:
            select.select([pidfd], [], [])      # readable once main_pid has ended
        else:
            while _alive(main_pid):
                time.sleep(poll_s)
        sys.stderr.flush()
        os._exit(1)

    threading.Thread(target=watch, name="multieye-main-watchdog", daemon=True).start()


#: Most bytes of the workers' standard error shown after a worker ended abruptly.
RELAY_BYTES = 4000

#: The file the fork server's (and its workers') standard error is written to, once started.
_WORKER_STDERR: dict[str, int] = {}
#: The modules the fork server this process started imported first (its preload).
_PRELOADED: list[str] = []


def _quiet_forkserver(mp_context) -> int | None:
    """Start the fork server of ``mp_context`` (once a process) with its standard error on
    an unnamed temporary file; returns that file's descriptor (None for other start methods
    or when the fork server was started elsewhere, with the terminal's standard error)."""
    if mp_context is None or mp_context.get_start_method() != "forkserver":
        return None
    from multiprocessing import forkserver  # noqa: PLC0415 (only where the forkserver is used)

    if "fd" not in _WORKER_STDERR:
        server = getattr(forkserver, "_forkserver", None)
        if getattr(server, "_forkserver_pid", None) is not None:
            return None         # already running, started by someone else
        import tempfile  # noqa: PLC0415 (only once, when the forkserver first starts)

        try:
            with tempfile.TemporaryFile(prefix="multieye-workers-") as log:
                fd = os.dup(log.fileno())
        except OSError:         # no usable temporary folder: workers write where we do
            return None
        try:
            saved = os.dup(2)
        except OSError:         # no standard error at all: nothing to protect
            os.close(fd)
            return None
        if sys.stderr is not None:
            sys.stderr.flush()
        try:
            os.dup2(fd, 2)      # inherited by the fork server, so by every worker
            forkserver.ensure_running()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        _WORKER_STDERR["fd"] = fd
        _PRELOADED.extend(getattr(server, "_preload_modules", None) or ())
    return _WORKER_STDERR["fd"]


def _relay(fd: int | None, start: int) -> None:
    """Copy what the workers wrote to ``fd`` since offset ``start`` to standard error."""
    if fd is None or sys.stderr is None:
        return
    with contextlib.suppress(OSError):
        end = os.fstat(fd).st_size
        if end <= start:
            return
        data = os.pread(fd, min(end - start, RELAY_BYTES), max(start, end - RELAY_BYTES))
        if data.strip():
            sys.stderr.write("multieye: a worker process ended abruptly; it wrote:\n"
                             + data.decode("utf-8", "replace"))
            sys.stderr.flush()


def _start_worker(main_pid: int, initializer: Callable | None, initargs: tuple) -> None:
    die_with(main_pid)
    if initializer is not None:
        initializer(*initargs)


def stop_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel the queued work of ``pool`` and end its worker processes now."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        with contextlib.suppress(Exception):
            p.terminate()
    deadline = time.monotonic() + 2.0
    for p in processes:
        with contextlib.suppress(Exception):
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()


#: Seconds :func:`stop_helpers` waits for each helper process to end before leaving it.
HELPER_WAIT_S = 2.0


def _wait_for(pid: int, timeout_s: float) -> bool:
    """Collect child ``pid`` once it ends, waiting at most ``timeout_s``; True when it did.

    On Linux (5.3 and later) it waits on a pidfd of the child, readable the moment the child
    ends; elsewhere it checks every 10 ms (which made every command end up to 10 ms later
    per helper)."""
    deadline = time.monotonic() + timeout_s
    try:
        pidfd = os.pidfd_open(pid)
    except (AttributeError, OSError):   # not Linux 5.3+, or not a process any more
        pidfd = None
    try:
        while True:
            try:
                done, _ = os.waitpid(pid, os.WNOHANG)
            except ChildProcessError:       # not ours, or already collected
                return True
            if done:
                return True
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            if pidfd is not None:
                select.select([pidfd], [], [], left)
            else:
                time.sleep(min(0.01, left))
    finally:
        if pidfd is not None:
            os.close(pidfd)


def stop_helpers(timeout_s: float = HELPER_WAIT_S) -> None:
    """Stop this process's fork server and resource tracker (multiprocessing's helper
    processes) and collect them, each within ``timeout_s``.

    Both end when the pipe this process holds to them closes; the fork server first
    collects the workers it forked.  Called at exit (registered by :func:`worker_pool`);
    harmless when they never started or were stopped already.  A pool started afterwards
    starts them again.
    """
    from multiprocessing import forkserver, resource_tracker, util  # noqa: PLC0415 (at exit only)

    server = getattr(forkserver, "_forkserver", None)
    pid, fd = getattr(server, "_forkserver_pid", None), getattr(server, "_forkserver_alive_fd", None)
    if pid is not None and fd is not None:
        with server._lock:
            with contextlib.suppress(OSError):
                os.close(fd)
            server._forkserver_alive_fd = None
            if _wait_for(pid, timeout_s):
                server._forkserver_pid = None
                address = getattr(server, "_forkserver_address", None)
                if address and not util.is_abstract_socket_namespace(address):
                    with contextlib.suppress(OSError):
                        os.unlink(address)
                server._forkserver_address = None
    # the tracker only after the server has ended: closed together, the tracker could end
    # first and unlink the semaphores the process's own finalizers unlink next (a stopped
    # run then printed "Exception ignored ... sem_unlink" tracebacks)
    tracker = getattr(resource_tracker, "_resource_tracker", None)
    pid, fd = getattr(tracker, "_pid", None), getattr(tracker, "_fd", None)
    if pid is not None and fd is not None:
        with tracker._lock:
            with contextlib.suppress(OSError):
                os.close(fd)
            tracker._fd = None
            if _wait_for(pid, timeout_s):
                tracker._pid = None


_AT_EXIT: list[bool] = []


def _stop_helpers_at_exit() -> None:
    if not _AT_EXIT:
        atexit.register(stop_helpers)
        _AT_EXIT.append(True)


def start_forkserver(mp_context) -> bool:
    """Start the fork server of ``mp_context`` now, as :func:`worker_pool` would at its
    first pool (standard error on the workers' file, stopped and collected at exit).

    A fork server imports its preload modules (numpy, OpenCV) once; started early, that runs
    while this process goes on with its own work (imports, reading the dataset) instead of
    before the first worker can start.  True when a fork server of this process is running
    (started now or before); False for other start methods.
    """
    _stop_helpers_at_exit()
    return _quiet_forkserver(mp_context) is not None


@contextlib.contextmanager
def worker_pool(max_workers: int, *, mp_context=None, initializer: Callable | None = None,
                initargs: tuple = ()) -> Iterator[ProcessPoolExecutor]:
    """A process pool whose workers end with this process (see the module docstring).

    Parameters
    ----------
    max_workers : int
    mp_context : multiprocessing context, optional
        Default: the platform's default start method.
    initializer, initargs
        Run in every worker after its watchdog is set up.

    Yields
    ------
    ProcessPoolExecutor
        Shut down normally (waiting for its work) when the block ends normally; on an
        exception (``KeyboardInterrupt`` included) its queued work is cancelled and its
        workers are terminated before the exception propagates.
    """
    _stop_helpers_at_exit()
    log = _quiet_forkserver(mp_context)
    start = os.fstat(log).st_size if log is not None else 0
    pool = ProcessPoolExecutor(max_workers, mp_context=mp_context, initializer=_start_worker,
                               initargs=(os.getpid(), initializer, tuple(initargs)))
    try:
        yield pool
    except BaseException as exc:
        stop_workers(pool)
        if isinstance(exc, BrokenProcessPool):
            _relay(log, start)
        raise
    pool.shutdown(wait=True)

#: What the fork server imports once, before it forks any worker: the detection (numpy,
#: OpenCV), so that each worker starts in milliseconds; then what ends the server without
#: the interpreter's teardown (:mod:`multieye.imaging.forkserver_exit`).
FORKSERVER_PRELOAD = ("multieye.imaging.batch", "multieye.imaging.forkserver_exit")


def mp_context(preload: tuple[str, ...] = ()):
    """forkserver where it exists, spawn elsewhere: workers never inherit OpenCV's threads.

    The fork server imports :data:`FORKSERVER_PRELOAD` once, so that each worker it forks
    starts in milliseconds; without that preload every worker would import them again.
    ``preload``: more modules for it to import (before the last of them), e.g. one that
    registers work for later (:mod:`multieye.imaging.forkserver_later`); only a server not
    yet running takes them.
    """
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([*FORKSERVER_PRELOAD[:-1], *preload, FORKSERVER_PRELOAD[-1]])
    return ctx


def ask_fork_server(module: str) -> bool:
    """Ask the fork server for the work that ``module`` registered when the server imported
    it (:func:`multieye.imaging.forkserver_later.when_asked`): done before the server forks
    again, so the workers forked afterwards start with it.

    Returns
    -------
    bool
        Whether it was asked: a fork server this process started is running and imported
        ``module`` first; otherwise (no server, another's, or without ``module``) nothing.
    """
    from multiprocessing import forkserver  # noqa: PLC0415 (only where the forkserver is used)

    from multieye.imaging.forkserver_later import ask  # noqa: PLC0415 (only where the forkserver is used)

    pid = getattr(getattr(forkserver, "_forkserver", None), "_forkserver_pid", None)
    if pid is None or "fd" not in _WORKER_STDERR or module not in _PRELOADED:
        return False
    return ask(pid)


def prestart_workers(processes: int | None = None, preload: tuple[str, ...] = ()) -> bool:
    """Start, now, the fork server that the detection
    (:func:`multieye.imaging.batch.detect_and_estimate_jobs`) takes its worker processes
    from, when it will use some (more than one worker, forkserver available, the main
    script safe to import again).

    Its imports (numpy, OpenCV: about a quarter of a CPU second) then run on the other core
    while the caller imports and reads the rest, instead of between reading the dataset and
    the first detection; this module imports neither, so the server starts before the
    caller imports them too.  Nothing else changes: the pool forks its workers from it
    later, and it is stopped and collected when this process ends.  ``preload``: more
    modules for the server to import first (:func:`mp_context`).

    Returns
    -------
    bool
        Whether a fork server is running for the workers (not for ``processes`` other than
        None or an integer above 1: the detection says what is wrong with it).
    """
    wanted = available_cores() if processes is None else processes
    if (isinstance(wanted, bool) or not isinstance(wanted, int)
            or min(wanted, available_cores()) <= 1 or main_reimport_problem() is not None):
        return False
    ctx = mp_context(preload)
    return ctx.get_start_method() == "forkserver" and start_forkserver(ctx)


class Alongside:
    """Work for a thread of this process while the block runs, e.g. imports while the workers
    detect: started by :meth:`start` (at most once; at the block's end when never started),
    waited for when the block ends, and its exception raised then, when the block itself
    raised none.

    >>> with Alongside(work) as meanwhile:      # doctest: +SKIP
    ...     send_the_first_images()
    ...     meanwhile.start()                    # work() runs while the workers detect
    ...     collect_the_results()
    """

    def __init__(self, work: Callable[[], object] | None):
        self._work = work
        self._thread: threading.Thread | None = None
        self._failed: list[BaseException] = []

    def _run(self) -> None:
        try:
            self._work()
        except BaseException as exc:    # noqa: BLE001 - raised in the caller's thread, __exit__
            self._failed.append(exc)

    def start(self) -> None:
        """Start the work on its thread, unless started already (or there is none)."""
        if self._work is not None and self._thread is None:
            self._thread = threading.Thread(target=self._run, name="multieye-alongside",
                                            daemon=True)
            self._thread.start()

    def __enter__(self) -> Alongside:
        return self

    def __exit__(self, kind, exc, tb) -> None:
        if kind is None:
            self.start()
        if self._thread is not None:
            try:
                self._thread.join()
            except RuntimeError:        # never started: Ctrl-C came inside start(); the
                if kind is None:        # block's own exception (KeyboardInterrupt) goes on
                    raise
        if kind is None and self._failed:
            raise self._failed[0]


def progress_bar(total: int | None, desc: str, progress: bool | None):
    """A tqdm bar on stderr (None when ``progress`` is false, or None and stderr is not a
    terminal)."""
    show = sys.stderr.isatty() if progress is None else bool(progress)
    if not show:
        return None
    from tqdm import tqdm  # noqa: PLC0415 (tqdm only when a progress bar is shown)

    return tqdm(total=total, desc=desc, unit="img", file=sys.stderr)


def call_once(call: Callable[[], object] | None) -> Callable[[], None]:
    """``call``, called at most once (nothing for None)."""
    pending = [] if call is None else [call]

    def once() -> None:
        while pending:
            pending.pop()()

    return once
