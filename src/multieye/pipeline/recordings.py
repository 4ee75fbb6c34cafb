"""Recordings as users lay them out: each camera's images as rig.yaml names them (a folder or a
pattern, ``sync``), the key that makes images of different cameras one instant, and the notes
about single images gathered into one line per cause (docs/recordings.md).

Synopsis
--------
>>> images = listed_images(rig, "left")          # doctest: +SKIP
>>> image_notes([("left/01.jpg", "blurred"), ("right/01.jpg", "blurred")])
('blurred (2 images: left/01.jpg, right/01.jpg)',)
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from multieye.core.errors import DatasetError
from multieye.core import geometry as g
from multieye.io import RejectedItem, Rig, Trajectory, list_image_files, list_images, read_tum
from multieye.io.frame_stamps import read_image_stamps
from multieye.io.image_folder import (image_name, label_stem, natural_key, numbers_in_names,
                                     sync_key, sync_keys)
from multieye.io.mocap import pose_frames
from multieye.io.pose_files import PoseFormat, poses_by_name, poses_by_order, poses_by_table

__all__ = ["precomputed_poses", "listed_images", "check_sync", "sync_instant", "instant_keys",
           "image_notes", "note_label", "camera_warnings",
           "poses_by_name_of", "FIRST_NAMED"]

#: How many image names a note names before ``and N more``.
FIRST_NAMED = 3


def listed_images(rig: Rig, name: str) -> list[tuple[float, int, Path]]:
    """A camera's images as ``(stamp_s, stamp_ns, path)`` (:func:`multieye.io.list_images`
    with its ``images`` pattern and the rig's ``sync``): by the stamps in their names, or,
    with ``sync`` other than ``time``, in natural name order with their places as stamps."""
    cam = rig.cameras[name]
    try:
        if cam.stamps is not None:      # the names are not stamps: a stamps file gives them
            return _stamped_by_file(cam)
        return list_images(cam.images, cam.images_pattern, rig.sync)
    except DatasetError as exc:
        if exc.camera is not None:
            raise
        raise DatasetError(exc.reason, path=exc.path, line=exc.line, camera=name) from None


def _stamped_by_file(cam) -> list[tuple[float, int, Path]]:
    """An image folder's images with the stamps of its ``stamps`` file
    (:func:`multieye.io.frame_stamps.read_image_stamps`), in time order; two images with one
    stamp are refused naming both."""
    files = sorted(list_image_files(cam.images, cam.images_pattern),
                   key=lambda p: natural_key(image_name(p, cam.images)))
    ns = read_image_stamps(cam.stamps, files, cam.images)
    order = sorted(range(len(files)), key=lambda k: ns[k])
    for a, b in zip(order, order[1:]):
        if ns[a] == ns[b]:
            raise DatasetError(f"images {image_name(files[a], cam.images)} and "
                               f"{image_name(files[b], cam.images)} have one stamp", path=cam.stamps)
    return [(ns[k] / 1e9, ns[k], files[k]) for k in order]


def check_sync(rig: Rig) -> dict[str, int]:
    """The count of images per camera with images, checked against ``sync``: with ``order``
    (the k-th image of each camera is one instant) every camera must have as many, else one
    line naming each camera's count (a missing image would shift every later pair)."""
    _no_shared_images(rig)
    _no_shared_frames(rig)
    listed = {n: [p for _, _, p in listed_images(rig, n)] for n, c in rig.cameras.items()
              if c.source == "images" and rig.sync != "time"}
    counts = {n: len(p) for n, p in listed.items()}
    if rig.sync == "number":
        _one_number_each(rig, listed)
    if rig.sync == "order" and len(set(counts.values())) > 1:
        shown = ", ".join(f"{n} {k}" for n, k in counts.items())
        raise DatasetError(f"sync: order pairs the k-th image of each camera, but the cameras "
                           f"have different counts of images ({shown}); give every camera the "
                           "same images, or sync: number (the number in each name)",
                           path=rig.path)
    if rig.sync == "order":
        _order_shift(rig, listed)
    return counts


def _no_shared_images(rig: Rig) -> None:
    """Refuse two cameras whose ``images`` list one file (the same folder, or patterns that
    overlap, or links to one file): each would be calibrated against itself, a rig of two
    cameras at one pose, exactly, with nothing to doubt (a copied line in rig.yaml).  Two
    cameras whose ``crop`` regions of the files share no pixel (a side-by-side stereo
    recording) may."""
    owner: dict[str, str] = {}
    for n, c in rig.cameras.items():
        if c.source != "images":
            continue
        try:
            files = list_image_files(c.images, c.images_pattern)
        except DatasetError:
            continue                    # said with the camera's name when it is listed
        shared, folder = [], os.path.realpath(c.images)
        for p in files:
            real = (os.path.realpath(p) if os.path.islink(p)
                    else os.path.join(folder, p.relative_to(c.images)))
            first = owner.setdefault(real, n)
            if first != n and not _apart(rig.cameras[first].crop, c.crop):
                shared.append((first, p))
        if shared:
            other, first = shared[0]
            more = f" and {len(shared) - 1} more" if len(shared) > 1 else ""
            raise DatasetError(f"cameras {other} and {n} read the same image files "
                               f"({first.relative_to(c.images).as_posix()}"
                               f"{more}): each camera needs its own images (check their images: "
                               "in rig.yaml)", path=rig.path)


def _one_number_each(rig: Rig, listed: Mapping[str, list[Path]]) -> None:
    """Refuse ``sync: number`` for a camera with one image whose name holds several integers
    (``0005_cam0.png``): the frame number is the integer that differs between a camera's
    images (:func:`~multieye.io.image_folder.numbers_in_names`), which one image cannot say;
    the last one (the camera's 0) would pair it with another camera's frame 0."""
    for n, paths in listed.items():
        if len(paths) != 1:
            continue
        name = image_name(paths[0], rig.cameras[n].images)
        numbers = re.findall(r"\d+", name)
        if len(numbers) > 1:
            raise DatasetError(
                f"sync: number pairs images by the frame number in their names, but camera {n} "
                f"has one image, whose name holds several numbers ({', '.join(numbers)}): "
                "which is the frame number is told by the one that differs between a camera's "
                "images; give it more images, or sync: name", path=paths[0], camera=n)


def _no_shared_frames(rig: Rig) -> None:
    """Refuse two cameras reading one video (or one bag's topic) whose ``crop`` regions share
    a pixel, as :func:`_no_shared_images` refuses for files: two regions of one sensor's
    frames that overlap are not two cameras (identical regions were caught only after the
    detection, overlapping ones not at all)."""
    owner: dict[tuple, list[str]] = {}
    for n, c in rig.cameras.items():
        if c.source not in ("video", "rosbag"):
            continue
        key = (os.path.realpath(c.video if c.source == "video" else c.rosbag), c.topic)
        for other in owner.get(key, []):
            if not _apart(rig.cameras[other].crop, c.crop):
                what = "video" if c.source == "video" else f"bag's topic {c.topic}"
                raise DatasetError(f"cameras {other} and {n} read the same {what} "
                                   f"({Path(key[0]).name}) with regions that share pixels "
                                   f"(crop: {_shown_crop(rig.cameras[other].crop)} and "
                                   f"{_shown_crop(c.crop)}): each camera needs its own frames, "
                                   "or its own part of them (crops side by side)", path=rig.path)
        owner.setdefault(key, []).append(n)


def _shown_crop(crop) -> str:
    return "none" if crop is None else f"[{', '.join(map(str, crop))}]"


def _apart(a, b) -> bool:
    """Whether two cameras' crops ``(x, y, width, height)`` of one image share no pixel (the
    halves of a side-by-side stereo frame); False where either has none."""
    if a is None or b is None:
        return False
    return (a[0] + a[2] <= b[0] or b[0] + b[2] <= a[0] or a[1] + a[3] <= b[1]
            or b[1] + b[3] <= a[1])


def no_copied_images(cameras: Mapping, path=None) -> None:
    """Refuse two cameras that found the target at exactly the same pixels in most images:
    copies of one camera's images given to another (by :func:`check_sync`'s rule on shared
    files, copies are not caught).  Real cameras never agree to the last bit on sub-pixel
    corners; such a pair would be calibrated as two cameras at one pose, with nothing to
    doubt.  ``cameras``: name to :class:`~multieye.pipeline.camera_data.CameraData`;
    ``path``: rig.yaml, which the message names.

    Raises
    ------
    DatasetError
        Naming both cameras, when they share at least 3 views and at least half of the
        views of the one with fewer.
    """
    seen: dict[str, set[bytes]] = {}
    for n, d in cameras.items():
        points = {np.ascontiguousarray(o.image_points, np.float64).tobytes()
                  for o in d.observations if o.image_points is not None}
        for other, theirs in seen.items():
            same = len(points & theirs)
            if same >= 3 and 2 * same >= min(len(points), len(theirs)):
                raise DatasetError(f"cameras {other} and {n} found the target at exactly the "
                                   f"same pixels in {same} images: copies of one camera's "
                                   "images? each camera needs its own images (check their "
                                   "images: in rig.yaml)", path=path)
        seen[n] = points


def _order_shift(rig: Rig, listed: Mapping[str, list[Path]]) -> None:
    """Refuse ``sync: order`` when the numbers in the names say that an image is missing in
    one camera and another in a second (equal counts, every pair after the first gap shifted
    by one): the numbers of the k-th images of two cameras differ by one constant at most
    places (frame counters) but not at all.  Names without numbers, or numbers that differ
    at every place (each camera's own clock), say nothing."""
    cams = [n for n, p in listed.items() if p]
    numbers = {n: numbers_in_names([image_name(p, rig.cameras[n].images) for p in listed[n]])
               for n in cams}
    if len(cams) < 2 or any(None in v for v in numbers.values()):
        return
    first = np.asarray(numbers[cams[0]], dtype=object)
    for n in cams[1:]:
        d = np.asarray(numbers[n], dtype=object) - first
        values, counts = np.unique(d.astype(str), return_counts=True)
        if len(values) < 2 or 2 * counts.max() < len(d):
            continue
        k = int(np.flatnonzero(d != d[0])[0])
        a, b = listed[cams[0]][k], listed[n][k]
        raise DatasetError(
            f"sync: order pairs the k-th image of each camera, but the numbers in the names of "
            f"image {k + 1} of {cams[0]} and {n} ({_shown(rig, cams[0], a)}, "
            f"{_shown(rig, n, b)}) differ by {d[k]} where "
            f"those of the {k} before differ by {d[0]}: an image missing in one camera shifts "
            "every pair after it; give sync: number to pair images by the number in their "
            "names (sync: time when they are time stamps)", path=rig.path)


def _shown(rig: Rig, name: str, path: Path) -> str:
    """An image of camera ``name`` for a message: its path below the camera's folder."""
    return path.relative_to(rig.cameras[name].images).as_posix()


def sync_instant(label: str, stamp: float, sync: str, keys: Mapping[str, str] | None = None
                 ) -> str:
    """The instant key of an image named ``label`` listed with ``stamp`` under ``sync`` (not
    ``time``): its key in ``keys`` (its camera's :func:`instant_keys`, by stem), else its
    stem, the last integer in it, or its place (the stamp)."""
    stem = label_stem(label)
    if keys is not None and stem in keys:
        return keys[stem]
    return sync_key(stem, sync, int(stamp))


def instant_keys(rig: Rig, name: str) -> dict[str, str]:
    """Every listed image's instant key under rig.yaml's ``sync`` (not ``time``) by its
    stem (:func:`multieye.io.image_folder.sync_keys`: ``sync: number`` takes the number
    that differs between the camera's images); empty for a camera without images or with
    ``sync: time``."""
    if rig.sync == "time" or rig.cameras[name].source != "images":
        return {}
    stems = [image_name(p, rig.cameras[name].images) for _, _, p in listed_images(rig, name)]
    return dict(zip(stems, sync_keys(stems, rig.sync)))


def note_label(rig: Rig, name: str, label: str) -> str:
    """An image in a note about single images: its path from rig.yaml's folder where it is a
    file inside it (``cam0/1700000000.5.png``, ``frames/0001/left.jpg``: a path the user can
    open, whatever the layout), else ``camera/label`` (a bag's or a video's frame)."""
    cam = rig.cameras[name]
    if cam.source == "images" and rig.path is not None:
        path = Path(os.path.abspath(Path(cam.images) / label))
        folder = Path(os.path.abspath(Path(rig.path).parent))
        if path.is_relative_to(folder):
            return path.relative_to(folder).as_posix()
    return f"{name}/{label}"


def image_notes(notes: Iterable[tuple[str, str]], limit: int = FIRST_NAMED
                ) -> tuple[str, ...]:
    """Notes about single images, ``(image, cause)``, as one line per cause in order of first
    appearance: ``cause (N images: a, b, c and N-3 more)``; a cause of one image stays
    ``image: cause``."""
    by_cause: dict[str, list[str]] = {}
    for image, cause in notes:
        by_cause.setdefault(cause, []).append(image)
    out = []
    for cause, images in by_cause.items():
        if len(images) == 1:
            out.append(f"{images[0]}: {cause}")
            continue
        named = ", ".join(images[:limit])
        more = f" and {len(images) - limit} more" if len(images) > limit else ""
        out.append(f"{cause} ({len(images)} images: {named}{more})")
    return tuple(out)


def camera_warnings(cameras: Mapping) -> tuple[str, ...]:
    """Every camera's warnings (``CameraData`` by name), then the notes about its single
    images gathered over the cameras (:func:`image_notes`)."""
    own = tuple(w for d in cameras.values() for w in d.warnings)
    return own + image_notes(n for d in cameras.values() for n in d.image_notes)


def poses_by_name_of(name: str, cam, spec, sync: str = "time") -> tuple[Trajectory, list, list]:
    """A by-name camera's poses (stamps 0, 1, 2, ... in name order; ``cam`` its
    ``CameraSpec``, ``spec`` its ``MocapSpec``), its images with a pose file as ``(stamp, ns,
    path)``, and what has no partner, with the reason."""
    fmt = PoseFormat(rotation=spec.rotation, values=spec.values, key=spec.key,
                     unit=spec.unit or "m")
    folder = cam.images
    try:
        images = (list_image_files(folder, cam.images_pattern) if sync == "time"
                  else [p for _, _, p in list_images(folder, cam.images_pattern, sync)])
        read = {"image": poses_by_table, "order": poses_by_order}.get(spec.match)
        matched, unmatched = (read(images, spec.file, fmt) if read is not None
                              else poses_by_name(images, str(spec.file), fmt))
    except DatasetError as exc:
        raise DatasetError(exc.reason, path=exc.path, line=exc.line, camera=name) from None
    rejected = [RejectedItem(item, reason) for item, reason in unmatched]
    if not matched:
        raise DatasetError(f"no image has its pose in {spec.file}"
                           + (f" (first: {rejected[0].item}: {rejected[0].reason})"
                              if rejected else ""), path=folder, camera=name)
    parent, child = pose_frames(spec.pose)
    stamps = np.arange(len(matched), dtype=np.float64)
    traj = Trajectory(stamps, np.stack([T for _, T in matched]), parent, child)
    traj = traj if parent == "world" else traj.inverted()
    listed = [(float(k), k * 1_000_000_000, image) for k, (image, _) in enumerate(matched)]
    return traj, listed, rejected


def precomputed_poses(cam) -> Trajectory:
    """A camera's precomputed target poses (``cam`` its ``CameraSpec``, given by ``poses``)
    as ``T_cam_target``: the TUM file read, each pose inverted where rig.yaml says the file
    holds ``T_target_cam`` (``CameraSpec.poses_inverted``)."""
    traj = read_tum(cam.poses, parent="cam", child="target")
    if not cam.poses_inverted:
        return traj
    return replace(traj, T=g.inv(traj.T))
