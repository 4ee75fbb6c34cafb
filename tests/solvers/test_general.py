"""The general closed form A_i X_a = Y_b B_i: exact recovery, equivariance, the single-Y case,
disconnected and degenerate graphs, input errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multieye.core import geometry as g
from multieye.core.errors import (
    DegenerateMotionError,
    DisconnectedError,
    InputError,
    TooFewMeasurementsError,
)
from multieye.solvers.general import MeasurementGroup, random_general_problem, solve_general
from multieye.core.metrics import loop_residuals
from multieye.solvers import solve


def _max_error(sol, X, Y) -> float:
    return max(max(np.abs(sol.X[k] - X[k]).max() for k in X),
               max(np.abs(sol.Y[k] - Y[k]).max() for k in Y))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), extra=st.integers(0, 8))
def test_noise_free_three_targets_five_cameras_recovered_exactly(seed, extra):
    rng = np.random.default_rng(seed)
    # 7 pairs form a spanning tree of 3 + 5 unknowns; up to 15 pairs exist.
    groups, X, Y = random_general_problem(rng, 3, 5, 60, n_groups=7 + extra)
    sol = solve_general(groups)
    assert _max_error(sol, X, Y) < 1e-9
    assert set(sol.X) == set(X) and set(sol.Y) == set(Y)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_x=st.integers(1, 6), n_y=st.integers(1, 6))
def test_noise_free_recovery_for_any_shape(seed, n_x, n_y):
    rng = np.random.default_rng(seed)
    groups, X, Y = random_general_problem(rng, n_x, n_y, 8 * (n_x + n_y))
    assert _max_error(solve_general(groups), X, Y) < 1e-9


def test_result_lists_groups_unknowns_and_residuals(rng):
    groups, X, Y = random_general_problem(rng, 2, 3, 30, n_groups=5, rot_noise_rad=0.01,
                                          trans_noise_m=0.005)
    sol = solve_general(groups)
    assert sol.groups == tuple((gr.x_name, gr.y_name, len(gr.A)) for gr in groups)
    xs = list(dict.fromkeys(gr.x_name for gr in groups))
    ys = list(dict.fromkeys(gr.y_name for gr in groups))
    assert sol.unknowns == tuple([("X", x) for x in xs] + [("Y", y) for y in ys])
    assert sol.method == "joint" and sol.covariance is None
    for gr in groups:
        rot_deg, trans_m = loop_residuals(gr.A, gr.B, sol.X[gr.x_name], sol.Y[gr.y_name])
        res = sol.residuals[(gr.x_name, gr.y_name)]
        assert res.n == len(gr.A)
        assert res.e_t_m == pytest.approx(trans_m.mean())
        assert res.max_R_deg == pytest.approx(rot_deg.max())
    with pytest.raises(InputError, match="refine=True"):
        sol.covariance_of("Y", ys[0])


def test_single_y_agrees_with_the_joint_solver(rng):
    # One Y shared by m X: the general closed form must be the single-Y joint solver.
    groups, _, _ = random_general_problem(rng, 4, 1, 60, rot_noise_rad=0.02, trans_noise_m=0.01)
    single = solve([gr.A for gr in groups], [gr.B for gr in groups], method="joint")
    general = solve_general(groups)
    for j, gr in enumerate(groups):
        assert np.abs(general.X[gr.x_name] - single.X[j]).max() < 1e-9
    assert np.abs(general.Y["y0"] - single.Y).max() < 1e-9


def test_solution_moves_with_a_change_of_frame_on_the_a_side(rng):
    # W A X_a = (W Y_b) B: the residuals only rotate, so the closed form follows exactly.
    groups, _, _ = random_general_problem(rng, 3, 4, 80, rot_noise_rad=0.02, trans_noise_m=0.01)
    sol = solve_general(groups)
    W = g.random_transforms(rng)
    left = solve_general([(gr.x_name, gr.y_name, W @ gr.A, gr.B) for gr in groups])
    for name in sol.X:
        assert np.abs(left.X[name] - sol.X[name]).max() < 1e-9
    for name in sol.Y:
        assert np.abs(left.Y[name] - W @ sol.Y[name]).max() < 1e-9


def test_solution_moves_with_a_change_of_frame_on_the_b_side(rng):
    # A X_a Z = Y_b B Z.  The rotation step follows exactly even with noise; the translation
    # residual R_A t_X + t_A - R_Y t_B - t_Y gains (R_A R_X - R_Y R_B) t_Z, so the
    # translations follow exactly only without noise.
    Z = g.random_transforms(rng)
    for noise in (0.0, 0.02):
        groups, _, _ = random_general_problem(rng, 3, 4, 80, rot_noise_rad=noise,
                                              trans_noise_m=noise)
        sol = solve_general(groups)
        right = solve_general([(gr.x_name, gr.y_name, gr.A, gr.B @ Z) for gr in groups])
        part = np.s_[:3, :3] if noise else np.s_[:, :]
        for name in sol.X:
            assert np.abs(right.X[name][part] - (sol.X[name] @ Z)[part]).max() < 1e-9
        for name in sol.Y:
            assert np.abs(right.Y[name][part] - sol.Y[name][part]).max() < 1e-9


def test_noisy_solution_is_close_to_the_truth(rng):
    groups, X, Y = random_general_problem(rng, 3, 5, 400, rot_noise_rad=0.005,
                                          trans_noise_m=0.002)
    sol = solve_general(groups)
    for name in X:
        assert np.degrees(g.rotation_angle_between(sol.X[name], X[name])) < 0.5
    for name in Y:
        assert g.translation_distance(sol.Y[name], Y[name]) < 0.02


def test_repeated_pairs_are_merged(rng):
    groups, _, _ = random_general_problem(rng, 2, 2, 40, n_groups=3, rot_noise_rad=0.01,
                                          trans_noise_m=0.01)
    first = groups[0]
    split = [MeasurementGroup(first.x_name, first.y_name, first.A[:4], first.B[:4]),
             *groups[1:],
             MeasurementGroup(first.x_name, first.y_name, first.A[4:], first.B[4:])]
    merged = solve_general(groups)
    again = solve_general(split)
    assert again.groups[0] == (first.x_name, first.y_name, len(first.A))
    assert len(again.groups) == len(groups)
    for name in merged.Y:
        assert np.abs(again.Y[name] - merged.Y[name]).max() < 1e-12


def test_disconnected_unknowns_are_named(rng):
    big, _, _ = random_general_problem(rng, 2, 3, 40)
    small, _, _ = random_general_problem(rng, 1, 1, 10)
    lonely = [MeasurementGroup("tagL", "camL", gr.A, gr.B) for gr in small]
    with pytest.raises(DisconnectedError) as info:
        solve_general(big + lonely)
    assert set(info.value.names) == {"tagL", "camL"}
    assert "X[tagL]" in str(info.value) and "Y[camL]" in str(info.value)
    assert "x0" not in str(info.value)


def test_rotation_about_one_axis_everywhere_is_degenerate(rng):
    X = g.random_transforms(rng)
    Y = g.random_transforms(rng)
    groups = []
    for name, X_ in (("a", X), ("b", X @ g.random_transforms(rng))):
        A = g.transform_from_rotvec(np.outer(rng.uniform(-2, 2, 12), [0, 0, 1]),
                                    rng.normal(size=(12, 3)))
        groups.append((name, "cam", A, g.inv(Y) @ A @ X_))
    with pytest.raises(DegenerateMotionError, match="single axis"):
        solve_general(groups)


def test_one_group_about_one_axis_is_fine_when_the_graph_determines_it(rng):
    # Group (x0, y1) rotates about z only; x0 and y1 are fixed through the other groups.
    groups, X, Y = random_general_problem(rng, 2, 2, 60, n_groups=4)
    A = g.transform_from_rotvec(np.outer(rng.uniform(-2, 2, 5), [0, 0, 1]),
                                rng.normal(size=(5, 3)))
    groups = [gr for gr in groups if (gr.x_name, gr.y_name) != ("x0", "y1")]
    groups.append(MeasurementGroup("x0", "y1", A, g.inv(Y["y1"]) @ A @ X["x0"]))
    assert _max_error(solve_general(groups), X, Y) < 1e-9


@pytest.mark.parametrize("mutate, error, message", [
    (lambda gr: [("x", "y", gr.A, gr.B[:-1])], InputError, "A but"),
    (lambda gr: [("x", "y", gr.A[:, :3], gr.B)], InputError, r"shape \(N, 4, 4\)"),
    (lambda gr: [("x", "y", gr.A * np.diag([2.0, 2.0, 2.0, 1.0]), gr.B)], InputError,
     r"A\(x, y\)\[0\]: not a rigid transform"),
    (lambda gr: [("x", "y", gr.A, np.where(np.arange(16).reshape(4, 4) == 3, np.nan, gr.B))],
     InputError, "NaN"),
    (lambda gr: [("x", "y", gr.A[:0], gr.B[:0])], TooFewMeasurementsError, "no measurements"),
    (lambda gr: [], TooFewMeasurementsError, "no measurement groups"),
    (lambda gr: [("x", 3, gr.A, gr.B)], InputError, "names must be strings"),
    (lambda gr: [("x", gr.A, gr.B)], InputError, r"expected \(x_name, y_name, A, B\)"),
])
def test_bad_input_raises_with_a_clear_message(rng, mutate, error, message):
    groups, _, _ = random_general_problem(rng, 1, 1, 6)
    with pytest.raises(error, match=message):
        solve_general(mutate(groups[0]))


def test_unknown_method_and_stray_refine_options_are_rejected(rng):
    groups, _, _ = random_general_problem(rng, 1, 1, 6)
    with pytest.raises(InputError, match="unknown method 'shah'"):
        solve_general(groups, method="shah")
    with pytest.raises(InputError, match="without refine=True"):
        solve_general(groups, loss="linear")


def test_generator_rejects_impossible_graphs(rng):
    with pytest.raises(InputError, match="n_groups"):
        random_general_problem(rng, 2, 2, 10, n_groups=2)
    with pytest.raises(InputError, match="n_measurements"):
        random_general_problem(rng, 2, 2, 3, n_groups=4)
