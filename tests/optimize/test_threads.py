"""BLAS threads for the refinement (issue 21, item 3): one thread on small reduced systems,
restored afterwards; no scipy.stats on the refinement's import path; its quantiles exact."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from multieye.core import geometry as g
from multieye.core.cpus import BLAS_THREAD_VARIABLES, available_cores, one_blas_thread
from multieye.estimate import refine_images as ri
from multieye.optimize import levenberg_marquardt as lm
from multieye.optimize.threads import PARALLEL_FROM, blas_threads, threads_for
from multieye.sim.images import simulate_images
from multieye.solvers import solve


def _blas_threads() -> list[int]:
    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


def test_rule_switches_at_parallel_from(monkeypatch):
    """One thread below PARALLEL_FROM; from there on every core, unless the user chose a
    number (then it is left as it is); the command line's own one thread is not a choice."""
    for name in BLAS_THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    assert blas_threads(48) == 1
    assert blas_threads(PARALLEL_FROM - 1) == 1
    assert blas_threads(PARALLEL_FROM) == available_cores()
    assert one_blas_thread()
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
    assert not one_blas_thread()                    # set already
    assert blas_threads(PARALLEL_FROM) == available_cores()
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "3")  # the user's choice stands
    assert blas_threads(PARALLEL_FROM) is None and blas_threads(48) == 1
    monkeypatch.delenv("OPENBLAS_NUM_THREADS")
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert blas_threads(PARALLEL_FROM) is None
    assert not one_blas_thread() and "OPENBLAS_NUM_THREADS" not in os.environ


CLI_THREADS = """
import sys
from multieye.cli import main
main(sys.argv[1:], standalone_mode=False)
from threadpoolctl import threadpool_info
print("BLAS", sorted({lib["num_threads"] for lib in threadpool_info()
                      if lib["user_api"] == "blas"}), flush=True)
"""


def test_the_command_line_starts_with_one_blas_thread(tmp_path):
    """`multieye calibrate` imports numpy with OPENBLAS_NUM_THREADS=1 unless the user set a
    number (their number stands): no pool of BLAS threads spinning after each small call."""
    from small_dataset import render_small

    ds = tmp_path / "ds"
    render_small(ds, images_per_camera=6)
    env = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES
           and k != "MULTIEYE_ONE_BLAS_THREAD"}
    seen = []
    for extra in ({}, {"OPENBLAS_NUM_THREADS": "2"}):
        run = subprocess.run([sys.executable, "-c", CLI_THREADS, "calibrate", str(ds), "-o",
                              str(tmp_path / f"out{len(seen)}"), "--processes", "1"],
                             capture_output=True, text=True, timeout=300, env={**env, **extra})
        assert run.returncode == 0, run.stderr
        seen.append([line for line in run.stdout.splitlines() if line.startswith("BLAS")])
    assert seen[0] == ["BLAS [1]"]
    assert seen[1] == ["BLAS [2]"]


@pytest.mark.skipif(not _blas_threads(), reason="no BLAS library that threadpoolctl controls")
def test_threads_for_limits_small_systems_and_restores():
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        with threads_for(300):
            assert set(_blas_threads()) == {1}
        assert _blas_threads() == before
    with threadpool_limits(limits=1, user_api="blas"):
        with threads_for(PARALLEL_FROM + 1):
            assert set(_blas_threads()) == {blas_threads(PARALLEL_FROM + 1) or 1}
        assert set(_blas_threads()) == {1}


@pytest.mark.skipif(not _blas_threads(), reason="no BLAS library that threadpoolctl controls")
def test_refinement_solves_on_one_thread_and_gives_the_same_digits(monkeypatch):
    seen = []
    solve_step = lm.solve_step

    def recording(*args, **kwargs):
        seen.append(max(_blas_threads()))
        return solve_step(*args, **kwargs)

    monkeypatch.setattr(lm, "solve_step", recording)
    sc = simulate_images(3, n_cameras=2, images=12)
    closed = solve(list(sc.A), [g.inv(T) for T in sc.T_cam_target])
    with threadpool_limits(limits=2, user_api="blas"):
        runs = [ri.refine_images(sc.setup, sc.observations, sc.intrinsics, closed.X, closed.Y)
                for _ in range(2)]
        assert max(_blas_threads()) == 2                      # restored after the refinement
    assert seen and set(seen) == {1}
    np.testing.assert_array_equal(runs[0].X, runs[1].X)
    np.testing.assert_array_equal(runs[0].covariance, runs[1].covariance)


def test_outlier_thresholds_are_the_chi_square_quantiles():
    from scipy.special import chdtri
    from scipy.stats import chi2

    p = ri.OUTLIER_PROBABILITY
    assert chdtri(2, p) == pytest.approx(chi2.isf(p, 2), rel=1e-12)
    assert chdtri(2, p) == pytest.approx(-2 * np.log(p), rel=1e-12)
    assert chdtri(6, p) == pytest.approx(chi2.isf(p, 6), rel=1e-12)


def test_no_scipy_stats_on_the_calibrate_path():
    code = ("import sys, multieye.cli, multieye.pipeline.run, multieye.estimate.refine_images; "
            "print(sorted(m for m in sys.modules if m.startswith('scipy.stats')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"
