"""Maximum-likelihood refinement of the pose residuals of ``A_i X_a = Y_b B_i``, with covariance.

Objective (the pose-residual maximum-likelihood cost of Wise et al. 2025, "A certifiably
correct algorithm for generalized robot-world and hand-eye calibration", with the geodesic
rotation residual in place of their chordal one and a robust loss)::

    min  sum_i  rho(||r_R,i / sigma_R||^2) + rho(||r_t,i / sigma_t||^2)    (per component)
    r_R,i = Log(R_A R_X R_B^T R_Y^T)                 rotation vector, radians (A-side frame)
    r_t,i = R_A t_X + t_A - R_Y t_B - t_Y            metres (A-side frame)

``sigma_R`` is the standard deviation of each component of the rotation-vector residual and
``sigma_t`` of each translation component; ``rho`` is one of scipy's losses applied to each
of the six components of a measurement's residual separately, with the threshold
``loss_scale`` in units of sigma.

Parameterisation: each unknown ``T = (R, t)`` is perturbed on the left for the rotation and
additively for the translation, ``R = Exp(phi) R_hat``, ``t = t_hat + tau``, parameters
``(phi, tau)`` (6 per unknown, radians and metres).  ``phi`` is a rotation in the unknown's
world-side (left) frame; ``tau`` is a translation in metres in the same frame, so the
translation block of the covariance is directly the covariance of ``t``.  The Jacobian is
analytic and sparse (each residual involves one X and one Y):

    d r_R / d phi_X = J_l^-1(r_R) R_A,          d r_R / d phi_Y = -J_l^-1(r_R) E,
    d r_t / d tau_X = R_A,   d r_t / d tau_Y = -I,   d r_t / d phi_Y = [R_Y t_B]_x,

with ``E = R_A R_X R_B^T R_Y^T`` and ``J_l`` the left Jacobian of SO(3) (times ``J_l(phi)`` of
the current parameter, since the chart is anchored at the starting estimate).

Minimisation: by default Levenberg-Marquardt on the sparse normal equations of the robust
cost (a ``6k x 6k`` system per iteration, k unknowns, assembled from the sparse Jacobian at a
cost linear in the measurements); ``solver="scipy"`` runs :func:`scipy.optimize.least_squares`
(trf, lsmr) on the same residuals and analytic sparse Jacobian instead.  Both reach the same
optimum; scipy's trust region needs far more iterations with a robust loss (about 10x slower
on the UTIAS data).

Covariance: the Jacobian ``J`` of the sigma-normalised residuals is re-evaluated at the
optimum (chart re-anchored there) and ``cov = kappa (J^T J)^-1`` with Huber's asymptotic factor
``kappa = E[psi^2] / E[psi']^2`` of the loss's influence function ``psi``.  When the sigmas are
given, the expectations are those of standard normal residuals (``kappa = 1`` for the linear
loss, the Cramér-Rao bound).  When they are not, ``sigma_R`` and ``sigma_t`` are estimated
robustly (1.4826 x median absolute residual component), the refinement runs twice (the second
time with the sigmas re-estimated from the refined residuals), and the expectations are the
sample averages over the final residuals, ``kappa = [sum psi^2 / (m - n)] / [sum psi' / m]^2``,
which for the linear loss is the estimated residual variance.  The covariance describes noise
in A and B only: it does not cover model error (unsynchronised measurements, a non-rigid
rig) or outliers that the loss has not down-weighted.

Synopsis
--------
>>> from multieye.solvers.general import solve_general
>>> sol = solve_general(groups, refine=True)                     # doctest: +SKIP
>>> sol.covariance_of("Y", "cam1")                               # 6x6   # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.optimize import least_squares

from multieye.core.errors import InputError
from multieye.solvers.groups import GeneralSolution, MeasurementGroup, as_groups, assemble_solution
from multieye.core.geometry import make_transform, skew
from multieye.core.lie import exp_so3, left_jacobian, left_jacobian_inv, log_so3
from multieye.core.robust_loss import LOSSES, gaussian_kappa, rho, robust_cost, sample_kappa
from multieye.solvers.result import Solution

__all__ = [
    "refine_general",
    "refine_solution",
    "PoseProblem",
    "relative_pose_covariance",
    "LOSSES",
]

F64 = NDArray[np.float64]

_MAD_TO_SIGMA = 1.4826
_SIGMA_FLOOR = 1e-12


# --- the stacked problem --------------------------------------------------------------------

class PoseProblem:
    """All measurements of the groups stacked, with the index of each row's X and Y unknown.

    Parameters are 6 per unknown, ``(phi, tau)`` in ``unknowns`` order, relative to an anchor
    ``T0`` (k, 4, 4): ``R = Exp(phi) R0``, ``t = t0 + tau``.  Residuals are 6 per measurement,
    ``(r_R / sigma_R, r_t / sigma_t)``, measurement by measurement in group order.

    Parameters
    ----------
    groups : iterable of (x_name, y_name, A, B)
        As for :func:`multieye.solvers.general.solve_general`.
    """

    def __init__(self, groups: Iterable):
        groups = as_groups(groups)
        self.groups = groups
        xs = list(dict.fromkeys(g.x_name for g in groups))
        ys = list(dict.fromkeys(g.y_name for g in groups))
        #: (side, name) of each unknown, in parameter order.
        self.unknowns = tuple([("X", x) for x in xs] + [("Y", y) for y in ys])
        index = {u: k for k, u in enumerate(self.unknowns)}
        self.A = np.concatenate([g.A for g in groups])
        self.B = np.concatenate([g.B for g in groups])
        n = [len(g.A) for g in groups]
        self.xi = np.repeat([index[("X", g.x_name)] for g in groups], n)
        self.yi = np.repeat([index[("Y", g.y_name)] for g in groups], n)
        self.m = len(self.A)
        self.k = len(self.unknowns)
        # Residual rows 6i..6i+5 depend on the 6 columns of X[xi] and the 6 of Y[yi].
        rows = np.repeat(6 * np.arange(self.m)[:, None] + np.arange(6), 12, axis=1)
        cx = 6 * self.xi[:, None] + np.arange(6)
        cy = 6 * self.yi[:, None] + np.arange(6)
        cols = np.broadcast_to(np.concatenate([cx, cy], axis=1)[:, None, :], (self.m, 6, 12))
        self._rows = rows.ravel()
        self._cols = cols.ravel()

    @property
    def sparsity(self) -> sp.csr_matrix:
        """Structural non-zeros of the Jacobian, (6m, 6k)."""
        return self._sparse(np.ones(self._rows.size))

    def _sparse(self, data: F64) -> sp.csr_matrix:
        return sp.csr_matrix((data.ravel(), (self._rows, self._cols)),
                             shape=(6 * self.m, 6 * self.k))

    def anchor(self, solution: GeneralSolution) -> F64:
        """The unknowns of ``solution`` stacked in parameter order, (k, 4, 4)."""
        try:
            return np.stack([(solution.X if side == "X" else solution.Y)[name]
                             for side, name in self.unknowns])
        except KeyError as exc:
            raise InputError(f"the solution has no unknown named {exc.args[0]!r}") from None

    def poses(self, T0: F64, p: F64) -> F64:
        """Unknowns (k, 4, 4) at parameters ``p`` (6k,) relative to the anchor ``T0``."""
        p = np.asarray(p, dtype=np.float64).reshape(self.k, 6)
        return make_transform(exp_so3(p[:, :3]) @ T0[:, :3, :3], T0[:, :3, 3] + p[:, 3:])

    def raw_residuals(self, T: F64) -> tuple[F64, F64]:
        """Unweighted ``(r_R, r_t)`` (each (m, 3), radians and metres) at unknowns ``T``."""
        RA, tA = self.A[:, :3, :3], self.A[:, :3, 3]
        RB, tB = self.B[:, :3, :3], self.B[:, :3, 3]
        RX, tX = T[self.xi, :3, :3], T[self.xi, :3, 3]
        RY, tY = T[self.yi, :3, :3], T[self.yi, :3, 3]
        E = RA @ RX @ np.swapaxes(RB, 1, 2) @ np.swapaxes(RY, 1, 2)
        r_t = (np.einsum("nij,nj->ni", RA, tX) + tA
               - np.einsum("nij,nj->ni", RY, tB) - tY)
        return log_so3(E), r_t

    def residuals(self, p: F64, T0: F64, sigma_rot: float, sigma_t: float) -> F64:
        """Sigma-normalised residual vector (6m,) at ``p``."""
        r_rot, r_t = self.raw_residuals(self.poses(T0, p))
        return np.concatenate([r_rot / sigma_rot, r_t / sigma_t], axis=1).ravel()

    def jacobian(self, p: F64, T0: F64, sigma_rot: float, sigma_t: float) -> sp.csr_matrix:
        """Analytic sparse Jacobian (6m, 6k) of :meth:`residuals` (module docstring)."""
        p = np.asarray(p, dtype=np.float64).reshape(self.k, 6)
        T = self.poses(T0, p)
        r_rot, _ = self.raw_residuals(T)
        RA = self.A[:, :3, :3]
        RB, tB = self.B[:, :3, :3], self.B[:, :3, 3]
        RX, RY = T[self.xi, :3, :3], T[self.yi, :3, :3]
        E = RA @ RX @ np.swapaxes(RB, 1, 2) @ np.swapaxes(RY, 1, 2)
        Jinv = left_jacobian_inv(r_rot)
        Jl = left_jacobian(p[:, :3])
        JlX, JlY = Jl[self.xi], Jl[self.yi]
        blk = np.zeros((self.m, 6, 12))
        blk[:, :3, 0:3] = Jinv @ RA @ JlX / sigma_rot
        blk[:, :3, 6:9] = -(Jinv @ E) @ JlY / sigma_rot
        blk[:, 3:, 3:6] = RA / sigma_t
        blk[:, 3:, 6:9] = skew(np.einsum("nij,nj->ni", RY, tB)) @ JlY / sigma_t
        blk[:, 3:, 9:12] = -np.eye(3) / sigma_t
        return self._sparse(blk)


def _robust_sigma(r: F64) -> float:
    return max(_MAD_TO_SIGMA * float(np.median(np.abs(r))), _SIGMA_FLOOR)


# --- minimisation ---------------------------------------------------------------------------

def _minimize_lm(problem: PoseProblem, T: F64, s_rot: float, s_t: float, loss: str,
                 scale: float, max_iter: int, tol: float) -> F64:
    """Levenberg-Marquardt on the sparse normal equations of the robust cost.

    Every iteration re-anchors the chart at the current estimate (p = 0), solves
    ``(J^T W J + lambda diag(J^T W J)) dp = -J^T psi(f)`` with ``W = psi'(f)`` (floored at
    ``1e-3 rho'`` so that it stays positive for redescending losses), a ``6k x 6k`` system
    assembled from the sparse J at a cost linear in the measurements, and accepts the step
    when the robust cost decreases.  It reaches a stationary point of the same cost that
    :func:`scipy.optimize.least_squares` minimises with ``loss``, ``f_scale=scale``.
    """
    zero = np.zeros(6 * problem.k)
    f = problem.residuals(zero, T, s_rot, s_t)
    cost = robust_cost(f, loss, scale)
    lam = 1e-6
    for _ in range(max_iter):
        J = problem.jacobian(zero, T, s_rot, s_t)
        z = (f / scale) ** 2
        _, d1, d2 = rho(z, loss)
        # Gauss-Newton Hessian of the robust cost, psi'(f) = rho' + 2 z rho'', kept positive.
        w = np.maximum(d1 + 2.0 * z * d2, 1e-3 * d1)
        H = (J.T @ sp.diags(w) @ J).toarray()
        g = J.T @ (d1 * f)
        d = np.diag(H).copy()
        while True:
            dp = np.linalg.solve(H + lam * np.diag(d), -g)
            T_new = problem.poses(T, dp)
            f_new = problem.residuals(zero, T_new, s_rot, s_t)
            cost_new = robust_cost(f_new, loss, scale)
            if cost_new <= cost:
                break
            lam *= 10.0
            if lam > 1e8:
                return T
        decrease = cost - cost_new
        T, f, cost = T_new, f_new, cost_new
        lam = max(lam / 10.0, 1e-12)
        if decrease <= tol * max(cost, 1e-300) or np.abs(dp).max() <= tol:
            break
    return T


def _minimize_scipy(problem: PoseProblem, T: F64, s_rot: float, s_t: float, loss: str,
                    scale: float, max_iter: int, tol: float) -> F64:
    """The same minimisation with :func:`scipy.optimize.least_squares` (trf, lsmr)."""
    res = least_squares(problem.residuals, np.zeros(6 * problem.k), jac=problem.jacobian,
                        args=(T, s_rot, s_t), loss=loss, f_scale=scale, method="trf",
                        tr_solver="lsmr", tr_options={"atol": 1e-12, "btol": 1e-12},
                        x_scale="jac", ftol=tol, xtol=tol, gtol=tol, max_nfev=max_iter)
    return problem.poses(T, res.x)


_SOLVERS = {"lm": _minimize_lm, "scipy": _minimize_scipy}


# --- public API -----------------------------------------------------------------------------

def refine_general(groups: Iterable, initial: GeneralSolution, *,
                   rot_sigma_rad: float | None = None, trans_sigma_m: float | None = None,
                   loss: str = "huber", loss_scale: float = 1.345, solver: str = "lm",
                   max_iter: int = 100, tol: float = 1e-10) -> GeneralSolution:
    """Maximum-likelihood refinement of every X and Y of ``A_i X_a = Y_b B_i``, with covariance.

    Parameters
    ----------
    groups : iterable of (x_name, y_name, A, B)
        As for :func:`multieye.solvers.general.solve_general`; ``A``, ``B`` shape (N, 4, 4), metres.
    initial : GeneralSolution
        Starting estimate (the closed form), with every unknown named in ``groups``.
    rot_sigma_rad : float, optional
        Noise standard deviation of each rotation-vector component of ``Log(R_A R_X R_B^T
        R_Y^T)``, radians.  Estimated from the residuals when not given (see module docstring).
    trans_sigma_m : float, optional
        Noise standard deviation of each component of ``R_A t_X + t_A - R_Y t_B - t_Y``,
        metres.  Estimated when not given.
    loss : {"huber", "linear", "soft_l1", "cauchy", "arctan"}
        scipy's robust loss, applied to each sigma-normalised residual component.
    loss_scale : float
        Where the loss departs from least squares, in units of sigma (1.345: Huber's 95 %
        efficiency under Gaussian noise).
    solver : {"lm", "scipy"}
        ``"lm"``: Levenberg-Marquardt on the sparse normal equations with IRLS weights (fast:
        a 6k x 6k system per iteration).  ``"scipy"``: :func:`scipy.optimize.least_squares`
        (trf, lsmr on the same analytic sparse Jacobian), much slower with robust losses;
        both minimise the same cost.
    max_iter : int
        Iterations (``"lm"``) or residual evaluations (``"scipy"``) per minimisation.
    tol : float
        Relative cost decrease and step size at which the minimisation stops (``ftol``,
        ``xtol``, ``gtol`` for scipy).

    Returns
    -------
    GeneralSolution
        Refined X and Y, residuals, ``covariance`` (6k x 6k, order ``unknowns``, left rotation
        perturbation and additive translation as in the module docstring), and the sigmas
        used (``sigma_rot_rad``, ``sigma_trans_m``).

    Raises
    ------
    InputError
        Unknown loss or solver, non-positive sigma or loss scale, or an unknown missing from
        ``initial``.
    """
    if loss not in LOSSES:
        raise InputError(f"unknown loss {loss!r}; expected one of {', '.join(LOSSES)}")
    if solver not in _SOLVERS:
        raise InputError(f"unknown solver {solver!r}; expected one of {', '.join(_SOLVERS)}")
    for name, v in (("rot_sigma_rad", rot_sigma_rad), ("trans_sigma_m", trans_sigma_m),
                    ("loss_scale", loss_scale)):
        if v is not None and not (np.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v!r}")
    problem = PoseProblem(groups)
    T = problem.anchor(initial)
    minimize = _SOLVERS[solver]

    given = rot_sigma_rad is not None and trans_sigma_m is not None
    for _ in range(1 if given else 2):
        s_rot, s_t = _sigmas(problem, T, rot_sigma_rad, trans_sigma_m)
        T = minimize(problem, T, s_rot, s_t, loss, loss_scale, max_iter, tol)

    s_rot, s_t = _sigmas(problem, T, rot_sigma_rad, trans_sigma_m)
    zero = np.zeros(6 * problem.k)
    f = problem.residuals(zero, T, s_rot, s_t)
    J = problem.jacobian(zero, T, s_rot, s_t)
    kappa = (gaussian_kappa(loss, loss_scale) if given
             else sample_kappa(f, loss, loss_scale, 6 * problem.k))
    cov = kappa * np.linalg.inv((J.T @ J).toarray())
    cov = 0.5 * (cov + cov.T)

    X = {name: T[k] for k, (side, name) in enumerate(problem.unknowns) if side == "X"}
    Y = {name: T[k] for k, (side, name) in enumerate(problem.unknowns) if side == "Y"}
    return assemble_solution(problem.groups, X, Y, initial.method, covariance=cov,
                             sigma_rot_rad=float(s_rot), sigma_trans_m=float(s_t))


def _sigmas(problem: PoseProblem, T: F64, rot_sigma_rad: float | None,
            trans_sigma_m: float | None) -> tuple[float, float]:
    """The given sigmas, or robust estimates from the residuals at ``T``."""
    r_rot, r_t = problem.raw_residuals(T)
    s_rot = rot_sigma_rad if rot_sigma_rad is not None else _robust_sigma(r_rot)
    s_t = trans_sigma_m if trans_sigma_m is not None else _robust_sigma(r_t)
    return s_rot, s_t


def refine_solution(solution: Solution, **options) -> Solution:
    """Refine a single-Y solution of ``A_i^j X^j = Y B_i^j``: what ``solve(..., refine=True)`` runs.

    Parameters
    ----------
    solution : Solution
        A closed-form solution carrying its validated ``measurements``.
    **options
        Keyword options of :func:`refine_general` (sigmas, loss, solver, ...).

    Returns
    -------
    Solution
        Same method name, ``Y_per_camera`` and measurements; refined ``X`` and ``Y``;
        ``covariance`` (6(m+1), 6(m+1)) of X^1..X^m then Y, each (rotation vector,
        translation) with ``R = Exp(phi) R_hat`` and ``t = t_hat + tau`` (radians, metres).

    Raises
    ------
    InputError
        The solution carries no measurements, or an option is invalid.
    """
    meas = solution.measurements
    if meas is None:
        raise InputError("cannot refine a Solution built without its measurements")
    m = meas.m
    A, B = meas.split(meas.A), meas.split(meas.B)
    groups = [MeasurementGroup(str(j), "Y", A[j], B[j]) for j in range(m)]
    initial = GeneralSolution(X={str(j): solution.X[j] for j in range(m)}, Y={"Y": solution.Y},
                              method=solution.method, residuals={}, groups=(), unknowns=())
    ref = refine_general(groups, initial, **options)
    return Solution(X=np.stack([ref.X[str(j)] for j in range(m)]), Y=ref.Y["Y"],
                    method=solution.method, Y_per_camera=solution.Y_per_camera,
                    covariance=ref.covariance, measurements=meas)


def relative_pose_covariance(T_w_r, T_w_c, cov) -> F64:
    """Covariance of ``T_r_c = inv(T_w_r) @ T_w_c`` from the joint covariance of the two poses.

    Both inputs and the output use the convention of :func:`refine_general`: rotation vector
    ``phi`` with ``R = Exp(phi) R_hat`` and additive translation ``tau``; for ``T_r_c`` the
    perturbation is in frame ``r``.  First-order propagation:

        phi_rc = R_wr^T (phi_c - phi_r)
        tau_rc = R_wr^T (tau_c - tau_r) + R_wr^T [t_wc - t_wr]_x phi_r

    Parameters
    ----------
    T_w_r, T_w_c : array_like, shape (4, 4)
    cov : array_like, shape (12, 12)
        Joint covariance of (phi_r, tau_r, phi_c, tau_c).

    Returns
    -------
    ndarray, shape (6, 6)
        (rotation vector, translation) of ``T_r_c``, radians and metres.
    """
    T_w_r = np.asarray(T_w_r, dtype=np.float64)
    T_w_c = np.asarray(T_w_c, dtype=np.float64)
    Rt = T_w_r[:3, :3].T
    d = T_w_c[:3, 3] - T_w_r[:3, 3]
    J = np.zeros((6, 12))
    J[:3, 0:3] = -Rt
    J[:3, 6:9] = Rt
    J[3:, 0:3] = Rt @ skew(d)
    J[3:, 3:6] = -Rt
    J[3:, 9:12] = Rt
    return J @ np.asarray(cov, dtype=np.float64) @ J.T
