"""Intrinsics estimated in the joint image-level problem: Jacobians, exact recovery from a
wrong start, images that only inform the intrinsics, and honest covariance (NEES)."""

from __future__ import annotations

import numpy as np
import pytest

import multieye
from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.estimate.image_data import ImageProblem, image_data
from multieye.estimate.image_residuals import intrinsics_family
from multieye.estimate.refine_images import refine_images
from multieye.optimize.gradient_check import numerical_jacobians
from multieye.sim.images import simulate_images

RATIONAL = Intrinsics(K=[[700.0, 0, 640.5], [0, 702.0, 478.0], [0, 0, 1]],
                      dist=[-0.1, 0.02, 1e-3, -5e-4, 0.002, 0.01, -0.002, 0.001],
                      width=1280, height=960)


def _wrong(intr: Intrinsics, rng, focal=0.02, centre=5.0) -> Intrinsics:
    """Intrinsics a few percent and pixels off, distortion zeroed (a wide-angle model's own
    parameters a tenth off instead)."""
    p = intr.params.copy()
    p[:2] *= 1 + rng.uniform(-focal, focal, 2)
    p[2:4] += rng.uniform(-centre, centre, 2)
    if intr.model in ("double-sphere", "eucm"):
        p[4:] *= 0.9
    else:
        p[4 + (intr.model == "unified"):] = 0.0
        p[4] *= 0.9 if intr.model == "unified" else 1.0
    return intr.with_params(p)


def _moved(T, rng, rot=0.01, trans=0.01):
    n = np.shape(T)[:-2] + (3,)
    return g.transform_from_rotvec(rng.normal(scale=rot, size=n),
                                   rng.normal(scale=trans, size=n)) @ T


def _free_images(sc, j, k, rng):
    """k images of camera j's board at new poses, without motion capture (noise-free)."""
    out = []
    for T in _moved(sc.T_cam_target[j][:k], rng, rot=0.2, trans=0.05):
        pc = sc.object_points @ T[:3, :3].T + T[:3, 3]
        out.append((sc.object_points, project_points(pc, sc.intrinsics[j]), T))
    return out


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_jacobians_with_intrinsics_match_central_differences(setup, rng):
    sc = simulate_images(3, n_cameras=2, images=3, setup=setup,
                         intrinsics=[RATIONAL, simulate_images(0).intrinsics[0]])
    fisheye = simulate_images(3, n_cameras=1, images=3, setup=setup, model="fisheye")
    wide = simulate_images(3, n_cameras=3, images=3, setup=setup, intrinsics=[
        simulate_images(0, model=m).intrinsics[0] for m in ("unified", "double-sphere", "eucm")])
    for scene in (sc, fisheye, wide):
        extra = [_free_images(scene, j, 2, rng) for j in range(scene.n_cameras)]
        data = image_data(ImageProblem(setup, scene.observations, scene.intrinsics,
                         free_intrinsics=[True] * scene.n_cameras, intrinsics_observations=extra))
        fams = data.families(_moved(scene.X, rng), _moved(scene.Y, rng),
                             _moved(data.mocap_measured, rng),
                             free_poses=_moved(data.extra.poses, rng))
        values = {f.name: f.value for f in fams}
        groups = data.groups(0.3, 1e-3, 3e-4)
        assert any(intrinsics_family("cam0") in grp.slots for grp in groups)
        for grp in groups:
            _, analytic = grp.evaluate(values, True)
            for a, n in zip(analytic, numerical_jacobians(fams, grp, step=1e-7)):
                scale = np.abs(n).max()
                assert np.abs(a - n).max() <= 1e-5 * scale, grp.slots


@pytest.mark.parametrize("setup, model", [("eye-to-base", "pinhole"), ("eye-on-hand", "fisheye"),
                                          ("eye-to-base", "rational"),
                                          ("eye-to-base", "unified"),
                                          ("eye-on-hand", "double-sphere"),
                                          ("eye-to-base", "eucm")])
def test_exact_recovery_of_intrinsics_and_extrinsics_from_a_wrong_start(setup, model, rng):
    kw = dict(intrinsics=[RATIONAL] * 3) if model == "rational" else dict(model=model)
    sc = simulate_images(5, n_cameras=3, images=15, setup=setup, pixel_sigma=0.0,
                         mocap_rot_sigma_rad=0.0, mocap_trans_sigma_m=0.0, **kw)
    start = [_wrong(k, rng) for k in sc.intrinsics]
    res = refine_images(setup, sc.observations, start, _moved(sc.X, rng), _moved(sc.Y, rng),
                        pixel_sigma=0.1, loss="linear", free_intrinsics=[True] * 3, tol=1e-14,
                        max_iter=200)
    rays = np.column_stack([np.tan(np.radians(np.random.default_rng(0).uniform(
        [-35, -25], [35, 25], size=(200, 2)))), np.ones(200)])   # inside the observed area
    # the rational lens's denominator prior (DenominatorPrior) draws k4..k6 towards 0 by a
    # prior of 1 at the image's edge: on noise-free data stated at 0.1 px that moves the
    # projection by up to 9e-5 px and the poses by 8e-8 (0 for the other models)
    exact = 1e-4 if model == "rational" else 1e-6
    for got, true in zip(res.intrinsics, sc.intrinsics):
        assert np.abs(project_points(rays, got) - project_points(rays, true)).max() < exact
        if model != "rational":   # (its 6 radial terms are not separable over +-40 degrees)
            np.testing.assert_allclose(got.params, true.params, rtol=0, atol=1e-6)
    assert np.abs(res.X - sc.X).max() < exact / 100
    assert np.abs(res.Y - sc.Y).max() < exact / 100
    assert all(c.shape == (k.params.size,) * 2 for c, k in zip(res.intrinsics_covariance,
                                                                 res.intrinsics))


def test_images_without_motion_capture_inform_the_intrinsics(rng):
    """A camera with few motion-captured images: extra images of the board alone shrink the
    intrinsics' uncertainty, and recovery stays exact."""
    sc = simulate_images(7, n_cameras=2, images=6, pixel_sigma=0.0, mocap_rot_sigma_rad=0.0,
                         mocap_trans_sigma_m=0.0)
    start = [_wrong(k, rng) for k in sc.intrinsics]
    kw = dict(pixel_sigma=0.3, loss="linear", free_intrinsics=[True, True], tol=1e-14,
              max_iter=200)
    plain = refine_images(sc.setup, sc.observations, start, sc.X, sc.Y, **kw)
    extra = [_free_images(sc, 0, 6, rng), []]
    more = refine_images(sc.setup, sc.observations, start, sc.X, sc.Y,
                         intrinsics_observations=extra, **kw)
    np.testing.assert_allclose(more.intrinsics[0].params, sc.intrinsics[0].params, atol=1e-6)
    var_plain = np.diag(plain.intrinsics_covariance[0])
    var_more = np.diag(more.intrinsics_covariance[0])
    assert np.all(var_more < var_plain)
    assert np.all(np.diag(more.intrinsics_covariance[1]) <= np.diag(
        plain.intrinsics_covariance[1]) * 1.0001)


def test_covariance_of_intrinsics_x_and_y_is_honest():
    """Normalised estimation error squared over repeated noisy rigs: its mean per dimension
    is about 1 when the covariance is right (0.5-2 required), for the intrinsics, X and Y."""
    nees = {"intrinsics": [], "X": [], "Y": []}
    for t in range(24):
        sc = simulate_images(np.random.default_rng([3, t]), n_cameras=2, images=12,
                             noise_rng=np.random.default_rng([4, t]), pixel_sigma=0.5)
        sol = multieye.solve(sc.A, sc.B)
        res = refine_images(sc.setup, sc.observations, sc.intrinsics, sol.X, sol.Y,
                            pixel_sigma=0.5, mocap_rot_sigma_rad=sc.mocap_rot_sigma_rad,
                            mocap_trans_sigma_m=sc.mocap_trans_sigma_m, loss="linear",
                            free_intrinsics=[True, True])
        for j in range(2):
            e = res.intrinsics[j].params - sc.intrinsics[j].params
            nees["intrinsics"].append(e @ np.linalg.solve(res.intrinsics_covariance[j], e) / e.size)
        err = [(res.X[j], sc.X[j], res.covariance[6 * j:6 * j + 6, 6 * j:6 * j + 6])
               for j in range(2)] + [(res.Y, sc.Y, res.covariance[12:18, 12:18])]
        for k, (T, T_true, C) in enumerate(err):
            e = np.concatenate([_left(T, T_true), T[:3, 3] - T_true[:3, 3]])
            nees["X" if k < 2 else "Y"].append(e @ np.linalg.solve(C, e) / 6)
    for name, values in nees.items():
        assert 0.5 < np.mean(values) < 2.0, (name, np.mean(values))


def _left(T, T_true):
    """Rotation vector phi with R = Exp(phi) R_true."""
    return g.rotvec_from_transform(g.make_transform(T[:3, :3] @ T_true[:3, :3].T, np.zeros(3)))
