"""Cameras whose intrinsics come from the recording itself (rig.yaml ``model:``).

Detection runs without intrinsics; the detected views (the motion-captured images and the
``intrinsics_images``) give a starting lens per camera (OpenCV's calibration,
:func:`multieye.imaging.calibrate.initial_intrinsics`); every view's target pose follows by
PnP with it; the joint problem (:func:`multieye.estimate.refine_images.refine_images` with
``free_intrinsics``) then estimates the lens with everything else.  Weak data is said: too
few views, too little tilt or too little of the image covered for a lens model gives a
warning that names the camera and what to add.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import LENS_MODELS, Intrinsics, lens_model, parameter_names
from multieye.core.lens import project_points
from multieye.imaging.batch import DEFAULT_MAX_RMS_PX, ImageResult
from multieye.imaging.calibrate import (
    START_VIEWS,
    InitialIntrinsics,
    accept_on_refined_lens,
    initial_intrinsics,
    poses_from_detections,
)
from multieye.imaging.generic_start import RIVAL_SIGMA2
from multieye.imaging.model_choice import compare_models, edge_rms, may_be_beaten
from multieye.imaging.pnp import refit_poses

__all__ = ["LensStart", "start_lens", "lens_start", "with_poses", "weak_data_warnings", "check_model",
           "RECOMMENDED_VIEWS", "posed_on_refined_lens", "model_warnings",
           "valley_warnings"]

#: Views of the target a lens model wants before its intrinsics count as well supported.
RECOMMENDED_VIEWS = {"pinhole-radtan": 10, "pinhole-radtan4": 10, "pinhole-rational": 20,
                     "fisheye": 15, "unified": 15, "double-sphere": 15, "eucm": 15}
#: Fewest views on which lens models are compared (4 folds of at least 2 views).
MIN_COMPARED_VIEWS = 8
#: Smallest largest tilt of the board against the line of sight, degrees.
MIN_TILT_DEG = 20.0
#: Smallest share of a 4 x 4 grid over the image in which the target was seen.
MIN_COVERAGE = 0.5
#: Median reprojection RMS of the start's views beyond which no lens explains them, pixels.
LAYOUT_RMS_PX = 20.0


@dataclass(frozen=True)
class LensStart:
    """A camera's starting lens and what it was estimated from.

    Attributes
    ----------
    intrinsics : Intrinsics
    rms_px : float
        OpenCV's reprojection RMS over the views, pixels.
    views : int
        Views used.
    warnings : tuple of str
    """

    intrinsics: Intrinsics
    rms_px: float
    views: int
    warnings: tuple[str, ...]


def check_model(name: str, intrinsics: Intrinsics, model: str | None, path) -> Intrinsics:
    """A camera with both ``intrinsics`` and ``model``: the file's lens must be that model.

    OpenCV's k1 k2 p1 p2 is its 5-coefficient model with k3 = 0, so a 4-coefficient file is
    also ``pinhole-radtan``, and a 5-coefficient file whose k3 is 0 also ``pinhole-radtan4``
    (returned with its 4 coefficients, so that refining it keeps k3 at 0).

    Returns
    -------
    Intrinsics
        ``intrinsics`` in the form ``model`` names.

    Raises
    ------
    DatasetError
        The file holds another model (naming both, and k3 when it is what differs).
    """
    held = lens_model(intrinsics)
    if model is None or held == model or (model, held) == ("pinhole-radtan",
                                                           "pinhole-radtan4"):
        return intrinsics
    k3 = intrinsics.dist[4] if model == "pinhole-radtan4" and intrinsics.dist.size == 5 \
        else None
    if k3 == 0:
        return replace(intrinsics, dist=intrinsics.dist[:4])
    what = f"{held} lens" + ("" if k3 is None else f" with k3 = {k3:g}")
    raise DatasetError(f"rig.yaml says model: {model} but the intrinsics file holds a {what}; "
                       "give one or make them agree", path=path, camera=name)


def sized_as_seen(results: Sequence[ImageResult]) -> list[ImageResult]:
    """A camera's results (lens estimated: no intrinsics give its image size) with the images
    of another size than every image showing the target left out as of the wrong
    resolution, like those that given intrinsics refuse; unchanged when the target is found
    in images of several sizes (:func:`start_lens` refuses them) or in none.  Frames of
    another size among a recording's (a preview, a thumbnail) refused the whole camera."""
    seen = {r.image_size for r in results if r.reason is None and r.image_size is not None}
    if len(seen) != 1:
        return list(results)
    (w, h), = seen
    return [r if r.image_size in (None, (w, h)) else replace(
        r, pose=None, detection=None, parts=(), reason=f"wrong resolution ({r.image_size[0]} x "
        f"{r.image_size[1]}, the images showing the target are {w} x {h})") for r in results]


def _image_size(name: str, results: Sequence[ImageResult], where) -> tuple[int, int]:
    results = [r for r in results if not (r.reason or "").startswith("wrong resolution")]
    sizes = {r.image_size for r in results if r.image_size is not None}
    if not sizes:
        raise DatasetError("no image could be read to estimate the intrinsics from",
                           path=where, camera=name)
    if len(sizes) > 1:
        first = next(r for r in results if r.image_size is not None)
        other = next(r for r in results if r.image_size not in (None, first.image_size))
        raise DatasetError(f"images of different sizes: {first.path} is "
                           f"{first.image_size[0]} x {first.image_size[1]}, {other.path} is "
                           f"{other.image_size[0]} x {other.image_size[1]}; one camera's "
                           "images must all have one size", path=where, camera=name)
    return sizes.pop()


def start_lens(name: str, model: str, results: Sequence[ImageResult], where) -> LensStart:
    """OpenCV's calibration of one camera from its detections (every image it has).

    Raises
    ------
    DatasetError
        Images of different sizes, too few views, or OpenCV failing; the message names the
        camera and what to add.
    """
    size = _image_size(name, results, where)
    try:
        start = initial_intrinsics(_views(results), size, model, name=name)
    except InputError as exc:
        # the error names the camera already; the DatasetError adds it in its own place
        message = str(exc).removeprefix(f"camera {name}: ")
        raise DatasetError(message, path=where, camera=name) from None
    return lens_start(name, model, results, start)


def _views(results: Sequence[ImageResult]) -> list:
    return [(r.detection.object_points, r.detection.image_points) for r in results
            if r.detection is not None and r.reason is None]


def lens_start(name: str, model: str, results: Sequence[ImageResult],
               start: InitialIntrinsics) -> LensStart:
    """The :class:`LensStart` of OpenCV's calibration ``start`` from ``results`` (made by
    :func:`start_lens`, or by a worker process: :func:`multieye.imaging.calibrate.
    lens_start_task`), with what the views lack for ``model``."""
    views = _views(results)
    size = next(r.image_size for r in sorted(results, key=lambda r: r.reason is not None)
                if r.image_size is not None)                # an image showing the target first
    _check_layout(name, views, start)
    warnings = weak_data_warnings(name, model, views, start.T_cam_target, size)
    return LensStart(start.intrinsics, start.rms_px, len(views),
                     warnings + model_warnings(name, model, views, size, start)
                     + valley_warnings(name, model, min(len(views), START_VIEWS), start))


def _check_layout(name: str, views, start: InitialIntrinsics) -> None:
    """Refuse a start whose median view is more than :data:`LAYOUT_RMS_PX` off: no lens puts
    the points there, so the board of rig.yaml is not the one in the images (rows and cols
    of a marker grid swapped: every id found, at the wrong place).  One bad view does not
    move the median; the acceptance that follows takes such views out."""
    rms = []
    for (obj, img), T in zip(views, start.T_cam_target):
        if np.all(np.isfinite(T)):
            uv = project_points(obj @ T[:3, :3].T + T[:3, 3], start.intrinsics)
            rms.append(float(np.sqrt(np.nanmean(np.sum((uv - img) ** 2, axis=1)))))
    if rms and np.median(rms) > LAYOUT_RMS_PX:
        raise DatasetError(
            f"the lens started from its {len(views)} views leaves {np.median(rms):.3g} px of "
            "reprojection RMS in the median view (a lens fits the views of a board to about a "
            "pixel): the points are not where rig.yaml's board puts them; check the target's "
            "rows and cols (swapped?) and first_id, and intrinsics_target for the "
            "intrinsics_images", camera=name)


def model_warnings(name: str, model: str, views, size,
                   start: InitialIntrinsics | None = None) -> tuple[str, ...]:
    """The model the same views fit clearly better, with the figures
    (:func:`multieye.imaging.model_choice.compare_models`: held-out reprojection by
    radius), or nothing.  A pinhole model is compared only when its lens (``start``, else
    OpenCV's calibration on the views) leaves residuals in the outer quarter of the radii
    that another model could clearly beat (:func:`multieye.imaging.model_choice.
    may_be_beaten`: a wide lens given ``pinhole-radtan``): the pinhole path stays as fast on
    a lens it fits."""
    if len(views) < MIN_COMPARED_VIEWS:
        return ()
    if LENS_MODELS[model][0] == "pinhole":
        try:
            start = start or initial_intrinsics(views, size, model, name=name)
        except InputError:
            return ()
        if not may_be_beaten(*edge_rms(views, start.intrinsics, start.T_cam_target, size)):
            return ()
    message = compare_models(views, size, model).message(name)
    return () if message is None else (message,)


def _lens_text(lens: Intrinsics) -> str:
    names = parameter_names(lens)
    return ", ".join(f"{n} {v:.4g}" for n, v in zip(names, lens.params)
                     if n == "fx" or n not in ("fy", "cx", "cy"))


def valley_warnings(name: str, model: str, views: int, start: InitialIntrinsics
                    ) -> tuple[str, ...]:
    """A warning when another optimum of the model's valley fits the start's ``views`` as
    well as the lens kept (:attr:`multieye.imaging.calibrate.InitialIntrinsics.rivals`:
    within :data:`multieye.imaging.generic_start.RIVAL_SIGMA2` times the pixel noise's
    variance): the parameters printed with their +- describe one of several lenses of nearly
    the same image, so their linearised uncertainty understates how far they may be from
    the lens; the projection, and its std, hold.  On rendered double-sphere lenses of 190
    and 220 degrees (``xi`` -0.15, ``alpha`` 0.6, 20 views, 0.2 px) every fit has such
    rivals, with focal lengths 1.4 and 3 times the true one (docs/results/wide_lens.md,
    section 2c)."""
    if not start.rivals:
        return ()
    rivals = "; ".join(f"{_lens_text(r.intrinsics)} ({r.delta_sigma2:.1f} sigma^2 worse)"
                       for r in start.rivals)
    return (f"{name}: {model} lens: {len(start.rivals)} other lens(es) of this model fit its "
            f"{views} starting views about as well as the one found ({_lens_text(start.intrinsics)}): "
            f"{rivals}; within {RIVAL_SIGMA2:g} sigma^2 the views cannot tell them apart. They "
            "determine the lens' projection (its projection std holds) but not its parameters, "
            "whose +- understate how far they may be from the lens's; for parameters to "
            "compare or to hand to another tool use model: eucm (one optimum), or add views "
            "with the board near the rim of the image",)


def with_poses(results: Sequence[ImageResult], intrinsics: Intrinsics, *,
               max_rms_px: float = DEFAULT_MAX_RMS_PX) -> list[ImageResult]:
    """Detection-only results completed with the target pose by PnP with ``intrinsics``
    (:func:`multieye.imaging.calibrate.poses_from_detections`: a failed PnP or a bad fit
    becomes the image's reason)."""
    return poses_from_detections(results, intrinsics, max_rms_px=max_rms_px)


def posed_on_refined_lens(lens: LensStart, results: Sequence[ImageResult], *,
                          max_rms_px: float = DEFAULT_MAX_RMS_PX
                          ) -> tuple[LensStart, list[ImageResult]]:
    """Detection-only results posed with the starting lens, then judged on the refined one
    (:func:`multieye.imaging.calibrate.accept_on_refined_lens`: an image rejected as a bad
    fit with the start is taken back when it fits the lens refined on it); the
    :class:`LensStart` carries the lens the images were judged on."""
    posed = poses_from_detections(results, lens.intrinsics, max_rms_px=max_rms_px)
    intrinsics, accepted = accept_on_refined_lens(posed, lens.intrinsics, max_rms_px=max_rms_px)
    return (lens if intrinsics is lens.intrinsics else replace(lens, intrinsics=intrinsics),
            accepted)


def refit_paired(paired, intrinsics: Intrinsics):
    """A paired camera's target poses refitted with its estimated ``intrinsics``.

    The poses (``B``, each observation's ``T_cam_target`` and ``rms_px``) came from PnP with
    the starting lens; the loop residuals and per-image RMS reported for the final result are
    those of the final lens (all views refitted together, :func:`multieye.imaging.pnp.
    refit_poses`).  ``A`` and the motion capture stay as they are.

    Parameters
    ----------
    paired : multieye.pipeline.camera_data.PairedCamera
    intrinsics : Intrinsics
        The refined lens.
    """

    fit = [k for k, o in enumerate(paired.observations)
           if o.object_points is not None and o.image_points is not None]
    poses = refit_poses(np.array([paired.observations[k].T_cam_target for k in fit]),
                        [paired.observations[k].object_points for k in fit],
                        [paired.observations[k].image_points for k in fit], intrinsics)
    obs = list(paired.observations)
    for k, pose in zip(fit, poses):
        obs[k] = replace(obs[k], T_cam_target=pose.T_cam_target, rms_px=pose.rms_px)
    B = g.inv(np.stack([o.T_cam_target for o in obs]))            # T_target_cam
    return replace(paired, B=B, observations=tuple(obs))


def image_coverage(uv: np.ndarray, size: tuple[int, int]) -> float:
    """Share of the image's 4 x 4 cells holding at least one of the points ``uv``, (n, 2)
    pixels, in an image of ``size`` (width, height)."""
    w, h = size
    return len(np.unique(np.clip((np.asarray(uv) / [w, h] * 4).astype(int), 0, 3),
                         axis=0)) / 16.0


def weak_data_warnings(name: str, model: str, views, T_cam_target, size) -> tuple[str, ...]:
    """What the views lack for ``model``: their number, the board's tilt, the image covered.

    Parameters
    ----------
    views : sequence of (object_points, image_points)
    T_cam_target : ndarray, shape (n, 4, 4)
        The board's pose in each view (NaN where none was found).
    size : (int, int)
    """
    out = []
    want = RECOMMENDED_VIEWS[model]
    if len(views) < want:
        out.append(f"{name}: only {len(views)} images of the target to estimate its "
                   f"{model} intrinsics; add at least {want - len(views)} more, with the "
                   "board tilted and near the edges of the image")
    normal = np.asarray(T_cam_target)[:, :3, 2]                  # board z axis in the camera
    line = np.asarray(T_cam_target)[:, :3, 3]
    cos = np.abs(np.einsum("ij,ij->i", normal, line)) / np.linalg.norm(line, axis=1)
    tilt = np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))
    tilt = tilt[np.isfinite(tilt)]                # a view no PnP could pose says nothing
    if tilt.size and tilt.max() < MIN_TILT_DEG:
        out.append(f"{name}: the board is never tilted more than {tilt.max():.0f} degrees "
                   f"against the line of sight, which leaves the focal length poorly "
                   f"determined; add views with the board tilted 30-45 degrees")
    uv = np.concatenate([u for _, u in views]) if views else np.zeros((0, 2))
    coverage = image_coverage(uv, size)
    if coverage < MIN_COVERAGE:
        out.append(f"{name}: the target was seen in only {coverage:.0%} of the image (4 x 4 "
                   "cells); the distortion is extrapolated elsewhere; add views with the "
                   "board near the edges and corners of the image")
    return tuple(out)
