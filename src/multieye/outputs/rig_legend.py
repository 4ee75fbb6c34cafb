"""The caption of the report's rig figures (:func:`multieye.outputs.figures_rig.rig_pngs`):
one sentence per kind of mark, saying what is really drawn (the motion capture, the target
from instant to instant, or the rig's own trajectory before the boards); and what links the
cameras of a rig without motion capture (:func:`linked_by`).  Plain text.
"""

from __future__ import annotations

from multieye.io.calibration_json import CalibrationRecord

__all__ = ["rig_legend", "linked_by"]


def rig_legend(sc, depth: float, magnified, in_fixed_frame: bool, max_dots: int) -> list[str]:
    """One sentence per kind of mark of :func:`multieye.outputs.figures_rig.rig_pngs`: ``sc``
    its scene, ``depth`` the frustums' depth (metres), ``magnified`` the uncertainty's
    ``(factor, 3-sigma mm, 3-sigma degrees)`` or None, ``max_dots`` the most dots per camera."""
    frame = sc.frame
    legend = [f"frustums {depth:.2f} m deep, the thick edge at the image top"]
    if sc.targets:
        many = max(len(t) for t in sc.targets) > max_dots
        legend.append(("dots: each view's board origin placed through the rig's pose and the "
                       "camera (they gather at the boards, their spread the residuals in "
                       "space)" if sc.by_motion else "dots: the target's origin at each used "
                       "image")
                      + (f" ({max_dots} spread evenly over a camera's images where it has "
                         "more)" if many else ""))
    if sc.trajectories:
        legend.append(_trajectory_legend(sc.trajectory_pose, sc.by_motion))
    legend.append("axes x red, y green, z blue: the reference camera's"
                  + (f" and the origin of {frame}" if in_fixed_frame else ""))
    if magnified is not None:
        factor, t3, r3 = magnified
        times = f"magnified {factor:g} times" if factor > 1 else "to scale"
        legend.append(f"around each camera its 3σ position ellipsoid (ellipse from above) and "
                      f"the 3σ cone of its optical axis (wedge from above), {times}; the "
                      f"largest: {t3 * 1e3:.2g} mm and {r3:.2g}°")
    else:
        legend.append("no uncertainty drawn: the run computed no covariance")
    return legend


def _trajectory_legend(pose: str, by_motion: bool) -> str:
    """What the grey line is: the motion capture, the target's origin from instant to instant
    (no motion capture, one board) or the rig's trajectory (linked by its motion)."""
    if pose == "T_ref_target":
        return ("grey line: the target's origin from instant to instant, in the reference "
                f"camera's frame ({pose}; no motion capture)")
    if by_motion:
        return ("grey line: the rig's trajectory, the reference camera's position at every "
                f"instant ({pose}, estimated from the boards; no motion capture)")
    return f"grey line: the motion capture ({pose})"


def linked_by(rec: CalibrationRecord) -> str:
    """What links the cameras of a rig without motion capture to the reference camera, from
    their ``links`` (``calibration.json``)."""
    if len(rec.cameras) == 1:
        return (f"one camera, {rec.cameras[0].name}, whose frame is the rig's: nothing to "
                "link")
    ref = rec.reference_camera
    links = {c.name: c.links for c in rec.cameras if c.name != ref}
    if any(v is None for v in links.values()):          # files of earlier versions
        return "the cameras are linked by the views they share"
    motion = [n for n, v in links.items() if v.motion]
    overlap = [n for n, v in links.items() if v.overlap and n not in motion]
    parts = ([f"{_names(overlap)} by the views {'it shares' if len(overlap) == 1 else 'they share'} "
              "with another camera (one board at one instant)"] if overlap else []) + (
        [f"{_names(motion)} by the rig's motion before the boards (a board a linked camera "
         "saw at another instant)"] if motion else [])
    return (f"linked to the reference camera {ref}: " + "; ".join(parts) if parts
            else "no camera is linked to the reference camera " + ref)


def _names(cams: list[str]) -> str:
    return cams[0] if len(cams) == 1 else ", ".join(cams[:-1]) + " and " + cams[-1]
