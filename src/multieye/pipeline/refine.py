"""The refinement stage: the maximum-likelihood refinement after the closed form, fed from the
problem at one boundary.

On the target points and the motion-capture poses when every camera has target points
(:func:`multieye.estimate.refine_images.refine_images`, which takes per-camera sequences in
the order of the pairing: built here and nowhere else, and its per-camera results turned back
into dicts keyed by camera name here), else on the pose residuals
(:func:`multieye.solvers.refine_poses.refine_solution`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from multieye.core.errors import CalibrationError, InputError, UnprojectableStartError
from multieye.estimate.clock_residuals import ClockData, LocalTrajectory, shared_clocks
from multieye.estimate.refine_images import RefinementResult, RefineOptions, refine_images
from multieye.estimate.uncertainty import RelativeUncertainty, relative_covariance
from multieye.io import Rig
from multieye.pipeline.camera_data import PairedCamera
from multieye.pipeline.image_acceptance import (Judged, judge_images, rejected_by_consensus,
                                                taken_back, taken_back_warning,
                                                with_taken_back, without_outliers)
from multieye.pipeline.options import Options
from multieye.pipeline.problem import Pairing, Problem
from multieye.pipeline.result import Refinement
from multieye.solvers import Solution
from multieye.solvers.refine_poses import refine_solution

__all__ = ["Refined", "refine", "mocap_noise"]

#: An estimated motion-capture noise below this (radians, metres) is one the recording could
#: not resolve (its variance component went to zero).
_UNRESOLVED_NOISE = 1e-6


@dataclass(frozen=True)
class Refined:
    """What the refinement stage gave.

    Attributes
    ----------
    refinement : Refinement or None
        None when the refinement was not asked for or failed.
    uncertainty : RelativeUncertainty or None
        Of ``T_ref_cam`` per camera, from the refinement's covariance.
    warnings : tuple of str
    pairing : Pairing or None
        The measurements the refinement ended on, when they are not those it was given:
        images of a camera whose lens is estimated taken back or left out on the jointly
        refined lens (:mod:`multieye.pipeline.image_acceptance`); None otherwise.
    """

    refinement: Refinement | None
    uncertainty: RelativeUncertainty | None
    warnings: tuple[str, ...] = ()
    pairing: Pairing | None = None


def mocap_noise(rig: Rig, paired: dict[str, PairedCamera], opts: Options):
    """The motion capture of the first paired camera and its noise per axis (radians, metres):
    the options' where given, else rig.yaml's, else None (to be estimated)."""
    first = next(iter(paired))
    spec = rig.mocap_for(first) if first in rig.cameras else rig.mocap
    rot, trans = opts.mocap_rot_sigma_rad, opts.mocap_trans_sigma_m
    if spec is not None:
        rot = spec.rot_sigma_rad if rot is None else rot
        trans = spec.trans_sigma_m if trans is None else trans
    return spec, rot, trans


def refine(problem: Problem, pairing: Pairing, sol: Solution) -> Refined:
    """The refinement of ``sol`` on the measurements kept, when the options ask for it; a
    refinement that fails leaves the closed form, with a warning saying why."""
    if not problem.options.refine:
        return Refined(None, None)
    judged = None
    try:
        if _have_points(problem, pairing.paired):
            refinement, judged = _judged(problem, pairing, sol)
            pairing = judged or pairing
        else:
            ref = refine_solution(sol)
            refinement = Refinement(kind="poses", X=ref.X, Y=ref.Y, covariance=ref.covariance,
                                    reprojection_rms_px={}, warnings=(), result=ref)
    except CalibrationError as exc:
        return Refined(None, None, (f"refinement failed, the result is the closed form without "
                                    f"uncertainty: {exc}",))
    uncertainty = None
    if refinement.covariance is not None:
        uncertainty = relative_covariance(refinement.X, refinement.covariance,
                                          reference=list(pairing.paired).index(problem.reference))
    return Refined(refinement, uncertainty, refinement.warnings, judged)


def _judged(problem: Problem, pairing: Pairing, sol: Solution
            ) -> tuple[Refinement, Pairing | None]:
    """The image-level refinement, then the images of the cameras whose lens is estimated
    judged on the refined lens (:mod:`multieye.pipeline.image_acceptance`): those left out
    as a bad fit that fit it taken back, then the outliers of the joint refinement left
    out, the refinement run again from its optimum after each that changed the images; the
    pairing it ended on when it changed, else None."""
    given = pairing
    refinement, pairing, notes = _first_refinement(problem, pairing, sol.X, sol.Y)
    cameras = problem.cameras
    estimated = [n for n in pairing.paired if cameras[n].intrinsics_estimated]
    if not estimated:
        refinement = replace(refinement, warnings=refinement.warnings + tuple(notes))
        return refinement, None if pairing is given else pairing
    # left out on the starting lens: as a bad fit, or by the consensus on its poses
    by_consensus = {n: rejected_by_consensus(cameras[n], pairing.paired[n]) for n in estimated}
    early = {n: list(cameras[n].bad_fits) + by_consensus[n] for n in estimated}
    back = {n: taken_back(early[n], refinement.intrinsics[n]) for n in estimated}
    grown, added = with_taken_back(problem, pairing, back, rig=(refinement.X, refinement.Y))
    if added:
        try:
            refinement = _refine_images(problem, grown, refinement.X, refinement.Y,
                                        refinement.intrinsics)
            pairing = grown
            notes += [taken_back_warning(n, obs, by_consensus=[o.name for o in by_consensus[n]])
                      for n, obs in added.items()]
        except CalibrationError as exc:
            added = {}
            notes.append(f"images left out as a bad fit that fit the refined lens were not "
                         f"taken back: the refinement with them failed ({exc})")
    res, names = refinement.result, list(pairing.paired)
    judged = judge_images(
        {n: pairing.paired[n].observations for n in estimated},
        {n: res.image_rms_px[names.index(n)] for n in estimated},
        {n: [int(np.sum(np.isfinite(w))) for w in res.point_weights[names.index(n)]]
         for n in estimated})
    notes += judged.warnings
    if judged:
        try:
            smaller = without_outliers(pairing, judged)
            refinement = _refine_images(problem, smaller, refinement.X, refinement.Y,
                                        refinement.intrinsics)
            pairing = smaller
        except CalibrationError as exc:
            notes = [n for n in notes if n not in judged.warnings] + [
                f"outliers of the joint refinement kept: the refinement without them failed "
                f"({exc})"]
    refinement = replace(refinement, warnings=refinement.warnings + tuple(notes))
    return refinement, None if pairing is given else pairing


#: At most this share of a camera's images is left out for target points behind it at the
#: start; more says the closed form or the setup is wrong, not the images.
MAX_LEFT_OUT = 0.25
#: Why an image the image-level refinement's start puts behind its camera is left out.
BEHIND_AT_START = ("target points behind the camera at the refinement's start (the closed "
                   "form with the image's motion-capture pose): it disagrees with the rest")


def _first_refinement(problem: Problem, pairing: Pairing, X0, Y0
                      ) -> tuple[Refinement, Pairing, list[str]]:
    """The image-level refinement from the closed form; the images whose target points its
    start puts behind their camera (:class:`~multieye.core.errors.UnprojectableStartError`:
    a wrong board, or a motion-capture pose that is not the image's) left out, among their
    camera's rejected and named in a warning, and the refinement run without them (at most
    :data:`MAX_LEFT_OUT` of a camera's images, else the error stands).  Returns the
    refinement, the pairing it ran on and the warnings."""
    try:
        return _refine_images(problem, pairing, X0, Y0, {}), pairing, []
    except UnprojectableStartError as exc:
        names = list(pairing.paired)
        out: dict[str, list[int]] = {}
        for j, i in exc.items:
            out.setdefault(names[j], []).append(int(i))
        if any(len(ix) > MAX_LEFT_OUT * len(pairing.paired[n].observations)
               for n, ix in out.items()):
            raise                       # not a few images: the closed form or the setup
        judged = Judged({n: np.array(ix) for n, ix in out.items()},
                        {n: dict.fromkeys(ix, BEHIND_AT_START) for n, ix in out.items()}, ())
        smaller = without_outliers(pairing, judged)
        note = "; ".join(f"{n}: {len(ix)} image(s) left out, their {BEHIND_AT_START}: "
                         + ", ".join(pairing.paired[n].observations[i].name for i in ix)
                         for n, ix in out.items())
        return _refine_images(problem, smaller, X0, Y0, {}), smaller, [note]


def _have_points(problem: Problem, paired: dict[str, PairedCamera]) -> bool:
    return all(problem.cameras[n].intrinsics is not None and p.observations
               and all(o.image_points is not None for o in p.observations)
               for n, p in paired.items())


def _refine_images(problem: Problem, pairing: Pairing, X0, Y0, lenses: dict) -> Refinement:
    """Image-level refinement from ``X0``, ``Y0`` and the cameras' lenses (``lenses`` by
    name where given, else the problem's); with ``time_offset="auto"`` the clock offsets
    (starting at the pairing's) are unknowns of the problem
    (:mod:`multieye.estimate.clock_residuals`)."""
    paired, cameras = pairing.paired, problem.cameras
    _, rot, trans = mocap_noise(problem.rig, paired, problem.options)
    sigmas = {k: v for k, v in (("mocap_rot_sigma_rad", rot), ("mocap_trans_sigma_m", trans))
              if v is not None}
    # Motion-capture noise not stated: refine_images estimates it, like the pixel noise,
    # from how far the refinement moves the measured poses.
    # (one of the two stated: the other takes refine_images' default)
    given = sigmas or {"mocap_rot_sigma_rad": None, "mocap_trans_sigma_m": None}
    obs = [[(o.object_points, o.image_points, T) for o, T in zip(p.observations, p.T_world_mocap)]
           for p in paired.values()]
    views = [[(o.object_points, o.image_points, o.T_cam_target)
              for o in cameras[n].intrinsics_views] for n in paired]
    warnings: list[str] = []
    clocks = _clocks(problem, pairing, warnings) if problem.options.time_offset == "auto" else None
    scale = [p.mocap_noise_scale for p in paired.values()]
    options = RefineOptions(names=list(paired), clocks=clocks,
                            mocap_noise_scale=None if all(f is None for f in scale) else scale,
                            free_intrinsics=[cameras[n].intrinsics_estimated for n in paired],
                            intrinsics_observations=views if any(views) else None, **given)
    res = refine_images(problem.setup, obs, [lenses.get(n, cameras[n].intrinsics) for n in paired],
                        X0, Y0, options)
    warnings.extend(_image_warnings(res, paired))
    names = list(paired)
    estimated = [j for j, n in enumerate(names) if cameras[n].intrinsics_estimated]
    joint = [j for j, t in enumerate(res.time_offsets) if t is not None]
    return Refinement(kind="images", X=res.X, Y=res.Y, covariance=res.covariance,
                      reprojection_rms_px={n: float(res.camera_rms_px[j])
                                           for j, n in enumerate(names)},
                      warnings=tuple(warnings), result=res,
                      intrinsics={names[j]: res.intrinsics[j] for j in estimated},
                      intrinsics_covariance={names[j]: res.intrinsics_covariance[j]
                                             for j in estimated},
                      time_offsets={names[j]: res.time_offsets[j] for j in joint},
                      time_offset_std={names[j]: res.time_offset_std_s[j] for j in joint})


def _image_warnings(res: RefinementResult, paired: dict[str, PairedCamera]) -> list[str]:
    """What the image-level refinement doubts: undetermined directions, an estimated
    motion-capture noise, no convergence, images that fit the refined rig poorly."""
    warnings = []
    for family in res.undetermined:
        what = (f"{family[2:]}: the intrinsics" if family.startswith("K:")
                else f"the {family} estimate")
        warnings.append(f"{what} include a combination of parameters this recording does "
                        "not determine (their uncertainty covers the other directions "
                        "only); add views with more tilt and nearer the image corners, or "
                        "use a lens model with fewer coefficients")
    if res.mocap_sigma_estimated:
        unresolved = [what for what, v in (("rotation", res.mocap_rot_sigma_rad),
                                           ("position", res.mocap_trans_sigma_m))
                      if v < _UNRESOLVED_NOISE]
        warnings.append(
            f"motion-capture noise estimated from the data: "
            f"{np.degrees(res.mocap_rot_sigma_rad):.3g} deg, "
            f"{res.mocap_trans_sigma_m * 1e3:.3g} mm per pose (state rotation_noise_deg and "
            "translation_noise_m under mocap in rig.yaml to fix it)"
            + (f"; in {' and '.join(unresolved)} it is too small for this recording to "
               "tell apart from the pixel noise, which then carries it in the uncertainty"
               if unresolved else ""))
    if not res.converged:
        warnings.append(f"refinement did not converge ({res.message}); the result may be "
                        "short of the best the data allow")
    for (name, p), outliers in zip(paired.items(), res.image_outliers):
        bad = np.flatnonzero(outliers)
        if bad.size:
            warnings.append(f"{name}: {bad.size} image(s) fit the refined rig poorly: "
                            + ", ".join(p.observations[i].name for i in bad[:5])
                            + (" ..." if bad.size > 5 else ""))
    return warnings


def _clocks(problem: Problem, pairing: Pairing, warnings: list[str]) -> list[ClockData | None]:
    """Per paired camera, its clock as an unknown of the image-level problem (None: paired by
    name, or kept at the estimate before the solve, with a warning saying why)."""
    clocks: dict[str, ClockData | None] = {}
    for n, p in pairing.paired.items():
        data, offset = problem.cameras[n], pairing.offsets[n]
        try:
            clock = None if data.by_name else ClockData(
                [o.stamp for o in p.observations], data.mocap.stamps, data.mocap.T, offset=offset)
            if clock is not None:
                LocalTrajectory(clock)         # every image inside the motion capture
        except InputError as exc:
            warnings.append(f"{n}: clock offset kept at the estimate before the solve "
                            f"({offset:+.4f} s), not refined with the rig: {exc}")
            clock = None
        clocks[n] = clock
    return list(_share_clocks(clocks, warnings).values())


def _share_clocks(by_camera: dict[str, ClockData | None], warnings: list[str]
                  ) -> dict[str, ClockData | None]:
    """Cameras triggered together (equal stamps for at least half of each one's images,
    :func:`multieye.estimate.clock_residuals.shared_clocks`) on one motion capture are
    stamped by one clock: one offset for them, started at the mean of their estimates."""
    names, clocks = list(by_camera), list(by_camera.values())
    timed = [j for j, c in enumerate(clocks) if c is not None]
    for group in shared_clocks([clocks[j].image_stamps for j in timed],
                               [(clocks[j].mocap_stamps, clocks[j].mocap_T) for j in timed]):
        js = [timed[k] for k in group]
        start = float(np.mean([clocks[j].offset for j in js]))
        for j in js:
            clocks[j] = replace(clocks[j], offset=start, shared=names[js[0]])
        warnings.append(f"{', '.join(names[j] for j in js)}: image stamps equal (triggered "
                        "together), so one clock: one time offset estimated for them")
    return dict(zip(names, clocks))
