"""Central differences of a residual group on its blocks' manifolds (Ceres' GradientChecker).

Every analytic Jacobian handed to the engine is tested against this in the suite.

Synopsis
--------
>>> numeric = numerical_jacobians(families, group)                # doctest: +SKIP
>>> analytic = group.evaluate({f.name: f.value for f in families}, True)[1]   # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from multieye.optimize.blocks import Blocks, ResidualGroup

__all__ = ["numerical_jacobians"]

F64 = NDArray[np.float64]


def numerical_jacobians(families: Sequence[Blocks], group: ResidualGroup, *,
                        step: float = 1e-6) -> list[F64]:
    """Central-difference Jacobians of ``group`` in the layout of its analytic ones.

    Each block touched by a row is perturbed on its own manifold
    (:meth:`~multieye.optimize.blocks.Blocks.retract`) by ``+-step`` along each parameter.
    All blocks of a family move together, which is exact as long as no group touches one
    family through two slots (each row then sees only its own block move).

    Returns
    -------
    list of ndarray, shape (n_rows, dim, size of slot k)
    """
    fams = {f.name: f for f in families}
    values = {n: f.value for n, f in fams.items()}
    out = []
    for name in group.slots:
        f = fams[name]
        J = np.zeros((group.n_rows, group.dim, f.size))
        for a in range(f.size):
            diff = []
            for sign in (1.0, -1.0):
                delta = np.zeros((f.count, f.size))
                delta[:, a] = sign * step
                moved = dict(values)
                moved[name] = f.retract(delta).value
                diff.append(group.evaluate(moved, False)[0])
            # every block moved at once: a row sees only the blocks it touches
            J[:, :, a] = (diff[0] - diff[1]) / (2 * step)
        out.append(J)
    return out
