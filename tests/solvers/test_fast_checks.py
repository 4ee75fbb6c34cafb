"""The fast paths of the input checks and of the per-camera sums agree with their definitions.

``_surely_rigid`` is a cheap sufficient test run before the exact one (``_first_bad``); it
may send good input to the exact test, never let bad input through.  ``camera_stats`` forms
every sum from one matrix product per camera; here each is checked against a plain loop.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from synthetic import eye_to_base

import multieye
from multieye.core import geometry as g
from multieye.solvers import checks, solve
from multieye.solvers.checks import (_first_bad, _surely_rigid, check_measurements,
                                     check_transforms)
from multieye.solvers.kronecker import (camera_stats, normalize_rotation, solve_translations,
                                        transform_entries)


def _rigid(rng, n):
    return g.random_transforms(rng, n)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), log_eps=st.floats(-12.0, -2.0),
       bottom=st.sampled_from([0.0, 1e-12, 1e-7, 1e-3]), n=st.integers(1, 40))
def test_fast_rigidity_test_never_accepts_what_the_definition_refuses(seed, log_eps, bottom, n):
    rng = np.random.default_rng(seed)
    T = _rigid(rng, n)
    k = rng.integers(n)
    T[k, :3, :3] += 10.0 ** log_eps * rng.normal(size=(3, 3))    # one perturbed rotation
    T[rng.integers(n), 3, rng.integers(4)] += bottom
    if _surely_rigid(transform_entries(T)):
        assert _first_bad(T) is None


def test_fast_rigidity_test_accepts_rigid_transforms_and_rounding():
    rng = np.random.default_rng(0)
    T = _rigid(rng, 1000)
    assert _surely_rigid(transform_entries(T))
    T32 = T.astype(np.float32).astype(np.float64)        # 1e-7 per entry: the exact test decides
    assert _first_bad(T32) is None
    check_transforms(T32)


@pytest.mark.parametrize("bad", ["zero", "reflection", "scaled", "nan", "inf"])
def test_one_bad_rotation_among_many_is_caught_and_named(bad):
    """A zero block has a zero cofactor matrix too; only the determinant sum exposes it."""
    rng = np.random.default_rng(1)
    n = 2 * checks._RIGID_CHUNK + 5                    # the bad one sits in the last chunk
    T = _rigid(rng, n)
    i = n - 3
    if bad == "zero":
        T[i, :3, :3] = 0.0
    elif bad == "reflection":
        T[i, :3, :3] = -T[i, :3, :3]
    elif bad == "scaled":
        T[i, :3, :3] *= 1.0 + 1e-4
    elif bad == "nan":
        T[i, 1, 3] = np.nan
    else:
        T[i, 0, 0] = np.inf
    assert not _surely_rigid(transform_entries(T))
    with pytest.raises(multieye.InputError, match=rf"T\[{i}\]"):
        check_transforms(T, "T")


@pytest.mark.parametrize("other_exact", [True, False])
def test_huge_translations_are_refused_by_name_whatever_the_other_transforms(other_exact):
    """Beyond MAX_TRANSLATION both the fast and the exact path refuse, naming the transform."""
    A, B, _, _ = eye_to_base(np.random.default_rng(2), [5, 5])
    A[1] = A[1].copy()
    A[1][2, 0, 3] = 1e120
    if not other_exact:                        # sends the check down the exact path
        A[0] = A[0].copy()
        A[0][0, 3, 3] = 1.0 + 1e-9
    with pytest.raises(multieye.InputError, match=r"A\[cam1\]\[2\].*1e\+120.*metres"):
        solve(A, B)
    A[1][2, 0, 3] = 1e99                       # absurd, but summable: accepted
    assert np.isfinite(solve(A, B).X).all()


@pytest.mark.parametrize("delta", [5.1e-6, 5.7e-6, 1e-5, 3e-5])
def test_fast_rigidity_test_refuses_just_beyond_the_tolerance(delta):
    """|R^T R - I| = 2 delta + delta^2 is just over 1e-5: the exact test refuses, so must the
    fast one, in any direction of the stretch."""
    rng = np.random.default_rng(8)
    T = _rigid(rng, 50)
    for _ in range(20):
        E = rng.normal(size=(3, 3))
        E = (E + E.T) / 2.0
        E *= delta / np.abs(E).max()
        bad = T.copy()
        bad[17, :3, :3] = bad[17, :3, :3] @ (np.eye(3) + E)
        if _first_bad(bad) is not None:
            assert not _surely_rigid(transform_entries(bad))
    bad = T.copy()
    bad[17, :3, :3] *= 1.0 + delta
    assert _first_bad(bad) is not None
    assert not _surely_rigid(transform_entries(bad))


def test_bottom_row_entries_too_small_to_square_are_still_made_exact():
    A, B, _, _ = eye_to_base(np.random.default_rng(9), [5, 5])
    A[0] = A[0].copy()
    A[0][2, 3, 0] = 1e-170
    meas = check_measurements(A, B, per_camera_motion=False)
    assert (meas.A[:, 3] == [0.0, 0.0, 0.0, 1.0]).all()


@pytest.mark.parametrize("where", [(1, 2), (2, 1), (0, 0), (2, 2)])
def test_inf_in_a_rotation_gives_the_input_error_even_with_warnings_as_errors(where):
    A, B, _, _ = eye_to_base(np.random.default_rng(10), [5, 5])
    B[1] = B[1].copy()
    B[1][3][where] = np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(multieye.InputError, match=r"B\[cam1\]\[3\].*NaN or inf"):
            solve(A, B)


def test_bottom_rows_within_tolerance_are_made_exact():
    A, B, _, _ = eye_to_base(np.random.default_rng(3), [6, 7])
    A_off = [a.copy() for a in A]
    A_off[0][:, 3, 3] = 1.0 + 1e-9
    A_off[1][:, 3, 0] = -1e-9
    meas = check_measurements(A_off, B, per_camera_motion=False)
    assert (meas.A[:, 3] == [0.0, 0.0, 0.0, 1.0]).all()
    exact = solve(A, B)
    off = solve(A_off, B)
    np.testing.assert_array_equal(off.X, exact.X)
    np.testing.assert_array_equal(off.Y, exact.Y)


def test_measurements_give_back_the_input():
    A, B, _, _ = eye_to_base(np.random.default_rng(4), [3, 8, 5])
    meas = check_measurements(A, B)
    np.testing.assert_array_equal(meas.A, np.concatenate(A))
    np.testing.assert_array_equal(meas.B, np.concatenate(B))
    np.testing.assert_array_equal(meas.RB, np.concatenate(B)[:, :3, :3])
    np.testing.assert_array_equal(meas.tA, np.concatenate(A)[:, :3, 3])
    np.testing.assert_array_equal(meas.starts, [0, 3, 11])
    unchecked = checks.Measurements.from_cameras(A, B)
    np.testing.assert_array_equal(unchecked.entries, meas.entries)
    np.testing.assert_array_equal(meas.camera, [0] * 3 + [1] * 8 + [2] * 5)
    assert [len(a) for a in meas.split(meas.A)] == [3, 8, 5]


@pytest.mark.parametrize("counts", [[7], [5, 5, 5, 5], [3, 9, 4]])   # one, batched, looped
def test_camera_stats_match_plain_sums(counts):
    rng = np.random.default_rng(5)
    A = [_rigid(rng, c) for c in counts]
    B = [_rigid(rng, c) for c in counts]
    stats = camera_stats(transform_entries(*A, *B), counts)
    for j, (Aj, Bj) in enumerate(zip(A, B)):
        RA, tA, RB, tB = Aj[:, :3, :3], Aj[:, :3, 3], Bj[:, :3, :3], Bj[:, :3, 3]
        np.testing.assert_allclose(stats.K[j], sum(np.kron(b, a) for a, b in zip(RA, RB)),
                                   atol=1e-12)
        np.testing.assert_allclose(
            stats.G[j], sum(np.kron(tb[None, :], a.T) for a, tb in zip(RA, tB)), atol=1e-12)
        np.testing.assert_allclose(stats.h[j], np.einsum("nsr,ns->r", RA, tA), atol=1e-12)
        np.testing.assert_allclose(stats.SA[j], RA.sum(axis=0), atol=1e-12)
        np.testing.assert_allclose(stats.StA[j], tA.sum(axis=0), atol=1e-12)
        np.testing.assert_allclose(stats.StB[j], tB.sum(axis=0), atol=1e-12)
        assert stats.n[j] == counts[j]
    allA, allB = np.concatenate(A), np.concatenate(B)
    np.testing.assert_allclose(stats.totals, [*allA[:, :3, 3].sum(0), *allB[:, :3, 3].sum(0),
                                              sum(counts)], atol=1e-12)


def test_normalize_rotation_is_the_projection_of_sign_det_times_M():
    """Paper section IV-A: scale by sign(det), project onto SO(3); one SVD does both."""
    rng = np.random.default_rng(6)
    M = rng.normal(size=(200, 3, 3))
    sign = np.sign(np.linalg.det(M))
    assert (sign < 0).any() and (sign > 0).any()
    expected = g.project_to_so3(M * sign[:, None, None])
    np.testing.assert_allclose(normalize_rotation(M), expected, atol=1e-12)
    out = np.zeros((200, 4, 4))
    normalize_rotation(M, out=out[:, :3, :3])
    np.testing.assert_array_equal(out[:, :3, :3], normalize_rotation(M))


def test_translations_without_any_rotation_are_degenerate():
    rng = np.random.default_rng(7)
    R = g.random_transforms(rng, 1)[0, :3, :3]
    A = np.tile(np.eye(4), (6, 1, 1))
    A[:, :3, :3] = R                                   # the same rotation every time
    A[:, :3, 3] = rng.normal(size=(6, 3))
    stats = camera_stats(transform_entries(A, A), [6])
    with pytest.raises(multieye.DegenerateMotionError, match="translations are not determined"):
        solve_translations(stats, np.eye(3))
