"""Closed-form solution of the general problem ``A_i X_a = Y_b B_i`` (several X, several Y).

Each measurement ``i`` names one unknown on each side: ``A_i @ X[a] ≈ Y[b] @ B_i``.  The
paper's case (Wang et al. ICRA 2022) is the special case of one Y shared by every camera;
Wise et al. (2025, "A certifiably correct algorithm for generalized robot-world and hand-eye
calibration") pose the general case, with several cameras and several targets at once.

Synopsis
--------
>>> from multieye.solvers.general import solve_general
>>> sol = solve_general([("tag0", "cam0", A00, B00), ("tag0", "cam1", A01, B01),
...                      ("tag1", "cam1", A11, B11)])            # doctest: +SKIP
>>> sol.Y["cam1"]                                                # (4, 4)   # doctest: +SKIP

Method (``method="joint"``)
---------------------------
Rotation.  With column-major ``vec``, ``R_A R_X = R_Y R_B`` is the linear row block
``(R_B ⊗ R_A) vec(R_X) - vec(R_Y) = 0`` (paper section IV-A, here one block per measurement
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
dense symmetric system of size ``3 min(n_X, n_Y)`` remains.  The per-group sums both steps
need are formed in one pass (:class:`multieye.solvers.kronecker.CameraStats`, one "camera"
per group).

Degeneracy.  The normalised rotation system ``I - C C^T`` has one zero eigenvalue without
noise; the rotations are taken as undetermined (:class:`~multieye.core.errors.DegenerateMotionError`)
when its second-smallest eigenvalue is below ``1e-8`` or below 4 times the smallest (the
noise floor), and the translations when the reduced translation system is singular to
``1e-10`` relative.  A group may be degenerate on its own (few rows, one rotation axis) as
long as the whole graph is not.

Connectivity.  Unknowns are nodes of the bipartite graph X-names/Y-names, groups its edges.
If the graph has several components the problem is not one problem: :func:`solve_general`
raises :class:`~multieye.core.errors.DisconnectedError` naming the unknowns outside the main
component (the one with the most measurements) instead of returning values for them.  Solve
each component separately by calling :func:`solve_general` on its groups.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from multieye.core.errors import DegenerateMotionError, InputError
from multieye.core.geometry import inv, make_transform, random_transforms, transform_from_rotvec
from multieye.solvers.measurements import Measurements
from multieye.solvers.groups import (
    GeneralSolution,
    MeasurementGroup,
    as_groups,
    assemble_solution,
    check_connected,
    group_names,
)
from multieye.solvers.kronecker import TRANSLATION_RCOND, normalize_rotation, unvec, vec
from multieye.solvers.refine_poses import check_refine_options, refine_groups

__all__ = [
    "MeasurementGroup",
    "GeneralSolution",
    "solve_general",
    "as_groups",
    "check_connected",
    "random_general_problem",
    "METHODS",
]

F64 = NDArray[np.float64]

METHODS = ("joint",)

# The rotation system's second eigenvalue (normalised as in _rotations) must exceed this and
# 4 times the first (the noise floor) for the rotations to be determined (0 without noise).
_ROTATION_GAP_TOL = 1e-8
# The reduced translation system is singular below TRANSLATION_RCOND (smallest / largest
# eigenvalue), as in the joint solver.


class _Layout(NamedTuple):
    """Index maps of a grouped problem: names, group -> unknown, measurement counts."""

    xs: list[str]
    ys: list[str]
    gx: np.ndarray      # (n_groups,) X index of each group
    gy: np.ndarray      # (n_groups,) Y index of each group
    dx: np.ndarray      # (n_X,) measurements of each X
    dy: np.ndarray      # (n_Y,) measurements of each Y


def _layout(groups: tuple[MeasurementGroup, ...], counts: np.ndarray) -> _Layout:
    xs, ys = group_names(groups)
    ix = {n: i for i, n in enumerate(xs)}
    iy = {n: i for i, n in enumerate(ys)}
    gx = np.array([ix[g.x_name] for g in groups])
    gy = np.array([iy[g.y_name] for g in groups])
    return _Layout(xs, ys, gx, gy, np.bincount(gx, weights=counts, minlength=len(xs)),
                   np.bincount(gy, weights=counts, minlength=len(ys)))


def _bipartite(lay: _Layout, blocks: F64) -> sp.csr_matrix:
    """Sparse ``G`` (k n_Y x k n_X) whose block (b, a) is the sum of ``blocks`` of groups (a, b)."""
    k = blocks.shape[1]
    r = (lay.gy[:, None, None] * k + np.arange(k)[None, :, None]).repeat(k, axis=2)
    c = (lay.gx[:, None, None] * k + np.arange(k)[None, None, :]).repeat(k, axis=1)
    return sp.csr_matrix((blocks.ravel(), (r.ravel(), c.ravel())),
                         shape=(k * len(lay.ys), k * len(lay.xs)))


def _rotations(lay: _Layout, K: F64) -> tuple[F64, F64]:
    """Rotations of every X and every Y, (n_X, 3, 3) and (n_Y, 3, 3).

    ``K`` (n_groups, 9, 9) holds each group's ``sum_i R_B ⊗ R_A``.
    """
    G = _bipartite(lay, K)
    wx = np.repeat(lay.dx, 9)
    wy = np.repeat(lay.dy, 9)
    C = sp.diags(wy ** -0.5) @ G @ sp.diags(wx ** -0.5)
    keep_y = len(lay.ys) <= len(lay.xs)
    mu, V = np.linalg.eigh((C @ C.T if keep_y else C.T @ C).toarray())
    # Eigenvalues of the normalised normal matrix are 1 - mu: the smallest is 0 without
    # noise; a second one near it leaves the rotations undetermined.
    lam1, lam2 = 1.0 - mu[-1], 1.0 - mu[-2]
    if lam2 <= max(_ROTATION_GAP_TOL, 4.0 * lam1):
        raise DegenerateMotionError(
            "the rotations of the unknowns are not determined by the measurements (the "
            "rotation system has a second near-zero eigenvalue: within the linked groups the "
            "rotations of A vary about a single axis, or not at all); rotate the targets or "
            "the rig about at least two different axes")
    top = V[:, -1]
    if keep_y:
        vy = top * wy ** -0.5
        vx = (G.T @ vy) / wx
    else:
        vx = top * wx ** -0.5
        vy = (G @ vx) / wy
    return normalize_rotation(unvec(vx.reshape(-1, 9))), normalize_rotation(unvec(vy.reshape(-1, 9)))


def _translations(lay: _Layout, stats, RX: F64, RY: F64) -> tuple[F64, F64]:
    """Translations of every X and every Y given the rotations, (n_X, 3) and (n_Y, 3).

    Least squares of ``R_A t_X - t_Y = c`` with ``c = R_Y t_B - t_A`` over all measurements.
    Normal equations, with ``G[b, a] = sum over group (a, b) of R_A``:
    ``d_x t_X - G^T t_Y = bx`` and ``-G t_X + d_y t_Y = by`` where ``bx[a] = sum R_A^T c``
    and ``by[b] = -sum c``.  ``stats`` are the per-group sums
    (:class:`multieye.solvers.kronecker.CameraStats`).
    """
    RYg = RY[lay.gy]                                             # (n_groups, 3, 3)
    q = np.einsum("gij,gj->gi", stats.G, vec(RYg)) - stats.h     # sum R_A^T c per group
    s = np.einsum("gij,gj->gi", RYg, stats.StB) - stats.StA      # sum c per group
    bx = np.zeros((len(lay.xs), 3))
    by = np.zeros((len(lay.ys), 3))
    np.add.at(bx, lay.gx, q)
    np.add.at(by, lay.gy, -s)
    G = _bipartite(lay, stats.SA)
    wx = np.repeat(lay.dx, 3)
    wy = np.repeat(lay.dy, 3)
    bx, by = bx.ravel(), by.ravel()
    keep_y = len(lay.ys) <= len(lay.xs)
    if keep_y:
        S = (sp.diags(wy) - G @ sp.diags(1.0 / wx) @ G.T).toarray()
        rhs = by + G @ (bx / wx)
    else:
        S = (sp.diags(wx) - G.T @ sp.diags(1.0 / wy) @ G).toarray()
        rhs = bx + G.T @ (by / wy)
    ev = np.linalg.eigvalsh(S)
    if ev[0] <= TRANSLATION_RCOND * ev[-1]:
        raise DegenerateMotionError(
            "the translations of the unknowns are not determined by the measurements (within "
            "the linked groups the rotations of A do not vary enough); rotate the targets or "
            "the rig about at least two different axes")
    sol = np.linalg.solve(S, rhs)
    if keep_y:
        ty = sol
        tx = (bx + G.T @ ty) / wx
    else:
        tx = sol
        ty = (by + G @ tx) / wy
    return tx.reshape(-1, 3), ty.reshape(-1, 3)


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
        (:func:`multieye.solvers.refine_poses.refine_general`), which also fills ``covariance``.
    **refine_options
        Keyword options of :func:`multieye.solvers.refine_poses.refine_general` (only with
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
    if not isinstance(method, str) or method not in METHODS:
        raise InputError(f"unknown method {method!r} for solve_general; expected one of "
                         f"{', '.join(METHODS)}")
    if refine_options and not refine:
        raise InputError(f"refinement options {sorted(refine_options)} given without refine=True")
    if refine:
        check_refine_options(refine_options)
    groups = as_groups(groups)
    check_connected(groups)
    counts = np.array([len(g.A) for g in groups])
    stats = Measurements.from_arrays(np.concatenate([g.A for g in groups]),
                                     np.concatenate([g.B for g in groups]), counts).stats
    lay = _layout(groups, counts)
    RX, RY = _rotations(lay, stats.K)
    tX, tY = _translations(lay, stats, RX, RY)
    X = dict(zip(lay.xs, make_transform(RX, tX)))
    Y = dict(zip(lay.ys, make_transform(RY, tY)))
    sol = assemble_solution(groups, X, Y, method)
    if refine:
        sol = refine_groups(groups, sol, **refine_options)
    return sol


def random_general_problem(rng: np.random.Generator, n_x: int, n_y: int, n_measurements: int, *,
                           n_groups: int | None = None, rot_noise_rad: float = 0.0,
                           trans_noise_m: float = 0.0, translation_scale: float = 1.0):
    """A random connected general problem with known answer (tests, benchmarks).

    The X/Y graph is a random spanning tree plus random extra pairs up to ``n_groups``; every
    group gets at least one measurement and the rest are spread at random.  ``A`` are
    uniformly random rotations with Gaussian translations; ``B = inv(Y) A X`` then
    ``B <- B [Exp(n_R), n_t]`` with ``n_R ~ N(0, rot_noise_rad^2 I)``,
    ``n_t ~ N(0, trans_noise_m^2 I)``, which makes the residuals of
    :mod:`multieye.solvers.refine_poses` Gaussian with exactly those per-component sigmas.

    Parameters
    ----------
    rng : numpy.random.Generator
    n_x, n_y : int
        Number of X unknowns (``"x0"``, ...) and Y unknowns (``"y0"``, ...).
    n_measurements : int
        Total measurements, at least the number of groups.
    n_groups : int, optional
        Number of (x, y) pairs, from ``n_x + n_y - 1`` (a tree) to ``n_x n_y``; default
        halfway.
    rot_noise_rad, trans_noise_m : float
        Noise on B, radians and metres per component.
    translation_scale : float
        Scale of the random translations, metres.

    Returns
    -------
    groups : list of MeasurementGroup
    X, Y : dict of str -> ndarray, shape (4, 4)
        The true unknowns.
    """
    lo, hi = n_x + n_y - 1, n_x * n_y
    n_groups = (lo + hi) // 2 if n_groups is None else n_groups
    if not lo <= n_groups <= hi or n_measurements < n_groups:
        raise InputError(f"need {lo} <= n_groups <= {hi} and n_measurements >= n_groups, got "
                         f"n_groups={n_groups}, n_measurements={n_measurements}")
    X = {f"x{i}": T for i, T in enumerate(random_transforms(rng, n_x,
                                                              translation_scale=translation_scale))}
    Y = {f"y{i}": T for i, T in enumerate(random_transforms(rng, n_y,
                                                              translation_scale=translation_scale))}
    # Random bipartite spanning tree: each new node hangs from a placed node of the other side.
    order = [("x", i) for i in range(1, n_x)] + [("y", i) for i in range(1, n_y)]
    rng.shuffle(order)
    placed = {"x": [0], "y": [0]}
    pairs = {(0, 0)}
    for side, i in order:
        other = placed["y" if side == "x" else "x"]
        j = int(other[rng.integers(len(other))])
        pairs.add((i, j) if side == "x" else (j, i))
        placed[side].append(i)
    rest = [(a, b) for a in range(n_x) for b in range(n_y) if (a, b) not in pairs]
    for k in rng.choice(len(rest), size=n_groups - len(pairs), replace=False):
        pairs.add(rest[k])
    pairs = sorted(pairs)
    counts = 1 + rng.multinomial(n_measurements - len(pairs), np.full(len(pairs), 1 / len(pairs)))
    groups = []
    for (a, b), n in zip(pairs, counts):
        Xa, Yb = X[f"x{a}"], Y[f"y{b}"]
        A = random_transforms(rng, int(n), translation_scale=translation_scale)
        B = inv(Yb) @ A @ Xa
        if rot_noise_rad or trans_noise_m:
            B = B @ transform_from_rotvec(rng.normal(scale=rot_noise_rad, size=(n, 3)),
                                          rng.normal(scale=trans_noise_m, size=(n, 3)))
        B[:, 3] = [0.0, 0.0, 0.0, 1.0]
        groups.append(MeasurementGroup(f"x{a}", f"y{b}", A, B))
    return groups, X, Y
