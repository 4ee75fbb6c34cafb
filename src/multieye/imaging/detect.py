"""Find a calibration target in an image: point ids, pixels and object points in canonical order.

=================== ==================================================================
target              detector
=================== ==================================================================
chessboard          ``cv2.findChessboardCorners`` (the classic detector), where it fails
                    ``cv2.findChessboardCornersSB``, each at half size first on images
                    of 800 px and more (the order: ``chessboard_corners.search_order``);
                    then ``cv2.cornerSubPix`` at full size, the grid checked
circles             ``cv2.findCirclesGrid`` on the image and on its negative (dark
asymmetric-circles  circles on light and light on dark), default blob detector, then a
                    permissive one, then clustering
charuco             ``cv2.aruco.CharucoDetector`` (partial views; ids from the markers)
aprilgrid           ``cv2.aruco.ArucoDetector`` with ``DICT_APRILTAG_36h11`` and a 2-bit
                    marker border as Kalibr prints it; the tags found seed a search of
                    the rest of the grid; tag corners refined with ``cv2.cornerSubPix``
                    and every tag checked against its code (partial views; ids from
                    the tags)
=================== ==================================================================

Canonical order (grid targets): OpenCV's order is only defined up to the symmetries of the
grid (it may start from any corner that keeps its rows and columns). The detected grid is
reordered so that (1) the target frame is right-handed with z into the board, i.e. the map
from the board to the image keeps orientation, and (2) for a chessboard whose half turn
swaps the colours (``rows + cols`` odd), the square next to the first corner is black (see
:class:`~multieye.imaging.targets.Chessboard`). When a symmetry of the board leaves the
order undecidable (``rows + cols`` even, symmetric circle grids, asymmetric grids with an
even number of rows, square grids) the order whose x axis points most to the right in the
image is kept, :attr:`Detection.warnings` says so; the rig decides (:mod:`.order_turn`).

Synopsis
--------
>>> from multieye.imaging.detect import detect                      # doctest: +SKIP
>>> det = detect(cv2.imread("cam0/1.5.png"), board)                 # doctest: +SKIP
>>> det.ids, det.image_points, det.object_points, det.warnings      # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from multieye.core.errors import InputError
from multieye.imaging import chessboard_corners as cc
from multieye.imaging.image_file import to_8_bits
from multieye.imaging.small_markers import at_twice_the_size
from multieye.imaging.targets import (
    AprilGrid,
    ArucoGrid,
    ArucoMarker,
    AsymmetricCircleGrid,
    Charuco,
    Chessboard,
    CircleGrid,
    Target,
)

__all__ = ["Detection", "detect", "detect_or_why", "to_gray", "canonical_order"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Detection:
    """The target points found in one image.

    Attributes
    ----------
    ids : ndarray of int, shape (N,)
        Point ids (rows of ``target.object_points()``), increasing.
    image_points : ndarray, shape (N, 2)
        Pixels, float64; pixel (0, 0) is the centre of the top-left pixel.
    object_points : ndarray, shape (N, 3)
        The same points in the canonical target frame, metres.
    warnings : tuple of str
        Problems the caller should pass on (e.g. an order that the board's symmetry leaves
        undecided).
    circle_diameter : float or None
        Circle grids whose target states its ``diameter``: that diameter, metres. The image
        points are then blob centroids, which sit off the image of the circle centres under
        perspective and distortion; :func:`~multieye.imaging.pnp.estimate_pose` corrects for it.
    """

    ids: NDArray[np.int64]
    image_points: F64
    object_points: F64
    warnings: tuple[str, ...] = ()
    circle_diameter: float | None = None

    def __len__(self) -> int:
        return len(self.ids)


def to_gray(image: ArrayLike) -> NDArray[np.uint8]:
    """8-bit grayscale copy of an image: (H, W) or (H, W, 1|3|4) BGR(A), uint8 or uint16/float.

    Other bit depths are scaled by their maximum to 0..255.
    """
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim == 3 and img.shape[2] in (3, 4):
        if img.dtype != np.uint8:
            img = _to_uint8(img)
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
    if img.ndim != 2 or min(img.shape) < 8:
        raise InputError(f"image must be (H, W) or (H, W, 3) with sides of at least 8 pixels, got {img.shape}")
    return np.ascontiguousarray(_to_uint8(img))


def _to_uint8(img: np.ndarray) -> NDArray[np.uint8]:
    # one scaling for every source: a bag's 16-bit message and the same pixels as a 16-bit
    # PNG file give the same 8-bit image (rounded, not truncated)
    return img if img.dtype == np.uint8 else to_8_bits(img)


def detect(image: ArrayLike, target: Target) -> Detection | None:
    """Detect ``target`` in ``image``.

    Parameters
    ----------
    image : array_like
        Grayscale (H, W) or BGR (H, W, 3) image, see :func:`to_gray`.
    target : Target

    Returns
    -------
    Detection or None
        None when the target is not found: a grid target must be found whole; a ChArUco
        board or an AprilGrid needs at least 4 points (one tag, or four inner corners).

    Notes
    -----
    Degenerate cases: a board seen very obliquely or blurred may be missed (None), never
    half-ordered; a grid board whose symmetry leaves the order undecided is returned with a
    warning (see the module docstring); several AprilTags with the same id (a stray tag in
    view) are dropped, with a warning.
    """
    return detect_or_why(image, target)[0]


def detect_or_why(image: ArrayLike, target: Target) -> tuple[Detection | None, str]:
    """:func:`detect`, and when it finds nothing, what it can say about why.

    Returns
    -------
    detection : Detection or None
    why : str
        Empty when found or when nothing more is known; for a chessboard whose every grid
        found had a corner of the board one square beyond it
        (:func:`multieye.imaging.chessboard_corners.whole_board`): ``"part of the board is
        outside the image, or it has more inner corners than R x C"``.
    """
    gray = to_gray(image)
    if isinstance(target, Chessboard):
        return _detect_chessboard(gray, target)
    return _detect_other(gray, target), ""


def _detect_other(gray: NDArray[np.uint8], target: Target) -> Detection | None:
    """:func:`detect` for every target but the chessboard."""
    if isinstance(target, (CircleGrid, AsymmetricCircleGrid)):
        return _detect_circles(gray, target)
    if isinstance(target, Charuco):
        return _detect_charuco(gray, target)
    if isinstance(target, (AprilGrid, ArucoMarker, ArucoGrid)):     # small markers: 2x too
        find = _detect_aprilgrid if isinstance(target, AprilGrid) else _detect_aruco
        return find(gray, target) or at_twice_the_size(find, gray, target)
    raise InputError(f"no detector for target type {type(target).__name__}")


# --------------------------------------------------------------------------- grids

def _detect_chessboard(gray: NDArray[np.uint8], target: Chessboard) -> tuple[Detection | None, str]:
    """The classic ``findChessboardCorners`` first, ``findChessboardCornersSB`` only where it
    fails or leaves a corner off the grid (each at half size first on large images); the
    corners refined with ``cornerSubPix`` at full size in a window of 40 % of a square
    (:func:`multieye.imaging.chessboard_corners.locate_board`), then put in the canonical
    order (:func:`canonical_order`), so that the order and ids do not depend on the detector that
    found them (the two start from opposite corners of some boards).

    The classic detector is much faster than SB (1.6 against 22 ms per 800 x 600 rendered
    image at half size; docs/results/detection_speed.md) and, once both are refined by
    ``cornerSubPix``, as accurate. SB finds boards the classic misses (strong blur, boards
    at the image border), so it stays as the fallback. SB's own CALIB_CB_ACCURACY costs 4x
    the time and gained nothing over cornerSubPix on its corners (PnP RMS on the
    young_mocap_cam images).  Nothing found: why, when every grid found had a corner of the
    board beyond it (:func:`detect_or_why`)."""
    located = cc.locate_board(gray, target)
    if located.corners is None:
        return None, (f"part of the board is outside the image, or it has more inner "
                      f"corners than {target.rows} x {target.cols}" if located.beyond else "")
    return canonical_order(gray, target, located.corners), ""


#: Per circle target, whether its circles were last found light on dark: tried first next
#: time, which halves the search on a folder of images of one board.
_LIGHT_CIRCLES_FIRST: dict[Target, bool] = {}


def _detect_circles(gray: NDArray[np.uint8], target: CircleGrid | AsymmetricCircleGrid) -> Detection | None:
    """findCirclesGrid with OpenCV's default blob detector, then a permissive one (circles of
    8 px area up to the whole board), then with clustering; each on the image (dark circles)
    and on its negative (light circles), the polarity that worked last time first."""
    size = (target.cols, target.rows)
    grid = cv2.CALIB_CB_ASYMMETRIC_GRID if isinstance(target, AsymmetricCircleGrid) else cv2.CALIB_CB_SYMMETRIC_GRID
    permissive = _blob_detector(gray.shape[0] * gray.shape[1] / (target.rows * target.cols))
    attempts = ((grid, None), (grid, permissive), (grid | cv2.CALIB_CB_CLUSTERING, None))
    polarities = (True, False) if _LIGHT_CIRCLES_FIRST.get(target, False) else (False, True)
    for flags, blobs in attempts:
        for light in polarities:
            img = 255 - gray if light else gray
            if blobs is None:
                found, centres = cv2.findCirclesGrid(img, size, flags=flags)
            else:
                found, centres = cv2.findCirclesGrid(img, size, flags=flags, blobDetector=blobs)
            if found:
                _LIGHT_CIRCLES_FIRST[target] = light
                return canonical_order(gray, target, centres.reshape(-1, 2).astype(np.float64))
    return None


def _blob_detector(max_area: float):
    """Dark-blob detector for circles from 8 px area up to ``max_area`` px."""
    params = cv2.SimpleBlobDetector_Params()
    params.minArea = 8.0
    params.maxArea = float(max(max_area, 100.0))
    params.minDistBetweenBlobs = 3.0
    return cv2.SimpleBlobDetector_create(params)


@lru_cache(maxsize=32)
def _symmetries(target: Target) -> tuple[tuple[NDArray[np.int64], bool], ...]:
    """Index permutations of the point grid that an isometry of the board induces.

    Each entry ``(perm, proper)``: object point ``perm[k]`` is where an isometry (a rotation
    when ``proper``, else a reflection) takes object point k. Candidates are the grid's
    flips (and transposes of a square grid); only those that keep the point set are kept.
    """
    rows, cols = target.grid_shape()
    P = target.object_points()[:, :2]
    idx = np.arange(rows * cols).reshape(rows, cols)
    candidates = [idx, idx[::-1, :], idx[:, ::-1], idx[::-1, ::-1]]
    if rows == cols:
        candidates += [c.T for c in candidates]
    out = []
    for cand in candidates:
        perm = cand.ravel()
        A = P - P.mean(axis=0)
        B = P[perm] - P[perm].mean(axis=0)
        U, _, Vt = np.linalg.svd(A.T @ B)
        Q = U @ Vt                               # best orthogonal map A -> B (Procrustes)
        if np.allclose(A @ Q, B, atol=1e-9 * target.spacing + 1e-12):
            out.append((perm, bool(np.linalg.det(Q) > 0)))
    return tuple(out)


@dataclass(frozen=True)
class _Orders:
    """What :func:`canonical_order` needs of a grid target, computed once per target.

    Attributes
    ----------
    object_points : ndarray, shape (N, 3)
    pinv : ndarray, shape (2, N)
        Pseudo-inverse of the centred board (x, y): ``(pinv @ centred pixels).T`` is the
        linear part of the least-squares affine map from the board to the pixels.
    sources : tuple of (ndarray, bool)
        Per symmetry of the board (:func:`_symmetries`): ``source`` with ``source[c]`` the
        detected index that lands on canonical point c, and whether it is a rotation.
    squares : ndarray, shape (S, 4)
        Inner squares of the grid as indices of their corners (of the detected grid, which
        OpenCV returns row by row like the canonical one).
    black : tuple of ndarray
        Chessboards: per symmetry, the squares (rows of ``squares``) that its order expects
        black; empty otherwise.
    """

    object_points: F64
    pinv: F64
    sources: tuple[tuple[NDArray[np.int64], bool], ...]
    squares: NDArray[np.int64]
    black: tuple[NDArray[np.int64], ...]


@lru_cache(maxsize=32)
def _orders(target: Target) -> _Orders:
    obj = target.object_points()
    obj.setflags(write=False)
    xy = obj[:, :2] - obj[:, :2].mean(axis=0)
    sources = tuple((np.argsort(perm), proper) for perm, proper in _symmetries(target))
    if not isinstance(target, Chessboard):
        return _Orders(obj, np.linalg.pinv(xy), sources, np.zeros((0, 4), np.int64), ())
    squares = _square_corners(target)
    index = {frozenset(corners): k for k, corners in enumerate(squares.tolist())}
    expected = squares[_expected_black(target)]
    black = tuple(np.array(sorted(index[frozenset(c)] for c in src[expected].tolist()))
                  for src, _ in sources)
    return _Orders(obj, np.linalg.pinv(xy), sources, squares, black)


def _affine(orders: _Orders, img: F64) -> F64:
    """2x2 linear part of the least-squares affine map from board (x, y) to pixels."""
    return (orders.pinv @ (img - np.add.reduce(img, axis=0) / len(img))).T     # centred


def canonical_order(gray: NDArray[np.uint8], target: Target, detected: F64) -> Detection:
    """Reorder a full-grid detection (OpenCV's order) into the canonical order.

    Candidate orders are the board's symmetries applied to the detected order; kept are
    those with the canonical handedness, then (chessboard) the one whose colours fit the
    image best; ties left by the board's symmetry are broken by the direction of the x
    axis in the image (towards its lower right) and reported.
    """
    orders = _orders(target)
    proper_id = np.linalg.det(_affine(orders, detected)) > 0
    # source[c] = detected index that lands on canonical point c
    kept = [k for k, (_, proper) in enumerate(orders.sources) if proper == proper_id]
    warnings: tuple[str, ...] = ()
    if isinstance(target, Chessboard):
        grey = _square_greys(gray, detected, orders.squares)
        total = grey.sum()
        scores = []
        for k in kept:                          # white minus black, in mean grey
            black = orders.black[k]
            dark = grey[black].sum()
            scores.append((total - dark) / (len(grey) - len(black)) - dark / len(black))
        best = orders.black[kept[int(np.argmax(scores))]]
        kept = [k for k in kept if np.array_equal(orders.black[k], best)]
    sources = [orders.sources[k][0] for k in kept]
    if len(sources) > 1:
        # x towards (1, 1): upright and quarter-turned boards are both far from the tie
        x_dirs = [_affine(orders, detected[src])[:, 0] for src in sources]
        sources = [sources[int(np.argmax([(x[0] + x[1]) / math.sqrt(x @ x) for x in x_dirs]))]]
        warnings = (f"{target.kind} {target.rows}x{target.cols} looks the same after a turn, so its "
                    "point order cannot be told from the image; the order whose x axis points "
                    "towards the image's lower right was taken, the rig's geometry then decides "
                    "(a board without that symmetry, e.g. a chessboard with rows + cols odd, "
                    "decides each image by itself)",)
    return Detection(ids=np.arange(len(orders.object_points)), image_points=detected[sources[0]],
                     object_points=orders.object_points.copy(), warnings=warnings,
                     circle_diameter=getattr(target, "diameter", None))


def _square_corners(target: Chessboard) -> NDArray[np.int64]:
    """Canonical ids of the 4 corners of every inner square, shape (n_squares, 4)."""
    r, c = np.divmod(np.arange((target.rows - 1) * (target.cols - 1)), target.cols - 1)
    first = r * target.cols + c
    return np.column_stack([first, first + 1, first + target.cols, first + target.cols + 1])


def _expected_black(target: Chessboard) -> NDArray[np.bool_]:
    """Per inner square (canonical, row-major): black? (the square at the first corner is)."""
    r, c = np.divmod(np.arange((target.rows - 1) * (target.cols - 1)), target.cols - 1)
    return (r + c) % 2 == 0


#: Offsets of a 3 x 3 box of pixels, shape (9, 2).
_BOX_OFFSETS = np.stack(np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]), axis=-1).reshape(9, 2)


def _square_greys(gray: NDArray[np.uint8], corners: F64, squares: NDArray[np.int64]) -> F64:
    """Mean grey of a 3 x 3 box at the centre of every square (its 4 corners' mean), read
    bilinearly: the same as sampling the image blurred by a 3 x 3 box, without blurring the
    whole image.  Shape (S,)."""
    centres = np.add.reduce(corners[squares], axis=1) / 4         # the 4 corners' mean
    pts = (centres[:, None, :] + _BOX_OFFSETS[None]).reshape(1, -1, 2).astype(np.float32)
    samples = cv2.remap(gray, pts[..., 0], pts[..., 1], cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE)
    return np.add.reduce(samples.reshape(len(centres), 9).astype(np.float64), axis=1) / 9


# --------------------------------------------------------------------------- markers

@lru_cache(maxsize=8)
def _charuco_detector(target: Charuco):
    return cv2.aruco.CharucoDetector(target.opencv_board())


def _detect_charuco(gray: NDArray[np.uint8], target: Charuco) -> Detection | None:
    # OpenCV places the corners by local homographies of the markers and refines them with
    # cornerSubPix in a window that stays clear of the markers; refining again does not help
    corners, ids, _, _ = _charuco_detector(target).detectBoard(gray)
    if ids is None or len(ids) < 4:
        return None
    ids = ids.ravel().astype(np.int64)
    order = np.argsort(ids)
    ids = ids[order]
    return Detection(ids=ids, image_points=corners.reshape(-1, 2)[order].astype(np.float64),
                     object_points=target.object_points()[ids])


@lru_cache(maxsize=8)
def _aruco_detector(dictionary: str):
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)),
                                   params)


def _detect_aruco(gray: NDArray[np.uint8], target: ArucoMarker | ArucoGrid) -> Detection | None:
    """OpenCV's ArUco detector with sub-pixel corner refinement; markers of the target only.

    A marker id seen more than once (a stray copy in view) is dropped with a warning.
    """
    corners, ids, _ = _aruco_detector(target.dictionary).detectMarkers(gray)
    if ids is None:
        return None
    ids = ids.ravel().astype(np.int64)
    corners = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    first = target.id if isinstance(target, ArucoMarker) else target.first_id
    count = target.rows * target.cols
    unique, counts = np.unique(ids, return_counts=True)
    repeated = unique[counts > 1]
    keep = (ids >= first) & (ids < first + count) & ~np.isin(ids, repeated)
    mine = repeated[(repeated >= first) & (repeated < first + count)]
    warnings = ((f"ArUco ids {sorted(mine.tolist())} seen more than once (a marker that is not "
                 "on the target is in view); dropped",) if len(mine) else ())
    if not keep.any():
        return None
    point_ids = ((ids[keep] - first)[:, None] * 4 + np.arange(4)[None]).ravel()
    pts = corners[keep].reshape(-1, 2)
    order = np.argsort(point_ids)
    ids_out = point_ids[order].astype(np.int64)
    return Detection(ids=ids_out, image_points=pts[order],
                     object_points=target.object_points()[ids_out], warnings=warnings)


#: Kalibr corner (0 bottom-left, 1 bottom-right, 2 top-right, 3 top-left, as printed) of
#: OpenCV's marker corners 0..3 (top-left, top-right, bottom-right, bottom-left of the
#: marker as OpenCV draws it): Kalibr prints each tag a half turn from OpenCV's drawing.
_KALIBR_CORNER_OF_CV = (1, 0, 3, 2)

#: Largest number of the 100 cells of a tag (border included) allowed to read wrong.
_MAX_BAD_CELLS = 4


@lru_cache(maxsize=1)
def _apriltag_detector():
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = 2
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    return cv2.aruco.ArucoDetector(dictionary, params)


def _detect_aprilgrid(gray: NDArray[np.uint8], target: AprilGrid) -> Detection | None:
    """Tags found by OpenCV's marker detector, then grown over the grid.

    Kalibr's black squares touch every tag corner, so the contour of a tag often merges with
    them and OpenCV's contour-based detector misses the tag (most tags below ~40 px). Each tag
    found seeds a search of its neighbours: their corners are predicted by a homography fitted
    to the tags found nearby, refined as X-junctions (``cv2.cornerSubPix``) and accepted only
    when the image read through them matches the tag's own code and border.
    """
    corners, ids, _ = _apriltag_detector().detectMarkers(gray)
    if ids is None:
        return None
    ids = ids.ravel()
    corners = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    warnings: tuple[str, ...] = ()
    unique, counts = np.unique(ids, return_counts=True)
    repeated = unique[counts > 1]
    if len(repeated):
        warnings = (f"AprilTag ids {sorted(repeated.tolist())} seen more than once (a tag that is not "
                    "on the grid is in view); dropped",)
    images = target.tag_images()
    found: dict[int, F64] = {}
    for code, quad in zip(ids, corners):
        t = int(code) - target.first_id               # the grid's tag (ids from first_id)
        if 0 <= t < target.rows * target.cols and code not in repeated:
            kalibr = np.empty((4, 2))
            kalibr[list(_KALIBR_CORNER_OF_CV)] = quad
            refined = _refine_tag(gray, target, images[t], t, kalibr)
            if refined is not None:
                found[t] = refined
    _grow_aprilgrid(gray, target, images, found)
    _check_against_neighbours(gray, target, images, found)
    if not found:
        return None
    point_ids = np.array([target.tag_corner_ids(t) for t in found]).ravel()
    pts = np.concatenate([found[t] for t in found])
    order = np.argsort(point_ids)
    ids_out = point_ids[order].astype(np.int64)
    return Detection(ids=ids_out, image_points=pts[order], object_points=target.object_points()[ids_out],
                     warnings=warnings)


def _refine_tag(gray, target: AprilGrid, expected: NDArray, tag: int, quad: F64) -> F64 | None:
    """Corners of one tag refined as X-junctions (Kalibr order), or None if they do not hold up.

    The window stays inside the 2-bit border and the gap square around each corner; the
    tag is rejected when a corner leaves its window or the image, or the tag read through
    the refined corners does not match ``expected`` (see :func:`_tag_matches`).
    """
    h, w = gray.shape
    side = np.mean(np.linalg.norm(quad - np.roll(quad, 1, axis=0), axis=1))
    half = int(np.clip(np.floor(0.8 * min(0.2, target.tag_spacing) * side), 2, 15))
    if np.any(quad < half + 1) or np.any(quad[:, 0] > w - half - 2) or np.any(quad[:, 1] > h - half - 2):
        return None
    refined = cc.refine_corners(gray, quad, half)
    if np.any(np.linalg.norm(refined - quad, axis=1) >= half):
        return None
    return refined if _tag_matches(gray, target, expected, tag, refined) else None


def _tag_matches(gray, target: AprilGrid, expected: NDArray, tag: int, quad: F64) -> bool:
    """Whether the image, read on the tag's 10x10 cells through ``quad``, shows ``expected``.

    Cells are sampled at their centres (bilinear) through the homography from the tag's
    board corners to ``quad``; the threshold is halfway between the means of the cells
    expected black and white. At most :data:`_MAX_BAD_CELLS` of the 100 may disagree, and
    black and white must differ by 15 grey levels. AprilTag 36h11 codes differ in at least
    11 bits under any rotation, so a wrong tag or a misplaced quad does not pass.
    """
    board = target.tag_corners(tag)
    H = cv2.getPerspectiveTransform(board.astype(np.float32), quad.astype(np.float32))
    b = target.spacing / 10
    i, j = np.mgrid[0:10, 0:10]
    cells = np.column_stack([(board[0, 0] + (j + 0.5) * b).ravel(),
                             (board[0, 1] + (9 - i + 0.5) * b).ravel()])
    uv = cv2.perspectiveTransform(cells.reshape(-1, 1, 2), H).reshape(-1, 2).astype(np.float32)
    values = cv2.remap(gray, uv[:, 0].reshape(1, -1), uv[:, 1].reshape(1, -1), cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_REPLICATE).ravel().astype(np.float64)
    white = expected.ravel() > 0.5
    lo, hi = values[~white].mean(), values[white].mean()
    if hi - lo < 15:
        return False
    bad = np.sum((values > (lo + hi) / 2) != white)
    return bool(bad <= _MAX_BAD_CELLS)


def _grow_aprilgrid(gray, target: AprilGrid, images: NDArray, found: dict[int, F64]) -> None:
    """Add to ``found`` the tags next to found ones that :func:`_refine_tag` confirms."""
    queue = list(found)
    tried: set[int] = set(found)
    while queue:
        t = queue.pop()
        tr, tc = divmod(t, target.cols)
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                r, c = tr + dr, tc + dc
                n = r * target.cols + c
                if not (0 <= r < target.rows and 0 <= c < target.cols) or n in tried:
                    continue
                tried.add(n)
                quad = _predict_tag(target, found, n)
                if quad is None:
                    continue
                refined = _refine_tag(gray, target, images[n], n, quad)
                if refined is not None:
                    found[n] = refined
                    queue.append(n)


def _check_against_neighbours(gray, target: AprilGrid, images: NDArray, found: dict[int, F64]) -> None:
    """Re-place tags whose corners disagree with their neighbours.

    A corner that starts a few pixels off can settle on the far corner of the gap square
    (another X-junction) while the tag still reads right. Each tag with found neighbours is
    compared with the prediction from those neighbours alone; a corner off by more than a
    third of the gap is refined again from the prediction, and the tag is dropped if it
    still disagrees.
    """
    for t in sorted(found):
        predicted = _predict_tag(target, found, t, exclude_self=True)
        if predicted is None:
            continue
        quad = found[t]
        side = np.mean(np.linalg.norm(quad - np.roll(quad, 1, axis=0), axis=1))
        limit = max(1.0, target.tag_spacing * side / 3)
        if np.all(np.linalg.norm(quad - predicted, axis=1) <= limit):
            continue
        again = _refine_tag(gray, target, images[t], t, predicted)
        if again is not None and np.all(np.linalg.norm(again - predicted, axis=1) <= limit):
            found[t] = again
        else:
            del found[t]


def _predict_tag(target: AprilGrid, found: dict[int, F64], tag: int, *,
                 exclude_self: bool = False) -> F64 | None:
    """Image corners of ``tag`` by a homography fitted to the found tags around it."""
    tr, tc = divmod(tag, target.cols)
    near = [t for t in found if max(abs(t // target.cols - tr), abs(t % target.cols - tc)) <= 1
            and not (exclude_self and t == tag)]
    if not near:
        return None
    board = np.concatenate([target.tag_corners(t) for t in near])
    image = np.concatenate([found[t] for t in near])
    H, _ = cv2.findHomography(board, image, 0)
    if H is None:
        return None
    return cv2.perspectiveTransform(target.tag_corners(tag).reshape(-1, 1, 2), H).reshape(4, 2)
