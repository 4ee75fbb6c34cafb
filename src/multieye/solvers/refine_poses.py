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

Parameterisation: every unknown lives on ``se3-left`` (:mod:`multieye.optimize.blocks`),
``R = Exp(phi) R_hat``, ``t = t_hat + tau``: ``phi`` is a rotation in the unknown's world-side
(left) frame and ``tau`` a translation in metres in the same frame, so the translation block
of the covariance is directly the covariance of ``t``.  The Jacobian (:class:`PoseResiduals`)
is analytic; each residual involves one X and one Y:

    d r_R / d phi_X = J_l^-1(r_R) R_A,          d r_R / d phi_Y = -J_l^-1(r_R) E,
    d r_t / d tau_X = R_A,   d r_t / d tau_Y = -I,   d r_t / d phi_Y = [R_Y t_B]_x,

with ``E = R_A R_X R_B^T R_Y^T`` and ``J_l`` the left Jacobian of SO(3).

Minimisation: the engine (:mod:`multieye.optimize.levenberg_marquardt`), Levenberg-Marquardt on
the normal equations of the robust cost (a ``6k x 6k`` system per iteration for k unknowns,
assembled at a cost linear in the measurements).

Covariance: the Jacobian ``J`` of the sigma-normalised residuals at the optimum gives
``cov = kappa (J^T J)^-1`` with Huber's asymptotic factor ``kappa = E[psi^2] / E[psi']^2`` of
the loss's influence function ``psi``.  When the sigmas are given, the expectations are those
of standard normal residuals (``kappa = 1`` for the linear loss, the Cramér-Rao bound).  When
they are not, ``sigma_R`` and ``sigma_t`` are estimated robustly (1.4826 x median absolute
residual component), the refinement runs twice (the second time with the sigmas re-estimated
from the refined residuals), and the expectations are the sample averages over the final
residuals, ``kappa = [sum psi^2 / (m - n)] / [sum psi' / m]^2``, which for the linear loss is
the estimated residual variance.  The covariance describes noise in A and B only: it does not
cover model error (unsynchronised measurements, a non-rigid rig) or outliers that the loss has
not down-weighted.

Synopsis
--------
>>> from multieye.solvers.general import solve_general
>>> sol = solve_general(groups, refine=True)                     # doctest: +SKIP
>>> sol.covariance_of("Y", "cam1")                               # 6x6   # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.geometry import skew
from multieye.core.lie import left_jacobian_inv, log_so3
from multieye.core.problem import MeasurementGroup
from multieye.core.robust_loss import LOSSES, gaussian_kappa, sample_kappa
from multieye.optimize.blocks import Blocks, ResidualGroup
from multieye.optimize.levenberg_marquardt import Options, covariance, evaluate, minimize
from multieye.solvers.groups import GeneralSolution, as_groups, assemble_solution
from multieye.solvers.result import Solution

__all__ = [
    "refine_general",
    "refine_solution",
    "refine_groups",
    "PoseResiduals",
    "relative_pose_covariance",
    "LOSSES",
]

F64 = NDArray[np.float64]

_MAD_TO_SIGMA = 1.4826
_SIGMA_FLOOR = 1e-12


class PoseResiduals(ResidualGroup):
    """Pose residuals of every measurement, over their sigmas (module docstring).

    Rows are measurements in group order; slots are the block families ``X`` and ``Y``.

    Parameters
    ----------
    groups : tuple of MeasurementGroup
        Validated (:func:`multieye.solvers.groups.as_groups`).
    x_names, y_names : sequence of str
        Order of the blocks of the ``X`` and ``Y`` families.
    sigma_rot, sigma_t : float
    """

    def __init__(self, groups: tuple[MeasurementGroup, ...], x_names, y_names,
                 sigma_rot: float, sigma_t: float):
        ix = {n: k for k, n in enumerate(x_names)}
        iy = {n: k for k, n in enumerate(y_names)}
        n = [len(g.A) for g in groups]
        index = np.column_stack([np.repeat([ix[g.x_name] for g in groups], n),
                                 np.repeat([iy[g.y_name] for g in groups], n)])
        super().__init__(("X", "Y"), index, np.arange(len(index)), 6)
        self.A = np.concatenate([g.A for g in groups])
        self.B = np.concatenate([g.B for g in groups])
        self.sigma_rot, self.sigma_t = float(sigma_rot), float(sigma_t)

    def raw(self, X: F64, Y: F64) -> tuple[F64, F64, F64]:
        """Unweighted ``r_R``, ``r_t`` (each (n, 3), radians and metres) and ``E``."""
        RA, tA = self.A[:, :3, :3], self.A[:, :3, 3]
        RB, tB = self.B[:, :3, :3], self.B[:, :3, 3]
        Xi, Yi = X[self.index[:, 0]], Y[self.index[:, 1]]
        RX, tX, RY, tY = Xi[:, :3, :3], Xi[:, :3, 3], Yi[:, :3, :3], Yi[:, :3, 3]
        E = RA @ RX @ np.swapaxes(RB, 1, 2) @ np.swapaxes(RY, 1, 2)
        r_t = (np.einsum("nij,nj->ni", RA, tX) + tA - np.einsum("nij,nj->ni", RY, tB) - tY)
        return log_so3(E), r_t, E

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        X, Y = values["X"], values["Y"]
        r_rot, r_t, E = self.raw(X, Y)
        r = np.concatenate([r_rot / self.sigma_rot, r_t / self.sigma_t], axis=1)
        if not jacobians:
            return r, None
        RA = self.A[:, :3, :3]
        RY = Y[self.index[:, 1], :3, :3]
        tB = self.B[:, :3, 3]
        Jinv = left_jacobian_inv(r_rot)
        n = len(r)
        JX = np.zeros((n, 6, 6))
        JY = np.zeros((n, 6, 6))
        JX[:, :3, :3] = Jinv @ RA / self.sigma_rot
        JX[:, 3:, 3:] = RA / self.sigma_t
        JY[:, :3, :3] = -(Jinv @ E) / self.sigma_rot
        JY[:, 3:, :3] = skew(np.einsum("nij,nj->ni", RY, tB)) / self.sigma_t
        JY[:, 3:, 3:] = -np.eye(3) / self.sigma_t
        return r, [JX, JY]


def _robust_sigma(r: F64) -> float:
    return max(_MAD_TO_SIGMA * float(np.median(np.abs(r))), _SIGMA_FLOOR)


def _families(groups, initial: GeneralSolution) -> tuple[list[str], list[str], list[Blocks]]:
    xs = list(dict.fromkeys(g.x_name for g in groups))
    ys = list(dict.fromkeys(g.y_name for g in groups))
    try:
        X = np.stack([initial.X[n] for n in xs])
        Y = np.stack([initial.Y[n] for n in ys])
    except KeyError as exc:
        raise InputError(f"the solution has no unknown named {exc.args[0]!r}") from None
    return xs, ys, [Blocks("X", X, "se3-left"), Blocks("Y", Y, "se3-left")]


def refine_general(groups: Iterable, initial: GeneralSolution, *,
                   rot_sigma_rad: float | None = None, trans_sigma_m: float | None = None,
                   loss: str = "huber", loss_scale: float = 1.345,
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
    max_iter : int
        Levenberg-Marquardt iterations per minimisation at most.
    tol : float
        Relative cost decrease at which the minimisation stops.

    Returns
    -------
    GeneralSolution
        Refined X and Y, residuals, ``covariance`` (6k x 6k, order ``unknowns``, left rotation
        perturbation and additive translation as in the module docstring), and the sigmas
        used (``sigma_rot_rad``, ``sigma_trans_m``).

    Raises
    ------
    InputError
        Unknown loss, non-positive sigma or loss scale, or an unknown missing from
        ``initial``.
    """
    return refine_groups(as_groups(groups), initial, rot_sigma_rad=rot_sigma_rad,
                         trans_sigma_m=trans_sigma_m, loss=loss, loss_scale=loss_scale,
                         max_iter=max_iter, tol=tol)


def refine_groups(groups: tuple[MeasurementGroup, ...], initial: GeneralSolution, *,
                  rot_sigma_rad: float | None = None, trans_sigma_m: float | None = None,
                  loss: str = "huber", loss_scale: float = 1.345, max_iter: int = 100,
                  tol: float = 1e-10) -> GeneralSolution:
    """:func:`refine_general` on groups already validated by
    :func:`multieye.solvers.groups.as_groups` (the transforms are not checked again)."""
    if not isinstance(loss, str) or loss not in LOSSES:
        raise InputError(f"unknown loss {loss!r}; expected one of {', '.join(LOSSES)}")
    for name, v in (("rot_sigma_rad", rot_sigma_rad), ("trans_sigma_m", trans_sigma_m),
                    ("loss_scale", loss_scale)):
        if v is not None and not (isinstance(v, (int, float, np.floating, np.integer))
                                  and np.isfinite(v) and v > 0):
            raise InputError(f"{name} must be a positive number, got {v!r}")
    xs, ys, fams = _families(groups, initial)
    opts = Options(loss=loss, f_scale=float(loss_scale), max_iter=max_iter, tol=tol)

    def sigmas(fams) -> tuple[float, float]:
        r_rot, r_t, _ = PoseResiduals(groups, xs, ys, 1.0, 1.0).raw(fams[0].value, fams[1].value)
        return (rot_sigma_rad if rot_sigma_rad is not None else _robust_sigma(r_rot),
                trans_sigma_m if trans_sigma_m is not None else _robust_sigma(r_t))

    given = rot_sigma_rad is not None and trans_sigma_m is not None
    for _ in range(1 if given else 2):
        res = minimize(fams, [PoseResiduals(groups, xs, ys, *sigmas(fams))], opts)
        fams = res.families
    s_rot, s_t = sigmas(fams)
    residual_group = [PoseResiduals(groups, xs, ys, s_rot, s_t)]
    ev = evaluate(fams, residual_group, jacobians=True)
    k = len(xs) + len(ys)
    kappa = (gaussian_kappa(loss, loss_scale) if given
             else sample_kappa(ev[0][0].ravel(), loss, loss_scale, 6 * k))
    cov = kappa * covariance(fams, residual_group, evaluated=ev).kept
    X = dict(zip(xs, fams[0].value))
    Y = dict(zip(ys, fams[1].value))
    return assemble_solution(groups, X, Y, initial.method, covariance=cov,
                             sigma_rot_rad=float(s_rot), sigma_trans_m=float(s_t))


#: Keyword options of the pose-level refinement (``solve(..., refine=True, **options)``).
REFINE_OPTIONS = ("rot_sigma_rad", "trans_sigma_m", "loss", "loss_scale", "max_iter", "tol")


def check_refine_options(options: Mapping) -> None:
    """InputError for an option name the refinement does not take (before any work)."""
    unknown = sorted(set(options) - set(REFINE_OPTIONS))
    if unknown:
        raise InputError(f"unknown refinement option {', '.join(unknown)}; the options are "
                         f"{', '.join(REFINE_OPTIONS)}")


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
    check_refine_options(options)
    meas = solution.measurements
    if meas is None:
        raise InputError("cannot refine a Solution built without its measurements")
    m = meas.m
    A, B = meas.split(meas.A), meas.split(meas.B)
    groups = tuple(MeasurementGroup(str(j), "Y", A[j], B[j]) for j in range(m))
    initial = GeneralSolution(X={str(j): solution.X[j] for j in range(m)}, Y={"Y": solution.Y},
                              method=solution.method, residuals={}, groups=(), unknowns=())
    ref = refine_groups(groups, initial, **options)       # measurements validated by solve
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
