"""The calibration target as rig.yaml's ``target:`` describes it (docs/rig-yaml.md,
section 3): the one schema, shared by the reader of rig.yaml (:mod:`multieye.io.rig`, which
checks each key where it is written) and the target geometry (:mod:`multieye.imaging.targets`,
which builds a board from a :class:`TargetSpec` or from the same mapping in Python).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

__all__ = ["TargetSpec", "TARGET_TYPES", "TARGET_KEYS", "TYPE_KEYS", "PYTHON_ONLY_KEYS",
           "owners", "grid_keys"]

#: The target types, in the order messages list them.
TARGET_TYPES = ("chessboard", "circles", "asymmetric-circles", "charuco", "aprilgrid", "aruco",
                "aruco-grid")

#: Per type, the keys of rig.yaml's ``target:`` besides ``type``: None = required,
#: ``"optional"``.  ``aruco`` and ``aruco-grid`` give the marker side as ``marker_size`` (the
#: board's ``spacing``); ``aruco`` has rows = cols = 1.
TYPE_KEYS: dict[str, dict[str, str | None]] = {
    "chessboard": {"rows": None, "cols": None, "spacing": None},
    "circles": {"rows": None, "cols": None, "spacing": None},
    "asymmetric-circles": {"rows": None, "cols": None, "spacing": None},
    "charuco": {"rows": None, "cols": None, "spacing": None, "marker_size": None,
                "dictionary": None, "first_id": "optional"},
    "aprilgrid": {"rows": None, "cols": None, "spacing": None, "tag_spacing": None,
                  "first_id": "optional"},
    "aruco": {"marker_size": None, "dictionary": None, "id": None},
    "aruco-grid": {"rows": None, "cols": None, "marker_size": None, "marker_separation": None,
                   "dictionary": None, "first_id": "optional"},
}

#: Keys a Python caller may add to the mapping (the rendered targets of the simulation), all
#: optional: circle ``diameter``, ChArUco ``legacy`` layout.
PYTHON_ONLY_KEYS: dict[str, dict[str, str]] = {
    "circles": {"diameter": "optional"},
    "asymmetric-circles": {"diameter": "optional"},
    "charuco": {"legacy": "optional"},
}

_COMMON = ("rows", "cols", "spacing")

#: Every key of rig.yaml's ``target:``, in the order messages list them.
TARGET_KEYS = ("type", *_COMMON, "marker_size", "dictionary", "tag_spacing",
               "marker_separation", "id", "first_id")


def owners(key: str) -> tuple[str, ...]:
    """The target types that take ``key`` (one of the keys beyond rows, cols, spacing)."""
    return tuple(t for t in TARGET_TYPES if key in TYPE_KEYS[t])


def grid_keys(kind: str) -> tuple[str, ...]:
    """Which of rows, cols, spacing the type ``kind`` requires."""
    return tuple(k for k in _COMMON if k in TYPE_KEYS[kind])


@dataclass(frozen=True)
class TargetSpec:
    """The calibration board (docs/rig-yaml.md, section 3; metres).

    Attributes
    ----------
    type : {"chessboard", "circles", "asymmetric-circles", "charuco", "aprilgrid", "aruco", "aruco-grid"}
    rows, cols : int
        Along the board's y and x axes, counted as the board's own tools count them.
    spacing : float
        Square size, circle centre distance, or tag size (aprilgrid), metres.
    marker_size : float or None
        ChArUco marker side, metres.
    dictionary : str or None
        ChArUco OpenCV dictionary name (``DICT_5X5_100``).
    tag_spacing : float or None
        AprilGrid gap between tags as a fraction of the tag size (Kalibr's ratio).
    marker_separation : float or None
        ``aruco-grid``: the gap between markers, metres.
    id : int or None
        ``aruco``: the marker's id.
    first_id : int or None
        ``aruco-grid``, ``charuco``, ``aprilgrid``: the id of the first marker (default 0); boards of
        several ``targets:`` in one dictionary tell themselves apart by their id ranges.

    name : str
        The board's name: ``targets:``'s ``name``, or ``"target"`` (rig.yaml's ``target:``).
    cameras : tuple of str or None
        The cameras that see this board (``targets:``'s ``cameras``); None: any camera.
    pose : tuple of 4 tuples of 4 floats, or None
        The board's given pose in the first board's frame (``T_<first>_<name>``, metres).

    ``aruco`` targets have ``rows = cols = 1``; for ``aruco`` and ``aruco-grid`` ``spacing`` is
    the marker side (``marker_size``), which rig.yaml gives instead.
    """

    type: str
    rows: int
    cols: int
    spacing: float
    marker_size: float | None = None
    dictionary: str | None = None
    tag_spacing: float | None = None
    marker_separation: float | None = None
    id: int | None = None
    first_id: int | None = None
    name: str = "target"
    cameras: tuple[str, ...] | None = None
    pose: tuple[tuple[float, ...], ...] | None = None

    def sees(self, camera: str) -> bool:
        """Whether ``camera`` may see this board (its ``cameras``, else every camera)."""
        return self.cameras is None or camera in self.cameras

    def as_dict(self) -> dict:
        """The fields that are set, as rig.yaml's ``target:`` mapping writes them."""
        keys = TYPE_KEYS[self.type]
        return {"type": self.type, **{f.name: getattr(self, f.name) for f in fields(self)
                                      if f.name in keys and getattr(self, f.name) is not None}}
