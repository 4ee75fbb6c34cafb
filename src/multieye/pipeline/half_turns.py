"""A half-turn symmetric board's point order, decided by the rig's geometry.

A board that looks the same after a half turn (:mod:`multieye.imaging.order_turn`) is
detected in the order whose x axis points towards the image's lower right.  Two cameras
rolled apart by more than a quarter turn (a camera upside down, a ring of cameras, a
surround-view rig), or a board held at about 45 degrees in the image, take opposite orders
of the same board at the same instant, or one camera flips between frames.  Each such view
carries its other order: the pose ``T_cam_target @ H`` and the permutation of its image
points (:func:`offer_half_turn`, ``Observation.alternative`` and ``alternative_order``), and
the rig chooses:

- with motion capture, the consensus, as for a single marker's two PnP poses
  (:mod:`multieye.pipeline.ambiguity`); of the two choices that differ by turning every
  view (the board's frame, a gauge), the one that turns fewer views is kept
  (:func:`fewest_turns`);
- without motion capture, the views of one instant are made to agree under the link's
  estimate (:func:`multieye.estimate.half_turns.choose_turns`, in
  :func:`multieye.pipeline.overlap.solve_overlap`).

A view chosen in its other order is :func:`turned`: its pose, its RMS and its image points
become the other order's, so the refinement and the outputs all see one order.
:func:`turn_warning` says how many views were turned.

Synopsis
--------
>>> obs = offer_half_turn(obs, target)                         # doctest: +SKIP
>>> obs = turned(obs)                                          # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from multieye.imaging.order_turn import half_turn, turn_order
from multieye.imaging.targets import Target

__all__ = ["offer_half_turn", "turned", "turnable", "fewest_turns", "turn_warning",
           "turn_views", "half_turn_of"]


def half_turn_of(observation) -> np.ndarray | None:
    """``T_target_turned`` of a view that carries its other order (``inv(T_cam_target) @
    alternative``), else None."""
    if getattr(observation, "alternative_order", None) is None:
        return None
    T = np.asarray(observation.T_cam_target, dtype=np.float64)
    return np.linalg.solve(T, np.asarray(observation.alternative, dtype=np.float64))


def offer_half_turn(observation, target: Target | None):
    """``observation`` (a :class:`~multieye.pipeline.camera_data.Observation`) with its
    other order as its ``alternative`` when ``target`` looks the same after a half turn and
    the view holds points the turn maps onto each other; else unchanged (also when PnP
    already gave it a second pose)."""
    turn = None if target is None else half_turn(target)
    if (turn is None or observation.alternative is not None
            or observation.image_points is None or observation.object_points is None):
        return observation
    order = turn_order(observation.object_points, turn.T_target_turned)
    if order is None:
        return observation
    return replace(observation, alternative=observation.T_cam_target @ turn.T_target_turned,
                   alternative_rms_px=observation.rms_px, alternative_order=order)


def turned(observation):
    """The observation in its other order: pose and RMS swapped with the alternative's and,
    for a board's other point order, its image points permuted (turning again restores
    it)."""
    o = observation
    out = replace(o, T_cam_target=o.alternative, alternative=o.T_cam_target,
                  rms_px=o.alternative_rms_px, alternative_rms_px=o.rms_px)
    if o.alternative_order is None:
        return out
    order = np.asarray(o.alternative_order)
    return replace(out, image_points=np.asarray(o.image_points)[order],
                   alternative_order=np.argsort(order))


def turnable(observations: Sequence) -> np.ndarray:
    """Per observation: does it carry a board's other point order?  Shape (n,), bool."""
    return np.array([getattr(o, "alternative_order", None) is not None for o in observations],
                    dtype=bool)


def fewest_turns(observations: Sequence[Sequence], choices: Sequence[np.ndarray],
                 kept: Sequence[np.ndarray] | None = None) -> list[np.ndarray]:
    """Per camera the views to turn, of the two choices that agree alike with one board.

    Turning every view of one board changes only the board's frame (``Y`` with motion
    capture: ``A X = (Y H) (H B)``), so ``choices`` and the choices with every turnable view
    toggled fit alike; the one turning fewer of the ``kept`` views is returned (ties: the
    given one).  Views of several boards are left as given.

    Parameters
    ----------
    observations : sequence of sequence of Observation
        Per camera.
    choices : sequence of ndarray of bool
        Per camera, the views whose alternative was chosen.
    kept : sequence of ndarray of bool, optional
        Per camera the views kept (default all).
    """
    can = [turnable(obs) for obs in observations]
    boards = {o.target for obs, c in zip(observations, can) for o, t in zip(obs, c) if t}
    choices = [np.asarray(c, dtype=bool) for c in choices]
    if len(boards) != 1:
        return choices
    kept = kept if kept is not None else [np.ones(len(c), bool) for c in choices]
    total = sum(int(np.sum(c & k)) for c, k in zip(can, kept))
    turns = sum(int(np.sum(ch & c & k)) for ch, c, k in zip(choices, can, kept))
    if 2 * turns > total:
        return [ch ^ c for ch, c in zip(choices, can)]
    return choices


def turn_views(cameras: Mapping, turn: Mapping[str, np.ndarray]) -> dict:
    """``cameras`` (name -> CameraData) with the observations ``turn[name]`` marks
    :func:`turned`."""
    out = {}
    for n, d in cameras.items():
        mask = np.asarray(turn.get(n, ()), dtype=bool)
        if not mask.any():
            out[n] = d
            continue
        obs = tuple(turned(o) if t else o for o, t in zip(d.observations, mask))
        out[n] = replace(d, observations=obs)
    return out


def turn_warning(observations: Mapping[str, Sequence], turns: Mapping[str, np.ndarray],
                 how: str) -> tuple[str, ...]:
    """The line saying how many views of a half-turn symmetric board the rig turned
    (``how``: by what), or nothing when no view carries a board's other order.

    Parameters
    ----------
    observations : mapping of str to sequence of Observation
        Per camera, the views used.
    turns : mapping of str to ndarray of bool
        Per camera, which of them were turned.
    how : str
        What decided, e.g. ``"the consensus with the motion capture"``.
    """
    can = {n: turnable(o) for n, o in observations.items()}
    total = sum(int(c.sum()) for c in can.values())
    if not total:
        return ()
    per = {n: int(np.sum(np.asarray(turns.get(n, np.zeros(len(c), bool)), bool) & c))
           for n, c in can.items()}
    n_turned = sum(per.values())
    detail = ", ".join(f"{n} {k}" for n, k in per.items() if k)
    return (f"half-turn symmetric board: {n_turned} of {total} views were turned to the other "
            f"point order, decided by {how}" + (f" ({detail})" if detail else ""),)
