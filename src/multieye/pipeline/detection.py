"""Detection of a rig's images: one pool of worker processes for every camera's image files
(issue 21), or the tasks of an engine (Dask distributed, issue 22); used by
:mod:`multieye.pipeline.camera_data`."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from multieye.imaging.boards import Boards
from multieye.imaging.batch import (
    ImageJob,
    detect_and_estimate,
    detect_and_estimate_arrays,
    detect_jobs_then,
)
from multieye.imaging.calibrate import lens_start_task
from multieye.imaging.image_file import cropped_frames  # re-exported: where it was
from multieye.imaging.engines import Engine, detect_arrays_on, detect_on
from multieye.core.errors import DatasetError
from multieye.io import Rig, iter_bag_images, list_image_files
from multieye.pipeline.boards import camera_boards, intrinsics_boards
from multieye.pipeline.frames import bag_frames, video_frames, video_listing
from multieye.pipeline.recordings import listed_images
from multieye.pipeline.rig_model import RigModel

__all__ = ["Workers", "cropped_frames", "detect_all", "detect_listed"]


@dataclass(frozen=True)
class Workers:
    """How detection runs: worker processes (None: one per core), a progress bar, or the
    tasks of an engine (Dask, :mod:`multieye.imaging.engines`); and the results of the image
    files already detected (:func:`detect_all`), keyed by camera and ``"images"`` or
    ``"intrinsics_images"``, with the seconds they took; and, by camera name, the lens
    started from them where it is estimated (a
    :class:`~multieye.imaging.calibrate.StartedLens`, or None when no start could be made),
    made by the workers as soon as the camera's images were detected."""

    processes: int | None
    progress: bool
    engine: Engine | None = None
    detected: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)
    started: dict = field(default_factory=dict)

    def detect(self, paths, target, intr, crop=None) -> list:
        if self.engine is not None:
            return detect_on(self.engine, paths, target, intr, crop=crop)
        return detect_and_estimate(paths, target, intr, processes=self.processes,
                                   progress=self.progress, crop=crop)

    def detect_arrays(self, items, target, intr, crop=None) -> list:
        if self.engine is not None:
            return detect_arrays_on(self.engine, items, target, intr, crop=crop)
        return detect_and_estimate_arrays(items, target, intr, processes=self.processes,
                                          progress=self.progress, crop=crop)


def detect_all(rig: Rig, model: RigModel, motions: dict, workers: Workers, chosen: dict, *,
               on_sent: Callable[[], object] | None = None) -> Workers:
    """Every camera's image files (folders, not bags; those ``chosen`` before decoding)
    detected on one pool of workers, with PnP in the worker where the lens is given; a
    camera's ``intrinsics_images`` too.  On an engine, each camera's own detection runs
    its tasks instead.

    One pool for the rig keeps every core busy to the last image (a pool per camera left
    one idle at the end of each camera). The seconds are shared out by image count.  A
    camera whose lens is estimated (``model:`` without ``intrinsics:`` nor
    ``intrinsics_images``) gets its lens start and its poses from the workers too, as soon
    as its images are detected (``Workers.started``).  ``on_sent()`` is called once the
    first images are sent to the workers (not when none are).  ``motions``: by camera, its
    :class:`~multieye.pipeline.camera_data.CameraMotion` where the images to detect are
    those with a pose file (paired by name); a camera not in it detects its folder's images.
    ``model``: the targets and the given lenses, built once.
    """
    keys, jobs, then = [], [], {}
    for name, cam in rig.cameras.items() if workers.engine is None else ():
        if cam.source != "images":
            continue
        intr = model.lenses[name]
        target, _ = camera_boards(rig, name, model.targets)
        listed = (chosen[name].kept if name in chosen
                  else getattr(motions.get(name), "listed", None))
        images = listed_images(rig, name) if listed is None else listed
        if (intr is None and cam.model is not None and cam.intrinsics_images is None
                and not isinstance(target, Boards)):     # several boards: started later
            # the lens start and every pose with it, in a worker once the images are in
            then[len(jobs)] = lens_start_task(cam.model, name, target)
        keys.append((name, "images"))
        jobs.append(ImageJob(tuple(str(p) for _, _, p in images), target, intr, cam.crop))
        if cam.intrinsics_images is not None:
            keys.append((name, "intrinsics_images"))
            jobs.append(ImageJob(tuple(str(p) for p in list_image_files(cam.intrinsics_images)),
                                 intrinsics_boards(rig, name, model)[0], intr, cam.crop))
    if not jobs:
        return workers
    t0 = time.perf_counter()
    results, started = detect_jobs_then(jobs, then, processes=workers.processes,
                                        progress=workers.progress, on_sent=on_sent)
    seconds = time.perf_counter() - t0
    total = max(sum(len(job.paths) for job in jobs), 1)
    return replace(workers, detected=dict(zip(keys, results)),
                   seconds={k: seconds * len(job.paths) / total for k, job in zip(keys, jobs)},
                   started={keys[j][0]: lens for j, lens in started.items()})


def detect_listed(rig: Rig, model: RigModel, name: str, intr, workers: Workers, listed,
                  lost: list, *, fresh: bool = False) -> tuple[list, list, float]:
    """Detection (and PnP with ``intr`` unless None) of one camera's images: its folder's
    time-stamped images, its video's frames or its bag's image topic, or only those
    ``listed`` as ``(stamp, ns, item)``.  The folder's images come from the detection of
    :func:`detect_all` unless ``fresh`` (images chosen again after the first ones proved
    unusable, :func:`multieye.pipeline.selection.with_refills`).  Video frames that could
    not be decoded (and a bag's compressed messages) are appended to ``lost`` as
    ``(label, reason)``.

    Returns
    -------
    stamped : list of (float, str)
        Per image detected: its stamp (camera clock, seconds) and label.
    results : list of ImageResult
        In the same order.
    seconds : float
    """
    cam = rig.cameras[name]
    target, _ = camera_boards(rig, name, model.targets)
    t0 = time.perf_counter()
    if cam.source == "video":
        stamped: list = []         # the video is read as the frames are detected
        results = workers.detect_arrays(
            video_frames(cam, video_listing(cam) if listed is None else listed, stamped, lost),
            target, intr, cam.crop)
        return stamped, results, time.perf_counter() - t0
    if cam.topic is None:
        images = listed_images(rig, name) if listed is None else listed
        results = None if fresh else workers.detected.get((name, "images"))
        if results is None:
            results = workers.detect([p for _, _, p in images], target, intr, cam.crop)
        seconds = time.perf_counter() - t0 if fresh else workers.seconds.get(
            (name, "images"), time.perf_counter() - t0)
        return ([(stamp, path.relative_to(cam.images).as_posix()) for stamp, _, path in images],
                results, seconds)
    stamped, bad = [], []

    def frames():
        for stamp_ns, image in iter_bag_images(cam.rosbag, cam.topic, gray=True, lost=bad):
            label = f"{cam.topic}@{stamp_ns}"
            stamped.append((stamp_ns * 1e-9, label))
            yield label, image
        lost.extend((f"{cam.topic}@{ns}", why) for ns, why in bad)

    # the bag is read as the frames are detected
    chosen = frames() if listed is None else bag_frames(cam, listed, stamped, lost)
    results = workers.detect_arrays(chosen, target, intr, cam.crop)
    if not stamped and not lost and not fresh:
        raise DatasetError(f"image topic {cam.topic} holds no images", path=cam.rosbag,
                           camera=name)
    return stamped, results, time.perf_counter() - t0
