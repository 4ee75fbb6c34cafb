"""Pairing images with motion capture: nearest within tolerance, SLERP between brackets."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.estimate.pairing import interpolate_poses, pair_in_time


def _trajectory(rate=100.0, duration=2.0):
    """Constant-velocity motion: rotation 0.5 rad/s about a fixed axis, 0.2 m/s along x."""
    t = np.arange(0.0, duration, 1.0 / rate)
    axis = np.array([0.2, 0.5, 0.84]) / np.linalg.norm([0.2, 0.5, 0.84])
    T = g.transform_from_rotvec(np.outer(0.5 * t, axis), np.outer(t, [0.2, 0.0, 0.0]))
    return t, T, axis


def _truth(tq, axis):
    return g.transform_from_rotvec(np.outer(0.5 * tq, axis), np.outer(tq, [0.2, 0.0, 0.0]))


def test_interpolation_is_exact_for_constant_velocity():
    t, T, axis = _trajectory()
    tq = np.array([0.0031, 0.5, 1.23456, 1.9849])
    p = pair_in_time(t, T, tq, tolerance=0.01)
    np.testing.assert_array_equal(p.index, [0, 1, 2, 3])
    np.testing.assert_allclose(p.T, _truth(tq, axis), atol=1e-12)
    assert p.interpolated.tolist() == [True, False, True, True]   # 0.5 is a sample
    assert p.unpaired == ()


def test_offset_shifts_the_query_into_the_mocap_clock():
    t, T, axis = _trajectory()
    tq = np.array([0.3, 0.9])
    p = pair_in_time(t, T, tq - 0.04, tolerance=0.01, offset=0.04)
    np.testing.assert_allclose(p.T, _truth(tq, axis), atol=1e-12)


def test_outside_and_gaps_are_reported():
    t, T, _ = _trajectory()
    t2 = np.concatenate([t[:50], t[150:]])          # 1 s dropout from 0.5 s to 1.5 s
    T2 = np.concatenate([T[:50], T[150:]])
    p = pair_in_time(t2, T2, np.array([-0.5, 0.495, 1.0, 1.505, 3.0]), tolerance=0.02)
    assert p.index.tolist() == [1, 3]
    reasons = dict(p.unpaired)
    assert "before the motion-capture recording" in reasons[0]
    assert reasons[2] == "nearest motion-capture sample is 0.500 s away"
    assert "after" in reasons[4]
    # next to the dropout the nearest sample is used, never an interpolation across it
    assert p.interpolated.tolist() == [False, True]     # 0.495: only 0.49 is near; 1.505: 1.50..1.51
    assert p.gap_s.max() <= 0.02


def test_no_interpolation_across_a_dropout():
    t = np.array([0.0, 0.01, 0.02, 1.0, 1.01])
    T = g.transform_from_rotvec(np.zeros((5, 3)), np.outer(t, [1.0, 0, 0]))
    T[3:, 0, 3] += 10.0                                 # something different after the gap
    p = pair_in_time(t, T, np.array([0.025]), tolerance=0.01)
    assert not p.interpolated[0]
    np.testing.assert_allclose(p.T[0], T[2])


def test_bad_arguments():
    t, T, _ = _trajectory()
    with pytest.raises(InputError, match="positive"):
        pair_in_time(t, T, [0.1], tolerance=0.0)
    with pytest.raises(InputError, match="strictly increasing"):
        pair_in_time(t[::-1], T, [0.1], tolerance=0.01)


@settings(max_examples=50, deadline=None)
@given(st.floats(0.0, 1.0))
def test_slerp_endpoints_and_midpoint_symmetry(alpha):
    rng = np.random.default_rng(0)
    T0 = g.random_transforms(rng, 3)
    T1 = T0 @ g.transform_from_rotvec(rng.normal(scale=0.5, size=(3, 3)), rng.normal(size=(3, 3)))
    Ta = interpolate_poses(T0, T1, np.full(3, alpha))
    Tb = interpolate_poses(T1, T0, np.full(3, 1.0 - alpha))
    np.testing.assert_allclose(Ta, Tb, atol=1e-9)
    np.testing.assert_allclose(interpolate_poses(T0, T1, np.zeros(3)), T0, atol=1e-12)
    np.testing.assert_allclose(interpolate_poses(T0, T1, np.ones(3)), T1, atol=1e-9)


_T = g.transform_from_rotvec(np.zeros((5, 3)), np.zeros((5, 3)))


@pytest.mark.parametrize("args, kw, message", [
    ((None, _T, [1.0]), {}, "motion-capture stamps is None; expected a real array of shape (N,)"),
    ((np.arange(5.0), None, [1.0]), {}, "motion-capture poses T is None; expected one 4x4 pose "
                                        "per stamp, shape (5, 4, 4)"),
    ((np.arange(5.0), _T, None), {}, "image stamps (query) is None"),
    ((np.arange(5.0) + 0j, _T, [1.0]), {}, "motion-capture stamps must be real, got complex"),
    ((np.arange(5.0), _T[:, :3], [1.0]), {}, "must be one 4x4 pose per stamp, shape (5, 4, 4), "
                                             "got shape (5, 3, 4)"),
    ((np.arange(4.0), _T, [1.0]), {}, "got shape (5, 4, 4)"),
    ((np.arange(5.0), _T, [[1.0]]), {}, "image stamps (query) must be a real array of shape (N,)"),
    ((np.arange(5.0), _T, ["soon"]), {}, "image stamps (query) must be a real array"),
    ((np.arange(5.0), _T, [np.nan]), {}, "image stamps must be finite"),
    ((np.arange(5.0), _T * np.nan, [1.0]), {}, "motion-capture poses must be finite"),
    ((np.arange(5.0), _T, [1.0]), {"tolerance": None}, "time tolerance must be a positive number, "
                                                       "got None"),
    ((np.arange(5.0), _T, [1.0]), {"tolerance": float("nan")}, "time tolerance must be a "
                                                               "positive number, got nan"),
    ((np.arange(5.0), _T, [1.0]), {"tolerance": "0.1"}, "time tolerance must be a positive "
                                                        "number, got '0.1'"),
    ((np.arange(5.0), _T, [1.0]), {"offset": None}, "time offset must be a number, got None"),
    ((np.arange(5.0), _T, [1.0]), {"offset": 1e300}, "time offset must be within 1e+10 s"),
    ((np.arange(5.0)[::-1], _T, [1.0]), {}, "strictly increasing"),
])
def test_bad_arguments_are_input_errors_saying_what_was_expected(args, kw, message):
    kw = {"tolerance": 0.1, **kw}
    with pytest.raises(InputError) as info:
        pair_in_time(*args, **kw)
    assert message in str(info.value)


def test_unpaired_images_a_power_of_1000_apart_say_the_clocks_units_may_differ():
    """Images stamped in seconds against motion capture in microseconds read as nanoseconds
    (16 digits): each unpaired image says the stamps are 1000 times apart (before: only the
    recording's span and the distance)."""
    stamps = 1_700_000.0 + 0.01 * np.arange(5)          # 1.7e15 us read as ns: 1.7e6 s
    T = np.repeat(np.eye(4)[None], 5, axis=0)
    res = pair_in_time(stamps, T, [1_700_000_000.0], tolerance=0.03)
    assert "about 1000 times the others" in res.unpaired[0][1]
    res = pair_in_time(stamps, T, [1_700_010.0], tolerance=0.03)      # just after: no hint
    assert "times the others" not in res.unpaired[0][1]


def test_a_motion_capture_timed_from_its_take_against_dated_images_says_so():
    """Motion capture whose times start at 0 (an OptiTrack or Vicon export: time since the take
    started) against images named by dates: each unpaired image says so and gives the
    time_offset that would put the first image at the first sample (before: only the span and
    a distance of 1.7e9 s); and the reverse; no hint where both are dates."""
    T = np.repeat(np.eye(4)[None], 5, axis=0)
    take = 0.01 * np.arange(5)
    res = pair_in_time(take, T, [1_700_000_000.5, 1_700_000_001.0], tolerance=0.03)
    why = res.unpaired[0][1]
    assert "the motion capture's times start at 0.000 s (time since its take started" in why
    assert "time_offset (seconds added to its image stamps: -1700000000.500 if" in why
    res = pair_in_time(1_700_000_000.0 + take, T, [3.5], tolerance=0.03)
    assert "the image stamps are times since a start" in res.unpaired[0][1]
    res = pair_in_time(1_700_000_000.0 + take, T, [1_700_000_100.0], tolerance=0.03)
    assert "time_offset" not in res.unpaired[0][1]
