"""``multieye check``'s verdict where its budget (10 x --sample images per camera) stopped the
search with fewer than 3 images showing the target: 'calibrating may fail' (exit 0), also when
the few found extrapolate to enough. Before, 2 found among 20 searched of 302 images read as
"about 30 usable" and the verdict was 'ok, calibrating can run', while calibrate, which
searches them all, refused the camera (exit 2: only 2 images hold the board)."""

from __future__ import annotations

import pytest

from multieye.pipeline.dry_run_sample import shortfall


@pytest.mark.parametrize("found, expected", [(2, 30), (1, 15), (0, 0)])
def test_few_found_when_the_budget_stopped_the_search_is_undecided(found, expected):
    why, decided = shortfall(found, found, 20, expected, 302)
    assert not decided
    assert why == (f"fewer than 3 usable images among the 20 searched ({found} usable); 282 of "
                   "its 302 images were not searched (the check's budget): calibrating may "
                   "fail, and searches them all (--sample 31 searches them here)")


def test_enough_found_or_every_image_searched_decides():
    assert shortfall(3, 3, 20, 45, 302) is None                 # 3 found: the estimate holds
    why, decided = shortfall(2, 2, 302, 2, 302)                  # all searched: it would fail
    assert decided and why.startswith("fewer than 3 usable images would remain (2 of 302")
    why, decided = shortfall(0, 0, 20, 0, 302, decided=True)     # another board: the target
    assert decided                                               # section is wrong


def test_cameras_never_seeing_the_board_together_in_a_sample_may_fail(tmp_path):
    """Two cameras that see the board at different instants (cam0 in the first 4 of 8, cam1
    in the last 4): calibrate refuses them (nothing links them, exit 2). Searched whole,
    `check` says it would fail; on a sample (6 of 8 each) it said 'ok, calibrating can run'
    under a problem line saying so; now the verdict says that calibrating may fail."""
    from apart_views import render_apart
    from multieye.outputs.summary import check_table
    from multieye.pipeline.dry_run import check_dataset

    ds = render_apart(tmp_path / "ds")
    result = check_dataset(ds, sample=4, processes=1)
    assert all(c.sampled < c.listed for c in result.cameras)      # a sample, not all
    assert result.ok and len(result.doubts) == 2, result.doubts
    assert "cam0: the board is in 3 of its sampled images, but never at an instant when " \
           "another camera's image shows it" in result.doubts[0]
    assert check_table(result).splitlines()[-1].startswith(
        "verdict: calibrating may fail: cam0: the board is in 3 of its sampled images")
