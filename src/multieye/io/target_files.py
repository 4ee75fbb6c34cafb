"""Other tools' descriptions of a calibration board, read as rig.yaml's ``target:`` keys
(docs/rig-yaml.md, section 3: ``target: {file: april_6x6.yaml}``).

A lab that calibrated with Kalibr or BoofCV has its board described in that tool's file; this
module reads the file into the mapping rig.yaml's ``target:`` takes (``type``, ``rows``,
``cols``, ``spacing``, ...), which :func:`multieye.io.rig_targets.read_target` then checks as
if it had been typed.  What each format holds and how it maps:

- **Kalibr** (its target YAML, ``target_type``):

  - ``aprilgrid``: ``tagCols``, ``tagRows``, ``tagSize`` (metres), ``tagSpacing`` (a fraction
    of the tag size) -> ``aprilgrid`` with ``cols``, ``rows``, ``spacing``, ``tag_spacing``;
  - ``checkerboard``: ``targetCols``, ``targetRows`` (inner corners), ``rowSpacingMeters``,
    ``colSpacingMeters`` (the square) -> ``chessboard``; the two spacings must agree (1e-9
    relative): multieye's squares are square;
  - ``circlegrid``: ``targetCols``, ``targetRows``, ``spacingMeters``, ``asymmetricGrid`` ->
    ``circles`` with ``spacing`` = ``spacingMeters``; asymmetric: ``asymmetric-circles``
    with ``spacing`` = 2 ``spacingMeters`` (Kalibr puts point (r, c) at x = (2c + r mod 2)
    ``spacingMeters``, y = r ``spacingMeters``; multieye's ``spacing`` is the centre distance
    within a row).

- **Basalt** (``aprilgrid_6x6.json``: ``tagCols``, ``tagRows``, ``tagSize``, ``tagSpacing``,
  no ``target_type``): an AprilGrid as Kalibr's.

- **BoofCV** (a serialised ``ConfigCalibrationTarget``: ``type`` and ``grid``) : ``CHESSBOARD``
  (the default when ``type`` is absent; ``numRows``, ``numCols`` count squares) ->
  ``chessboard`` of ``numRows - 1`` x ``numCols - 1`` inner corners; ``CIRCLE_GRID``
  (``numRows`` x ``numCols`` circles, ``shapeDistance`` the centre distance) -> ``circles``.
  BoofCV's sizes carry no unit (its sample files give ``shapeSize: 1.0``), so the file gives
  the layout only and rig.yaml must give ``spacing:`` in metres beside ``file:``.

Every other kind (Kalibr's or BoofCV's) is refused with one line naming the file, the line and
what multieye reads.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from multieye.io.yamlfile import YamlDocument, load_yaml, shown

__all__ = ["target_from_file", "NEEDS_SPACING"]

#: What :func:`target_from_file` returns in place of a spacing the file cannot give in metres.
NEEDS_SPACING = "needs-spacing"

_BOOF_KEY = "boofcv.alg.fiducial.calib.ConfigCalibrationTarget"
#: Basalt's AprilGrid file (``aprilgrid_6x6.json``): Kalibr's keys without ``target_type``.
_BASALT_KEYS = ("tagCols", "tagRows", "tagSize", "tagSpacing")


def target_from_file(path: Path) -> tuple[dict, str]:
    """The ``target:`` mapping a Kalibr or BoofCV target file describes, and the tool's name.

    Parameters
    ----------
    path : Path
        The file (a regular file; YAML within the YAML byte limit).

    Returns
    -------
    mapping : dict
        rig.yaml's target keys (``type``, ``rows``, ``cols``, ``spacing`` in metres, and
        ``tag_spacing`` for an AprilGrid); ``spacing`` is :data:`NEEDS_SPACING` where the
        file has no unit (BoofCV).
    tool : str
        ``"Kalibr"``, ``"Basalt"`` or ``"BoofCV"``.

    Raises
    ------
    DatasetError
        At the file's line: not a mapping, neither format, a kind multieye does not detect, a
        missing or non-numeric key, a checkerboard with unequal row and column spacings.
    """
    doc = load_yaml(path, what="target file")
    data = doc.data
    if isinstance(data, Mapping) and "target_type" in data:
        return _kalibr(doc), "Kalibr"
    if isinstance(data, Mapping) and set(_BASALT_KEYS) <= set(data):
        return _basalt(doc), "Basalt"
    if isinstance(data, Mapping) and _BOOF_KEY in data:
        return _boofcv(doc), "BoofCV"
    raise doc.error("expected a Kalibr target file (target_type: aprilgrid, checkerboard or "
                    f"circlegrid), Basalt's AprilGrid JSON (tagCols, tagRows, tagSize, "
                    f"tagSpacing) or BoofCV's ({_BOOF_KEY}: with its grid); or give the board's "
                    "keys in rig.yaml (docs/rig-yaml.md, section 3)")


def _value(doc: YamlDocument, raw: Mapping, keys: tuple, key: str, *, integer: bool = False):
    if key not in raw:
        raise doc.error(f"missing key {key!r}", *keys)
    v = raw[key]
    ok = isinstance(v, int) if integer else isinstance(v, (int, float))
    if isinstance(v, bool) or not ok:
        raise doc.error(f"expected {'an integer' if integer else 'a number'}, got {shown(v)}",
                        *keys, key)
    return v


def _kalibr(doc: YamlDocument) -> dict:
    raw = doc.data
    kind = raw["target_type"]
    if kind == "aprilgrid":
        return {"type": "aprilgrid", "rows": _value(doc, raw, (), "tagRows", integer=True),
                "cols": _value(doc, raw, (), "tagCols", integer=True),
                "spacing": _value(doc, raw, (), "tagSize"),
                "tag_spacing": _value(doc, raw, (), "tagSpacing")}
    if kind == "checkerboard":
        row, col = (_value(doc, raw, (), k) for k in ("rowSpacingMeters", "colSpacingMeters"))
        if abs(row - col) > 1e-9 * max(abs(row), abs(col)):
            raise doc.error(f"rowSpacingMeters ({row:g}) and colSpacingMeters ({col:g}) differ: "
                            "multieye's chessboard squares are square", "colSpacingMeters")
        return {"type": "chessboard", "rows": _value(doc, raw, (), "targetRows", integer=True),
                "cols": _value(doc, raw, (), "targetCols", integer=True), "spacing": row}
    if kind == "circlegrid":
        asym = raw.get("asymmetricGrid", False)
        if not isinstance(asym, bool):
            raise doc.error(f"expected true or false, got {shown(asym)}", "asymmetricGrid")
        spacing = _value(doc, raw, (), "spacingMeters")
        return {"type": "asymmetric-circles" if asym else "circles",
                "rows": _value(doc, raw, (), "targetRows", integer=True),
                "cols": _value(doc, raw, (), "targetCols", integer=True),
                "spacing": 2 * spacing if asym else spacing}
    raise doc.error(f"Kalibr target_type {shown(kind)}: expected aprilgrid, checkerboard or "
                    "circlegrid", "target_type")


def _basalt(doc: YamlDocument) -> dict:
    raw = doc.data
    for key in raw:
        if key not in _BASALT_KEYS:
            raise doc.error(f"not a key of Basalt's AprilGrid file (expected "
                            f"{', '.join(_BASALT_KEYS)})", key)
    return {"type": "aprilgrid", "rows": _value(doc, raw, (), "tagRows", integer=True),
            "cols": _value(doc, raw, (), "tagCols", integer=True),
            "spacing": _value(doc, raw, (), "tagSize"),
            "tag_spacing": _value(doc, raw, (), "tagSpacing")}


def _boofcv(doc: YamlDocument) -> dict:
    config = doc.data[_BOOF_KEY]
    at = (_BOOF_KEY,)
    if not isinstance(config, Mapping) or not isinstance(config.get("grid"), Mapping):
        raise doc.error("expected a mapping with 'grid' (numRows, numCols, shapeSize)", *at)
    kind = config.get("type", "CHESSBOARD")
    grid, at_grid = config["grid"], at + ("grid",)
    rows = _value(doc, grid, at_grid, "numRows", integer=True)
    cols = _value(doc, grid, at_grid, "numCols", integer=True)
    if kind == "CHESSBOARD":
        return {"type": "chessboard", "rows": rows - 1, "cols": cols - 1,
                "spacing": NEEDS_SPACING}
    if kind == "CIRCLE_GRID":
        _value(doc, grid, at_grid, "shapeDistance")
        return {"type": "circles", "rows": rows, "cols": cols, "spacing": NEEDS_SPACING}
    raise doc.error(f"BoofCV target type {shown(kind)}: multieye reads CHESSBOARD and "
                    "CIRCLE_GRID; give other boards' keys in rig.yaml (docs/rig-yaml.md, "
                    "section 3)", *at, "type")

