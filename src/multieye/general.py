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
noise; the rotations are taken as undetermined (:class:`~multieye.errors.DegenerateMotionError`)
when its second-smallest eigenvalue is below ``1e-8`` or below 4 times the smallest (the
noise floor), and the translations when the reduced translation system is singular to
``1e-10`` relative.  A group may be degenerate on its own (few rows, one rotation axis) as
long as the whole graph is not.

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
from .geometry import inv, make_transform, random_transforms, transform_from_rotvec
from .metrics import camera_residual
from .solvers.checks import Measurements, check_transforms
from .solvers.kronecker import TRANSLATION_RCOND, normalize_rotation, unvec, vec
from .solvers.result import CameraResidual

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


def _as_transform_batch(T, what: str) -> F64:
    try:
        T = np.asarray(T, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{what}: expected an array of 4x4 transforms ({exc})") from None
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise InputError(f"{what}: expected shape (N, 4, 4), got {T.shape}")
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
        Malformed entries, non-rigid or non-finite transforms (see
        :func:`multieye.solvers.checks.check_transforms`; the message names the group and
        the row), mismatched counts.
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
        label = f"({x_name}, {y_name})"
        A = _as_transform_batch(A, f"A{label}")
        B = _as_transform_batch(B, f"B{label}")
        if len(A) != len(B):
            raise InputError(f"group {label}: {len(A)} A but {len(B)} B transforms; "
                             "A[i] and B[i] must be paired")
        if len(A) == 0:
            raise TooFewMeasurementsError(f"group {label}: no measurements")
        merged.setdefault((x_name, y_name), []).append((A, B))
    if not merged:
        raise TooFewMeasurementsError("no measurement groups given")
    out = tuple(
        MeasurementGroup(x, y, *(parts[0] if len(parts) == 1 else
                                 (np.concatenate([a for a, _ in parts]),
                                  np.concatenate([b for _, b in parts]))))
        for (x, y), parts in merged.items())
    # One vectorised rigidity check over everything; per group only to name the culprit.
    for side in ("A", "B"):
        try:
            check_transforms(np.concatenate([getattr(g, side) for g in out]), side)
        except InputError:
            for g in out:
                check_transforms(getattr(g, side), f"{side}({g.x_name}, {g.y_name})")
            raise
    return out


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
    np.add.at(weight, label[rows], [len(g.A) for g in groups])
    main = int(np.argmax(weight))
    nodes = [("X", x) for x in xs] + [("Y", y) for y in ys]
    outside = [nodes[k] for k in range(n) if label[k] != main]
    desc = ", ".join(f"{side}[{name}]" for side, name in outside)
    raise DisconnectedError(
        f"the measurements split the unknowns into {ncomp} unconnected sets; {desc} share no "
        f"chain of measurements with the others, so their poses relative to the rest are not "
        f"determined. Add measurements linking them, or solve each set on its own.",
        names=tuple(name for _, name in outside))


class _Layout(NamedTuple):
    """Index maps of a grouped problem: names, group -> unknown, measurement counts."""

    xs: list[str]
    ys: list[str]
    gx: np.ndarray      # (n_groups,) X index of each group
    gy: np.ndarray      # (n_groups,) Y index of each group
    dx: np.ndarray      # (n_X,) measurements of each X
    dy: np.ndarray      # (n_Y,) measurements of each Y


def _layout(groups: tuple[MeasurementGroup, ...], counts: np.ndarray) -> _Layout:
    xs, ys = _names(groups)
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


def assemble_solution(groups: tuple[MeasurementGroup, ...], X: Mapping[str, F64],
                      Y: Mapping[str, F64], method: str, **extra) -> GeneralSolution:
    """GeneralSolution with the residuals of every group (``extra``: covariance fields)."""
    xs, ys = _names(groups)
    return GeneralSolution(
        X=dict(X), Y=dict(Y), method=method,
        residuals={(g.x_name, g.y_name): camera_residual(g.A, g.B, X[g.x_name], Y[g.y_name])
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
        from .pose_refine import refine_general
        sol = refine_general(groups, sol, **refine_options)
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
    :mod:`multieye.pose_refine` Gaussian with exactly those per-component sigmas.

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
