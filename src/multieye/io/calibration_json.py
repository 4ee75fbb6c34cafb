"""``calibration.json``: the result file of ``multieye calibrate`` (docs/outputs.md, section 2).

The pipeline fills a :class:`CalibrationRecord`; :func:`write_calibration` writes it atomically
and :func:`read_calibration` reads and validates it back into the same dataclass.  Keys depend
on the setup (docs/conventions.md, section 2):

============  =====================  ==================
setup         shared unknown Y       per camera X
============  =====================  ==================
eye-to-base   ``T_marker_target``    ``T_world_cam``
eye-on-hand   ``T_world_target``     ``T_body_cam``
============  =====================  ==================

Every camera also has ``T_ref_cam`` and ``measurements_used``; optional per camera:
``residuals``, ``time_offset_s`` (motion-capture clock minus camera clock, s),
``time_offset_std_s`` (its standard deviation, when estimated in the joint problem),
``std_rot_deg``, ``std_trans_m``, ``covariance`` (6x6, rotation vector then translation) and ``rejected``
(``[{"item", "reason"}]``).  Top level: ``setup``, ``method``, ``reference_camera``, the shared
unknown, ``cameras`` (in order), ``residuals``, ``warnings`` and ``plausibility`` (what the
plausibility checks doubt: ``[{"cause", "message", "camera"}]``, ``camera`` only for a
per-camera doubt; files without it read as none).  Matrices are nested lists of
floats written with full precision, so a round trip is exact.  Keys the reader does not know
are ignored (forward compatibility); missing keys and non-rigid matrices are errors.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path

import numpy as np

from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import WIDE_MODELS, Intrinsics, lens_model
from multieye.core.lens_curve import RadialCurve
from multieye.io.atomic import write_text_atomic
from multieye.io.calibration_record import (
    FORMAT_VERSION,
    OVERLAP,
    WIDE_LENS_VERSION,
    ROLE_NAMES,
    SETUP_KEYS,
    BoardRecord,
    CalibrationRecord,
    CameraLinks,
    CameraRecord,
    IntrinsicsRecord,
    PlausibilityItem,
    PoseUncertainty,
    RejectedItem,
    Residuals,
)
from multieye.io.textfile import read_json_as

__all__ = [
    "FORMAT_VERSION",
    "SETUP_KEYS",
    "Residuals",
    "RejectedItem",
    "PlausibilityItem",
    "PoseUncertainty",
    "IntrinsicsRecord",
    "CameraRecord",
    "CalibrationRecord",
    "write_calibration",
    "read_calibration",
    "calibration_to_dict",
    "calibration_from_dict",
    "ROLE_NAMES",
    "OVERLAP",
    "CameraLinks",
    "BoardRecord",
]

# --------------------------------------------------------------------------- to / from dict


def _matrix(T: np.ndarray) -> list[list[float]]:
    return [[float(v) for v in row] for row in T]


def _residuals_dict(r: Residuals) -> dict:
    return {f.name: float(getattr(r, f.name)) for f in fields(r) if getattr(r, f.name) is not None}


def calibration_to_dict(rec: CalibrationRecord) -> dict:
    """The JSON object of a record (key order of docs/outputs.md, section 2)."""
    y_key, x_key = SETUP_KEYS.get(rec.setup, (None, None))
    cameras = {}
    for cam in rec.cameras:
        entry = ({} if cam.X is None else {x_key: _matrix(cam.X)}) | {
            "T_ref_cam": _matrix(cam.T_ref_cam), "measurements_used": cam.measurements_used}
        if cam.residuals is not None:
            entry["residuals"] = _residuals_dict(cam.residuals)
        for key in ("time_offset_s", "time_offset_std_s", "std_rot_deg", "std_trans_m"):
            if getattr(cam, key) is not None:
                entry[key] = float(getattr(cam, key))
        if cam.covariance is not None:
            entry["covariance"] = _matrix(cam.covariance)
        if cam.rejected:
            entry["rejected"] = [{"item": r.item, "reason": r.reason} for r in cam.rejected]
        if cam.intrinsics is not None:
            entry["intrinsics"] = _intrinsics_dict(cam.intrinsics)
        if cam.uncertainty:
            entry["uncertainty"] = _uncertainty_dict(cam.uncertainty)
        if cam.links is not None:
            entry["links"] = {"overlap": dict(cam.links.overlap), "mocap": cam.links.mocap}
            if cam.links.motion:
                entry["links"]["motion"] = {"cameras": list(cam.links.motion[0]),
                                            "boards": list(cam.links.motion[1])}
            if cam.links.boards:
                entry["links"]["boards"] = dict(cam.links.boards)
        cameras[cam.name] = entry
    wide = any(c.intrinsics is not None and c.intrinsics.intrinsics.model in WIDE_MODELS
               for c in rec.cameras)
    out = {"format_version": WIDE_LENS_VERSION if wide else WIDE_LENS_VERSION - 1,   # 2: as before
           "setup": rec.setup, "method": rec.method, "reference_camera": rec.reference_camera,
           **({} if rec.Y is None else {y_key: _matrix(rec.Y)}), "cameras": cameras,
           "residuals": _residuals_dict(rec.residuals), "warnings": list(rec.warnings),
           "plausibility": [{"cause": d.cause, "message": d.message}
                            | ({} if d.camera is None else {"camera": d.camera})
                            for d in rec.plausibility]}
    if rec.refinement is not None:
        out["refinement"] = rec.refinement
    if rec.motion_diagnostics is not None:
        out["motion_diagnostics"] = dict(rec.motion_diagnostics)
    if rec.uncertainty:
        out["uncertainty"] = _uncertainty_dict(rec.uncertainty)
    if rec.frames is not None:
        out["frames"] = dict(rec.frames)
    if rec.targets:
        out["targets"] = {k: {"T_world_target": _matrix(b.T_world_target), "given": b.given,
                              "views": b.views, "cameras": dict(b.cameras)} | (
            {} if b.bounds is None else {"bounds": list(b.bounds),
                                         "z_into_board": b.z_into_board}) | (
            {} if b.uncertainty is None else _uncertainty_dict({"u": b.uncertainty})["u"])
            for k, b in rec.targets.items()}
    return out


def _uncertainty_dict(unc: Mapping) -> dict:
    return {k: {"std_rot_deg": float(u.std_rot_deg), "std_trans_m": float(u.std_trans_m),
                "covariance": _matrix(u.covariance)} for k, u in unc.items()}


def _intrinsics_dict(r: IntrinsicsRecord) -> dict:
    I = r.intrinsics
    return {"model": lens_model(I),
            "image_size": None if I.width is None else [I.width, I.height],
            "K": _matrix(I.K), "distortion": [float(v) for v in I.dist],
            "estimated": bool(r.estimated),
            "covariance": None if r.covariance is None else _matrix(r.covariance),
            "projection_std_px": None if r.projection_std_px is None else {
                "mean": float(r.projection_std_px[0]), "max": float(r.projection_std_px[1])}
            } | ({} if r.lens_curve is None else {"lens_curve": {
                "angles_deg": [float(v) for v in r.lens_curve.angles_deg],
                "radii_px": [float(v) for v in r.lens_curve.radii_px],
                "covariance": _matrix(r.lens_curve.covariance)}})


def _read_uncertainty(obj, w: _Where, keys: tuple[str, ...], camera=None) -> dict:
    if not isinstance(obj, Mapping) or not set(obj) <= set(keys):
        raise w.error(f"uncertainty must be an object with keys among {', '.join(keys)}",
                      camera)
    out = {}
    for k, v in obj.items():
        if not isinstance(v, Mapping):
            raise w.error(f"uncertainty.{k} must be an object", camera)
        out[k] = w.call(PoseUncertainty, w.number(w.need(v, "std_rot_deg", k, camera),
                                                  f"uncertainty.{k}.std_rot_deg", camera),
                        w.number(w.need(v, "std_trans_m", k, camera),
                                 f"uncertainty.{k}.std_trans_m", camera),
                        w.call(np.asarray, w.need(v, "covariance", k, camera),
                               dtype=np.float64, camera=camera),
                        camera=camera)
    return out


#: ``intrinsics.model`` names (:func:`multieye.core.intrinsics.lens_model`) and the numbers
#: of ``distortion`` each has.
_MODEL_SIZES = {"pinhole-radtan": (0, 5), "pinhole-radtan4": (4,), "pinhole-rational": (8,),
                "pinhole-thin-prism": (12,), "pinhole-tilted": (14,), "fisheye": (4,),
                "unified": (5,), "double-sphere": (2,), "eucm": (2,)}


def _no_booleans(value, key: str, w: _Where, camera):
    """``value`` (numbers, nested lists) unless it holds a boolean (JSON's true / false),
    which numpy would read as 1 / 0."""
    items = value if isinstance(value, list) else [value]
    for v in (x for item in items for x in (item if isinstance(item, list) else [item])):
        if isinstance(v, bool):
            raise w.error(f"intrinsics.{key} must be numbers, got {v}", camera)
    return value


def _read_intrinsics(obj, w: _Where, camera, version: int) -> IntrinsicsRecord:
    if not isinstance(obj, Mapping):
        raise w.error("intrinsics must be an object", camera)
    model = w.need(obj, "model", "intrinsics", camera)
    if model in WIDE_MODELS and version < WIDE_LENS_VERSION:
        raise w.error(f"intrinsics.model {model} needs format_version {WIDE_LENS_VERSION} or "
                      f"later, the file says {version}", camera)
    if model not in _MODEL_SIZES:
        raise w.error(f"intrinsics.model {model!r} is not one of {', '.join(_MODEL_SIZES)}",
                      camera)
    kind = model if model in WIDE_MODELS else "fisheye" if model == "fisheye" else "pinhole"
    size = obj.get("image_size")
    if size is not None and (not isinstance(size, list) or len(size) != 2 or None in size):
        raise w.error("intrinsics.image_size must be [width, height] or null", camera)
    K, dist = (_no_booleans(w.need(obj, key, "intrinsics", camera), key, w, camera)
               for key in ("K", "distortion"))
    dist = w.call(np.asarray, dist, np.float64, camera=camera)
    if dist.ndim == 1 and dist.size not in _MODEL_SIZES[model]:
        raise w.error(f"intrinsics.model {model} does not match its {dist.size} distortion "
                      f"numbers (expected {' or '.join(map(str, _MODEL_SIZES[model]))})",
                      camera)
    intr = w.call(Intrinsics, w.call(np.asarray, K, np.float64, camera=camera), dist,
                  kind, *(size or (None, None)), camera=camera)
    cov = obj.get("covariance")
    if cov is not None:
        cov = w.call(np.asarray, cov, dtype=np.float64, camera=camera)
        n = intr.params.size
        if cov.shape != (n, n) or not np.all(np.isfinite(cov)):
            raise w.error(f"intrinsics.covariance must be a finite {n}x{n} matrix", camera)
    proj = obj.get("projection_std_px")
    if proj is not None:
        if not isinstance(proj, Mapping):
            raise w.error("intrinsics.projection_std_px must be {mean, max} or null", camera)
        proj = (w.number(w.need(proj, "mean", "projection_std_px", camera),
                         "projection_std_px.mean", camera),
                w.number(w.need(proj, "max", "projection_std_px", camera),
                         "projection_std_px.max", camera))
    estimated = obj.get("estimated", False)
    if not isinstance(estimated, bool):
        raise w.error("intrinsics.estimated must be true or false", camera)
    curve = obj.get("lens_curve")
    return IntrinsicsRecord(intr, estimated, cov, proj,
                            None if curve is None else _read_lens_curve(curve, w, camera))


def _read_lens_curve(obj, w: _Where, camera) -> RadialCurve:
    """``intrinsics.lens_curve`` (optional; files without it read as None)."""
    message = ("intrinsics.lens_curve must be {angles_deg: [n], radii_px: [n], covariance: "
               "n x n}, finite, the covariance symmetric")
    if not isinstance(obj, Mapping) or not {"angles_deg", "radii_px", "covariance"} <= set(obj):
        raise w.error(message, camera)
    try:
        a, r, c = (np.asarray(obj[k], np.float64)
                   for k in ("angles_deg", "radii_px", "covariance"))
    except (TypeError, ValueError):
        raise w.error(message, camera) from None
    n = a.size
    if (a.shape != (n,) or r.shape != (n,) or c.shape != (n, n) or n == 0
            or not all(np.all(np.isfinite(v)) for v in (a, r, c)) or not np.allclose(c, c.T)):
        raise w.error(message, camera)
    return RadialCurve(a, r, c)


def _read_links(obj, w: _Where, camera) -> CameraLinks:
    if not isinstance(obj, Mapping) or not isinstance(obj.get("overlap", {}), Mapping):
        raise w.error('links must be {"overlap": {camera: instants}, "mocap": true/false}',
                      camera)
    motion = obj.get("motion")
    if motion is not None and not (isinstance(motion, Mapping) and set(motion) == {
            "cameras", "boards"}):
        raise w.error('links.motion must be {"cameras": [...], "boards": [...]}', camera)
    boards = obj.get("boards", {})
    if not isinstance(boards, Mapping):
        raise w.error('links.boards must be {board: views}', camera)
    return w.call(CameraLinks, dict(obj.get("overlap", {})), obj.get("mocap", False),
                  () if motion is None else (motion["cameras"], motion["boards"]),
                  dict(boards), camera=camera)


class _Where:
    """Builds DatasetErrors for one file."""

    def __init__(self, path):
        self.path = path

    def error(self, message: str, camera: str | None = None) -> DatasetError:
        return DatasetError(message, path=self.path, camera=camera)

    def need(self, obj: Mapping, key: str, where: str, camera=None):
        if key not in obj:
            raise self.error(f"missing key {key!r}" + ("" if camera else f" in {where}"), camera)
        return obj[key]

    def number(self, value, key: str, camera=None) -> float:
        if (isinstance(value, bool) or not isinstance(value, (int, float))
                or not math.isfinite(value)):
            raise self.error(f"{key} must be a finite number, got {value!r}", camera)
        return float(value)

    def call(self, fn, *args, camera=None, **kwargs):
        try:
            return fn(*args, **kwargs)
        except (InputError, TypeError, ValueError, OverflowError) as exc:
            message = str(exc).removeprefix(f"camera {camera}: ")
            raise self.error(message, camera) from None


def _read_residuals(obj, w: _Where, where: str, camera=None) -> Residuals:
    if not isinstance(obj, Mapping):
        raise w.error(f"{where} must be an object with e_R_deg and e_t_m", camera)
    values = {}
    for f in fields(Residuals):
        if f.name in obj:
            values[f.name] = w.number(obj[f.name], f"{where}.{f.name}", camera)
        elif f.default is not None:
            raise w.error(f"missing key {f.name!r} in {where}", camera)
    return Residuals(**values)


def calibration_from_dict(data, path: str | os.PathLike | None = None) -> CalibrationRecord:
    """Validate a parsed ``calibration.json`` object into a record.

    Raises
    ------
    DatasetError
        Missing keys, unknown setup, non-numeric values, non-rigid matrices, a covariance that
        is not 6x6, a reference camera that is not listed.
    """
    w = _Where(path)
    if not isinstance(data, Mapping):
        raise w.error("expected a JSON object")
    version = data.get("format_version", 1)
    if (isinstance(version, bool) or not isinstance(version, int)
            or not 1 <= version <= FORMAT_VERSION):
        raise w.error(f"format_version must be an integer from 1 to {FORMAT_VERSION} (a newer "
                      f"multieye writes later versions), got {version!r}")
    setup = w.need(data, "setup", "the top level")
    if not isinstance(setup, str) or (setup not in SETUP_KEYS and (setup != OVERLAP
                                                                     or version < 2)):
        raise w.error(f"setup must be one of {', '.join(SETUP_KEYS)}" + (
            f" or {OVERLAP}" if version >= 2 else "") + f", got {setup!r}")
    y_key, x_key = SETUP_KEYS.get(setup, (None, None))
    cams = w.need(data, "cameras", "the top level")
    if not isinstance(cams, Mapping) or not cams:
        raise w.error("cameras must be a non-empty object of camera name -> result")
    records = []
    for name, entry in cams.items():
        if not isinstance(entry, Mapping):
            raise w.error("expected an object", name)
        kw = {}
        for key in ("time_offset_s", "time_offset_std_s", "std_rot_deg", "std_trans_m"):
            if key in entry:
                kw[key] = w.number(entry[key], key, name)
        if "residuals" in entry:
            kw["residuals"] = _read_residuals(entry["residuals"], w, "residuals", name)
        if "covariance" in entry:
            kw["covariance"] = w.call(np.asarray, entry["covariance"], dtype=np.float64,
                                      camera=name)
        rejected = entry.get("rejected", [])
        if not isinstance(rejected, list) or not all(
                isinstance(r, Mapping) and isinstance(r.get("item"), str)
                and isinstance(r.get("reason"), str) for r in rejected):
            raise w.error("rejected must be a list of {\"item\": str, \"reason\": str}", name)
        kw["rejected"] = tuple(RejectedItem(r["item"], r["reason"]) for r in rejected)
        if "intrinsics" in entry and entry["intrinsics"] is not None:
            kw["intrinsics"] = _read_intrinsics(entry["intrinsics"], w, name, version)
        if "uncertainty" in entry:
            kw["uncertainty"] = _read_uncertainty(entry["uncertainty"], w, tuple(
                k for k in (x_key, "T_ref_cam") if k is not None), name)
        if "links" in entry:
            kw["links"] = _read_links(entry["links"], w, name)
        X = None if x_key is None else w.call(
            np.asarray, w.need(entry, x_key, f"camera {name}", name), dtype=np.float64,
            camera=name)
        T_ref = w.call(np.asarray, w.need(entry, "T_ref_cam", f"camera {name}", name),
                       dtype=np.float64, camera=name)
        used = w.need(entry, "measurements_used", f"camera {name}", name)
        records.append(w.call(CameraRecord, str(name), X, T_ref, used, camera=name, **kw))
    Y = None if y_key is None else w.call(np.asarray, w.need(data, y_key, "the top level"),
                                          dtype=np.float64)
    warnings = data.get("warnings", [])
    if not isinstance(warnings, list) or not all(isinstance(s, str) for s in warnings):
        raise w.error("warnings must be a list of strings")
    residuals = _read_residuals(w.need(data, "residuals", "the top level"), w, "residuals")
    for key in ("method", "reference_camera"):
        if not isinstance(w.need(data, key, "the top level"), str):
            raise w.error(f"{key} must be a string")
    refinement = data.get("refinement")
    if refinement is not None and not isinstance(refinement, str):
        raise w.error("refinement must be a string")
    motion = data.get("motion_diagnostics")
    if motion is not None and not isinstance(motion, Mapping):
        raise w.error("motion_diagnostics must be an object of camera name -> numbers")
    doubts = data.get("plausibility", [])       # absent from files of older versions
    if not isinstance(doubts, list) or not all(
            isinstance(d, Mapping) and isinstance(d.get("cause"), str)
            and isinstance(d.get("message"), str)
            and isinstance(d.get("camera", ""), str) for d in doubts):
        raise w.error('plausibility must be a list of {"cause": str, "message": str, '
                      '"camera": str (optional)}')
    items = tuple(PlausibilityItem(d["cause"], d["message"], d.get("camera")) for d in doubts)
    unc = (_read_uncertainty(data["uncertainty"], w, (y_key,) if y_key else ())
           if "uncertainty" in data else None)
    frames = data.get("frames")           # absent from files of older versions
    if frames is not None and not (isinstance(frames, Mapping)
                                   and all(isinstance(v, str) for v in frames.values())):
        raise w.error("frames must be an object of role -> frame name")
    return w.call(CalibrationRecord, setup, data["method"], data["reference_camera"], Y,
                  tuple(records), residuals, tuple(warnings), refinement, motion, items, unc,
                  frames, _read_targets(data["targets"], w) if "targets" in data else None)


def _read_targets(obj, w: _Where) -> dict:
    """``targets``: name -> ``{"T_world_target", "given", "views", "cameras", "std_rot_deg",
    "std_trans_m", "covariance", "bounds", "z_into_board"}`` (the last two optional)."""
    if not isinstance(obj, Mapping) or not all(isinstance(v, Mapping) for v in obj.values()):
        raise w.error("targets must be an object of board name -> {T_world_target, ...}")
    out = {}
    for k, v in obj.items():
        T = w.call(np.asarray, w.need(v, "T_world_target", f"target {k}"), dtype=np.float64)
        rest = {x: y for x, y in v.items() if x in ("std_rot_deg", "std_trans_m",
                                                     "covariance")}
        unc = _read_uncertainty({k: rest}, w, (k,))[k] if rest else None
        cams = v.get("cameras", {})
        if not isinstance(cams, Mapping):
            raise w.error(f"targets.{k}.cameras must be an object of camera name -> views")
        bounds = v.get("bounds")          # absent from files of older versions
        out[str(k)] = w.call(BoardRecord, T, v.get("given", False), v.get("views", 0),
                             dict(cams), unc, None if bounds is None else w.call(
                                 np.asarray, bounds, dtype=np.float64),
                             v.get("z_into_board", True))
    return out
# --------------------------------------------------------------------------- files


def write_calibration(path: str | os.PathLike, rec: CalibrationRecord) -> None:
    """Write ``calibration.json`` atomically (a failed run leaves no partial file)."""
    text = json.dumps(calibration_to_dict(rec), indent=2, allow_nan=False)
    write_text_atomic(path, text + "\n")


def read_calibration(path: str | os.PathLike) -> CalibrationRecord:
    """Read and validate ``calibration.json``.

    Raises
    ------
    DatasetError
        Missing file, invalid JSON (with the line), or any check of
        :func:`calibration_from_dict`.
    """
    path = Path(path)
    if not path.exists() and (path.parent / "rig.yaml").exists():
        raise DatasetError("calibration file not found: this folder holds rig.yaml, a dataset; "
                           "give the output folder of multieye calibrate (its -o OUT)", path=path)
    return read_json_as(path, calibration_from_dict, what="calibration file")
