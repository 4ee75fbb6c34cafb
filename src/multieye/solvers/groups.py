"""Input and result of the general problem ``A_i X_a = Y_b B_i``: measurement groups, solution.

Shared by the closed form (:mod:`multieye.solvers.general`) and the pose-level refinement
(:mod:`multieye.solvers.refine_poses`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from multieye.core.arguments import real_array
from multieye.core.errors import DisconnectedError, InputError, TooFewMeasurementsError
from multieye.core.metrics import CameraResidual, camera_residual
from multieye.core.problem import MeasurementGroup
from multieye.solvers.checks import check_transforms

__all__ = ["MeasurementGroup", "GeneralSolution", "as_groups", "check_connected",
           "assemble_solution", "group_names"]

F64 = NDArray[np.float64]


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
        After refinement (:func:`multieye.solvers.refine_poses.refine_general`): joint covariance of
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
    T = real_array(T, what, expected="an array of 4x4 transforms, shape (N, 4, 4)")
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
    if groups is None or isinstance(groups, (str, bytes, Mapping)) or not isinstance(
            groups, Iterable):
        raise InputError(f"groups must be an iterable of (x_name, y_name, A, B), got "
                         f"{type(groups).__name__}")
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


def group_names(groups: tuple[MeasurementGroup, ...]) -> tuple[list[str], list[str]]:
    """X names and Y names in first-seen order."""
    xs = list(dict.fromkeys(g.x_name for g in groups))
    ys = list(dict.fromkeys(g.y_name for g in groups))
    return xs, ys


def check_connected(groups: tuple[MeasurementGroup, ...]) -> None:
    """Raise DisconnectedError unless the bipartite X/Y measurement graph is connected.

    The main component is the one with the most measurements; the error names every unknown
    outside it (``DisconnectedError.names``) and says which side each is on.
    """
    xs, ys = group_names(groups)
    ix = {n: i for i, n in enumerate(xs)}
    iy = {n: len(xs) + i for i, n in enumerate(ys)}
    rows = [ix[g.x_name] for g in groups]
    cols = [iy[g.y_name] for g in groups]
    n = len(xs) + len(ys)
    adj = sp.coo_matrix((np.ones(len(groups)), (rows, cols)), shape=(n, n))
    from scipy.sparse.csgraph import connected_components  # noqa: PLC0415 (heavy: it imports scipy.sparse.linalg, about 0.05 CPU-s; general rigs only)

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


def assemble_solution(groups: tuple[MeasurementGroup, ...], X: Mapping[str, F64],
                      Y: Mapping[str, F64], method: str, **extra) -> GeneralSolution:
    """GeneralSolution with the residuals of every group (``extra``: covariance fields)."""
    xs, ys = group_names(groups)
    return GeneralSolution(
        X=dict(X), Y=dict(Y), method=method,
        residuals={(g.x_name, g.y_name): camera_residual(g.A, g.B, X[g.x_name], Y[g.y_name])
                   for g in groups},
        groups=tuple((g.x_name, g.y_name, len(g.A)) for g in groups),
        unknowns=tuple([("X", x) for x in xs] + [("Y", y) for y in ys]),
        **extra)
