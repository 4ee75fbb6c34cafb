"""What each camera contributes: its target poses, its motion capture, and their pairing.

``rig.yaml`` (docs/rig-yaml.md) -> per camera: images -> target detection -> PnP (or
precomputed ``T_cam_target`` poses) -> :class:`CameraData`; then pairing with the motion
capture in time -> ``A``, ``B`` (docs/conventions.md, section 2) -> :class:`PairedCamera`.
The pipeline (:mod:`multieye.pipeline`) takes it from there.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import DatasetError, TooFewMeasurementsError
from multieye.core.intrinsics import Intrinsics
from multieye.estimate.pairing import pair_in_time
from multieye.imaging.calibrate import look_again
from multieye.imaging.engines import Engine
from multieye.io import RejectedItem, Rig, Trajectory, list_image_files, read_mocap, skipped_entries
from multieye.io.image_folder import label_stem
from multieye.pipeline.boards import camera_boards, intrinsics_boards, per_board, resized_hint
from multieye.pipeline.boards import no_usable_image as _no_usable_image
from multieye.pipeline.boards import rejection_kind  # noqa: F401  (where it was)
from multieye.pipeline.detection import Workers, detect_all, detect_listed
from multieye.pipeline.estimated_lens import lens_start, posed_on_refined_lens, sized_as_seen, start_lens, with_poses
from multieye.pipeline.recordings import (check_sync, instant_keys, note_label, poses_by_name_of,
                                          precomputed_poses, sync_instant)
from multieye.pipeline.rig_model import RigModel, build_rig_model
from multieye.pipeline.selection import Chosen, SelectionSummary, motion_first, preselected, with_refills
from multieye.solvers.methods import MIN_MEASUREMENTS
from multieye.imaging.pnp import ambiguity_warning
from multieye.pipeline.half_turns import offer_half_turn

__all__ = ["Observation", "CameraData", "PairedCamera", "CameraMotion", "load_camera_data",
           "instant_key", "camera_motion", "pair_stamps", "pair_camera", "rejection_kind",
           "BY_NAME_TOLERANCE"]

@dataclass(frozen=True)
class Observation:
    """The target seen in one image (or one precomputed pose).

    Attributes
    ----------
    name : str
        Image file name, or ``"<poses file> pose <k>"`` (k-th pose of the file, from 1).
    stamp : float
        Camera clock, seconds.
    T_cam_target : ndarray, shape (4, 4)
    rms_px : float or None
        PnP reprojection RMS, pixels (None for precomputed poses).
    object_points : ndarray, shape (n, 3), or None
        Detected target points in the target frame, metres.
    image_points : ndarray, shape (n, 2), or None
        Their pixels.
    alternative : ndarray, shape (4, 4), or None
        The target's other PnP pose (a single marker's mirrored pose,
        :attr:`multieye.imaging.pnp.PoseEstimate.alternative`), for the consensus to choose.
    alternative_rms_px : float or None
        Its reprojection RMS, pixels.
    alternative_order : ndarray of int, shape (n,), or None
        For a board that looks the same after a half turn, whose ``alternative`` is its other
        point order (``T_cam_target @ H``): the image points of that order are
        ``image_points[alternative_order]`` (:mod:`multieye.pipeline.half_turns`).
    target : str
        The name of the board the view shows (rig.yaml's ``targets:``; ``"target"`` for
        ``target:``).  An image showing two boards gives two observations, one per board,
        with the same ``name`` and ``instant`` (:mod:`multieye.pipeline.boards`).
    instant : str
        The instant the image was taken, as a key that images of other cameras taken at the
        same instant share (the target then has one pose for all of them): today the key of
        the pairing, the camera-clock ``stamp`` (``repr``) or, for a camera paired by name,
        the image's name without its suffix; with rig.yaml's ``sync`` other than ``time``,
        the key its name gives (:func:`instant_key`).  The problem groups the
        images by it (:attr:`multieye.pipeline.problem.Problem.instants`).
    """

    name: str
    stamp: float
    T_cam_target: np.ndarray
    rms_px: float | None = None
    object_points: np.ndarray | None = None
    image_points: np.ndarray | None = None
    alternative: np.ndarray | None = None
    alternative_rms_px: float | None = None
    instant: str = ""
    alternative_order: np.ndarray | None = None
    target: str = "target"


def instant_key(observation: Observation, by_name: bool, sync: str = "time",
                keys: Mapping[str, str] | None = None) -> str:
    """The :attr:`Observation.instant` of an image: under rig.yaml's ``sync`` other than
    ``time`` the key its name gives among its camera's ``keys`` (:mod:`multieye.pipeline.
    recordings`); else its stem when the camera is paired by name, else its stamp (exact)."""
    if sync != "time":
        return sync_instant(observation.name, observation.stamp, sync, keys)
    return label_stem(observation.name) if by_name else repr(float(observation.stamp))


@dataclass(frozen=True)
class CameraData:
    """What one camera contributes before pairing.

    Attributes
    ----------
    name : str
    intrinsics : Intrinsics or None
        None for a camera given by precomputed poses.
    observations : tuple of Observation
        Images with a target pose, in time order.
    rejected : tuple of RejectedItem
        Images left out, and why.
    n_inputs : int
        Images (or pose rows) read.
    mocap : Trajectory or None
        ``T_world_marker`` (eye-to-base) or ``T_world_body`` (eye-on-hand).  None is a
        camera without motion capture (a rig linked by the cameras that see the target
        together: rig.yaml without ``mocap:``, docs/rig-yaml.md, section 2).
    time_offset : float
        Motion-capture clock minus camera clock, seconds.
    time_tolerance : float
        Seconds.
    warnings : tuple of str
    detection_s : float
        Seconds spent on target detection and PnP (reading the images included, listing
        them not); 0 for precomputed poses.
    intrinsics_estimated : bool
        The intrinsics are estimated from the recording (``intrinsics`` is then the start:
        OpenCV's calibration from the camera's own views, or the given file to refine).
    intrinsics_views : tuple of Observation
        Images without motion capture that inform the intrinsics only (``intrinsics_images``),
        with their starting target pose.
    by_name : bool
        Paired by name (one pose file beside each image): the images with a pose file have
        the stamps 0, 1, 2, ... in name order and ``mocap`` holds their poses at the same
        stamps; :func:`pair_camera` pairs them exactly, without clock offset.
    selection : SelectionSummary or None
        What the image selection did (:mod:`multieye.pipeline.selection`); None when it did
        not choose among this camera's images.
    image_notes : tuple of (str, str)
        Notes about single images, ``(camera/image, cause)``, gathered over the rig into one
        line per cause (:func:`multieye.pipeline.recordings.camera_warnings`).
    bad_fits : tuple of Observation
        The images left out as a bad fit (``bad fit: reprojection RMS ...`` among
        ``rejected``, their item there the observation's ``name``, with `` (<target>)``
        when the camera looks for several boards), with their points and
        their pose by PnP on the lens they were judged on: a camera whose lens is estimated
        judges them again on the jointly refined lens
        (:mod:`multieye.pipeline.image_acceptance`).
    """

    name: str
    intrinsics: Intrinsics | None
    observations: tuple[Observation, ...]
    rejected: tuple[RejectedItem, ...]
    n_inputs: int
    mocap: Trajectory | None
    time_offset: float
    time_tolerance: float
    warnings: tuple[str, ...] = ()
    detection_s: float = 0.0
    intrinsics_estimated: bool = False
    intrinsics_views: tuple[Observation, ...] = ()
    by_name: bool = False
    selection: SelectionSummary | None = None
    image_notes: tuple[tuple[str, str], ...] = ()
    bad_fits: tuple[Observation, ...] = ()


@dataclass(frozen=True)
class PairedCamera:
    """One camera's measurements for ``A_i X = Y B_i`` (docs/conventions.md, section 2).

    Attributes
    ----------
    name : str
    A, B : ndarray, shape (n, 4, 4)
    T_world_mocap : ndarray, shape (n, 4, 4)
        The motion-capture pose at each used image (``T_world_marker`` or ``T_world_body``).
    observations : tuple of Observation
        The used images, one per row of A and B.
    rejected : tuple of RejectedItem
        Everything left out so far (detection and pairing).
    mocap_noise_scale : ndarray, shape (n,), or None
        Per used image, :attr:`multieye.estimate.pairing.Pairing.noise_scale`; None: ones.
    """

    name: str
    A: np.ndarray
    B: np.ndarray
    T_world_mocap: np.ndarray
    observations: tuple[Observation, ...]
    rejected: tuple[RejectedItem, ...]
    mocap_noise_scale: np.ndarray | None = None


#: How the reason of a motion-capture row left out starts (those rows are listed with the
#: images of every camera that uses the file, but are not images).
_MOCAP_ROW = "motion-capture row left out"


def _listed(items: list[RejectedItem], prefix: str = "", limit: int = 3) -> str:
    text = ", ".join(f"{r.item} ({r.reason})" for r in items[:limit])  # a.png (why), ... and 5 more
    return prefix + text + (f" and {len(items) - limit} more" if len(items) > limit else "") if items else ""


@dataclass(frozen=True)
class _Detected:
    """What detection and PnP gave for one camera's images."""

    observations: list[Observation]
    rejected: list[RejectedItem]
    n_inputs: int
    warnings: tuple[str, ...]
    seconds: float
    intrinsics: Intrinsics | None = None     # the started lens, when it was estimated
    notes: tuple[tuple[str, str], ...] = ()  # (camera/image, cause)
    chosen: Chosen | None = None             # the choice before decoding, with its refills
    bad_fits: tuple[Observation, ...] = ()   # left out as a bad fit, with points and pose


def _observations_from_images(rig: Rig, model: RigModel, name: str, intr: Intrinsics | None,
                              workers: Workers, *, listed=None, extra_views=(),
                              chosen: Chosen | None = None) -> _Detected:
    """Detection and PnP over a folder of time-stamped images, or a bag's image topic.

    Without ``intr`` (a camera whose lens is estimated), detection runs alone, the lens
    ``model`` is started from the detections (:mod:`multieye.pipeline.estimated_lens`) and the
    poses follow by PnP with it; the start is then ``_Detected.intrinsics``. ``listed``:
    the images as ``(stamp, ns, path)`` instead of the folder's time-stamped names.
    ``extra_views``: detection-only results of the camera's ``intrinsics_images``, which
    inform the starting lens too.  ``chosen``: the images chosen before decoding (then
    ``listed``), to which more are added while chosen ones prove unusable
    (:func:`~multieye.pipeline.selection.with_refills`).
    """
    cam = rig.cameras[name]
    source = {"images": cam.images, "rosbag": cam.rosbag, "video": cam.video}[cam.source]
    target, boards = camera_boards(rig, name, model.targets)
    lost: list = []
    stamped, results, seconds = detect_listed(rig, model, name, intr, workers, listed, lost)
    t0, n_first = time.perf_counter(), len(results)
    stamped, results, chosen = with_refills(
        chosen, (stamped, results),
        lambda items: detect_listed(rig, model, name, intr, workers, items, lost, fresh=True)[:2],
        usable=lambda r: r.ok if intr is not None else r.reason is None)
    seconds += time.perf_counter() - t0
    lens, n_images = None, len(stamped)
    stamped, results, boards = per_board(stamped, results, boards)    # one per (image, board)
    if intr is None:
        results = sized_as_seen(results)
        detected = [r for r in results if r.reason is None]
        if not detected:
            raise DatasetError(_no_usable_image(rig, [RejectedItem(lb, r.reason) for (_, lb), r
                                                      in zip(stamped, results)], n_images),
                               path=source, camera=name)
        started = None if extra_views or len(results) > n_first else workers.started.get(name)
        if started is not None:     # started by the detection's workers (detect_all)
            lens = lens_start(name, cam.model, results, started.start)
            results = list(started.results)
        else:
            lens = start_lens(name, cam.model, list(results) + list(extra_views), source)
            if cam.source == "images":      # a wide lens's second look, before the poses
                results = look_again(results, target, lens.intrinsics)
            lens, results = posed_on_refined_lens(lens, results)
    obs, rejected, notes, bad_fits = [], [], [], []
    warnings = list(lens.warnings if lens else ()) + list(_recovered(name, results, n_images))
    for (stamp, label), res, board in zip(stamped, results, boards):
        if res.ok:
            obs.append(offer_half_turn(_observation(label, stamp, res, board),
                                       model.targets.get(board, target)))
            notes.extend((note_label(rig, name, label), w) for w in res.warnings)
        else:
            shown = label if board is None or len(set(boards)) == 1 else f"{label} ({board})"
            rejected.append(RejectedItem(shown, res.reason))
            if res.pose is not None and res.detection is not None \
                    and res.reason.startswith("bad fit"):
                bad_fits.append(offer_half_turn(_observation(label, stamp, res, board),
                                                model.targets.get(board, target)))
    # pose ambiguity (single marker): warn when the two poses fit alike in most images
    warnings.extend(w for w in [ambiguity_warning(name, [r.pose for r in results if r.ok])] if w)
    skipped = [RejectedItem(n, why) for n, why in lost]
    if cam.source == "images":      # links to nowhere, devices, folders named like images
        skipped += [RejectedItem(n, why) for n, why in skipped_entries(source, cam.images_pattern)]
    rejected.extend(skipped)
    if not obs:
        why = _no_usable_image(rig, rejected, n_images, resized_hint(intr, results))
        raise DatasetError(why, path=source, camera=name)
    return _Detected(observations=obs, rejected=rejected, n_inputs=n_images + len(skipped),
                     warnings=tuple(warnings), seconds=seconds,
                     intrinsics=None if lens is None else lens.intrinsics, notes=tuple(notes),
                     chosen=chosen, bad_fits=tuple(bad_fits))


def _observation(label: str, stamp: float, res, board: str | None) -> Observation:
    """The :class:`Observation` of an image result with a pose."""
    pose, det = res.pose, res.detection
    return Observation(name=label, stamp=stamp, T_cam_target=pose.T_cam_target, rms_px=pose.rms_px,
                       object_points=det.object_points, image_points=det.image_points,
                       alternative=pose.alternative, alternative_rms_px=pose.alternative_rms_px,
                       target=board)


def _detect_intrinsics_images(rig: Rig, cam, model: RigModel, intr: Intrinsics | None,
                              workers: Workers) -> tuple[list[tuple[Path, str | None]], list,
                                                         float]:
    """Detection (and PnP with ``intr`` unless None) over a camera's ``intrinsics_images``
    (their own board if given, else every board the camera may see): per (image, board)
    the path and board name, the results, and the seconds it took."""
    target, names = intrinsics_boards(rig, cam.name, model)
    paths = list_image_files(cam.intrinsics_images)
    key = (cam.name, "intrinsics_images")
    if key in workers.detected:
        results, seconds = workers.detected[key], workers.seconds[key]
    else:
        t0 = time.perf_counter()
        results = workers.detect(paths, target, intr, cam.crop)
        seconds = time.perf_counter() - t0
    paths, results, boards = per_board(paths, results, names)      # one per (image, board)
    return list(zip(paths, boards)), results, seconds


def _intrinsics_views(rig: Rig, cam, model: RigModel, intr: Intrinsics, workers: Workers,
                      detected=None) -> tuple[list[Observation], list[RejectedItem], float,
                                              tuple[str, ...]]:
    """Detection and PnP over a camera's ``intrinsics_images`` (their own board if given);
    ``detected``: their detection-only ``(paths, results, seconds)`` already at hand, to
    which the second look of a wide lens (:func:`multieye.imaging.calibrate.look_again`)
    and the PnP with ``intr`` are added.  Also the line of how many the second look found
    (:func:`_recovered`)."""
    if detected is None:
        paths, results, seconds = _detect_intrinsics_images(rig, cam, model, intr, workers)
    else:
        paths, results, seconds = detected
        results = with_poses(look_again(results, intrinsics_boards(rig, cam.name, model)[0],
                                        intr), intr)
    obs, rejected = [], []
    recovered = _recovered(cam.name, results, len(results), cam.intrinsics_images.name)
    several = len({b for _, b in paths}) > 1
    for (path, board), res in zip(paths, results):
        label = f"{cam.intrinsics_images.name}/{path.name}"
        label += f" ({board})" if several and board is not None else ""
        if res.ok:
            obs.append(Observation(name=label, stamp=float("nan"),
                                   T_cam_target=res.pose.T_cam_target, rms_px=res.pose.rms_px,
                                   object_points=res.detection.object_points,
                                   image_points=res.detection.image_points,
                                   target=board or "target"))
        else:
            rejected.append(RejectedItem(label, res.reason))
    rejected.extend(RejectedItem(f"{cam.intrinsics_images.name}/{n}", why)
                    for n, why in skipped_entries(cam.intrinsics_images))
    return obs, rejected, seconds, recovered


def _recovered(name: str, results, n_images: int, folder: str | None = None) -> tuple[str, ...]:
    """The line that says how many of a camera's usable views the second look of its wide
    lens found (:mod:`multieye.imaging.wide_look`), or nothing; ``folder``: of its
    ``intrinsics_images``."""
    n = sum(r.ok and r.second_look for r in results)
    where = "" if folder is None else f" in {folder}"
    return (f"{name}: {n} of {n_images} images{where} recovered by the wide lens's second look "
            "(the board, not found in the image itself, found in a perspective view of the "
            "lens's field)",) if n else ()


def load_camera_data(rig: Rig, *, processes: int | None = None, progress: bool = False,
                     select: int | None = None, time_offset: str | float = "rig",
                     engine: Engine | None = None, on_sent: Callable[[], object] | None = None,
                     model: RigModel | None = None) -> dict[str, CameraData]:
    """Read, detect and estimate every camera's target poses and its motion capture.

    Parameters
    ----------
    rig : Rig
    processes, progress
        Detection processes, progress bar.
    select : int, optional
        Image budget per camera: a camera with images (a folder) and more than this many
        detects only as many, chosen before decoding (:func:`multieye.pipeline.selection.
        preselect`); None detects every image.
    time_offset : "rig", "auto" or float
        The clock offset the selection pairs with (``Options.time_offset``); with "auto"
        nothing is chosen before decoding.
    engine : Engine, optional
        Detection as tasks of this engine (:func:`multieye.imaging.engines.open_engine`)
        instead of the local worker processes.
    on_sent : callable, optional
        Called once the first image files are sent to the local workers
        (:func:`multieye.imaging.batch.detect_jobs_then`); not called when none are.
    model : RigModel, optional
        The targets and given lenses, built once (:func:`multieye.pipeline.rig_model.
        build_rig_model`; built here when not given).

    Raises
    ------
    DatasetError
        A missing or malformed file, or a camera in which the target is never detected.
    """
    trajectories: dict[tuple, Trajectory] = {}
    motions: dict[str, CameraMotion] = {}
    model = build_rig_model(rig) if model is None else model
    check_sync(rig)                 # sync: order, cameras with as many images

    def read_motions() -> None:     # once; in rig.cameras order, as the errors come
        motions.update({} if motions else {
            name: camera_motion(rig, name, trajectories) if rig.has_mocap
            else CameraMotion(None) for name in rig.cameras})

    def sent() -> None:             # the first images are with the workers: read it now
        if on_sent is not None:
            on_sent()
        read_motions()

    # the motion capture before the detection only where it chooses or lists the images
    first = motion_first(rig, select, time_offset)
    if first:
        read_motions()
    chosen = preselected(rig, motions, select, time_offset, pair_stamps) if first else {}
    workers = detect_all(rig, model, motions, Workers(processes, progress, engine), chosen,
                         on_sent=on_sent if first else sent)
    read_motions()                  # when no image went to workers
    return {name: _camera_data(rig, model, name, motions[name], workers, chosen.get(name))
            for name in rig.cameras}


@dataclass(frozen=True)
class _Seen:
    """What one camera's own files gave: its lens (None for poses without intrinsics), the
    observations, what was left out, and the views for its lens only."""

    intrinsics: Intrinsics | None
    observations: tuple[Observation, ...]
    rejected: tuple[RejectedItem, ...]
    n_inputs: int
    warnings: tuple[str, ...] = ()
    seconds: float = 0.0
    views: tuple[Observation, ...] = ()
    notes: tuple[tuple[str, str], ...] = ()
    selection: SelectionSummary | None = None
    bad_fits: tuple[Observation, ...] = ()


def _camera_data(rig: Rig, model: RigModel, name: str, motion: CameraMotion, workers: Workers,
                 chosen=None) -> CameraData:
    cam, spec = rig.cameras[name], rig.mocap_for(name)
    seen = (_from_poses(cam, model.lenses[name]) if cam.source == "poses"
            else _from_images(rig, model, name, motion, workers, chosen))
    # motion-capture rows left out, listed with every camera that uses the file
    rejected = seen.rejected + tuple(
        RejectedItem(f"{spec.file.name} {r.where}", f"{_MOCAP_ROW}: {r.reason}")
        for r in (motion.trajectory.skipped if spec is not None else ()))
    by_name = spec is not None and spec.by_name
    keys = instant_keys(rig, name)
    observations = tuple(replace(o, instant=instant_key(o, by_name, rig.sync, keys))
                         for o in seen.observations)
    bad_fits = tuple(replace(o, instant=instant_key(o, by_name, rig.sync, keys))
                     for o in seen.bad_fits)
    return CameraData(name=name, intrinsics=seen.intrinsics, observations=observations,
                      rejected=rejected, n_inputs=seen.n_inputs, mocap=motion.trajectory,
                      time_offset=cam.time_offset,
                      time_tolerance=0.0 if spec is None else spec.time_tolerance,
                      warnings=seen.warnings, detection_s=seen.seconds,
                      intrinsics_estimated=cam.estimate_intrinsics, intrinsics_views=seen.views,
                      by_name=by_name, image_notes=seen.notes,
                      selection=seen.selection, bad_fits=bad_fits)


def _from_poses(cam, lens: Intrinsics | None) -> _Seen:
    """A camera given by precomputed ``T_cam_target`` poses."""
    traj = precomputed_poses(cam)
    # poses keep their row number in the file (k of "pose k") when rows are left out
    gone = {r.row for r in traj.skipped}
    rows = [k for k in range(1, len(traj) + len(gone) + 1) if k not in gone]
    obs = tuple(Observation(name=f"{cam.poses.name} pose {k}", stamp=float(t), T_cam_target=T)
                for k, t, T in zip(rows, traj.stamps, traj.T))
    rejected = tuple(RejectedItem(f"{cam.poses.name} pose {r.row}", f"{r.where}: {r.reason}")
                     for r in traj.skipped)
    return _Seen(intrinsics=lens, observations=obs, rejected=rejected, n_inputs=len(obs) + len(rejected))


def _from_images(rig: Rig, model: RigModel, name: str, motion: CameraMotion, workers: Workers,
                 chosen=None) -> _Seen:
    """A camera given by images (a folder or a bag topic): detection, the starting lens when
    it is estimated, PnP; its ``intrinsics_images`` as views for the lens.  ``chosen``: the
    images selected before decoding, those left out and the summary (:func:`preselect`)."""
    cam = rig.cameras[name]
    intr = model.lenses[name]
    # a lens to estimate: the intrinsics_images inform its start too
    extra = None
    if cam.intrinsics_images is not None and intr is None:
        extra = _detect_intrinsics_images(rig, cam, model, None, workers)
    det = _observations_from_images(rig, model, name, intr, workers,
                                    listed=motion.listed if chosen is None else chosen.kept,
                                    extra_views=() if extra is None else extra[1], chosen=chosen)
    left = [] if det.chosen is None else det.chosen.left
    rejected = list(motion.unmatched) + det.rejected + list(left)
    n_inputs = (det.n_inputs + len(left)
                + sum(r.reason.startswith("no pose file") for r in motion.unmatched))
    intr = intr if det.intrinsics is None else det.intrinsics
    seconds, views, warnings = det.seconds, [], det.warnings
    if cam.intrinsics_images is not None:
        views, lost, s, recovered = _intrinsics_views(rig, cam, model, intr, workers,
                                                      detected=extra)
        rejected, seconds, warnings = rejected + lost, seconds + s, warnings + recovered
    return _Seen(intrinsics=intr, observations=tuple(det.observations), rejected=tuple(rejected),
                 n_inputs=n_inputs, warnings=warnings, seconds=seconds, views=tuple(views),
                 notes=det.notes, selection=None if det.chosen is None else det.chosen.summary,
                 bad_fits=det.bad_fits)


@dataclass(frozen=True)
class CameraMotion:
    """The motion capture one camera pairs with, as :func:`camera_motion` reads it.

    Attributes
    ----------
    trajectory : Trajectory or None
        ``T_world_marker`` / ``T_world_body`` samples (for a camera paired by name: at the
        stamps 0, 1, 2, ... of its images with a pose file, in name order); None for a rig
        without motion capture.
    listed : list of (float, int, Path), or None
        Paired by name: the images with a pose file as ``(stamp, ns, path)``; else None (the
        images are listed by the detection).
    unmatched : tuple of RejectedItem
        Paired by name: images or pose files without their partner, and why.
    """

    trajectory: Trajectory | None
    listed: list | None = None
    unmatched: tuple[RejectedItem, ...] = ()


#: Tolerance of the pairing of a camera paired by name (seconds): its images and poses have
#: the same integer stamps, so any tolerance below 1 pairs exactly.
BY_NAME_TOLERANCE = 0.25


def camera_motion(rig: Rig, name: str, cache: dict[tuple, Trajectory]) -> CameraMotion:
    """The motion capture of camera ``name``; a file shared by several cameras is read once
    (``cache``, keyed by what selects its poses)."""
    spec, cam = rig.mocap_for(name), rig.cameras[name]
    key = (str(spec.file), spec.pose, spec.format, spec.topic, spec.rigid_body)
    if spec.by_name:
        traj, listed, unmatched = poses_by_name_of(name, cam, spec, rig.sync)
        cache[(key, name)] = traj
        return CameraMotion(traj, listed, tuple(unmatched))
    if key not in cache:
        cache[key] = read_mocap(spec)
    return CameraMotion(cache[key])


def pair_stamps(mocap: Trajectory, stamps: np.ndarray, *, by_name: bool, tolerance: float,
                offset: float):
    """:func:`multieye.estimate.pairing.pair_in_time` of image ``stamps`` (camera clock,
    seconds) with ``mocap``; a camera paired by name pairs stamp k with pose k exactly."""
    if by_name:
        return pair_in_time(mocap.stamps, mocap.T, stamps, tolerance=BY_NAME_TOLERANCE, offset=0.0)
    return pair_in_time(mocap.stamps, mocap.T, stamps, tolerance=tolerance, offset=offset)


def pair_camera(setup: str, data: CameraData, *, time_offset: float | None = None) -> PairedCamera:
    """Pair a camera's observations with motion capture and form its A and B.

    Parameters
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
    data : CameraData
    time_offset : float, optional
        Overrides ``data.time_offset`` (seconds, motion-capture minus camera clock).

    Raises
    ------
    TooFewMeasurementsError
        Fewer than 3 images paired; the message counts what was lost where.
    """
    offset = data.time_offset if time_offset is None else time_offset
    stamps = np.array([o.stamp for o in data.observations])
    p = pair_stamps(data.mocap, stamps, by_name=data.by_name, tolerance=data.time_tolerance,
                    offset=offset)
    unpaired = [RejectedItem(data.observations[i].name,
                             f"no motion capture within {data.time_tolerance:g} s ({why})")
                for i, why in p.unpaired]
    rejected = list(data.rejected) + unpaired
    used = tuple(data.observations[i] for i in p.index)
    if len(used) < MIN_MEASUREMENTS:
        lost = [r for r in data.rejected if not r.reason.startswith(_MOCAP_ROW)] + unpaired
        paired = "a pose for it" if data.by_name else f"motion capture within {data.time_tolerance:g} s"
        raise TooFewMeasurementsError(
            f"camera {data.name}: only {len(used)} of {data.n_inputs} images could be used "
            f"({data.n_inputs - len(data.observations)} without a target pose, {len(p.unpaired)} "
            f"without {paired}); at least {MIN_MEASUREMENTS} are needed{_listed(lost, '; left out: ')}")
    B = g.inv(np.stack([o.T_cam_target for o in used]))  # T_target_cam
    A = g.inv(p.T) if setup == "eye-to-base" else p.T  # T_marker_world or T_world_body
    return PairedCamera(name=data.name, A=A, B=B, T_world_mocap=p.T, observations=used,
                        rejected=tuple(rejected), mocap_noise_scale=p.noise_scale)
