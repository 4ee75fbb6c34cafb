"""The lens estimated jointly with the rig is at least as close to the truth as OpenCV's
per-camera calibration on the same images (issue 32, item 2), on small rendered rigs: three
cameras x 12 images, 640 x 480, each lens estimated in its true model.

Compared, as mrcal's ``projection_diff`` does, after the rotation between the two camera
frames that fits best (a principal point off by d pixels is the camera turned by d / f: the
extrinsics absorb it): RMS over every camera's observed corners of
``|pi_est(R ray) - pi_true(ray)|``.  One camera of one rig can go either way (on 20 rigs of
benchmarks/bench_nees.py the joint lens is below OpenCV's on 12-16 of 20 per camera); the
RMS over the rigs' cameras is what the claim is about."""

from __future__ import annotations

import re

import cv2
import numpy as np
import pytest
from scipy.optimize import least_squares

from multieye.core.intrinsics import Intrinsics, lens_model
from multieye.core.lens import project_points, undistort_points
from multieye.pipeline import calibrate
from multieye.sim.dataset import DatasetSpec, render_dataset

SEEDS = (0, 1)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = []
    for seed in SEEDS:
        folder = tmp_path_factory.mktemp(f"joint_lens{seed}")
        spec = DatasetSpec(n_cameras=3, images_per_camera=12, width=640, height=480,
                           processes=1)
        truth = render_dataset(folder, spec, seed=seed)
        text = (folder / "rig.yaml").read_text()
        for j, lens in enumerate(truth.intrinsics):
            text = re.sub(rf"intrinsics: cam{j}\.yaml", f"model: {lens_model(lens)}", text)
        (folder / "rig_model.yaml").write_text(text)
        out.append((calibrate(folder / "rig_model.yaml", processes=1), truth))
    return out


def _opencv(obs, true: Intrinsics) -> Intrinsics:
    obj = [o.object_points.astype(np.float32) for o in obs]
    img = [o.image_points.astype(np.float32) for o in obs]
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    _, K, d, _, _ = cv2.calibrateCamera(obj, img, (true.width, true.height), None, None,
                                        flags=cv2.CALIB_FIX_K3, criteria=crit)
    return Intrinsics(K=K, dist=d.ravel()[:4], width=true.width, height=true.height)


def _after_rotation(est: Intrinsics, true: Intrinsics, pixels: np.ndarray) -> np.ndarray:
    """Per-corner errors of ``est`` after the best-fitting rotation, (n, 2) px."""
    rays = np.column_stack([undistort_points(pixels, true), np.ones(len(pixels))])
    target = project_points(rays, true)
    fit = least_squares(lambda r: (project_points(rays @ cv2.Rodrigues(r)[0].T, est)
                                   - target).ravel(), np.zeros(3), x_scale=1e-3)
    return fit.fun


def test_joint_lens_is_at_least_opencvs_per_camera_lens(runs):
    joint, opencv = [], []
    for run, truth in runs:
        for j, name in enumerate(truth.names):
            assert run.cameras[name].intrinsics_estimated
            obs = run.cameras[name].observations
            pixels = np.concatenate([o.image_points for o in obs])
            joint.append(_after_rotation(run.refinement.intrinsics[name], truth.intrinsics[j],
                                         pixels))
            opencv.append(_after_rotation(_opencv(obs, truth.intrinsics[j]),
                                          truth.intrinsics[j], pixels))
    rms = [float(np.sqrt(np.mean(np.concatenate(e) ** 2) * 2)) for e in (joint, opencv)]
    per_camera = [(float(np.sqrt(2 * np.mean(a ** 2))), float(np.sqrt(2 * np.mean(b ** 2))))
                  for a, b in zip(joint, opencv)]
    assert rms[0] <= rms[1], (rms, per_camera)
