"""The report's PNG writer: the pixels matplotlib's own ``savefig`` writes, decoded by
Pillow, RGB for an opaque figure and RGBA otherwise, and a smaller file than savefig's."""

from __future__ import annotations

from io import BytesIO

import numpy as np
import pytest

from multieye.outputs.figures import _png, png_bytes

PIL = pytest.importorskip("PIL.Image")
matplotlib = pytest.importorskip("matplotlib")


def _decoded(data: bytes) -> tuple[str, np.ndarray]:
    image = PIL.open(BytesIO(data))
    return image.mode, np.asarray(image.convert("RGBA"))


def _figure():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.0, 2.5), dpi=90)
    ax = fig.add_subplot()
    x = np.linspace(0, 6, 200)
    ax.plot(x, np.sin(x), lw=1.2, label="sin")
    ax.scatter(x[::10], np.cos(x[::10]), s=8, c=x[::10], cmap="viridis")
    ax.set_title("a title, 0.123 mm", fontsize=9, loc="left")
    ax.legend(fontsize=7)
    return fig


def test_the_pixels_savefig_writes_in_a_smaller_file():
    fig = _figure()
    ours = _png(fig)
    buffer = BytesIO()
    from matplotlib import rc_context

    from multieye.outputs.figures import _RC

    with rc_context(_RC):
        fig.savefig(buffer, format="png")
    mode, pixels = _decoded(ours)
    _, theirs = _decoded(buffer.getvalue())
    assert mode == "RGB"                      # an opaque figure: no alpha channel stored
    assert pixels.shape == theirs.shape == (225, 360, 4)
    assert np.array_equal(pixels, theirs)
    assert len(np.unique(pixels.reshape(-1, 4), axis=0)) > 50   # drawn, antialiased
    assert len(ours) < len(buffer.getvalue())
    assert _png(fig) == ours                  # the same bytes drawn again


def test_any_image_round_trips():
    rng = np.random.default_rng(0)
    rgba = rng.integers(0, 256, (17, 31, 4), dtype=np.uint8)
    mode, back = _decoded(png_bytes(rgba))
    assert mode == "RGBA" and np.array_equal(back, rgba)
    rgba[..., 3] = 255
    for level in (0, 1, 9):
        mode, back = _decoded(png_bytes(rgba, level))
        assert mode == "RGB" and np.array_equal(back, rgba)
