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
