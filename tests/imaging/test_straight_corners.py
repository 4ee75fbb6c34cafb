"""Corners whose edges the lens bends: cornerSubPix alone puts them outward, the straightened
refinement of ``refine_grid`` does not (issue 32, item 1; benchmarks/corner_bias.py)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from multieye.core.lie import exp_so3
from multieye.imaging import chessboard_corners as cc
from multieye.imaging.straight_corners import refine_straightened
from multieye.imaging.targets import Chessboard

F, CX, CY, W, H = 520.0, 399.5, 299.5, 800, 600
#: Division-model lens (Fitzgibbon 2001): undistorted = distorted / (1 + LAM r^2), normalised
#: coordinates; LAM < 0 is barrel distortion.  Its inverse is closed-form, so the images are
#: rendered exactly here, independently of multieye's lens models and renderers.
LAM = -0.5
BOARD = Chessboard(rows=8, cols=11, spacing=0.03)


def _distort(xy: np.ndarray) -> np.ndarray:
    ru = np.linalg.norm(xy, axis=1, keepdims=True)
    rd = (1.0 - np.sqrt(1.0 - 4.0 * LAM * ru ** 2)) / (2.0 * LAM * ru)
    return xy * rd / ru


def _truth(T: np.ndarray) -> np.ndarray:
    P = BOARD.object_points() @ T[:3, :3].T + T[:3, 3]
    return _distort(P[:, :2] / P[:, 2:]) * F + [CX, CY]


def _render(T: np.ndarray, ss: int = 4, blur: float = 0.7) -> np.ndarray:
    """The board (white beyond its squares, grey 110 beyond its bounding box), each pixel
    the mean of ss x ss sub-pixels traced exactly, blurred, in whole grey levels."""
    true = _truth(T)
    (u0, v0), (u1, v1) = np.floor(true.min(axis=0) - 60), np.ceil(true.max(axis=0) + 60)
    u0, v0, u1, v1 = int(max(u0, 0)), int(max(v0, 0)), int(min(u1, W)), int(min(v1, H))
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    u = ((np.arange(u0, u1)[:, None] + offs).ravel() - CX) / F
    v = ((np.arange(v0, v1)[:, None] + offs).ravel() - CY) / F
    xd, yd = np.meshgrid(u, v)
    scale = 1.0 / (1.0 + LAM * (xd * xd + yd * yd))
    ray = np.stack([xd * scale, yd * scale, np.ones_like(xd)], axis=-1) @ T[:3, :3]
    o = -T[:3, :3].T @ T[:3, 3]
    lam = -o[2] / ray[..., 2]
    i = np.floor((o[0] + lam * ray[..., 0]) / BOARD.spacing)
    j = np.floor((o[1] + lam * ray[..., 1]) / BOARD.spacing)
    inside = (i >= -1) & (i < BOARD.cols) & (j >= -1) & (j < BOARD.rows)
    grey = np.where(inside & ((i + j) % 2 == 0), 25.0, 225.0).astype(np.float32)
    image = np.full((H, W), 110.0, np.float32)
    image[v0:v1, u0:u1] = grey.reshape(v1 - v0, ss, u1 - u0, ss).mean(axis=(1, 3))
    image = cv2.GaussianBlur(image, (0, 0), blur)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def _pose(k: int) -> np.ndarray:
    """The board tilted by 30 degrees, its centre a third of the way to an image corner."""
    a = np.pi / 4 + k * np.pi / 2 + 0.3 * k
    R = exp_so3(np.radians(30) * np.array([np.cos(a), np.sin(a), 0.0])) @ exp_so3([0, 0, 0.2 * k])
    centre = np.array([(BOARD.cols - 1) / 2, (BOARD.rows - 1) / 2, 0.0]) * BOARD.spacing
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.array([0.12 * np.sign(np.cos(a)), 0.09 * np.sign(np.sin(a)), 0.55]) - R @ centre
    return T


@pytest.fixture(scope="module")
def radial_errors() -> dict[str, np.ndarray]:
    """Per refinement, every corner's error along the direction from the image centre, px."""
    out: dict[str, list] = {"cornerSubPix": [], "refine_grid": []}
    rng = np.random.default_rng(0)
    for k in range(6):
        T = _pose(k)
        true = _truth(T)
        assert np.all((true > 20) & (true < [W - 20, H - 20]))
        image = _render(T)
        start = true + rng.uniform(-0.3, 0.3, true.shape)
        half = cc.corner_window(true, BOARD)
        outward = (true - [CX, CY]) / np.linalg.norm(true - [CX, CY], axis=1)[:, None]
        for name, got in (("cornerSubPix", cc.refine_corners(image, start, half)),
                          ("refine_grid", cc.refine_grid(image, start, BOARD))):
            out[name].append(np.sum((got - true) * outward, axis=1))
    return {k: np.concatenate(v) for k, v in out.items()}


def _mean_and_se(e: np.ndarray) -> tuple[float, float]:
    return float(e.mean()), float(e.std() / np.sqrt(e.size))


def test_cornersubpix_alone_is_pushed_outward(radial_errors):
    """The premise: on these exact renders cornerSubPix's mean error points away from the
    image centre, beyond 4 of its standard errors (its fixed, sub-pixel-phase errors of
    about 0.02 px are the noise floor here: no sensor noise)."""
    mean, se = _mean_and_se(radial_errors["cornerSubPix"])
    assert mean > 4 * se, (mean, se)


def test_refine_grid_is_not(radial_errors):
    mean, se = _mean_and_se(radial_errors["refine_grid"])
    assert abs(mean) < 2.5 * se, (mean, se)
    rms = np.sqrt(np.mean(radial_errors["refine_grid"] ** 2))
    assert rms < 1.1 * np.sqrt(np.mean(radial_errors["cornerSubPix"] ** 2))


def test_a_straight_grid_is_left_where_it_is():
    """A board without distortion, fronto-parallel, corners on whole pixels: the patches
    are the image itself, and the corners stay where cornerSubPix put them."""
    image = np.full((200, 260), 225, np.uint8)
    for r in range(-1, 4):
        for c in range(-1, 5):
            if (r + c) % 2 == 0:
                image[60 + 30 * r: 90 + 30 * r, 60 + 30 * c: 90 + 30 * c] = 25
    image = cv2.GaussianBlur(image, (0, 0), 0.8)
    corners = np.array([[89.5 + 30 * c, 89.5 + 30 * r] for r in range(3) for c in range(4)])
    first = cc.refine_corners(image, corners + 0.2, 8)
    again = refine_straightened(image, first, 3, 4, 8)
    assert np.max(np.abs(again - first)) < 2e-3
    assert np.max(np.abs(again - corners)) < 5e-3
