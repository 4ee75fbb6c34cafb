"""A dry run: what calibrating a dataset would find, and what would go wrong, without solving.

:func:`check_dataset` reads ``rig.yaml`` and the motion capture, lists each camera's images
(or poses, or the messages of its bag's image topic), detects the target in an evenly spaced
sample of the images (of a bag, only the sampled messages are decoded), pairs the images with
the motion capture as :func:`multieye.pipeline.camera_data.pair_camera` does, and measures the
rotation of the paired motion. ``multieye check DATASET`` prints it (docs/outputs.md,
section 7) and exits 2 when calibrating would fail.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from multieye.core.arguments import real_number
from multieye.core.errors import InputError
from multieye.estimate.covisibility import (covisibility, link_groups, pairing_hint,
                                            unlinked_message)
from multieye.estimate.diagnostics import MIN_AXIS_RATIO, MIN_ROTATION_RANGE_DEG, MIN_SECOND_AXIS_DEG
from multieye.estimate.instants import default_sync_tolerance, instants_from_stamps
from multieye.imaging.batch import detect_and_estimate, detect_and_estimate_arrays
from multieye.imaging.image_file import read_region
from multieye.imaging.target_hints import counting_rule, suggest_target
from multieye.estimate.instants import instants_from_names
from multieye.io import Trajectory, bag_image_count, list_image_files, load_rig
from multieye.io import sample_bag_images
from multieye.pipeline.recordings import (check_sync, image_notes, instant_keys, listed_images,
                                          precomputed_poses, sync_instant)
from multieye.pipeline.rig_model import RigModel, build_rig_model
from multieye.pipeline.boards import camera_boards
from multieye.pipeline.dry_run_sample import (
    budget_note, evenly_spaced, sample_budget, sampled_on, shortfall)
from multieye.pipeline.dry_run_motion import nearest_gap, rotation_range
from multieye.pipeline.dry_run_boards import boards_found, motion_links, one_axis_problems, posed_boards
from multieye.pipeline.camera_data import BY_NAME_TOLERANCE, camera_motion, pair_stamps, rejection_kind
from multieye.pipeline.estimated_lens import MIN_COVERAGE, RECOMMENDED_VIEWS, image_coverage
from multieye.pipeline.estimated_lens import model_warnings
from multieye.io.calibration_json import OVERLAP
from multieye.pipeline.sources import outside_reads
from multieye.pipeline.frames import video_frames, video_listing

__all__ = ["CameraCheck", "DatasetCheck", "check_dataset"]

#: Below this share of the sampled images with the target found, the camera is warned about.
MIN_FOUND_SHARE = 0.5


@dataclass(frozen=True)
class CameraCheck:
    """What the dry run found for one camera.

    Attributes
    ----------
    name : str
    source : {"images", "poses", "rosbag", "video"}
    listed : int
        Images (or pose rows) of the camera.
    sampled : int
        Images in which the target was looked for (all pose rows for a camera given by poses).
    found : int
        Of those, the images with the target detected (and, with intrinsics, its pose).
    failures : tuple of (str, int)
        Why the others failed, by kind (``target not detected``, ``PnP failed``, ...).
    with_mocap : int
        Listed images with motion capture within the time tolerance; without motion
        capture, listed images that share an instant with another camera's.
    paired : int
        Sampled images with the target found and motion capture: the usable sample.
    expected_usable : int
        ``listed`` times the usable share of the sample: the images calibrating would use.
    time_tolerance_s : float
    rotation_range_deg, rotation_spread_deg : float and tuple of 3 floats, or None
        Largest rotation between the paired motion-capture poses of the usable sample, and
        the RMS rotation about its principal axes (descending); None below 2 such images.
    problems : tuple of str
        What will go wrong, or may.
    fatal : tuple of str
        The problems that make calibrating fail.
    undecided : tuple of str
        The problems that may make it fail, which the sample cannot decide (too few images
        with the target among those searched, the rest not searched: the check's budget).
    stamps : tuple of float
        Without motion capture: every listed image's stamp plus the camera's time offset.
    keys : tuple of str
        With rig.yaml's ``sync`` other than ``time``: every listed image's instant key.
    boards : tuple of (str, int)
        Every board the camera may see (rig.yaml ``targets:``) and in how many sampled images
        it was found.
    seen : tuple of (int, tuple of str)
        Per sampled image with a board found: its index among the listed images and the
        boards found in it.
    board_poses : tuple of (int, str, ndarray of shape (4, 4))
        With the lens given: per sampled image and board found in it with a pose, its index
        among the listed images, the board and ``T_cam_board`` (metres).
    """

    name: str
    source: str
    listed: int
    sampled: int
    found: int
    failures: tuple[tuple[str, int], ...]
    with_mocap: int
    paired: int
    expected_usable: int
    time_tolerance_s: float
    rotation_range_deg: float | None
    rotation_spread_deg: tuple[float, float, float] | None
    problems: tuple[str, ...]
    fatal: tuple[str, ...]
    stamps: tuple[float, ...] = ()
    keys: tuple[str, ...] = ()
    boards: tuple[tuple[str, int], ...] = ()
    seen: tuple[tuple[int, tuple[str, ...]], ...] = ()
    board_poses: tuple = ()
    sampled_at: tuple[int, ...] = ()
    undecided: tuple[str, ...] = ()

    @property
    def found_percent(self) -> float:
        return 100.0 * self.found / self.sampled if self.sampled else 0.0


@dataclass(frozen=True)
class DatasetCheck:
    """The dry run of a whole dataset: per camera, and the verdict."""

    path: str
    setup: str
    cameras: tuple[CameraCheck, ...]
    #: Files read from outside the dataset folder named (:mod:`multieye.pipeline.sources`).
    notes: tuple[str, ...] = ()
    #: The instants found and what links each camera, one line each.
    links: tuple[str, ...] = ()

    @property
    def reasons(self) -> tuple[str, ...]:
        """Why calibrating would fail, ``camera: reason``; empty when it can run."""
        return tuple(f"{c.name}: {r}" for c in self.cameras for r in c.fatal)

    @property
    def ok(self) -> bool:
        return not self.reasons

    @property
    def doubts(self) -> tuple[str, ...]:
        """Why calibrating may fail, undecided by the images searched, ``camera: reason``."""
        return tuple(f"{c.name}: {r}" for c in self.cameras for r in c.undecided)


def _sample_bag(cam, target, intr, lost: list, *, sample, processes):
    """Detection in an evenly spaced sample of a bag's image topic, as for a folder.

    The sample is drawn over the topic's messages in bag order (their count from the bag's
    index); only the sampled messages are decoded, the stamp of every other one is read from
    its header bytes, and the bag is read once, one message at a time (at most one batch of
    sampled images in memory); read again for more while too few show the target
    (:func:`sampled_on`). Returns the stamps of all messages (seconds, bag order), the
    indices of the sampled messages and their detection results; the sampled compressed
    messages that could not be decoded are appended to ``lost`` as ``(label, reason)``.
    """

    wanted = evenly_spaced(bag_image_count(cam.rosbag, cam.topic), sample)
    stamps_ns: list[int] = []
    picked: list[int] = []

    def read(indices, done: list, **stamps):     # these messages decoded, in bag order
        bad: list = []
        for index, t, image in sample_bag_images(cam.rosbag, cam.topic, indices, gray=True,
                                                 lost=bad, **stamps):
            done.append(index)
            yield f"{cam.topic}@{t}", image
        lost.extend((f"{cam.topic}@{ns}", why) for ns, why in bad)

    results = detect_and_estimate_arrays(read(wanted, picked, stamps=stamps_ns), target, intr,
                                         processes=processes, progress=False, crop=cam.crop)
    stamps = np.array(stamps_ns, dtype=np.int64) * 1e-9

    def more(indices):          # another pass over the bag, decoding only these
        got: list[int] = []
        return got, detect_and_estimate_arrays(read(indices, got), target, intr,
                                               processes=processes, progress=False,
                                               crop=cam.crop)

    picked, results = sampled_on(len(stamps), picked, results, more, sample_budget(sample))
    return stamps, picked, results


def _lens_problems(cam, results, found_mask, n_listed: int, n_sampled: int) -> list[str]:
    """What the views of a camera whose lens is estimated lack, as calibrate will warn: too
    few views for its model (``RECOMMENDED_VIEWS``; its ``intrinsics_images`` counted as
    listed), the image too little covered by the sampled detections (4 x 4 cells)."""

    out = []
    views = int(round(n_listed * found_mask.sum() / n_sampled)) if n_sampled else 0
    extra = len(list_image_files(cam.intrinsics_images)) if cam.intrinsics_images else 0
    want = RECOMMENDED_VIEWS[cam.model]
    if views + extra < want:
        more = f" and {extra} intrinsics_images listed" if cam.intrinsics_images else ""
        out.append(f"lens {cam.model} estimated from about {views} views with the target"
                   f"{more}; {want} recommended: add views with the board tilted and near "
                   "the edges of the image (or intrinsics_images)")
    found = [r for r, ok in zip(results, found_mask) if ok and r.detection is not None
             and r.image_size is not None]
    if found:
        coverage = image_coverage(np.concatenate([r.detection.image_points for r in found]),
                                  found[0].image_size)
        if coverage < MIN_COVERAGE and not cam.intrinsics_images:
            out.append(f"the sampled views cover only {coverage:.0%} of the image "
                       "(4 x 4 cells): the lens's distortion would be extrapolated elsewhere; "
                       "add views with the board near the edges and corners")
        # a fisheye or wide model: another that the sampled views fit clearly better
        out.extend(w.removeprefix(f"{cam.name}: ") for w in model_warnings(
            cam.name, cam.model, [(r.detection.object_points, r.detection.image_points)
                                  for r in found], found[0].image_size))
    return out


def _target_hint(rig, cam, paths, results) -> str:
    """``; <what the images hold>`` from two of the sampled images where the target was not
    found (:func:`multieye.imaging.target_hints.suggest_target`; the camera's region of
    them), or ``""``."""
    missed = [p for p, r in zip(paths, results) if r.reason and r.reason.startswith(
        "target not detected")]
    if not missed:
        return ""
    picked = sorted({missed[0], missed[len(missed) // 2]})
    hint = suggest_target(picked if cam.crop is None else [
        im for p in picked if (im := read_region(p, None, cam.crop)[0]) is not None], rig.target)
    return f"; {hint.text}" if hint is not None else ""


@dataclass(frozen=True)
class _Sample:
    """A camera's listed images (or pose rows) and the detections on the sampled ones."""

    stamps: np.ndarray
    n_listed: int
    sampled_idx: list[int]
    found_mask: np.ndarray
    results: list
    failures: dict[str, int]
    n_sampled: int
    problems: tuple[str, ...] = ()
    paths: tuple = ()           # the sampled images' files (a folder of images only)
    names: tuple = ()           # every listed image's file name (a folder of images only)
    boards: tuple = ()          # (board, sampled images it was found in), every board looked for
    seen: tuple = ()            # (listed index, boards found) of each sampled image with one
    board_poses: tuple = ()     # (listed index, board, T_cam_board) where a pose was found


def _sampled(rig, cam, listed, unmatched, *, sample: int, processes,
             model: RigModel) -> _Sample:
    """Detection on at most ``sample`` evenly spaced images of the camera (every pose row of
    a camera given by poses), counting the failures by kind."""
    problems: list[str] = []
    results: list = []
    paths: list = []
    names: tuple = ()
    boards: tuple = ()
    seen: tuple = ()
    posed: tuple = ()
    failures: dict[str, int] = {}
    if cam.source == "poses":
        poses = precomputed_poses(cam)
        stamps = np.asarray(poses.stamps, dtype=np.float64)
        n_listed = len(stamps) + len(poses.skipped)
        sampled_idx = list(range(len(stamps)))
        found_mask = np.ones(len(stamps), bool)
        if poses.skipped:
            failures["pose row left out"] = len(poses.skipped)
        n_sampled = n_listed
    else:
        target, looked_for = camera_boards(rig, cam.name, model.targets)
        intr = model.lenses[cam.name]
        if cam.source == "images":
            images = listed_images(rig, cam.name) if listed is None else listed
            names = tuple(p.relative_to(cam.images).as_posix() for _, _, p in images)
            stamps = np.array([s for s, _, _ in images], dtype=np.float64)
            n_listed = len(images) + sum(r.reason.startswith("no pose file") for r in unmatched)

            def detect(indices):
                return indices, detect_and_estimate([images[i][2] for i in indices], target,
                                                    intr, processes=processes, progress=False,
                                                    crop=cam.crop)

            first = evenly_spaced(len(images), sample)     # more while too few show the target
            sampled_idx, results = sampled_on(len(images), *detect(first), detect, sample_budget(sample))
            paths = [images[i][2] for i in sampled_idx]
        elif cam.source == "video":
            listing = video_listing(cam)
            stamps = np.array([s for s, _, _ in listing], dtype=np.float64)
            n_listed, lost = len(listing), []

            def frames(indices):    # a video's frame index is its place in the listing
                read: list = []
                items = video_frames(cam, [listing[i] for i in indices], read, lost)
                found = detect_and_estimate_arrays(items, target, intr, processes=processes,
                                                   progress=False, crop=cam.crop)
                got = {label for _, label in read}
                return [i for i in indices if listing[i][2].name in got], found

            first = evenly_spaced(len(listing), sample)     # more while too few show it
            sampled_idx, results = sampled_on(len(listing), *frames(first), frames, sample_budget(sample))
            problems.extend(image_notes(lost))         # one line per cause
        else:
            lost = []
            stamps, sampled_idx, results = _sample_bag(cam, target, intr, lost, sample=sample,
                                                       processes=processes)
            problems.extend(image_notes(lost))         # one line per cause
            n_listed = len(stamps)
            if not n_listed:
                problems.append(f"image topic {cam.topic} holds no images")
        found_mask = np.array([r.reason is None for r in results], bool)
        for r in results:
            if r.reason is not None:
                failures[rejection_kind(r.reason)] = failures.get(rejection_kind(r.reason), 0) + 1
        n_sampled = len(sampled_idx)
        found = boards_found(results, looked_for)
        boards = tuple((n, sum(n in f for f in found)) for n in looked_for)
        seen = tuple((i, f) for i, f in zip(sampled_idx, found) if f)
        posed = tuple((i, b, T) for i, r in zip(sampled_idx, results)
                      for b, T in posed_boards(r, looked_for))
    return _Sample(stamps=stamps, n_listed=n_listed, sampled_idx=sampled_idx,
                   found_mask=found_mask, results=results, failures=failures,
                   n_sampled=n_sampled, problems=tuple(problems), paths=tuple(paths),
                   names=names, boards=boards, seen=seen, board_poses=posed)


def _check_camera(rig, name, cam, traj_cache, *, sample, processes, model) -> CameraCheck:
    spec = rig.mocap_for(name)
    if spec is None:                 # no motion capture: linked by the views (check_dataset)
        return _check_unpaired(rig, name, cam, sample=sample, processes=processes, model=model)
    problems: list[str] = []
    motion = camera_motion(rig, name, traj_cache)
    traj, listed, unmatched = motion.trajectory, motion.listed, motion.unmatched
    tolerance = BY_NAME_TOLERANCE if spec.by_name else spec.time_tolerance
    offset = 0.0 if spec.by_name else cam.time_offset
    seen = _sampled(rig, cam, listed, unmatched, sample=sample, processes=processes,
                    model=model)
    stamps, n_listed, sampled_idx = seen.stamps, seen.n_listed, seen.sampled_idx
    found_mask, results, failures, n_sampled = (seen.found_mask, seen.results, seen.failures,
                                                seen.n_sampled)
    problems.extend(seen.problems)
    lacking = [u for u in unmatched if not u.reason.startswith("pose file without")]
    if lacking:          # a pose file without an image (a toolkit's config.json) costs nothing
        problems.append(f"{len(lacking)} images without a pose (first {lacking[0].item}: "
                        f"{lacking[0].reason})")
    # pairing of every listed image in time (cheap), by calibrate's pairing
    if len(stamps):
        p = pair_stamps(traj, stamps, by_name=spec.by_name, tolerance=spec.time_tolerance,
                        offset=cam.time_offset)
        has_pose = np.zeros(len(stamps), bool)
        has_pose[p.index] = True
        T_at = np.full((len(stamps), 4, 4), np.nan)
        T_at[p.index] = p.T
    else:
        has_pose, T_at = np.zeros(0, bool), np.zeros((0, 4, 4))
    n_found = int(found_mask.sum())
    usable = [i for i, f in zip(sampled_idx, found_mask) if f and has_pose[i]]
    n_paired = len(usable)
    expected = int(round(n_listed * n_paired / n_sampled)) if n_sampled else 0
    expected = min(expected, int(has_pose.sum()))
    hint = ""                      # another board found in the images: decided, not a budget
    if cam.source != "poses" and n_found < MIN_FOUND_SHARE * n_sampled:
        text = (f"target found in only {n_found} of {n_sampled} sampled images"
                + budget_note(n_found, n_listed, sample))
        if n_found == 0:
            t = rig.target
            text += (f"; check the target section of rig.yaml ({t.type} {t.rows}x{t.cols}, "
                     f"spacing {t.as_dict().get('spacing', '?')} m: {counting_rule(t.type)}) "
                     "and the images")
            hint = _target_hint(rig, cam, seen.paths, results) if cam.source == "images" else ""
            text += hint
        problems.append(text)
    n_no_pose = len(stamps) - int(has_pose.sum())
    if n_no_pose:
        mocap_times = np.asarray(traj.stamps, dtype=np.float64)
        q = stamps[~has_pose] + offset
        nearest = nearest_gap(mocap_times, q)
        span = (f"motion capture {mocap_times[0]:.3f} to {mocap_times[-1]:.3f} s, images "
                f"{stamps.min() + offset:.3f} to {stamps.max() + offset:.3f} s in its clock"
                if len(mocap_times) else "no motion capture")
        problems.append(f"{n_no_pose} of {len(stamps)} images have no motion capture within "
                        f"{tolerance:g} s (nearest {np.min(nearest):.3g} to "
                        f"{np.max(nearest):.3g} s away; {span})")
    range_deg, spread = rotation_range(T_at[usable]) if usable else (None, None)
    if spread is not None:
        s0, s1 = spread[:2]
        if range_deg < MIN_ROTATION_RANGE_DEG:
            problems.append(f"rotation range {range_deg:.1f} deg, under "
                            f"{MIN_ROTATION_RANGE_DEG:g} deg: the extrinsic is poorly "
                            "determined; tilt by 30 deg or more about two axes")
        elif s1 < MIN_SECOND_AXIS_DEG or s1 < MIN_AXIS_RATIO * s0:
            problems.append(f"rotation about one axis (RMS {s0:.1f} deg about it, {s1:.2f} deg "
                            "about any other): rotate about a second axis")
    if cam.estimate_intrinsics and cam.source != "poses":
        problems.extend(_lens_problems(cam, results, found_mask, n_listed, n_sampled))
    short = shortfall(n_paired, n_found, n_sampled, expected, n_listed, decided=bool(hint))
    problems += [short[0]] if short else []
    fatal = [short[0]] if short and short[1] else []
    return CameraCheck(name=name, source=cam.source, listed=n_listed, sampled=n_sampled,
                       found=n_found, failures=tuple(sorted(failures.items())),
                       with_mocap=int(has_pose.sum()), paired=n_paired,
                       expected_usable=expected, time_tolerance_s=float(tolerance),
                       rotation_range_deg=range_deg, rotation_spread_deg=spread,
                       problems=tuple(problems), fatal=tuple(fatal), boards=seen.boards,
                       undecided=() if fatal or not short else (short[0],),
                       seen=seen.seen, board_poses=seen.board_poses)


def _check_unpaired(rig, name, cam, *, sample, processes, model) -> CameraCheck:
    """A camera of a rig without motion capture: every image with the target is usable; the
    links between cameras are checked over the rig (:func:`_linked`)."""
    seen = _sampled(rig, cam, None, (), sample=sample, processes=processes, model=model)
    problems = list(seen.problems)
    n_found = int(seen.found_mask.sum())
    expected = int(round(seen.n_listed * n_found / seen.n_sampled)) if seen.n_sampled else 0
    hint = (_target_hint(rig, cam, seen.paths, seen.results)
            if n_found == 0 and cam.source == "images" else "")
    if n_found < MIN_FOUND_SHARE * seen.n_sampled:
        problems.append(f"target found in only {n_found} of {seen.n_sampled} sampled images"
                        + budget_note(n_found, seen.n_listed, sample)
                        + hint)
    if cam.estimate_intrinsics:
        problems.extend(_lens_problems(cam, seen.results, seen.found_mask, seen.n_listed,
                                       seen.n_sampled))
    short = shortfall(n_found, n_found, seen.n_sampled, expected, seen.n_listed,
                      decided=bool(hint))
    problems += [short[0]] if short else []
    fatal = [short[0]] if short and short[1] else []
    return CameraCheck(name=name, source=cam.source, listed=seen.n_listed,
                       sampled=seen.n_sampled, found=n_found,
                       failures=tuple(sorted(seen.failures.items())), with_mocap=0,
                       paired=n_found, expected_usable=expected, time_tolerance_s=0.0,
                       rotation_range_deg=None, rotation_spread_deg=None,
                       problems=tuple(problems), fatal=tuple(fatal),
                       undecided=() if fatal or not short else (short[0],),
                       stamps=tuple(float(t) + cam.time_offset for t in seen.stamps),
                       keys=_keys(rig, name, seen), boards=seen.boards, seen=seen.seen,
                       board_poses=seen.board_poses, sampled_at=tuple(seen.sampled_idx))


def _keys(rig, name: str, seen) -> tuple[str, ...]:
    """The sampled images' instant keys under rig.yaml's ``sync`` (none with ``time``)."""
    if rig.sync == "time":
        return ()
    keys = instant_keys(rig, name)
    return tuple(sync_instant(n, t, rig.sync, keys) for n, t in zip(seen.names, seen.stamps))


def _linked(rig, cams: tuple[CameraCheck, ...]) -> tuple[tuple[CameraCheck, ...], tuple]:
    """A rig without motion capture: per camera, ``with_mocap`` becomes its listed images
    that share an instant with another camera's (docs/rig-yaml.md, section 2), and cameras
    in groups that nothing links get the refusal calibrating would give (with one board:
    with several the rig's motion may link them, issue 34); with the lines that say the
    instants found and what links each camera."""
    if rig.sync != "time":
        by_key, n_inst = instants_from_names({c.name: list(c.keys) for c in cams})
        inst, tol = [by_key[c.name] for c in cams], 0.0
    else:
        stamps = [np.asarray(c.stamps, dtype=np.float64) for c in cams]
        tol = (default_sync_tolerance(stamps) if rig.sync_tolerance is None
               else rig.sync_tolerance)
        inst, n_inst = instants_from_stamps(stamps, tol)
    allc = np.concatenate([np.full(len(i), j) for j, i in enumerate(inst)])
    cov = covisibility(allc, np.concatenate(inst), len(cams))
    groups = link_groups(cov.shared > 0, [False] * len(cams))
    several = len(rig.targets or {}) > 1
    lines = _link_lines(rig, cams, inst, n_inst, cov.shared, tol)
    if several:         # the rig's motion may link them: what the sampled detections say
        views = [(j, int(inst[j][i]), b) for j, c in enumerate(cams) for i, bs in c.seen
                 for b in bs]
        lines = lines[:1] + tuple(motion_links([c.name for c in cams], views))
        given = frozenset(n for n, t in rig.targets.items() if getattr(t, "pose", None) is not None)
        turned = one_axis_problems([c.name for c in cams], views, cams[0].board_poses, given)
        cams = tuple(replace(c, problems=c.problems + turned.get(c.name, ())) for c in cams)
    else:
        cams = _never_together(cams, inst)
    out = []
    for j, c in enumerate(cams):
        others = np.concatenate([i for k, i in enumerate(inst) if k != j] or [np.zeros(0)])
        shared = int(np.isin(inst[j], others).sum())
        fatal = c.fatal
        # several boards: the rig's motion may link them (which the detections decide)
        if len(groups) > 1 and j not in groups[0] and not several:
            fatal += (unlinked_message([[cams[i].name for i in g] for g in groups], tol,
                                       rig.sync) + pairing_hint(
                groups, [c.stamps for c in cams], [c.keys for c in cams], rig.sync,
                [c.name for c in cams]),)
        apart = tuple(f"linked to {cams[0].name} by nothing in the sampled images: no board "
                      "seen at an instant when a linked camera sees one (calibrating would "
                      "refuse it unless other images link it)"
                      for line in lines[1:] if j > 0
                      and line.startswith(f"{c.name} linked by: nothing"))
        out.append(replace(c, with_mocap=shared, fatal=fatal,
                           problems=c.problems + fatal[len(c.fatal):] + apart))
    return tuple(out), lines


def _never_together(cams: tuple[CameraCheck, ...], inst) -> tuple[CameraCheck, ...]:
    """One board: a camera whose sampled images show the board, none of them at an instant
    when another camera's sampled image shows it too, though both were sampled at some, gets
    a problem: the listed images share instants, but calibrating links cameras by the board
    seen together (cameras that do not overlap are refused unless other images link them):
    the refusal itself when every image was sampled, else a doubt ('calibrating may fail')."""
    sampled = [{int(inst[j][i]) for i in c.sampled_at} for j, c in enumerate(cams)]
    board = [{int(inst[j][i]) for i, _ in c.seen} for j, c in enumerate(cams)]
    complete = all(len(c.sampled_at) == c.listed for c in cams)    # as calibrating sees them
    out = []
    for j, c in enumerate(cams):
        others = [k for k in range(len(cams)) if k != j]
        both = sum(len(sampled[j] & sampled[k]) for k in others)
        if both and board[j] and not any(board[j] & board[k] for k in others):
            what = (f"the board is in {len(board[j])} of its {'' if complete else 'sampled '}"
                    "images, but never at an instant when another camera's image shows it "
                    f"({both} instants {'' if complete else 'sampled '}in both): cameras "
                    "without motion capture are linked by the board seen together (check that "
                    "the cameras overlap, or give motion capture or several boards: targets:)")
            c = replace(c, problems=c.problems + (what,),   # undecided on a sample
                        fatal=c.fatal + ((what,) if complete else ()),
                        undecided=c.undecided + (() if complete else (what,)))
        out.append(c)
    return tuple(out)


#: How each ``sync`` makes images of different cameras one instant, for the dry run's lines.
_SYNC_RULE = {"name": "equal names without the extension",
              "number": "the same frame number in their names",
              "order": "the same place in each camera's name order"}


def _link_lines(rig, cams, inst, n_inst: int, shared, tol: float) -> tuple[str, ...]:
    """``instants: ...`` and ``<camera> linked by: ...`` lines of a rig without motion
    capture (listed images, before detection; ``cams``: the CameraChecks)."""
    labels = [c.name for c in cams]
    rule = (f"sync: {rig.sync}, {_SYNC_RULE[rig.sync]}" if rig.sync != "time"
            else f"stamps within sync_tolerance = {tol:g} s")
    counts = np.bincount(np.concatenate([np.unique(i) for i in inst]), minlength=n_inst)
    lines = [f"instants: {n_inst} found by {rule}; {int((counts > 1).sum())} of them seen by "
             "more than one camera"]
    for j, n in enumerate(labels):
        with_ = [f"{labels[k]} ({int(shared[j, k])} instants)" for k in range(len(labels))
                 if k != j and shared[j, k]]
        lines.append(f"{n} linked by: " + (", ".join(with_) if with_ else
                                             "nothing needed (the only camera)"
                                             if len(labels) == 1 else "nothing"))
    return tuple(lines)


def check_dataset(path, *, sample: int = 20, processes: int | None = None) -> DatasetCheck:
    """Dry-run the calibration of the dataset at ``path`` (a folder or its rig.yaml).

    Parameters
    ----------
    path : path-like
    sample : int
        At most this many images per camera, evenly spaced in time, are searched for the
        target: of a folder's images sorted by time, or of a bag topic's messages in bag
        order (only those are decoded; the stamps of the others, for the pairing, are read
        from their header bytes); more while fewer than 3 show it, at most 10 x ``sample``.
    processes : int, optional
        Detection processes (default: one per core).

    Returns
    -------
    DatasetCheck

    Raises
    ------
    DatasetError, InputError
        Bad input, as for :func:`multieye.pipeline.calibrate`.
    """
    if isinstance(sample, bool) or not isinstance(sample, (int, np.integer)) or sample < 1:
        raise InputError(f"sample must be a whole number of images >= 1, got {sample!r}")
    if processes is not None:
        real_number(processes, "processes", positive=True)
    rig = load_rig(path)
    model = build_rig_model(rig)
    check_sync(rig)
    cache: dict[tuple, Trajectory] = {}
    cams = tuple(_check_camera(rig, name, cam, cache, sample=int(sample), processes=processes,
                               model=model) for name, cam in rig.cameras.items())
    links: tuple = tuple(f"{c.name} linked by: motion capture ({c.with_mocap} of {c.listed} "
                         "images with it)" for c in cams)
    if not rig.has_mocap:
        cams, links = _linked(rig, cams)
    named = Path(path) / "rig.yaml" if Path(path).is_dir() else Path(path)
    return DatasetCheck(path=str(rig.path), setup=rig.setup if rig.has_mocap else OVERLAP,
                        cameras=cams, notes=outside_reads(rig, named), links=links)
