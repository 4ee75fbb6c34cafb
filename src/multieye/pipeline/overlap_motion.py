"""A rig without motion capture moved in front of several boards (issue 34).

When the cameras' images show several boards (rig.yaml's ``targets:``), the cameras are
linked by the views they share *and* by the rig's motion: the boards stand still, so a board
one camera sees at one instant and another camera at another instant ties the two through
the rig's poses at those instants (:mod:`multieye.estimate.motion_links`).  Stages, keyed by
camera name like :mod:`multieye.pipeline.overlap`:

1. instants: as :func:`multieye.pipeline.overlap.observation_instants` (one image showing two
   boards: two views at one instant); each image of a camera's ``intrinsics_images`` an
   instant of its own;
2. solve: every ``T_ref_cam``, every board's pose (the first board of rig.yaml seen is the
   world), the rig's pose per instant and the lenses estimated from the recording, started
   from the loops the views close and the joint hand-eye problem, refined on the pixels
   (:func:`multieye.estimate.refine_motion.refine_motion`); cameras nothing links are
   refused (one line naming them and what would link them);
3. checks: the ``fit`` check of :mod:`multieye.pipeline.overlap`, and the directions the
   motion leaves undetermined (:mod:`multieye.estimate.observability`; cause
   ``observability``, exit status 3: a rig driven on a floor whose cameras each see their
   own boards has every camera's height undetermined).

Synopsis
--------
>>> sol = solve_motion(cameras, reference="cam0", boards=("north", "west"))  # doctest: +SKIP
>>> sol.result.T_ref_cam, sol.links["cam2"].describe()                      # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from multieye.core import geometry as g
from multieye.estimate.findings import Finding
from multieye.estimate.motion_residuals import MotionViews
from multieye.estimate.observability import Observability, observability
from multieye.estimate.refine_motion import MotionResult, refine_motion
from multieye.io.calibration_json import CameraLinks
from multieye.pipeline.camera_data import CameraData
from multieye.pipeline.overlap import (
    _check_images,
    _fit_findings,
    _rig_warnings,
    observation_instants,
)

__all__ = ["MotionSolution", "solve_motion", "target_of", "board_order"]


def target_of(observation) -> str:
    """The board an observation shows (``"target"`` for rig.yaml's one ``target:``)."""
    return observation.target


def board_order(cameras: Mapping[str, CameraData], declared: Sequence[str] = ()) -> tuple:
    """The boards the cameras saw: those of ``declared`` (rig.yaml's order) first, then any
    other in the order first seen.  The first is the world."""
    seen = dict.fromkeys(target_of(o) for d in cameras.values() for o in d.observations)
    return tuple([b for b in declared if b in seen] + [b for b in seen if b not in declared])


@dataclass(frozen=True)
class MotionSolution:
    """The rig solved from the views of several boards.

    Attributes
    ----------
    names : tuple of str
    reference : str
    boards : tuple of str
        Board names in the order of the result's ``T_world_board`` (the first is the world).
    result : MotionResult
    views : MotionViews
    used : dict of str to tuple of Observation
    instants : dict of str to ndarray of int
        The instant of each used observation.
    board : dict of str to ndarray of int
        The board of each used observation.
    links : dict of str to CameraLinks
    observability : Observability
    sync_tolerance : float
    findings, warnings : tuple
    """

    names: tuple[str, ...]
    reference: str
    boards: tuple[str, ...]
    result: MotionResult
    views: MotionViews
    used: dict
    instants: dict
    board: dict
    links: dict
    observability: Observability
    sync_tolerance: float
    findings: tuple = ()
    warnings: tuple = ()

    def T_ref_target(self, name: str) -> np.ndarray:
        """The board of each used observation of camera ``name`` in the rig's frame at its
        instant, (n, 4, 4)."""
        res = self.result
        return g.inv(res.T_world_rig[self.instants[name]]) @ res.T_world_board[self.board[name]]


def _links(sol_views: MotionViews, result: MotionResult, boards: Sequence[str]
           ) -> dict[str, CameraLinks]:
    """Per camera: the cameras it saw one board with at one instant (how many times), and the
    cameras and boards that gave the rig's pose when the motion placed it."""
    v = sol_views
    names = v.names
    seen = {}
    for c, t, b in zip(v.camera, v.instant, v.board):
        seen.setdefault((int(t), int(b)), set()).add(int(c))
    out = {}
    for j, n in enumerate(names):
        shared: dict[str, int] = {}
        for together in seen.values():
            if j in together:
                for k in sorted(together - {j}):
                    shared[names[k]] = shared.get(names[k], 0) + 1
        link = result.start.links[j]
        motion = ((tuple(names[c] for c in link.cameras), tuple(boards[b] for b in link.boards))
                  if link.kind == "motion" and link.cameras else ())
        mine = np.bincount(v.board[v.camera == j], minlength=len(boards))
        out[n] = CameraLinks(shared, False, motion,
                             {boards[b]: int(c) for b, c in enumerate(mine) if c})
    return out


def _observability_findings(obs: Observability) -> tuple[Finding, ...]:
    return tuple(Finding("observability", u.message, u.camera, u.sigma / u.best_sigma, 1.0,
                         {"sigma": u.sigma, "best_sigma": u.best_sigma,
                          "direction_rig": [float(x) for x in u.direction_rig]})
                 for u in obs.undetermined)


def solve_motion(cameras: Mapping[str, CameraData], reference: str, *,
                 sync_tolerance: float | None = None, sync: str = "time", robust: bool = True,
                 boards: Sequence[str] = (), mocap: Callable | None = None) -> MotionSolution:
    """Calibrate the rig from views of several still boards (module docstring).

    Parameters
    ----------
    cameras : mapping of str to CameraData
        Cameras with images, in rig.yaml's order; no motion capture.
    reference : str
    sync_tolerance : float, optional
        Seconds; default a quarter of the shortest interval between two images of a camera.
    sync : {"time", "name", "number", "order"}
        rig.yaml's ``sync``: what makes images of different cameras one instant
        (:func:`multieye.pipeline.overlap.observation_instants`).
    robust : bool
        Huber loss on the pixels (else least squares).
    boards : sequence of str
        rig.yaml's board names in order (the first one seen is the world).
    mocap : callable, optional
        The rig's motion capture: called with the instants (dict of camera name to the
        instant of each observation), returns a
        :class:`~multieye.estimate.motion_mocap.RigMocap` at those instants
        (:func:`multieye.pipeline.overlap_mocap.rig_mocap`), refined with the views.

    Raises
    ------
    DatasetError
        A camera given by poses (no board points).
    DisconnectedError
        Cameras that neither overlap nor the rig's motion links (one line naming them).
    """
    _check_images(cameras)
    names = tuple(cameras)
    order = board_order(cameras, boards)
    inst, n_inst, tol = observation_instants(cameras, sync_tolerance, sync)
    views, poses, extra = [], [], n_inst
    which = {}
    for n in names:
        d = cameras[n]
        which[n] = np.array([order.index(target_of(o)) for o in d.observations], dtype=np.int64)
        vs = [(o.object_points, o.image_points, int(t), int(b))
              for o, t, b in zip(d.observations, inst[n], which[n])]
        poses += [o.T_cam_target for o in d.observations]
        for o in (d.intrinsics_views if d.intrinsics_estimated else ()):
            vs.append((o.object_points, o.image_points, extra, order.index(target_of(o))
                       if target_of(o) in order else 0))
            poses.append(o.T_cam_target)
            extra += 1
        views.append(vs)
    mv = MotionViews(dict(zip(names, views)), [cameras[n].intrinsics for n in names],
                     names.index(reference),
                     free_intrinsics=[cameras[n].intrinsics_estimated for n in names])
    result = refine_motion(mv, np.stack(poses), loss="huber" if robust else "linear",
                           mocap=None if mocap is None else mocap(inst))
    obs = observability(result, mv)
    findings = _fit_findings(cameras, mv, result) + _observability_findings(obs)
    return MotionSolution(
        names=names, reference=reference, boards=order, result=result, views=mv,
        used={n: cameras[n].observations for n in names}, instants=inst, board=which,
        links=_links(mv, result, order), observability=obs, sync_tolerance=tol,
        findings=findings, warnings=_rig_warnings(cameras, mv, result))
