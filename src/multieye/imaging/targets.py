"""Calibration targets: their geometry in the canonical target frame.

Every target is a frozen dataclass with ``rows``, ``cols`` and ``spacing`` as docs/rig-yaml.md
(section 3) defines them, and :meth:`object_points` giving its points, metres, in the
target frame:

================== ============================ ================================================
type               rows x cols count            spacing
================== ============================ ================================================
chessboard         inner corners                square size
circles            circles                      centre distance (rows and columns)
asymmetric-circles circles (``cols`` per row)   centre distance within a row; rows are
                                                spacing/2 apart, odd rows shifted by spacing/2
charuco            squares                      square size (points: the (rows-1)x(cols-1)
                                                inner corners, OpenCV's ChArUco ids)
aprilgrid          AprilTag 36h11 tags          tag size, black edge to black edge (Kalibr
                                                ``tagSize``); gap = ``tag_spacing`` * tag size
aruco              1 x 1 (one marker)           marker side (``marker_size``); points: its 4
                                                corners
aruco-grid         markers (OpenCV GridBoard)   marker side (``marker_size``); points: 4
                                                corners per marker
================== ============================ ================================================

Canonical frame: origin at the first point, x along ``cols``, y along ``rows``, z = x cross y.
Point ``id`` is ``row * cols_of_points + col`` (row-major), the order of ``object_points()``.
For the first four types the first point is the one OpenCV reports first on an upright
board, y runs down the printed face and z points into the board (away from a camera that
sees the pattern). The AprilGrid keeps Kalibr's frame and point ids exactly so that poses
compare with Kalibr's: tag 0 at the bottom-left of the printed sheet, origin at its
bottom-left corner, y *up* the printed face, so z points *out of* the printed face
(:attr:`Target.z_into_board` is False); point ids are Kalibr's ``2*rows`` x ``2*cols`` grid
(tag t has corners ``b, b+1, b+2C+1, b+2C`` = bottom-left, bottom-right, top-right,
top-left with ``b = (t // C) * 4C + (t % C) * 2`` and ``C = cols``).

Synopsis
--------
>>> from multieye.imaging.targets import target_from_spec
>>> board = target_from_spec({"type": "chessboard", "rows": 7, "cols": 8, "spacing": 0.033})
>>> board.object_points().shape
(56, 3)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, ClassVar

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core.arguments import did_you_mean
from multieye.core.errors import DatasetError, InputError
from multieye.core.limits import MAX_GRID_SIDE, MAX_SPACING_M
from multieye.core.target_spec import PYTHON_ONLY_KEYS, TYPE_KEYS, TargetSpec

__all__ = [
    "Target",
    "Chessboard",
    "CircleGrid",
    "AsymmetricCircleGrid",
    "Charuco",
    "AprilGrid",
    "ArucoMarker",
    "ArucoGrid",
    "TARGET_TYPES",
    "target_from_spec",
]

F64 = NDArray[np.float64]

#: Tags in Kalibr's (and OpenCV's) AprilTag 36h11 family.
APRILTAG_36H11_SIZE = 587


def _grid(rows: int, cols: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Row and column index of every point, row-major."""
    r, c = np.divmod(np.arange(rows * cols), cols)
    return r, c


@dataclass(frozen=True)
class Target:
    """Base of the target types: ``rows``, ``cols``, ``spacing`` (metres).

    Subclasses define :meth:`object_points` and :meth:`bounds`.
    """

    rows: int
    cols: int
    spacing: float

    #: Name in rig.yaml ``target.type``.
    kind: ClassVar[str] = ""
    #: Smallest ``rows`` and ``cols`` that the detector accepts.
    min_size: ClassVar[int] = 3
    #: True when +z points into the board (away from a camera that sees the printed face).
    z_into_board: ClassVar[bool] = True

    def __post_init__(self):
        for name in ("rows", "cols"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise InputError(f"{self.kind} {name} must be an integer, got {value!r}")
            if value < self.min_size:
                raise InputError(f"{self.kind} {name} must be at least {self.min_size}, got {value}")
            if value > MAX_GRID_SIDE:
                raise InputError(f"{self.kind} {name} must be at most {MAX_GRID_SIDE}, got {value}")
            object.__setattr__(self, name, int(value))
        object.__setattr__(self, "spacing", _positive(self.spacing, f"{self.kind} spacing"))

    @property
    def n_points(self) -> int:
        """Number of points of the whole target."""
        return len(self.object_points())

    def object_points(self) -> F64:
        """Points of the target, shape (N, 3), metres, in the canonical target frame, by id."""
        raise NotImplementedError

    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)``, metres: extent of the printed pattern (no margin)."""
        raise NotImplementedError

    def grid_shape(self) -> tuple[int, int] | None:
        """``(rows, cols)`` of the point grid when ids are row-major over a full grid."""
        return (self.rows, self.cols)


def _positive(value: Any, name: str, maximum: float | None = MAX_SPACING_M) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} must be a number (metres), got {value!r}")
    value = float(value)
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{name} must be a positive finite number (metres), got {value}")
    if maximum is not None and value > maximum:
        raise InputError(f"{name} must be at most {maximum:g} metres, got {value:g}")
    return value


@dataclass(frozen=True)
class Chessboard(Target):
    """Chessboard with ``rows`` x ``cols`` inner corners and squares of side ``spacing``.

    The square diagonally outside the first corner (x, y in [-spacing, 0]) is black, as on
    OpenCV's printed pattern. When ``rows + cols`` is even the board looks the same after a
    half turn and the detected order cannot be resolved (the detector then warns).
    """

    kind: ClassVar[str] = "chessboard"

    def object_points(self) -> F64:
        r, c = _grid(self.rows, self.cols)
        return np.column_stack([c * self.spacing, r * self.spacing, np.zeros(r.size)])

    def bounds(self):
        s = self.spacing
        return (-s, self.cols * s, -s, self.rows * s)

    @property
    def half_turn_symmetric(self) -> bool:
        """True when the board is unchanged by a half turn (``rows + cols`` even)."""
        return (self.rows + self.cols) % 2 == 0


@dataclass(frozen=True)
class _CircleTarget(Target):
    """What the circle grids share: the circle ``diameter``, metres, optional.

    When the diameter is stated, PnP corrects the blob centroids for the offset between the
    centroid of a circle's image and the image of its centre (perspective and distortion);
    rendering draws circles of ``circle_diameter`` (default spacing/2).
    """

    diameter: float | None = None

    def __post_init__(self):
        super().__post_init__()
        if self.diameter is not None:
            d = _positive(self.diameter, f"{self.kind} diameter")
            nearest = self._neighbour_distance()
            if d >= nearest:
                raise InputError(f"{self.kind} diameter {d} must be smaller than the distance "
                                 f"between neighbouring centres ({nearest:.6g})")
            object.__setattr__(self, "diameter", d)

    def _neighbour_distance(self) -> float:
        return self.spacing

    @property
    def circle_diameter(self) -> float:
        """Diameter used for drawing, metres: ``diameter``, or spacing/2 when not stated."""
        return self.spacing / 2 if self.diameter is None else self.diameter

    def bounds(self):
        P = self.object_points()
        rad = self.circle_diameter / 2
        return (P[:, 0].min() - rad, P[:, 0].max() + rad, P[:, 1].min() - rad, P[:, 1].max() + rad)


@dataclass(frozen=True)
class CircleGrid(_CircleTarget):
    """Symmetric grid of ``rows`` x ``cols`` circles, centres ``spacing`` apart.

    The grid always looks the same after a half turn, so the detector warns that the order
    is ambiguous. ``diameter``: see :class:`_CircleTarget`.
    """

    kind: ClassVar[str] = "circles"

    def object_points(self) -> F64:
        r, c = _grid(self.rows, self.cols)
        return np.column_stack([c * self.spacing, r * self.spacing, np.zeros(r.size)])


@dataclass(frozen=True)
class AsymmetricCircleGrid(_CircleTarget):
    """Asymmetric circle grid, OpenCV's ``CALIB_CB_ASYMMETRIC_GRID`` with pattern (cols, rows).

    ``cols`` circles per row, ``spacing`` apart; ``rows`` rows ``spacing / 2`` apart, odd rows
    shifted by ``spacing / 2`` along x: point (r, c) is at ``((c + (r % 2) / 2) * spacing,
    r * spacing / 2)``. This is OpenCV's ordering (its sample uses ``(2c + r % 2) * s, r * s``
    with s = spacing / 2) and the Open3DV board's (7 x 11, 20 or 40 mm). With an odd number
    of rows the grid is not symmetric under a half turn; with an even number it is and the
    detector warns. ``diameter``: see :class:`_CircleTarget`.
    """

    kind: ClassVar[str] = "asymmetric-circles"

    def _neighbour_distance(self) -> float:
        return self.spacing / np.sqrt(2)

    def object_points(self) -> F64:
        r, c = _grid(self.rows, self.cols)
        x = (c + 0.5 * (r % 2)) * self.spacing
        return np.column_stack([x, r * self.spacing / 2, np.zeros(r.size)])


@dataclass(frozen=True)
class Charuco(Target):
    """OpenCV ChArUco board of ``rows`` x ``cols`` squares of side ``spacing``.

    Points are the (rows-1) x (cols-1) inner chessboard corners with OpenCV's ChArUco ids
    (row-major from the corner next to the top-left square); the origin is corner id 0, one
    square in from the board's outer corner. Markers of ``marker_size`` metres from the
    OpenCV dictionary ``dictionary`` (e.g. ``"DICT_5X5_100"``) sit in the white squares, ids
    from ``first_id`` (default 0; boards that share a dictionary are told apart by their id
    ranges). ``legacy=True`` selects the layout OpenCV used before 4.6 (it differs when
    ``rows`` is even).
    """

    marker_size: float = 0.0
    dictionary: str = "DICT_5X5_100"
    legacy: bool = False
    first_id: int = 0
    kind: ClassVar[str] = "charuco"

    def __post_init__(self):
        super().__post_init__()
        m = _positive(self.marker_size, "charuco marker_size")
        if m >= self.spacing:
            raise InputError(f"charuco marker_size {m} must be smaller than the square size {self.spacing}")
        object.__setattr__(self, "marker_size", m)
        if not isinstance(self.legacy, bool):
            raise InputError(f"charuco legacy must be true or false, got {self.legacy!r}")
        n_markers = (self.rows * self.cols) // 2
        available = aruco_dictionary_size(self.dictionary)
        if n_markers > available:
            raise InputError(f"charuco {self.rows}x{self.cols} needs {n_markers} markers but "
                             f"{self.dictionary} has only {available}")
        _marker_ids(self.dictionary, self.first_id, n_markers, "charuco first_id")

    @property
    def marker_ids(self) -> range:
        """The ids of the board's markers."""
        return range(self.first_id, self.first_id + (self.rows * self.cols) // 2)

    def object_points(self) -> F64:
        r, c = _grid(self.rows - 1, self.cols - 1)
        return np.column_stack([c * self.spacing, r * self.spacing, np.zeros(r.size)])

    def bounds(self):
        s = self.spacing
        return (-s, (self.cols - 1) * s, -s, (self.rows - 1) * s)

    def grid_shape(self):
        return (self.rows - 1, self.cols - 1)

    def opencv_board(self):
        """The ``cv2.aruco.CharucoBoard`` of this target. OpenCV's board frame has its origin
        at the outer corner of the top-left square, one square from the canonical origin."""

        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        ids = np.asarray(self.marker_ids, dtype=np.int32)
        board = cv2.aruco.CharucoBoard((self.cols, self.rows), self.spacing, self.marker_size,
                                       dictionary, ids)
        board.setLegacyPattern(self.legacy)
        return board


def aruco_dictionary_size(name: str) -> int:
    """Number of markers in the OpenCV predefined dictionary ``name`` (e.g. ``"DICT_5X5_100"``).

    Raises
    ------
    InputError
        When OpenCV has no dictionary of that name.
    """

    code = getattr(cv2.aruco, name, None) if isinstance(name, str) and name.startswith("DICT_") else None
    if not isinstance(code, int):
        raise InputError(f"unknown ArUco dictionary {name!r}: expected an OpenCV name such as "
                         "DICT_4X4_50, DICT_5X5_100, DICT_6X6_250 or DICT_APRILTAG_36h11")
    return int(cv2.aruco.getPredefinedDictionary(code).bytesList.shape[0])


@dataclass(frozen=True)
class AprilGrid(Target):
    """Kalibr AprilGrid: ``rows`` x ``cols`` AprilTag 36h11 tags (ids 0.. row-major from the
    bottom-left tag), tag size ``spacing`` (black edge to black edge), gap between tags
    ``tag_spacing * spacing``; black squares of the gap size fill the gap at every tag
    corner, and tags have a 2-bit black border, as ``kalibr_create_target_pdf`` draws them.

    Points: Kalibr's ``2*rows`` x ``2*cols`` tag corners (see the module docstring); partial
    views are fine since tag ids give the correspondences.  ``first_id`` (default 0, Kalibr's
    grids) shifts the tags' codes: grid tag t carries code ``first_id + t``, so that several
    grids in one room are told apart by their id ranges.
    """

    tag_spacing: float = 0.0
    first_id: int = 0
    kind: ClassVar[str] = "aprilgrid"
    min_size: ClassVar[int] = 1
    z_into_board: ClassVar[bool] = False

    def __post_init__(self):
        super().__post_init__()
        s = _positive(self.tag_spacing, "aprilgrid tag_spacing", maximum=None)
        if s > 1.0:
            raise InputError(f"aprilgrid tag_spacing is the gap as a fraction of the tag size "
                             f"(Kalibr tagSpacing, 0 < x <= 1), got {s}")
        object.__setattr__(self, "tag_spacing", s)
        if self.rows * self.cols > APRILTAG_36H11_SIZE:
            raise InputError(f"aprilgrid {self.rows}x{self.cols} needs {self.rows * self.cols} tags "
                             f"but AprilTag 36h11 has {APRILTAG_36H11_SIZE}")
        _marker_ids("DICT_APRILTAG_36h11", self.first_id, self.rows * self.cols,
                    "aprilgrid first_id")

    @property
    def pitch(self) -> float:
        """Distance between the origins of neighbouring tags, metres."""
        return self.spacing * (1 + self.tag_spacing)

    def object_points(self) -> F64:
        r, c = _grid(2 * self.rows, 2 * self.cols)
        x = (c // 2) * self.pitch + (c % 2) * self.spacing
        y = (r // 2) * self.pitch + (r % 2) * self.spacing
        return np.column_stack([x, y, np.zeros(r.size)])

    def bounds(self):
        gap = self.tag_spacing * self.spacing
        return (-gap, self.cols * self.pitch, -gap, self.rows * self.pitch)

    def grid_shape(self):
        return (2 * self.rows, 2 * self.cols)

    def tag_images(self) -> NDArray[np.float32]:
        """Every tag as printed, shape (rows * cols, 10, 10): 1 white, 0 black, a 2-bit black
        border around the 6x6 code, row 0 at the top of the sheet (+y), column 0 at -x.

        Kalibr draws AprilTag 36h11 code t turned by a half turn with respect to OpenCV's
        ``cv2.aruco.generateImageMarker`` of ``DICT_APRILTAG_36h11`` id t (checked against
        the code table of ``kalibr_create_target_pdf`` for several ids).
        """
        return _kalibr_tag_images(self.first_id + self.rows * self.cols)[self.first_id:].copy()

    def tag_corners(self, tag_id: int) -> F64:
        """Board (x, y) of a tag's corners, metres, shape (4, 2), in Kalibr's order:
        bottom-left, bottom-right, top-right, top-left as printed."""
        tr, tc = divmod(int(tag_id), self.cols)
        x0, y0, s = tc * self.pitch, tr * self.pitch, self.spacing
        return np.array([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]])

    def tag_corner_ids(self, tag_id: int) -> tuple[int, int, int, int]:
        """Point ids of a tag's corners: bottom-left, bottom-right, top-right, top-left
        (as printed; Kalibr's order)."""
        width = 2 * self.cols
        base = (tag_id // self.cols) * 2 * width + (tag_id % self.cols) * 2
        return (base, base + 1, base + width + 1, base + width)


@dataclass(frozen=True)
class ArucoMarker(Target):
    """One ArUco marker of side ``marker_size`` metres, id ``id`` of the OpenCV dictionary
    ``dictionary``.  ``rows = cols = 1`` and ``spacing`` is the marker side.

    Points: the marker's 4 outer corners in OpenCV's order (top-left, top-right,
    bottom-right, bottom-left as ``cv2.aruco.generateImageMarker`` draws it); origin at the
    top-left corner, x along the top edge, y down the printed face, z into the board.
    """

    dictionary: str = "DICT_6X6_250"
    id: int = 0
    kind: ClassVar[str] = "aruco"
    min_size: ClassVar[int] = 1

    def __post_init__(self):
        super().__post_init__()
        _marker_ids(self.dictionary, self.id, 1, "aruco id")

    @property
    def marker_size(self) -> float:
        return self.spacing

    def object_points(self) -> F64:
        s = self.spacing
        return np.array([[0.0, 0.0, 0.0], [s, 0.0, 0.0], [s, s, 0.0], [0.0, s, 0.0]])

    def bounds(self):
        return (0.0, self.spacing, 0.0, self.spacing)

    def grid_shape(self):
        return None


@dataclass(frozen=True)
class ArucoGrid(Target):
    """OpenCV ArUco ``GridBoard``: ``rows`` x ``cols`` markers of side ``marker_size``,
    ``marker_separation`` apart, ids ``first_id``, ``first_id + 1``, ... row-major from the
    top-left marker, of the OpenCV dictionary ``dictionary``.  ``spacing`` is the marker side.

    Points: 4 corners per marker, point id ``4 * k + j`` for marker ``k`` (counted from
    ``first_id``) and OpenCV's corner ``j`` (top-left, top-right, bottom-right, bottom-left);
    OpenCV's board frame: origin at the top-left corner of the first marker, x along
    ``cols``, y down the printed face, z into the board.  Partial views are fine.
    """

    marker_separation: float = 0.0
    dictionary: str = "DICT_6X6_250"
    first_id: int = 0
    kind: ClassVar[str] = "aruco-grid"
    min_size: ClassVar[int] = 1

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "marker_separation",
                           _positive(self.marker_separation, "aruco-grid marker_separation"))
        _marker_ids(self.dictionary, self.first_id, self.rows * self.cols, "aruco-grid first_id")

    @property
    def marker_size(self) -> float:
        return self.spacing

    @property
    def pitch(self) -> float:
        """Distance between the top-left corners of neighbouring markers, metres."""
        return self.spacing + self.marker_separation

    def object_points(self) -> F64:
        r, c = _grid(self.rows, self.cols)
        corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) * self.spacing
        xy = (np.column_stack([c, r]) * self.pitch)[:, None, :] + corners[None]
        return np.column_stack([xy.reshape(-1, 2), np.zeros(4 * r.size)])

    def bounds(self):
        return (0.0, self.cols * self.pitch - self.marker_separation,
                0.0, self.rows * self.pitch - self.marker_separation)

    def grid_shape(self):
        return None

    def opencv_board(self):
        """The ``cv2.aruco.GridBoard`` of this target (same frame and corners)."""

        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        ids = np.arange(self.first_id, self.first_id + self.rows * self.cols, dtype=np.int32)
        return cv2.aruco.GridBoard((self.cols, self.rows), self.spacing, self.marker_separation,
                                   dictionary, ids)


def _marker_ids(dictionary: Any, first: Any, count: int, name: str) -> None:
    """Check that ``dictionary`` is an OpenCV dictionary holding ids ``first .. first+count-1``."""
    if not isinstance(dictionary, str):
        raise InputError(f"dictionary must be an OpenCV name such as DICT_6X6_250, got {dictionary!r}")
    available = aruco_dictionary_size(dictionary)
    if isinstance(first, bool) or not isinstance(first, (int, np.integer)) or first < 0:
        raise InputError(f"{name} must be a marker id (an integer >= 0), got {first!r}")
    if first + count > available:
        raise InputError(f"{name} {first} needs ids up to {first + count - 1} but {dictionary} "
                         f"has ids 0 to {available - 1}")


@lru_cache(maxsize=4)
def _kalibr_tag_images(n: int) -> NDArray[np.float32]:
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    out = np.zeros((n, 10, 10), dtype=np.float32)
    for t in range(n):
        img = cv2.aruco.generateImageMarker(dictionary, t, 8, borderBits=1)
        out[t, 2:8, 2:8] = np.rot90(img[1:7, 1:7], 2) / 255.0
    return out


TARGET_TYPES: dict[str, type[Target]] = {
    cls.kind: cls for cls in (Chessboard, CircleGrid, AsymmetricCircleGrid, Charuco, AprilGrid,
                              ArucoMarker, ArucoGrid)
}

#: The keys per type (besides ``type``), mapped to dataclass fields; None = required: rig.yaml's
#: schema (:mod:`multieye.core.target_spec`) and the keys only a Python caller gives.
_SPEC_KEYS: dict[str, dict[str, Any]] = {
    kind: {**TYPE_KEYS[kind], **PYTHON_ONLY_KEYS.get(kind, {})} for kind in TYPE_KEYS}


def target_from_spec(spec: TargetSpec | Mapping[str, Any], *, path=None,
                     line: int | None = None) -> Target:
    """Build a target from rig.yaml's target (a :class:`~multieye.core.target_spec.TargetSpec`
    as :func:`multieye.io.load_rig` reads it) or from the same ``target:`` mapping
    (docs/rig-yaml.md, section 3).

    Parameters
    ----------
    spec : TargetSpec or mapping
        ``type`` (chessboard | circles | asymmetric-circles | charuco | aprilgrid), ``rows``,
        ``cols``, ``spacing`` (metres); charuco also ``marker_size`` (metres) and
        ``dictionary`` (OpenCV name, e.g. ``DICT_5X5_100``), optionally ``legacy``; aprilgrid
        also ``tag_spacing`` (Kalibr ratio); circle grids optionally ``diameter`` (metres).
        ``aruco``: ``marker_size``, ``dictionary``, ``id`` only; ``aruco-grid``: ``rows``,
        ``cols``, ``marker_size``, ``marker_separation``, ``dictionary``, optionally
        ``first_id`` (0).
    path, line : optional
        Where the mapping came from, for the error message.

    Returns
    -------
    Target

    Raises
    ------
    DatasetError
        Not a mapping, unknown ``type``, unknown or missing key, or a value of the wrong type
        or range; the message names the key and what was expected.
    """
    def fail(message: str):
        raise DatasetError(f"target: {message}", path=path, line=line)

    if isinstance(spec, TargetSpec):     # its fields that the type takes, as the mapping
        spec = {"type": spec.type, **{k: getattr(spec, k) for k in TYPE_KEYS[spec.type]
                                      if getattr(spec, k) is not None}}

    if not isinstance(spec, Mapping):
        fail(f"expected a mapping with type, rows, cols, spacing; got {type(spec).__name__}")
    kind = spec.get("type")
    if kind not in TARGET_TYPES:
        fail(f"unknown type {kind!r}{did_you_mean(kind, TARGET_TYPES)}; expected one of "
             f"{', '.join(TARGET_TYPES)}")
    allowed = _SPEC_KEYS[kind]
    unknown = sorted(set(spec) - set(allowed) - {"type"}, key=str)
    if unknown:
        fail(f"unknown key {unknown[0]!r}{did_you_mean(unknown[0], list(allowed))} for type "
             f"{kind}; expected keys: type, {', '.join(allowed)}")
    missing = [k for k, v in allowed.items() if v is None and k not in spec]
    if missing:
        fail(f"{kind} needs key {missing[0]!r} (keys: type, {', '.join(allowed)})")
    kwargs = {k: spec[k] for k in allowed if k in spec}
    cls = TARGET_TYPES[kind]
    if kind in ("aruco", "aruco-grid"):
        kwargs["spacing"] = kwargs.pop("marker_size")
        if kind == "aruco":
            kwargs.update(rows=1, cols=1)
    if kind == "charuco" and not isinstance(kwargs["dictionary"], str):
        fail(f"charuco dictionary must be an OpenCV name such as DICT_5X5_100, got {kwargs['dictionary']!r}")
    try:
        return cls(**kwargs)
    except InputError as exc:
        fail(str(exc))
