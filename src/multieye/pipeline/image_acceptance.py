"""Images judged on the jointly refined lens (issue 33, item 2).

A camera whose lens is estimated has its images accepted or rejected by PnP on its lens start
(:func:`multieye.pipeline.estimated_lens.posed_on_refined_lens`), but its final lens is the
joint refinement's (with motion capture: :mod:`multieye.pipeline.refine`; without:
:mod:`multieye.pipeline.overlap`).  After that refinement, for such a camera:

1. every image left out as a bad fit (``bad fit: reprojection RMS ... px > 2 px``,
   :attr:`~multieye.pipeline.camera_data.CameraData.bad_fits`) is posed again by PnP on the
   refined lens; those within the limit now are taken back (:func:`taken_back`) and the
   refinement runs again, once, from its optimum;
2. its images' residuals in the joint refinement are tested against the camera's pixel noise
   (:func:`multieye.estimate.image_outliers.image_outliers`: a chi-square test against a
   robust noise estimate, with the spread of the images' noise allowed for); those that fail
   are left out, named, with the reason ``outlier of the joint refinement: ...``, and the
   refinement runs again, once; a floor keeps three quarters of each camera's images.

Both say what they did in one warning per camera.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from multieye.core import geometry as g
from multieye.estimate.consensus import DEFAULT_THRESHOLDS, choose_poses, measurement_residuals
from multieye.estimate.image_outliers import MAX_SHARE, image_outliers
from multieye.imaging.batch import DEFAULT_MAX_RMS_PX
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import estimate_poses
from multieye.io import RejectedItem
from multieye.pipeline.camera_data import Observation, pair_stamps
from multieye.pipeline.half_turns import half_turn_of, turned
from multieye.solvers.checks import check_measurements

__all__ = ["taken_back", "unrejected", "Judged", "judge_images", "taken_back_warning",
           "agreeing_turns", "rejected_by_consensus", "CONSENSUS_REASON",
           "with_taken_back", "without_outliers", "camera_data_now", "OUTLIER_REASON"]

#: How the reason of an image left out by the outlier test starts.
OUTLIER_REASON = "outlier of the joint refinement"
#: How the reason of a view the consensus left out starts (:mod:`multieye.estimate.consensus`).
CONSENSUS_REASON = "outlier by consensus"
#: The reasons of the views left out on the starting lens that may be taken back.
STARTING_LENS_REASONS = ("bad fit", CONSENSUS_REASON)


def taken_back(bad_fits: Sequence[Observation], intrinsics, *,
               max_rms_px: float = DEFAULT_MAX_RMS_PX) -> list[Observation]:
    """The images left out as a bad fit that fit ``intrinsics`` (the refined lens) within
    ``max_rms_px``: posed again by PnP on it (:func:`multieye.imaging.pnp.estimate_poses`),
    with that pose and RMS."""
    if not bad_fits:
        return []
    detections = [Detection(np.arange(len(o.image_points)), o.image_points, o.object_points)
                  for o in bad_fits]
    out = []
    for o, pose in zip(bad_fits, estimate_poses(detections, intrinsics)):
        if isinstance(pose, Exception) or not pose.rms_px <= max_rms_px \
                or pose.n_points < len(o.image_points):
            continue
        H = half_turn_of(o)                 # a symmetric board's other order, kept
        out.append(replace(o, T_cam_target=pose.T_cam_target, rms_px=pose.rms_px,
                           alternative=pose.alternative if H is None else pose.T_cam_target @ H,
                           alternative_rms_px=pose.alternative_rms_px if H is None
                           else pose.rms_px))
    return out


def unrejected(rejected: Sequence[RejectedItem], back: Sequence[Observation]
               ) -> tuple[RejectedItem, ...]:
    """``rejected`` without the items of the images taken ``back`` that were left out on the
    starting lens (a bad fit, or an outlier of the consensus on poses from that lens; an item
    is the image's name, with `` (<target>)`` when the camera looks for several boards)."""
    names = {o.name for o in back} | {f"{o.name} ({o.target})" for o in back}
    return tuple(r for r in rejected
                 if not (r.item in names and r.reason.startswith(STARTING_LENS_REASONS)))


def rejected_by_consensus(data, paired) -> list[Observation]:
    """The views of camera ``data`` (:class:`~multieye.pipeline.camera_data.CameraData`)
    that the consensus left out of ``paired`` (its
    :class:`~multieye.pipeline.camera_data.PairedCamera`), with their points: judged on poses
    from the starting lens, they are offered to :func:`taken_back` as the bad fits are."""
    names = {r.item for r in paired.rejected if r.reason.startswith(CONSENSUS_REASON)}
    return [o for o in data.observations if o.image_points is not None
            and (o.name in names or f"{o.name} ({o.target})" in names)]


def taken_back_warning(name: str, back: Sequence[Observation], max_rms_px: float =
                       DEFAULT_MAX_RMS_PX, by_consensus: Sequence[str] = ()) -> str:
    """The warning of a camera whose images left out on the starting lens (as a bad fit, or
    by the consensus: those named in ``by_consensus``) were taken ``back``."""
    shown = ", ".join(o.name for o in back[:5]) + (" ..." if len(back) > 5 else "")
    k = sum(o.name in set(by_consensus) for o in back)
    if not k:
        return (f"{name}: {len(back)} image(s) left out as a bad fit on the starting lens "
                f"taken back: posed again on the jointly refined lens they fit within "
                f"{max_rms_px:g} px (the refinement ran again with them): {shown}")
    return (f"{name}: {len(back)} image(s) left out on the starting lens ({len(back) - k} as "
            f"a bad fit, {k} by the consensus on its poses) taken back: posed again on the "
            f"jointly refined lens they fit within {max_rms_px:g} px and agree with the rig "
            f"within {DEFAULT_THRESHOLDS[0]:g} deg / {DEFAULT_THRESHOLDS[1]:g} m (the "
            f"refinement ran again with them): {shown}")


@dataclass(frozen=True)
class Judged:
    """The outlier test of the cameras' images (:func:`judge_images`).

    Attributes
    ----------
    left_out : dict of str to ndarray of int
        Per camera the images (indices into its observations) left out, worst first.
    reasons : dict of str to dict of int to str
        Their reasons (``outlier of the joint refinement: ...``).
    warnings : tuple of str
        One per camera that left images out or kept some by the floor.
    """

    left_out: dict
    reasons: dict
    warnings: tuple[str, ...]

    def __bool__(self) -> bool:
        return any(v.size for v in self.left_out.values())


def judge_images(observations: dict[str, Sequence[Observation]],
                 rms_px: dict[str, np.ndarray], points: dict[str, np.ndarray]) -> Judged:
    """The outlier test (:func:`multieye.estimate.image_outliers.image_outliers`) of each
    camera's images from their residuals in the joint refinement.

    Parameters
    ----------
    observations : dict of str to sequence of Observation
        Per camera tested, its images in the refinement (for their names).
    rms_px : dict of str to ndarray, shape (n,)
        Per image its residuals' RMS per point at the optimum, pixels.
    points : dict of str to ndarray of int, shape (n,)
        Per image the points the refinement used.
    """
    left_out: dict[str, np.ndarray] = {}
    reasons: dict[str, dict[int, str]] = {}
    warnings: list[str] = []
    for name, obs in observations.items():
        n_pts = np.asarray(points[name], dtype=np.int64)
        rms = np.asarray(rms_px[name], dtype=np.float64)
        found = image_outliers(rms ** 2 * n_pts, n_pts)
        typical = found.sigma_px * np.sqrt(2.0)             # the median image's RMS per point
        if found.left_out.size:
            left_out[name] = found.left_out
            reasons[name] = {int(i): f"{OUTLIER_REASON}: residual RMS {rms[i]:.2f} px, "
                                 f"{rms[i] / typical:.0f} times the camera's images' "
                                 f"{typical:.2f} px" for i in found.left_out}
            shown = ", ".join(f"{obs[i].name} ({rms[i]:.2f} px)" for i in found.left_out[:5])
            warnings.append(
                f"{name}: {found.left_out.size} image(s) left out as outliers of the joint "
                f"refinement, their residuals far beyond the camera's pixel noise (its median "
                f"image {typical:.2f} px RMS): {shown}"
                + (" ..." if found.left_out.size > 5 else "")
                + "; the refinement ran again without them")
        if found.over_floor.size:
            shown = ", ".join(obs[i].name for i in found.over_floor[:5])
            warnings.append(
                f"{name}: {found.over_floor.size} more image(s) fail the outlier test of the "
                f"joint refinement but are kept, so that at most {MAX_SHARE:.0%} of the "
                f"camera's {len(obs)} images are left out: {shown}"
                + (" ..." if found.over_floor.size > 5 else "")
                + "; so many point at the lens model or the target's description rather than "
                "at single images")
    return Judged(left_out, reasons, tuple(warnings))


def with_taken_back(problem, pairing, back: dict[str, list[Observation]], rig=None):
    """``pairing`` (:class:`~multieye.pipeline.problem.Pairing`) of ``problem``
    (:class:`~multieye.pipeline.problem.Problem`: its setup and cameras) with the images taken
    ``back`` per camera that pair with its motion capture (at the camera's offset of the
    pairing) added to its measurements, in time order, and their bad-fit items out of its
    ``rejected``; also what was added per camera.  Those without motion capture stay
    rejected as they were.

    ``rig``, the refined ``(X, Y)`` (``X`` shape (n_cameras, 4, 4) in the pairing's camera
    order, ``Y`` shape (4, 4); ``A_i X = Y B_i``, docs/conventions.md, section 2), puts each
    view taken back that carries a symmetric board's other point order in the order the rig
    agrees with (:func:`agreeing_turns`), as the consensus did for the views kept from the
    start, and takes back only the views whose loop residual under it is within the
    consensus's default thresholds (:data:`multieye.estimate.consensus.DEFAULT_THRESHOLDS`)."""
    paired, added = dict(pairing.paired), {}
    for n, obs in back.items():
        data, p = problem.cameras[n], pairing.paired[n]
        if not obs or data.mocap is None:
            continue
        m = pair_stamps(data.mocap, np.array([o.stamp for o in obs]), by_name=data.by_name,
                        tolerance=data.time_tolerance, offset=pairing.offsets[n])
        if not len(m.index):
            continue
        A_new = g.inv(m.T) if problem.setup == "eye-to-base" else m.T
        new = [obs[i] for i in m.index]
        if rig is not None:
            X_n = rig[0][list(pairing.paired).index(n)]
            new = agreeing_turns(new, A_new, X_n, rig[1])
            rot, trans = measurement_residuals(
                A_new, g.inv(np.stack([o.T_cam_target for o in new])), X_n, rig[1])
            agree = (rot <= DEFAULT_THRESHOLDS[0]) & (trans <= DEFAULT_THRESHOLDS[1])
            new, m = [o for o, a in zip(new, agree) if a], _kept_pairs(m, agree)
            if not new:
                continue
        scale = np.ones(len(new)) if m.noise_scale is None else np.asarray(m.noise_scale)
        old_scale = (np.ones(len(p.observations)) if p.mocap_noise_scale is None
                     else np.asarray(p.mocap_noise_scale))
        every = list(p.observations) + new
        order = np.argsort([o.stamp for o in every], kind="stable")
        M = np.concatenate([p.T_world_mocap, m.T])[order]
        B = g.inv(np.stack([every[i].T_cam_target for i in order]))
        paired[n] = replace(p, observations=tuple(every[i] for i in order), T_world_mocap=M,
                            A=g.inv(M) if problem.setup == "eye-to-base" else M, B=B,
                            rejected=unrejected(p.rejected, new),
                            mocap_noise_scale=np.concatenate([old_scale, scale])[order])
        added[n] = new
    return _remeasured(pairing, paired), added


def agreeing_turns(observations: Sequence[Observation], A, X, Y) -> list[Observation]:
    """Each of ``observations`` that carries a symmetric board's other point order
    (:func:`multieye.pipeline.half_turns.turned`) in the order whose ``B = inv(T_cam_target)``
    agrees better with the rig's ``X``, ``Y`` (``A_i X = Y B_i``, docs/conventions.md,
    section 2; the consensus's choice, :func:`multieye.estimate.consensus.choose_poses`); the
    others unchanged.

    Parameters
    ----------
    observations : sequence of Observation
        One camera's views.
    A : ndarray, shape (n, 4, 4)
        Their ``A_i`` (from the motion capture, as the pairing builds it).
    X, Y : ndarray, shape (4, 4)
        The camera's ``X`` and the rig's ``Y``.
    """
    turnable = [getattr(o, "alternative_order", None) is not None for o in observations]
    if not any(turnable):
        return list(observations)
    B = g.inv(np.stack([o.T_cam_target for o in observations]))
    B_alt = np.stack([g.inv(o.alternative) if t else np.full((4, 4), np.nan)
                      for o, t in zip(observations, turnable)])
    turn = choose_poses(np.asarray(A, np.float64), B, B_alt, X, Y)
    return [turned(o) if t else o for o, t in zip(observations, turn)]


def _kept_pairs(m, keep):
    """The stamp pairing ``m`` (:func:`~multieye.pipeline.camera_data.pair_stamps`'s) with
    only the pairs ``keep`` (bool per pair)."""
    return replace(m, index=np.asarray(m.index)[keep], T=np.asarray(m.T)[keep],
                   gap_s=np.asarray(m.gap_s)[keep], interpolated=np.asarray(m.interpolated)[keep],
                   noise_scale=None if m.noise_scale is None else np.asarray(m.noise_scale)[keep])


def without_outliers(pairing, judged: Judged):
    """``pairing`` without the images ``judged`` outliers, each among its camera's
    ``rejected`` with its reason."""
    paired = dict(pairing.paired)
    for n, idx in judged.left_out.items():
        p = paired[n]
        keep = np.setdiff1d(np.arange(len(p.observations)), idx)
        scale = None if p.mocap_noise_scale is None else np.asarray(p.mocap_noise_scale)[keep]
        paired[n] = replace(p, A=p.A[keep], B=p.B[keep], T_world_mocap=p.T_world_mocap[keep],
                            observations=tuple(p.observations[i] for i in keep),
                            mocap_noise_scale=scale,
                            rejected=p.rejected + tuple(
                                RejectedItem(p.observations[i].name, judged.reasons[n][int(i)])
                                for i in sorted(idx)))
    return _remeasured(pairing, paired)


def _remeasured(pairing, paired: dict):
    """``pairing`` with ``paired`` and its measurements validated again."""
    meas = check_measurements([p.A for p in paired.values()], [p.B for p in paired.values()],
                              names=list(paired), per_camera_motion=False)
    return replace(pairing, paired=paired, measurements=meas)


def camera_data_now(data, used: Sequence[Observation], rejected=None):
    """A camera's :class:`~multieye.pipeline.camera_data.CameraData` as the run leaves it,
    once its images were judged on the refined lens: its bad fits among the images ``used``
    now (taken back) are among its observations and no longer among its ``rejected`` or
    ``bad_fits`` (an outlier of the joint refinement stays among its observations and is
    left out in its pairing, as a consensus outlier is).  With ``rejected`` (a rig without
    motion capture, whose cameras' rejected items are their record's): its observations are
    the images ``used`` and its ``rejected`` what it leaves out now."""
    names = {o.name for o in used}
    back = [o for o in data.bad_fits if o.name in names]
    if not back and rejected is None:
        return data
    bad_fits = tuple(o for o in data.bad_fits if o.name not in names)
    if rejected is not None:
        return replace(data, observations=tuple(used), rejected=tuple(rejected),
                       bad_fits=bad_fits)
    every = sorted(data.observations + tuple(back), key=lambda o: o.stamp)
    return replace(data, observations=tuple(every), rejected=unrejected(data.rejected, back),
                   bad_fits=bad_fits)
