"""The lens start run as the pipeline's task (issue 21): OpenCV poses only the views it
calibrates from, the others' poses are those of the PnP every view gets anyway; the start
then holds every view's pose, close to OpenCV's own, and the weak-data warnings are the same
as from a start that posed every view itself."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.lens import project_points
from multieye.imaging.batch import ImageResult
from multieye.imaging.calibrate import START_VIEWS, initial_intrinsics, lens_start_task
from multieye.imaging.detect import Detection
from multieye.pipeline.estimated_lens import MIN_TILT_DEG, lens_start, weak_data_warnings
from multieye.sim.images import default_intrinsics


@pytest.fixture(autouse=True)
def _one_thread():
    """OpenCV on one thread, as in the workers: its calibration differs in the last digits
    with the thread count."""
    cv2 = pytest.importorskip("cv2")
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    yield
    cv2.setNumThreads(threads)


def _results(max_tilt_deg: float, n: int = 45, seed: int = 4, model: str = "pinhole"):
    """Detection-only results of a 9 x 6 board seen ``n`` times, tilted up to
    ``max_tilt_deg`` against the line of sight, 0.1 px noise; and one unreadable image."""
    lens = default_intrinsics(model)
    rng = np.random.default_rng(seed)
    xy = np.stack(np.meshgrid(np.arange(9), np.arange(6)), -1).reshape(-1, 2) * 0.04
    obj = np.column_stack([xy - xy.mean(axis=0), np.zeros(len(xy))])
    out = [ImageResult("gone.png", None, None, "unreadable file: gone.png")]
    for k in range(n):
        axis = rng.normal(size=3)
        axis[2] = 0.0
        tilt = np.radians(max_tilt_deg) * (0.3 + 0.7 * (k % 7) / 6)
        R = g.rotation_from_rotvec(axis / np.linalg.norm(axis) * tilt)
        spread = 0.25 if max_tilt_deg > MIN_TILT_DEG else 0.03      # line of sight near the axis
        t = np.array([rng.uniform(-spread, spread), rng.uniform(-spread, spread) * 0.6,
                      rng.uniform(0.8, 1.3)])
        uv = project_points(obj @ R.T + t, lens) + rng.normal(0, 0.1, (len(obj), 2))
        det = Detection(ids=np.arange(len(obj)), image_points=uv, object_points=obj)
        out.append(ImageResult(f"{k:03d}.png", None, det, None, image_size=(1280, 960)))
    return out


@pytest.mark.parametrize("model, max_tilt", [("pinhole-radtan", 10.0), ("pinhole-radtan", 40.0),
                                             ("fisheye", 10.0)])
def test_the_task_gives_every_pose_and_the_same_warnings(model, max_tilt):
    results = _results(max_tilt, model="fisheye" if model == "fisheye" else "pinhole")
    views = [(r.detection.object_points, r.detection.image_points) for r in results
             if r.detection is not None]
    assert len(views) > START_VIEWS
    own = initial_intrinsics(views, (1280, 960), model, name="cam0")      # poses every view
    started = lens_start_task(model, "cam0")(results)
    start = started.start
    assert np.array_equal(start.intrinsics.K, own.intrinsics.K)
    assert start.rms_px == own.rms_px
    assert start.T_cam_target.shape == own.T_cam_target.shape
    assert np.all(np.isfinite(start.T_cam_target))
    # the views OpenCV calibrated from keep its poses; the others are the PnP poses, which
    # the noise (0.1 px) moves by about 1e-4: OpenCV's own PnP agrees far below that (for
    # the pinhole the same minimum; for the fisheye OpenCV's fits the undistorted points,
    # not the pixels, another estimate within the noise)
    same = np.all(start.T_cam_target == own.T_cam_target, axis=(1, 2))
    assert same.sum() >= START_VIEWS
    assert not same.all()
    np.testing.assert_allclose(start.T_cam_target, own.T_cam_target,
                               atol=1e-3 if model == "fisheye" else 1e-6)
    posed = [r for r in started.results if r.detection is not None]
    for k in np.flatnonzero(~same):
        assert np.array_equal(start.T_cam_target[k], posed[k].pose.T_cam_target)
    # the warnings: the same as from every pose OpenCV's; the tilt's said when it is small
    ours = lens_start("cam0", model, results, start).warnings
    theirs = weak_data_warnings("cam0", model, views, own.T_cam_target, (1280, 960))
    assert ours == theirs
    tilted = [w for w in ours if "never tilted more than" in w]
    assert bool(tilted) == (max_tilt < MIN_TILT_DEG)


def test_a_view_pnp_failed_on_is_posed_by_opencv():
    """A view whose PnP failed (its reason says so, no pose) still gets the start's pose of
    it, by cv2.solvePnP as before (the tilt check looks at every view)."""
    from dataclasses import replace

    from multieye.imaging import calibrate

    results = _results(30.0)
    task = lens_start_task("pinhole-radtan", "cam0")
    first = task.first(results)
    start = first.start
    missing = np.flatnonzero(np.isnan(start.T_cam_target[:, 0, 0]))
    posed = task.each(first, results)
    k = int(missing[0])
    index = first.views[k]              # the result whose view is the start's k-th
    assert index == [i for i, r in enumerate(results) if r.detection is not None][k]
    posed[index] = replace(posed[index], pose=None, reason="PnP failed: made up")
    joined = task.join(first, posed)
    own = initial_intrinsics([(r.detection.object_points, r.detection.image_points)
                              for r in results if r.detection is not None], (1280, 960),
                             "pinhole-radtan")
    np.testing.assert_allclose(joined.start.T_cam_target[k], own.T_cam_target[k], atol=1e-9)
    assert joined.results[index].reason == "PnP failed: made up"
    assert calibrate._pnp_pose(results[1].detection.object_points[:3],
                               results[1].detection.image_points[:3],
                               start.intrinsics).shape == (4, 4)


def test_a_view_without_pose_leaves_the_tilt_check_to_the_others():
    results = _results(10.0)
    views = [(r.detection.object_points, r.detection.image_points) for r in results
             if r.detection is not None]
    T = initial_intrinsics(views, (1280, 960), "pinhole-radtan").T_cam_target
    said = weak_data_warnings("cam0", "pinhole-radtan", views, T, (1280, 960))
    T[3, :3] = np.nan
    assert weak_data_warnings("cam0", "pinhole-radtan", views, T, (1280, 960)) == said
    assert any("never tilted more than" in w for w in said)
