"""What the images do contain when the target of rig.yaml is not found in them.

``multieye check`` calls :func:`suggest_target` on one or two sampled images of a camera
whose images show no target: it looks for ArUco markers and AprilTags of every OpenCV
dictionary family, then tries the target variants users get wrong (another dictionary, rows
and cols swapped, squares counted instead of inner corners or the other way round, the
ChArUco marker-to-square ratio, the legacy ChArUco layout, the other circle grid), and
returns the ``target:`` mapping that found the board, or what the images hold. The texts fit
the target type (:func:`counting_rule`): a circle grid's hint never speaks of inner corners.

Synopsis
--------
>>> hint = suggest_target([gray], {"type": "charuco", "rows": 5,   # doctest: +SKIP
...     "cols": 7, "spacing": 0.04, "marker_size": 0.03, "dictionary": "DICT_5X5_100"})
>>> hint.text                                                                    # doctest: +SKIP
"found in 1 of 1 images with another dictionary (DICT_4X4_50): write in rig.yaml
 target: {type: charuco, rows: 5, cols: 7, ...}"
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import cv2
import numpy as np

from multieye.core.errors import DatasetError, InputError
from multieye.core.target_spec import TargetSpec
from multieye.imaging.detect import detect, to_gray
from multieye.imaging.targets import target_from_spec

__all__ = ["TargetHint", "MarkerSighting", "counting_rule", "markers_in", "suggest_target",
           "MARKER_FAMILIES"]

#: What ``rows`` and ``cols`` (and the type's other keys) count, per target type.
_COUNTING = {
    "chessboard": "rows and cols count the inner corners (where four squares meet), one less "
                  "than the squares along each side",
    "circles": "rows and cols count the circles along the board's y and x axes",
    "asymmetric-circles": "cols counts the circles of one row and rows the rows (spacing/2 "
                          "apart, every other one shifted by half a spacing)",
    "charuco": "rows and cols count the squares (not the inner corners); dictionary is the "
               "OpenCV dictionary of the markers and marker_size their side",
    "aprilgrid": "rows and cols count the tags (AprilTag 36h11, Kalibr's grid); spacing is the "
                 "tag size and tag_spacing the gap as a fraction of it",
    "aruco": "dictionary and id name the one marker",
    "aruco-grid": "rows and cols count the markers; dictionary and first_id (the id of the "
                  "top-left marker) name them",
}

#: The marker families searched (the largest dictionary of each; the smallest one that holds
#: the ids seen is suggested) and the sizes of each ``DICT_<n>X<n>_<size>`` family.
MARKER_FAMILIES = ("DICT_4X4_1000", "DICT_5X5_1000", "DICT_6X6_1000", "DICT_7X7_1000",
                   "DICT_ARUCO_ORIGINAL", "DICT_ARUCO_MIP_36h12", "DICT_APRILTAG_16h5",
                   "DICT_APRILTAG_25h9", "DICT_APRILTAG_36h10", "DICT_APRILTAG_36h11")
_SIZES = (50, 100, 250, 1000)
#: Fewest markers of one dictionary (in all the images) that count as a sighting.
MIN_MARKERS = 2


def counting_rule(kind: str) -> str:
    """What ``rows``/``cols`` and the type's keys count for target type ``kind``."""
    return _COUNTING.get(kind, "see docs/rig-yaml.md, section 3")


@dataclass(frozen=True)
class MarkerSighting:
    """Markers of one OpenCV dictionary seen in the images.

    Attributes
    ----------
    dictionary : str
        The smallest predefined dictionary that holds every id seen (``DICT_4X4_50``).
    ids : tuple of int
        The distinct ids seen, ascending.
    border_bits : int
        The black border the markers were found with (Kalibr's AprilGrid tags: 2).
    family : str
        The dictionary searched (:data:`MARKER_FAMILIES`).
    """

    dictionary: str
    ids: tuple[int, ...]
    border_bits: int = 1
    family: str = ""

    @property
    def ids_text(self) -> str:
        ids = self.ids
        if len(ids) > 6 and ids[-1] - ids[0] + 1 == len(ids):
            return f"ids {ids[0]}-{ids[-1]}"
        return "ids " + ", ".join(map(str, ids[:8])) + (" ..." if len(ids) > 8 else "")


@dataclass(frozen=True)
class TargetHint:
    """What the images hold instead of rig.yaml's target.

    Attributes
    ----------
    spec : mapping or None
        The complete ``target:`` mapping that found the board (None: no variant did; the
        text then says what the images hold).
    found, tried : int
        Images with that target found, of those searched.
    why : str
        What differs from rig.yaml's target (``rows and cols swapped``).
    """

    spec: Mapping[str, Any] | None
    found: int
    tried: int
    why: str

    @property
    def yaml(self) -> str:
        """The ``target:`` line to write in rig.yaml (a YAML flow mapping)."""
        if self.spec is None:
            return ""
        return "target: {" + ", ".join(f"{k}: {_yaml_value(v)}" for k, v in self.spec.items()) + "}"

    @property
    def text(self) -> str:
        """One sentence for the screen: what was found and what to write."""
        if self.spec is None:
            return self.why
        return (f"found in {self.found} of {self.tried} images with {self.why}: write in "
                f"rig.yaml {self.yaml}")


def _yaml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


@lru_cache(maxsize=32)
def _marker_detector(dictionary: str, border_bits: int):
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = border_bits
    params.errorCorrectionRate = 0.3         # few false markers from the wrong family
    known = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    return cv2.aruco.ArucoDetector(known, params)


def _smallest(family: str, ids: Sequence[int], needed: int = 0, prefer: Any = None) -> str:
    """The smallest dictionary of ``family`` (``DICT_4X4_1000``) holding ``ids`` and at
    least ``needed`` markers; ``prefer`` (rig.yaml's) when it is of the family and large
    enough."""
    if not family.endswith("_1000"):
        return family
    top = max(max(ids, default=0) + 1, needed)
    stem = family[:-len("1000")]
    if isinstance(prefer, str) and prefer.startswith(stem) and prefer[len(stem):].isdigit() \
            and int(prefer[len(stem):]) >= top:
        return prefer
    size = next((n for n in _SIZES if n >= top), 1000)
    return f"{stem}{size}"


def markers_in(images: Sequence[np.ndarray], *, min_markers: int = MIN_MARKERS
               ) -> list[MarkerSighting]:
    """ArUco markers and AprilTags of every family in :data:`MARKER_FAMILIES`, most ids first.

    Parameters
    ----------
    images : sequence of ndarray
        Grayscale (H, W) or BGR images.

    Returns
    -------
    list of MarkerSighting
        Families with at least ``min_markers`` markers in all, the family with the most
        distinct ids first (AprilTag 36h11 also tried with Kalibr's 2-bit border).
    """
    grays = [to_gray(im) for im in images]
    out = []
    for family in MARKER_FAMILIES:
        best: tuple[int, ...] = ()
        border = 1
        for bits in ((1, 2) if family == "DICT_APRILTAG_36h11" else (1,)):
            seen: list[int] = []
            for gray in grays:
                _, ids, _ = _marker_detector(family, bits).detectMarkers(gray)
                if ids is not None:
                    seen.extend(int(i) for i in ids.ravel())
            if len(seen) > len(best):
                best, border = tuple(seen), bits
        if len(best) >= min_markers:
            ids = tuple(sorted(set(best)))
            out.append(MarkerSighting(_smallest(family, ids), ids, border, family))
    return sorted(out, key=lambda s: -len(s.ids))


def _score(images, spec: Mapping) -> tuple[int, int]:
    """(images with the target found, points found in all) for the target ``spec``."""
    try:
        target = target_from_spec(spec)
    except DatasetError:
        return 0, 0
    found = points = 0
    for gray in images:
        try:
            det = detect(gray, target)
        except (InputError, cv2.error):
            det = None
        if det is not None:
            found += 1
            points += len(det)
    return found, points


def _swapped(spec) -> dict:
    return {"rows": spec.get("cols"), "cols": spec.get("rows")}


def _chessboard_size(images) -> tuple[int, int] | None:
    """Inner corners (a, b) of the largest chessboard in the images, by OpenCV's SB detector
    with CALIB_CB_LARGER (any board of at least 3 x 3 inner corners)."""
    sizes = []
    for gray in images:
        ok, corners, meta = cv2.findChessboardCornersSBWithMeta(gray, (3, 3), cv2.CALIB_CB_LARGER)
        if ok and meta is not None:
            sizes.append(tuple(int(n) for n in meta.shape[:2]))
    return max(sizes, key=lambda ab: ab[0] * ab[1], default=None)


def _nearest_assignment(spec, a: int, b: int) -> dict:
    r, c = spec["rows"], spec["cols"]
    return ({"rows": a, "cols": b} if abs(r - a) + abs(c - b) <= abs(r - b) + abs(c - a)
            else {"rows": b, "cols": a})


def _grid_variants(spec, kind_rule: str) -> Iterator[tuple[dict, str]]:
    r, c = spec["rows"], spec["cols"]
    yield _swapped(spec), f"rows and cols swapped ({kind_rule})"
    for dr, dc in ((1, 1), (-1, -1), (1, 0), (0, 1), (-1, 0), (0, -1)):
        if r + dr > 0 and c + dc > 0:
            yield ({"rows": r + dr, "cols": c + dc},
                   f"rows {r + dr} and cols {c + dc} ({kind_rule})")


def _candidates(spec: Mapping, images, sightings: list[MarkerSighting]
                ) -> Iterator[tuple[dict, str]]:
    """Changes to ``spec`` worth trying, most likely first, with what each changes."""
    kind = spec["type"]
    rule = counting_rule(kind)
    if kind == "chessboard":
        # OpenCV's SB detector grows from 3 x 3 to the board it sees (not always all of it)
        size = _chessboard_size(images)
        sizes = [] if size is None else [_nearest_assignment(spec, *size)]
        sizes += [v for v, _ in _grid_variants(spec, rule)]
        for change in sizes:
            squares = (change["rows"], change["cols"]) == (spec["rows"] - 1, spec["cols"] - 1)
            yield change, (f"{change['rows']} x {change['cols']} inner corners"
                           + (" (squares counted instead of inner corners)" if squares else
                              f" ({rule})"))
        return
    if kind in ("circles", "asymmetric-circles"):
        other = "asymmetric-circles" if kind == "circles" else "circles"
        yield from _grid_variants(spec, rule)
        yield {"type": other}, f"type {other} ({counting_rule(other)})"
        yield {"type": other, **_swapped(spec)}, f"type {other}, rows and cols swapped"
        return
    if kind == "aprilgrid":
        yield _swapped(spec), "rows and cols swapped"
        return
    if kind == "aruco":
        for s in sightings:
            seen = spec.get("id") if spec.get("id") in s.ids else s.ids[0]
            yield ({"dictionary": s.dictionary, "id": seen},
                   f"dictionary {s.dictionary} and id {seen} (the images hold {s.ids_text})")
        return
    for s in sightings[:2]:
        changes: dict = {}
        if kind == "aruco-grid" and spec.get("first_id", 0) not in s.ids:
            changes["first_id"] = s.ids[0]
        needed = ((spec["rows"] * spec["cols"]) // 2 if kind == "charuco" else
                  changes.get("first_id", spec.get("first_id", 0)) + spec["rows"] * spec["cols"])
        changes["dictionary"] = _smallest(s.family, s.ids, needed, spec.get("dictionary"))
        for extra, what in _structure(spec, kind, rule):
            yield ({**changes, **extra},
                   f"dictionary {changes['dictionary']} (the images hold {s.ids_text})" + what)
    for extra, what in _structure(spec, kind, rule):
        if extra:
            yield extra, what.lstrip(", ")


def _structure(spec, kind: str, rule: str) -> Iterator[tuple[dict, str]]:
    yield {}, ""
    yield _swapped(spec), ", rows and cols swapped"
    if kind == "charuco":
        yield ({"rows": spec["rows"] + 1, "cols": spec["cols"] + 1},
               f", rows {spec['rows'] + 1} and cols {spec['cols'] + 1} ({rule})")
        yield {"legacy": True}, ", the layout of OpenCV before 4.6 (legacy: true)"
        yield {**_swapped(spec), "legacy": True}, ", rows and cols swapped, legacy: true"


def _charuco_ratio(images, spec: Mapping) -> float | None:
    """The markers' side over the square's, measured in the images: the board's corners give
    the homography from the image to the board, through which the markers' sides are
    measured (None when too little is seen)."""
    target = target_from_spec(spec)
    dictionary = spec["dictionary"]
    sides = []
    for gray in images:
        det = detect(gray, target)
        if det is None or len(det) < 6:
            continue
        H, _ = cv2.findHomography(det.image_points, det.object_points[:, :2])
        if H is None:
            continue
        corners, ids, _ = _marker_detector(dictionary, 1).detectMarkers(gray)
        if ids is None:
            continue
        for quad in corners:
            board = cv2.perspectiveTransform(np.asarray(quad, np.float64).reshape(-1, 1, 2), H)
            board = board.reshape(4, 2)
            sides.extend(np.linalg.norm(board - np.roll(board, 1, axis=0), axis=1))
    return float(np.median(sides)) / float(spec["spacing"]) if len(sides) >= 8 else None


def _read(image) -> np.ndarray | None:
    """A grayscale image from an array or a file (None: unreadable)."""
    if isinstance(image, np.ndarray):
        return to_gray(image)
    return cv2.imread(str(image), cv2.IMREAD_GRAYSCALE)


def suggest_target(images: Sequence[Any], spec: TargetSpec | Mapping[str, Any]
                   ) -> TargetHint | None:
    """Search the images for the board rig.yaml's ``target:`` (``spec``) fails to find.

    Parameters
    ----------
    images : sequence of ndarray or path-like
        One or two images of a camera (grayscale or BGR arrays, or image files) in which
        ``spec`` found nothing.
    spec : TargetSpec or mapping
        rig.yaml's ``target:`` mapping (docs/rig-yaml.md, section 3).

    Returns
    -------
    TargetHint or None
        The variant of ``spec`` found in the most images (then with the most points), with
        the complete mapping to write; else, when the images hold markers of some dictionary,
        a hint naming them; None when nothing was recognised.
    """
    grays = [_read(im) for im in images]
    grays = [g for g in grays if g is not None]
    if not grays:
        return None
    spec = spec.as_dict() if isinstance(spec, TargetSpec) else dict(spec)
    kind = spec.get("type")
    sightings = markers_in(grays[:1], min_markers=1 if kind == "aruco" else MIN_MARKERS)
    best = None
    for changes, why in _candidates(spec, grays, sightings):    # on the first image, then
        candidate = {**spec, **changes}                          # the best on all of them
        if candidate == spec:
            continue
        found, points = _score(grays[:1], candidate)
        if found and (best is None or points > best[0]):     # a part of a grid is found too
            best = (points, candidate, why)
    if best is not None:
        _, candidate, why = best
        found, _ = _score(grays, candidate)
        if candidate["type"] == "charuco":
            ratio = _charuco_ratio(grays, candidate)
            given = candidate["marker_size"] / candidate["spacing"]
            if ratio is not None and abs(ratio - given) > 0.1 * given:
                ratio = round(ratio * 20) / 20            # printed boards: 0.5, 0.7, 0.75 ...
                candidate["marker_size"] = float(f"{ratio * candidate['spacing']:.6g}")
                why += (f", marker_size {candidate['marker_size']:g} (the markers measure "
                        f"about {ratio:.2f} of a square, rig.yaml says {given:.2f})")
        if sightings and kind in ("chessboard", "circles", "asymmetric-circles"):
            # a ChArUco board is a chessboard too: say what else the board holds
            why += "; " + _markers_note(kind, sightings[0]).replace("hold", "also hold", 1)
        return TargetHint(candidate, found, len(grays), why)
    if sightings:
        return TargetHint(None, 0, len(grays), _markers_note(kind, sightings[0]))
    return None


def _markers_note(kind: str, s: MarkerSighting) -> str:
    """``the images hold <markers>, not the <kind> of rig.yaml: <what it may be>``."""
    what = "AprilTags" if "APRILTAG" in s.dictionary else "ArUco markers"
    border = " with a 2-bit border (Kalibr)" if s.border_bits == 2 else ""
    if s.family == "DICT_APRILTAG_36h11" and s.border_bits == 2 and kind != "aprilgrid":
        return (f"the images hold AprilTags 36h11 with a 2-bit border ({s.ids_text}), as on "
                f"Kalibr's AprilGrid, not the {kind} of rig.yaml: type: aprilgrid with rows x "
                f"cols = the tags of the grid, spacing (tag size) and tag_spacing "
                f"({counting_rule('aprilgrid')})")
    advice = {
        "chessboard": "a ChArUco board? type: charuco",
        "circles": "a ChArUco board or a marker grid? type: charuco or aruco-grid",
        "asymmetric-circles": "a ChArUco board or a marker grid? type: charuco or aruco-grid",
        "aprilgrid": "an aprilgrid is AprilTag 36h11 with a 2-bit border (Kalibr); for "
                     "other tags: type: aruco-grid",
    }.get(kind, f"type {kind}")
    target = "charuco" if kind == "chessboard" else "aruco-grid" if kind == "aprilgrid" else kind
    return (f"the images hold {what} of {s.dictionary}{border} ({s.ids_text}), not the {kind} "
            f"of rig.yaml: {advice}, with dictionary: {s.dictionary} "
            f"({counting_rule(target)})")
