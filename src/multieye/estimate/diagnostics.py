"""Weak-motion diagnostics: how well each camera's measurements determine its extrinsic.

``A_i X = Y B_i`` determines the rotation only when the relative rotations ``R_A[k] R_A[l]^T``
turn about at least two different axes, and its translation only as well as those rotations
are spread (Tsai and Lenz; paper section IV).  The input checks of :mod:`multieye.solve`
stop only the hopeless case (no second axis at all, to 0.06 degrees); these diagnostics
measure the weak cases before solving, per camera, and turn them into advice:

- ``rotation_range_deg``: the largest angle between two orientations of the motion-capture
  poses (``R_A``; equal to that of the target poses seen by the camera up to noise);
- ``rotation_spread_deg``: RMS relative rotation about each principal axis
  (:func:`multieye.solvers.checks.rotation_spread`), descending; a second value near zero
  means every rotation shares one axis;
- ``rotation_condition``: ``n / lambda_2`` of the camera's reduced rotation system
  ``n I - K K^T / n`` (``K = sum_i R_B ⊗ R_A``, paper eq. 6 with ``X`` eliminated; its
  eigenvalues lie in [0, n]): the smallest eigenvalue belongs to the solution, the second
  says how far the nearest other rotation is from fitting as well;
- ``translation_condition``: ``n / lambda_min`` of the reduced translation system
  ``n I - S S^T / n`` (``S = sum_i R_A``, ``t_X`` eliminated from ``R_A t_X - t_Y = ...``;
  eigenvalues in [0, n]).

Both conditions are 1 at best (orientations spread over all of SO(3)), grow like
``1 / theta^2`` for rotations of RMS angle ``theta`` (radians) and are infinite for rotations
about a single axis: roughly the factor by which the motion amplifies the variance of the
measurement noise in the worst direction of the unknown.

In the joint problem (``joint``) a camera whose own motion is weak still gets an answer, from
the shared ``Y`` that the other cameras determine; the warning says so.

Synopsis
--------
>>> from multieye.estimate.diagnostics import motion_diagnostics
>>> diag = motion_diagnostics(A, B, names=["cam0", "cam1"])     # doctest: +SKIP
>>> for w in diag.warnings: print(w)                       # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core.arguments import with_fields
from multieye.core.errors import InputError
from multieye.core.problem import SETUPS
from multieye.solvers.checks import (
    check_measurements,
    rotation_spread,
)

__all__ = ["CameraMotion", "MotionDiagnostics", "MotionOptions", "motion_diagnostics",
           "MIN_ROTATION_RANGE_DEG", "MIN_SECOND_AXIS_DEG", "MIN_AXIS_RATIO",
           "MAX_CONDITION"]

F64 = NDArray[np.float64]

#: A camera whose orientations span less than this many degrees gets a warning.
MIN_ROTATION_RANGE_DEG = 10.0
#: RMS rotation about the second principal axis below which the motion counts as about one
#: axis, degrees ...
MIN_SECOND_AXIS_DEG = 0.5
#: ... or below this fraction of the rotation about the first axis.
MIN_AXIS_RATIO = 0.1
#: Condition of the reduced rotation or translation system above which a warning is given
#: (100: the rotations' RMS angle is below about 6 degrees in some direction).
MAX_CONDITION = 100.0
#: Orientations compared pairwise for the rotation range at most (evenly subsampled above).
_MAX_RANGE_POSES = 2000


@dataclass(frozen=True)
class CameraMotion:
    """Motion numbers of one camera (module docstring).

    Attributes
    ----------
    name : str
    measurements : int
    rotation_range_deg : float
    rotation_spread_deg : ndarray, shape (3,)
        Descending.
    rotation_condition : float
        ``inf`` when the second eigenvalue vanishes.
    translation_condition : float
        ``inf`` when the smallest eigenvalue vanishes.
    """

    name: str
    measurements: int
    rotation_range_deg: float
    rotation_spread_deg: F64
    rotation_condition: float
    translation_condition: float

    def as_dict(self) -> dict:
        """Plain-JSON form (``inf`` becomes None) for ``calibration.json``."""
        def num(v: float):
            return float(v) if np.isfinite(v) else None
        return {"measurements": self.measurements,
                "rotation_range_deg": num(self.rotation_range_deg),
                "rotation_spread_deg": [num(v) for v in self.rotation_spread_deg],
                "rotation_condition": num(self.rotation_condition),
                "translation_condition": num(self.translation_condition)}


@dataclass(frozen=True)
class MotionDiagnostics:
    """Result of :func:`motion_diagnostics`.

    Attributes
    ----------
    cameras : tuple of CameraMotion
    warnings : tuple of str
        One line per problem, each naming its camera and what to record instead.
    """

    cameras: tuple[CameraMotion, ...]
    warnings: tuple[str, ...]

    def as_dict(self) -> dict:
        """``{"cameras": {name: {...}}, "warnings": [...]}`` for ``calibration.json``."""
        return {"cameras": {c.name: c.as_dict() for c in self.cameras},
                "warnings": list(self.warnings)}


def _rotation_range(R: F64) -> float:
    """Largest angle (radians) between two of the rotations (n, 3, 3)."""
    if len(R) > _MAX_RANGE_POSES:
        R = R[np.linspace(0, len(R) - 1, _MAX_RANGE_POSES).astype(int)]
    F = R.reshape(len(R), 9)
    tr = np.min(F @ F.T)                                   # trace(R_k^T R_l) = <R_k, R_l>_F
    return float(np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0)))


def _ratio(big: float, small: float) -> float:
    return big / small if small > 1e-12 * max(big, 1e-300) else float("inf")


def _camera_motion(name: str, RA: F64, RB: F64, A: F64) -> CameraMotion:
    n = len(RA)
    K = np.einsum("npq,nrs->prqs", RB, RA).reshape(9, 9)   # sum R_B ⊗ R_A
    lam = np.linalg.eigvalsh(n * np.eye(9) - K @ K.T / n)
    S = RA.sum(axis=0)
    mu = np.linalg.eigvalsh(n * np.eye(3) - S @ S.T / n)
    return CameraMotion(name=name, measurements=n,
                        rotation_range_deg=float(np.degrees(_rotation_range(RA))),
                        rotation_spread_deg=np.degrees(rotation_spread(A)),
                        rotation_condition=_ratio(n, max(lam[1], 0.0)),
                        translation_condition=_ratio(n, max(mu[0], 0.0)))


@dataclass(frozen=True)
class MotionOptions:
    """What :func:`motion_diagnostics` calls weak motion, and how it advises.

    Attributes
    ----------
    setup : {"eye-to-base", "eye-on-hand"}
        Only changes the advice (move the target, or move the rig).
    names : sequence of str, optional
        Camera names for arrays ``A, B``; default ``cam0, cam1, ...`` (validated
        :class:`Measurements` bring their own).
    min_range_deg : float
        Warn below this rotation range.
    min_second_axis_deg, min_axis_ratio : float
        Warn that the rotations are about one axis when the RMS rotation about the second
        principal axis is below ``min_second_axis_deg`` or below ``min_axis_ratio`` times the
        rotation about the first.
    max_condition : float
        Warn above this condition of the reduced rotation or translation system (when no
        other warning already explains it).
    """

    setup: str = "eye-to-base"
    names: Sequence[str] | None = None
    min_range_deg: float = MIN_ROTATION_RANGE_DEG
    min_second_axis_deg: float = MIN_SECOND_AXIS_DEG
    min_axis_ratio: float = MIN_AXIS_RATIO
    max_condition: float = MAX_CONDITION


def _advice(name: str, opts: MotionOptions, what: str) -> str:
    """``what`` done to the target in front of the camera, or to the rig while it sees it."""
    if opts.setup == "eye-to-base":
        return f"{what.format(thing='the target')} in front of {name}"
    return f"{what.format(thing='the rig')} while {name} sees the target"


def motion_diagnostics(A, B=None, options: MotionOptions = MotionOptions(),
                       **kw) -> MotionDiagnostics:
    """Measure every camera's motion and warn, with advice, where it is weak.

    Parameters
    ----------
    A, B : sequence of array_like, each shape (N_j, 4, 4)
        One entry per camera, as for :func:`multieye.solve` (docs/conventions.md, section 2);
        or ``A`` is a :class:`~multieye.solvers.checks.Measurements` validated before and
        ``B`` is omitted (no checks run again).
    options : MotionOptions
        The setup, the camera names and the thresholds.
    **kw
        Or :class:`MotionOptions`' fields as keyword arguments (``setup="eye-on-hand"``).

    Returns
    -------
    MotionDiagnostics

    Raises
    ------
    InputError, TooFewMeasurementsError
        As :func:`multieye.solvers.checks.check_measurements` (bad shapes, non-rigid
        transforms, fewer than 3 measurements for a camera).  Weak or degenerate motion is
        reported, not raised.
    """
    opts = with_fields(options, kw, MotionOptions, "options")
    setup, min_range_deg, max_condition = opts.setup, opts.min_range_deg, opts.max_condition
    min_second_axis_deg, min_axis_ratio = opts.min_second_axis_deg, opts.min_axis_ratio
    if setup not in SETUPS:
        raise InputError(f"setup must be one of {SETUPS}, got {setup!r}")
    meas = check_measurements(A, B, names=list(opts.names) if opts.names is not None
                              else None, per_camera_motion=False)
    cameras, warnings = [], []
    for j, (RA, RB, Aj) in enumerate(zip(meas.split(meas.RA), meas.split(meas.RB),
                                          meas.split(meas.A))):
        name = meas.names[j]
        cam = _camera_motion(name, RA, RB, Aj)
        cameras.append(cam)
        s0, s1 = cam.rotation_spread_deg[:2]
        shared = ("T_marker_target" if setup == "eye-to-base" else "T_world_target")
        if cam.rotation_range_deg < min_range_deg:
            warnings.append(
                f"{name}: rotation range {cam.rotation_range_deg:.1f} deg < {min_range_deg:g} "
                f"deg, so its extrinsic is poorly determined; "
                + _advice(name, opts, "tilt {thing} by 30 deg or more about two axes"))
        elif s1 < min_second_axis_deg or s1 < min_axis_ratio * s0:
            why = (f"so {name} alone does not determine its extrinsic and it rests on the "
                   f"other cameras' estimate of {shared}" if meas.m > 1
                   else "so its extrinsic is poorly determined")
            warnings.append(
                f"{name}: all rotations are about one axis (RMS {s0:.1f} deg about it, "
                f"{s1:.2f} deg about any other), {why}; "
                + _advice(name, opts, "rotate {thing} about a second axis"))
        elif max(cam.rotation_condition, cam.translation_condition) > max_condition:
            warnings.append(
                f"{name}: the rotations are small about some axis (RMS {s0:.1f}, {s1:.1f}, "
                f"{cam.rotation_spread_deg[2]:.1f} deg about the principal axes; conditions "
                f"{cam.rotation_condition:.3g} rotation, {cam.translation_condition:.3g} "
                f"translation > {max_condition:g}), so its extrinsic is poorly determined; "
                + _advice(name, opts, "turn {thing} further, by 30 deg or more about two axes"))
    return MotionDiagnostics(cameras=tuple(cameras), warnings=tuple(warnings))
