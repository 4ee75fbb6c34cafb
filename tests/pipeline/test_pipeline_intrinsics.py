"""Whole rig from one recording: cameras given by their lens model instead of intrinsics, on a
rendered dataset, through rig.yaml and the pipeline; and the rig.yaml rules of these keys."""

from __future__ import annotations

import re

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.errors import DatasetError
from multieye.core.lens import project_points
from multieye.io import load_rig
from multieye.pipeline import calibrate
from multieye.sim.dataset import DatasetSpec, render_dataset


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lens") / "dataset"
    spec = DatasetSpec(n_cameras=2, images_per_camera=24, width=640, height=480, processes=2)
    truth = render_dataset(folder, spec, seed=5)
    return folder, truth


def _with_model(folder, out, model="pinhole-radtan", extra=""):
    """A copy of rig.yaml whose cameras give ``model:`` instead of their intrinsics file."""
    text = (folder / "rig.yaml").read_text()
    text = re.sub(r"intrinsics: (cam\d)\.yaml", rf"model: {model}{extra}", text)
    rig = folder / out
    rig.write_text(text)
    return rig


def _projection_error(est, true, truth_T, board):
    rays = np.concatenate([board @ T[:3, :3].T + T[:3, 3] for T in truth_T])
    return np.linalg.norm(project_points(rays, est) - project_points(rays, true), axis=1)


def test_model_instead_of_intrinsics_recovers_lens_and_rig(rendered):
    folder, truth = rendered
    given = calibrate(folder, processes=2)
    run = calibrate(_with_model(folder, "rig_model.yaml"), processes=2)
    assert [run.cameras[n].intrinsics_estimated for n in run.cameras] == [True, True]
    for j, name in enumerate(truth.names):
        est = run.cameras[name].intrinsics
        true = truth.intrinsics[j]
        assert est.model == "pinhole" and est.dist.size == 5
        assert (est.width, est.height) == (640, 480)
        # within a few tenths of a pixel of the true lens where the board was seen
        grid = np.stack(np.meshgrid(np.linspace(-0.4, 0.4, 9), np.linspace(-0.3, 0.3, 7)),
                        axis=-1).reshape(-1, 2)
        rays = np.column_stack([grid, np.ones(len(grid))])
        err = np.linalg.norm(project_points(rays, est) - project_points(rays, true), axis=1)
        assert err.max() < 1.0, err.max()
        cov = run.refinement.intrinsics_covariance[name]
        assert cov.shape == (9, 9) and np.all(np.linalg.eigvalsh(cov) > 0)
    # the rig: close to the truth, and close to what the true intrinsics give
    for T_est, T_given, T_true in zip(run.record.cameras, given.record.cameras, truth.T_ref_cam):
        assert np.degrees(g.rotation_angle_between(T_est.T_ref_cam, T_true)) < 0.1
        assert g.translation_distance(T_est.T_ref_cam, T_true) < 2e-3
        assert g.translation_distance(T_est.T_ref_cam, T_given.T_ref_cam) < 2e-3


def test_loop_residuals_and_image_rms_are_those_of_the_final_lens(rendered):
    """The target poses of the final result come from the estimated lens, not from the
    per-camera start the closed form was solved with."""
    from multieye.core.metrics import camera_residual
    from multieye.imaging.pnp import refit_pose

    folder, _ = rendered
    run = calibrate(_with_model(folder, "rig_model.yaml"), processes=2)
    for _j, cam in enumerate(run.record.cameras):
        p, lens = run.paired[cam.name], run.refinement.intrinsics[cam.name]
        assert lens is run.cameras[cam.name].intrinsics
        for o in p.observations:
            again = refit_pose(o.T_cam_target, o.object_points, o.image_points, lens)
            np.testing.assert_allclose(again.T_cam_target, o.T_cam_target, atol=1e-9)
            assert abs(again.rms_px - o.rms_px) < 1e-9
        np.testing.assert_allclose(p.B, g.inv(np.stack([o.T_cam_target
                                                        for o in p.observations])))
        r = camera_residual(p.A, p.B, cam.X, run.record.Y)
        assert cam.residuals.e_R_deg == pytest.approx(r.e_R_deg, rel=1e-12)
        assert cam.residuals.e_t_m == pytest.approx(r.e_t_m, rel=1e-12)


def test_intrinsics_images_join_the_joint_problem(rendered, tmp_path):
    folder, _ = rendered
    extra_dir = folder / "cam0_intrinsics"
    if not extra_dir.exists():
        extra_dir.mkdir()
        for k, p in enumerate(sorted((folder / "cam0").iterdir())[:6]):
            (extra_dir / f"view{k}.png").write_bytes(p.read_bytes())
    text = (folder / "rig.yaml").read_text()
    text = text.replace("intrinsics: cam0.yaml", "model: pinhole-radtan\n    intrinsics_images: "
                        "cam0_intrinsics/")
    text = re.sub(r"intrinsics: (cam1)\.yaml", "model: pinhole-radtan", text)
    (folder / "rig_views.yaml").write_text(text)
    run = calibrate(folder / "rig_views.yaml", processes=2)
    assert len(run.cameras["cam0"].intrinsics_views) == 6
    assert run.cameras["cam1"].intrinsics_views == ()
    assert "cam0" in run.refinement.intrinsics


@pytest.mark.parametrize("camera, message", [
    ("{model: kannala, images: cam0/}", r"model: expected one of pinhole-radtan, "
                                        r"pinhole-radtan4, pinhole-rational, fisheye, unified, "
                                        r"double-sphere, eucm, got 'kannala'"),
    ("{images: cam0/}", "missing key 'intrinsics' or 'model'"),
    ("{model: fisheye, refine_intrinsics: false, images: cam0/}",
     "'refine_intrinsics: false' but no 'intrinsics' to hold fixed"),
    ("{intrinsics: cam0.yaml, intrinsics_images: cam0/, images: cam0/}",
     "images for the intrinsics only, but this camera's intrinsics are held fixed"),
    ("{model: fisheye, poses: p.txt}", "precomputed 'poses' has no images to estimate"),
    ("{model: fisheye, images: cam0/, intrinsics_target: {type: chessboard}}",
     "'intrinsics_target' describes the board of 'intrinsics_images'"),
    ("{model: fisheye, images: cam0/, refine_intrinsics: 1}",
     "refine_intrinsics: expected true or false"),
])
def test_lens_keys_are_checked_where_they_enter(rendered, tmp_path, camera, message):
    folder, _ = rendered
    (tmp_path / "cam0").mkdir()
    (tmp_path / "p.txt").write_text("")
    (tmp_path / "cam0.yaml").write_text((folder / "cam0.yaml").read_text())
    (tmp_path / "m.txt").write_text("")
    rig = tmp_path / "rig.yaml"
    rig.write_text("setup: eye-to-base\ntarget: {type: chessboard, rows: 6, cols: 9, "
                   f"spacing: 0.05}}\nmocap: {{file: m.txt}}\ncameras:\n  cam0: {camera}\n")
    with pytest.raises(DatasetError, match=message):
        load_rig(rig)


def test_intrinsics_of_another_model_than_stated_are_refused(rendered):
    folder, _ = rendered
    text = (folder / "rig.yaml").read_text().replace(
        "intrinsics: cam0.yaml", "intrinsics: cam0.yaml\n    model: fisheye")
    (folder / "rig_mismatch.yaml").write_text(text)
    with pytest.raises(DatasetError, match="camera cam0.*rig.yaml says model: fisheye but the "
                                           "intrinsics file holds a pinhole-radtan4 lens"):
        calibrate(folder / "rig_mismatch.yaml", processes=1)


def test_estimated_intrinsics_are_written_where_people_look(rendered, tmp_path):
    """calibration.json's intrinsics and uncertainty blocks, OUT/intrinsics/<camera>.yaml
    (read back by cv2.FileStorage and by multieye) and the camchain with the refined lens."""
    import json

    import cv2

    from multieye.io import read_intrinsics
    from multieye.outputs.write import write_outputs

    folder, _ = rendered
    run = calibrate(_with_model(folder, "rig_out.yaml"), processes=2)
    written = write_outputs(run, tmp_path / "out", report=False)
    data = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert set(data["uncertainty"]) == {"T_marker_target"}
    # Kalibr's radtan has no k3: neither camera fits, the camchain is not written, and the
    # note names both cameras with the reason, once (one note per cause)
    assert not (tmp_path / "out" / "camchain.yaml").exists()
    assert [n for n in written.notes if "Kalibr" in n] == [
        "camchain.yaml not written: Kalibr cannot hold any camera: cam0, cam1 (Kalibr radtan "
        "holds k1 k2 p1 p2 only; these intrinsics have 5 non-trivial coefficients (model: "
        "pinhole-radtan4 in rig.yaml estimates a lens Kalibr can hold))"], written.notes
    for name in ("cam0", "cam1"):
        block = data["cameras"][name]["intrinsics"]
        lens = run.cameras[name].intrinsics
        assert block["model"] == "pinhole-radtan" and block["estimated"] is True
        assert block["image_size"] == [640, 480]
        np.testing.assert_array_equal(block["K"], lens.K)
        cov = np.array(block["covariance"])
        assert cov.shape == (9, 9) and np.all(np.linalg.eigvalsh(cov) > 0)
        assert 0 < block["projection_std_px"]["mean"] <= block["projection_std_px"]["max"] < 1
        assert "lens_curve" not in block                # a pinhole lens: its parameters'
        unc = data["cameras"][name]["uncertainty"]
        assert set(unc) == {"T_world_cam", "T_ref_cam"}
        assert unc["T_world_cam"]["std_rot_deg"] > 0 and unc["T_world_cam"]["std_trans_m"] > 0
        assert unc["T_ref_cam"]["std_rot_deg"] == data["cameras"][name].get("std_rot_deg", 0.0)
        path = tmp_path / "out" / "intrinsics" / f"{name}.yaml"
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        np.testing.assert_allclose(fs.getNode("camera_matrix").mat(), lens.K, rtol=1e-12)
        fs.release()
        back = read_intrinsics(path)
        np.testing.assert_allclose(back.dist, lens.dist, rtol=1e-12)


def test_camchain_keeps_the_cameras_kalibr_can_hold_and_names_the_others(rendered, tmp_path):
    from multieye.io import read_camchain
    from multieye.outputs.write import write_outputs

    folder, _ = rendered
    text = (folder / "rig.yaml").read_text().replace("intrinsics: cam0.yaml",
                                                     "model: pinhole-radtan")
    (folder / "rig_mixed.yaml").write_text(text)
    run = calibrate(folder / "rig_mixed.yaml", processes=2)
    written = write_outputs(run, tmp_path / "out", report=False)
    chain = read_camchain(tmp_path / "out" / "camchain.yaml")
    assert [e.name for e in chain] == ["cam1"]
    np.testing.assert_allclose(chain[0].intrinsics.K, run.cameras["cam1"].intrinsics.K)
    head = (tmp_path / "out" / "camchain.yaml").read_text().splitlines()[0]
    assert head.startswith("# left out of this camchain: cam0 (Kalibr radtan holds k1 k2 p1 p2")
    assert any(n.startswith("camchain.yaml holds cam1 only; left out: cam0 (Kalibr radtan")
               for n in written.notes)


def test_a_lens_estimated_as_kalibrs_radtan_goes_into_the_camchain(rendered, tmp_path):
    """model: pinhole-radtan4 estimates k1 k2 p1 p2 with k3 held at 0: the lens Kalibr's
    radtan holds, so the camchain carries both cameras, each with its estimated lens."""
    from multieye.io import read_camchain
    from multieye.outputs.write import write_outputs

    folder, truth = rendered
    text = re.sub(r"intrinsics: (cam\d)\.yaml", "model: pinhole-radtan4",
                  (folder / "rig.yaml").read_text())
    (folder / "rig_radtan4.yaml").write_text(text)
    run = calibrate(folder / "rig_radtan4.yaml", processes=2)
    write_outputs(run, tmp_path / "out", report=False)
    chain = read_camchain(tmp_path / "out" / "camchain.yaml")
    assert [e.name for e in chain] == ["cam0", "cam1"]
    for e in chain:
        lens = run.cameras[e.name].intrinsics
        assert run.cameras[e.name].intrinsics_estimated and lens.dist.size == 4
        np.testing.assert_allclose(e.intrinsics.K, lens.K)
        np.testing.assert_allclose(e.intrinsics.dist, lens.dist)
        assert run.record.camera(e.name).intrinsics.covariance.shape == (8, 8)
    import json
    cal = json.loads((tmp_path / "out" / "calibration.json").read_text())
    assert cal["cameras"]["cam0"]["intrinsics"]["model"] == "pinhole-radtan4"
    for T_est, T_true in zip(run.record.cameras, truth.T_ref_cam):
        assert np.degrees(g.rotation_angle_between(T_est.T_ref_cam, T_true)) < 0.1


def test_radtan_and_radtan4_files_under_either_model_name():
    """k1 k2 p1 p2 is OpenCV's 5-coefficient model with k3 = 0: a 4-coefficient file is also
    pinhole-radtan, a 5-coefficient file with k3 = 0 also pinhole-radtan4 (then with its 4
    coefficients, so that refining keeps k3 at 0), and a non-zero k3 is refused by name."""
    from multieye.core.intrinsics import Intrinsics
    from multieye.pipeline.estimated_lens import check_model

    K = [[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]
    four = Intrinsics(K=K, dist=[-0.2, 0.05, 1e-3, -1e-3], width=640, height=480)
    zero_k3 = Intrinsics(K=K, dist=[-0.2, 0.05, 1e-3, -1e-3, 0.0], width=640, height=480)
    k3 = Intrinsics(K=K, dist=[-0.2, 0.05, 1e-3, -1e-3, 0.05], width=640, height=480)
    assert check_model("cam0", four, "pinhole-radtan", "f.yaml") is four
    assert check_model("cam0", four, "pinhole-radtan4", "f.yaml") is four
    assert check_model("cam0", k3, "pinhole-radtan", "f.yaml") is k3
    got = check_model("cam0", zero_k3, "pinhole-radtan4", "f.yaml")
    np.testing.assert_array_equal(got.dist, four.dist)
    np.testing.assert_array_equal(got.K, four.K)
    with pytest.raises(DatasetError, match="model: pinhole-radtan4 but the intrinsics file "
                                           "holds a pinhole-radtan lens with k3 = 0.05"):
        check_model("cam0", k3, "pinhole-radtan4", "f.yaml")
    with pytest.raises(DatasetError, match="holds a pinhole-radtan4 lens;"):
        check_model("cam0", four, "fisheye", "f.yaml")
