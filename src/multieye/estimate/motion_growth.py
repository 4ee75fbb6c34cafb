"""The growth rule of a rig linked by its own motion in front of still boards, on the views'
indices alone: which instant, board and camera gets placed next, and what placed a camera
(overlap or motion).  :func:`multieye.estimate.motion_links.motion_start` follows it with the
poses; ``multieye check`` (:func:`multieye.pipeline.dry_run_boards.motion_links`) follows it
on the sampled detections, which have none.

A view is ``(camera, instant, board)``: camera ``camera[v]`` saw board ``board[v]`` at
instant ``instant[v]``.  From what is placed (the reference camera and the boards the growth
starts from):

1. *chaining*, one round (:func:`chain_round`): the instants at which a placed camera sees a
   placed board; then the boards a placed camera sees at a placed instant (those just placed
   included); then the cameras that see a placed board at a placed instant.  Rounds follow
   until one places nothing;
2. *hand-eye*: the views of unplaced cameras at placed instants whose boards are unplaced
   too (:func:`hand_eye_views`) may place those cameras and boards together (the joint
   hand-eye problem, when the rig's motion determines it); then back to 1.

:func:`reached` is what the growth places when every hand-eye step succeeds.  What placed a
camera (:func:`link_of`): *overlap* when, at an instant it saw a board, another camera that
gave that instant saw the same board; else *motion*, through the cameras and boards that gave
the instants.

Synopsis
--------
>>> r = chain_round(camera, instant, board, cams={0}, insts=set(), boards={0})  # doctest: +SKIP
>>> r.instants, r.boards, r.cameras                                             # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Collection, Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass

__all__ = ["Link", "Round", "chain_round", "hand_eye_views", "link_of", "reached"]


@dataclass(frozen=True)
class Link:
    """What placed a camera: ``kind`` ``"reference"``, ``"overlap"`` (``cameras`` saw the
    same board at the same instants) or ``"motion"`` (the rig's pose at the instants came
    from ``cameras`` seeing ``boards``)."""

    kind: str
    cameras: tuple[int, ...] = ()
    boards: tuple[int, ...] = ()


@dataclass(frozen=True)
class Round:
    """What one round of chaining places, each with the indices of the views that place it
    (in view order).

    Attributes
    ----------
    instants : dict of instant to list of int
        Instants at which a placed camera sees a placed board.
    boards : dict of board to list of int
        Boards a placed camera sees at a placed instant (``instants`` included).
    cameras : dict of camera to list of int
        Cameras that see a placed board (``boards`` included) at a placed instant.
    """

    instants: dict
    boards: dict
    cameras: dict

    def __bool__(self) -> bool:
        return bool(self.instants or self.boards or self.cameras)


def _views(views: tuple[Sequence, Sequence, Sequence], placed: tuple[Collection, ...],
           known: tuple[bool, bool, bool]) -> list[int]:
    """The views whose camera, instant and board are placed (or not) as ``known`` says."""
    camera, instant, board = views
    cams, insts, boards = placed
    kc, ki, kb = known
    return [v for v in range(len(camera))
            if (camera[v] in cams) == kc and (instant[v] in insts) == ki
            and (board[v] in boards) == kb]


def _by(key: Sequence, views: list[int]) -> dict:
    out: dict = {}
    for v in views:
        out.setdefault(key[v], []).append(v)
    return out


def chain_round(camera: Sequence, instant: Sequence, board: Sequence, cams: Collection,
                insts: Collection, boards: Collection) -> Round:
    """One round of step 1 of the module docstring.

    Parameters
    ----------
    camera, instant, board : sequence of hashable, length n_views
        Each view's camera, instant and board.
    cams, insts, boards : collection
        What is placed (sets, or dicts keyed by it).
    """
    vw = (camera, instant, board)
    new_i = _by(instant, _views(vw, (cams, insts, boards), (True, False, True)))
    insts = set(insts) | set(new_i)
    new_b = _by(board, _views(vw, (cams, insts, boards), (True, True, False)))
    boards = set(boards) | set(new_b)
    new_c = _by(camera, _views(vw, (cams, insts, boards), (False, True, True)))
    return Round(new_i, new_b, new_c)


def hand_eye_views(camera: Sequence, instant: Sequence, board: Sequence, cams: Collection,
                   insts: Collection, boards: Collection) -> list[int]:
    """The views step 2 of the module docstring works from: an unplaced camera seeing an
    unplaced board at a placed instant (parameters as :func:`chain_round`)."""
    return _views((camera, instant, board), (cams, insts, boards), (False, True, False))


def reached(camera: Sequence, instant: Sequence, board: Sequence, reference: Hashable,
            seed: Iterable) -> tuple[set, set, set]:
    """The cameras, instants and boards the growth from camera ``reference`` and the boards
    ``seed`` places when every hand-eye step succeeds (module docstring).

    Returns
    -------
    cams, insts, boards : set
    """
    cams, insts, boards = {reference}, set(), set(seed)
    while True:
        r = chain_round(camera, instant, board, cams, insts, boards)
        if not r:
            rest = hand_eye_views(camera, instant, board, cams, insts, boards)
            if not rest:
                return cams, insts, boards
            r = Round({}, {board[v]: [v] for v in rest}, {camera[v]: [v] for v in rest})
        cams |= set(r.cameras)
        insts |= set(r.instants)
        boards |= set(r.boards)


def link_of(seen: Iterable[tuple[Hashable, Hashable]],
            placers: Mapping[Hashable, Collection[tuple[Hashable, Hashable]]]) -> Link:
    """What placed a camera (module docstring).

    Parameters
    ----------
    seen : iterable of (instant, board)
        The camera's views that placed it.
    placers : mapping of instant to collection of (camera, board)
        Per instant the other cameras' views that gave it.

    Returns
    -------
    Link
        ``"overlap"`` with the cameras that saw one of the camera's boards at its instant,
        else ``"motion"`` with the cameras and boards that gave its instants (each sorted,
        as given: indices, or the names of the dry run's boards).
    """
    over, via_c, via_b = set(), set(), set()
    for t, b in seen:
        by = placers.get(t, set())
        same = {c for c, bb in by if bb == b}
        over |= same
        if not same:
            via_c |= {c for c, _ in by}
            via_b |= {bb for _, bb in by}
    if over:
        return Link("overlap", tuple(sorted(over)))
    return Link("motion", tuple(sorted(via_c)), tuple(sorted(via_b)))
