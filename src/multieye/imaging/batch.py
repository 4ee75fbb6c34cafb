"""Detection and PnP over many image files, in parallel processes.

Worker processes start by importing the main script again (the ``spawn`` and
``forkserver`` start methods, Linux, macOS and Windows alike; ``fork`` would not, but forks
OpenCV's and BLAS's threads and is unsafe on macOS).  A script that calls multieye at its
top level, outside ``if __name__ == "__main__":``, would run again in every worker;
:func:`main_reimport_problem` recognises that case, and detection then runs in threads of
this process instead (OpenCV releases the GIL while it detects), with a warning that says
why.

Synopsis
--------
>>> from multieye.imaging.batch import detect_and_estimate
>>> results = detect_and_estimate(sorted(Path("cam0").glob("*.png")), board, intrinsics)  # doctest: +SKIP
>>> [(r.path, r.pose.rms_px) for r in results if r.ok]                                    # doctest: +SKIP
>>> [(r.path, r.reason) for r in results if not r.ok]                                     # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from typing import Any

import cv2

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.boards import Boards, combined_reason
from multieye.imaging.detect import Detection, to_gray
from multieye.imaging.image_file import cropped_frames, read_region
from multieye.imaging.pnp import PoseEstimate, estimate_pose
from multieye.imaging.pool_tasks import OnPool, SplitTask
from multieye.imaging.targets import Target
from multieye.imaging.wide_look import detect_with_second_look
from multieye.imaging.main_script import main_reimport_problem, threads_instead
from multieye.core.arguments import positive_int
from multieye.imaging.workers import (  # re-exported: where they were
    mp_context as _mp_context,
    available_cores,
    prestart_workers,
    call_once,
    progress_bar,
    worker_pool,
)

__all__ = ["ImageResult", "ImageJob", "detect_and_estimate", "detect_and_estimate_jobs",
           "worker_count", "detect_and_estimate_arrays", "process_image", "process_array",
           "main_reimport_problem", "DEFAULT_MAX_RMS_PX", "prestart_workers",
           "detect_jobs_then"]

#: Images whose PnP reprojection RMS exceeds this many pixels are left out by default.
DEFAULT_MAX_RMS_PX = 2.0

#: Chunks per worker at the start (:func:`_chunks`; smaller ones follow): enough for load
#: balance, few enough that start-up and pickling stay small.
_CHUNKS_PER_WORKER = 4

#: Fewest images in a chunk (:func:`_chunks`), unless a chunk of the start holds fewer.
_MIN_CHUNK = 4


@dataclass(frozen=True)
class ImageResult:
    """Outcome for one image file.

    Attributes
    ----------
    path : str
    pose : PoseEstimate or None
        The pose when the image is usable (``reason is None``); also kept, for diagnosis,
        when the fit was rejected as bad.
    detection : Detection or None
        The detected points, when the target was found.
    reason : str or None
        Why the image is left out, starting with its kind: ``unreadable file: ...``,
        ``wrong resolution (W x H, intrinsics say W' x H')``, ``target not detected (...)``,
        ``PnP failed: ...`` or ``bad fit: ...`` (reprojection RMS above the threshold). None
        for a usable image.
    warnings : tuple of str
        From the detector (e.g. an ambiguous point order).
    image_size : (int, int) or None
        Width and height of the image read, pixels (None when it could not be read).
    parts : tuple of (str, ImageResult)
        Several boards (:class:`~multieye.imaging.boards.Boards`): each board's own result
        in this image, by name (``pose`` and ``detection`` are then None; usable when one is).
    second_look : bool
        Found by a wide lens's second look (:mod:`multieye.imaging.wide_look`).
    crop : (x, y, width, height) or None
        The region of the file's image read (:func:`process_image`; ``image_size`` its).
    """

    path: str
    pose: PoseEstimate | None
    detection: Detection | None
    reason: str | None
    warnings: tuple[str, ...] = ()
    image_size: tuple[int, int] | None = None
    parts: tuple[tuple[str, ImageResult], ...] = ()
    second_look: bool = False
    crop: tuple[int, int, int, int] | None = None

    @property
    def ok(self) -> bool:
        """True when the image gave a usable pose."""
        return self.reason is None


def process_image(path, target: Target, intrinsics: Intrinsics | None, *,
                  max_rms_px: float = DEFAULT_MAX_RMS_PX, crop=None) -> ImageResult:
    """Read one image, detect the target, estimate its pose; failures become a reason.

    Parameters
    ----------
    path : str or os.PathLike
    target : Target
    intrinsics : Intrinsics
    max_rms_px : float
        Reprojection RMS, pixels, above which the fit counts as bad.
    crop : (x, y, width, height) of int, optional
        The camera's region of the image (a side-by-side stereo frame's half): detection
        and pose in its pixels (:func:`multieye.imaging.image_file.cropped`).

    Returns
    -------
    ImageResult
        Never raises for a bad image (missing, not a regular file, unreadable, empty, a
        header stating more pixels than :data:`~multieye.core.limits.MAX_IMAGE_PIXELS`,
        another size than the intrinsics state, no target, degenerate points); the file is
        read by :func:`multieye.imaging.image_file.read_gray` (size checked before decoding,
        EXIF orientation ignored with a warning, unless only the turned image fits).
    """
    path = str(path)
    fit = None if intrinsics is None else (intrinsics.width, intrinsics.height)
    image, reason, notes = read_region(path, fit, crop)
    if image is None:
        return ImageResult(path, None, None, reason, crop=crop)
    res = process_array(image, path, target, intrinsics, max_rms_px=max_rms_px)
    return replace(res, warnings=notes + res.warnings, crop=crop) if notes or crop else res


def _guarded(work, item, name: str) -> ImageResult:
    """``work(item)``; an exception (MemoryError included) is the image's reason."""
    try:
        return work(item)
    except Exception as exc:                    # noqa: BLE001 - one image, never the run
        return ImageResult(name, None, None, f"failed while reading or detecting: "
                           f"{type(exc).__name__}: {_first_line(exc)}")


def process_array(image, name: str, target: Target | Boards, intrinsics: Intrinsics | None, *,
                  max_rms_px: float = DEFAULT_MAX_RMS_PX) -> ImageResult:
    """:func:`process_image` for an image already in memory (e.g. from a ROS bag).

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
    name : str
        How the image is named in the result (``ImageResult.path``).
    intrinsics : Intrinsics or None
        None: detection only (the camera's intrinsics are still to be estimated); a usable
        result then has a detection and no pose.
    """
    path = name
    if image.ndim == 3:
        image = to_gray(image)
    shape = (int(image.shape[1]), int(image.shape[0]))
    size = (None, None) if intrinsics is None else (intrinsics.width, intrinsics.height)
    if None not in size and shape != size:
        return ImageResult(path, None, None, f"wrong resolution ({shape[0]} x {shape[1]}, "
                           f"intrinsics say {size[0]} x {size[1]})", image_size=shape)
    if isinstance(target, Boards):      # each board in the one decoded image
        parts = tuple((n, process_array(image, name, b, intrinsics, max_rms_px=max_rms_px))
                      for n, b in target.boards)
        reason = None if any(r.ok for _, r in parts) else combined_reason(
            target, {n: r.reason for n, r in parts})
        return ImageResult(path, None, None, reason, image_size=shape, parts=parts)
    try:
        detection, why, looked = detect_with_second_look(image, target, intrinsics)
    except (InputError, cv2.error) as exc:
        return ImageResult(path, None, None, "target not detected (detection failed: "
                           f"{_first_line(exc)})", image_size=shape)
    if detection is None:
        return ImageResult(path, None, None, f"target not detected ({target.kind} "
                           f"{target.rows}x{target.cols}" + (f": {why}" if why else "") + ")",
                           image_size=shape)
    if intrinsics is None:
        return ImageResult(path, None, detection, None, detection.warnings, image_size=shape)
    try:
        pose = estimate_pose(detection, intrinsics)
    except (InputError, cv2.error) as exc:
        return ImageResult(path, None, detection, f"PnP failed: {_first_line(exc)}",
                           detection.warnings, image_size=shape, second_look=looked)
    reason = None if pose.rms_px <= max_rms_px else (
        f"bad fit: reprojection RMS {pose.rms_px:.2f} px > {max_rms_px:g} px")
    return ImageResult(path, pose, detection, reason, detection.warnings, image_size=shape,
                       second_look=looked)


def _first_line(exc: Exception) -> str:
    text = str(exc).strip().splitlines()
    return text[-1].strip() if text else type(exc).__name__


# Per-worker state, set once by the pool initializer so that tasks carry only a path (and the
# index of its job: the target and intrinsics it is detected with).
_WORKER: dict = {}


def _init_jobs(jobs: tuple, max_rms_px: float) -> None:
    """Worker state for :func:`detect_and_estimate_jobs`: ``jobs`` holds
    ``(target, intrinsics, crop)`` per job."""
    cv2.setNumThreads(1)            # one process per core: no nested thread pools
    _WORKER.update(jobs=tuple(jobs), max_rms_px=max_rms_px)


def _init_worker(target: Target, intrinsics: Intrinsics | None, max_rms_px: float) -> None:
    _init_jobs(((target, intrinsics, None),), max_rms_px)


def _work_item(item: tuple[int, str]) -> ImageResult:
    job, path = item
    target, intrinsics, crop = _WORKER["jobs"][job]
    return _guarded(lambda p: process_image(p, target, intrinsics, crop=crop,
                                            max_rms_px=_WORKER["max_rms_px"]), path, path)


def _work_array(item) -> ImageResult:
    name, image = item
    target, intrinsics, _ = _WORKER["jobs"][0]
    return _guarded(lambda im: process_array(im, name, target, intrinsics,
                                             max_rms_px=_WORKER["max_rms_px"]), image, name)


@dataclass(frozen=True)
class ImageJob:
    """Image files to detect one target in, with one camera's lens.

    Attributes
    ----------
    paths : tuple of str
    target : Target
    intrinsics : Intrinsics or None
        None: detection only (a lens still to be estimated).
    crop : (x, y, width, height) of int or None
        The camera's region of each image (:func:`process_image`).
    """

    paths: tuple[str, ...]
    target: Target
    intrinsics: Intrinsics | None
    crop: tuple[int, int, int, int] | None = None


def detect_and_estimate(paths: Iterable, target: Target, intrinsics: Intrinsics | None, *,
                        processes: int | None = None, progress: bool | None = None,
                        max_rms_px: float = DEFAULT_MAX_RMS_PX, crop=None) -> list[ImageResult]:
    """Detect ``target`` and estimate its pose in every image, in parallel processes.

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        Image files (any format OpenCV reads; colour is converted to gray).
    target : Target
    intrinsics : Intrinsics or None
        None: detection only, no pose (a camera whose intrinsics are still to be estimated).
    processes : int, optional
        Worker processes; default the cores this process may use; never more than those
        cores nor one per image (:func:`worker_count`).  1 runs in this process.
    progress : bool, optional
        Show a tqdm progress bar on stderr; default only when stderr is a terminal.
    max_rms_px : float
        Reprojection RMS, pixels, above which an image is rejected as a bad fit.
    crop : (x, y, width, height) of int, optional
        The camera's region of each image (:func:`process_image`).

    Returns
    -------
    list of ImageResult
        One per path, in input order; unreadable or failed images carry a ``reason``.

    Notes
    -----
    :func:`detect_and_estimate_jobs` with one job: see there.
    """
    job = ImageJob(tuple(str(p) for p in paths), target, intrinsics, crop)
    return detect_and_estimate_jobs([job], processes=processes, progress=progress,
                                    max_rms_px=max_rms_px)[0]


def detect_and_estimate_jobs(jobs: Iterable[ImageJob], *, processes: int | None = None,
                             progress: bool | None = None,
                             max_rms_px: float = DEFAULT_MAX_RMS_PX) -> list[list[ImageResult]]:
    """:func:`detect_and_estimate` for several jobs (e.g. every camera of a rig) on one pool
    of worker processes.

    Parameters
    ----------
    jobs : iterable of ImageJob
    processes, progress, max_rms_px
        As for :func:`detect_and_estimate`; one progress bar counts every job's images.

    Returns
    -------
    list of list of ImageResult
        Per job, one result per path, in input order.

    Notes
    -----
    Every image is read once, as gray (:func:`multieye.imaging.image_file.read_gray`), and
    detection and PnP run in the worker that read it, so only paths go to the workers and
    results come back.  Paths go in chunks (about four per worker, then smaller ones:
    :func:`_chunks`) so that inter-process traffic stays small next to detection and the
    workers end together; each worker holds the jobs' targets and
    intrinsics from its start and runs OpenCV single-threaded.  One pool serves every job,
    so the workers start once and stay busy across the jobs' boundaries (a pool per
    camera left a core idle at the end of each camera).  Workers come from a fork server
    (spawn where there is none): its first start in a session costs about a second, later
    pools start in milliseconds.  Workers end with this process however it ends, and at
    once when an exception (Ctrl-C included) leaves the pool; they are joined before this
    returns (:mod:`multieye.imaging.workers`).  A failure inside a worker is that image's
    reason, never the run's end: an exception (``MemoryError`` included) is caught around
    each image, and when a worker dies (a crash in a decoder, killed for memory) the images
    not yet done run again one per worker, so that only the image that killed it is
    rejected.  Workers import the main script again; when it calls this at its top level,
    outside ``if __name__ == "__main__":``, detection runs in threads of this process
    instead, with a warning (:func:`main_reimport_problem`).
    """
    return detect_jobs_then(jobs, processes=processes, progress=progress,
                            max_rms_px=max_rms_px)[0]


def detect_jobs_then(jobs: Iterable[ImageJob], then: dict[int, Callable] | None = None, *,
                     processes: int | None = None, progress: bool | None = None,
                     max_rms_px: float = DEFAULT_MAX_RMS_PX,
                     on_sent: Callable[[], object] | None = None
                     ) -> tuple[list[list[ImageResult]], dict[int, Any]]:
    """:func:`detect_and_estimate_jobs`, then per job a task on that job's results, run by
    the same workers as soon as the job's images are detected (while the others' are).

    Parameters
    ----------
    jobs : iterable of ImageJob
    then : dict of int to callable, optional
        By job index, a picklable function of the job's results (a list of ImageResult),
        e.g. a camera's lens start (:func:`multieye.imaging.calibrate.lens_start_task`).
        Run in a worker process, or in this one when detection runs here; a
        :class:`~multieye.imaging.pool_tasks.SplitTask` on every worker at once.
    processes, progress, max_rms_px
        As for :func:`detect_and_estimate`.
    on_sent : callable, optional
        Called once, when the first images are sent to the workers (when detection runs in
        this process: before it starts), e.g. ``Alongside.start``
        (:class:`multieye.imaging.workers.Alongside`): the caller's imports on a thread
        while the workers detect.

    Returns
    -------
    results : list of list of ImageResult
        Per job, one result per path, in input order.
    done : dict of int to object
        What ``then[j]`` returned, for every ``j`` of ``then``.

    Notes
    -----
    The paths go to the workers in chunks, at most one more chunk than there are workers
    at a time, so that a job's task, submitted once its last image is back, waits behind a
    few chunks only instead of behind every image still to detect (with a camera's lens
    estimated, its lens start and PnP ran after the whole rig's detection, one camera after
    another in this process).  A worker that dies takes the pool down: the images not yet
    done then run one per worker, and the tasks not yet done in this process.
    """
    jobs, then = list(jobs), dict(then or {})
    items = [(j, p) for j, job in enumerate(jobs) for p in job.paths]
    n_workers = worker_count(processes, len(items))
    bar = progress_bar(len(items), f"detecting {', '.join(sorted({j.target.kind for j in jobs})) or 'targets'}",
               progress)
    initargs = (tuple((job.target, job.intrinsics, job.crop) for job in jobs), max_rms_px)
    flat: list[ImageResult] = []
    done: dict[int, Any] = {}

    def one(item):
        j, p = item
        return _guarded(lambda q: process_image(q, jobs[j].target, jobs[j].intrinsics,
                                                max_rms_px=max_rms_px, crop=jobs[j].crop), p, p)

    def per_job() -> list[list[ImageResult]]:
        out: list[list[ImageResult]] = [[] for _ in jobs]
        for (j, _), r in zip(items, flat):
            out[j].append(r)
        return out

    sent = call_once(on_sent)
    try:
        if n_workers <= 1 or threads_instead(n_workers):
            sent()
            _here(one, items, n_workers, flat, bar)
        else:
            try:
                with worker_pool(n_workers, mp_context=_mp_context(), initializer=_init_jobs,
                                 initargs=initargs) as pool:
                    done.update(_on_pool(pool, items, jobs, then, flat, bar, n_workers, sent))
            except BrokenProcessPool:
                # a worker died (a crash in a decoder, killed for memory): the images not
                # yet done run one by one, each in a worker of its own, so only the culprit
                # is lost
                for item in items[len(flat):]:
                    flat.append(_isolated(_work_item, item, item[1], initargs,
                                          initializer=_init_jobs))
                    if bar is not None:
                        bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    results = per_job()
    done.update({j: task(results[j]) for j, task in then.items() if j not in done})
    return results, done


def _here(one, items, n_workers: int, flat: list, bar) -> None:
    """Detection in this process: one image after another, or in ``n_workers`` threads."""
    if n_workers <= 1:
        for item in items:
            flat.append(one(item))
            if bar is not None:
                bar.update(1)
        return
    with ThreadPoolExecutor(n_workers) as pool:
        for r in pool.map(one, items):
            flat.append(r)
            if bar is not None:
                bar.update(1)


def _work_chunk(chunk: list) -> list[ImageResult]:
    return [_work_item(item) for item in chunk]


def _chunks(items: list, n_workers: int) -> list[list]:
    """``items`` cut in chunks that shrink as the work ends (guided scheduling): each holds a
    ``1 / (2 n_workers)`` share of the items left, at most a ``1 / (n_workers *``
    :data:`_CHUNKS_PER_WORKER` ``)`` share of all and at least :data:`_MIN_CHUNK`, so that the
    workers end within a few images of each other (equal chunks of 50 images left one of 2
    cores idle 0.01-0.22 s at the end of a 4 x 100 rig, 0.11 s on average)."""
    cap = max(1, math.ceil(len(items) / (n_workers * _CHUNKS_PER_WORKER)))
    chunks, start = [], 0
    while start < len(items):
        size = min(cap, max(_MIN_CHUNK, math.ceil((len(items) - start) / (2 * n_workers))))
        chunks.append(items[start:start + size])
        start += size
    return chunks


def _on_pool(pool, items, jobs, then, flat: list, bar, n_workers: int,
             sent: Callable[[], None]) -> dict:
    """Detection of ``items`` on ``pool`` (of ``n_workers``), in chunks (:func:`_chunks`)
    with at most one more chunk submitted than there
    are workers; each job's ``then`` task submitted once its last result is back; ``sent()``
    called once the first chunks are submitted.  Returns what the tasks returned, by job."""
    in_flight = n_workers + 1
    chunks = _chunks(items, n_workers)
    left = [len(job.paths) for job in jobs]
    tasks = {j: pool.submit(task, []) for j, task in then.items() if left[j] == 0}
    first = [0]                     # where the job being collected starts in ``flat``

    def collect(future) -> None:
        for r in future.result():
            flat.append(r)
            j = items[len(flat) - 1][0]
            left[j] -= 1
            if left[j] == 0:        # the job's last image: its task goes next
                if isinstance(then.get(j), SplitTask):      # on every worker at its end
                    tasks[j] = OnPool(pool, then[j], flat[first[0]:], n_workers)
                elif j in then:
                    tasks[j] = pool.submit(then[j], flat[first[0]:])
                first[0] = len(flat)
            if bar is not None:
                bar.update(1)

    pending: deque = deque()
    for chunk in chunks:
        pending.append(pool.submit(_work_chunk, chunk))
        if len(pending) >= in_flight:
            sent()
            collect(pending.popleft())
    sent()
    while pending:
        collect(pending.popleft())
    return {j: f.result() for j, f in tasks.items()}


def _isolated(work, item, name: str, initargs: tuple, *, initializer=_init_worker) -> ImageResult:
    """``work(item)`` in a worker process of its own; its crash is the item's reason."""
    try:
        with worker_pool(1, mp_context=_mp_context(), initializer=initializer,
                         initargs=initargs) as pool:
            return pool.submit(work, item).result()
    except BrokenProcessPool:
        return ImageResult(name, None, None, "failed while reading or detecting: the worker "
                           "process ended abruptly (a crash, or killed for lack of memory)")


def worker_count(processes: int | None, n_items: int | None = None) -> int:
    """Worker processes to start: the request (default: all), at most the CPUs this process
    may use (``os.sched_getaffinity``) and one per item.

    Raises
    ------
    InputError
        ``processes`` is not a positive integer.
    """
    cores = available_cores()
    n = cores if processes is None else min(positive_int(processes, "processes"), cores)
    if n_items is not None:
        n = min(n, max(int(n_items), 1))
    return max(n, 1)


def detect_and_estimate_arrays(items: Iterable, target: Target, intrinsics: Intrinsics | None,
                               *,
                               processes: int | None = None, progress: bool | None = None,
                               max_rms_px: float = DEFAULT_MAX_RMS_PX,
                               batch: int = 64, crop=None) -> list[ImageResult]:
    """:func:`detect_and_estimate` for images in memory, e.g. streamed from a ROS bag.

    Parameters
    ----------
    items : iterable of (str, ndarray)
        Name and image; consumed ``batch`` at a time, so a long stream is never held in
        memory whole.
    target, intrinsics, processes, progress, max_rms_px
        As for :func:`detect_and_estimate`.
    batch : int
        Images sent to the workers at once.
    crop : (x, y, width, height) of int, optional
        The camera's region of each image, cut as the stream is read
        (:func:`~multieye.imaging.image_file.cropped_frames`: a frame without it raises).

    Returns
    -------
    list of ImageResult
        In input order.
    """
    n_workers = worker_count(processes)
    bar = progress_bar(None, f"detecting {target.kind}", progress)
    results: list[ImageResult] = []
    it = iter(cropped_frames(items, crop))

    def one(item):
        return _guarded(lambda im: process_array(im, item[0], target, intrinsics,
                                                 max_rms_px=max_rms_px), item[1], item[0])

    try:
        if n_workers <= 1:
            for item in it:
                results.append(one(item))
                if bar is not None:
                    bar.update(1)
            return results
        if threads_instead(n_workers):
            with ThreadPoolExecutor(n_workers) as pool:
                while True:
                    chunk = [item for _, item in zip(range(batch), it)]
                    if not chunk:
                        return results
                    results.extend(pool.map(one, chunk))
                    if bar is not None:
                        bar.update(len(chunk))
        initargs = (target, intrinsics, max_rms_px)
        chunk: list = []
        while True:                     # a new pool after a worker died
            try:
                with worker_pool(n_workers, mp_context=_mp_context(), initializer=_init_worker,
                                 initargs=initargs) as pool:
                    while True:
                        chunk = [item for _, item in zip(range(batch), it)]
                        if not chunk:
                            return results
                        results.extend(pool.map(_work_array, chunk,
                                                chunksize=max(1, len(chunk) // (2 * n_workers))))
                        if bar is not None:
                            bar.update(len(chunk))
            except BrokenProcessPool:
                results.extend(_isolated(_work_array, item, item[0], initargs)
                               for item in chunk)
                if bar is not None:
                    bar.update(len(chunk))
    finally:
        if bar is not None:
            bar.close()
