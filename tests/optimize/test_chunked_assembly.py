"""The normal equations summed chunk by chunk (optimize.normal_equations.Assembly,
ResidualGroup.linearize_chunks): the same system as from the whole Jacobian, and a
refinement whose memory holds one chunk's Jacobian, not every image's."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import multieye
from multieye.estimate.image_data import ImageProblem, image_data
from multieye.estimate.refine_images import refine_images
from multieye.optimize import levenberg_marquardt as lm
from multieye.optimize.blocks import ResidualGroup, SegmentRange
from multieye.optimize.normal_equations import Layout, assemble
from multieye.sim.images import simulate_images


@pytest.mark.parametrize("chunk", [1, 7, 1000])
def test_chunks_give_the_normal_equations_of_the_whole_jacobian(chunk, monkeypatch):
    sc = simulate_images(1, n_cameras=3, images=[40, 25, 33])
    data = image_data(ImageProblem(sc.setup, sc.observations, sc.intrinsics))
    fams = data.families(sc.X, sc.Y, data.mocap_measured)
    groups = data.groups(0.3, 1e-3, 3e-4)
    layout = Layout.of(fams)
    whole = assemble(layout, {f.name: f for f in fams}, groups, lm.evaluate(fams, groups, True))
    monkeypatch.setattr(lm, "CHUNK_SEGMENTS", chunk)
    pieces = lm.normal_equations(fams, groups, layout)
    for a, b in ((pieces.U, whole.U), (pieces.V, whole.V), (pieces.g, whole.g),
                 (pieces.g_local, whole.g_local), (pieces.W.toarray(), whole.W.toarray())):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())


def _peak_bytes(sc, sol) -> int:
    tracemalloc.start()
    try:
        refine_images(sc.setup, sc.observations, sc.intrinsics, sol.X, sol.Y, pixel_sigma=0.3,
                      mocap_rot_sigma_rad=sc.mocap_rot_sigma_rad,
                      mocap_trans_sigma_m=sc.mocap_trans_sigma_m, max_iter=3)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_refinement_memory_does_not_hold_every_jacobian(monkeypatch):
    """2 cameras x 1500 images: the peak of the refinement with 256-image chunks is well
    under that with the whole Jacobian at once (one chunk per camera)."""
    sc = simulate_images(2, n_cameras=2, images=1500)
    sol = multieye.solve(sc.A, sc.B)
    chunked = _peak_bytes(sc, sol)
    monkeypatch.setattr(lm, "CHUNK_SEGMENTS", 10**9)
    whole = _peak_bytes(sc, sol)
    print(f"peak {chunked / 2**20:.0f} MB chunked, {whole / 2**20:.0f} MB whole")
    assert chunked < 0.5 * whole, (chunked / 2**20, whole / 2**20)


class _Rows(ResidualGroup):
    """Rows only (the layout of the segments); never evaluated."""

    def evaluate(self, values, jacobians):
        raise NotImplementedError


@pytest.mark.parametrize("counts", [[3, 3, 3, 3], [3, 1, 3, 2]])
def test_segment_ranges_pad_and_gather_their_rows(counts, rng):
    """A range whose segments are all full is padded by a reshape (no zeros to add); any
    range's padding puts each row at (its segment, its position) and gather takes it back."""
    segment = np.repeat(np.arange(len(counts)), counts)
    group = _Rows(("X",), np.zeros((len(counts), 1), int), segment, 2)
    rows = rng.normal(size=(segment.size, 2, 5))
    for lo, hi in ((0, len(counts)), (1, 3), (2, 3)):
        part = SegmentRange(group, lo, hi)
        mine = rows[part.rows]
        padded = part.pad(mine).reshape(hi - lo, group.longest, 2, 5)
        expected = np.zeros_like(padded)
        for r, (s, p) in enumerate(zip(part.segment, part.position)):
            expected[s, p] = mine[r]
        np.testing.assert_array_equal(padded, expected)
        assert part.full == all(counts[s] == group.longest for s in range(lo, hi))
        np.testing.assert_array_equal(part.gather(padded), mine)


@pytest.mark.parametrize("chunk", [7, 1000])
def test_covariance_and_residuals_from_one_linearisation(chunk, monkeypatch):
    """covariance_and_residuals: covariance() and evaluate() at once, the residuals joined
    from the chunks they were linearised in."""
    sc = simulate_images(2, n_cameras=2, images=[20, 13])
    data = image_data(ImageProblem(sc.setup, sc.observations, sc.intrinsics))
    fams = data.families(sc.X, sc.Y, data.mocap_measured)
    groups = data.groups(0.3, 1e-3, 3e-4)
    monkeypatch.setattr(lm, "CHUNK_SEGMENTS", chunk)
    cov, ev = lm.covariance_and_residuals(fams, groups, local=True)
    ref = lm.covariance(fams, groups, local=True)
    np.testing.assert_allclose(cov.kept, ref.kept, rtol=1e-12)
    np.testing.assert_allclose(cov.local, ref.local, rtol=1e-12)
    for (r, none), (r_ref, _) in zip(ev, lm.evaluate(fams, groups, jacobians=False)):
        assert none is None and r.shape == r_ref.shape
        np.testing.assert_allclose(r, r_ref, rtol=1e-12, atol=1e-12)
