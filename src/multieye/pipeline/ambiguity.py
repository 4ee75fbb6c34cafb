"""Two poses per image: the mirrored PnP poses of a single planar marker, chosen by the rig.

Four coplanar corners (one ArUco marker, one AprilTag) have two poses that fit almost
equally (:attr:`multieye.imaging.pnp.PoseEstimate.alternative`); PnP picks the mirrored
one in many images. The pipeline carries both to the consensus
(:func:`multieye.estimate.consensus.consensus`, ``B_alternative``), or, without consensus
(``robust=False``), lets the closed form choose (:func:`closed_form_choice`); the pose
chosen becomes the observation's ``T_cam_target`` (and its row of ``B``), the other its
``alternative``, so the closed form, the plausibility checks, the refinement and the outputs
all see the chosen one.

Synopsis
--------
>>> B_alt = alternatives(paired.values())                          # doctest: +SKIP
>>> paired = {n: with_choice(p, mask) for (n, p), mask in zip(...)}  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import numpy as np

from multieye.core import geometry as g
from multieye.estimate.consensus import choose_poses
from multieye.pipeline.camera_data import PairedCamera
from multieye.pipeline.half_turns import fewest_turns, turned
from multieye.solvers import solve
from multieye.solvers.checks import Measurements

__all__ = ["alternatives", "with_choice", "closed_form_choice"]


def alternatives(paired: Iterable[PairedCamera]) -> list[np.ndarray] | None:
    """Per camera the second ``T_target_cam`` of each measurement (rows of NaN where none),
    shaped like its ``B``; None when no measurement of any camera has one."""
    out = [_second_poses(p) for p in paired]
    return out if any(np.isfinite(a[:, 0, 0]).any() for a in out) else None


def _second_poses(p: PairedCamera) -> np.ndarray:
    alt = np.full_like(p.B, np.nan)
    for i, o in enumerate(p.observations):
        if o.alternative is not None:
            alt[i] = g.inv(o.alternative)
    return alt


def with_choice(p: PairedCamera, choice: np.ndarray) -> PairedCamera:
    """``p`` with the measurements where ``choice`` (shape (n,), bool) on their second pose:
    that pose (and its RMS) becomes ``T_cam_target`` and the row of ``B``, the first its
    ``alternative``; a half-turn symmetric board's view takes the other order's image points
    too (:func:`multieye.pipeline.half_turns.turned`)."""
    choice = np.asarray(choice, dtype=bool)
    if not choice.any():
        return p
    obs = list(p.observations)
    B = p.B.copy()
    for i in np.flatnonzero(choice):
        obs[i] = turned(obs[i])
        B[i] = g.inv(obs[i].T_cam_target)
    return replace(p, B=B, observations=tuple(obs))


def kept_measurements(meas: Measurements, cons, paired: dict[str, PairedCamera],
                      choices=None) -> Measurements:
    """The measurements the consensus ``cons`` kept, each with the pose chosen (``paired``:
    the cameras after :func:`with_choice` and the inlier selection; ``choices``: per camera
    the measurements on their second pose, default the consensus's)."""
    choices = cons.alternative if choices is None else choices
    if not any(np.any(c) for c in choices):
        return meas.select(cons.inliers)
    return replace(Measurements.from_cameras([p.A for p in paired.values()],
                                             [p.B for p in paired.values()]),
                   names=tuple(paired))


def closed_form_choice(paired: dict[str, PairedCamera], meas: Measurements, method: str,
                       *, rounds: int = 5) -> tuple[dict[str, PairedCamera], Measurements,
                                                   dict[str, np.ndarray]]:
    """Without consensus: solve, choose per image the pose that agrees better with ``X``,
    ``Y`` (:func:`multieye.estimate.consensus.choose_poses`), solve again, until the choice
    no longer changes (at most ``rounds`` times); a half-turn symmetric board's views then
    turned the way that turns fewer of them (:func:`multieye.pipeline.half_turns.fewest_turns`).

    Parameters
    ----------
    paired : dict of str to PairedCamera
    meas : Measurements
        Their ``A``, ``B`` (first poses), in the order of ``paired``.
    method : str
        The closed form (:func:`multieye.solvers.solve`).

    Returns
    -------
    paired, meas
        With the chosen poses; the same objects when there are no second poses.
    turns : dict of str to ndarray of bool
        Per camera, the measurements on their second pose.
    """
    turns = {n: np.zeros(len(p.observations), dtype=bool) for n, p in paired.items()}
    if alternatives(paired.values()) is None:
        return paired, meas, turns
    paired, names = dict(paired), list(paired)
    for _ in range(rounds):
        sol = solve(meas, method=method)
        X, Y = sol.X, sol.Y
        changed = False
        for j, n in enumerate(names):
            p = paired[n]
            choice = choose_poses(p.A, p.B, _second_poses(p), X[j], Y)
            if choice.any():
                paired[n] = with_choice(p, choice)
                turns[n] ^= choice
                changed = True
        if not changed:
            break
        meas = _rebuilt(paired)
    fewest = fewest_turns([paired[n].observations for n in names], [turns[n] for n in names])
    if any(np.any(f != turns[n]) for f, n in zip(fewest, names)):
        # the views' alternatives are now the detected orders: toggling back the others
        paired = {n: with_choice(paired[n], f != turns[n]) for f, n in zip(fewest, names)}
        turns = dict(zip(names, fewest))
        meas = _rebuilt(paired)
    return paired, meas, turns


def _rebuilt(paired: dict[str, PairedCamera]) -> Measurements:
    return replace(Measurements.from_cameras([p.A for p in paired.values()],
                                             [p.B for p in paired.values()]),
                   names=tuple(paired))
