"""Camera models: OpenCV's formulas reproduced independently, and pixel round trips."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from multieye.core.errors import InputError
from multieye.core.lens import (
    distort_points,
    project_points,
    project_with_jacobian,
    undistort_points,
)
from multieye.core.intrinsics import Intrinsics

K = np.array([[610.0, 0.0, 402.3], [0.0, 605.0, 297.8], [0.0, 0.0, 1.0]])

PINHOLE_DIST = {
    4: [-0.28, 0.09, 0.0011, -0.0007],
    5: [-0.3, 0.1, 0.001, -0.001, -0.02],
    8: [0.458331, -2.87024, 0.00048617, -9.82262e-05, 1.74446, 0.331466, -2.66947, 1.65473],
    12: [-0.25, 0.07, 0.001, -0.0005, -0.01, 0.02, -0.01, 0.003, 0.002, -0.001, 0.0015, 0.0005],
    14: [-0.25, 0.07, 0.001, -0.0005, -0.01, 0.02, -0.01, 0.003, 0.002, -0.001, 0.0015, 0.0005,
         0.01, -0.008],
}
FISHEYE = Intrinsics(K=[[300.0, 0.0, 399.5], [0.0, 301.0, 299.5], [0.0, 0.0, 1.0]],
                     dist=[-0.02, 0.005, -0.001, 0.0002], model="fisheye")


def brown_conrady_5(xy, k1, k2, p1, p2, k3):
    """OpenCV's 5-coefficient pinhole model, written out (OpenCV docs, calib3d)."""
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.column_stack([K[0, 0] * xd + K[0, 2], K[1, 1] * yd + K[1, 2]])


def equidistant(xy, fx, fy, cx, cy, k1, k2, k3, k4):
    """The equidistant fisheye model, written out (OpenCV fisheye docs, Kalibr equidistant)."""
    r = np.hypot(xy[:, 0], xy[:, 1])
    theta = np.arctan(r)
    theta_d = theta * (1 + k1 * theta ** 2 + k2 * theta ** 4 + k3 * theta ** 6 + k4 * theta ** 8)
    scale = np.where(r > 0, theta_d / np.where(r > 0, r, 1), 1.0)
    return np.column_stack([fx * xy[:, 0] * scale + cx, fy * xy[:, 1] * scale + cy])


def test_pinhole_projection_matches_the_written_out_model(rng):
    cam = Intrinsics(K=K, dist=PINHOLE_DIST[5])
    P = np.column_stack([rng.uniform(-0.5, 0.5, (200, 2)), rng.uniform(0.8, 3.0, 200)])
    expected = brown_conrady_5(P[:, :2] / P[:, 2:], *PINHOLE_DIST[5])
    np.testing.assert_allclose(project_points(P, cam), expected, atol=1e-9)


def test_fisheye_projection_matches_the_written_out_model(rng):
    P = np.column_stack([rng.uniform(-2, 2, (200, 2)), rng.uniform(0.5, 2.0, 200)])
    K_ = FISHEYE.K
    expected = equidistant(P[:, :2] / P[:, 2:], K_[0, 0], K_[1, 1], K_[0, 2], K_[1, 2], *FISHEYE.dist)
    np.testing.assert_allclose(project_points(P, FISHEYE), expected, atol=1e-9)


@pytest.mark.parametrize("n_coeffs", sorted(PINHOLE_DIST))
def test_pinhole_round_trip_to_a_micro_pixel(n_coeffs, rng):
    cam = Intrinsics(K=K, dist=PINHOLE_DIST[n_coeffs])
    xy = rng.uniform(-0.55, 0.55, (500, 2))            # about +-30 deg: inside an 800x600 view
    uv = distort_points(xy, cam)
    back = undistort_points(uv, cam)
    np.testing.assert_allclose(back, xy, atol=1e-9)
    np.testing.assert_allclose(distort_points(back, cam), uv, atol=1e-6)


def test_pixel_grid_round_trip_for_the_rational_model():
    cam = Intrinsics(K=[[607.88, 0, 641.875], [0, 607.966, 365.585], [0, 0, 1]], dist=PINHOLE_DIST[8])
    u, v = np.meshgrid(np.arange(0, 1280, 7.5), np.arange(0, 720, 7.5))
    uv = np.column_stack([u.ravel(), v.ravel()])
    xy = undistort_points(uv, cam)
    assert np.all(np.isfinite(xy))
    assert np.max(np.linalg.norm(distort_points(xy, cam) - uv, axis=1)) < 1e-6


def test_fisheye_round_trip_wide_angles(rng):
    angle = rng.uniform(0, np.radians(85), 500)
    azimuth = rng.uniform(0, 2 * np.pi, 500)
    xy = np.tan(angle)[:, None] * np.column_stack([np.cos(azimuth), np.sin(azimuth)])
    uv = distort_points(xy, FISHEYE)
    back = undistort_points(uv, FISHEYE)
    assert np.max(np.linalg.norm(distort_points(back, FISHEYE) - uv, axis=1)) < 1e-6
    np.testing.assert_allclose(back, xy, rtol=1e-7, atol=1e-9)


def test_fisheye_pixels_beyond_90_degrees_have_no_ray():
    # the image corner of a 300 px focal length is about 95 degrees off axis
    xy = undistort_points([[0.0, 0.0], [399.5, 299.5]], FISHEYE)
    assert np.all(np.isnan(xy[0])) and np.allclose(xy[1], 0.0)


def test_points_behind_the_camera_do_not_project():
    cam = Intrinsics(K=K, dist=PINHOLE_DIST[5])
    uv = project_points([[0.1, 0.1, 1.0], [0.1, 0.1, 0.0], [0.1, 0.1, -1.0], [np.nan, 0, 1]], cam)
    assert np.all(np.isfinite(uv[0])) and np.all(np.isnan(uv[1:]))


def test_shapes_are_checked():
    cam = Intrinsics(K=K)
    with pytest.raises(InputError, match=r"shape \(N, 3\)"):
        project_points(np.zeros((4, 2)), cam)
    with pytest.raises(InputError, match=r"shape \(N, 2\)"):
        undistort_points(np.zeros((4, 3)), cam)
    assert project_points(np.array([0.0, 0.0, 1.0]), cam).shape == (1, 2)


@settings(max_examples=40, deadline=None)
@given(x=st.floats(-0.6, 0.6), y=st.floats(-0.6, 0.6), k1=st.floats(-0.3, 0.3), k2=st.floats(-0.1, 0.1))
def test_round_trip_property(x, y, k1, k2):
    cam = Intrinsics(K=K, dist=[k1, k2, 0.001, -0.001, 0.0])
    uv = distort_points([[x, y]], cam)
    back = undistort_points(uv, cam)
    # in this range the model is one-to-one, so the ray must come back
    np.testing.assert_allclose(back, [[x, y]], atol=1e-9)
    assert np.linalg.norm(distort_points(back, cam) - uv) < 1e-6


@pytest.mark.parametrize("n_coeffs", [0, 4, 5, 8, 12, 14])
def test_project_with_jacobian_matches_opencv(n_coeffs, rng):
    """The pinhole model in numpy (up to 12 coefficients; 14 with tilt is OpenCV's) gives
    OpenCV's pixels and Jacobians to rounding."""
    dist = np.asarray(PINHOLE_DIST.get(n_coeffs, []), dtype=float)
    cam = Intrinsics(K=K, dist=dist)
    P = np.column_stack([rng.uniform(-0.6, 0.6, (300, 2)), rng.uniform(0.8, 3.0, 300)])
    uv, J_point, J_intr = project_with_jacobian(P, cam)
    out, jac = cv2.projectPoints(P.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    jac = jac.reshape(-1, 2, jac.shape[-1])
    np.testing.assert_allclose(uv, out.reshape(-1, 2), rtol=0, atol=1e-9)
    np.testing.assert_allclose(J_point, jac[:, :, 3:6], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(J_intr, jac[:, :, 6:10 + n_coeffs], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(project_points(P, cam), uv, rtol=0, atol=1e-9)


def test_pinhole_jacobians_match_central_differences(rng):
    dist = np.asarray(PINHOLE_DIST[12])
    cam = Intrinsics(K=K, dist=dist)
    P = np.column_stack([rng.uniform(-0.5, 0.5, (50, 2)), rng.uniform(0.8, 3.0, 50)])
    _, J_point, J_intr = project_with_jacobian(P, cam)
    h = 1e-6
    for a in range(3):
        e = np.zeros(3)
        e[a] = h
        d = (project_points(P + e, cam) - project_points(P - e, cam)) / (2 * h)
        np.testing.assert_allclose(J_point[:, :, a], d, rtol=1e-6, atol=1e-4)
    params = cam.params
    for a in range(params.size):
        step = h * max(1.0, abs(params[a]))
        e = np.zeros(params.size)
        e[a] = step
        d = (project_points(P, cam.with_params(params + e))
             - project_points(P, cam.with_params(params - e))) / (2 * step)
        np.testing.assert_allclose(J_intr[:, :, a], d, rtol=1e-6, atol=1e-5)


def test_points_behind_the_camera_have_no_pixel_nor_jacobian(rng):
    cam = Intrinsics(K=K, dist=PINHOLE_DIST[5])
    P = np.column_stack([rng.uniform(-0.5, 0.5, (6, 2)), rng.uniform(0.8, 3.0, 6)])
    P[1, 2] = -1.0
    P[4, 0] = np.nan
    uv, J_point, J_intr = project_with_jacobian(P, cam)
    bad = np.isin(np.arange(6), [1, 4])
    assert np.all(np.isnan(uv[bad])) and np.all(np.isnan(J_point[bad]))
    assert np.all(np.isnan(J_intr[bad]))
    good = project_with_jacobian(P[~bad], cam)
    for a, b in zip((uv, J_point, J_intr), good):
        np.testing.assert_array_equal(a[~bad], b)


@pytest.mark.parametrize("cam", [Intrinsics(K=K, dist=PINHOLE_DIST[5]), FISHEYE])
def test_the_lens_jacobian_is_left_out_when_not_asked_for(cam, rng):
    P = np.column_stack([rng.uniform(-0.5, 0.5, (20, 2)), rng.uniform(0.8, 3.0, 20)])
    P[3, 2] = -1.0
    full = project_with_jacobian(P, cam)
    uv, J_point, J_intr = project_with_jacobian(P, cam, lens_jacobian=False)
    assert J_intr is None
    np.testing.assert_array_equal(uv, full[0])
    np.testing.assert_array_equal(J_point, full[1])
