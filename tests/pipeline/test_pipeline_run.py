"""The pipeline's own contracts: inputs validated once, the run's result names."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from multieye.io import load_rig, read_calibration
from multieye.pipeline import calibrate, calibrate_rig, load_camera_data
from multieye.solvers import checks, solve
from pose_dataset import write_pose_dataset
from small_dataset import render_small


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """A calibration of a small rendered dataset, refined on the images, and its outputs."""
    from multieye.outputs.write import write_outputs

    folder = tmp_path_factory.mktemp("small")
    render_small(folder / "ds")
    run = calibrate(folder / "ds", processes=1)
    write_outputs(run, folder / "out", report=False)
    return folder / "out", run


def _count_calls(monkeypatch, module_attr: str, fn, counts=lambda *args, **kwargs: True) -> list:
    """Replace ``fn`` wherever a multieye module holds it under ``module_attr``; count the
    calls for which ``counts(*args, **kwargs)`` holds."""
    calls = []

    def counting(*args, **kwargs):
        if counts(*args, **kwargs):
            calls.append(1)
        return fn(*args, **kwargs)

    for mod in list(sys.modules.values()):
        if (getattr(mod, "__name__", "").startswith("multieye")
                and getattr(mod, module_attr, None) is fn):
            monkeypatch.setattr(mod, module_attr, counting)
    return calls


@pytest.mark.parametrize("method", ["joint", "shah"])
@pytest.mark.parametrize("robust", [True, False])
def test_measurements_are_validated_once_per_calibration(tmp_path, monkeypatch, method, robust):
    folder, _, _ = write_pose_dataset(tmp_path)
    rig = load_rig(folder / "rig.yaml")
    cameras = load_camera_data(rig)
    # consensus, the motion diagnostics and the solver are all loaded, so every module that
    # imported check_measurements by name is patched
    import multieye.estimate.consensus  # noqa: F401
    import multieye.estimate.diagnostics  # noqa: F401

    # validated Measurements passed on are returned as they are (no check runs): not counted
    calls = _count_calls(monkeypatch, "check_measurements", checks.check_measurements,
                         lambda A, *args, **kwargs: not isinstance(A, checks.Measurements))
    run = calibrate_rig(rig, cameras, method=method, robust=robust)
    assert len(calls) == 1
    assert run.record.cameras[1].measurements_used == 12


def test_public_functions_still_validate_raw_arrays():
    from multieye.core.errors import InputError
    from multieye.estimate.consensus import consensus
    from multieye.estimate.diagnostics import motion_diagnostics
    from multieye.solvers import solve

    bad = [np.tile(np.eye(4), (5, 1, 1)) * 2.0]        # not rigid
    good = [np.tile(np.eye(4), (5, 1, 1))]
    for fn in (solve, consensus, motion_diagnostics):
        with pytest.raises(InputError):
            fn(bad, good)
        with pytest.raises(InputError, match="B is missing"):
            fn(good)


def test_validated_measurements_are_not_checked_again_but_subsets_keep_their_rows(monkeypatch):
    from multieye.core import geometry as g
    from multieye.estimate.consensus import consensus
    from multieye.estimate.diagnostics import motion_diagnostics
    from multieye.solvers import solve

    rng = np.random.default_rng(1)
    X = g.random_transforms(rng, 2)
    Y = g.random_transforms(rng)
    A = [g.random_transforms(rng, 10) for _ in range(2)]
    B = [g.inv(Y) @ a @ x for a, x in zip(A, X)]
    meas = checks.check_measurements(A, B, names=["a", "b"], per_camera_motion=False)
    # validated Measurements passed on are returned as they are (no check runs): not counted
    calls = _count_calls(monkeypatch, "check_measurements", checks.check_measurements,
                         lambda A, *args, **kwargs: not isinstance(A, checks.Measurements))
    sol = solve(meas)
    np.testing.assert_allclose(sol.X, X, atol=1e-9)
    assert consensus(meas).rejected == ()
    assert [c.name for c in motion_diagnostics(meas).cameras] == ["a", "b"]
    keep = [np.arange(10) % 2 == 0, np.arange(10) < 7]
    sub = meas.select(keep)
    assert sub.counts.tolist() == [5, 7]
    np.testing.assert_array_equal(sub.A[5:], A[1][:7])
    np.testing.assert_array_equal(sub.B[:5], B[0][::2])
    np.testing.assert_allclose(solve(sub, method="shah").X, X, atol=1e-9)
    assert calls == []
    from multieye.core.errors import InputError, TooFewMeasurementsError

    with pytest.raises(InputError, match="not both"):
        solve(meas, B)
    with pytest.raises(InputError, match="differ"):
        solve(meas, names=["x", "y"])
    with pytest.raises(TooFewMeasurementsError, match="camera b keeps 2"):
        meas.select([np.ones(10, bool), np.arange(10) < 2])


def test_run_gives_the_final_result_under_plain_names_and_the_closed_form_apart(small_run):
    out, run = small_run
    rec = read_calibration(out / "calibration.json")
    assert run.refinement is not None and run.refinement.kind == "images" == rec.refinement
    # the final (refined) result is what calibration.json holds
    assert list(run.X) == [c.name for c in rec.cameras]
    for j, c in enumerate(rec.cameras):
        np.testing.assert_allclose(run.X[c.name], c.X, atol=1e-12)
        np.testing.assert_allclose(run.X[c.name], run.refinement.X[j], atol=1e-12)
    np.testing.assert_allclose(run.Y, rec.Y, atol=1e-12)
    assert list(run.T_ref_cam) == [c.name for c in rec.cameras] == ["cam0", "cam1"]
    for c in rec.cameras:
        np.testing.assert_allclose(run.T_ref_cam[c.name], c.T_ref_cam, atol=1e-12)
    np.testing.assert_allclose(run.T_ref_cam["cam0"], np.eye(4), atol=1e-12)
    assert run.covariance.shape == (18, 18)
    np.testing.assert_allclose(run.covariance, run.refinement.covariance)
    # the closed form: joint on the measurements kept, not the refinement
    paired = list(run.paired.values())
    closed = solve([p.A for p in paired], [p.B for p in paired], "joint")
    np.testing.assert_allclose(run.closed_form.X, closed.X, atol=1e-9)
    np.testing.assert_allclose(run.closed_form.Y, closed.Y, atol=1e-9)
    assert not np.allclose(run.closed_form.X, np.stack(list(run.X.values())), atol=1e-9)


def test_run_keys_every_per_camera_result_by_camera_name(small_run):
    out, run = small_run
    data = json.loads((out / "calibration.json").read_text())
    names = list(data["cameras"])
    assert names == ["cam0", "cam1"] and run.reference == data["reference_camera"]
    for mapping in (run.X, run.T_ref_cam, run.X_covariance, run.X_std,
                    run.T_ref_cam_covariance, run.T_ref_cam_std, run.intrinsics):
        assert list(mapping) == names
    for name, cam in data["cameras"].items():
        x = cam["uncertainty"]["T_world_cam"]
        np.testing.assert_allclose(run.X_covariance[name], x["covariance"], rtol=1e-12)
        assert run.X_std[name] == pytest.approx((x["std_rot_deg"], x["std_trans_m"]), rel=1e-12)
        np.testing.assert_allclose(run.T_ref_cam_covariance[name], cam["covariance"], rtol=1e-12)
        assert run.T_ref_cam_std[name] == pytest.approx((cam["std_rot_deg"], cam["std_trans_m"]),
                                                         rel=1e-12)
        np.testing.assert_allclose(run.intrinsics[name].K, cam["intrinsics"]["K"], rtol=1e-12)
    # the X covariance of each camera is its diagonal block of the joint covariance
    for j, name in enumerate(names):
        np.testing.assert_allclose(run.X_covariance[name],
                                   run.covariance[6 * j:6 * j + 6, 6 * j:6 * j + 6], rtol=1e-9)
    np.testing.assert_allclose(run.Y_covariance, run.covariance[-6:, -6:], rtol=1e-9)
    y = data["uncertainty"]["T_marker_target"]
    assert run.Y_std == pytest.approx((y["std_rot_deg"], y["std_trans_m"]), rel=1e-12)
    assert run.warnings == tuple(data["warnings"])


def test_run_without_refinement_is_the_closed_form(small_run):
    _, run = small_run
    plain = calibrate_rig(run.rig, run.cameras, refine=False)
    assert plain.refinement is None and plain.covariance is None
    np.testing.assert_allclose(np.stack(list(plain.X.values())), plain.closed_form.X, atol=1e-12)
    assert set(plain.X_std.values()) == {None} and plain.Y_covariance is None
    np.testing.assert_allclose(plain.Y, plain.closed_form.Y, atol=1e-12)
    np.testing.assert_allclose(plain.closed_form.X, run.closed_form.X, atol=1e-12)
