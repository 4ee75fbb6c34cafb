"""rig.yaml's ``crop:`` as users type it wrong: each refusal one line at the key's line that
says what is expected (whole pixels), never a bound the value does not break."""

from __future__ import annotations

import pytest

from multieye.core.errors import DatasetError
from multieye.io import load_rig


@pytest.mark.parametrize("crop", ["[0.0, 0, 640, 480]", "[0.5, 0, 640, 480]",
                                  "['0', 0, 640, 480]", "[true, 0, 640, 480]",
                                  "[0, 0, 640.0, 480]", "[0, 0, .nan, 480]"])
def test_a_crop_that_is_not_whole_pixels_says_so(tmp_path, crop):
    """Before, ``[0.0, 0, 640, 480]`` gave ``expected a integer between -100000 and 100000,
    got 0.0``: a bound 0.0 is within, and a grammar slip."""
    (tmp_path / "sbs").mkdir()
    (tmp_path / "rig.yaml").write_text(
        "target: {type: chessboard, rows: 6, cols: 4, spacing: 0.03}\ncameras:\n"
        f"  left: {{model: pinhole-radtan4, images: sbs/, crop: {crop}}}\n")
    with pytest.raises(DatasetError) as info:
        load_rig(tmp_path)
    message = str(info.value)
    assert "rig.yaml:3: cameras.left.crop: expected [x, y, width, height] in whole pixels" in \
        message, message
    assert "between" not in message


def test_an_integer_key_out_of_bounds_reads_an_integer(tmp_path):
    (tmp_path / "sbs").mkdir()
    (tmp_path / "rig.yaml").write_text(
        "target: {type: chessboard, rows: 6, cols: 4, spacing: 0.03}\ncameras:\n"
        "  left: {model: pinhole-radtan4, images: sbs/, crop: [0, 0, 1000000, 480]}\n")
    with pytest.raises(DatasetError, match="expected an integer between -100000 and 100000"):
        load_rig(tmp_path)
