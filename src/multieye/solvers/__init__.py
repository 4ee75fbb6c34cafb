"""Closed forms of the hand-eye problem and the pose-level refinement behind them.

``A_i^j X^j = Y B_i^j`` for a rig (:func:`solve`, :mod:`multieye.solvers.registry`) and the general
``A_i X_a = Y_b B_i`` (:func:`solve_general`, :mod:`multieye.solvers.general`); with
``refine=True`` both continue with the maximum-likelihood refinement of the pose residuals
(:mod:`multieye.solvers.refine_poses`) on the engine of :mod:`multieye.optimize`.

Synopsis
--------
>>> from multieye.solvers import solve, solve_general     # doctest: +SKIP
>>> sol = solve(A, B, method="joint")                  # doctest: +SKIP
"""

from multieye.solvers.general import solve_general
from multieye.solvers.groups import GeneralSolution, MeasurementGroup
from multieye.solvers.result import CameraResidual, Solution
from multieye.solvers.registry import (
    JOINT_METHODS,
    METHODS,
    SINGLE_METHODS,
    check_measurements,
    check_transforms,
    combine_y,
    solve,
)

__all__ = ["solve", "solve_general", "METHODS", "JOINT_METHODS", "SINGLE_METHODS", "Solution",
           "GeneralSolution", "MeasurementGroup", "CameraResidual", "check_measurements",
           "check_transforms", "combine_y"]
