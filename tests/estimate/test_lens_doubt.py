"""Issue 33, item 4, in rigs without motion capture (estimate.lens_doubt): a lens given
without its distortion, or with one far weaker than the images show, is named even when it
fits its views within 0.5 px (it was not tested below that: exit status 0, the camera 8 mm
off on a rendered overlap rig); a right lens, with or without distortion, is not doubted."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.estimate.lens_doubt import given_lens_findings, lens_message
from multieye.estimate.lens_freed import lens_bend, lens_search
from multieye.estimate.plausibility import CameraEvidence
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import estimate_pose

_K = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])


def _board() -> np.ndarray:
    x, y = np.meshgrid(np.arange(9) * 0.05, np.arange(6) * 0.05)
    return np.stack([x.ravel() - 0.2, y.ravel() - 0.125, np.zeros(54)], axis=1)


def _camera(truth: Intrinsics, given: Intrinsics, seed: int, views: int = 12) -> CameraEvidence:
    """A camera of a rig without motion capture: the rig's board poses in the reference
    camera (``A`` = inv(T_ref_target), from the other cameras: exact here) and this camera's
    PnP poses with the ``given`` lens of pixels made by the ``truth`` (0.1 px noise)."""
    rng = np.random.default_rng(seed)
    obj = _board()
    T_ref_cam = g.transform_from_rotvec([0.0, 0.6, 0.0], [-0.67, 0.0, 0.2])
    M, B, img, rms = [], [], [], []
    for _ in range(views):
        T = g.transform_from_rotvec(rng.uniform(-0.4, 0.4, 3),
                                    [*rng.uniform(-0.15, 0.15, 2), rng.uniform(0.6, 0.9)])
        u = project_points(obj @ T[:3, :3].T + T[:3, 3], truth) + rng.normal(
            scale=0.1, size=(len(obj), 2))
        est = estimate_pose(Detection(np.arange(len(obj)), u, obj), given)
        M.append(T_ref_cam @ T)
        B.append(g.inv(est.T_cam_target))
        img.append(u)
        rms.append(est.rms_px)
    M = np.stack(M)
    return CameraEvidence("cam1", g.inv(M), np.stack(B), M, intrinsics=given,
                          object_points=(obj,) * views, image_points=tuple(img),
                          rms_px=np.array(rms))


def _lens(dist) -> Intrinsics:
    return Intrinsics(K=_K, dist=np.asarray(dist, dtype=np.float64), width=640, height=480)


@pytest.mark.parametrize("k1, given", [(-0.05, np.zeros(5)), (-0.17, np.zeros(4)),
                                       (-0.4, np.zeros(0))])
def test_a_lens_given_without_distortion_is_named(k1, given):
    """k1 from -0.05 to -0.4 left out (zeros, or none): the finding names the camera, the
    missing distortion, the residuals before and after, and how to estimate the lens. At k1
    -0.05 the given lens leaves under 0.5 px in its median view, and was not freed before
    (no finding, exit status 0)."""
    cam = _camera(_lens([k1, 0.3 * k1 ** 2, 0, 0]), _lens(given), seed=1)
    assert (np.median(cam.rms_px) < 0.5) == (k1 == -0.05)
    found = given_lens_findings([cam])
    assert [f.cause for f in found] == ["intrinsics"], found
    m = found[0].message
    for w in ("camera cam1", "distortion none -> k1", "left out of the intrinsics file",
              "mean pose residual against the rig", "model: instead of intrinsics:"):
        assert w in m, m
    e = found[0].evidence
    assert e["loop_freed_deg"] < e["loop_given_deg"] and e["loop_freed_m"] < e["loop_given_m"]
    assert e["rms_freed_px"] < 0.16          # the 0.1 px per axis of the noise


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("dist", [np.zeros(5), [-0.17, 0.0087, 0.0, 0.0, 0.0]])
def test_the_right_lens_is_not_doubted(seed, dist):
    """False-alarm rate over seeds: the right lens (without distortion, or with k1 -0.17)
    given, 0.1 px noise: no finding on any seed."""
    lens = _lens(dist)
    assert given_lens_findings([_camera(lens, lens, seed)]) == ()


def test_a_distortion_far_weaker_than_the_images_show_is_named_so():
    """k1 -0.2 given as -0.05 (a quarter): named as a far weaker distortion than the images
    show, with how far each lens bends the rays; before, as a lens of another camera."""
    truth = _lens([-0.2, 0.012, 0, 0])
    cam = _camera(truth, _lens([-0.05, 0.003, 0, 0]), seed=2)
    found = given_lens_findings([cam])
    assert [f.cause for f in found] == ["intrinsics"], found
    m = found[0].message
    assert "far weaker lens distortion than these images show" in m, m
    assert "do not belong" not in m
    pixels = np.concatenate(cam.image_points)
    assert lens_bend(pixels, cam.intrinsics) < 0.5 * lens_bend(pixels, truth)


def test_another_cameras_lens_keeps_its_own_cause():
    """A focal length 8 % off is not a weak distortion: the message keeps 'do not belong'."""
    truth = _lens([-0.2, 0.012, 0, 0])
    other = Intrinsics(K=_K * [[1.08], [1.08], [1]], dist=truth.dist, width=640, height=480)
    cam = _camera(truth, other, seed=3)
    test = lens_search(cam, (1e-3, 1e-3))
    assert test is not None
    assert "do not belong to these images" in lens_message(cam, test, loop=False).message


def test_lens_bend_of_a_plain_pinhole_is_zero_and_grows_with_k1():
    uv = np.array([[600.0, 450.0], [40.0, 30.0], [319.5, 239.5]])
    assert lens_bend(uv, _lens(np.zeros(5))) == pytest.approx(0.0, abs=1e-4)
    assert lens_bend(uv, _lens([-0.1, 0, 0, 0])) < lens_bend(uv, _lens([-0.3, 0, 0, 0]))


@pytest.mark.parametrize("model, truth, start", [
    ("pinhole", [-0.2, 0.05, 0.001, -0.0005, 0.0], [0.0, 0.0, 0.001, -0.0005, 0.0]),
    ("fisheye", [0.05, -0.01, 0.002, 0.0], [0.0, 0.0, 0.002, 0.0]),
])
def test_free_distortion_recovers_k1_k2_exactly_without_noise(model, truth, start):
    """Noise-free pixels, the poses started 1 degree and 1 cm off: k1 and k2 (and every
    pose) recovered to 1e-7, the other coefficients kept as given."""
    from multieye.estimate.lens_freed import free_distortion

    rng = np.random.default_rng(5)
    lens = Intrinsics(K=_K, dist=np.array(truth), model=model, width=640, height=480)
    obj, views, starts = _board(), [], []
    for _ in range(6):
        T = g.transform_from_rotvec(rng.uniform(-0.4, 0.4, 3),
                                    [*rng.uniform(-0.15, 0.15, 2), rng.uniform(0.5, 0.8)])
        views.append((obj, project_points(obj @ T[:3, :3].T + T[:3, 3], lens)))
        starts.append(g.transform_from_rotvec(rng.normal(scale=0.01, size=3),
                                              rng.normal(scale=0.01, size=3)) @ T)
    given = Intrinsics(K=_K, dist=np.array(start, dtype=float), model=model, width=640,
                       height=480)
    freed = free_distortion(views, np.stack(starts), given)
    assert freed is not None
    assert np.allclose(freed.dist[:2], truth[:2], atol=1e-7), freed.dist
    assert np.array_equal(freed.dist[2:], given.dist[2:]) and np.array_equal(freed.K, _K)


def test_a_mild_distortion_left_out_is_named_under_robot_noise():
    """Motion capture of a robot's 0.1 deg / 1 mm and k1 -0.05 left out: the given lens
    leaves 0.19 px and its loop fits that noise, so the lens was not freed (no finding,
    exit status 0); now k1 and k2 are refitted and the finding gives the mean loop residual
    before and after. The right lens, and its distortion given, raise none."""
    from plausibility_cases import _board as board
    from plausibility_cases import _stream, _with_intrinsics

    from multieye.estimate.plausibility import check_plausibility

    lens = _lens([-0.05, 0.0, 0.0, 0.0, 0.0])
    st, obj = _stream(61), board()
    rng = np.random.default_rng(3)
    img = [project_points(obj @ T[:3, :3].T + T[:3, 3], lens)
           + rng.normal(scale=0.1, size=(len(obj), 2)) for T in st.T_cam_target]
    robot = {"mocap_rot_sigma_rad": np.radians(0.1), "mocap_trans_sigma_m": 0.001}
    for given, causes in ((np.zeros(5), ["intrinsics"]), (lens.dist, [])):
        rep = check_plausibility([_with_intrinsics(st, obj, img, _lens(given))], clock=False,
                                 **robot)
        assert [f.cause for f in rep.findings] == causes, rep.findings
    m = check_plausibility([_with_intrinsics(st, obj, img, _lens(np.zeros(5)))], clock=False,
                           **robot).findings[0].message
    assert "mean loop residual" in m and "left out of the intrinsics file" in m, m


def _wide_camera(truth: Intrinsics, given: Intrinsics, fov: float, seed: int) -> CameraEvidence:
    """:func:`_camera` for a wide lens: 12 views spread over its field (0.2 px noise)."""
    from multieye.sim.wide_lens import board_views

    views, T = board_views(truth, fov, 12, np.random.default_rng(seed))
    T_ref_cam = g.transform_from_rotvec([0.0, 0.6, 0.0], [-0.67, 0.0, 0.2])
    B, rms = [], []
    for o, u in views:
        est = estimate_pose(Detection(np.arange(len(o)), u, o), given)
        B.append(g.inv(est.T_cam_target))
        rms.append(est.rms_px)
    M = T_ref_cam @ T
    return CameraEvidence("cam1", g.inv(M), np.stack(B), M, intrinsics=given,
                          object_points=tuple(o for o, _ in views),
                          image_points=tuple(u for _, u in views), rms_px=np.array(rms))


@pytest.mark.parametrize("scale, cause", [(0.0, "left out of the intrinsics file"),
                                          (0.25, "far weaker lens distortion")])
def test_a_unified_lens_without_its_radial_tangential_part_is_named(scale, cause):
    """A 190-degree unified lens (xi 1.1, k1 -0.08) given as Kalibr's omni with radtan
    [0, 0, 0, 0] (or a quarter of it): named with xi kept and the distortion missing (or
    far weaker); before, as a lens of another camera whose 'k1' was xi."""
    from multieye.sim.wide_lens import wide_lens

    truth = wide_lens("unified", 190.0)
    dist = truth.dist.copy()
    dist[1:] *= scale
    given = Intrinsics(K=truth.K, dist=dist, model="unified", width=truth.width,
                       height=truth.height)
    found = given_lens_findings([_wide_camera(truth, given, 190.0, 1)])
    assert [f.cause for f in found] == ["intrinsics"], found
    m = found[0].message
    assert cause in m and "do not belong" not in m, m
    assert "-> xi 1.1, k1 -0.0" in m, m
    assert ("distortion xi 1.1, no k1 k2 p1 p2 ->" in m) == (scale == 0.0), m


@pytest.mark.parametrize("model, fov", [("unified", 190.0), ("double-sphere", 220.0),
                                        ("eucm", 190.0), ("fisheye", 170.0)])
def test_a_right_wide_lens_is_not_doubted(model, fov):
    from multieye.sim.wide_lens import wide_lens

    truth = wide_lens(model, fov)
    for seed in range(3):
        assert given_lens_findings([_wide_camera(truth, truth, fov, 100 + seed)]) == ()


@pytest.mark.parametrize("seed", range(3))
def test_a_camera_alone_is_judged_on_its_pixels(seed):
    """One camera without motion capture: its board poses are its own PnP poses, so the
    message showed pose residuals that grew with the right distortion (0.08 deg -> 4.3 deg
    on boofcv_stereo's left camera alone); now none are shown, a distortion left out is
    named on the pixels, and the right lens is left alone."""
    truth = _lens([-0.05, 0.00075, 0, 0])
    cam = _camera(truth, _lens(np.zeros(5)), seed=seed)
    # alone, the rig's board poses are the camera's own
    cam = replace(cam, A=cam.B.copy(), T_world_mocap=g.inv(cam.B))
    found = given_lens_findings([cam], alone=True)
    assert [f.cause for f in found] == ["intrinsics"], found
    m = found[0].message
    assert "pose residual" not in m and "left out of the intrinsics file" in m, m
    right = _camera(truth, truth, seed=seed)
    assert given_lens_findings([replace(right, A=right.B.copy())], alone=True) == ()


def test_a_fisheye_given_without_its_mild_distortion_is_named():
    """A fisheye (k1 0.05) given with k1..k4 zero: the PnP poses absorb the distortion, so
    the RMS barely drops (1.01 times) while the camera's pose residuals against the rig halve;
    named (before: a given lens under 0.5 px was not tested; then the RMS had to drop 1.05
    times)."""
    K = np.array([[230.0, 0.0, 319.5], [0.0, 230.0, 239.5], [0.0, 0.0, 1.0]])
    truth = Intrinsics(K=K, dist=np.array([0.05, -0.01, 0.002, -0.0005]), model="fisheye",
                       width=640, height=480)
    given = Intrinsics(K=K, dist=np.zeros(4), model="fisheye", width=640, height=480)
    for seed in range(2):
        found = given_lens_findings([_camera(truth, given, seed=10 + seed)])
        assert [f.cause for f in found] == ["intrinsics"], found
        assert "left out of the intrinsics file" in found[0].message
        assert given_lens_findings([_camera(truth, truth, seed=10 + seed)]) == ()
