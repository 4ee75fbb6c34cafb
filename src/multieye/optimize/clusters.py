"""Cluster-robust covariance: the delete-one-cluster jackknife of the kept parameters.

The model-based covariance ``(J^T J)^-1`` of :func:`~multieye.optimize.normal_equations.
marginal_covariance` is right when every residual component is independent with the noise
it was normalised by.  When the errors of the rows of one measurement are correlated, or
their noise differs from the stated one, it is not; a *cluster-robust* covariance (Liang and
Zeger 1986; the sandwich of White 1980 with clusters) needs only that the clusters are
independent.  Here a cluster is one eliminated block's rows (one measurement: every row
that touches it, e.g. every image of one motion-capture instant and its prior), and a row
that touches no eliminated block is a cluster of its own segment.

For cluster ``c`` with profiled score and information (its eliminated block ``l``
marginalised, which only its own rows touch)::

    g_c = g_kept,c - W_c V_l^-1 g_l,        S_c = U_c - W_c V_l^-1 W_c^T

the Gauss-Newton change of the kept parameters when the cluster is deleted is
``d_c = (S - S_c)^-1 g_c`` (one step from the optimum; ``S`` the reduced information of
every cluster), computed from ``C = S^-1`` by the Woodbury identity on the few columns the
cluster touches.  The jackknife covariance (Efron and Stein 1981; MacKinnon and White 1985,
"HC3", and Bell and McCaffrey 2002, "CR3", for clusters) is

    C_jack = (G - 1) / G  sum_c (d_c - mean d)(d_c - mean d)^T

over the ``G`` clusters that touch a kept parameter.  It carries its own small-sample
(leverage) correction: a cluster's own pull on the estimate is removed before its spread is
measured, so it is not biased low with few clusters per parameter as the plain sandwich is.

Cost: per cluster one solve of the size of the columns it touches (an image: its camera's
pose and lens, the target's pose), batched over clusters of one shape; no Jacobian is kept
beyond each segment's Gram matrix, which the normal equations form anyway.

Synopsis
--------
>>> rec = ClusterRecord(layout)                          # doctest: +SKIP
>>> acc = Assembly(layout, families, clusters=rec)       # doctest: +SKIP
>>> ...; ne = acc.result()                               # doctest: +SKIP
>>> C_jack = jackknife_covariance(ne, rec, cov_kept)     # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["ClusterRecord", "jackknife_covariance"]

F64 = NDArray[np.float64]

#: Clusters solved at once (bounds the memory of the batched Woodbury solves).
_BATCH = 512


@dataclass
class ClusterRecord:
    """Each segment's share of the normal equations, kept for :func:`jackknife_covariance`.

    Filled by :class:`~multieye.optimize.normal_equations.Assembly` piece by piece: per piece
    (one residual group's segments) the cluster of every segment (its eliminated block, or
    ``n_local + `` a running number when it touches none), its kept columns (S, c) and its
    Gram blocks ``G_kk`` (S, c, c), ``G_kl`` (S, c, d) and score ``g_k`` (S, c).  Pieces
    whose segments touch no kept parameter are not kept (their rows are in ``V`` and
    ``g_local`` already).
    """

    n_local: int
    pieces: list = field(default_factory=list)
    _own: int = 0

    def add(self, lblock, cols, Gkk, Gkl, gk) -> None:
        """One piece: ``lblock`` (S,) eliminated block of each segment or None."""
        S = len(cols)
        if cols.shape[1] == 0 or S == 0:
            return
        if lblock is None:
            cluster = self.n_local + self._own + np.arange(S)
            self._own += S
        else:
            cluster = np.asarray(lblock, dtype=np.int64)
        self.pieces.append((cluster, cols, Gkk, Gkl, gk))


def _clusters(rec: ClusterRecord):
    """Per cluster, the (piece, segment) pairs that touch kept columns, grouped by the
    sequence of pieces' widths (clusters of one shape are solved together)."""
    parts: dict[int, list[tuple[int, int]]] = {}
    for p, (cluster, *_rest) in enumerate(rec.pieces):
        for s, c in enumerate(cluster.tolist()):
            parts.setdefault(c, []).append((p, s))
    shapes: dict[tuple, list[int]] = {}
    for c, segs in parts.items():
        key = tuple(rec.pieces[p][1].shape[1] for p, _ in segs)
        shapes.setdefault(key, []).append(c)
    return parts, shapes


def _stack(rec: ClusterRecord, parts, batch: list[int], widths: tuple, d: int):
    """The clusters of ``batch`` side by side: columns E (n, T), block-diagonal Gram
    ``s`` (n, T, T), kept-local coupling ``w`` (n, T, d) and score ``gamma`` (n, T); a
    column repeats when two segments of a cluster touch it (their blocks add through E)."""
    n, T = len(batch), sum(widths)
    E = np.empty((n, T), dtype=np.int64)
    s = np.zeros((n, T, T))
    w = np.zeros((n, T, max(d, 1)))
    gamma = np.empty((n, T))
    at = 0
    for k, width in enumerate(widths):
        sl = slice(at, at + width)
        for i, c in enumerate(batch):
            p, seg = parts[c][k]
            _, cols, Gkk, Gkl, gk = rec.pieces[p]
            E[i, sl] = cols[seg]
            s[i, sl, sl] = Gkk[seg]
            gamma[i, sl] = gk[seg]
            if Gkl is not None:
                w[i, sl, :d] = Gkl[seg]
        at += width
    return E, s, w[:, :, :d], gamma


def jackknife_covariance(ne, rec: ClusterRecord, cov: F64) -> tuple[F64, int]:
    """Delete-one-cluster jackknife covariance of the kept parameters (module docstring).

    Parameters
    ----------
    ne : NormalEquations
        At the optimum, with ``V`` and ``g_local`` of every eliminated block.
    rec : ClusterRecord
        Filled while ``ne`` was assembled.
    cov : ndarray, shape (k, k)
        ``S^-1``, the model-based covariance of the kept parameters (from ``ne``).

    Returns
    -------
    C_jack : ndarray, shape (k, k)
    clusters : int
        ``G``, the clusters that touch a kept parameter.
    """
    k = len(cov)
    d = ne.V.shape[1] if ne.V.size else 0
    parts, shapes = _clusters(rec)
    total, outer, G = np.zeros(k), np.zeros((k, k)), 0
    for widths, members in shapes.items():
        for lo in range(0, len(members), _BATCH):
            batch = members[lo:lo + _BATCH]
            E, s, w, gamma = _stack(rec, parts, batch, widths, d)
            local = np.array([c < rec.n_local for c in batch])
            if d and local.any():
                blk = np.array(batch)[local]
                Vi = np.linalg.inv(ne.V[blk])                                   # (n, d, d)
                wV = w[local] @ Vi
                s[local] -= wV @ np.swapaxes(w[local], 1, 2)
                gamma[local] -= (wV @ ne.g_local[blk][:, :, None])[:, :, 0]
            C_EE = cov[E[:, :, None], E[:, None, :]]                            # (n, T, T)
            eye = np.eye(E.shape[1])
            u = np.linalg.solve(eye - C_EE @ s, (C_EE @ gamma[:, :, None]))[:, :, 0]
            v = gamma + (s @ u[:, :, None])[:, :, 0]                            # (n, T)
            delta = np.einsum("knt,nt->nk", cov[:, E], v)                       # (n, k)
            total += delta.sum(axis=0)
            outer += delta.T @ delta
            G += len(batch)
    if G < 2:
        return np.zeros((k, k)), G
    mean = total / G
    C = (G - 1) / G * (outer - G * np.outer(mean, mean))
    return 0.5 * (C + C.T), G
