"""The wide-angle lens models (multieye.core.lens_wide through multieye.core.lens): analytic
Jacobians against central differences, project/unproject round trips over the whole valid
region (rays beyond 90 degrees included), NaN outside it, the models' identities, and the
published formulas written out independently."""

import numpy as np
import pytest

from multieye.core.errors import InputError
from multieye.core.intrinsics import (
    LENS_MODELS, Intrinsics, check_lens_bounds, lens_model, parameter_names)
from multieye.core.lens import (
    project_points, project_with_jacobian, projectable, undistort_points, unproject_points)

K = [[400.0, 0.0, 320.0], [0.0, 410.0, 300.0], [0.0, 0.0, 1.0]]

#: (model, dist): xi below and above 1, negative double-sphere xi (TUM VI's Basalt lenses
#: have xi about -0.17, alpha 0.59), alpha on both sides of 1/2, beta on both sides of 1.
LENSES = [
    ("unified", [0.8, -0.1, 0.02, 0.001, -0.002]),
    ("unified", [1.4, -0.05, 0.004, 0.001, -0.002]),
    ("unified", [0.0, -0.2, 0.05, 0.001, 0.002]),
    ("double-sphere", [-0.17, 0.59]),
    ("double-sphere", [0.5, 0.3]),
    ("double-sphere", [0.9, 0.2]),
    ("double-sphere", [1.5, 0.6]),
    ("eucm", [0.6, 1.1]),
    ("eucm", [0.3, 0.8]),
    ("eucm", [0.9, 1.7]),
]
IDS = [f"{m}-{'_'.join(f'{v:g}' for v in d[:2])}" for m, d in LENSES]


def _lens(model, dist):
    return Intrinsics(K=K, dist=dist, model=model)


def _sphere(n, seed=0):
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1)[:, None]


def _region_w(cam):
    """w of the region z > -w d, found independently of the library: the largest angle up
    to which the model's radius grows along a meridian (with a positive denominator)."""
    th = np.linspace(0.0, np.pi, 400001)[1:-1]
    P = np.column_stack([np.sin(th), np.zeros_like(th), np.cos(th)])
    undistorted = Intrinsics(K=cam.K, dist=np.r_[cam.dist[:1], 0, 0, 0, 0], model="unified") \
        if cam.model == "unified" else cam
    r, D = _reference(P, undistorted)
    bad = np.flatnonzero((np.diff(r) <= 0) | ~(D[1:] > 0))
    if not len(bad):
        return 1.0
    t = th[bad[0]]
    beta = cam.dist[1] if cam.model == "eucm" else 1.0
    return -np.cos(t) / np.sqrt(beta * np.sin(t) ** 2 + np.cos(t) ** 2)


def _reference(P, cam):
    """Radius (x only, y = 0 points) and denominator, written from the papers' formulas."""
    x, y, z = P.T
    if cam.model == "unified":
        xi = cam.dist[0]
        D = z + xi * np.sqrt(x * x + y * y + z * z)
    elif cam.model == "double-sphere":
        xi, a = cam.dist
        d1 = np.sqrt(x * x + y * y + z * z)
        d2 = np.sqrt(x * x + y * y + (xi * d1 + z) ** 2)
        D = a * d2 + (1 - a) * (xi * d1 + z)
    else:
        a, b = cam.dist
        D = a * np.sqrt(b * (x * x + y * y) + z * z) + (1 - a) * z
    return x / D, D


@pytest.mark.parametrize("model,dist", LENSES, ids=IDS)
def test_valid_region_is_where_the_model_is_one_to_one(model, dist):
    cam = _lens(model, dist)
    w = _region_w(cam)
    v = _sphere(40000, seed=1)
    d = np.sqrt(dist[1] * (v[:, 0] ** 2 + v[:, 1] ** 2) + v[:, 2] ** 2) if model == "eucm" \
        else np.ones(len(v))
    c = v[:, 2] / d
    ok = projectable(v, cam)
    clear = np.abs(c + w) > 1e-4                 # the meridian scan's resolution
    assert np.array_equal(ok[clear], (c > -w)[clear])
    uv = project_points(v, cam)
    assert np.all(np.isfinite(uv[ok])) and np.all(np.isnan(uv[~ok]))
    uv, jp, ji = project_with_jacobian(v, cam)
    assert np.all(np.isnan(uv[~ok])) and np.all(np.isnan(jp[~ok])) and np.all(np.isnan(ji[~ok]))
    assert w < 0.01 or np.any(ok & (v[:, 2] < -w / 2))   # wide: rays beyond 90 degrees
    assert not np.any(projectable(np.array([[0.0, 0, 0], [np.nan, 0, 1], [0, 0, -1]]), cam))


@pytest.mark.parametrize("model,dist", LENSES, ids=IDS)
def test_jacobians_match_central_differences(model, dist):
    cam = _lens(model, dist)
    v = _sphere(3000, seed=2)
    w = _region_w(cam)
    d = np.sqrt(dist[1] * (v[:, 0] ** 2 + v[:, 1] ** 2) + v[:, 2] ** 2) if model == "eucm" \
        else np.ones(len(v))
    P = 3.0 * v[v[:, 2] / d > -w + 0.05]          # away from the boundary, where D -> 0,
    P = P[np.abs(project_points(P, cam)).max(axis=1) < 1e4][:300]   # and within 1e4 px
    uv, jp, ji = project_with_jacobian(P, cam)
    assert np.all(np.isfinite(jp)) and ji.shape == (len(P), 2, 4 + len(dist))
    h = 1e-6
    num = np.stack([(project_points(P + h * e, cam) - project_points(P - h * e, cam)) / (2 * h)
                    for e in np.eye(3)], axis=2)
    scale = np.abs(jp).max(axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(jp / scale, num / scale, atol=1e-6)
    p = cam.params
    for i, name in enumerate(parameter_names(cam)):
        step = np.zeros(p.size)
        step[i] = 1e-6 * max(1.0, abs(p[i]))
        if name == "xi" and p[i] == 0:          # xi >= 0: a one-sided second-order difference
            f0, f1, f2 = (project_points(P, cam.with_params(p + j * step)) for j in range(3))
            d_uv = (-3 * f0 + 4 * f1 - f2) / (2 * step[i])
        else:
            d_uv = (project_points(P, cam.with_params(p + step))
                    - project_points(P, cam.with_params(p - step))) / (2 * step[i])
        s = max(1.0, np.abs(ji[:, :, i]).max())
        np.testing.assert_allclose(ji[:, :, i] / s, d_uv / s, atol=1e-6, err_msg=name)
    _, jp2, none = project_with_jacobian(P, cam, lens_jacobian=False)
    assert none is None and np.array_equal(jp2, jp)


@pytest.mark.parametrize("model,dist", LENSES, ids=IDS)
def test_project_unproject_round_trip_over_the_whole_region(model, dist):
    cam = _lens(model, dist)
    if model == "unified":       # the distortion polynomial folds back far out: test the
        cam = _lens(model, [dist[0], 0, 0, 0, 0])   # model's region without it (and with
    v = _sphere(50000, seed=3)                      # it below)
    ok = projectable(v, cam)
    uv = project_points(v, cam)
    back = unproject_points(uv[ok], cam)
    err = np.linalg.norm(back - v[ok], axis=1)
    # near the boundary the model compresses rays into a pixel (at alpha > 1/2 the radius is
    # stationary there), so the ray is as sensitive as 1/derivative: hold 1e-9 to 1e-3 (in
    # cos) inside it, and finite everywhere
    w = _region_w(cam)
    d = np.sqrt(dist[1] * (v[ok, 0] ** 2 + v[ok, 1] ** 2) + v[ok, 2] ** 2) if model == "eucm" \
        else 1.0
    inner = v[ok, 2] / d > -w + 1e-3
    assert np.all(np.isfinite(err))
    assert err[inner].max() < 1e-9
    assert w < 0.01 or np.any(v[ok][inner][:, 2] < -w / 2)
    np.testing.assert_allclose(project_points(back, cam), uv[ok], atol=1e-6)


def test_unified_distortion_round_trip_and_the_fold():
    cam = _lens("unified", [1.1331346732794045, -0.24972089525362837, 0.009672326567075125,
                            0.001, -0.0005])     # BoofCV's fisheye (tangential added)
    th = np.radians(np.linspace(0, 100, 201))       # up to 100 degrees off axis
    ph = np.linspace(0, 2 * np.pi, 37)
    T, F = np.meshgrid(th, ph)
    v = np.column_stack([(np.sin(T) * np.cos(F)).ravel(), (np.sin(T) * np.sin(F)).ravel(),
                         np.cos(T).ravel()])
    uv = project_points(v, cam)
    back = unproject_points(uv, cam)
    assert np.linalg.norm(back - v, axis=1).max() < 1e-9
    # pixels of the image's edge whose distorted radius no undistorted radius reaches: NaN
    assert np.all(np.isnan(unproject_points([[320 + 1e4, 300.0]], cam)))


@pytest.mark.parametrize("model,dist", LENSES, ids=IDS)
def test_undistort_points_is_the_ray_in_front(model, dist):
    cam = _lens(model, [dist[0], 0, 0, 0, 0] if model == "unified" else dist)
    v = _sphere(2000, seed=4)
    v = v[projectable(v, cam) & (np.abs(v[:, 2]) > 0.05)]
    uv = project_points(v, cam)
    xy = undistort_points(uv, cam)
    front = v[:, 2] > 0
    np.testing.assert_allclose(xy[front], v[front, :2] / v[front, 2:3], rtol=1e-7, atol=1e-9)
    assert np.all(np.isnan(xy[~front]))


def test_identities_between_models():
    v = _sphere(3000, seed=5)
    v = v[v[:, 2] > 0.3]
    pin = Intrinsics(K=K, dist=[-0.2, 0.05, 0.001, 0.002])
    np.testing.assert_allclose(project_points(v, _lens("unified", [0.0, -0.2, 0.05, 0.001,
                                                                   0.002])),
                               project_points(v, pin), rtol=0, atol=1e-9)
    np.testing.assert_allclose(project_points(v, _lens("eucm", [0.0, 1.7])),
                               project_points(v, Intrinsics(K=K)), atol=1e-9)
    v = _sphere(3000, seed=6)
    for alpha in (0.2, 0.5, 0.7):
        ucm = _lens("eucm", [alpha, 1.0])
        ok = projectable(v, ucm)
        ds = _lens("double-sphere", [0.0, alpha])
        assert np.array_equal(projectable(v, ds), ok)
        np.testing.assert_allclose(project_points(v[ok], ds), project_points(v[ok], ucm),
                                   atol=1e-9)
        xi = alpha / (1 - alpha)
        Ku = np.array(K)
        Ku[0, 0], Ku[1, 1] = K[0][0] / (1 - alpha), K[1][1] / (1 - alpha)
        uni = Intrinsics(K=Ku, dist=[xi, 0, 0, 0, 0], model="unified")
        assert np.array_equal(projectable(v, uni), ok)
        np.testing.assert_allclose(project_points(v[ok], uni), project_points(v[ok], ucm),
                                   atol=1e-8)
    # the double sphere with alpha = 0 is the undistorted unified model, region included
    for xi in (0.4, 1.0, 1.6):
        ds = _lens("double-sphere", [xi, 0.0])
        uni = _lens("unified", [xi, 0, 0, 0, 0])
        assert np.array_equal(projectable(v, ds), projectable(v, uni))
        ok = projectable(v, uni)
        np.testing.assert_allclose(project_points(v[ok], ds), project_points(v[ok], uni),
                                   atol=1e-9)


def test_against_published_numbers():
    """Closed forms written out by hand for one point each (Kalibr's omni with radtan,
    Usenko's eq. (40)-(42), Khomutenko's eucm)."""
    X = np.array([[0.3, -0.2, 0.5]])
    n = np.sqrt(0.38)
    xi, k1, k2, p1, p2 = 1.2, -0.1, 0.01, 0.002, -0.001
    mx, my = 0.3 / (0.5 + xi * n), -0.2 / (0.5 + xi * n)
    r2 = mx * mx + my * my
    c = 1 + k1 * r2 + k2 * r2 * r2
    dx = mx * c + 2 * p1 * mx * my + p2 * (r2 + 2 * mx * mx)
    dy = my * c + p1 * (r2 + 2 * my * my) + 2 * p2 * mx * my
    np.testing.assert_allclose(project_points(X, _lens("unified", [xi, k1, k2, p1, p2])),
                               [[400 * dx + 320, 410 * dy + 300]], rtol=1e-13)
    xi, a = 0.4, 0.6
    k = xi * n + 0.5
    D = a * np.sqrt(0.13 + k * k) + (1 - a) * k
    np.testing.assert_allclose(project_points(X, _lens("double-sphere", [xi, a])),
                               [[400 * 0.3 / D + 320, 410 * -0.2 / D + 300]], rtol=1e-13)
    a, b = 0.6, 1.3
    D = a * np.sqrt(b * 0.13 + 0.25) + (1 - a) * 0.5
    np.testing.assert_allclose(project_points(X, _lens("eucm", [a, b])),
                               [[400 * 0.3 / D + 320, 410 * -0.2 / D + 300]], rtol=1e-13)


def test_intrinsics_accept_and_refuse_the_wide_models():
    for model, names in (("unified", ("xi", "k1", "k2", "p1", "p2")),
                         ("double-sphere", ("xi", "alpha")), ("eucm", ("alpha", "beta"))):
        assert LENS_MODELS[model] == (model, names)
        cam = _lens(model, [0.5] * len(names))
        assert lens_model(cam) == model
        assert parameter_names(cam) == ("fx", "fy", "cx", "cy") + names
        assert cam.with_params(cam.params).model == model
    bad = [("unified", [-0.1, 0, 0, 0, 0], "xi"), ("unified", [1.0, 0, 0, 0], "5 numbers"),
           ("double-sphere", [-1.0, 0.5], "xi"), ("double-sphere", [0.1, 1.2], "alpha"),
           ("eucm", [-0.1, 1.0], "alpha"), ("eucm", [0.5, 0.0], "beta"),
           ("eucm", [0.5, np.nan], "finite"), ("omni", [0.5, 1.0], "camera model")]
    for model, dist, word in bad:
        with pytest.raises(InputError, match=word):
            Intrinsics(K=K, dist=dist, model=model)
    check_lens_bounds(_lens("unified", [3.0, -0.3, 0.1, 0.001, 0.001]))
    for model, dist, word in (("unified", [150.0, 0, 0, 0, 0], "xi"),
                              ("unified", [1.0, 0, 0, 2.0, 0], "p1"),
                              ("eucm", [0.5, 500.0], "beta")):
        with pytest.raises(InputError, match=word):
            check_lens_bounds(_lens(model, dist))
