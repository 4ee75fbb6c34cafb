"""The report's pictures: rig labels, colours, uncertainty, frame names, time axes, and the
detections drawn on the images."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from multieye.imaging.thumbnails import POINT_BGR, RESIDUAL_BGR, crop_box, residual_thumbnail
from multieye.io.calibration_json import PoseUncertainty
from multieye.outputs.details import write_run_details
from multieye.outputs.figures import HIGHLIGHT, camera_colours, stamps_are_indices
from multieye.outputs.figures_rig import (_overlap, _scene, place_labels, rig_pngs,
                                          uncertainty_magnification)
from export_runs import make_run


def test_labels_do_not_overlap_each_other_or_the_anchors():
    rng = np.random.default_rng(4)
    anchors = rng.uniform(100, 300, size=(16, 2))     # 16 cameras crowded in the middle
    sizes = np.column_stack([rng.uniform(30, 80, 16), np.full(16, 14.0)])
    box = (0.0, 0.0, 400.0, 400.0)
    centres = place_labels(anchors, sizes, box)
    boxes = np.column_stack([centres - sizes / 2, centres + sizes / 2])
    for i in range(16):
        assert box[0] <= boxes[i, 0] and boxes[i, 2] <= box[2]
        assert box[1] <= boxes[i, 1] and boxes[i, 3] <= box[3]
        for j in range(i):
            assert _overlap(boxes[i], boxes[j]) == 0.0, (i, j)
        inside = ((anchors[:, 0] > boxes[i, 0]) & (anchors[:, 0] < boxes[i, 2])
                  & (anchors[:, 1] > boxes[i, 1]) & (anchors[:, 1] < boxes[i, 3]))
        assert not inside.any(), i
    # each label near its own anchor (the first ring of candidates when there is room)
    alone = place_labels(np.array([[200.0, 200.0]]), np.array([[40.0, 12.0]]), box, gap=6.0)
    assert np.hypot(*(alone[0] - [200, 200])) <= 6.0 + 20.0 + 1e-9


def test_camera_colours_are_distinct_and_never_the_highlight():
    for n in (1, 4, 10, 16):
        colours = camera_colours(n)
        assert len(set(colours)) == n
        assert HIGHLIGHT not in colours
        for c in colours:     # no grey either: r, g, b not all equal
            r, g, b = (int(c[k:k + 2], 16) for k in (1, 3, 5))
            assert max(r, g, b) - min(r, g, b) > 20, c


def test_uncertainty_is_magnified_by_a_round_factor_to_be_seen():
    C = np.diag([1e-8, 1e-8, 1e-8, 1e-8, 4e-8, 1e-8])     # sigma 0.2 mm on y
    factor, t3, r3 = uncertainty_magnification([C, None], depth=0.3)
    assert t3 == pytest.approx(3 * 2e-4)
    assert r3 == pytest.approx(np.degrees(3e-4))
    assert factor in (100.0, 200.0)                      # 1, 2 or 5 x 10^n
    assert 0.33 * 0.3 / 2.5 <= factor * t3 <= 0.33 * 0.3
    assert uncertainty_magnification([None, None], 0.3) is None
    assert uncertainty_magnification([np.eye(6)], 0.3)[0] == 1.0   # already visible


def test_stamps_that_are_image_places_are_told_from_times():
    assert stamps_are_indices(np.arange(8.0))            # poses matched by name
    assert not stamps_are_indices(1.7e9 + 0.25 * np.arange(8))
    assert not stamps_are_indices(0.1 + np.arange(8.0))


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_rig_uses_the_users_frame_names_and_draws_uncertainty(setup, tmp_path):
    run, _ = make_run(tmp_path, setup, noise=1e-3)
    details = write_run_details(tmp_path / "details.json", run)
    roles = ("world", "marker") if setup == "eye-to-base" else ("world", "body")
    frames = dict(zip(roles, ("base", "tool0")))
    rec = dataclasses.replace(run.record, frames=frames)
    assert _scene(rec, details).frame == "base"
    figures = rig_pngs(rec, details)
    assert sorted(figures.pngs) == ["rig_3d.png", "rig_top.png"]
    legend = " ".join(figures.legend)
    assert "T_base_tool0" in legend and "world" not in legend
    # uncertainty: drawn when the record has it, said when not
    x_key = "T_world_cam" if setup == "eye-to-base" else "T_body_cam"
    C = np.diag([1e-6, 1e-6, 1e-6, 1e-7, 1e-7, 1e-7])
    unc = {x_key: PoseUncertainty(0.1, 0.5e-3, C)}
    with_unc = dataclasses.replace(rec, cameras=tuple(
        dataclasses.replace(c, uncertainty=unc) for c in rec.cameras))
    assert "3σ position ellipsoid" in " ".join(rig_pngs(with_unc, details).legend)
    without = dataclasses.replace(rec, cameras=tuple(
        dataclasses.replace(c, uncertainty=None) for c in rec.cameras))
    assert "no uncertainty drawn" in " ".join(rig_pngs(without, details).legend)
    if setup == "eye-on-hand":   # X's covariance is in the body frame: drawn in the world
        R = details.T_world_body_shown[:3, :3]
        C_body = np.zeros((6, 6))
        C_body[3:, 3:] = np.diag([1e-6, 0, 0])
        unc = {x_key: PoseUncertainty(0.0, 1e-3, C_body)}
        one = dataclasses.replace(rec, cameras=tuple(
            dataclasses.replace(c, uncertainty=unc) for c in rec.cameras))
        drawn = _scene(one, details).covariances[0][3:, 3:]
        np.testing.assert_allclose(drawn, R @ np.diag([1e-6, 0, 0]) @ R.T, atol=1e-15)


def test_detections_are_drawn_on_the_pixels(tmp_path):
    image = np.full((480, 640), 40, np.uint8)
    image[200:280, 300:340] = 220                       # a bright patch where the points are
    path = tmp_path / "1.5.png"
    cv2.imwrite(str(path), image)
    uv = np.array([[310.0, 210.0], [330.0, 270.0], [320.0, 240.0]])
    res = np.array([[0.5, 0.0], [0.0, -0.5], [np.nan, np.nan]])
    jpeg = residual_thumbnail(path, uv, res, magnify=40.0, max_width=480)
    pic = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    x0, y0, x1, y1 = crop_box(uv, 640, 480)
    assert (x0, y0) == (192, 144) and (x1, y1) == (448, 336)   # 40 % of the image around them
    assert pic.shape[:2] == (y1 - y0, x1 - x0)                  # never enlarged
    def colour_near(p, bgr, r=4):     # a pixel of that hue near p (the picture is grey)
        x, y = int(round(p[0] - x0)), int(round(p[1] - y0))
        patch = pic[y - r:y + r + 1, x - r:x + r + 1].reshape(-1, 3).astype(int)
        low = int(np.argmin(bgr))         # the channel the colour lacks
        others = [k for k in range(3) if k != low]
        return bool(np.any(patch[:, others].min(axis=1) - patch[:, low] > 50))
    assert POINT_BGR[2] == min(POINT_BGR) and RESIDUAL_BGR[1] == min(RESIDUAL_BGR)
    for p in uv[:2]:
        assert colour_near(p, POINT_BGR)
    assert colour_near(uv[0] + [20.0, 0.0], RESIDUAL_BGR)        # 0.5 px x 40 to the right
    assert colour_near(uv[1] + [0.0, -20.0], RESIDUAL_BGR)       # and up
    assert not colour_near(uv[0] + [-20.0, 0.0], RESIDUAL_BGR)   # not the other way
    assert not colour_near([260.0, 180.0], POINT_BGR)            # nothing where no point is
    # the grey image is still there, lighter where it was bright
    assert pic[5, 5].mean() < pic[int(240 - y0), int(305 - x0)].mean()
    assert residual_thumbnail(path, uv, res, magnify=1.0, image_size=(800, 600)) is None
    assert residual_thumbnail(tmp_path / "gone.png", uv, res, magnify=1.0) is None
    (tmp_path / "bad.png").write_bytes(b"not an image")
    assert residual_thumbnail(tmp_path / "bad.png", uv, res, magnify=1.0) is None
