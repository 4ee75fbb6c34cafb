"""The dry run of a rig with several boards (rig.yaml ``targets:``, issue 34): which boards
each camera found in its sampled images, and what links each camera to the reference camera.

:func:`boards_found` counts, per board, the sampled images in which a camera found it (the
results of :class:`~multieye.imaging.boards.Boards`, or of a camera's single board).
:func:`motion_links` follows the growth rule of the calibration's start
(:mod:`multieye.estimate.motion_growth`, which
:func:`multieye.estimate.motion_links.motion_start` follows with the poses) on the sampled
detections alone, without poses: from the reference camera and the board it sees most, an
instant is placed when a placed camera sees a placed board then, a board when a placed camera
sees it at a placed instant, and a camera when it sees a placed board at a placed instant or
any board at a placed instant (the hand-eye step, taken to succeed); a camera is linked by
*overlap* when another camera saw one of its boards at one of its instants, else by *motion*
(:func:`multieye.estimate.motion_growth.link_of`, every other placed camera's views giving
the instants).  The calibration may still find the motion too poor
(turned about one axis); it never links a camera this leaves apart.
:func:`one_axis_problems` says beforehand when the sampled views of the reference camera show
the rig turned about one axis only (with the lens given: the board poses), which leaves the
cameras linked by the motion alone partly undetermined (calibrating doubts them, exit 3).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from multieye.core import geometry as g
from multieye.estimate.motion_growth import Link, link_of, reached
from multieye.estimate.observability import one_axis_advice, turn_axis
from multieye.imaging.pnp import collinear

__all__ = ["boards_found", "motion_links", "posed_boards", "one_axis_problems"]


def boards_found(results: Sequence, looked_for: tuple[str, ...]) -> list[tuple[str, ...]]:
    """Per sampled image, the names of the boards found in it and usable (posable).

    Parameters
    ----------
    results : sequence of ImageResult
        One per image; with several boards, one per board inside (``parts``).
    looked_for : tuple of str
        The boards looked for (:func:`multieye.pipeline.boards.camera_boards`).
    """
    return [tuple(n for n, p in (r.parts or ((looked_for[0], r),)) if _posable(p))
            for r in results]


def _posable(r) -> bool:
    """A usable detection that also gives a pose: 4 points or more not on one line (those
    on one line, a ChArUco board's single column, are refused by PnP once the lens is
    known: without a lens the dry run leaves them out as calibrating will)."""
    if r.reason is not None or r.detection is None:
        return False
    obj = np.asarray(r.detection.object_points, np.float64)
    return len(obj) >= 4 and not collinear(obj[:, :2])


def motion_links(labels: Sequence[str], views: Sequence[tuple[int, int, str]]
                 ) -> list[str]:
    """``<camera> linked by: ...`` for every camera (module docstring).

    Parameters
    ----------
    labels : sequence of str
        Camera names; the first is the reference camera.
    views : sequence of (int, int, str)
        Camera index, instant and board of every sampled detection.

    Returns
    -------
    list of str
        Per camera ``reference camera``, ``overlap with cam1 (3 instants); motion via cam0
        and boards north, west`` or ``nothing (...)``.
    """
    own = [b for c, _, b in views if c == 0]
    if not own:
        return [f"{labels[0]} linked by: nothing (the reference camera saw no board in the "
                "sampled images)"] + [f"{n} linked by: nothing" for n in labels[1:]]
    camera, instant, board = (list(x) for x in zip(*views))
    cams, insts, _ = reached(camera, instant, board, 0, {max(set(own), key=own.count)})
    lines = [f"{labels[0]} linked by: reference camera"]
    for j in range(1, len(labels)):
        if j not in cams:
            lines.append(f"{labels[j]} linked by: nothing (no sampled image with a board at "
                         "an instant when a linked camera sees one)")
            continue
        link, shared = _link(j, views, cams, insts)
        how = "motion"
        if link.kind == "overlap":
            how = "overlap with " + ", ".join(
                f"{labels[c]} ({shared[c]}{' instants' if i == 0 else ''})"
                for i, c in enumerate(link.cameras))
        elif link.cameras:
            how = (f"motion via {', '.join(labels[c] for c in link.cameras)} and "
                   f"board{'s' * (len(link.boards) > 1)} {', '.join(link.boards)}")
        lines.append(f"{labels[j]} linked by: {how}")
    return lines


def _link(j: int, views: Sequence[tuple[int, int, str]], cams: set, insts: set
          ) -> tuple[Link, dict[int, int]]:
    """What links placed camera ``j`` (:func:`multieye.estimate.motion_growth.link_of`), its
    instants given by every other placed camera's views then, and per other camera how many
    of its views share an instant and a board with ``j``'s."""
    mine = {(t, b) for c, t, b in views if c == j and t in insts}
    placers: dict[int, set] = {}
    shared: dict[int, int] = {}
    for c, t, b in views:
        if c != j and c in cams and t in insts:
            placers.setdefault(t, set()).add((c, b))
        if c != j and (t, b) in mine:
            shared[c] = shared.get(c, 0) + 1
    return link_of(mine, placers), shared


def posed_boards(result, looked_for: tuple[str, ...]) -> list[tuple[str, np.ndarray]]:
    """The boards of one sampled image's result that have a pose (the lens given), with
    ``T_cam_board``: ``[(board, (4, 4) array), ...]``."""
    return [(n, np.asarray(p.pose.T_cam_target, dtype=np.float64))
            for n, p in (result.parts or ((looked_for[0], result),))
            if _posable(p) and p.pose is not None]


def one_axis_problems(labels: Sequence[str], views: Sequence[tuple[int, int, str]],
                      reference_poses: Sequence, given: frozenset = frozenset()
                      ) -> dict[str, tuple[str, ...]]:
    """Per camera the problem line when the reference camera's sampled views of the board it
    saw most (``reference_poses``: ``(index, board, T_cam_board)``, at least 4 views) show the
    rig turned about one axis only (:func:`multieye.estimate.observability.turn_axis`, the
    calibration's own test) and the camera is apart from the reference camera's boards: no
    chain of boards seen by both cameras joins them in the sampled views (``views``: camera
    index, instant, board).  Such a camera and its boards shift together along the axis
    without changing a pixel (docs/results/motion_links.md, observability); cameras whose
    boards the others see too are determined by planar motion, and so are those that see a
    board whose pose rig.yaml gives (``given``: held in the world).  Else nothing."""
    boards = [b for _, b, _ in reference_poses]
    if not boards:
        return {}
    main = max(set(boards), key=boards.count)
    T = [g.inv(T) for _, b, T in reference_poses if b == main]     # T_board_ref
    axis = turn_axis(np.stack(T)) if len(T) >= 4 else None
    if axis is None:
        return {}
    joined, grew = {0}, True                  # cameras joined to the reference by boards
    while grew:
        seen_by = {b for c, _, b in views if c in joined} | set(given)
        more = {c for c, _, b in views if b in seen_by} - joined
        joined |= more
        grew = bool(more)
    return {labels[j]: (
        "the sampled views show the rig turned about one axis only, and no board this camera "
        f"sees is seen by {labels[0]} or a camera that shares one with it: its position along "
        "that axis would be undetermined (calibrating doubts it, exit status 3); "
        + one_axis_advice(axis),)
        for j in range(1, len(labels)) if any(c == j for c, _, _ in views) and j not in joined}
