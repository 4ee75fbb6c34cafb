"""Images of different cameras at one instant (issue 23): by stamp within sync_tolerance, or by
name."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core.errors import InputError
from multieye.estimate.instants import (
    MAX_DEFAULT_SYNC_S,
    default_sync_tolerance,
    instants_from_names,
    instants_from_stamps,
)


def test_stamps_within_the_tolerance_are_one_instant_one_image_per_camera():
    a = np.array([10.000, 10.250, 10.500, 10.504])
    b = np.array([10.002, 10.249, 10.9])
    c = np.array([10.0045, 10.7])
    inst, k = instants_from_stamps([a, b, c], 0.005)
    assert inst[0].tolist() == [0, 1, 2, 3]          # 10.504: camera a is already in instant 2
    assert inst[1].tolist() == [0, 1, 5]
    assert inst[2].tolist() == [0, 4]
    assert k == 6
    inst, k = instants_from_stamps([a, b, c], 0.0)
    assert k == a.size + b.size + c.size


def test_default_tolerance_is_a_quarter_of_the_shortest_frame_interval():
    assert default_sync_tolerance([np.array([0.0, 0.02, 0.1]), np.array([0.0])]) == 0.005
    assert default_sync_tolerance([np.array([0.0, 1.0])]) == MAX_DEFAULT_SYNC_S
    assert default_sync_tolerance([np.array([3.0])]) == MAX_DEFAULT_SYNC_S


def test_equal_names_are_one_instant():
    inst, k = instants_from_names([["f2", "f1"], ["f1", "f3"]])
    assert [i.tolist() for i in inst] == [[1, 0], [0, 2]] and k == 3
    with pytest.raises(InputError, match="two images named 'f1'"):
        instants_from_names([["f1", "f1"]])


def test_bad_stamps_and_tolerances_are_refused():
    with pytest.raises(InputError, match="sync_tolerance"):
        instants_from_stamps([np.zeros(1)], -1.0)
    with pytest.raises(InputError, match="finite"):
        instants_from_stamps([np.array([np.nan])], 0.01)
    with pytest.raises(InputError, match="no cameras"):
        instants_from_stamps([], 0.01)
