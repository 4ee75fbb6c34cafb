"""Stereo rectification of overlapping pairs (issue 23, item 5): after rectification a point
projects to the same row in both cameras, and P holds the baseline."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.imaging.rectify import stereo_rectification


def _lens(model="pinhole"):
    dist = np.array([-0.2, 0.05, 1e-4, -2e-4, 0.0]) if model == "pinhole" else \
        np.array([0.05, -0.01, 0.002, -0.0005])
    return Intrinsics(K=[[520.0, 0, 322.0], [0, 518.0, 236.0], [0, 0, 1]], dist=dist,
                      model=model, width=640, height=480)


@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_rectified_rows_agree_and_p_holds_the_baseline(model):
    T_a_b = g.transform_from_rotvec([0.02, -0.05, 0.01], [0.15, 0.004, -0.01])
    lens = _lens(model)
    r = stereo_rectification(lens, lens, T_a_b)
    baseline = np.linalg.norm(T_a_b[:3, 3])
    assert abs(-r.P_b[0, 3] / r.P_b[0, 0] - baseline) < 1e-9
    rng = np.random.default_rng(0)
    p_a = np.column_stack([rng.uniform(-0.5, 0.5, (20, 2)), rng.uniform(1.5, 3, 20)])
    p_b = (p_a - T_a_b[:3, 3]) @ T_a_b[:3, :3]                # T_b_a p_a
    rows = []
    for R, P, p in ((r.R_a, r.P_a, p_a), (r.R_b, r.P_b, p_b)):
        q = p @ R.T
        uvw = np.column_stack([q, np.ones(len(q))]) @ P.T
        rows.append(uvw[:, 1] / uvw[:, 2])
    assert np.max(np.abs(rows[0] - rows[1])) < 1e-6
    for R in (r.R_a, r.R_b):
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-9)


def test_mixed_lenses_and_missing_sizes_are_refused():
    T = g.transform_from_rotvec([0, 0, 0], [0.1, 0, 0])
    with pytest.raises(InputError, match="pinhole lens paired with a fisheye"):
        stereo_rectification(_lens(), _lens("fisheye"), T)
    no_size = Intrinsics(K=_lens().K, dist=_lens().dist)
    with pytest.raises(InputError, match="image sizes"):
        stereo_rectification(no_size, _lens(), T)
    with pytest.raises(InputError, match="zero baseline"):
        stereo_rectification(_lens(), _lens(), np.eye(4))
