"""The rig linked by what its cameras see together, without motion capture (issue 23).

Stages, each keyed by camera name like the rest of the pipeline:

1. instants: every camera's images with a target pose grouped into instants (equal stamps
   within ``sync_tolerance``, docs/rig-yaml.md, section 2), each image of a camera's
   ``intrinsics_images`` an instant of its own (it informs that camera's lens only);
2. links: the co-visibility graph; cameras in groups that nothing links are refused with one
   line naming the groups (:func:`multieye.estimate.covisibility.unlinked_message`);
3. solve: every ``T_ref_cam``, the lenses estimated from the recording (``model:`` or
   ``refine_intrinsics``) and one target pose per instant, started from the graph and
   refined on the pixels (:func:`multieye.estimate.refine_rig.refine_rig`);
4. checks: a camera whose pixels fit the rig far worse than they fit its own PnP poses is
   doubted (cause ``fit``: cameras not synchronised, a rig that moved, a wrong lens).

Synopsis
--------
>>> sol = solve_overlap(cameras, reference="cam0")         # doctest: +SKIP
>>> sol.result.T_ref_cam, sol.links["cam1"].overlap       # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.special import chdtri

from multieye.core.errors import (
    CalibrationError,
    DatasetError,
    DisconnectedError,
    InputError,
    TooFewMeasurementsError,
)
from multieye.estimate.covisibility import (covisibility, link_groups, pairing_hint,
                                            unlinked_message)
from multieye.estimate.findings import Finding
from multieye.estimate.half_turns import choose_turns
from multieye.estimate.refine_images import OUTLIER_PROBABILITY
from multieye.io import Rig
from multieye.io.calibration_json import CameraLinks
from multieye.io.image_folder import label_stem
from multieye.core import geometry as g
from multieye.estimate.instants import (
    default_sync_tolerance,
    instants_from_names,
    instants_from_stamps,
)
from multieye.estimate.refine_rig import RigResult, refine_rig
from multieye.estimate.rig_residuals import RigViews
from multieye.io import RejectedItem
from multieye.pipeline import half_turns
from multieye.pipeline.camera_data import CameraData, PairedCamera
from multieye.pipeline.image_acceptance import (judge_images, taken_back, taken_back_warning,
                                                unrejected)

__all__ = ["CameraLinks", "OverlapSolution", "solve_overlap", "observation_instants",
           "camera_views", "CameraViews", "assign_instants", "paired_instants",
           "share_instants", "agreeing_orders", "UNEXPLAINED_RATIO"]

#: A camera is doubted (cause ``fit``) when its pixel residuals in the rig are this many times
#: (in variance) those of its own PnP poses.
UNEXPLAINED_RATIO = 10.0


@dataclass(frozen=True)
class OverlapSolution:
    """The rig solved from co-observations.

    Attributes
    ----------
    names : tuple of str
    reference : str
    result : RigResult
        ``T_ref_cam``, lenses, target poses, covariances, residuals (cameras in ``names``'
        order).
    used : dict of str to tuple of Observation
        Per camera the images used (with a target pose), in time order.
    instants : dict of str to ndarray of int
        The instant of each used image.
    links : dict of str to CameraLinks
    sync_tolerance : float
        Seconds.
    findings : tuple of Finding
        What the checks doubt (empty when nothing).
    warnings : tuple of str
        Images that fit the rig poorly, undetermined directions, no convergence; images
        taken back or left out on the refined lens (:func:`judged_on_refined_lens`).
    rejected : dict of str to tuple of RejectedItem
        Per camera whose images were taken back or left out on the refined lens, what it
        leaves out now (its ``CameraData.rejected`` for the others).
    """

    names: tuple[str, ...]
    reference: str
    result: RigResult
    used: dict
    instants: dict
    links: dict
    sync_tolerance: float
    findings: tuple = ()
    warnings: tuple = ()
    rejected: dict = field(default_factory=dict)


def observation_instants(cameras: Mapping[str, CameraData], sync_tolerance: float | None,
                         sync: str = "time") -> tuple[dict[str, NDArray[np.int64]], int, float]:
    """The instant of every observation of every camera, their count, and the tolerance used
    (``sync_tolerance``, or the default: :func:`multieye.estimate.instants.default_sync_tolerance`).

    Images of different cameras are one instant when their stamps (each camera's
    ``time_offset`` applied) are within the tolerance; when every camera is paired by name,
    when their names' stems are equal and their given poses too (cameras named alike but
    posed apart were not triggered together).  With ``sync`` other than ``time`` (rig.yaml),
    images are one instant when their :attr:`Observation.instant` keys are equal."""
    # one image showing several boards gives one observation per board: the image, not
    # the observation, is what joins an instant (its stamp or name, once per camera)
    if sync != "time":
        once = {n: np.unique(np.asarray([o.instant for o in d.observations], dtype=str),
                             return_inverse=True) for n, d in cameras.items()}
        inst, k = instants_from_names({n: [str(x) for x in u] for n, (u, _) in once.items()})
        return {n: inst[n][np.ravel(once[n][1])] for n in cameras}, k, 0.0
    if cameras and all(d.by_name and d.mocap is not None for d in cameras.values()):
        keys = {n: [f"{label_stem(o.name)}|{_pose_at(d, o.stamp)}" for o in d.observations]
                for n, d in cameras.items()}
        once = {n: np.unique(np.asarray(k, dtype=object), return_inverse=True)
                for n, k in keys.items()}
        inst, k = instants_from_names({n: [str(x) for x in u] for n, (u, _) in once.items()})
        return {n: inst[n][once[n][1]] for n in cameras}, k, 0.0
    stamps = [np.array([o.stamp for o in d.observations], dtype=np.float64) + d.time_offset
              for d in cameras.values()]
    tol = default_sync_tolerance(stamps) if sync_tolerance is None else float(sync_tolerance)
    once = [np.unique(s, return_inverse=True) for s in stamps]
    inst, k = instants_from_stamps([u for u, _ in once], tol)
    return {n: i[back] for n, i, (_, back) in zip(cameras, inst, once)}, k, tol


def _pose_at(data: CameraData, stamp: float) -> str:
    """A by-name camera's given pose of the image with this stamp (its place in name order),
    as hex bytes ('' when it has none)."""
    i = np.flatnonzero(data.mocap.stamps == stamp)
    return data.mocap.T[i[0]].tobytes().hex() if i.size else ""


def assign_instants(cameras: Mapping[str, CameraData], sync_tolerance: float | None
                    ) -> dict[str, CameraData]:
    """Every observation's :attr:`~multieye.pipeline.camera_data.Observation.instant` set to
    its instant's key (:func:`observation_instants`): the camera-clock stamp (``repr``) of the
    instant's first image, or its first image's name stem for cameras paired by name."""
    inst, _, _ = observation_instants(cameras, sync_tolerance)
    first: dict[int, str] = {}
    for n, d in cameras.items():
        for o, k in zip(d.observations, inst[n]):
            first.setdefault(int(k), label_stem(o.name) if d.by_name else repr(float(o.stamp)))
    return {n: replace(d, observations=tuple(replace(o, instant=first[int(k)]) for o, k in
                                             zip(d.observations, inst[n])))
            for n, d in cameras.items()}


@dataclass(frozen=True)
class CameraViews:
    """Every camera's views at their instants, as the solves without motion capture take them
    (:func:`camera_views`).

    Attributes
    ----------
    instants : dict of str to ndarray of int
        The instant of each observation (:func:`observation_instants`).
    n_instants : int
        How many instants the observations make; each image of a camera's
        ``intrinsics_images`` is an instant of its own after them.
    sync_tolerance : float
        Seconds (0 when instants come from names).
    views : dict of str to list of tuple
        Per camera ``(object_points (k, 3), image_points (k, 2), instant)`` of each
        observation, then of each ``intrinsics_images`` view when its lens is estimated;
        ``board`` (an int) appended to each when the views name their board.
    poses : ndarray, shape (n, 4, 4)
        ``T_cam_target`` (PnP) of every view, camera after camera in the same order.
    """

    instants: dict
    n_instants: int
    sync_tolerance: float
    views: dict
    poses: np.ndarray


def camera_views(cameras: Mapping[str, CameraData], sync_tolerance: float | None,
                 sync: str = "time", board_of: Callable | None = None) -> CameraViews:
    """The cameras' images checked (:func:`_check_images`), grouped into instants
    (:func:`observation_instants`) and stated as views, with their PnP poses.

    ``board_of(observation) -> int``, when given, names each view's board (a rig before
    several boards: :func:`multieye.pipeline.overlap_motion.solve_motion`).

    Raises
    ------
    DatasetError, TooFewMeasurementsError
        As :func:`_check_images`.
    """
    _check_images(cameras)
    inst, n_inst, tol = observation_instants(cameras, sync_tolerance, sync)
    tag = (lambda o: ()) if board_of is None else (lambda o: (board_of(o),))
    views, poses, extra = {}, [], n_inst
    for n, d in cameras.items():
        vs = [(o.object_points, o.image_points, int(t), *tag(o))
              for o, t in zip(d.observations, inst[n])]
        poses += [o.T_cam_target for o in d.observations]
        for o in (d.intrinsics_views if d.intrinsics_estimated else ()):
            vs.append((o.object_points, o.image_points, extra, *tag(o)))
            poses.append(o.T_cam_target)
            extra += 1
        views[n] = vs
    return CameraViews(inst, n_inst, tol, views, np.stack(poses))


def _check_images(cameras: Mapping[str, CameraData]) -> None:
    for name, d in cameras.items():
        if d.intrinsics is None or any(o.image_points is None for o in d.observations):
            raise DatasetError("a rig without motion capture is linked by the target points "
                               "its cameras see together; this camera gives poses, not images "
                               "(give it images:, or add mocap:)", camera=name)
        if not d.observations:
            raise TooFewMeasurementsError(f"camera {name}: no image with the target detected")


def _links(cameras: Mapping, shared) -> dict[str, CameraLinks]:
    """What links each camera of ``cameras`` (keyed by name, in the order of ``shared``'s
    rows): the images it shares with each other camera."""
    names = tuple(cameras)
    return {n: CameraLinks({names[k]: int(shared[j, k]) for k in np.flatnonzero(shared[j])
                            if k != j}) for j, n in enumerate(names)}


def solve_overlap(cameras: Mapping[str, CameraData], reference: str, *,
                  sync_tolerance: float | None = None, robust: bool = True,
                  isolate: bool = True, sync: str = "time", judge: bool = True
                  ) -> OverlapSolution:
    """Calibrate the rig from the views its cameras share (module docstring).

    Parameters
    ----------
    cameras : mapping of str to CameraData
        Cameras with images (target points), in rig.yaml's order; no motion capture.
    reference : str
        The camera whose frame is ``ref``.
    sync_tolerance : float, optional
        Seconds; default a quarter of the shortest interval between two images of a camera.
    robust : bool
        Huber loss on the pixels (else least squares).
    isolate : bool
        When several cameras are doubted, look for the one without which the others fit
        (solving without each in turn) and doubt that one alone.
    sync : str
        rig.yaml's ``sync``: other than ``time``, the instants are the images'
        :attr:`Observation.instant` keys (:func:`observation_instants`).
    judge : bool
        The images of cameras whose lens is estimated judged on the refined lens
        (:func:`judged_on_refined_lens`).

    Raises
    ------
    DatasetError
        A camera given by poses (no target points).
    DisconnectedError
        Cameras in groups that share no instant (one line naming the groups).
    """
    cameras, turn_lines = agreeing_orders(cameras, reference, sync_tolerance, sync)
    prepared = camera_views(cameras, sync_tolerance, sync)
    names, inst, tol = tuple(cameras), prepared.instants, prepared.sync_tolerance
    cov = _covisibility(inst, names)
    groups = link_groups(cov.shared > 0, [False] * len(names))
    if len(groups) > 1:
        obs = [cameras[n].observations for n in names]
        hint = pairing_hint(groups, [[o.stamp + cameras[n].time_offset for o in ob]
                                     for n, ob in zip(names, obs)],
                            [[label_stem(o.name) for o in ob] for ob in obs], sync, names)
        raise DisconnectedError(unlinked_message([[names[j] for j in grp] for grp in groups], tol,
                                                 sync) + hint,
                                tuple(n for g in groups[1:] for n in (names[j] for j in g)))
    solve = _Solve(reference, sync_tolerance, sync, robust)
    prepared, rv, result = solve(cameras, prepared)
    notes: tuple[str, ...] = ()
    before = cameras
    if judge and any(cameras[n].intrinsics_estimated for n in names):
        cameras, (prepared, rv, result), notes = judged_on_refined_lens(cameras, solve,
                                                                        (prepared, rv, result))
        inst, tol = prepared.instants, prepared.sync_tolerance
        cov = _covisibility(inst, names)
    used = {n: cameras[n].observations for n in names}
    findings = _fit_findings(cameras, rv, result, sync)
    if isolate and len(findings) > 1:
        findings = _culprit(cameras, reference, (tol, sync), robust, findings)
    return OverlapSolution(names=names, reference=reference, result=result, used=used,
                           instants=inst, links=_links(cameras, cov.shared), sync_tolerance=tol,
                           findings=findings,
                           warnings=turn_lines + _rig_warnings(cameras, rv, result) + notes,
                           rejected={n: cameras[n].rejected for n in names
                                     if cameras[n] is not before[n]})


def _covisibility(inst: Mapping[str, np.ndarray], order: tuple[str, ...]):
    """The graph of the instants the cameras share, in ``order`` (:func:`multieye.estimate.
    covisibility.covisibility` of each camera's instant keys ``inst[name]``)."""
    return covisibility(np.concatenate([np.full(len(inst[n]), j) for j, n in enumerate(order)]),
                        np.concatenate([inst[n] for n in order]), len(order))


@dataclass(frozen=True)
class _Solve:
    """The refinement of :func:`solve_overlap` on given cameras' views (prepared when
    given, else prepared here), as it is run again on the refined lens."""

    reference: str
    sync_tolerance: float | None
    sync: str
    robust: bool

    def ordered(self, cameras: Mapping[str, CameraData]):
        """The cameras with a symmetric board's views in the orders that agree
        (:func:`agreeing_orders`), e.g. with the views taken back added."""
        return agreeing_orders(cameras, self.reference, self.sync_tolerance, self.sync)

    def __call__(self, cameras: Mapping[str, CameraData], prepared: CameraViews | None = None):
        if prepared is None:
            prepared = camera_views(cameras, self.sync_tolerance, self.sync)
        names = tuple(cameras)
        rv = RigViews(prepared.views, [cameras[n].intrinsics for n in names],
                      names.index(self.reference),
                      free_intrinsics=[cameras[n].intrinsics_estimated for n in names])
        return prepared, rv, refine_rig(rv, prepared.poses,
                                        loss="huber" if self.robust else "linear")


def judged_on_refined_lens(cameras: Mapping[str, CameraData], solve: _Solve, solved: tuple):
    """The images of the cameras whose lens is estimated judged on the refined lens
    (:mod:`multieye.pipeline.image_acceptance`): those left out as a bad fit that fit it
    taken back, then the outliers of the solve left out, the solve run again (from the
    refined lenses) after each that changed the images.  Returns the cameras (their
    observations and ``rejected`` as they are now), what ``solve`` gives at the end, and
    the warnings."""
    names = tuple(cameras)
    estimated = [n for n in names if cameras[n].intrinsics_estimated]
    result, before, cameras, notes = solved[2], cameras, dict(cameras), []
    lens = {n: result.intrinsics[names.index(n)] for n in estimated}
    back = {n: taken_back(cameras[n].bad_fits, lens[n]) for n in estimated}
    back = {n: b for n, b in back.items() if b}
    if back:
        for n, b in back.items():
            d = cameras[n]
            every = sorted(d.observations + tuple(b), key=lambda o: o.stamp)
            cameras[n] = replace(d, observations=tuple(every), intrinsics=lens[n],
                                 rejected=unrejected(d.rejected, b),
                                 bad_fits=tuple(o for o in d.bad_fits if o.name not in
                                                {x.name for x in b}))
            notes.append(taken_back_warning(n, b))
        cameras = solve.ordered(cameras)[0]     # the views taken back in the agreeing order
        try:
            solved = solve(cameras)
        except CalibrationError as exc:
            return before, solved, (f"images left out as a bad fit that fit the refined lens "
                                    f"were not taken back: the solve with them failed ({exc})",)
    judged = judge_images({n: cameras[n].observations for n in estimated},
                          *_image_residuals(cameras, estimated, solved[1], solved[2]))
    if judged:
        kept, result = dict(cameras), solved[2]
        for n, idx in judged.left_out.items():
            d = cameras[n]
            keep = np.setdiff1d(np.arange(len(d.observations)), idx)
            cameras[n] = replace(d, observations=tuple(d.observations[i] for i in keep),
                                 intrinsics=result.intrinsics[names.index(n)],
                                 rejected=d.rejected + tuple(
                                     RejectedItem(d.observations[i].name, judged.reasons[n][int(i)])
                                     for i in sorted(idx)))
        try:
            solved = solve(cameras)
            notes += judged.warnings
        except CalibrationError as exc:
            cameras = kept
            notes.append(f"outliers of the solve kept: the solve without them failed ({exc})")
    else:
        notes += judged.warnings            # the floor's, when it kept every image
    return cameras, solved, tuple(notes)


def _image_residuals(cameras: Mapping[str, CameraData], tested, views: RigViews,
                     result: RigResult) -> tuple[dict, dict]:
    """Per camera of ``tested``, its images' residual RMS per point at the optimum, pixels,
    and their points (the images only: not its ``intrinsics_images``)."""
    names = tuple(cameras)
    d2 = np.sum(result.residuals_px ** 2, axis=1)
    rms, points = {}, {}
    for n in tested:
        own = np.flatnonzero(views.camera == names.index(n))[:len(cameras[n].observations)]
        per = [d2[views.view == v] for v in own]
        rms[n] = np.array([np.sqrt(np.mean(x)) if x.size else np.nan for x in per])
        points[n] = np.array([x.size for x in per])
    return rms, points


def agreeing_orders(cameras: Mapping[str, CameraData], reference: str,
                    sync_tolerance: float | None, sync: str = "time"
                    ) -> tuple[dict[str, CameraData], tuple[str, ...]]:
    """The cameras with every view of a half-turn symmetric board in the order that agrees
    with the other cameras' views of its instant (:func:`multieye.estimate.half_turns.
    choose_turns`, :func:`multieye.pipeline.half_turns.turned`), and the line saying how many
    were turned (nothing when no view has another order, or for a single camera, whose
    views nothing links).  Cameras the checks refuse, or that see an instant twice, are left
    as they are for the solve to say why."""
    names = tuple(cameras)
    obs = [o for n in names for o in cameras[n].observations]
    if len(cameras) < 2 or not any(half_turns.turnable(obs)) or reference not in cameras:
        return dict(cameras), ()
    try:
        _check_images(cameras)
        inst, _, _ = observation_instants(cameras, sync_tolerance, sync)
    except CalibrationError:
        return dict(cameras), ()
    camera = np.concatenate([np.full(len(cameras[n].observations), j)
                             for j, n in enumerate(names)])
    keys = [(int(t), o.target) for n in names for o, t in zip(cameras[n].observations, inst[n])]
    instant = np.unique(np.array([f"{t}|{b}" for t, b in keys]), return_inverse=True)[1]
    H = np.stack([h if (h := half_turns.half_turn_of(o)) is not None
                  else np.full((4, 4), np.nan) for o in obs])
    try:
        turn = choose_turns(np.stack([o.T_cam_target for o in obs]), camera,
                            np.ravel(instant), H, len(names), names.index(reference))
    except InputError:
        return dict(cameras), ()
    per = dict(zip(names, np.split(turn, np.cumsum([len(cameras[n].observations)
                                                    for n in names])[:-1])))
    lines = half_turns.turn_warning({n: cameras[n].observations for n in names}, per,
                                    "the other cameras' views of the same instants")
    return half_turns.turn_views(cameras, per), lines


def _rig_warnings(cameras: Mapping[str, CameraData], views: RigViews, result: RigResult
                  ) -> tuple[str, ...]:
    """What the solve doubts: images most of whose points lie far beyond the pixel noise
    (more than half of them with a squared normalised residual over the chi-square quantile
    of 2 degrees of freedom at :data:`OUTLIER_PROBABILITY`: the rule of the motion-capture
    refinement, :func:`multieye.estimate.refine_images.refine_images`; a rule on any one
    point, or on an image's sum, flagged a third of the images of a clean rendered rig,
    whose corner errors are correlated within an image), directions the data do not
    determine, no convergence."""
    out = []
    limit = float(chdtri(2, OUTLIER_PROBABILITY))
    z2 = np.sum((result.residuals_px / result.pixel_sigma) ** 2, axis=1)
    for j, n in enumerate(views.names):
        own = np.flatnonzero(views.camera == j)[:len(cameras[n].observations)]
        bad = [cameras[n].observations[i].name for i, v in enumerate(own)
               if np.mean(z2[views.view == v] > limit) > 0.5]
        if bad:
            out.append(f"{n}: {len(bad)} image(s) fit the rig poorly: " + ", ".join(bad[:5])
                       + (" ..." if len(bad) > 5 else ""))
    for family in result.undetermined:
        what = (f"{family[2:]}: the intrinsics" if family.startswith("K:")
                else "the cameras' T_ref_cam")
        out.append(f"{what} include a combination of parameters this recording does not "
                   "determine (their uncertainty covers the other directions only); add "
                   "views seen together with more tilt and nearer the image corners")
    if not result.converged:
        out.append("the refinement did not converge; the result may be short of the best the "
                   "data allow")
    return tuple(out)


def _culprit(cameras: Mapping[str, CameraData], reference: str, sync: tuple[float, str],
             robust: bool, findings: tuple[Finding, ...]) -> tuple[Finding, ...]:
    """One camera that does not fit pulls the whole rig (its views tie the others): of the
    doubted cameras, worst first, the first without which the others fit together is named
    alone; else every doubt stays."""
    for f in sorted(findings, key=lambda f: -f.cost):
        rest = {n: d for n, d in cameras.items() if n != f.camera}
        if len(rest) < 2:
            continue
        try:
            sub = solve_overlap(rest, reference if reference in rest else next(iter(rest)),
                                sync_tolerance=sync[0], robust=robust, isolate=False,
                                sync=sync[1], judge=False)
        except CalibrationError:
            continue
        if not sub.findings:
            return (replace(f, message=f"{f.message} (the other cameras fit together "
                                       "without it)"),)
    return findings


#: What to check when the images of one instant do not show the target at one pose, by
#: rig.yaml's ``sync``.
_PAIRING_CHECK = {
    "time": "check that the cameras are synchronised (sync_tolerance, time_offset)",
    "name": "check that images named alike were taken together (sync: name)",
    "number": "check that images numbered alike were taken together (sync: number)",
    "order": "check that the k-th images of the cameras were taken together (sync: order: an "
             "image missing in one camera and another in a second shift every pair between "
             "them; names numbered by frame and sync: number avoid it)"}


def _fit_findings(cameras: Mapping[str, CameraData], views: RigViews,
                  result: RigResult, sync: str = "time") -> tuple[Finding, ...]:
    """Cameras whose pixels fit the rig far worse than their own PnP poses (``views`` holds
    the cameras in the order of ``cameras``; ``sync`` rig.yaml's, for what to check)."""
    out = []
    cam_of_point = views.camera[views.view]
    for j, n in enumerate(cameras):
        own = [o.rms_px for o in cameras[n].observations if o.rms_px is not None]
        if not own:
            continue
        r = result.residuals_px[cam_of_point == j]
        n_obs = len(cameras[n].observations)
        rig_ms = float(np.mean(np.sum(r[:sum(len(o.image_points) for o in
                                             cameras[n].observations)] ** 2, axis=1)))
        own_ms = max(float(np.mean(np.square(own))), 1e-6)
        ratio = rig_ms / own_ms
        if ratio >= UNEXPLAINED_RATIO and n_obs:
            out.append(Finding(
                "fit", f"poor fit: camera {n}'s target points are {np.sqrt(ratio):.0f} times "
                f"further from the rig's projection (RMS {np.sqrt(rig_ms):.2f} px) than from "
                f"its own PnP poses ({np.sqrt(own_ms):.2f} px): the images of one instant do "
                f"not show the target at one pose; {_PAIRING_CHECK[sync]}, that the rig did "
                "not move, and its lens", n,
                ratio, 1.0, {"rig_rms_px": float(np.sqrt(rig_ms)),
                             "pnp_rms_px": float(np.sqrt(own_ms))}))
    return tuple(out)


def paired_instants(paired: Mapping[str, PairedCamera], cameras: Mapping[str, CameraData],
                    offsets: Mapping[str, float], sync_tolerance: float | None
                    ) -> tuple[dict[str, NDArray[np.int64]], dict[str, CameraLinks]]:
    """The instant of every paired image of a rig with motion capture, and what links each
    camera: images of different cameras whose stamps (motion-capture clock: plus each
    camera's offset) are within ``sync_tolerance``, or, when every camera is paired by name,
    whose names' stems are equal and whose given poses are too, are one instant (images of
    two cameras named alike but posed apart were taken at different instants)."""
    names = list(paired)
    if all(o.instant for n in names for o in paired[n].observations):
        # the problem's instants (make_problem: assign_instants), as every stage sees them
        by_name, _ = instants_from_names({n: [o.instant for o in paired[n].observations]
                                          for n in names})
        inst = [by_name[n] for n in names]
    else:
        stamps = [np.array([o.stamp for o in paired[n].observations], dtype=np.float64)
                  + offsets[n] for n in names]
        tol = default_sync_tolerance(stamps) if sync_tolerance is None else sync_tolerance
        inst, _ = instants_from_stamps(stamps, tol)
    cams = np.concatenate([np.full(len(i), j) for j, i in enumerate(inst)])
    shared = covisibility(cams, np.concatenate(inst), len(names)).shared
    links = {n: CameraLinks(l.overlap, True) for n, l in _links(paired, shared).items()}
    return dict(zip(names, inst)), links


def share_instants(rig: Rig, paired: Mapping[str, PairedCamera],
                   instants: Mapping[str, NDArray[np.int64]], noise: tuple[float, float]
                   ) -> dict[str, PairedCamera]:
    """Every image of one instant given one motion-capture pose (the first camera's, in rig
    order), so that the image-level refinement holds one pose of the target per instant
    (its images share one block and one prior:
    :class:`multieye.estimate.image_residuals.ImageData`).

    An image keeps its own pose when the one it would take differs from it by more than the
    motion capture's noise ``noise`` (per axis: radians, metres): its camera was not triggered
    with the first one closely enough for the target to be at one pose (a free-running camera
    whose stamp falls within ``sync_tolerance`` by chance), and sharing would bias the
    result; the two stay linked by the motion capture."""
    first: dict[int, np.ndarray] = {}
    first_scale: dict[int, float] = {}
    for n, p in paired.items():
        scale = _noise_scale(p)
        for k, M, f in zip(instants[n], p.T_world_mocap, scale):
            first.setdefault(int(k), M)
            first_scale.setdefault(int(k), float(f))
    out = {}
    for n, p in paired.items():
        M, scale = p.T_world_mocap.copy(), _noise_scale(p).copy()
        if len(M):      # every image of the camera at once (one at a time: 10 ms of 4 x 100)
            F = np.stack([first[int(k)] for k in instants[n]])
            close = ((g.rotation_angle_between(F, M) <= noise[0])
                     & (g.translation_distance(F, M) <= noise[1]))
            M[close] = F[close]
            scale[close] = [first_scale[int(k)] for k in instants[n][close]]
        A = g.inv(M) if rig.setup == "eye-to-base" else M
        out[n] = PairedCamera(name=p.name, A=A, B=p.B, T_world_mocap=M,
                              observations=p.observations, rejected=p.rejected,
                              mocap_noise_scale=scale)
    return out


def _noise_scale(p: PairedCamera) -> NDArray[np.float64]:
    """The camera's :attr:`PairedCamera.mocap_noise_scale`, ones when it has none."""
    n = len(p.T_world_mocap)
    return np.ones(n) if p.mocap_noise_scale is None else np.asarray(p.mocap_noise_scale, float)
