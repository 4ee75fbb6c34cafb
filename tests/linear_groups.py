"""Test helpers for the optimisation engine: a linear residual group (optionally with a cubic
term) and the dense stacked Jacobian of a problem, shared by tests/optimize's modules."""

from __future__ import annotations

import numpy as np

from multieye.optimize.blocks import ResidualGroup

__all__ = ["Linear", "_dense"]


class Linear(ResidualGroup):
    """Rows ``r = (A_g x_g + A_l x_l - b)`` over slots (global family, local family)."""

    def __init__(self, slots, index, segment, Ag, Al, b, nonlinear=0.0):
        super().__init__(slots, index, segment, b.shape[1])
        self.Ag, self.Al, self.b, self.nonlinear = Ag, Al, b, nonlinear

    def evaluate(self, values, jacobians):
        xg = values[self.slots[0]][self.index[self.segment, 0]]           # (n, sg)
        parts = [np.einsum("nij,nj->ni", self.Ag, xg)]
        if self.Al is not None:
            xl = values[self.slots[1]][self.index[self.segment, 1]]
            parts.append(np.einsum("nij,nj->ni", self.Al, xl))
        lin = sum(parts)
        r = lin + self.nonlinear * lin ** 3 - self.b
        if not jacobians:
            return r, None
        scale = (1 + 3 * self.nonlinear * lin ** 2)[:, :, None]
        jac = [scale * self.Ag] + ([scale * self.Al] if self.Al is not None else [])
        return r, jac


def _dense(fams, groups):
    """The stacked Jacobian (rows x all parameters) and residuals at zero."""
    sizes = {f.name: f.size for f in fams}
    offsets, at = {}, 0
    for f in fams:
        offsets[f.name] = at
        at += f.count * f.size
    rows, r_all = [], []
    values = {f.name: f.value for f in fams}
    for grp in groups:
        r, jac = grp.evaluate(values, True)
        J = np.zeros((grp.n_rows, grp.dim, at))
        for s, name in enumerate(grp.slots):
            blk = grp.index[grp.segment, s]
            for i in range(grp.n_rows):
                o = offsets[name] + blk[i] * sizes[name]
                J[i, :, o:o + sizes[name]] = jac[s][i]
        rows.append(J.reshape(-1, at))
        r_all.append(r.ravel())
    return np.concatenate(rows), np.concatenate(r_all)
