"""The image selection as the pipeline runs it (docs/recordings.md, section 1).

Before decoding (:func:`preselect`): per camera with images, its listed images paired in
time with its motion capture at the clock offset rig.yaml (or the options) state; those
without a pose are left out undecoded, and of the others each camera keeps its budget
(twice it when the camera's lens is estimated, so that the second pass can choose for the
lens), instants of several cameras whole (:func:`multieye.estimate.selection.
select_before_decoding`).  With ``time_offset="auto"`` nothing is left out here: the clock
is estimated from the continuous stream.

After detection (:func:`select_paired`): per camera still over its budget once paired, the
images that add most (:func:`multieye.estimate.selection.select_after_detection`), for a
camera whose lens is estimated with the coverage of the image and the lens's information.

Chosen images that prove unusable once decoded (the wrong size, undecodable, no target
detected, a bad PnP fit) are chosen again from the rest (:func:`with_refills`): more of the
paired images not chosen, the most informative first, until the camera has its budget of
usable images or none is left; in a recording where most frames do not show the target, the
first choice alone could leave a camera too few images to calibrate.

Each camera's :class:`SelectionSummary` goes to ``details.json`` and the screen; each image
left out is a :class:`~multieye.io.RejectedItem` with its reason.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from multieye.core import geometry as g
from multieye.core.lens import project_with_jacobian
from multieye.estimate.instants import default_sync_tolerance
from multieye.estimate.selection import (
    LEFT_OUT,
    grid_cells,
    lens_information,
    select_after_detection,
    select_before_decoding,
)
from multieye.io import RejectedItem, Rig, bag_image_count
from multieye.io.image_folder import image_name
from multieye.pipeline.frames import bag_listing, video_listing
from multieye.pipeline.recordings import listed_images
from multieye.solvers.methods import MIN_MEASUREMENTS

__all__ = ["SelectionSummary", "Chosen", "preselect", "preselected", "motion_first",
           "select_paired", "merged", "with_refills"]


@dataclass(frozen=True)
class SelectionSummary:
    """What the selection did to one camera.

    Attributes
    ----------
    budget : int
        Images per camera asked for.
    seen : int
        Images it chose among (listed, or detected and paired).
    kept : int
    stage : str
        ``"before decoding"`` or ``"after detection"``.
    without_mocap : int
        Images left out before decoding for want of a motion-capture pose.
    unusable : int
        Images chosen before decoding that proved unusable once decoded (counted in
        ``kept``).
    refilled : int
        Images chosen again from the rest because chosen ones proved unusable (counted in
        ``kept``; :func:`with_refills`).
    """

    budget: int
    seen: int
    kept: int
    stage: str
    without_mocap: int = 0
    unusable: int = 0
    refilled: int = 0

    def as_dict(self) -> dict:
        return {"budget": self.budget, "seen": self.seen, "kept": self.kept, "stage": self.stage,
                "without_mocap": self.without_mocap, "unusable": self.unusable,
                "refilled": self.refilled}

    def line(self, camera: str) -> str:
        """``cam0: 300 of 5400 images selected before decoding (budget 300)``, how many
        chosen images proved unusable and were replaced, and how many proved usable when
        that is fewer than the budget (every paired image tried)."""
        extra = (f"; {self.without_mocap} without motion capture not decoded"
                 if self.without_mocap else "")
        if self.refilled:
            extra += (f"; {self.unusable} of the images chosen proved unusable, so "
                      f"{self.refilled} more were chosen from the rest")
        elif self.unusable:
            extra += f"; {self.unusable} of the images chosen proved unusable, none left to add"
        if self.unusable and self.stage == "before decoding" and \
                self.kept - self.unusable < self.budget:    # every paired image was tried
            extra += f"; {self.kept - self.unusable} usable in all, fewer than the budget"
        return (f"{camera}: {self.kept} of {self.seen} images selected {self.stage} "
                f"(budget {self.budget}{extra})")


@dataclass(frozen=True)
class Chosen:
    """One camera's images chosen before decoding (:func:`preselect`).

    Attributes
    ----------
    kept : list of (float, int, item)
        The images to detect, as listed (``item`` a path or a video / bag frame).
    left : list of RejectedItem
        The images left out, with their reason.
    summary : SelectionSummary
    spare : list of (float, int, item)
        The images paired with the motion capture but not chosen: where :func:`with_refills`
        chooses from when chosen images prove unusable.
    spare_T : ndarray, shape (len(spare), 4, 4)
        Their motion-capture poses.
    """

    kept: list
    left: list
    summary: SelectionSummary
    spare: list = field(default_factory=list)
    spare_T: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))


def _tolerance(rig: Rig, stamps: list) -> float:
    """rig.yaml's ``sync_tolerance``, else the default of :mod:`multieye.estimate.instants`
    (a quarter of the shortest interval between two images of one camera)."""
    if rig.sync_tolerance is not None:
        return float(rig.sync_tolerance)
    return default_sync_tolerance([t for t in stamps if len(t) and t[0] > -1e11])


def merged(before: SelectionSummary | None, after: SelectionSummary) -> SelectionSummary:
    """One camera's summary of both passes (``before`` None when only the second ran)."""
    if before is None:
        return after
    return SelectionSummary(budget=after.budget, seen=before.seen, kept=after.kept,
                            stage="before decoding and after detection",
                            without_mocap=before.without_mocap, unusable=before.unusable,
                            refilled=before.refilled)


def preselect(rig: Rig, listings: dict, motions: dict, budget: int, offsets: dict,
              pair_stamps) -> dict:
    """Choose, before decoding, which listed images each camera detects.

    Parameters
    ----------
    rig : Rig
    listings : dict of camera name to list of (stamp, ns, path)
        Every listed image of each camera with images (folder or by-name).
    motions : dict of camera name to CameraMotion
        Its motion capture (:func:`multieye.pipeline.camera_data.camera_motion`).
    budget : int
        Images per camera.
    offsets : dict of camera name to float
        Clock offset to pair with (seconds).
    pair_stamps : callable
        :func:`multieye.pipeline.camera_data.pair_stamps`.

    Returns
    -------
    dict of camera name to Chosen
        The images to detect, those left out with their reason, the summary, and the paired
        images to choose from when chosen ones prove unusable; a camera with fewer than 3
        images paired is not in it (it detects every image, and the pairing says why it
        fails).
    """
    stamps, paired, poses, why = {}, {}, {}, {}
    name_ids: dict[str, int] = {}       # paired by name: one instant per image name (stem)
    for name, listed in listings.items():
        spec = rig.mocap_for(name)
        st = np.array([s for s, _, _ in listed], dtype=np.float64)
        p = pair_stamps(motions[name].trajectory, st, by_name=spec.by_name,
                        tolerance=spec.time_tolerance, offset=offsets[name])
        if len(p.index) < MIN_MEASUREMENTS:
            continue        # the pairing will say why this camera cannot be calibrated
        paired[name], poses[name] = np.asarray(p.index, dtype=int), p.T
        # what makes an instant (estimate.instants): stamps on the motion-capture clock within
        # the sync tolerance, or for cameras paired by name equal name stems
        stamps[name] = st + offsets[name] if not spec.by_name else -1e12 - 1e3 * np.array(
            [name_ids.setdefault(image_name(f, rig.cameras[name].images), len(name_ids))
             for _, _, f in listed],
            dtype=np.float64)
        why[name] = f"no motion capture within {spec.time_tolerance:g} s (not decoded)"
    listings = {n: v for n, v in listings.items() if n in paired}
    budgets = {n: budget * (2 if rig.cameras[n].estimate_intrinsics else 1) for n in listings}
    out = {}
    # cameras with the same budget are chosen together, so that shared instants stay whole
    for b in sorted(set(budgets.values())):
        names = [n for n in listings if budgets[n] == b]
        chosen = select_before_decoding({n: stamps[n] for n in names},
                                        {n: paired[n] for n in names},
                                        {n: poses[n] for n in names}, b,
                                        unpaired_reason=why,
                                        sync_tolerance=_tolerance(rig, [stamps[n] for n in names]))
        for n in names:
            sel, listed = chosen[n], listings[n]
            kept = [item for item, k in zip(listed, sel.keep) if k]
            left = [RejectedItem(path.name, reason)
                    for (_, _, path), k, reason in zip(listed, sel.keep, sel.reasons) if not k]
            spare = [k for k, i in enumerate(paired[n]) if not sel.keep[i]]
            out[n] = Chosen(kept, left, SelectionSummary(
                budget=b, seen=len(listed), kept=len(kept), stage="before decoding",
                without_mocap=len(listed) - len(paired[n])),
                spare=[listed[paired[n][k]] for k in spare], spare_T=poses[n][spare])
    return out


def with_refills(chosen: Chosen | None, first: tuple[list, list],
                 detect: Callable[[list], tuple[list, list]],
                 usable: Callable[[object], bool]) -> tuple[list, list, Chosen | None]:
    """The detections of a camera's chosen images, and of more chosen from the rest while
    fewer than the budget proved usable (module docstring).

    Each round chooses, among the paired images not yet tried, the most informative
    (:func:`multieye.estimate.selection.select_before_decoding`), as many as the images
    still wanted divided by the share of usable ones so far (Laplace's estimate), so that a
    recording where half the frames show the target needs one round and one where almost
    none does is decoded whole; the second pass (:func:`select_paired`) trims a camera
    that ends over its budget.

    Parameters
    ----------
    chosen : Chosen or None
        The camera's choice before decoding (None: nothing was chosen, nothing to add).
    first : (list, list)
        ``stamped`` and ``results`` of the chosen images (:func:`multieye.pipeline.
        detection.detect_listed`).
    detect : callable
        ``detect(items) -> (stamped, results)`` for more listed items.
    usable : callable
        Whether an image's result counts towards the budget.

    Returns
    -------
    stamped, results : list
        Of every image detected, the chosen ones first.
    chosen : Chosen or None
        With ``left`` and ``summary`` saying what was added (unchanged when nothing was).
    """
    stamped, results = list(first[0]), list(first[1])
    if chosen is None:
        return stamped, results, chosen
    budget, tried = chosen.summary.budget, len(chosen.kept)
    good = sum(1 for r in results if usable(r))
    spare, added = np.arange(len(chosen.spare)), []
    while good < budget and len(spare):
        rate = (good + 1) / (tried + 2)
        ask = min(len(spare), math.ceil((budget - good) / rate))
        if ask < len(spare):
            sel = select_before_decoding({"c": np.zeros(len(spare))},
                                         {"c": np.arange(len(spare))},
                                         {"c": chosen.spare_T[spare]}, ask)["c"]
            pick, spare = spare[sel.keep], spare[~sel.keep]
        else:
            pick, spare = spare, spare[:0]
        batch = [chosen.spare[i] for i in pick]
        s, r = detect(batch)
        stamped += s
        results += r
        added += batch
        tried += len(batch)
        good += sum(1 for x in r if usable(x))
    if not added and good >= budget:
        return stamped, results, chosen
    names = {item.name for _, _, item in added}
    summary = replace(chosen.summary, kept=tried, refilled=len(added), unusable=tried - good)
    return stamped, results, replace(chosen, left=[r for r in chosen.left if r.item not in names],
                                     summary=summary)


def _budget(cam, select: int) -> int:
    """Images a camera keeps before decoding: ``select``, twice it for a lens to estimate."""
    return select * (2 if cam.estimate_intrinsics else 1)


def motion_first(rig: Rig, select: int | None, time_offset) -> bool:
    """Whether the detection needs the motion capture before it starts: a camera paired by
    name (its images with a pose file are detected), or images that :func:`preselected`
    may choose (a budget, the clock offset given, and a camera with a bag, a video or more
    images in its folder than its budget).  Otherwise the pipeline reads it once the first
    images are with the workers (:func:`multieye.pipeline.camera_data.load_camera_data`:
    the 12,193 rows of a 4 x 100 rig's file took 50-90 ms, which the workers waited)."""
    if not rig.has_mocap:
        return False
    if any(getattr(rig.mocap_for(name), "by_name", False) for name in rig.cameras):
        return True
    if not select or time_offset == "auto":
        return False
    return any(cam.source in ("rosbag", "video")
               or (cam.source == "images" and _over(rig, name, _budget(cam, select)))
               for name, cam in rig.cameras.items())


def _over(rig: Rig, name: str, budget: int) -> bool:
    """Whether a camera's image folder holds more images than ``budget``; not listed when it
    holds no more entries than that (a folder that cannot be read is listed: its error
    then, naming the camera)."""
    try:
        if len(os.listdir(rig.cameras[name].images)) <= budget:
            return False
    except OSError:
        pass
    return len(listed_images(rig, name)) > budget


def preselected(rig: Rig, motions: dict, select: int | None, time_offset, pair_stamps) -> dict:
    """The images chosen before decoding, for the cameras with images (a folder, a video, a
    bag's topic) with more than ``select`` (twice that for a lens to estimate), by
    camera name as :func:`preselect` gives them; nothing with ``time_offset="auto"``.
    ``pair_stamps``: :func:`multieye.pipeline.camera_data.pair_stamps`."""
    if not select or time_offset == "auto":
        return {}
    listings, offsets = {}, {}
    for name, cam in rig.cameras.items():
        limit = _budget(cam, select)
        if motions[name].trajectory is None:
            continue        # no motion capture: nothing to choose by before decoding
        if cam.source == "poses" or (cam.source == "rosbag"
                                     and bag_image_count(cam.rosbag, cam.topic) <= limit):
            continue        # (a bag's stamps need a pass over it: only when over the budget)
        listed = motions[name].listed
        if cam.source != "images":
            listed = video_listing(cam) if cam.source == "video" else bag_listing(cam)
        elif listed is None:
            listed = listed_images(rig, name)
        if len(listed) > limit:
            listings[name] = listed
            offsets[name] = (0.0 if rig.mocap_for(name).by_name else
                             cam.time_offset if time_offset == "rig" else float(time_offset))
    if not listings:
        return {}
    return preselect(rig, listings, motions, int(select), offsets, pair_stamps)



def _lens_information(observations, intrinsics) -> np.ndarray:
    """Per view, the information it gives the lens, its pose a nuisance, (n, k, k)."""
    out = []
    for o in observations:
        T = o.T_cam_target
        Rp = o.object_points @ T[:3, :3].T
        uv, Jp, Ji = project_with_jacobian(Rp + T[:3, 3], intrinsics)
        ok = np.all(np.isfinite(uv), axis=1)
        Jpose = np.concatenate([-Jp[ok] @ g.skew(Rp[ok]), Jp[ok]], axis=2).reshape(-1, 6)
        out.append(lens_information(Ji[ok].reshape(-1, Ji.shape[-1]), Jpose))
    return np.stack(out)


def select_paired(paired: dict, cameras: dict, budget: int, sync_tolerance: float | None = None,
                  offsets: dict | None = None) -> tuple[dict, dict]:
    """Choose among the detected and paired images of the cameras over their budget.

    Parameters
    ----------
    paired : dict of camera name to PairedCamera
    cameras : dict of camera name to CameraData
    budget : int
    sync_tolerance : float, optional
        Seconds within which images of different cameras are one instant (their stamps plus
        ``offsets``); None: the default of :mod:`multieye.estimate.instants`.
    offsets : dict of camera name to float, optional
        Clock offsets the cameras were paired with (seconds).

    Returns
    -------
    keep : dict of camera name to (ndarray of bool, dict of index to reason)
        For the cameras that were chosen among: the images kept, and the reason of each one
        left out.
    summaries : dict of camera name to SelectionSummary
    """
    over = [n for n, p in paired.items() if len(p.observations) > budget]
    if not over:
        return {}, {}
    cells, lens = {}, {}
    for n in over:
        data = cameras[n]
        if data.intrinsics_estimated and data.intrinsics is not None:
            obs = paired[n].observations
            if all(o.image_points is not None for o in obs):
                cells[n] = grid_cells([o.image_points for o in obs], data.intrinsics.width,
                                      data.intrinsics.height)
                lens[n] = _lens_information(obs, data.intrinsics)
    stamps = {n: np.array([o.stamp for o in paired[n].observations]) + (offsets or {}).get(n, 0.0)
              for n in over}
    tol = default_sync_tolerance(list(stamps.values())) if sync_tolerance is None else sync_tolerance
    chosen = select_after_detection(stamps, {n: paired[n].T_world_mocap for n in over}, budget,
                                    cells=cells or None, lens=lens or None, sync_tolerance=tol)
    keep, summaries = {}, {}
    for n in over:
        sel = chosen[n]
        keep[n] = (sel.keep, {i: r for i, r in enumerate(sel.reasons)
                              if r.startswith(LEFT_OUT)})
        summaries[n] = SelectionSummary(budget=budget, seen=sel.n_seen, kept=sel.n_kept,
                                        stage="after detection")
    return keep, summaries
