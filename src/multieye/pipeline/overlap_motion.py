"""A rig without motion capture moved in front of several boards (issue 34).

When the cameras' images show several boards (rig.yaml's ``targets:``), the cameras are
linked by the views they share *and* by the rig's motion: the boards stand still, so a board
one camera sees at one instant and another camera at another instant ties the two through
the rig's poses at those instants (:mod:`multieye.estimate.motion_links`).  Stages, keyed by
camera name like :mod:`multieye.pipeline.overlap`:

1. instants and views: :func:`multieye.pipeline.overlap.camera_views`, each view naming its
   board (one image showing two boards: two views at one instant); each image of a camera's
   ``intrinsics_images`` an instant of its own;
2. solve: every ``T_ref_cam``, every board's pose (the first board of rig.yaml seen is the
   world), the rig's pose per instant and the lenses estimated from the recording, started
   from the loops the views close and the joint hand-eye problem, refined on the pixels
   (:func:`multieye.estimate.refine_motion.refine_motion`); cameras nothing links are
   refused (one line naming them and what would link them).  A board whose pose rig.yaml
   gives (``pose:``, in the first board's frame) is held at it, not estimated;
3. checks: the ``fit`` check of :mod:`multieye.pipeline.overlap`, and the directions the
   motion leaves undetermined (:mod:`multieye.estimate.observability`; cause
   ``observability``, exit status 3: a rig driven on a floor whose cameras each see their
   own boards has every camera's height undetermined), and, with boards at given poses,
   whether the views agree with them: the rig solved again with those boards estimated
   (only the first board held), each given pose against that estimate and its covariance
   (cause ``given-pose``, exit status 3, naming the board, when ``e^T C^-1 e`` exceeds
   chi-square(6)'s 99.99 % quantile, :data:`GIVEN_POSE_CHI2`).

Synopsis
--------
>>> sol = solve_motion(cameras, reference="cam0", boards=("north", "west"))  # doctest: +SKIP
>>> sol.result.T_ref_cam, sol.links["cam2"].describe()                      # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import DegenerateMotionError, DisconnectedError
from multieye.core.lie import log_so3
from multieye.estimate.findings import Finding
from multieye.estimate.motion_repose import UnprojectableViewsError
from multieye.estimate.motion_residuals import MotionViews
from multieye.estimate.observability import Observability, observability
from multieye.estimate.refine_motion import MotionResult, refine_motion
from multieye.estimate.uncertainty import pose_std
from multieye.io import RejectedItem
from multieye.io.calibration_json import CameraLinks
from multieye.pipeline.camera_data import CameraData
from multieye.pipeline.overlap import (_fit_findings, _rig_warnings, camera_views,
                                       judged_on_refined_lens)

__all__ = ["MotionSolution", "solve_motion", "target_of", "board_order", "GIVEN_POSE_CHI2"]

#: A given board pose is doubted when its difference from the views' own estimate of it,
#: ``e^T C^-1 e`` (``C`` that estimate's covariance), exceeds this: chi-square(6)'s 99.99 %
#: quantile (``scipy.stats.chi2.ppf(0.9999, 6)``).
GIVEN_POSE_CHI2 = 27.856


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
    given : tuple of str
        The boards held at their given poses (rig.yaml's ``pose:``).
    world : str
        The board whose frame is the world: rig.yaml's first board (when seen or when given
        poses are in its frame), else the first board seen.
    rejected : dict of str to tuple of RejectedItem
        Per camera whose lens is estimated, what it leaves out once its images were judged
        on the refined lens (:func:`multieye.pipeline.overlap.judged_on_refined_lens`), and
        per camera with images left out as behind it wherever the rest places the rig, those
        too; empty otherwise.
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
    given: tuple = ()
    world: str = ""
    rejected: dict = field(default_factory=dict)

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
                 boards: Sequence[str] = (), mocap: Callable | None = None,
                 poses: Mapping[str, np.ndarray] | None = None) -> MotionSolution:
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
    poses : mapping of str to ndarray (4, 4), optional
        Board name -> its given pose in the first board's frame (rig.yaml's ``pose:``,
        ``T_<first>_<name>``, metres): held there, checked against the views (module
        docstring).

    Raises
    ------
    DatasetError
        A camera given by poses (no board points).
    DisconnectedError
        Cameras that neither overlap nor the rig's motion links (one line naming them).
    """
    once = _Judging(partial(_solve_once, reference=reference, sync_tolerance=sync_tolerance,
                            sync=sync, robust=robust, boards=boards, mocap=mocap, poses=poses))
    first = once(cameras)
    if not any(d.intrinsics_estimated for d in cameras.values()):
        return once.last
    # a camera whose lens is estimated: its images judged on the refined lens, as
    # solve_overlap does (bad fits on the starting lens taken back, outliers left out)
    judged, _, notes = judged_on_refined_lens(cameras, once, first)
    sol = once.last
    return replace(sol, warnings=tuple(sol.warnings) + tuple(notes), rejected={
        n: judged[n].rejected + tuple(r for r in sol.rejected.get(n, ())
                                      if r not in judged[n].rejected) for n in sol.names})


class _Judging:
    """``run(cameras) -> MotionSolution`` as the solve
    :func:`~multieye.pipeline.overlap.judged_on_refined_lens` calls (``(prepared, views,
    result)``), keeping the last solution it gave (``last``); the views keep the order they
    were detected in (no half-turn choice: a rig before several boards)."""

    def __init__(self, run: Callable):
        self.run, self.last = run, None

    def __call__(self, cameras):
        self.last = self.run(cameras)
        return None, self.last.views, self.last.result

    @staticmethod
    def ordered(cameras):
        return (cameras,)


#: At most this share of a camera's images is left out as unprojectable from the rest.
MAX_LEFT_OUT = 0.25
#: How many times the views a solve names as unprojectable from the rest
#: (:class:`~multieye.estimate.motion_repose.UnprojectableViewsError`) are left out and the
#: rig solved again.
_LEAVE_OUT_ROUNDS = 3


def _solve_once(cameras: Mapping[str, CameraData], **settings) -> MotionSolution:
    """One solve of :func:`solve_motion` on ``cameras``: the images whose board points
    stay unprojectable (behind the camera) wherever the rest places the rig left out, named
    in the warnings, and the rig solved without them (at most :data:`MAX_LEFT_OUT` of a
    camera's images, else the error stands)."""
    notes: list[str] = []
    left: dict[str, list[RejectedItem]] = {}
    for _ in range(_LEAVE_OUT_ROUNDS):
        try:
            sol = _solve_views(cameras, **settings)
        except UnprojectableViewsError as exc:
            names = _image_names(cameras, exc.views)
            if any(len(v) > MAX_LEFT_OUT * (len(cameras[n].observations)
                                            + len(cameras[n].intrinsics_views))
                   for n, v in names.items()):
                raise                   # not a few images: the rig does not hold together
            notes.append(f"images left out, {_BEHIND}: " + "; ".join(
                f"{n}: {', '.join(v)}" for n, v in names.items()))
            for n, v in names.items():
                left.setdefault(n, []).extend(RejectedItem(i, f"left out: {_BEHIND}") for i in v)
            cameras = _without(cameras, exc.views)
            continue
        break
    else:
        sol = _solve_views(cameras, **settings)
    return replace(sol, warnings=tuple(notes) + tuple(sol.warnings),
                   rejected={**sol.rejected, **{n: cameras[n].rejected + tuple(v)
                                                for n, v in left.items()}})


#: Why an image is left out as unprojectable from the rest (its warning and its rejection).
_BEHIND = ("its board points behind the camera wherever the other images place the rig, the "
           "boards and the cameras (a wrong board or instant?)")


def _listed(cameras: Mapping[str, CameraData]) -> list[tuple[str, int, str]]:
    """Every view as :func:`~multieye.pipeline.overlap.camera_views` lists them (camera by
    camera: its observations, then its lens's own images): camera, index among the
    camera's observations and lens images, ``"image (board)"``."""
    return [(n, i, f"{o.name} ({o.target})") for n, d in cameras.items()
            for i, o in enumerate(d.observations
                                  + (d.intrinsics_views if d.intrinsics_estimated else ()))]


def _image_names(cameras: Mapping[str, CameraData], which) -> dict[str, list[str]]:
    """Per camera ``"image (board)"`` of the views ``which``."""
    listed = _listed(cameras)
    out: dict[str, list[str]] = {}
    for v in sorted(int(w) for w in which):
        out.setdefault(listed[v][0], []).append(listed[v][2])
    return out


def _without(cameras: Mapping[str, CameraData], which) -> dict:
    """``cameras`` without the views ``which``."""
    listed = _listed(cameras)
    drop: dict[str, set] = {}
    for v in which:
        drop.setdefault(listed[int(v)][0], set()).add(listed[int(v)][1])
    out = {}
    for n, d in cameras.items():
        k = len(d.observations)
        out[n] = replace(d, observations=tuple(
            o for i, o in enumerate(d.observations) if i not in drop.get(n, ())),
            intrinsics_views=tuple(o for i, o in enumerate(d.intrinsics_views)
                                   if i + k not in drop.get(n, ()))) if n in drop else d
    return out


def _reposed_note(cameras: Mapping[str, CameraData], result: MotionResult
                  ) -> tuple[str, ...]:
    """Warnings naming the images the start left unprojectable, and those a first
    refinement left far off, at a local optimum (each solved without first, then brought
    back: :mod:`multieye.estimate.motion_repose`)."""
    out = []
    for which, what in ((result.reposed, "the start put board points of some images behind "
                         "the camera (a PnP pose far off, placing the rest wrongly); the rig "
                         "was solved without them first, then with them from there"),
                        (result.second_look, "a first solve stopped at a local optimum with "
                         "some images far off (its start placed wrongly by a PnP pose far "
                         "off); solved again without them, then with them from there, the "
                         "better optimum kept")):
        if which:
            names = _image_names(cameras, which)
            out.append(what + ": " + "; ".join(f"{n}: {', '.join(v)}" for n, v in names.items()))
    return tuple(out)


def _solve_views(cameras: Mapping[str, CameraData], *, reference: str, sync_tolerance, sync,
                 robust, boards, mocap, poses) -> MotionSolution:
    """One solve of :func:`solve_motion` on ``cameras`` as they are."""
    names = tuple(cameras)
    order = board_order(cameras, boards)
    prepared = camera_views(cameras, sync_tolerance, sync, lambda o: (
        order.index(target_of(o)) if target_of(o) in order else 0))
    inst, tol, views = prepared.instants, prepared.sync_tolerance, prepared.views
    which = {n: np.array([order.index(target_of(o)) for o in cameras[n].observations],
                         dtype=np.int64) for n in names}
    held = _held(order, boards, poses)
    mv = _views(cameras, views, reference, held)
    loss = "huber" if robust else "linear"
    result = refine_motion(mv, prepared.poses, loss=loss,
                           mocap=None if mocap is None else mocap(inst))
    obs = observability(result, mv)
    given = tuple(order[b] for b in (held or {}) if order[b] in (poses or {}))
    checked, notes, free = _given_findings(lambda h: _views(cameras, views, reference, h),
                                           mv, prepared.poses, loss, (order, given))
    # a given pose the views refute spoils every camera's fit: the fit is judged without it
    fit = _fit_findings(cameras, *((mv, result) if not checked else free), sync)
    findings = fit + _observability_findings(obs) + checked
    return MotionSolution(
        names=names, reference=reference, boards=order, result=result, views=mv,
        used={n: cameras[n].observations for n in names}, instants=inst, board=which,
        links=_links(mv, result, order), observability=obs, sync_tolerance=tol,
        findings=findings, given=given,
        warnings=_reposed_note(cameras, result) + _rig_warnings(cameras, mv, result) + notes,
        world=boards[0] if boards and (boards[0] in order or given) else order[0])


def _held(order: Sequence[str], declared: Sequence[str], poses) -> dict | None:
    """The boards held at a pose, by index in ``order``: rig.yaml's first board (the world)
    at the identity when it was seen, and each board with a given pose; None (board 0 is
    the world) when there are none."""
    held = {}
    if declared and declared[0] in order:
        held[order.index(declared[0])] = np.eye(4)
    for name, T in (poses or {}).items():
        if name in order:
            held[order.index(name)] = np.asarray(T, dtype=np.float64)
    return held or None


def _views(cameras: Mapping[str, CameraData], views: dict, reference: str,
           held: dict | None) -> MotionViews:
    names = tuple(cameras)
    return MotionViews(views, [cameras[n].intrinsics for n in names], names.index(reference),
                       free_intrinsics=[cameras[n].intrinsics_estimated for n in names],
                       board_poses=held)


def _given_findings(views_holding: Callable, mv: MotionViews, T_cam_board, loss: str,
                    boards: tuple) -> tuple[tuple, tuple, tuple | None]:
    """The given board poses of ``mv`` against the views (module docstring),
    ``views_holding(held)`` the same views holding only ``held``: the findings, a warning
    when the views alone cannot place the boards (nothing to check against), and the views
    and result of the solve without the given poses (None when not solved).  ``boards`` is
    ``(order, given)``: every board's name by index, those given."""
    order, given = boards
    gauge = [b for b in mv.held if order[b] not in given] or sorted(mv.held)[:1]
    checked = [b for b in mv.held if b != gauge[0]]
    if not checked:
        return (), (), None
    free = views_holding({gauge[0]: mv.held[gauge[0]]})
    try:
        est = refine_motion(free, T_cam_board, loss=loss)
    except (DisconnectedError, DegenerateMotionError, UnprojectableViewsError) as e:
        return (), (f"the given poses of targets {', '.join(order[b] for b in checked)} are "
                    f"not checked against the views: without them {e}",), None
    out = []
    for b in checked:
        G, E, C = mv.held[b], est.T_world_board[b], est.board_covariance[b]
        e = np.concatenate([log_so3(G[:3, :3] @ E[:3, :3].T), G[:3, 3] - E[:3, 3]])
        d2 = float(e @ np.linalg.lstsq(C, e, rcond=1e-12)[0])
        if d2 > GIVEN_POSE_CHI2:
            rot, trans = np.degrees(np.linalg.norm(e[:3])), float(np.linalg.norm(e[3:]))
            s_rot, s_trans = pose_std(C)
            out.append(Finding(
                "given-pose", f"given-pose: target {order[b]}'s pose given in rig.yaml "
                f"(pose:) is {rot:.3f} deg and {trans * 1e3:.1f} mm from where the views "
                f"place it (their uncertainty {float(s_rot):.3f} deg, "
                f"{float(s_trans) * 1e3:.2f} mm; chi-square {d2:.0f} over 6 values, more "
                f"than {GIVEN_POSE_CHI2:.1f}): it does not hold where the cameras see it; "
                "check the pose (the board in the first board's frame, metres) or leave it "
                "out to have it estimated",
                None, d2, GIVEN_POSE_CHI2,
                {"rot_deg": float(rot), "trans_m": trans, "chi2": d2,
                 "T_world_board_views": [[float(x) for x in r] for r in E]}))
    return tuple(out), (), (free, est)
