"""Normal equations of a problem, reduced by the Schur complement, and their solution.

For the stacked Jacobian ``J = [J_g, J_l]`` of the weighted residuals (``g``: blocks kept,
``l``: blocks of families marked ``eliminate``)::

    [[U,   W], [W^T, V]] [dx_g, dx_l] = -[g_g, g_l],     U = J_g^T J_g,  W = J_g^T J_l,  V = J_l^T J_l

``V`` is block diagonal (one block per eliminated block), so ``dx_l`` is eliminated:

    S = U - W V^-1 W^T,    S dx_g = -(g_g - W V^-1 g_l),    dx_l = -V^-1 (g_l + W^T dx_g)

which is how bundle adjusters treat the points (Triggs et al. 2000, section 6.1).  ``S`` is
small and dense (the global blocks); it is factorised by Cholesky
(:func:`scipy.linalg.cho_factor`), and the same factorisation gives the covariance: the global
block of ``(J^T J)^-1`` is ``S^-1`` and each eliminated block's marginal covariance is
``V^-1 + V^-1 W^T S^-1 W V^-1`` (its diagonal block).

Everything is formed segment by segment (:class:`~multieye.optimize.blocks.ResidualGroup`):
per segment one small Gram matrix, summed into ``U``, ``V`` and the sparse ``W`` by index,
so the cost is linear in the residual rows; and piece by piece (:class:`Assembly`: a group's
segments a chunk at a time, :meth:`~multieye.optimize.blocks.ResidualGroup.linearize_chunks`),
so the memory holds the normal equations and one chunk's Jacobian, not the whole Jacobian.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.linalg import LinAlgError, cho_factor, cho_solve, eigh

from multieye.core.errors import InputError
from multieye.optimize.blocks import Blocks, ResidualGroup

__all__ = ["Layout", "NormalEquations", "Assembly", "assemble", "solve_step", "marginal_covariance"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Layout:
    """Where each family's parameters sit.

    Attributes
    ----------
    names : tuple of str
        Families in order.
    offset : dict of str to int
        Global families: first column in the reduced system; eliminated families: first block
        number among the eliminated blocks.
    k : int
        Parameters kept (size of ``S``).
    n_local : int
        Eliminated blocks.
    d : int
        Parameters per eliminated block (0 when there are none).
    """

    names: tuple[str, ...]
    offset: dict[str, int]
    k: int
    n_local: int
    d: int

    @staticmethod
    def of(families: Sequence[Blocks]) -> Layout:
        """Layout of ``families``: kept ones first in the given order, then eliminated ones."""
        names = [f.name for f in families]
        if len(set(names)) != len(names):
            raise InputError(f"block family names must be unique, got {names}")
        offset, k, n_local, d = {}, 0, 0, 0
        for f in families:
            if f.eliminate:
                if d and f.size != d:
                    raise InputError("eliminated block families must have one block size, got "
                                     f"{d} and {f.size}")
                d = f.size
                offset[f.name] = n_local
                n_local += f.count
            else:
                offset[f.name] = k
                k += f.count * f.size
        return Layout(tuple(names), offset, k, n_local, d)


@dataclass(frozen=True)
class NormalEquations:
    """``J^T J`` and ``J^T r`` of the weighted residuals, split into kept and eliminated parts.

    Attributes
    ----------
    U : ndarray, shape (k, k)
    g : ndarray, shape (k,)
    V : ndarray, shape (n_local, d, d)
    g_local : ndarray, shape (n_local, d)
    W : scipy.sparse.csr_matrix, shape (k, n_local * d)
    """

    U: F64
    g: F64
    V: F64
    g_local: F64
    W: sp.csr_matrix


def _columns(layout: Layout, families: dict[str, Blocks], group: ResidualGroup):
    """Per segment: kept columns (S, cg) with their positions in the row Jacobian, and the
    eliminated block (S,) with its positions (or None)."""
    gcols, gpos, lblock, lpos, at = [], [], None, None, 0
    for s, name in enumerate(group.slots):
        f = families[name]
        pos = np.arange(at, at + f.size)
        at += f.size
        if f.eliminate:
            if lblock is not None:
                raise InputError(f"a residual group touches two eliminated blocks per row "
                                 f"({group.slots})")
            lblock, lpos = layout.offset[name] + group.index[:, s], pos
        else:
            gcols.append(layout.offset[name] + group.index[:, s, None] * f.size
                         + np.arange(f.size))
            gpos.append(pos)
    cols = np.concatenate(gcols, axis=1) if gcols else np.zeros((len(group.index), 0), int)
    return cols, (np.concatenate(gpos) if gpos else np.zeros(0, int)), lblock, lpos


class Assembly:
    """``J^T J`` and ``J^T r`` summed piece by piece, so that no more than one piece's Jacobian
    is held at a time (the pieces of a group: :meth:`~multieye.optimize.blocks.ResidualGroup.
    linearize_chunks`).

    Parameters
    ----------
    layout : Layout
    families : dict of str to Blocks
    clusters : multieye.optimize.clusters.ClusterRecord, optional
        Also keep each segment's share (its Gram blocks and score) there, for the
        cluster-robust covariance (:func:`multieye.optimize.clusters.jackknife_covariance`).
    """

    def __init__(self, layout: Layout, families: dict[str, Blocks], clusters=None):
        self.layout, self.families, self.clusters = layout, families, clusters
        k, L, d = layout.k, layout.n_local, layout.d
        self.U = np.zeros(k * k)
        self.g = np.zeros(k)
        self.V = np.zeros(L * d * d)
        self.gl = np.zeros(L * d)
        self._w: list[sp.csr_matrix] = []
        self._wr: list[F64] = []
        self._wc: list[F64] = []
        self._wd: list[F64] = []

    def add(self, group, B: F64, rb: F64, weights: F64 | None = None,
            gradient_weights: F64 | None = None) -> None:
        """Add one piece: ``group`` (or a :class:`~multieye.optimize.blocks.SegmentRange` of
        it), its Jacobian blocks ``B`` (S, m dim, c) and padded residuals ``rb`` (S, m dim),
        with per-component weights (n_rows, dim) if given: ``J^T diag(w) J`` and
        ``J^T diag(w) r``; or, with ``gradient_weights`` too, ``J^T diag(w) J`` and
        ``J^T diag(gradient_weights) r`` (a robust loss's curvature and its slope)."""
        layout = self.layout
        k, L, d = layout.k, layout.n_local, layout.d
        if group.n_rows == 0:
            return
        S = len(group.index)
        if gradient_weights is not None:
            gs = (np.swapaxes(B, 1, 2) @ (rb * group.pad(gradient_weights))[:, :, None])[:, :, 0]
            B = B * group.pad(np.sqrt(weights))[:, :, None]
            Bt = np.swapaxes(B, 1, 2)
        else:
            if weights is not None:
                sw = group.pad(np.sqrt(weights))
                B = B * sw[:, :, None]
                rb = rb * sw
            Bt = np.swapaxes(B, 1, 2)
            gs = (Bt @ rb[:, :, None])[:, :, 0]                           # (S, c)
        G = Bt @ B                                                        # (S, c, c)
        cols, gpos, lblock, lpos = _columns(layout, self.families, group)
        if self.clusters is not None:
            Gkk = G[:, gpos][:, :, gpos]
            self.clusters.add(lblock, cols, Gkk, None if lblock is None else
                              G[:, gpos][:, :, lpos], gs[:, gpos])
        if cols.shape[1]:
            Ugg = G[:, gpos][:, :, gpos]
            self.U += np.bincount((cols[:, :, None] * k + cols[:, None, :]).ravel(), Ugg.ravel(),
                                  minlength=k * k)
            self.g += np.bincount(cols.ravel(), gs[:, gpos].ravel(), minlength=k)
        if lblock is not None:
            Vll = G[:, lpos][:, :, lpos]
            self.V += np.bincount((lblock[:, None] * d * d + np.arange(d * d)).ravel(),
                                  Vll.ravel(), minlength=L * d * d)
            lcols = lblock[:, None] * d + np.arange(d)                    # (S, d)
            self.gl += np.bincount(lcols.ravel(), gs[:, lpos].ravel(), minlength=L * d)
            if cols.shape[1]:
                self._wr.append(np.broadcast_to(cols[:, :, None], (S, cols.shape[1], d)).ravel())
                self._wc.append(np.broadcast_to(lcols[:, None, :], (S, cols.shape[1], d)).ravel())
                self._wd.append(G[:, gpos][:, :, lpos].ravel())
                if sum(a.size for a in self._wd) > 4_000_000:     # keep W's triplets bounded
                    self._collapse()

    def _collapse(self) -> None:
        k, L, d = self.layout.k, self.layout.n_local, self.layout.d
        if self._wd:
            self._w.append(sp.csr_matrix((np.concatenate(self._wd), (np.concatenate(self._wr),
                                          np.concatenate(self._wc))), shape=(k, L * d)))
            self._wr, self._wc, self._wd = [], [], []

    def result(self) -> NormalEquations:
        k, L, d = self.layout.k, self.layout.n_local, self.layout.d
        self._collapse()
        W = sum(self._w[1:], self._w[0]) if self._w else sp.csr_matrix((k, L * d))
        return NormalEquations(self.U.reshape(k, k), self.g, self.V.reshape(L, d, d),
                               self.gl.reshape(L, d), sp.csr_matrix(W))


def assemble(layout: Layout, families: dict[str, Blocks], groups: Sequence[ResidualGroup],
             linearized: Sequence[tuple[F64, F64, F64]], weights: Sequence[F64] | None = None
             ) -> NormalEquations:
    """Normal equations of the (weighted) residuals.

    Parameters
    ----------
    layout : Layout
    families : dict of str to Blocks
    groups : sequence of ResidualGroup
    linearized : sequence of (residuals (n, dim), blocks (S, m dim, c), padded (S, m dim))
        What each group's :meth:`~ResidualGroup.linearize` returned.
    weights : sequence of ndarray, shape (n, dim), optional
        Per-component weights (the robust loss's IRLS weights); 1 when not given.
    """
    acc = Assembly(layout, families)
    for n, (group, (_, B, rb)) in enumerate(zip(groups, linearized)):
        acc.add(group, B, rb, None if weights is None else weights[n])
    return acc.result()


#: Relative eigenvalue of the Jacobi-scaled reduced system below which a direction counts as
#: not determined by the data.
_UNDETERMINED = 1e-12


def _factor(S: F64):
    """Cholesky of ``S`` with a Jacobi scaling (parameters in pixels, metres, radians and
    unitless distortion differ by orders of magnitude): ``(c, d)`` with ``S = D C D``."""
    d = np.sqrt(np.maximum(np.diag(S), 1e-300))
    with np.errstate(over="ignore", invalid="ignore"):
        scaled = S / np.outer(d, d)
    if not np.all(np.isfinite(scaled)):     # a diagonal at the floor: not definite
        raise LinAlgError("the Jacobi-scaled system is not finite")
    return cho_factor(scaled), d


def _solve(factor, rhs: F64) -> F64:
    c, d = factor
    if rhs.ndim == 1:
        return cho_solve(c, rhs / d) / d
    return cho_solve(c, rhs / d[:, None]) / d[:, None]


def _block_diagonal(blocks: F64) -> sp.csr_matrix:
    L, d, _ = blocks.shape
    return sp.bsr_matrix((blocks, np.arange(L), np.arange(L + 1)), shape=(L * d, L * d)).tocsr()


def _reduce(ne: NormalEquations, lam: float):
    """Damped Schur complement: ``S``, ``V^-1`` and ``W V^-1`` (or None if not definite)."""
    U = ne.U
    if lam:
        diag = np.diag(U)
        U = U + lam * np.diag(np.maximum(diag, 1e-12 * max(float(diag.max(initial=0.0)), 1.0)))
    if ne.V.size == 0:
        return U, ne.V, None
    V = ne.V
    if lam:
        V = V.copy()
        idx = np.arange(V.shape[1])
        V[:, idx, idx] *= 1.0 + lam
    try:
        Vinv = np.linalg.inv(V)
    except np.linalg.LinAlgError:
        return None
    WVi = ne.W @ _block_diagonal(Vinv)
    return U - (WVi @ ne.W.T).toarray(), Vinv, WVi


def solve_step(ne: NormalEquations, lam: float) -> tuple[F64, F64] | None:
    """The Levenberg-Marquardt step for damping ``lam`` (Marquardt's diagonal scaling).

    Returns
    -------
    (dx_global (k,), dx_local (n_local, d)), or None when the damped system is not positive
    definite.
    """
    reduced = _reduce(ne, lam)
    if reduced is None:
        return None
    S, Vinv, WVi = reduced
    rhs = -ne.g
    if WVi is not None:
        rhs = rhs + WVi @ ne.g_local.ravel()
    try:
        dg = _solve(_factor(S), rhs) if S.size else np.zeros(0)
    except LinAlgError:
        return None
    if WVi is None:
        return dg, np.zeros((0, 0))
    back = ne.g_local + (ne.W.T @ dg).reshape(ne.g_local.shape)
    return dg, -np.einsum("lij,lj->li", Vinv, back)


def marginal_covariance(ne: NormalEquations, *, local: bool = False
                        ) -> tuple[F64, F64 | None, F64]:
    """``(J^T J)^-1``: its kept block, and the diagonal blocks of the eliminated ones.

    When the kept system is numerically singular although every parameter is observed (a
    combination of parameters the data cannot tell apart, e.g. the numerator and the
    denominator terms of the rational lens model over a narrow field of view), the inverse
    is taken on the determined directions only (a pseudo-inverse of the Jacobi-scaled
    system) and the undetermined directions are returned, so that the caller can say so.

    Parameters
    ----------
    ne : NormalEquations
        Of the unweighted (noise-normalised) residuals at the optimum.
    local : bool
        Also return each eliminated block's marginal covariance.

    Returns
    -------
    cov : ndarray, shape (k, k)
    cov_local : ndarray, shape (n_local, d, d), or None
    undetermined : ndarray, shape (k, r)
        Unit directions of the kept parameters (in their own units) that the data do not
        determine; r = 0 when the system is regular.

    Raises
    ------
    InputError
        A parameter (or an eliminated block) has no information at all.
    """
    if np.any(np.diag(ne.U) <= 0.0):       # a parameter no residual depends on
        raise InputError("the information matrix is singular: the data do not determine "
                         "every parameter (too few measurements, or motion that leaves a "
                         "direction unobserved)")
    # Jacobi-scaled before the reduction: unscaled, a parameter with an information of 1e23
    # (a rational lens whose numerator and denominator nearly share a factor) left the
    # reduced system's other entries below its rounding, and their diagonal cancelled to
    # zero or below
    scaled, dk, dl = _jacobi_scaled(ne)
    reduced = _reduce(scaled, 0.0)
    if reduced is None:
        raise InputError("the information matrix is singular: an eliminated block is not "
                         "determined by its residuals")
    S, Vinv, WVi = reduced
    k = len(S)
    undetermined = np.zeros((k, 0))
    try:
        cov = cho_solve(cho_factor(S), np.eye(k)) if S.size else S
    except LinAlgError:
        w, V = eigh(S)
        keep = w > _UNDETERMINED * w.max()
        cov = (V[:, keep] / w[keep]) @ V[:, keep].T
        undetermined = V[:, ~keep] / dk[:, None]
        undetermined /= np.linalg.norm(undetermined, axis=0)
    cov = 0.5 * (cov + cov.T)                                            # scaled
    if not local or WVi is None:
        return cov / np.outer(dk, dk), None, undetermined
    L, d = ne.g_local.shape
    Z = WVi.T.toarray().reshape(L, d, -1)                                 # V^-1 W^T
    local_cov = Vinv + Z @ cov @ np.swapaxes(Z, 1, 2)
    return cov / np.outer(dk, dk), local_cov / (dl[:, :, None] * dl[:, None, :]), undetermined


def _jacobi_scaled(ne: NormalEquations) -> tuple[NormalEquations, F64, F64]:
    """``ne`` with every parameter scaled to unit information (``D^-1 H D^-1``, ``D`` the
    root of the diagonal of the whole ``J^T J``): ``(scaled, d_kept (k,), d_local (L, d))``.
    An eliminated block's zero diagonal stays zero (its inverse then fails, as unscaled)."""
    dk = np.sqrt(np.diag(ne.U))
    dl = np.sqrt(np.einsum("lii->li", ne.V))
    dl = np.where(dl > 0, dl, 1.0)          # a zero diagonal left as it is (its column too)
    W = sp.csr_matrix(sp.diags(1.0 / dk) @ ne.W @ sp.diags(1.0 / dl.ravel()))
    scaled = NormalEquations(U=ne.U / np.outer(dk, dk), g=ne.g / dk,
                             V=ne.V / (dl[:, :, None] * dl[:, None, :]),
                             g_local=ne.g_local / dl, W=W)
    return scaled, dk, dl
