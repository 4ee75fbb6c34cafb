"""Every camera of a rig at once: the solvers of ``A_i^j X^j = Y B_i^j`` behind :func:`solve`.

Synopsis
--------
>>> import multieye
>>> sol = multieye.solve(A, B, method="joint")      # doctest: +SKIP
>>> sol.X.shape, sol.Y.shape                         # doctest: +SKIP
((4, 4, 4), (4, 4))

Methods (docs/conventions.md, section 3):
=========== ================================================================ ===========
name        what                                                              cameras
=========== ================================================================ ===========
joint       least squares of the stacked joint Kronecker system, per-camera  all at once
            blocks eliminated: 9x9 eigenproblem + 3x3 solve (default)
wang2022    the paper exactly: SVD of the 18m x 9(m+1) matrix U              all at once
shah        Shah 2013, as OpenCV 4.x computes it                              one by one
li          Li, Wang, Wu 2010, as OpenCV 4.x computes it                      one by one
tabb-c1     Tabb & Yousef 2017, iterative, Euler angles, cost c1              one by one
tabb-c2     Tabb & Yousef 2017, iterative, Euler angles, cost c2              one by one
=========== ================================================================ ===========

Single-camera methods on a rig solve each camera alone and combine the m estimates of Y
as the paper did: chordal mean of the rotations, mean of the translations.  The
per-camera estimates stay on ``Solution.Y_per_camera``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from multieye.core.errors import DegenerateMotionError, InputError
from multieye.core.geometry import make_transform, rotation_mean
from multieye.solvers.checks import (
    check_measurements,
    check_motion,
    check_transforms,
)
from multieye.solvers.measurements import Measurements
from multieye.solvers.joint import solve_joint
from multieye.solvers.li import solve_li_single
from multieye.solvers.refine_poses import check_refine_options, refine_solution
from multieye.solvers.result import CameraResidual, Solution
from multieye.solvers.shah import solve_shah_single
from multieye.solvers.tabb import solve_tabb_single
from multieye.solvers.wang2022 import solve_wang2022

__all__ = ["solve", "METHODS", "JOINT_METHODS", "SINGLE_METHODS", "Solution", "CameraResidual",
           "check_measurements", "check_transforms", "combine_y"]

JOINT_METHODS: dict[str, Callable[[Measurements], tuple]] = {
    "joint": solve_joint,
    "wang2022": solve_wang2022,
}

SINGLE_METHODS: dict[str, Callable[[np.ndarray, np.ndarray], tuple]] = {
    "shah": solve_shah_single,
    "li": solve_li_single,
    "tabb-c1": lambda A, B: solve_tabb_single(A, B, "c1"),
    "tabb-c2": lambda A, B: solve_tabb_single(A, B, "c2"),
}

#: Every method name accepted by :func:`solve` (:mod:`multieye.solvers.methods`, which names
#: them without importing the solvers, in the same order).
METHODS: tuple[str, ...] = tuple(JOINT_METHODS) + tuple(SINGLE_METHODS)


def combine_y(Ys: np.ndarray) -> np.ndarray:
    """Combine per-camera estimates of Y ``(m, 4, 4)``: rotation mean, translation mean."""
    return make_transform(rotation_mean(Ys[:, :3, :3]), Ys[:, :3, 3].mean(axis=0))


def solve(A: Sequence[np.ndarray] | np.ndarray | Measurements,
          B: Sequence[np.ndarray] | np.ndarray | None = None, method: str = "joint", *,
          refine: bool = False, names: list[str] | None = None, **refine_options) -> Solution:
    """Solve ``A_i^j X^j = Y B_i^j`` for every camera j and the shared Y.

    Parameters
    ----------
    A, B : sequence of array_like, each shape (N_j, 4, 4)
        One entry per camera (a single (N, 4, 4) array means one camera).  Eye-to-base:
        ``A = T_marker_world`` (inverse motion capture), ``B = T_target_cam`` (inverse PnP).
        Eye-on-hand: ``A = T_world_body`` (motion capture), ``B = T_target_cam``.
        See docs/conventions.md, section 2.  Or ``A`` is a
        :class:`~multieye.solvers.checks.Measurements` validated before
        (:func:`~multieye.solvers.checks.check_measurements`) and ``B`` is omitted: only the
        motion test of the method runs again.
    method : str
        One of :data:`METHODS`; default ``"joint"``.
    refine : bool
        Follow the closed form with a maximum-likelihood refinement of the pose residuals
        and fill ``Solution.covariance`` (``multieye.solvers.refine_poses``).
    names : list of str, optional
        Camera names used in error messages.
    **refine_options
        Passed to the refinement (noise levels, robust loss).

    Returns
    -------
    Solution
        ``X`` (m, 4, 4): ``T_world_cam`` (eye-to-base) or ``T_body_cam`` (eye-on-hand);
        ``Y`` (4, 4): ``T_marker_target`` or ``T_world_target``.

    Raises
    ------
    InputError, TooFewMeasurementsError, DegenerateMotionError
        See :func:`multieye.solvers.checks.check_measurements`.  Joint methods need the
        pooled motion of all cameras to rotate about two axes; single-camera methods need
        it for every camera.  DegenerateMotionError also when the method's closed form gives
        a non-finite number (never returned as NaN).
    """
    if not isinstance(method, str) or method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if refine_options and not refine:
        raise InputError(f"refinement options {', '.join(sorted(refine_options))} given without "
                         "refine=True")
    if refine:
        check_refine_options(refine_options)
    joint = method in JOINT_METHODS
    meas = check_measurements(A, B, names=names, per_camera_motion=not joint)
    if isinstance(A, Measurements):     # validated before: only the motion test is new
        check_motion(meas, per_camera_motion=not joint)
    Y_per_camera = None
    if joint:
        X, Y = JOINT_METHODS[method](meas)
    else:
        As, Bs = meas.split(meas.A), meas.split(meas.B)
        pairs = [SINGLE_METHODS[method](Aj, Bj) for Aj, Bj in zip(As, Bs)]
        X = np.stack([p[0] for p in pairs])
        Y_per_camera = np.stack([p[1] for p in pairs])
        Y = combine_y(Y_per_camera)
    _check_finite(X, Y, method, meas)
    sol = Solution(X=X, Y=Y, method=method, Y_per_camera=Y_per_camera, measurements=meas)
    if refine:
        sol = refine_solution(sol, **refine_options)
    return sol


def _check_finite(X: np.ndarray, Y: np.ndarray, method: str, meas: Measurements) -> None:
    """Refuse a closed form with NaN or infinite entries (X: (m, 4, 4), Y: (4, 4)), naming
    the cameras of ``meas`` whose ``X`` is not finite."""
    bad = [str(meas.names[j]) for j in range(len(X)) if not np.isfinite(X[j]).all()]
    if bad or not np.isfinite(Y).all():
        where = f"X of camera {', '.join(bad)}" if bad else "Y"
        raise DegenerateMotionError(
            f"method {method}: the closed form gives a non-finite {where}, so these "
            "measurements do not determine it for this method; try method 'joint' or "
            "rotate the target about more axes")
