"""Issue 33, item 3, for the pinhole models: a lens estimated with ``model: pinhole-radtan``
was never compared (a 150-degree unified lens fitted 7 px off at its edge without a word;
compare_models with a pinhole model raised IndexError); now a pinhole lens whose residuals
grow towards the edge is compared with the rational and the wide models and the clearly
better one named with its figures, while a lens the model fits is not compared at all (the
pinhole path stays as fast)."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core.intrinsics import Intrinsics
from multieye.imaging import model_choice
from multieye.imaging.model_choice import compare_models, edge_rms, may_be_beaten
from multieye.pipeline.estimated_lens import model_warnings
from multieye.sim.wide_lens import IMAGE_SIDE, board_views, wide_lens

SIZE = (IMAGE_SIDE, IMAGE_SIDE)
_C = (IMAGE_SIDE - 1) / 2


def _pinhole(dist, f: float = 500.0) -> Intrinsics:
    return Intrinsics(K=np.array([[f, 0, _C], [0, f, _C], [0, 0, 1.0]]),
                      dist=np.asarray(dist, float), width=IMAGE_SIDE, height=IMAGE_SIDE)


def test_a_wide_lens_given_a_pinhole_model_is_told_which_fits():
    views, _ = board_views(wide_lens("unified", 150.0), 150.0, 12, np.random.default_rng(0))
    (text,) = model_warnings("wide", "pinhole-radtan", views, SIZE)
    assert text.startswith("wide: the pinhole-radtan lens leaves "), text
    assert "held-out reprojection RMS beyond" in text and "4-fold cross-validation" in text
    better = text.rsplit("consider model: ", 1)[1]
    assert better in ("fisheye", "unified", "double-sphere", "eucm"), text
    cmp = compare_models(views, SIZE, "pinhole-radtan")
    mine, other = cmp.scores["pinhole-radtan"], cmp.scores[cmp.better]
    assert mine.outer_rms_px > 2.0 and other.outer_rms_px < 0.4     # 0.2 px noise per axis


def test_a_rational_lens_given_radial_tangential_is_told_rational():
    lens = _pinhole([0.458331, -2.87024, 0.00048617, -9.82262e-05, 1.74446, 0.331466,
                     -2.66947, 1.65473], f=300.0)
    views, _ = board_views(lens, 110.0, 20, np.random.default_rng(0))
    (text,) = model_warnings("cam", "pinhole-radtan", views, SIZE)
    assert text.endswith("consider model: pinhole-rational"), text


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("dist", [[-0.05, 0.0, 0.0, 0.0], [-0.25, 0.06, 0.001, 0.0]])
def test_a_pinhole_lens_the_model_fits_is_not_compared(monkeypatch, seed, dist):
    """No false alarm, and no comparison run: its residuals do not grow towards the edge."""
    def refuse(*a, **k):
        raise AssertionError("compared")

    monkeypatch.setattr("multieye.pipeline.estimated_lens.compare_models", refuse)
    views, _ = board_views(_pinhole(dist), 90.0, 12, np.random.default_rng(seed))
    assert model_warnings("cam", "pinhole-radtan", views, SIZE) == ()


def test_the_edge_bound_follows_the_noise():
    """The outer residuals must be 1 / CLEARLY times the inner ones and EDGE_BOUND_PX: a
    noisy lens that fits (0.3 px everywhere) cannot be clearly beaten."""
    assert not may_be_beaten(0.3, 0.28)
    assert not may_be_beaten(0.15, 0.05)
    assert may_be_beaten(1.0, 0.3)
    lens = _pinhole([-0.2, 0.0, 0.0, 0.0])
    views, T = board_views(lens, 90.0, 8, np.random.default_rng(1), noise_px=0.0)
    outer, inner = edge_rms(views, lens, T, SIZE)
    assert outer < 1e-9 and inner < 1e-9
    assert model_choice.EDGE_BOUND_PX == pytest.approx(0.2)
