"""Closed-form solution of the general problem ``A_i X_a = Y_b B_i`` (several X, several Y).

Each measurement ``i`` names one unknown on each side: ``A_i @ X[a] ≈ Y[b] @ B_i``.  The
paper's case (Wang et al. ICRA 2022) is the special case of one Y shared by every camera;
Wise et al. (2025, "A certifiably correct algorithm for generalized robot-world and hand-eye
calibration") pose the general case, with several cameras and several targets at once.

Synopsis
--------
>>> from multieye.general import solve_general
>>> sol = solve_general([("tag0", "cam0", A00, B00), ("tag0", "cam1", A01, B01),
...                      ("tag1", "cam1", A11, B11)])            # doctest: +SKIP
>>> sol.Y["cam1"]                                                # (4, 4)   # doctest: +SKIP

Method (``method="joint"``)
---------------------------
Rotation.  With column-major ``vec``, ``R_A R_X = R_Y R_B`` is the linear row block
``(R_B ⊗ R_A) vec(R_X) - vec(R_Y) = 0`` (paper eq. 6 generalised: one block per measurement,
over the rotation unknowns of every X and every Y).  Because every ``K_i = R_B ⊗ R_A`` is
orthogonal, the normal matrix of the stacked system has scalar diagonal blocks::

    M = [[D_x ⊗ I9,   -G^T],
         [  -G,    D_y ⊗ I9]],      G[b, a] = sum over the group (a, b) of K_i   (9 x 9),

where ``D_x``, ``D_y`` count the measurements of each unknown.  Aggregating each group to its
9x9 ``G`` block makes the cost linear in the number of measurements.  The homogeneous system
fixes the rotations up to one common scale; the gauge chosen here is

    sum over all unknowns u of  d_u ||vec R_u||^2 = const   (d_u: measurements of u),

which makes the minimiser the top singular pair of ``C = D_y^-1/2 G D_x^-1/2`` and is also
what one gets by fixing the norm of either side alone (weighted by ``d``) after eliminating
the other side in closed form.  So the larger side is eliminated and a dense symmetric
eigenproblem of size ``9 min(n_X, n_Y)`` is solved; the eliminated side follows as
``vec R_X[a] = G[:, a]^T vec R_Y / d_a`` (or the mirror image).  With one Y this is the
9x9 eigenproblem of the single-Y joint solver (``D_y`` is then a scalar).  Each 3x3 block is
then sign-fixed by its determinant and projected onto SO(3).

Translation.  ``R_A t_X - t_Y = R_Y t_B - t_A`` per measurement, one sparse linear least
squares over all translations.  Its normal matrix has the same bipartite structure with
scalar diagonal blocks (``R_A^T R_A = I``), so the larger side is eliminated again and a
dense symmetric system of size ``3 min(n_X, n_Y)`` remains.

Connectivity.  Unknowns are nodes of the bipartite graph X-names/Y-names, groups its edges.
If the graph has several components the problem is not one problem: :func:`solve_general`
raises :class:`~multieye.errors.DisconnectedError` naming the unknowns outside the main
component (the one with the most measurements) instead of returning values for them.  Solve
each component separately by calling :func:`solve_general` on its groups.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import connected_components

from .errors import DegenerateMotionError, DisconnectedError, InputError, TooFewMeasurementsError
from .geometry import make_transform, project_to_so3, rotation_angle
from .solvers.result import CameraResidual

__all__ = [
    "MeasurementGroup",
    "GeneralSolution",
    "solve_general",
    "as_groups",
    "loop_residuals",
    "group_residual",
    "METHODS",
]

F64 = NDArray[np.float64]

METHODS = ("joint",)

# Relative size of the second-smallest eigenvalue of the rotation system below which the
# rotations are not determined by the measurements (exactly 0 without noise).
_ROTATION_GAP_TOL = 1e-8
# Condition number bound of the reduced translation system.
_TRANSLATION_RCOND = 1e-10


class MeasurementGroup(NamedTuple):
    """Measurements ``A[i] @ X[x_name] ≈ Y[y_name] @ B[i]`` of one pair of unknowns.

    Attributes
    ----------
    x_name, y_name : str
        Names of the unknowns on the left (X) and right (Y) side.  The two sides are separate
        name spaces.
    A, B : ndarray, shape (N, 4, 4)
        Rigid transforms, metres.
    """

    x_name: str
    y_name: str
    A: F64
    B: F64


@dataclass(frozen=True)
class GeneralSolution:
    """Solution of the general problem ``A_i X[a] = Y[b] B_i``.

    Attributes
    ----------
    X, Y : dict of str -> ndarray, shape (4, 4)
        The unknowns by name.
    method : str
        Closed-form method used (``"joint"``).
    residuals : dict of (x_name, y_name) -> CameraResidual
        Loop residuals of every group (paper section V-A metrics).
    groups : tuple of (x_name, y_name, n)
        The groups used, in input order after merging repeated pairs, with their sizes.
    unknowns : tuple of (side, name)
        Order of the unknowns in ``covariance``: every X (``("X", name)``) then every Y.
    covariance : ndarray, shape (6k, 6k), or None
        After refinement (:func:`multieye.pose_refine.refine_general`): joint covariance of
        the perturbations of the k unknowns in ``unknowns`` order, each as
        (rotation vector, translation) with ``R = Exp(phi) R_hat`` (left, i.e. perturbation
        in the unknown's world-side frame) and ``t = t_hat + tau``; radians and metres.
    sigma_rot_rad, sigma_trans_m : float or None
        After refinement: the noise standard deviations used to weight the residuals (per
        component of the rotation vector and of the translation), given or estimated.
    """

    X: dict[str, F64]
    Y: dict[str, F64]
    method: str
    residuals: dict[tuple[str, str], CameraResidual]
    groups: tuple[tuple[str, str, int], ...]
    unknowns: tuple[tuple[str, str], ...]
    covariance: F64 | None = None
    sigma_rot_rad: float | None = None
    sigma_trans_m: float | None = None

    def covariance_of(self, side: str, name: str) -> F64:
        """Marginal 6x6 covariance (rotation vector, translation) of one unknown.

        Parameters
        ----------
        side : {"X", "Y"}
        name : str

        Raises
        ------
        InputError
            If the solution carries no covariance (not refined) or the unknown is absent.
        """
        if self.covariance is None:
            raise InputError("this solution has no covariance: solve with refine=True")
        try:
            k = self.unknowns.index((side, name))
        except ValueError:
            raise InputError(f"no unknown {side}[{name!r}] in this solution") from None
        return self.covariance[6 * k:6 * k + 6, 6 * k:6 * k + 6].copy()


def _check_transforms(T, what: str) -> F64:
    """(N, 4, 4) finite rigid transforms, or InputError naming ``what``."""
    try:
        T = np.asarray(T, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what}: expected an array of 4x4 transforms ({exc})") from None
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise InputError(f"{what}: expected shape (N, 4, 4), got {T.shape}")
    if not np.all(np.isfinite(T)):
        bad = int(np.flatnonzero(~np.isfinite(T).all(axis=(1, 2)))[0])
        raise InputError(f"{what}[{bad}]: NaN or infinite entries")
    R = T[:, :3, :3]
    err = np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max(axis=(1, 2))
    row = np.abs(T[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1)
    bad = np.flatnonzero((err > 1e-6) | (row > 1e-9) | (np.linalg.det(R) <= 0))
    if bad.size:
        raise InputError(f"{what}[{int(bad[0])}]: not a rigid transform (rotation part not "
                         f"orthonormal with det +1, or last row not [0, 0, 0, 1])")
    return T


def as_groups(groups: Iterable) -> tuple[MeasurementGroup, ...]:
    """Validate groups and merge repeated (x_name, y_name) pairs, keeping first-seen order.

    Parameters
    ----------
    groups : iterable of (x_name, y_name, A, B)
        ``A``, ``B`` array_like, shape (N, 4, 4), with ``A[i] @ X[x_name] ≈ Y[y_name] @ B[i]``.

    Returns
    -------
    tuple of MeasurementGroup

    Raises
    ------
    InputError
        Malformed entries, non-rigid or non-finite transforms, mismatched counts.
    TooFewMeasurementsError
        No groups, or a group without measurements.
    """
    merged: dict[tuple[str, str], list[tuple[F64, F64]]] = {}
    for k, g in enumerate(groups):
        try:
            x_name, y_name, A, B = g
        except (TypeError, ValueError):
            raise InputError(f"group {k}: expected (x_name, y_name, A, B)") from None
        if not isinstance(x_name, str) or not isinstance(y_name, str):
            raise InputError(f"group {k}: names must be strings, got {x_name!r}, {y_name!r}")
        label = f"group ({x_name}, {y_name})"
        A = _check_transforms(A, f"{label} A")
        B = _check_transforms(B, f"{label} B")
        if len(A) != len(B):
            raise InputError(f"{label}: {len(A)} A but {len(B)} B transforms; "
                             "A[i] and B[i] must be paired")
        if len(A) == 0:
            raise TooFewMeasurementsError(f"{label}: no measurements")
        merged.setdefault((x_name, y_name), []).append((A, B))
    if not merged:
        raise TooFewMeasurementsError("no measurement groups given")
    return tuple(
        MeasurementGroup(x, y, np.concatenate([a for a, _ in parts]),
                         np.concatenate([b for _, b in parts]))
        for (x, y), parts in merged.items())


def _names(groups: tuple[MeasurementGroup, ...]) -> tuple[list[str], list[str]]:
    """X names and Y names in first-seen order."""
    xs = list(dict.fromkeys(g.x_name for g in groups))
    ys = list(dict.fromkeys(g.y_name for g in groups))
    return xs, ys


def check_connected(groups: tuple[MeasurementGroup, ...]) -> None:
    """Raise DisconnectedError unless the bipartite X/Y measurement graph is connected.

    The main component is the one with the most measurements; the error names every unknown
    outside it (``DisconnectedError.names``) and says which side each is on.
    """
    xs, ys = _names(groups)
    ix = {n: i for i, n in enumerate(xs)}
    iy = {n: len(xs) + i for i, n in enumerate(ys)}
    rows = [ix[g.x_name] for g in groups]
    cols = [iy[g.y_name] for g in groups]
    n = len(xs) + len(ys)
    adj = sp.coo_matrix((np.ones(len(groups)), (rows, cols)), shape=(n, n))
    ncomp, label = connected_components(adj, directed=False)
    if ncomp == 1:
        return
    weight = np.zeros(ncomp)
    for r, g in zip(rows, groups):
        weight[label[r]] += len(g.A)
    main = int(np.argmax(weight))
    nodes = [("X", x) for x in xs] + [("Y", y) for y in ys]
    outside = [nodes[k] for k in range(n) if label[k] != main]
    desc = ", ".join(f"{side}[{name}]" for side, name in outside)
    raise DisconnectedError(
        f"the measurements split the unknowns into {ncomp} unconnected sets; {desc} share no "
        f"chain of measurements with the others, so their poses relative to the rest are not "
        f"determined. Add measurements linking them, or solve each set on its own.",
        names=tuple(name for _, name in outside))


def _bipartite_blocks(groups, xs, ys, block):
    """Sparse ``G`` (``k n_Y x k n_X``) from the per-group kxk ``block`` sums, and degrees."""
    ix = {n: i for i, n in enumerate(xs)}
    iy = {n: i for i, n in enumerate(ys)}
    blocks = np.stack([block(g) for g in groups])
    k = blocks.shape[1]
    bi = np.array([iy[g.y_name] for g in groups])
    bj = np.array([ix[g.x_name] for g in groups])
    r = (bi[:, None, None] * k + np.arange(k)[None, :, None]).repeat(k, axis=2)
    c = (bj[:, None, None] * k + np.arange(k)[None, None, :]).repeat(k, axis=1)
    G = sp.csr_matrix((blocks.ravel(), (r.ravel(), c.ravel())), shape=(k * len(ys), k * len(xs)))
    dx = np.zeros(len(xs))
    dy = np.zeros(len(ys))
    for g in groups:
        dx[ix[g.x_name]] += len(g.A)
        dy[iy[g.y_name]] += len(g.A)
    return G, dx, dy


def _kron_sum(g: MeasurementGroup) -> F64:
    """``sum_i R_B[i] ⊗ R_A[i]`` (9 x 9) of one group: ``vec(R_A R_X R_B^T)`` for column-major vec."""
    RA = g.A[:, :3, :3]
    RB = g.B[:, :3, :3]
    return np.einsum("iac,ibd->abcd", RB, RA).reshape(9, 9)


def _vec_cm(R: F64) -> F64:
    """Column-major vec of (..., 3, 3)."""
    return np.swapaxes(R, -1, -2).reshape(R.shape[:-2] + (9,))


def _unvec_cm(v: F64) -> F64:
    return np.swapaxes(v.reshape(v.shape[:-1] + (3, 3)), -1, -2)


def _rotations(groups, xs, ys) -> tuple[F64, F64]:
    """Rotations of every X and every Y, shapes (n_X, 3, 3), (n_Y, 3, 3)."""
    G, dx, dy = _bipartite_blocks(groups, xs, ys, _kron_sum)
    wx = np.repeat(dx, 9)
    wy = np.repeat(dy, 9)
    C = sp.diags(wy ** -0.5) @ G @ sp.diags(wx ** -0.5)
    keep_y = len(ys) <= len(xs)
    CC = (C @ C.T) if keep_y else (C.T @ C)
    mu, V = np.linalg.eigh(CC.toarray())
    # mu[-1] = 1 without noise; 1 - mu[-2] measures how well the rotations are determined.
    lam1, lam2 = 1.0 - mu[-1], 1.0 - (mu[-2] if len(mu) > 1 else 0.0)
    if lam2 <= max(_ROTATION_GAP_TOL, 4.0 * lam1):
        raise DegenerateMotionError(
            "the rotations of the unknowns are not determined by the measurements (the "
            "rotation system has a second near-zero eigenvalue: the rotations of A and B "
            "vary about a single axis in the linked groups); rotate the targets or the rig "
            "about at least two different axes")
    top = V[:, -1]
    if keep_y:
        vy = top * wy ** -0.5
        vx = (G.T @ vy) / wx
    else:
        vx = top * wx ** -0.5
        vy = (G @ vx) / wy
    Mx = _unvec_cm(vx.reshape(-1, 9))
    My = _unvec_cm(vy.reshape(-1, 9))
    Mx *= np.sign(np.linalg.det(Mx))[:, None, None]
    My *= np.sign(np.linalg.det(My))[:, None, None]
    return project_to_so3(Mx), project_to_so3(My)


def _translations(groups, xs, ys, RX, RY) -> tuple[F64, F64]:
    """Translations of every X and every Y given the rotations, (n_X, 3), (n_Y, 3)."""
    ix = {n: i for i, n in enumerate(xs)}
    iy = {n: i for i, n in enumerate(ys)}
    G, dx, dy = _bipartite_blocks(groups, xs, ys, lambda g: g.A[:, :3, :3].sum(axis=0))
    # Normal equations of R_A t_X - t_Y = c with c = R_Y t_B - t_A:
    #   d_x t_X - G^T t_Y = bx,  -G t_X + d_y t_Y = by   (G[b, a] = sum R_A over group (a, b)).
    bx = np.zeros((len(xs), 3))
    by = np.zeros((len(ys), 3))
    for g in groups:
        a, b = ix[g.x_name], iy[g.y_name]
        c = g.B[:, :3, 3] @ RY[b].T - g.A[:, :3, 3]
        bx[a] += np.einsum("nji,nj->i", g.A[:, :3, :3], c)
        by[b] -= c.sum(axis=0)
    wx = np.repeat(dx, 3)
    wy = np.repeat(dy, 3)
    bx, by = bx.ravel(), by.ravel()
    if len(ys) <= len(xs):
        S = (sp.diags(wy) - G @ sp.diags(1.0 / wx) @ G.T).toarray()
        rhs = by + G @ (bx / wx)
    else:
        S = (sp.diags(wx) - G.T @ sp.diags(1.0 / wy) @ G).toarray()
        rhs = bx + G.T @ (by / wy)
    ev = np.linalg.eigvalsh(S)
    if ev[0] <= _TRANSLATION_RCOND * ev[-1]:
        raise DegenerateMotionError(
            "the translations of the unknowns are not determined by the measurements (the "
            "rotations of A do not vary enough within the linked groups); rotate the targets "
            "or the rig about at least two different axes")
    sol = np.linalg.solve(S, rhs)
    if len(ys) <= len(xs):
        ty = sol
        tx = (bx + G.T @ ty) / wx
    else:
        tx = sol
        ty = (by + G @ tx) / wy
    return tx.reshape(-1, 3), ty.reshape(-1, 3)


def loop_residuals(A, B, X, Y) -> tuple[F64, F64]:
    """Per-measurement residuals of ``A[i] X = Y B[i]`` (paper section V-A).

    Parameters
    ----------
    A, B : array_like, shape (N, 4, 4)
    X, Y : array_like, shape (4, 4)

    Returns
    -------
    rot_rad : ndarray, shape (N,)
        angle((R_Y R_B)^T (R_A R_X)), radians.
    trans_m : ndarray, shape (N,)
        ||(R_A t_X + t_A) - (R_Y t_B + t_Y)||, metres.
    """
    L = np.asarray(A, dtype=np.float64) @ np.asarray(X, dtype=np.float64)
    R = np.asarray(Y, dtype=np.float64) @ np.asarray(B, dtype=np.float64)
    rot = rotation_angle(np.swapaxes(R[:, :3, :3], 1, 2) @ L[:, :3, :3])
    trans = np.linalg.norm(L[:, :3, 3] - R[:, :3, 3], axis=1)
    return rot, trans


def group_residual(A, B, X, Y) -> CameraResidual:
    """Mean and worst loop residual of one group, as a :class:`CameraResidual`."""
    rot, trans = loop_residuals(A, B, X, Y)
    return CameraResidual(e_R_deg=float(np.degrees(rot.mean())), e_t_m=float(trans.mean()),
                          max_R_deg=float(np.degrees(rot.max())), max_t_m=float(trans.max()),
                          n=len(rot))


def assemble_solution(groups: tuple[MeasurementGroup, ...], X: Mapping[str, F64],
                      Y: Mapping[str, F64], method: str, **extra) -> GeneralSolution:
    """GeneralSolution with the residuals of every group (``extra``: covariance fields)."""
    xs, ys = _names(groups)
    return GeneralSolution(
        X=dict(X), Y=dict(Y), method=method,
        residuals={(g.x_name, g.y_name): group_residual(g.A, g.B, X[g.x_name], Y[g.y_name])
                   for g in groups},
        groups=tuple((g.x_name, g.y_name, len(g.A)) for g in groups),
        unknowns=tuple([("X", x) for x in xs] + [("Y", y) for y in ys]),
        **extra)


def solve_general(groups: Iterable, method: str = "joint", refine: bool = False,
                  **refine_options) -> GeneralSolution:
    """Solve ``A_i X[a] = Y[b] B_i`` for every X and every Y at once.

    Parameters
    ----------
    groups : iterable of (x_name, y_name, A, B)
        ``A``, ``B`` array_like, shape (N, 4, 4), meaning ``A[i] @ X[x_name] ≈ Y[y_name] @ B[i]``;
        metres.  Repeated (x_name, y_name) pairs are merged.
    method : {"joint"}
        The closed form described in the module docstring.
    refine : bool
        Follow the closed form with the maximum-likelihood refinement of the pose residuals
        (:func:`multieye.pose_refine.refine_general`), which also fills ``covariance``.
    **refine_options
        Keyword options of :func:`multieye.pose_refine.refine_general` (only with
        ``refine=True``).

    Returns
    -------
    GeneralSolution

    Raises
    ------
    InputError
        Malformed groups, non-rigid or non-finite transforms, mismatched counts, unknown method.
    TooFewMeasurementsError
        No groups or an empty group.
    DisconnectedError
        The measurement graph does not connect every unknown (``names`` lists those outside
        the main component).
    DegenerateMotionError
        The measurements do not determine the rotations or the translations.
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r} for solve_general; expected one of "
                         f"{', '.join(METHODS)}")
    if refine_options and not refine:
        raise InputError(f"refinement options {sorted(refine_options)} given without refine=True")
    groups = as_groups(groups)
    check_connected(groups)
    xs, ys = _names(groups)
    RX, RY = _rotations(groups, xs, ys)
    tX, tY = _translations(groups, xs, ys, RX, RY)
    X = dict(zip(xs, make_transform(RX, tX)))
    Y = dict(zip(ys, make_transform(RY, tY)))
    sol = assemble_solution(groups, X, Y, method)
    if refine:
        from .pose_refine import refine_general
        sol = refine_general(groups, sol, **refine_options)
    return sol
