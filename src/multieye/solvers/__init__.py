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

from multieye.core.lazy_names import lazy_names

#: Public names and the submodule that defines each, imported when first used: the solvers
#: import SciPy's sparse and dense linear algebra, which a command imports while its images
#: are detected, not before (issue 21; :mod:`multieye.solvers.methods` names the methods
#: without them).
_LAZY = {
    "solve_general": ".general",
    "GeneralSolution": ".groups",
    "MeasurementGroup": ".groups",
    "CameraResidual": ".result",
    "Solution": ".result",
    "JOINT_METHODS": ".registry",
    "METHODS": ".registry",
    "SINGLE_METHODS": ".registry",
    "check_measurements": ".registry",
    "check_transforms": ".registry",
    "combine_y": ".registry",
    "solve": ".registry",
}

__all__ = ["solve", "solve_general", "METHODS", "JOINT_METHODS", "SINGLE_METHODS", "Solution",
           "GeneralSolution", "MeasurementGroup", "CameraResidual", "check_measurements",
           "check_transforms", "combine_y"]


__getattr__, __dir__ = lazy_names(__name__, _LAZY)
