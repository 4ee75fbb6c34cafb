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

Each camera's :class:`SelectionSummary` goes to ``details.json`` and the screen; each image
left out is a :class:`~multieye.io.RejectedItem` with its reason.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

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
from multieye.io import RejectedItem, Rig, bag_image_count, list_images
from multieye.pipeline.frames import bag_listing, video_listing
from multieye.solvers.methods import MIN_MEASUREMENTS

__all__ = ["SelectionSummary", "preselect", "preselected", "motion_first", "select_paired",
           "merged"]


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
    """

    budget: int
    seen: int
    kept: int
    stage: str
    without_mocap: int = 0

    def as_dict(self) -> dict:
        return {"budget": self.budget, "seen": self.seen, "kept": self.kept, "stage": self.stage,
                "without_mocap": self.without_mocap}

    def line(self, camera: str) -> str:
        """``cam0: 300 of 5400 images selected before decoding (budget 300)``."""
        extra = (f"; {self.without_mocap} without motion capture not decoded"
                 if self.without_mocap else "")
        return (f"{camera}: {self.kept} of {self.seen} images selected {self.stage} "
                f"(budget {self.budget}{extra})")


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
                            without_mocap=before.without_mocap)


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
    dict of camera name to (list, list of RejectedItem, SelectionSummary)
        The images to detect, those left out with their reason, and the summary; a camera
        with fewer than 3 images paired is not in it (it detects every image, and the
        pairing says why it fails).
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
            [name_ids.setdefault(Path(f.name).stem, len(name_ids)) for _, _, f in listed],
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
            out[n] = (kept, left, SelectionSummary(
                budget=b, seen=len(listed), kept=len(kept), stage="before decoding",
                without_mocap=len(listed) - len(paired[n])))
    return out


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
               or (cam.source == "images" and _over(cam, _budget(cam, select)))
               for cam in rig.cameras.values())


def _over(cam, budget: int) -> bool:
    """Whether a camera's image folder holds more images than ``budget``; not listed when it
    holds no more entries than that (a folder that cannot be read is listed: its error
    then)."""
    try:
        if len(os.listdir(cam.images)) <= budget:
            return False
    except OSError:
        pass
    return len(list_images(cam.images, cam.images_pattern)) > budget


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
            listed = list_images(cam.images, cam.images_pattern)
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
