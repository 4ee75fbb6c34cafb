"""The report's images: per camera, its worst images with the detections drawn on the pixels.

:func:`image_thumbnails` picks, per camera, the used images of highest reprojection RMS
(:func:`multieye.outputs.image_stats.worst_images`, worst first), reads each from the
camera's image folder and draws its detected target points and their residuals (projection
minus detection, magnified by one factor per camera) on a small grey copy
(:func:`multieye.imaging.thumbnails.residual_thumbnail`), written as JPEG into
``OUT/figures/`` as ``image_<camera>_<rank>.jpg``.  :func:`images_section` shows them.

The images are not in the output folder: the folders come from the run (rig.yaml's
``images:``); a camera read from a bag or given by poses, an image that is gone or changed
size, or a report made again by ``multieye report`` (which knows only ``OUT``) has none, and
the section says so.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from html import escape
from pathlib import Path

import numpy as np

from multieye.core.names import file_stem
from multieye.io.calibration_json import CalibrationRecord
from multieye.io.image_folder import MAX_PATTERN_LEVELS
from multieye.io.run_details import RunDetails
from multieye.outputs.html import figure
from multieye.outputs.image_stats import arrow_scale, image_frame, stacked, worst_images
from multieye.pipeline import CalibrationRun
from multieye.imaging.thumbnails import residual_thumbnail

__all__ = ["IMAGES_PER_CAMERA", "Thumbnail", "image_thumbnails", "images_section",
           "image_folders", "image_crops", "THUMBNAIL"]

#: Images drawn per camera.
IMAGES_PER_CAMERA = 3
#: File names of the pictures in ``OUT/figures/``.
THUMBNAIL = re.compile(r"image_[A-Za-z0-9._-]+_\d+\.jpg")


@dataclass(frozen=True)
class Thumbnail:
    """One drawn image: which, its RMS, the file name in ``figures/`` and the JPEG."""

    camera: str
    image: str
    rms_px: float
    n_points: int
    file: str
    jpeg: bytes
    magnify: float


def image_folders(run: CalibrationRun) -> dict[str, Path]:
    """Camera name -> folder of its images, for the cameras of a run read from folders."""
    if run.rig is None:
        return {}
    cams = run.rig.cameras            # name -> CameraSpec
    return {name: Path(c.images) for name, c in cams.items() if c.images is not None}


def image_crops(run: CalibrationRun) -> dict[str, tuple]:
    """Camera name -> its ``crop`` of the image files (rig.yaml), for the cameras that have
    one."""
    if run.rig is None:
        return {}
    return {name: c.crop for name, c in run.rig.cameras.items() if c.crop is not None}


def _stem(name: str) -> str:
    """The camera's name in a thumbnail's file name: :func:`multieye.core.names.file_stem`,
    then reduced to the characters :data:`THUMBNAIL` allows."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", file_stem(name))


def _below(folder: Path, name: str) -> bool:
    """Whether an image's name in details.json is a file of ``folder`` or of its sub-folders
    (``0001/left.jpg``, as a pattern with folders lists them): a relative path of plain parts
    through real folders, never a link to a folder elsewhere, since the name is read from a
    file that may have been edited."""
    parts = name.split("/")
    if any(p in ("", ".", "..") or "\\" in p for p in parts) or len(parts) > MAX_PATTERN_LEVELS:
        return False
    parent = folder.joinpath(*parts[:-1])
    return os.path.realpath(parent) == os.path.join(os.path.realpath(folder), *parts[:-1])


def image_thumbnails(rec: CalibrationRecord, details: RunDetails | None,
                     folders: Mapping[str, os.PathLike] | None,
                     per_camera: int = IMAGES_PER_CAMERA,
                     crop: Mapping[str, tuple] | None = None) -> dict[str, list[Thumbnail]]:
    """The worst ``per_camera`` images of every camera drawn with their points and residuals
    (``crop``: by camera, the region of the files its pixels are in: the points are drawn
    on the whole image, moved by its corner).

    Returns camera name -> thumbnails, worst first (empty for a camera without images on
    disk or without target points).
    """

    out: dict[str, list[Thumbnail]] = {c.name: [] for c in rec.cameras}
    crop = dict(crop or {})
    if details is None or not folders:
        return out
    used_stems: set[str] = set()
    for c in rec.cameras:
        folder = folders.get(c.name)
        cam = details.camera(c.name)
        if folder is None or cam.points is None:
            continue
        stem = _stem(c.name)
        while stem in used_stems:
            stem += "_"
        used_stems.add(stem)
        frame = image_frame(cam)
        _, res = stacked(cam)
        _, magnify = arrow_scale(res, frame, share=0.03)
        index = {n: i for i, n in enumerate(cam.names)}
        for rank, (name, rms) in enumerate(worst_images(cam, per_camera), 1):
            if not _below(Path(folder), name):
                continue                       # not an image of the folder (or of its sub-folders)
            i = index[name]
            shift = np.zeros(2) if crop.get(c.name) is None else np.array(crop[c.name][:2])
            jpeg = residual_thumbnail(Path(folder) / name, np.asarray(cam.points.uv[i]) + shift,
                                      cam.points.residual_px[i], magnify=magnify,
                                      image_size=(frame.width, frame.height) if frame.known
                                      and crop.get(c.name) is None else None,
                                      region=crop.get(c.name))
            if jpeg is not None:
                out[c.name].append(Thumbnail(c.name, name, rms, len(cam.points.uv[i]),
                                             f"image_{stem}_{rank}.jpg", jpeg, magnify))
    return out


def images_section(rec: CalibrationRecord, details: RunDetails | None,
                   thumbnails: Mapping[str, Iterable[Thumbnail]]) -> str:
    """Per camera, its drawn images (worst first), or why there are none."""
    head = ('<section id="images"><h2>Detections on the images</h2><p class="note">Per camera '
            "its used images of highest reprojection RMS, worst first: the detected target "
            "points (cyan rings) and their residuals (magenta lines from the detection "
            "towards the projection by the calibrated rig, magnified by the factor given) on "
            "a grey copy of the image.</p>")
    parts = [head]
    for c in rec.cameras:
        thumbs = list(thumbnails.get(c.name, ()))
        parts.append(f"<h3>{escape(c.name)}</h3>")
        if not thumbs:
            if details is None:
                why = "this output folder has no <code>details.json</code>"
            elif details.camera(c.name).points is None:
                why = "the camera has no target points (given by poses)"
            else:
                why = ("its images are not on disk where the run read them (a bag, moved "
                       "files, or a report made again from the output folder alone)")
            parts.append(f'<p class="note">No images drawn: {why}.</p>')
            continue
        figs = "".join(
            figure(t.jpeg, f"{t.image} of {c.name} with its detections",
                   f"<b>{escape(t.image)}</b>: RMS {t.rms_px:.3f} px over {t.n_points} points; "
                   f"residuals × {t.magnify:.3g}", t.file) for t in thumbs)
        parts.append(f'<div class="thumbs">{figs}</div>')
    return "".join(parts) + "</section>"
