"""Where independent tasks run: the local process pool (default) or a Dask cluster.

Detection over the images of a recording and whole calibrations of many datasets are
independent tasks.  By default they run in worker processes of this machine
(:func:`multieye.imaging.workers.worker_pool`: the workers end with this process).  For
what outgrows one machine, the same tasks run on Dask distributed (``pip install
"multieye[distributed]"``): on the scheduler at a given address (``dask scheduler`` and
``dask worker ADDRESS`` started by the user on the machines that share the files), or on a
local cluster of worker processes that this process starts and closes
(docs/recordings.md, section 3).  No scheduler of our own: Dask
places the tasks, retries them on a lost worker and reports their errors.

Tasks are sent in chunks (a few per worker) so that a task's overhead (a few milliseconds
on Dask) stays small next to the work; results come back in input order.

Synopsis
--------
>>> from multieye.imaging.engines import open_engine
>>> with open_engine("dask", workers=2) as engine:            # doctest: +SKIP
...     squares = list(engine.map(pow, [(2, 2), (3, 2)], star=True))
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.batch import DEFAULT_MAX_RMS_PX, ImageResult, process_array, process_image
from multieye.imaging.image_file import cropped_frames
from multieye.imaging.targets import Target
from multieye.imaging.workers import available_cores, worker_pool

__all__ = ["ENGINES", "Engine", "LocalEngine", "DaskEngine", "open_engine", "DASK_MISSING",
           "detect_on", "detect_arrays_on"]

#: The engines by name (``--engine``).
ENGINES = ("local", "dask")
#: What to do when Dask is not installed.
DASK_MISSING = ('the dask engine needs Dask distributed: pip install "multieye[distributed]" '
                '(or pip install distributed)')
#: Chunks per worker.
_CHUNKS_PER_WORKER = 4


def _chunks(items: Sequence, n_workers: int, chunksize: int | None) -> list[list]:
    size = chunksize or max(1, math.ceil(len(items) / (max(n_workers, 1) * _CHUNKS_PER_WORKER)))
    return [list(items[k:k + size]) for k in range(0, len(items), size)]


def _run_chunk(fn: Callable, chunk: list, star: bool = False) -> list:
    return [fn(*item) if star else fn(item) for item in chunk]


class Engine:
    """What the engines share: ``map`` over independent tasks, in input order.

    Use as a context manager; ``workers`` is how many tasks run at once.
    """

    name = "engine"
    workers = 1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def close(self) -> None:  # pragma: no cover - overridden
        pass

    def map(self, fn: Callable, items: Iterable, *, star: bool = False,
            chunksize: int | None = None) -> Iterator:
        """``fn(item)`` (``fn(*item)`` with ``star``) for every item, in input order."""
        raise NotImplementedError


@dataclass
class LocalEngine(Engine):
    """Worker processes of this machine (``processes=1``: this process itself).

    Attributes
    ----------
    processes : int
        Worker processes.
    """

    processes: int = 1
    name = "local"

    def __post_init__(self):
        self.workers = self.processes
        self._stack = contextlib.ExitStack()
        self._pool = None

    def close(self) -> None:
        self._stack.close()
        self._pool = None

    def __exit__(self, *exc):
        # the block's exception (Ctrl-C, SIGTERM's Stopped, an error) reaches worker_pool,
        # which then cancels the queued tasks and ends its workers; close() would shut the
        # pool down as on success, waiting for every task (calibrate-many went on with every
        # dataset after "stopped by SIGTERM")
        try:
            self._stack.__exit__(*exc)
        finally:
            self._pool = None
        return False

    def map(self, fn, items, *, star=False, chunksize=None):
        items = list(items)
        if self.processes <= 1 or len(items) <= 1:
            for item in items:
                yield fn(*item) if star else fn(item)
            return
        if self._pool is None:
            self._pool = self._stack.enter_context(worker_pool(self.processes))
        chunks = _chunks(items, self.processes, chunksize)
        for chunk in self._pool.map(_run_chunk, itertools.repeat(fn, len(chunks)), chunks,
                                    itertools.repeat(star, len(chunks))):
            yield from chunk


class DaskEngine(Engine):
    """Tasks on Dask distributed: the scheduler at ``scheduler``, or a local cluster.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``); None starts a local cluster of
        ``workers`` worker processes (one thread each), closed with the engine.
    workers : int, optional
        Workers of the local cluster (default: the cores this process may use).
    processes : bool
        Local cluster only: worker processes (True) or threads of this process (False).
    timeout_s : float
        Seconds to wait for the scheduler.

    Raises
    ------
    InputError
        Dask distributed is not installed, or the scheduler cannot be reached.
    """

    name = "dask"

    def __init__(self, scheduler: str | None = None, *, workers: int | None = None,
                 processes: bool = True, timeout_s: float = 30.0):
        try:
            import distributed  # noqa: PLC0415 (optional dependency: the distributed extra)
        except ImportError:
            raise InputError(DASK_MISSING) from None
        self._cluster = None
        if scheduler is None:
            n = workers or available_cores()
            self._cluster = distributed.LocalCluster(
                n_workers=int(n), threads_per_worker=1, processes=processes,
                dashboard_address=None, silence_logs=50)
            target = self._cluster
        else:
            target = str(scheduler)
        try:
            self._client = distributed.Client(target, timeout=timeout_s, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            if self._cluster is not None:
                self._cluster.close()
            raise InputError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        self.workers = max(1, len(self._client.scheduler_info().get("workers", {})))
        self.scheduler = scheduler

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def map(self, fn, items, *, star=False, chunksize=None):
        items = list(items)
        chunks = _chunks(items, self.workers, chunksize)
        futures = self._client.map(_run_chunk, [fn] * len(chunks), chunks,
                                   [star] * len(chunks), pure=False)
        try:
            for future in futures:
                yield from future.result()
        finally:
            for future in futures:
                future.cancel()

    def submit_each(self, fn, items, *, star=False):
        """Every task on its own, yielded ``(index, result)`` as each finishes (for work whose
        tasks take minutes, such as whole calibrations)."""
        import distributed  # noqa: PLC0415 (optional dependency: the distributed extra)

        items = list(items)
        futures = [self._client.submit(_run_chunk, fn, [item], star, pure=False)
                   for item in items]
        index = {f.key: k for k, f in enumerate(futures)}
        try:
            for future in distributed.as_completed(futures, loop=self._client.loop):
                yield index[future.key], future.result()[0]
        finally:
            for future in futures:
                future.cancel()


def open_engine(name: str = "local", *, processes: int | None = None,
                scheduler: str | None = None, workers: int | None = None) -> Engine:
    """The engine called ``name`` (:data:`ENGINES`), to use as a context manager.

    Parameters
    ----------
    name : {"local", "dask"}
    processes : int, optional
        ``local``: worker processes (default one per core this process may use).
    scheduler : str, optional
        ``dask``: a scheduler's address; None starts a local cluster.
    workers : int, optional
        ``dask``: workers of the local cluster.

    Raises
    ------
    InputError
        An unknown engine, a scheduler given to the local engine, Dask missing or a
        scheduler that cannot be reached.
    """
    if name not in ENGINES:
        raise InputError(f"engine must be one of {', '.join(ENGINES)}, got {name!r}")
    if name == "local":
        if scheduler is not None:
            raise InputError("a scheduler address needs the dask engine (--engine dask)")
        cores = available_cores()
        return LocalEngine(processes=max(1, min(processes or cores, cores)))
    return DaskEngine(scheduler, workers=workers)


def _guarded(work, item, name: str) -> ImageResult:
    """``work(item)``; an exception is the image's reason, never the run's end."""
    try:
        return work(item)
    except Exception as exc:                    # noqa: BLE001 - one image, never the run
        text = str(exc).strip().splitlines()
        return ImageResult(name, None, None, f"failed while reading or detecting: "
                           f"{type(exc).__name__}: {text[0] if text else ''}")


def _image_task(path: str, target: Target, intrinsics: Intrinsics | None,
                max_rms_px: float, crop=None) -> ImageResult:
    import cv2  # noqa: PLC0415 (heavy: a Dask worker imports it on its first task)

    cv2.setNumThreads(1)            # one task per worker thread: no nested thread pools
    return _guarded(lambda p: process_image(p, target, intrinsics, max_rms_px=max_rms_px,
                                            crop=crop), path, path)


def _array_task(item, target: Target, intrinsics: Intrinsics | None,
                max_rms_px: float) -> ImageResult:
    name, image = item
    return _guarded(lambda im: process_array(im, name, target, intrinsics,
                                             max_rms_px=max_rms_px), image, name)


def detect_on(engine: Engine, paths, target: Target, intrinsics: Intrinsics | None, *,
              max_rms_px: float = DEFAULT_MAX_RMS_PX, crop=None) -> list[ImageResult]:
    """:func:`multieye.imaging.batch.detect_and_estimate` as tasks of ``engine`` (the
    workers read the image files themselves: on Dask they must see the same paths), in the
    region ``crop`` of each image where given.

    Returns
    -------
    list of ImageResult
        One per path, in input order; a failed image carries its reason.
    """
    work = functools.partial(_image_task, target=target, intrinsics=intrinsics,
                             max_rms_px=max_rms_px, crop=crop)
    return list(engine.map(work, [str(p) for p in paths]))


def detect_arrays_on(engine: Engine, items, target: Target, intrinsics: Intrinsics | None, *,
                     max_rms_px: float = DEFAULT_MAX_RMS_PX, batch: int = 64, crop=None
                     ) -> list[ImageResult]:
    """:func:`multieye.imaging.batch.detect_and_estimate_arrays` as tasks of ``engine``: the
    ``(name, image)`` stream, cut to ``crop`` where given, consumed ``batch`` at a time, each
    batch sent to the workers."""
    work = functools.partial(_array_task, target=target, intrinsics=intrinsics,
                             max_rms_px=max_rms_px)
    it, results = iter(cropped_frames(items, crop)), []
    while chunk := [item for _, item in zip(range(batch), it)]:
        results.extend(engine.map(work, chunk))
    return results
