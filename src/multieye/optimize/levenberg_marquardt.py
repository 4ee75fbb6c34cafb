"""Levenberg-Marquardt on a robust cost, and the covariance at its optimum.

The cost is scipy's: ``sum f_scale^2 rho(r^2 / f_scale^2) / 2`` over every residual component
``r`` of every group (:mod:`multieye.core.robust_loss`).  Each iteration

1. evaluates every group's residuals and Jacobians at the current values, a chunk of
   :data:`CHUNK_SEGMENTS` segments at a time (:meth:`~multieye.optimize.blocks.ResidualGroup.
   linearize_chunks`),
2. weights them by the loss's IRLS weights ``rho'`` (which makes the weighted Gauss-Newton step
   a descent direction of the robust cost; its stationary points are the robust cost's);
   near the optimum (``Options.newton_below``) the Hessian instead by the robust cost's own
   curvature ``rho' + 2 z rho''`` (at least 0; Triggs et al. 2000, section 4.3, as scipy's
   ``least_squares`` and Ceres do), the gradient still by ``rho'``: the IRLS weights
   overstate the curvature of the residuals beyond the loss's threshold (Huber's has none
   there), so IRLS converges only linearly (on the 4 x 100 rig by a factor 0.37 per
   iteration, six iterations to a relative decrease of 1e-8) where these steps converge in
   two; far from the optimum they are the safer ones, since they majorise the cost,
3. sums each chunk into the normal equations and lets its Jacobian go (so the memory holds the
   normal equations, not the Jacobian of every residual), eliminates the per-measurement blocks by the Schur complement
   (:mod:`multieye.optimize.normal_equations`) and solves the damped system,
4. moves every block on its manifold (:meth:`multieye.optimize.blocks.Blocks.retract`) and
   keeps the step if the cost went down (damping / 10), else retries with damping x 10.

The charts are re-anchored at every accepted step, so the Jacobians are always taken at zero
perturbation and the covariance (:func:`covariance`) is in the perturbation convention of each
family at the optimum (``R = Exp(phi) R_hat`` for ``se3-left``).

Synopsis
--------
>>> result = minimize(families, groups, Options(loss="huber"))   # doctest: +SKIP
>>> cov = covariance(result.families, groups).kept                # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core.arguments import real_number
from multieye.core.errors import InputError
from multieye.core.robust_loss import LOSSES, rho
from multieye.optimize.blocks import Blocks, ResidualGroup
from multieye.optimize.clusters import ClusterRecord, jackknife_covariance
from multieye.optimize.normal_equations import (
    Assembly,
    Layout,
    NormalEquations,
    assemble,
    marginal_covariance,
    solve_step,
)
from multieye.optimize.threads import threads_for

__all__ = ["Options", "Result", "Covariance", "minimize", "covariance", "evaluate",
           "covariance_and_residuals", "normal_equations", "CHUNK_SEGMENTS", "NEAR_DAMPING"]

#: Segments (images) linearised at once when the normal equations are summed.
CHUNK_SEGMENTS = 256
#: ``Options.initial_damping`` for a minimisation that starts at an earlier one's optimum (a
#: problem whose weights or noise levels moved a little): the default 1e-4 of the diagonal,
#: divided by 10 per accepted step, shortened the steps along ill-determined directions (a
#: lens's k3 against k1, k2): 5 iterations to 1e-7 above the minimum on the 4 x 100 rig of
#: benchmarks/bench_peers.py with the lenses unknown, against 2 to 2e-10 from this.  A step
#: that raises the cost still raises the damping.
NEAR_DAMPING = 1e-8

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Options:
    """How :func:`minimize` runs.

    Attributes
    ----------
    loss : {"linear", "huber", "soft_l1", "cauchy", "arctan"}
        Robust loss on every residual component (scipy's names).
    f_scale : float
        Where the loss departs from least squares, in the residuals' units (sigmas).
    max_iter : int
        Iterations (Jacobian evaluations) at most.
    tol : float
        Stop when an accepted step lowers the cost by less than ``tol`` times the cost.
    initial_damping : float
        Marquardt's damping of the first step, as a share of the diagonal
        (:data:`NEAR_DAMPING` from an earlier optimum).
    newton_below : float
        Relative decrease of the cost (of an accepted step) below which the steps use the
        robust cost's own curvature (module docstring, step 2); 0 (the default): never, inf:
        from the first step.
    """

    loss: str = "linear"
    f_scale: float = 1.0
    max_iter: int = 100
    tol: float = 1e-10
    initial_damping: float = 1e-4
    newton_below: float = 0.0

    def __post_init__(self):
        if self.loss not in LOSSES:
            raise InputError(f"unknown loss {self.loss!r}; expected one of {', '.join(LOSSES)}")
        real_number(self.f_scale, "f_scale", positive=True)
        if not (isinstance(self.max_iter, (int, np.integer)) and self.max_iter >= 1):
            raise InputError(f"max_iter must be a whole number >= 1, got {self.max_iter!r}")
        if not real_number(self.tol, "tol") >= 0:
            raise InputError(f"tol must be a non-negative number, got {self.tol!r}")
        if not (isinstance(self.newton_below, (int, float, np.floating))
                and self.newton_below >= 0):
            raise InputError("newton_below must be a non-negative number (inf: from the first "
                             f"step), got {self.newton_below!r}")


@dataclass(frozen=True)
class Result:
    """What :func:`minimize` reached.

    Attributes
    ----------
    families : tuple of Blocks
        At the optimum, in the order given.
    cost : float
        Robust cost there.
    iterations : int
        Jacobian evaluations.
    evaluations : int
        Residual evaluations.
    converged : bool
    message : str
    residuals : list
        Each group's ``(residuals (n_rows, dim), None)`` at ``families``, as :func:`evaluate`
        (``jacobians=False``) gives them: the last evaluation's, so that a caller needing
        them does not evaluate again.
    """

    families: tuple[Blocks, ...]
    cost: float
    iterations: int
    evaluations: int
    converged: bool
    message: str
    residuals: list | None = None

    def value(self, name: str) -> F64:
        """Values of the family called ``name``."""
        for f in self.families:
            if f.name == name:
                return f.value
        raise KeyError(name)


@dataclass(frozen=True)
class Covariance:
    """``(J^T J)^-1`` of the noise-normalised residuals at a point.

    Attributes
    ----------
    kept : ndarray, shape (k, k)
        Over the blocks of the families not eliminated, family by family in the given order,
        block by block, each in its manifold's perturbation (rotation then translation).
    local : ndarray, shape (n_local, d, d), or None
        Marginal covariance of each eliminated block (when asked for).
    layout : Layout
        Where each family's parameters sit in ``kept``.
    undetermined : ndarray, shape (k, r)
        Unit directions of the kept parameters that the data do not determine (r = 0 in a
        regular problem); ``kept`` is then the inverse on the other directions only.
    jackknife : ndarray, shape (k, k), or None
        The cluster-robust (delete-one-cluster jackknife) covariance of the kept parameters
        when asked for (:func:`covariance_and_residuals`), unscaled like ``kept``.
    clusters : int
        Clusters it was formed from.
    """

    kept: F64
    local: F64 | None
    layout: Layout
    undetermined: F64 = None
    jackknife: F64 | None = None
    clusters: int = 0

    def undetermined_in(self, name: str, count: int, size: int) -> bool:
        """Whether an undetermined direction involves the family ``name`` (count x size
        parameters) by more than 1 % of its length."""
        if self.undetermined is None or self.undetermined.shape[1] == 0:
            return False
        o = self.layout.offset[name]
        part = self.undetermined[o:o + count * size]
        return bool(np.any(np.linalg.norm(part, axis=0) > 0.01))


def evaluate(families: Sequence[Blocks], groups: Sequence[ResidualGroup], jacobians: bool):
    """Every group's residuals at the families' values: ``(residuals, None)`` per group, or
    with ``jacobians`` its :meth:`~multieye.optimize.blocks.ResidualGroup.linearize`
    ``(residuals, blocks, padded residuals)``."""
    values = {f.name: f.value for f in families}
    if jacobians:
        return [grp.linearize(values) for grp in groups]
    return [grp.evaluate(values, False) for grp in groups]


def normal_equations(families: Sequence[Blocks], groups: Sequence[ResidualGroup], layout: Layout,
                     opts: Options | None = None, newton: bool = False) -> NormalEquations:
    """``J^T J`` and ``J^T r`` at the families' values, summed chunk by chunk
    (:data:`CHUNK_SEGMENTS` segments at a time), weighted by the loss of ``opts`` (unweighted
    when None): by its IRLS weights ``rho'``, or with ``newton`` the Hessian by the robust
    cost's curvature ``rho' + 2 z rho''`` (at least 0) and the gradient by ``rho'``."""
    return _linearized(families, groups, layout, opts, newton)[0]


def _linearized(families: Sequence[Blocks], groups: Sequence[ResidualGroup], layout: Layout,
                opts: Options | None = None, newton: bool = False, clusters=None,
                scores: Options | None = None):
    """:func:`normal_equations`, and the residuals they were formed from: each group's
    ``(residuals (n_rows, dim), None)`` as :func:`evaluate` gives them (its chunks joined),
    so that a caller needing both linearises once.  With ``clusters`` (a
    :class:`~multieye.optimize.clusters.ClusterRecord`) each segment's share is kept there,
    its score (the gradient) weighted by the robust loss of ``scores`` (``rho'``: the
    M-estimator's score) while ``J^T J`` stays unweighted (``opts`` None)."""
    values = {f.name: f.value for f in families}
    acc = Assembly(layout, {f.name: f for f in families}, clusters)
    residuals = []
    for grp in groups:
        rows = []
        for piece, r, B, rb in grp.linearize_chunks(values, CHUNK_SEGMENTS):
            rows.append(r)
            if opts is None and scores is not None and scores.loss != "linear":
                slope = rho((r / scores.f_scale) ** 2, scores.loss)[1]
                acc.add(piece, B, rb, np.ones_like(slope), slope)
                continue
            if opts is None:
                acc.add(piece, B, rb)
                continue
            z = (r / opts.f_scale) ** 2
            _, slope, curvature = rho(z, opts.loss)
            if newton and opts.loss != "linear":
                acc.add(piece, B, rb, np.maximum(slope + 2.0 * z * curvature, 0.0), slope)
            else:
                acc.add(piece, B, rb, slope)
        residuals.append((rows[0] if len(rows) == 1 else np.concatenate(rows), None))
    return acc.result(), residuals


def _cost(evaluated, opts: Options) -> float:
    total = 0.0
    for r, *_ in evaluated:
        if not np.all(np.isfinite(r)):
            return np.inf
        total += float(rho((r / opts.f_scale) ** 2, opts.loss)[0].sum())
    return 0.5 * opts.f_scale ** 2 * total


def _retract(families: Sequence[Blocks], layout: Layout, dg: F64, dl: F64) -> tuple[Blocks, ...]:
    out = []
    for f in families:
        o = layout.offset[f.name]
        if f.eliminate:
            out.append(f.retract(dl[o:o + f.count]))
        else:
            out.append(f.retract(dg[o:o + f.count * f.size]))
    return tuple(out)


def minimize(families: Sequence[Blocks], groups: Sequence[ResidualGroup],
             options: Options = Options()) -> Result:
    """Minimise the robust cost of ``groups`` over ``families`` (module docstring).

    Parameters
    ----------
    families : sequence of Blocks
        Starting values.
    groups : sequence of ResidualGroup
    options : Options

    Returns
    -------
    Result
    """
    families = tuple(families)
    layout = Layout.of(families)  # BLAS threads for its size: multieye.optimize.threads
    by_name = {f.name: f for f in families}
    for grp in groups:
        missing = [s for s in grp.slots if s not in by_name]
        if missing:
            raise InputError(f"residual group refers to unknown block families {missing}")
    with threads_for(layout.k):
        return _minimize(families, groups, options, layout)


def _minimize(families, groups, opts: Options, layout: Layout) -> Result:
    newton = opts.newton_below == np.inf
    try:            # the starting cost from the residuals of the first linearisation
        ne, evaluated = _linearized(families, groups, layout, opts, newton)
    except InputError:                 # e.g. a lens outside its model: no Jacobian to take
        ne, evaluated = None, evaluate(families, groups, jacobians=False)
    cost = _cost(evaluated, opts)
    if not np.isfinite(cost):
        raise InputError("the residuals are not finite at the starting point")
    lam = opts.initial_damping
    evaluations, iterations = 1, 0
    for iterations in range(1, opts.max_iter + 1):
        if iterations > 1 or ne is None:
            ne = normal_equations(families, groups, layout, opts, newton)
        while True:
            step = solve_step(ne, lam)
            if step is not None:
                trial = _retract(families, layout, *step)
                ev_new = evaluate(trial, groups, jacobians=False)
                evaluations += 1
                cost_new = _cost(ev_new, opts)
                if cost_new <= cost:
                    break
            lam *= 10.0
            if lam > 1e10:
                return Result(families, cost, iterations, evaluations, True,
                              "no further decrease of the cost", evaluated)
        decrease = cost - cost_new
        families, cost, evaluated = trial, cost_new, ev_new
        lam = max(lam / 10.0, 1e-12)
        newton = newton or decrease < opts.newton_below * cost
        if decrease <= opts.tol * cost:
            return Result(families, cost, iterations, evaluations, True,
                          "relative decrease of the cost below tol", evaluated)
    return Result(families, cost, iterations, evaluations, False,
                  f"stopped after {opts.max_iter} iterations", evaluated)


def covariance_and_residuals(families: Sequence[Blocks], groups: Sequence[ResidualGroup], *,
                             local: bool = False, jackknife: Options | None = None
                             ) -> tuple[Covariance, list]:
    """:func:`covariance` and :func:`evaluate` (``jacobians=False``) at the families' values,
    from one linearisation; with ``jackknife`` (the options of the minimisation: its loss
    gives each cluster's score) also the cluster-robust covariance of the kept parameters
    (:func:`multieye.optimize.clusters.jackknife_covariance`, ``Covariance.jackknife``)."""
    families = tuple(families)
    layout = Layout.of(families)
    rec = None if jackknife is None else ClusterRecord(layout.n_local)
    with threads_for(layout.k):
        ne, evaluated = _linearized(families, groups, layout, clusters=rec, scores=jackknife)
        kept, loc, undetermined = marginal_covariance(ne, local=local)
        jack, n_clusters = (None, 0) if rec is None else jackknife_covariance(ne, rec, kept)
    return Covariance(kept, loc, layout, undetermined, jack, n_clusters), evaluated


def covariance(families: Sequence[Blocks], groups: Sequence[ResidualGroup], *,
               local: bool = False, evaluated=None) -> Covariance:
    """``(J^T J)^-1`` of the unweighted residuals at the families' values.

    For noise-normalised residuals and the linear loss this is the Cramér-Rao bound at that
    point; a caller with a robust loss multiplies it by the loss's efficiency factor
    (:func:`multieye.core.robust_loss.gaussian_kappa`).

    Parameters
    ----------
    families : sequence of Blocks
    groups : sequence of ResidualGroup
    local : bool
        Also the marginal covariance of each eliminated block.
    evaluated : list, optional
        :func:`evaluate` with ``jacobians=True`` at these values, if already at hand; else the
        normal equations are summed chunk by chunk (:func:`normal_equations`).
    """
    families = tuple(families)
    layout = Layout.of(families)
    with threads_for(layout.k):
        if evaluated is not None:
            ne = assemble(layout, {f.name: f for f in families}, groups, evaluated)
        else:
            ne = normal_equations(families, groups, layout)
        kept, loc, undetermined = marginal_covariance(ne, local=local)
    return Covariance(kept, loc, layout, undetermined)
