"""Wide lenses (up to and beyond 180 degrees) and a planar board's corners seen by them.

For the lens start's tests and ``benchmarks/bench_wide_lens.py`` (issue 33): a lens of each
model whose image circle of ``fov_deg`` fills a square image (:func:`wide_lens`), and views
of a chessboard's corners spread over that field, boards beyond 90 degrees off the axis
included, with Gaussian pixel noise (:func:`board_views`).  The corners are projected, not
rendered; :mod:`multieye.sim.render` renders these lenses beyond 90 degrees too
(``benchmarks/bench_wide_render.py`` calibrates from such images).

Synopsis
--------
>>> lens = wide_lens("double-sphere", 220.0)
>>> views, T = board_views(lens, 220.0, 20, np.random.default_rng(0))
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points

__all__ = ["wide_lens", "board_views", "SHAPES", "IMAGE_SIDE", "CIRCLE_PX"]

F64 = NDArray[np.float64]

#: Each model's distortion (``Intrinsics.dist``) in the simulated lenses.
SHAPES = {"fisheye": (-0.01, 0.002, -0.0005, 0.0), "unified": (1.1, -0.08, 0.01, 0.0, 0.0),
          "double-sphere": (-0.15, 0.6), "eucm": (0.62, 1.05)}
#: Side of the square image, pixels.
IMAGE_SIDE = 1024
#: Radius of the image circle (rays at half the field of view), pixels.
CIRCLE_PX = 480.0


def wide_lens(model: str, fov_deg: float) -> Intrinsics:
    """A lens of ``model`` (``Intrinsics.model``; fisheye at most 180 degrees) centred in a
    :data:`IMAGE_SIDE` square image whose rays at ``fov_deg / 2`` off the axis fall on the
    circle of :data:`CIRCLE_PX` pixels (fx = fy, the shape of :data:`SHAPES`)."""
    c = (IMAGE_SIDE - 1) / 2.0
    unit = Intrinsics(K=np.array([[1.0, 0, c], [0, 1.0, c], [0, 0, 1]]),
                      dist=np.array(SHAPES[model]), model=model, width=IMAGE_SIDE,
                      height=IMAGE_SIDE)
    half = np.radians(fov_deg / 2)
    r1 = project_points(np.array([[np.sin(half), 0.0, np.cos(half)]]), unit)[0, 0] - c
    if not np.isfinite(r1) or r1 <= 0:
        raise ValueError(f"{model} with {SHAPES[model]} does not reach {fov_deg} degrees")
    f = CIRCLE_PX / r1
    return unit.with_params([f, f, c, c, *SHAPES[model]])


def _board(rows: int, cols: int, spacing: float) -> F64:
    j, i = np.meshgrid(np.arange(cols), np.arange(rows))
    return np.column_stack([j.ravel() * spacing, i.ravel() * spacing, np.zeros(rows * cols)])


def _pose(rng: np.random.Generator, theta: float, obj: F64) -> F64:
    """A board centred on the ray ``theta`` off the axis (random azimuth), 0.3-0.6 m away,
    facing the camera within 40 degrees, turned at random in its plane."""
    phi = rng.uniform(0, 2 * np.pi)
    ray = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    z = ray                                             # the board's z: into it, away
    x = np.cross([0.0, 0.0, 1.0] if abs(ray[2]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(z, x), z])
    tilt = g.rotation_from_rotvec(np.append(rng.uniform(-0.7, 0.7, 2), rng.uniform(-np.pi, np.pi)))
    R = R @ tilt
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = rng.uniform(0.3, 0.6) * ray - R @ obj.mean(axis=0)
    return T


def board_views(lens: Intrinsics, fov_deg: float, n: int, rng: np.random.Generator, *,
                noise_px: float = 0.2, rows: int = 6, cols: int = 8, spacing: float = 0.03
                ) -> tuple[list[tuple[F64, F64]], F64]:
    """``n`` views of a chessboard's corners spread over the lens' field, with noise.

    Board centres are drawn at angles off the axis uniform from 0 to ``fov_deg / 2`` less 8
    degrees; a view is kept when every corner projects inside the image circle and more
    than 2 px from the image border.

    Returns
    -------
    views : list of (object_points (k, 3), image_points (k, 2))
        Target frame, metres; noisy pixels.
    T_cam_target : ndarray, shape (n, 4, 4)
        The true poses.
    """
    obj = _board(rows, cols, spacing)
    half = np.radians(fov_deg / 2)
    c = lens.K[:2, 2]
    views, poses = [], []
    for _ in range(200 * n):
        if len(views) == n:
            break
        T = _pose(rng, rng.uniform(0.0, half - np.radians(8.0)), obj)
        P = obj @ T[:3, :3].T + T[:3, 3]
        theta = np.arctan2(np.hypot(P[:, 0], P[:, 1]), P[:, 2])
        uv = project_points(P, lens)
        if (not np.isfinite(uv).all() or theta.max() > half
                or np.any(uv < 2) or np.any(uv > IMAGE_SIDE - 3)
                or np.any(np.hypot(*(uv - c).T) > CIRCLE_PX)):
            continue
        views.append((obj.copy(), uv + rng.normal(0.0, noise_px, uv.shape)))
        poses.append(T)
    if len(views) < n:
        raise ValueError(f"only {len(views)} of {n} views fit the {fov_deg} degree field")
    return views, np.array(poses)
