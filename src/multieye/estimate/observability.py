"""What a rig linked by its motion leaves undetermined, named (issue 34, item 3).

When the rig only turns about one axis (a vehicle on a floor: every turn about the vertical),
shifting a camera along that axis and the boards it sees by the same amount changes no
pixel unless loops close it: another camera sees those boards at instants whose rig pose
is known through other boards, or two cameras see one board at one instant.  Whether the
loops close depends on which camera saw which board when, so it is read off the refined
problem itself, not guessed from the motion: a direction of a camera's pose whose standard
deviation is more than :data:`UNDETERMINED_RATIO` times that of the camera's best-determined
direction of the same kind (translation, rotation), or that the information matrix does not
determine at all, is *undetermined*.  Each is named in the rig's and the camera's frames,
with the axis the rig turned about when it turned about one axis only
(:func:`turn_axis`), and what would determine it.

Synopsis
--------
>>> obs = observability(result, views)                      # doctest: +SKIP
>>> obs.undetermined[0].message                             # doctest: +SKIP
'cam2: translation along the axis the rig turned about (y of the rig, ...) ...'
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core.lie import log_so3

__all__ = ["UNDETERMINED_RATIO", "SINGLE_AXIS_SPREAD", "Undetermined", "Observability",
           "observability", "turn_axis", "one_axis_advice"]

F64 = NDArray[np.float64]

#: A direction is undetermined when its standard deviation exceeds this many times that of
#: the camera's best-determined direction of the same kind.  Measured (tests' rigs, 0.3 px):
#: at most 10 with 6-DoF motion or a floor-driven rig that turned fully; 390 to 3500 for
#: the heights of a floor-driven rig whose cameras each see their own boards; its turn about
#: the vertical 44 to 50 times (0.4 degrees: weak, but determined and in the covariance).
UNDETERMINED_RATIO = 100.0
#: The rig turned about one axis only when the second singular value of its turns' rotation
#: vectors is below this fraction of the first (about 1 degree of tilt per radian of turn).
SINGLE_AXIS_SPREAD = 0.02

_FIX = ("tilt the rig while recording (turn it about a second axis, not only about {axis}), "
        "turn it further so that each camera also sees the boards the others saw, or let it "
        "see a board together with another camera at the same instant (overlap)")


@dataclass(frozen=True)
class Undetermined:
    """One direction of a camera's pose the data do not determine.

    Attributes
    ----------
    camera : str
    kind : {"translation", "rotation"}
    direction_rig, direction_camera : ndarray, shape (3,)
        Unit vector in the rig's (reference camera's) frame and in the camera's.
    sigma : float
        Its standard deviation (metres or radians; inf when not determined at all).
    best_sigma : float
        That of the camera's best-determined direction of the same kind.
    along_turn_axis : bool
        Within 10 degrees of the one axis the rig turned about.
    message : str
    """

    camera: str
    kind: str
    direction_rig: F64
    direction_camera: F64
    sigma: float
    best_sigma: float
    along_turn_axis: bool
    message: str


@dataclass(frozen=True)
class Observability:
    """:func:`observability`'s answer: ``turn_axis`` (the rig frame's unit axis when the rig
    turned about one axis only, else None) and every undetermined direction."""

    turn_axis: F64 | None
    undetermined: tuple[Undetermined, ...]

    @property
    def cameras(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(u.camera for u in self.undetermined))


def turn_axis(T_world_rig, spread: float = SINGLE_AXIS_SPREAD) -> F64 | None:
    """The one axis (rig frame, unit) the rig turned about, or None when it turned about
    two or more (the second singular value of its turns' rotation vectors above ``spread``
    times the first).

    Parameters
    ----------
    T_world_rig : array_like, shape (K, 4, 4)
    spread : float
    """
    R = np.asarray(T_world_rig, dtype=np.float64)[:, :3, :3]
    w = np.array([log_so3(R[0].T @ Rk) for Rk in R[1:]])
    if len(w) == 0 or not np.any(w):
        return None
    _, s, Vt = np.linalg.svd(w, full_matrices=False)
    if len(s) > 1 and s[1] > spread * s[0]:
        return None
    return Vt[0] * np.sign(Vt[0][np.argmax(np.abs(Vt[0]))])


def one_axis_advice(axis: F64) -> str:
    """What fixes a rig turned about ``axis`` only (rig frame, unit), as the doubt says it."""
    return _FIX.format(axis=_axis_name(axis))


def _axis_name(u: F64) -> str:
    """``u`` as the rig frame's axis it lies along, or its components."""
    k = int(np.argmax(np.abs(u)))
    if abs(u[k]) > np.cos(np.radians(10.0)):
        return f"{'xyz'[k]} of the rig"
    return "({:+.2f}, {:+.2f}, {:+.2f}) in the rig's frame".format(*u)


def _directions(cov: F64, null: F64 | None, ratio: float):
    """Undetermined unit directions of a 3x3 block: (direction, sigma, best sigma)."""
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    sd = np.sqrt(np.clip(w, 0.0, None))
    out = []
    if null is not None:
        for v in null.T:
            if np.linalg.norm(v) > 0.01:
                out.append((v / np.linalg.norm(v), np.inf, float(sd.max())))
    if not out and sd[0] > 0 and sd[-1] > ratio * sd[0]:
        out = [(V[:, k], float(sd[k]), float(sd[0])) for k in range(3) if sd[k] > ratio * sd[0]]
    return out


def observability(result, views, *, ratio: float = UNDETERMINED_RATIO) -> Observability:
    """Every undetermined direction of every camera's ``T_ref_cam`` (module docstring).

    Parameters
    ----------
    result : MotionResult
        Its ``T_ref_cam``, ``covariance`` (per camera, rotation vector then translation, left
        perturbation in the rig's frame), ``T_world_rig`` (for the axis the rig turned
        about) and ``null_space`` (per camera its part of the directions the information
        matrix does not determine at all, which the engine's pseudo-inverse leaves out of
        the covariance) (:func:`multieye.estimate.refine_motion.refine_motion`).
    views : MotionViews
        For the cameras' names.
    ratio : float
    """
    T = np.asarray(result.T_ref_cam, dtype=np.float64)
    cov = np.asarray(result.covariance, dtype=np.float64)
    axis = turn_axis(result.T_world_rig)
    out = []
    for j, name in enumerate(views.names):
        if not np.any(cov[j]):
            continue
        for kind, sl in (("rotation", slice(0, 3)), ("translation", slice(3, 6))):
            null = None if result.null_space is None else result.null_space[j][sl]
            for u, sigma, best in _directions(cov[j][sl, sl], null, ratio):
                u = u * (np.sign(u @ axis) or 1.0) if axis is not None else u
                along = axis is not None and abs(u @ axis) > np.cos(np.radians(10.0))
                out.append(Undetermined(name, kind, u, T[j, :3, :3].T @ u, sigma, best, along,
                                        _message(name, kind, u, T[j, :3, :3].T @ u, sigma,
                                                 best, axis, along)))
    return Observability(axis, tuple(out))


def _message(name, kind, u, uc, sigma, best, axis, along) -> str:
    unit, scale = ("mm", 1e3) if kind == "translation" else ("deg", np.degrees(1.0))
    where = (f"the axis the rig turned about ({_axis_name(u)})" if along else _axis_name(u))
    how = ("not determined at all" if not np.isfinite(sigma) else
           f"standard deviation {sigma * scale:.3g} {unit}, {sigma / best:.0f} times its "
           f"best-determined direction's {best * scale:.3g} {unit}")
    turned = ("the rig turned about one axis only" if axis is not None
              else "the rig's motion and the boards seen do not close the loops")
    return (f"observability: {name}: {kind} along {where}, "
            "({:+.2f}, {:+.2f}, {:+.2f}) in {}'s frame, ".format(*uc, name)
            + f"is undetermined by the data ({how}): {turned}; "
            + _FIX.format(axis=_axis_name(axis) if axis is not None else "one axis"))
