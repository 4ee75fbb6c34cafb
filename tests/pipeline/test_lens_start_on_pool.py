"""A camera whose lens is estimated gets its lens start and its poses from the detection's
worker processes (issue 21), the same as the main process's own start."""

from __future__ import annotations

import re

import cv2
import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.imaging.batch import detect_and_estimate
from multieye.imaging.targets import target_from_spec
from multieye.io import list_images, load_rig
from multieye.pipeline import camera_data
from multieye.pipeline.estimated_lens import start_lens, with_poses
from multieye.sim.dataset import DatasetSpec, render_dataset


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pool") / "dataset"
    render_dataset(folder, DatasetSpec(n_cameras=2, images_per_camera=16, width=640,
                                       height=480, processes=2), seed=7)
    text = re.sub(r"intrinsics: (cam\d)\.yaml", "model: pinhole-radtan",
                  (folder / "rig.yaml").read_text())
    (folder / "rig_model.yaml").write_text(text)
    return load_rig(folder / "rig_model.yaml")


def _not_here(*args, **kwargs):
    raise AssertionError("the lens was started in the main process")


def test_lens_start_and_poses_run_on_the_workers_with_the_main_process_result(rig,
                                                                              monkeypatch):
    monkeypatch.setattr(camera_data, "start_lens", _not_here)
    monkeypatch.setattr(camera_data, "with_poses", _not_here)
    pooled = camera_data.load_camera_data(rig, processes=2)
    monkeypatch.undo()
    # the main process's own start on the same detections, with OpenCV on one thread as in
    # the workers (OpenCV's calibration differs in the last digits with its thread count)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        for name, cam in rig.cameras.items():
            paths = [p for _, _, p in list_images(cam.images)]
            found = detect_and_estimate(paths, target_from_spec(rig.target, path=rig.path),
                                        None, processes=1)
            lens = start_lens(name, cam.model, found, cam.images)
            posed = [r for r in with_poses(found, lens.intrinsics) if r.ok]
            data = pooled[name]
            assert data.intrinsics_estimated
            assert np.array_equal(data.intrinsics.K, lens.intrinsics.K)
            assert np.array_equal(data.intrinsics.dist, lens.intrinsics.dist)
            assert [o.name for o in data.observations] == [p.rsplit("/", 1)[-1] for p in
                                                           (r.path for r in posed)]
            for o, r in zip(data.observations, posed):
                assert np.array_equal(o.T_cam_target, r.pose.T_cam_target)
                assert o.rms_px == r.pose.rms_px
    finally:
        cv2.setNumThreads(threads)


def test_without_workers_the_start_is_the_same(rig, monkeypatch):
    """One process (no pool): the start runs here, through the same task."""
    monkeypatch.setattr(camera_data, "start_lens", _not_here)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        here = camera_data.load_camera_data(rig, processes=1)
    finally:
        cv2.setNumThreads(threads)
    monkeypatch.undo()
    pooled = camera_data.load_camera_data(rig, processes=2)
    for name in rig.cameras:
        assert np.array_equal(here[name].intrinsics.K, pooled[name].intrinsics.K)
        assert len(here[name].observations) == len(pooled[name].observations)


def test_a_lens_that_cannot_start_fails_as_in_the_main_process(rig, tmp_path):
    """Too few views (2 images) for the lens start: the workers give no start, and the run
    fails with the main process's own error (the camera, the count, what to add)."""
    folder = rig.path.parent if rig.path.is_file() else rig.path
    copy = tmp_path / "two"
    copy.mkdir()
    for p in folder.iterdir():
        if p.suffix == ".yaml":
            (copy / p.name).write_text(p.read_text())
        elif p.name != "cam0":
            (copy / p.name).symlink_to(p)
    (copy / "cam0").mkdir()
    for image in sorted((folder / "cam0").iterdir())[:2]:
        (copy / "cam0" / image.name).symlink_to(image)
    small = load_rig(copy / "rig_model.yaml")
    cam = small.cameras["cam0"]
    assert len(list_images(cam.images)) == 2
    found = detect_and_estimate([p for _, _, p in list_images(cam.images)],
                                target_from_spec(small.target, path=small.path), None,
                                processes=1)
    with pytest.raises(DatasetError) as expected:
        start_lens("cam0", cam.model, found, cam.images)
    assert "at least 3" in str(expected.value)
    with pytest.raises(DatasetError) as raised:
        camera_data.load_camera_data(small, processes=2)
    assert str(raised.value) == str(expected.value)
