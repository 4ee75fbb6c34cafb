"""A second look for chessboards near the rim of a wide lens: perspective views of its field.

A lens of 190-220 degrees bends a board near its rim into an arc, and OpenCV's chessboard
detectors (classic and SB alike) miss most such views (docs/results/wide_render.md).  Once
the lens is known (given, or started from the views that were found), an image whose board
was not found is looked at again through perspective (pinhole) virtual views of the sphere of
rays (:func:`directions`: a ring of :data:`RING_VIEWS` directions covering the field up to
its rim, then the axis), each resampled from the image by ``cv2.remap`` through the lens's
projection (:func:`view_maps`, :func:`virtual_view`).  In such a view the board is nearly
flat again.  A view that OpenCV's quick test says may show the board (:func:`_may_show`) is
searched as any image is (:func:`multieye.imaging.chessboard_corners.locate_board`); a board
found there is searched again in a view centred on it (:func:`_centred`), where it is least
stretched, and kept only when the usual checks pass there: every corner a saddle, no saddle
one square beyond the grid, the grid smooth.  Its corners, refined by ``cv2.cornerSubPix`` in
that view, are taken back to the image through the lens (they are refined and checked in the
centred view and not in the image: :func:`_centred` says why, with the figures).  The caller
then poses the view and keeps it by the same reprojection RMS as any other view.

Only lenses whose field reaches :data:`WIDE_FIELD_DEG` (:func:`is_wide`) get the second
look, and only for images whose board was not found: nothing changes for narrower lenses
nor for boards found in the image itself.

Synopsis
--------
>>> if is_wide(lens):                                                    # doctest: +SKIP
...     det = second_look(gray, board, lens)         # a Detection or None # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, unproject_points
from multieye.imaging import chessboard_corners as cc
from multieye.imaging.detect import Detection, canonical_order, detect_or_why, to_gray
from multieye.imaging.targets import Chessboard

__all__ = ["detect_with_second_look", "is_wide", "field_deg", "directions", "virtual_view",
           "view_maps", "VirtualView", "second_look", "WIDE_FIELD_DEG", "RING_VIEWS", "INNER_VIEWS",
           "VIEW_HALF_ANGLE_DEG", "CENTRED_MARGIN", "RIM_MARGIN_DEG", "MAX_TILT_DEG", "MAP_STEP"]

F64 = NDArray[np.float64]

#: Lenses whose field (:func:`field_deg`) is narrower than this get no second look.
WIDE_FIELD_DEG = 150.0
#: Directions of the outer and the inner ring of virtual views (:func:`directions`).
RING_VIEWS = 10
INNER_VIEWS = 6
#: Half the angle a virtual view spans from its centre to the middle of a side, degrees.
VIEW_HALF_ANGLE_DEG = 50.0
#: The outer ring's directions lie this far inside the half field (30 to
#: :data:`MAX_TILT_DEG` degrees off the axis), degrees: a view there spans from the rim to
#: well inside it.
RIM_MARGIN_DEG = 30.0
#: The view centred on a board found spans this many times the largest angle between its
#: centre and a corner (a margin of about a square on a 6 x 9 board), at most
#: :data:`VIEW_HALF_ANGLE_DEG`.
CENTRED_MARGIN = 1.5
#: Pixels per side of the grid whose rays give the field (:func:`field_deg`).
_GRID = 48
#: The ring's largest angle off the axis, degrees.
MAX_TILT_DEG = 90.0
#: The virtual view's pixels are taken through the lens on a grid of this step, pixels, and
#: interpolated between (:func:`view_maps`).
MAP_STEP = 4


def field_deg(lens: Intrinsics) -> float:
    """The lens's field of view, degrees: twice the largest angle off the axis of the rays
    of a grid of :data:`_GRID` x :data:`_GRID` pixels over the image (those the model has a
    ray for); 0 for a lens without a stated image size.  Pinhole and fisheye lenses: at most
    180 degrees.  The model's rays reach beyond the image circle of a lens whose circle is
    smaller than the image: the field is then the model's, larger than what the image shows."""
    if lens.width is None or lens.height is None:
        return 0.0
    j, i = np.meshgrid(np.linspace(0.0, lens.width - 1.0, _GRID),
                       np.linspace(0.0, lens.height - 1.0, _GRID))
    rays = unproject_points(np.column_stack([j.ravel(), i.ravel()]), lens)
    z = rays[np.isfinite(rays).all(axis=1), 2]
    return 0.0 if z.size == 0 else float(2.0 * np.degrees(np.arccos(np.clip(z.min(), -1, 1))))


def is_wide(lens: Intrinsics | None) -> bool:
    """Whether ``lens`` gets the second look: not a pinhole model, and a field
    (:func:`field_deg`) of at least :data:`WIDE_FIELD_DEG` (kept for the last lens)."""
    if lens is None or lens.model == "pinhole":
        return False
    key = _key(lens)
    if key not in _WIDE:
        _WIDE.clear()
        _WIDE[key] = field_deg(lens) >= WIDE_FIELD_DEG
    return _WIDE[key]


def _key(lens: Intrinsics) -> tuple:
    return (lens.model, lens.width, lens.height, tuple(np.asarray(lens.params).tolist()))


#: :func:`is_wide` of the last lens.
_WIDE: dict = {}


def directions(lens: Intrinsics) -> F64:
    """Unit directions (camera frame) of the virtual views, shape (RING_VIEWS + INNER_VIEWS
    + 1, 3): a ring of :data:`RING_VIEWS` around the axis, :data:`RIM_MARGIN_DEG` inside the
    half field (:func:`field_deg`; 30 to :data:`MAX_TILT_DEG` degrees off the axis), a ring
    of :data:`INNER_VIEWS` at half its angle, turned by half their step, then the axis.  The
    outer ring comes first: boards the detector misses in the image itself lie near the
    rim."""
    tilt = np.radians(np.clip(field_deg(lens) / 2.0 - RIM_MARGIN_DEG, 30.0, MAX_TILT_DEG))
    rings = []
    for angle, n, turn in ((tilt, RING_VIEWS, 0.0), (tilt / 2.0, INNER_VIEWS, 0.5)):
        phi = 2.0 * np.pi * (np.arange(n) + turn) / n
        rings.append(np.column_stack([np.sin(angle) * np.cos(phi), np.sin(angle) * np.sin(phi),
                                      np.full_like(phi, np.cos(angle))]))
    return np.vstack([*rings, [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class VirtualView:
    """A perspective camera at the lens's centre looking along one direction.

    Attributes
    ----------
    R : ndarray, shape (3, 3)
        ``R_cam_view``: its axes in the lens's camera frame (its z the direction).
    f : float
        Focal length, pixels (square pixels, no distortion).
    size : int
        Its image is ``size`` x ``size`` pixels, principal point at the centre.
    least : float
        The lens's smaller scale (pixels per radian, radial or tangential) at the view's
        centre: the view magnifies the image by ``f / least`` there, in that direction.
    """

    R: F64
    f: float
    size: int
    least: float = 0.0

    def rays(self, pixels: F64) -> F64:
        """Rays in the lens's camera frame (N, 3) of the view's pixels (N, 2)."""
        c = (self.size - 1) / 2.0
        xy = (np.asarray(pixels, np.float64) - c) / self.f
        return np.column_stack([xy, np.ones(len(xy))]) @ self.R.T

    def pixels(self, rays: F64) -> F64:
        """The view's pixels (N, 2) of rays (N, 3) in the lens's camera frame (NaN behind)."""
        local = np.asarray(rays, np.float64) @ self.R
        with np.errstate(invalid="ignore", divide="ignore"):
            xy = local[:, :2] / np.where(local[:, 2:] > 0, local[:, 2:], np.nan)
        return xy * self.f + (self.size - 1) / 2.0


def _view_for(lens: Intrinsics, direction: F64, half_deg: float = VIEW_HALF_ANGLE_DEG
              ) -> VirtualView:
    """The virtual view along ``direction``: as many pixels per radian at its centre as the
    lens has there (the larger of its radial and tangential scales), spanning ``half_deg``
    each way."""
    z = direction / np.linalg.norm(direction)
    x = np.cross([0.0, 1.0, 0.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0.0, 0.0])
    R = np.column_stack([x, np.cross(z, x), z])
    step = 1e-3
    probes = np.vstack([z, z + step * R[:, 0], z + step * R[:, 1]])
    uv = project_points(probes, lens)
    scale = np.linalg.norm(uv[1:] - uv[0], axis=1) / step
    f = float(np.nanmax(scale)) if np.isfinite(scale).any() else float(lens.K[0, 0])
    size = int(2 * np.ceil(f * np.tan(np.radians(half_deg)))) + 1
    return VirtualView(R, f, size, float(np.nanmin(scale)) if np.isfinite(scale).any() else f)


def view_maps(lens: Intrinsics, view: VirtualView) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """``cv2.remap``'s maps of ``view`` through ``lens``: per pixel of the view, the image's
    x and y, shapes (size, size); -10 where the lens does not show its ray.  Projected on a
    grid of :data:`MAP_STEP` pixels and interpolated between (:func:`_fine`), which costs
    1/16 of projecting every pixel: the map is smooth, within 0.01 px of the projection at
    99 % of the pixels of a 220-degree double-sphere lens's views (median 0.003 px)."""
    return _fine(view, _coarse(lens, view))


def _coarse(lens: Intrinsics, view: VirtualView) -> NDArray[np.float32]:
    """The image's pixels of the view's pixels on a grid of :data:`MAP_STEP`, (n, n, 2)."""
    n = int(np.ceil((view.size - 1) / MAP_STEP)) + 1
    j, i = np.meshgrid(np.arange(n) * MAP_STEP, np.arange(n) * MAP_STEP)
    uv = project_points(view.rays(np.column_stack([j.ravel(), i.ravel()]).astype(np.float64)),
                        lens)
    return np.where(np.isfinite(uv), uv, -10.0).astype(np.float32).reshape(n, n, 2)


def _fine(view: VirtualView, coarse: NDArray[np.float32]) -> tuple:
    """The maps of every pixel of ``view`` from its :func:`_coarse` grid: pixel k of the
    view is at k / MAP_STEP on the grid, an affine warp of it (bilinear)."""
    scale = np.array([[1.0 / MAP_STEP, 0, 0], [0, 1.0 / MAP_STEP, 0]], np.float32)
    fine = cv2.warpAffine(coarse, scale, (view.size, view.size),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE)
    return fine[:, :, 0].copy(), fine[:, :, 1].copy()


#: The last lens's views and their coarse maps (a worker looks at one camera's images in
#: turn; the coarse maps of its 17 views take about 6 MB, their full maps would take 100).
_MAPS: dict = {}


def _views(lens: Intrinsics) -> list[tuple[VirtualView, NDArray[np.float32]]]:
    """The virtual views of :func:`directions` with their coarse maps, kept for the last
    lens."""
    key = _key(lens)
    if key not in _MAPS:
        _MAPS.clear()
        views = [_view_for(lens, d) for d in directions(lens)]
        _MAPS[key] = [(v, _coarse(lens, v)) for v in views]
    return _MAPS[key]


def virtual_view(gray: NDArray[np.uint8], maps: tuple, grey: int | None = None
                 ) -> NDArray[np.uint8]:
    """The image ``gray`` (H, W) resampled by ``maps`` (:func:`view_maps`; bilinear; pixels
    whose ray the lens does not show are ``grey``, by default the image's median grey)."""
    if grey is None:
        grey = int(np.median(gray))
    return cv2.remap(gray, maps[0], maps[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=grey)


def detect_with_second_look(gray: NDArray, target, lens: Intrinsics | None
                            ) -> tuple[Detection | None, str, bool]:
    """:func:`multieye.imaging.detect.detect_or_why`, and where it finds no chessboard and
    ``lens`` is wide (:func:`is_wide`), :func:`second_look`.

    Returns
    -------
    detection : Detection or None
    why : str
        As :func:`~multieye.imaging.detect.detect_or_why` says it of the image itself.
    looked : bool
        The detection is the second look's.
    """
    gray = to_gray(gray)
    detection, why = detect_or_why(gray, target)
    if detection is not None or not isinstance(target, Chessboard) or not is_wide(lens):
        return detection, why, False
    detection = second_look(gray, target, lens)
    return detection, why, detection is not None


def second_look(gray: NDArray[np.uint8], target: Chessboard, lens: Intrinsics
                ) -> Detection | None:
    """The board found through the virtual views of :func:`directions` and found again in
    a view centred on it (:func:`_centred`), its corners taken back to ``gray`` through the
    lens and checked (module docstring), in the canonical order; None when no view gives a
    grid that passes.  Only views that pass OpenCV's quick test (:func:`_may_show`) are
    searched, in turn; the first board that passes is taken.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
        The image, of ``lens``'s size.
    target : Chessboard
    lens : Intrinsics
        The camera's lens (given, or its start).
    """
    grey = int(np.median(gray))           # once: 17 views of a 640 x 720 image, 15 ms
    for view, coarse in _views(lens):
        seen = virtual_view(gray, _fine(view, coarse), grey)
        if not _may_show(seen, target):
            continue
        located = cc.locate_board(seen, target)
        if located.corners is None:
            continue
        corners = _centred(gray, target, lens, view.rays(located.corners))
        if corners is not None:
            return canonical_order(gray, target, corners)
    return None


def _may_show(seen: NDArray[np.uint8], target: Chessboard) -> bool:
    """OpenCV's quick test (:func:`~multieye.imaging.chessboard_corners.quick_check`) on the
    view or on the view halved: either may pass alone where the board is (on the rendered
    rim views of the benchmark, 1 of 3 passed only at half size, 1 only at full size).  A
    search of a view without the board costs 0.2-0.7 s, the test a few ms."""
    if cc.quick_check(seen, target):
        return True
    half = cv2.resize(seen, (seen.shape[1] // 2, seen.shape[0] // 2), interpolation=cv2.INTER_AREA)
    return cc.quick_check(half, target)


def _centred(gray: NDArray[np.uint8], target: Chessboard, lens: Intrinsics, rays: F64
             ) -> F64 | None:
    """The board whose corners' rays (N, 3) a first view found, found again in a view
    centred on them, where a pinhole shows it least stretched, and spanning them with
    :data:`CENTRED_MARGIN` to spare; its corners (refined in that view, whose squares are
    at least as large as the image's) taken to ``gray`` through the lens; None unless the
    usual checks pass in that view: every corner a saddle
    (:func:`~multieye.imaging.chessboard_corners.saddle_grid`), no saddle one square beyond
    the grid (:func:`~multieye.imaging.chessboard_corners.whole_board`; both as
    :func:`~multieye.imaging.chessboard_corners.locate_board` checks them), the grid smooth
    (:func:`~multieye.imaging.chessboard_corners.consistent_grid`, its departures measured
    in the image's pixels: the view's shrunk by ``least / f``, also for the grids
    ``locate_board`` keeps bent).

    The corners are refined and checked in the centred view, not in ``gray``.  Where the
    lens bends the squares' edges within ``cornerSubPix``'s window (squares of 6-16 px at the
    rim of a 220-degree lens), its corners in ``gray`` were 0.09-0.44 px RMS (largest
    0.26-1.95 px) from the truth on rendered views, those of the centred view 0.06-0.10 px
    (largest 0.2-0.3 px).  And where the lens's magnification changes fast across a corner's
    circle, the saddle check refuses true corners in ``gray`` (the true corners of 3 of 13
    missed double-sphere views, correlation -0.3 to 0.1 at the rim) that pass it in the
    centred view."""
    rays = rays / np.linalg.norm(rays, axis=1)[:, None]
    centre = rays.mean(axis=0)
    centre /= np.linalg.norm(centre)
    spread = np.degrees(np.arccos(np.clip(rays @ centre, -1.0, 1.0)).max())
    view = _view_for(lens, centre, min(CENTRED_MARGIN * spread, VIEW_HALF_ANGLE_DEG))
    seen = virtual_view(gray, view_maps(lens, view))
    found = cc.locate_board(seen, target).corners
    # smooth within the image's pixels: the view magnifies the corners' noise by f / least
    if found is None or not cc.consistent_grid(found * (view.least / view.f), target) \
            or not cc.saddle_grid(seen, found, target):
        return None
    mapped = project_points(view.rays(found), lens)
    h, w = gray.shape
    if not np.isfinite(mapped).all() or np.any(mapped < 0) or np.any(mapped > [w - 1, h - 1]):
        return None
    return mapped
