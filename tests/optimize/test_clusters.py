"""The cluster-robust covariance (multieye.optimize.clusters): on a linear problem the
delete-one-cluster jackknife formed from the normal equations' pieces equals the one of
refitting without each cluster, and on independent rows it agrees with ``(J^T J)^-1``."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.optimize.blocks import Blocks
from multieye.optimize.levenberg_marquardt import (Options, covariance_and_residuals,
                                                   minimize)

from linear_groups import Linear, _dense


def _problem(rng, n_local=40, shared=0.0, noise=None):
    """Two global vectors (2 each) and n_local eliminated ones (3 each); each local cluster
    has 6 rows of 2 touching both globals (a two-camera instant: two segments, one per
    global), plus a segment of rows touching the first global alone (its own cluster).
    ``shared``: each cluster's rows share one error of that size per component; ``noise``:
    the generator of the errors (default ``rng``: design and errors drawn together)."""
    noise = rng if noise is None else noise
    seg = []
    index, Ag, Al, b = [], [], [], []
    for c in range(n_local):
        for gi in (0, 1):
            index.append((gi, c))
            seg += [len(index) - 1] * 3
            Ag.append(rng.normal(size=(3, 2, 2)))
            Al.append(rng.normal(size=(3, 2, 3)))
            b.append(noise.normal(size=(3, 2)) + noise.normal(scale=shared, size=2))
    group = Linear(("G", "L"), np.array(index), np.array(seg), np.concatenate(Ag),
                   np.concatenate(Al), np.concatenate(b))
    alone = Linear(("G",), np.zeros((5, 1), int), np.repeat(np.arange(5), 2),
                   rng.normal(size=(10, 2, 2)), None, noise.normal(size=(10, 2)))
    fams = [Blocks("G", np.zeros((2, 2)), "euclidean"),
            Blocks("L", np.zeros((n_local, 3)), "euclidean", eliminate=True)]
    return fams, [group, alone]


def _clusters_of_rows(groups):
    """Cluster label of every dense row (as _dense stacks them)."""
    labels = []
    g0, g1 = groups
    for i in range(g0.n_rows):
        labels += [int(g0.index[g0.segment[i], 1])] * g0.dim
    for i in range(g1.n_rows):
        labels += [1000 + int(g1.segment[i])] * g1.dim
    return np.array(labels)


def test_jackknife_equals_refits_without_each_cluster(rng):
    fams, groups = _problem(rng)
    res = minimize(fams, groups, Options(loss="linear", tol=1e-15, max_iter=5))
    cov, _ = covariance_and_residuals(res.families, groups, jackknife=Options(loss="linear"))
    J, r = _dense(res.families, groups)
    labels = _clusters_of_rows(groups)
    x_hat = np.zeros(J.shape[1])
    deltas = []
    for c in np.unique(labels):
        keep = labels != c
        Jk = J[keep]
        cols = np.flatnonzero(np.any(Jk != 0, axis=0))     # the deleted local drops out
        dx = np.linalg.lstsq(Jk[:, cols], -r[keep], rcond=None)[0]
        deltas.append(dx[:4] - x_hat[:4])                  # the globals come first
    deltas = np.array(deltas)
    G = len(deltas)
    d = deltas - deltas.mean(axis=0)
    expected = (G - 1) / G * d.T @ d
    assert cov.clusters == G
    np.testing.assert_allclose(cov.jackknife, expected, rtol=1e-8, atol=1e-14)


def test_jackknife_follows_errors_shared_within_a_cluster():
    """One design, 150 draws of its errors: with independent rows the jackknife's trace and
    (J^T J)^-1's both match the spread of the estimates (within 20 %); with an error shared
    by each cluster's rows (1 per component, as large as a row's own) (J^T J)^-1 is too
    small by half, the jackknife is not."""
    for shared in (0.0, 1.0):
        est, jack, model = [], [], []
        for seed in range(150):
            fams, groups = _problem(np.random.default_rng(5), shared=shared,
                                    noise=np.random.default_rng([seed, 6]))
            res = minimize(fams, groups, Options(loss="linear", tol=1e-15, max_iter=5))
            cov, _ = covariance_and_residuals(res.families, groups,
                                              jackknife=Options(loss="linear"))
            est.append(res.families[0].value.ravel())
            jack.append(np.trace(cov.jackknife))
            model.append(np.trace(cov.kept))
        spread = np.trace(np.cov(np.array(est).T))
        assert 0.8 < np.mean(jack) / spread < 1.25, (shared, np.mean(jack) / spread)
        if shared:
            assert np.mean(model) / spread < 0.5, np.mean(model) / spread
        else:
            assert 0.8 < np.mean(model) / spread < 1.25, np.mean(model) / spread


def test_gaussian_slope_is_the_share_of_huber_residuals_inside_its_threshold():
    """E[psi'] of Huber's loss at 2 sigma is P(|z| < 2) for standard normal z (psi' = 1
    inside, 0 outside): the jackknife's bread is this times J^T J."""
    from scipy.special import erf

    from multieye.core.robust_loss import gaussian_slope
    assert gaussian_slope("huber", 2.0) == pytest.approx(erf(2.0 / np.sqrt(2.0)), abs=1e-4)
    assert gaussian_slope("linear", 2.0) == 1.0
