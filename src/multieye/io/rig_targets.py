"""rig.yaml's boards: ``target:`` (one board) or ``targets:`` (several, each with its own
identity), read and checked for :func:`multieye.io.rig.load_rig` (docs/rig-yaml.md, section 3).

Schema of ``targets:`` (a list; each entry a ``target:`` mapping plus)::

    targets:
      - name: north                 # required when more than one; unique; a file-name-safe
        type: charuco               #   name (the board's key in calibration.json)
        ...                         # the target keys of ``target:``
        first_id: 0                 # charuco, aruco-grid, aprilgrid: boards of one family are
                                    #   told apart by their ids: the ranges must not overlap
        cameras: [cam0]             # the cameras that see this board; required for boards
                                    #   without ids (chessboard, circles) when there are
                                    #   several boards, and a camera may see one such board
        pose: [[1,0,0,x], ...]      # optional: the board's pose in the first board's frame
                                    #   (T_<first>_<name>, 4 x 4, metres), when it is known

``target:`` stays valid: it is the one board named ``"target"``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

import numpy as np

from multieye.core.limits import MAX_GRID_SIDE, MAX_SPACING_M
from multieye.core.names import NAME_RULE, camera_name_problem
from multieye.core import target_spec
from multieye.core.target_spec import TARGET_KEYS, TARGET_TYPES, TYPE_KEYS, TargetSpec, grid_keys
from multieye.io.rig_checks import Checker
from multieye.io.target_files import NEEDS_SPACING, target_from_file
from multieye.io.yamlfile import shown

__all__ = ["read_target", "read_targets", "TARGETS_ENTRY_KEYS", "marker_ids"]

#: The keys an entry of ``targets:`` takes besides those of ``target:``.
TARGETS_ENTRY_KEYS = ("name", "cameras", "pose")

#: The target keys beyond rows, cols, spacing, with the types that take them.
_TARGET_ONLY = {k: target_spec.owners(k) for k in TARGET_KEYS[4:]}

#: Types whose points carry no id: several of them are told apart by the cameras that see them.
_NO_IDS = ("chessboard", "circles", "asymmetric-circles")

#: Largest difference between a given pose's rotation and a rotation (|R^T R - I|, det).
_ROTATION_TOLERANCE = 1e-6


def read_target(c: Checker, raw, keys=("target",), more: Mapping | None = None) -> TargetSpec:
    """One board: ``target:``, a camera's ``intrinsics_target:`` or an entry of ``targets:``
    (``keys``, its key path), checked key by key; ``more`` holds the entry's ``name``,
    ``cameras`` and ``pose``, already checked (:func:`read_targets`)."""
    if isinstance(raw, str) or (isinstance(raw, Mapping) and "file" in raw):
        raw = _from_file(c, raw, keys)
    c.mapping(raw, keys, TARGET_KEYS + ("file",)       # file: read above, named in messages
              + (TARGETS_ENTRY_KEYS if more is not None else ()), ("type",))
    kind = c.choice(raw["type"], keys + ("type",), TARGET_TYPES)
    for key in grid_keys(kind):
        if key not in raw:
            raise c.error(f"missing key {key!r}", keys)
    if "spacing" not in TYPE_KEYS[kind] and "spacing" in raw:
        raise c.error(f"{kind} targets give the marker side as 'marker_size'", keys + ("spacing",))
    if kind == "aruco" and ("rows" in raw or "cols" in raw):
        raise c.error("a single marker has no rows and cols (use aruco-grid for a board)",
                      keys + ("rows" if "rows" in raw else "cols",))
    for key, owners in _TARGET_ONLY.items():
        if key in raw and kind not in owners:
            raise c.error(f"applies to {', '.join(owners)} targets only (this target is {kind})",
                          keys + (key,))
        if key not in raw and kind in owners and TYPE_KEYS[kind][key] is None:
            raise c.error(f"missing key {key!r} (required for {kind} targets)", keys)
    extra = {}
    if "marker_size" in raw:
        extra["marker_size"] = c.number(raw["marker_size"], keys + ("marker_size",),
                                        positive=True, maximum=MAX_SPACING_M, unit="metres")
    if "marker_separation" in raw:
        extra["marker_separation"] = c.number(raw["marker_separation"],
                                              keys + ("marker_separation",), positive=True,
                                              maximum=MAX_SPACING_M, unit="metres")
    for key in ("id", "first_id"):
        if key in raw:
            value = raw[key]
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise c.error(f"expected a marker id (an integer >= 0), got {shown(value)}",
                              keys + (key,))
            extra[key] = value
    if "tag_spacing" in raw:
        extra["tag_spacing"] = c.number(raw["tag_spacing"], keys + ("tag_spacing",),
                                        positive=True, maximum=1.0,
                                        unit="(a fraction of the tag size)")
    if "dictionary" in raw:
        name = c.string(raw["dictionary"], keys + ("dictionary",))
        if not name.startswith("DICT_"):
            raise c.error(f"expected an OpenCV dictionary name such as DICT_5X5_100, got "
                          f"{name!r}", keys + ("dictionary",))
        extra["dictionary"] = name
    if "spacing" not in TYPE_KEYS[kind]:
        spacing = extra["marker_size"]
    else:
        spacing = c.number(raw["spacing"], keys + ("spacing",), positive=True,
                           maximum=MAX_SPACING_M, unit="metres")
    if kind == "charuco" and extra["marker_size"] >= spacing:
        raise c.error(f"must be smaller than spacing ({spacing})", keys + ("marker_size",))
    rows, cols = (c.number(raw[k], keys + (k,), positive=True, integer=True,
                           maximum=MAX_GRID_SIDE) if k in raw else 1 for k in ("rows", "cols"))
    return TargetSpec(kind, rows, cols, spacing, **extra, **(more or {}))




def _from_file(c: Checker, raw, keys: tuple) -> dict:
    """``target: FILE`` or ``target: {file: FILE, ...}``: the board another tool's file
    describes (:func:`multieye.io.target_files.target_from_file`), with the keys given beside
    ``file:`` over the file's (a ``type`` must agree with it)."""
    given = {"file": raw} if isinstance(raw, str) else dict(raw)
    at = keys if isinstance(raw, str) else keys + ("file",)
    if isinstance(raw, str) and not (c.folder / raw).exists():
        raise c.error(f"expected the board's keys ({{type: chessboard, rows: 6, cols: 9, "
                      f"spacing: 0.03}}) or another tool's board file (Kalibr, BoofCV); no file "
                      f"{shown(raw)} beside rig.yaml", keys)
    path = c.path(given.pop("file"), at, "file")
    board, tool = target_from_file(path)
    if "type" in given and given["type"] != board["type"]:
        raise c.error(f"type {shown(given['type'])} disagrees with {path.name} ({tool}: "
                      f"{board['type']}); leave type out beside file:", keys + ("type",))
    out = {**board, **given}
    if out["spacing"] == NEEDS_SPACING:
        raise c.error(f"{path.name} ({tool}) gives the board's sizes in no stated unit: give "
                      "'spacing:' in metres beside 'file:' (e.g. {file: " + path.name +
                      ", spacing: 0.03})", keys)
    return out


def marker_ids(spec: TargetSpec) -> tuple[str, range] | None:
    """The marker family and the ids a board's markers use, or None (a board without ids).

    The family is what one detector reads: OpenCV's ``DICT_<n>X<n>_<size>`` dictionaries of
    one marker size share their first codes, so they are one family; AprilGrids use
    AprilTag 36h11 (``DICT_APRILTAG_36h11``, the same codes)."""
    if spec.type in _NO_IDS:
        return None
    if spec.type == "aprilgrid":
        first = spec.first_id or 0
        return "APRILTAG_36h11", range(first, first + spec.rows * spec.cols)
    family = re.sub(r"^DICT_(\d+X\d+)_\d+$", r"\1", spec.dictionary)
    family = family.replace("DICT_", "")       # APRILTAG_36h11 as the AprilGrids' family
    if spec.type == "aruco":
        return family, range(spec.id, spec.id + 1)
    first = spec.first_id or 0
    count = spec.rows * spec.cols // (2 if spec.type == "charuco" else 1)
    return family, range(first, first + count)


def _entry_keys(c: Checker, raw, keys: tuple, many: bool, taken: dict,
                known: tuple[str, ...]) -> dict:
    """The ``name``, ``cameras`` and ``pose`` of one entry of ``targets:``, checked."""
    if not isinstance(raw, Mapping):
        raise c.error(f"expected a mapping (a target with its name), got {type(raw).__name__}",
                      keys)
    out: dict = {}
    if "name" in raw:
        name = raw["name"]
        problem = camera_name_problem(name, taken)
        if problem is not None:
            raise c.error(f"target name {shown(name)} {problem}; a target name is "
                          f"{NAME_RULE}", keys + ("name",))
        out["name"] = name
    elif many:
        raise c.error("missing key 'name' (several targets: each is named, e.g. name: north)",
                      keys)
    if "cameras" in raw:
        cams = raw["cameras"]
        if not isinstance(cams, list) or not cams:
            raise c.error(f"expected a list of camera names, got {shown(cams)}",
                          keys + ("cameras",))
        for cam in cams:
            if not isinstance(cam, str) or cam not in known:
                raise c.error(f"no camera {shown(cam)} in cameras ({', '.join(known)})",
                              keys + ("cameras",))
        out["cameras"] = tuple(dict.fromkeys(cams))
    if "pose" in raw:
        out["pose"] = _pose(c, raw["pose"], keys + ("pose",))
    return out


def _pose(c: Checker, value, keys: tuple) -> tuple:
    """A given board pose: 4 x 4 rows of finite numbers, a rotation and translation (metres)."""
    rows = value if isinstance(value, list) and len(value) == 4 else None
    ok = rows is not None and all(isinstance(r, list) and len(r) == 4 and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) for x in r) for r in rows)
    T = np.array(rows, dtype=np.float64) if ok else None
    if T is None or not np.all(np.isfinite(T)):
        raise c.error("expected the board's pose in the first board's frame as 4 rows of 4 "
                      "numbers ([[r11, r12, r13, x], ..., [0, 0, 0, 1]], metres)", keys)
    R = T[:3, :3]
    if (not np.allclose(T[3], [0, 0, 0, 1], atol=_ROTATION_TOLERANCE)
            or np.abs(R.T @ R - np.eye(3)).max() > _ROTATION_TOLERANCE
            or abs(np.linalg.det(R) - 1) > _ROTATION_TOLERANCE):
        raise c.error("not a rigid transform: the upper-left 3 x 3 must be a rotation "
                      "(orthonormal, determinant 1) and the last row 0 0 0 1", keys)
    if np.abs(T[:3, 3]).max() > 1e4:
        raise c.error("translation beyond 10 km: expected metres", keys)
    return tuple(tuple(float(x) for x in r) for r in T)


def read_targets(c: Checker, raw: Mapping, cameras: Mapping) -> dict[str, TargetSpec]:
    """The rig's boards by name, in file order: ``targets:``, or ``target:`` as the one named
    ``"target"``; empty when there is neither.

    Raises
    ------
    DatasetError
        At the line of the key concerned: both keys, an empty list, a missing or repeated
        name, an unknown camera, overlapping marker ids of one family (naming both
        targets), a board without ids that is not told apart by its ``cameras``, a camera
        that would see two boards without ids, a pose that is not rigid or is given for the
        first board.
    """
    if "target" in raw and "targets" in raw:
        raise c.error("give either 'target' (one board) or 'targets' (a list of boards), "
                      "not both", ("targets",))
    if "targets" not in raw:
        return {"target": read_target(c, raw["target"])} if "target" in raw else {}
    entries = raw["targets"]
    if not isinstance(entries, list) or not entries:
        raise c.error("expected a list of targets, each a target mapping with its name "
                      "(docs/rig-yaml.md, section 3.1)", ("targets",))
    many, taken, out = len(entries) > 1, {}, {}
    names = tuple(cameras)
    for k, entry in enumerate(entries):
        keys = ("targets", k)
        more = _entry_keys(c, entry, keys, many, taken, names)
        if k == 0 and "pose" in more:
            raise c.error("the first target is the frame the others' poses are given in; it "
                          "takes no pose", keys + ("pose",))
        if more.get("name") in out:
            raise c.error(f"target name {shown(more['name'])} is taken by target "
                          f"{list(out).index(more['name'])}; each target has its own name",
                          keys + ("name",))
        spec = read_target(c, entry, keys, more)
        out[spec.name] = spec
    _distinct(c, out)
    return out


def _distinct(c: Checker, targets: dict[str, TargetSpec]) -> None:
    """Every board can be told from the others: marker ids of one family do not overlap;
    boards without ids have ``cameras`` and no camera sees two of them."""
    specs = list(targets.values())
    seen: list[tuple[int, str, range]] = []
    sees_plain: dict[str, int] = {}
    for k, spec in enumerate(specs):
        ids = marker_ids(spec)
        if ids is None:
            if len(specs) > 1 and spec.cameras is None:
                raise c.error(f"a {spec.type} has no ids to tell it from the other targets: "
                              "give 'cameras', the cameras that see it", ("targets", k))
            for cam in spec.cameras or ():
                if cam in sees_plain:
                    other = specs[sees_plain[cam]]
                    raise c.error(f"camera {cam} sees targets {other.name} and {spec.name}, "
                                  f"neither has ids ({other.type}, {spec.type}), so they "
                                  "cannot be told apart; a camera sees at most one board "
                                  "without ids", ("targets", k, "cameras"))
                sees_plain[cam] = k
            continue
        family, span = ids
        for j, other_family, other_span in seen:
            if family == other_family and span.start < other_span.stop \
                    and other_span.start < span.stop:
                other = specs[j]
                raise c.error(f"targets {other.name} and {spec.name} overlap in marker ids "
                              f"({_span(other_span)} and {_span(span)} of {family}): boards "
                              "are told apart by their ids; give first_id so the ranges do "
                              "not overlap", ("targets", k))
        seen.append((k, family, span))


def _span(ids: range) -> str:
    return f"id {ids.start}" if len(ids) == 1 else f"ids {ids.start}-{ids.stop - 1}"
