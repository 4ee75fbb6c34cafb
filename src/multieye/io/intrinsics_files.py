"""Camera intrinsics files -> :class:`~multieye.core.intrinsics.Intrinsics`.

:func:`read_intrinsics` recognises the format from the content:

OpenCV FileStorage (YAML starting ``%YAML:1.0``, or XML)
    Read with ``cv2.FileStorage``, the maintained reader of that format; its keys are then
    those of the mapping layouts below (``camera_matrix``, ``distortion_coefficients``,
    ``image_width``, ``image_height``, ``distortion_model``, ``fisheye_model``, ...).
Kalibr camchain (``camera_model: pinhole``)
    A single entry or a chain of ``cam0``, ``cam1``...; ``camera`` selects one by key or
    by ``camera_name`` (see :mod:`multieye.io.kalibr`).
ROS ``camera_info`` YAML, a ROS CameraInfo message, and the JSON or YAML layouts of common
toolkits (``K`` / ``dist``, ``camera_matrix`` / ``dist_coeffs``, flat ``fx fy cx cy k1 ...``)
    :mod:`multieye.io.intrinsics_mapping`.
aslam_cv's camera YAML (``type: pinhole``, ``intrinsics``, ``distortion: {type, parameters}``)
    As ETH Zurich's hand_eye_calibration writes it; also in
    :mod:`multieye.io.intrinsics_mapping`.
mrcal ``.cameramodel`` (a Python dictionary literal with ``lensmodel``)
    :mod:`multieye.io.cameramodel`.
BoofCV's camera YAML (``pinhole: {fx, ...}``, ``model: pinhole``,
``pinhole_radial_tangential``, ``omnidirectional_universal`` or ``kannala_brandt``)
    :mod:`multieye.io.boofcv` (the unified model of Mei and Rives with ``mirror_offset``;
    a symmetric Kannala-Brandt as the fisheye model).

Every key of every format is used or refused with one line naming it, except the metadata
keys each format's table in :data:`IGNORED_KEYS` lists (docs/rig-yaml.md, section 5); the
numbers are checked against :mod:`multieye.core.limits`
(:func:`~multieye.core.intrinsics.check_lens_bounds`).

``distortion_model`` names accepted everywhere: ``plumb_bob``, ``rational_polynomial``,
``radtan``, ``pinhole`` -> pinhole; ``equidistant``, ``fisheye``, ``kannala_brandt`` ->
fisheye.  The wide-angle models (unified, double-sphere, eucm) come from Kalibr camchains
(``omni``, ``ds``, ``eucm``), BoofCV files (unified) and multieye's own calibration.json.

:func:`write_opencv_intrinsics` writes OpenCV FileStorage YAML (atomically, without OpenCV),
adding ``distortion_model: fisheye`` for fisheye cameras so that the file reads back the same.
:func:`distortion_model_name` names an intrinsics' distortion model (``plumb_bob`` for 0, 4
or 5 coefficients, ``rational_polynomial`` for 8, ``thin_prism`` for 12, ``tilted`` for 14,
``equidistant`` for fisheye); :func:`camera_info_text` writes ROS ``sensor_msgs/CameraInfo``
YAML as ``camera_calibration_parsers`` does, which :func:`read_camera_info` reads back.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import WIDE_MODELS, Intrinsics, check_lens_bounds, lens_model
from multieye.io import cameramodel
from multieye.io.boofcv import (intrinsics_from_boofcv, intrinsics_from_boofcv_stereo,
                                is_boofcv, is_boofcv_stereo)
from multieye.io.atomic import write_text_atomic
from multieye.io.intrinsics_mapping import (
    DISTORTION_MODELS,
    READ_KEYS,
    has_camera_matrix,
    intrinsics_from_aslam,
    intrinsics_from_mapping,
    is_aslam,
    refuse_unknown,
)
from multieye.io.intrinsics_mapping import IGNORED_KEYS as _MAPPING_IGNORED
from multieye.io.kalibr import (
    CamchainEntry, camchain_entries, intrinsics_from_kalibr, is_camchain, kalibr_refusal,
    write_camchain)
from multieye.io.slam_configs import intrinsics_from_slam_config, slam_config_kind
from multieye.io.textfile import read_text
from multieye.io.basalt import intrinsics_from_basalt, is_basalt
from multieye.io.yamlfile import MAX_YAML_BYTES, MAX_YAML_DEPTH, YamlDocument, parse_yaml, yaml_list

__all__ = [
    "DISTORTION_MODELS",
    "IGNORED_KEYS",
    "MAX_INTRINSICS_BYTES",
    "read_intrinsics",
    "read_opencv_intrinsics",
    "read_camera_info",
    "read_kalibr_intrinsics",
    "write_opencv_intrinsics",
    "write_intrinsics_file",
    "distortion_model_name",
    "camera_info_text",
    "camera_info_note",
]

#: Largest ``.cameramodel`` file read, bytes: mrcal's carries its calibration's observations
#: (``optimization_inputs``); the other formats stop at
#: :data:`~multieye.io.yamlfile.MAX_YAML_BYTES`.
MAX_INTRINSICS_BYTES = 64_000_000

#: Keys a Kalibr camchain entry gives that multieye reads.
_KALIBR_READ = ("camera_model", "intrinsics", "distortion_model", "distortion_coeffs",
                "resolution")
#: Metadata keys ignored on purpose, per format (docs/rig-yaml.md, section 5): none changes
#: how a point projects.
IGNORED_KEYS = {
    **_MAPPING_IGNORED,
    "Kalibr camchain entry": ("T_cn_cnm1", "T_cam_imu", "timeshift_cam_imu", "rostopic",
                              "cam_overlaps", "camera_name"),
    "mrcal .cameramodel": cameramodel.IGNORED_KEYS,
}

#: Name of a pinhole camera's distortion model by its number of OpenCV coefficients.
_PINHOLE_NAMES = {0: "plumb_bob", 4: "plumb_bob", 5: "plumb_bob", 8: "rational_polynomial",
                  12: "thin_prism", 14: "tilted"}
#: The distortion models ROS's camera_info (image_geometry) knows, and their coefficient count.
_ROS_SIZES = {"plumb_bob": 5, "rational_polynomial": 8, "equidistant": 4}

_FORMATS = ("expected OpenCV FileStorage (%YAML:1.0 or XML with camera_matrix), a Kalibr "
            "camchain (camera_model, intrinsics), ROS camera_info, JSON or YAML with a camera "
            "matrix (K, camera_matrix, or fx fy cx cy), aslam_cv's camera YAML (type, "
            "intrinsics, distortion), a mrcal .cameramodel, a BoofCV camera YAML, EuRoC's "
            "sensor.yaml, camodocal's (VINS) or ORB-SLAM's camera settings, Basalt's "
            "calibration JSON")


def _read(path) -> str:
    """The file's text: the one place an intrinsics file is read (a ``.cameramodel`` up to
    :data:`MAX_INTRINSICS_BYTES`, any other up to :data:`~multieye.io.yamlfile.MAX_YAML_BYTES`)."""
    limit = MAX_INTRINSICS_BYTES if str(path).endswith(".cameramodel") else MAX_YAML_BYTES
    return read_text(path, what="intrinsics file", max_bytes=limit)


# --------------------------------------------------------------------------- OpenCV


#: Deepest nesting of ``[``/``{`` (YAML, JSON) or elements (XML) handed to OpenCV's
#: FileStorage parser, which recurses without a limit (and crashes the process on tens of
#: thousands), or to Python's JSON parser.
_MAX_OPENCV_NESTING = 32
_XML_TAG = re.compile(r"<(/?)([A-Za-z_][^\s/>]*)[^>]*?(/?)>")
_CV_WHERE = re.compile(r"\((\d+)\): (.*?)'?\s*$")


def _nesting(text: str) -> int:
    """Largest nesting of flow collections (YAML) or elements (XML) in ``text``; counted on
    the raw text (brackets inside strings too), which only errs on the safe side."""
    depth = deepest = 0
    if text.lstrip().startswith("<"):
        for close, _, empty in _XML_TAG.findall(text):
            depth = max(depth - 1, 0) if close else depth + (not empty)
            deepest = max(deepest, depth)
        return deepest
    for ch in text:
        if ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth = max(depth - 1, 0)
    return deepest


def _cv_message(exc: BaseException) -> tuple[str, int | None]:
    """What OpenCV says is wrong, and the line it names, from a cv2.error (or the SystemError
    its bindings wrap one in)."""
    import cv2  # noqa: PLC0415 (heavy: OpenCV, only for OpenCV FileStorage files)

    cause = exc if isinstance(exc, cv2.error) else (exc.__cause__ or exc.__context__ or exc)
    lines = str(cause).strip().splitlines()
    text = lines[-1].strip() if lines else type(exc).__name__
    m = _CV_WHERE.search(text)
    if m:
        return m.group(2).strip(), int(m.group(1))
    return text.split("error: ", 1)[-1], None


def _key_lines(text: str) -> dict:
    """Line of each top-level key of a FileStorage text (YAML ``key:`` at the margin, XML
    ``<key>`` one level in), for messages."""
    xml = text.lstrip().startswith("<")
    pattern = re.compile(r"^ {0,4}<([A-Za-z_]\w*)[\s>/]" if xml else
                         r"^([A-Za-z_][\w.]*)\s*:", re.M)     # ORB-SLAM's Camera.fx too
    lines: dict = {}
    for m in pattern.finditer(text):
        lines.setdefault((m.group(1),), text.count("\n", 0, m.start()) + 1)
    lines.pop(("opencv_storage",), None)
    return lines


def _opencv_document(text: str, p: Path) -> YamlDocument:
    """A FileStorage text as a mapping of its read keys (matrices as ``{rows, cols, data}``);
    the ignored keys are left unparsed and unknown keys refused."""
    import cv2  # noqa: PLC0415 (heavy: OpenCV, only for OpenCV FileStorage files)

    if _nesting(text) > _MAX_OPENCV_NESTING:
        raise DatasetError(f"FileStorage refused: nested deeper than {_MAX_OPENCV_NESTING} "
                           "levels", path=p)
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
        opened = fs.isOpened()
    except (cv2.error, SystemError) as exc:
        message, line = _cv_message(exc)
        raise DatasetError(f"OpenCV cannot parse this FileStorage file: {message}", path=p,
                           line=line) from None
    if not opened:
        raise DatasetError("OpenCV cannot open this FileStorage file", path=p)

    def value(n, name):
        if n.isInt():
            return int(n.real())
        if n.isReal():
            return n.real()
        if n.isString():
            return n.string()
        if n.isSeq():
            return [value(n.at(i), name) for i in range(n.size())]
        if n.isMap():
            keys = list(n.keys())
            if {"rows", "cols", "data"} <= set(keys):
                try:
                    mat = np.asarray(n.mat(), dtype=np.float64)
                except cv2.error as exc:
                    raise DatasetError(f"{name}: OpenCV cannot read this matrix "
                                       f"({_cv_message(exc)[0]}); rows x cols must match data",
                                       path=p) from None
                return {"rows": mat.shape[0], "cols": mat.shape[1] if mat.ndim > 1 else 1,
                        "data": mat.reshape(-1).tolist()}
            return {k: value(n.getNode(k), name) for k in keys}
        return None

    try:
        root = fs.root()
        if not root.isMap():
            raise DatasetError("expected a FileStorage map with camera_matrix (or K)", path=p)
        keys = list(root.keys())
        doc = YamlDocument(p, dict.fromkeys(keys), _key_lines(text))
        if not has_camera_matrix(doc.data) and slam_config_kind(doc.data) is not None:
            return YamlDocument(p, {k: value(fs.getNode(k), k) for k in keys}, doc.lines)
        if not has_camera_matrix(doc.data):
            raise DatasetError("no camera_matrix (or K); keys present: "
                               f"{', '.join(keys) or 'none'}", path=p)
        data = {k: value(fs.getNode(k), k) for k in keys if k in READ_KEYS}
        return YamlDocument(p, {**dict.fromkeys(keys), **data}, doc.lines)
    except (cv2.error, SystemError) as exc:
        message, line = _cv_message(exc)
        raise DatasetError(f"OpenCV cannot read this FileStorage file: {message}", path=p,
                           line=line) from None
    finally:
        fs.release()


def read_opencv_intrinsics(path: str | os.PathLike) -> Intrinsics:
    """Read OpenCV FileStorage YAML or XML (``camera_matrix``/``K``, ``distortion_*``/``D``).

    Raises
    ------
    DatasetError
        The file is missing, larger than :data:`~multieye.io.yamlfile.MAX_YAML_BYTES`, nested
        deeper than OpenCV's parser survives, OpenCV cannot parse it, a required key is
        missing (the message lists the keys present), a key is neither read nor ignored (named),
        or a value has the wrong type or range.
    """
    return _opencv(_read(path), Path(path))


def _opencv(text: str, p: Path, camera: str | None = None) -> Intrinsics:
    doc = _opencv_document(text, p)
    if slam_config_kind(doc.data) is not None:     # camodocal (VINS), ORB-SLAM settings
        return intrinsics_from_slam_config(doc, camera)
    return intrinsics_from_mapping(doc)


def write_opencv_intrinsics(path: str | os.PathLike, intr: Intrinsics) -> None:
    """Write OpenCV FileStorage YAML atomically (``cv2.FileStorage`` reads it).

    Keys: ``image_width``, ``image_height`` (when known), ``camera_matrix``,
    ``distortion_coefficients`` and, for fisheye cameras, ``distortion_model: fisheye``.

    Raises
    ------
    InputError
        A wide-angle lens (unified, double-sphere, eucm): OpenCV has no such model
        (:func:`write_intrinsics_file` writes it as a Kalibr camchain).
    """
    _no_wide(intr, "OpenCV FileStorage")
    def matrix(name, values, rows, cols):
        return [f"{name}: !!opencv-matrix", f"   rows: {rows}", f"   cols: {cols}",
                "   dt: d", f"   data: {yaml_list(values)}"]

    lines = ["%YAML:1.0", "---"]
    if intr.width is not None and intr.height is not None:
        lines += [f"image_width: {int(intr.width)}", f"image_height: {int(intr.height)}"]
    lines += matrix("camera_matrix", intr.K.reshape(-1), 3, 3)
    if intr.dist.size:
        lines += matrix("distortion_coefficients", intr.dist, 1, intr.dist.size)
    if intr.model == "fisheye":
        lines.append("distortion_model: fisheye")
    write_text_atomic(path, "\n".join(lines) + "\n")


def _no_wide(intr: Intrinsics, fmt: str) -> None:
    if intr.model in WIDE_MODELS:
        raise InputError(f"{fmt} has no {intr.model} lens model")


def write_intrinsics_file(path: str | os.PathLike, intr: Intrinsics) -> None:
    """Write a lens in a file that :func:`read_intrinsics` reads back as the same lens: OpenCV
    FileStorage (:func:`write_opencv_intrinsics`) for pinhole and fisheye lenses, a Kalibr
    camchain of one camera ``cam0`` for the wide-angle models (``omni``, ``ds``, ``eucm``;
    OpenCV has none of them)."""
    if intr.model in WIDE_MODELS:
        refusal = kalibr_refusal(intr)
        write_camchain(path, [CamchainEntry("cam0", intr, np.eye(4))],
                       comments=[f"{intr.model} lens written by multieye (Kalibr camchain: "
                                 "OpenCV FileStorage has no such model)"] + (
                           [] if refusal is None else
                           [f"Kalibr refuses this file: {refusal}; multieye reads it"]))
    else:
        write_opencv_intrinsics(path, intr)


def distortion_model_name(intr: Intrinsics) -> str:
    """The true name of an intrinsics' distortion model: ``equidistant`` (fisheye),
    ``plumb_bob`` (pinhole, 0/4/5 coefficients), ``rational_polynomial`` (8), ``thin_prism``
    (12) or ``tilted`` (14); every one reads back through :data:`DISTORTION_MODELS`."""
    if intr.model == "fisheye":
        return "equidistant"
    if intr.model in WIDE_MODELS:
        return intr.model
    return _PINHOLE_NAMES[int(intr.dist.size)]


def camera_info_note(intr: Intrinsics) -> str | None:
    """What a lens's ROS camera_info cannot say, or None: a ``pinhole-radtan4`` lens (k1 k2
    p1 p2) is written as ``plumb_bob``'s five coefficients with k3 = 0 (ROS's plumb_bob has
    five), the same projection, which reads back as ``pinhole-radtan`` (k3 freed when it is
    refined) unless rig.yaml says ``model: pinhole-radtan4``."""
    if lens_model(intr) != "pinhole-radtan4":
        return None
    return ("pinhole-radtan4 lens written as ROS's plumb_bob with k3 = 0 (the same "
            "projection); read back it is pinhole-radtan, pinhole-radtan4 with rig.yaml's "
            "model: pinhole-radtan4")


def camera_info_text(intr: Intrinsics, camera_name: str, rectification=None) -> str:
    """ROS ``sensor_msgs/CameraInfo`` YAML (``camera_calibration_parsers``' layout).

    Keys: ``image_width``, ``image_height``, ``camera_name``, ``camera_matrix``,
    ``distortion_model``, ``distortion_coefficients``, ``rectification_matrix`` (identity)
    and ``projection_matrix`` (``[K | 0]``), each matrix ``{rows, cols, data}``.  A pinhole
    lens with 0 or 4 coefficients is written as ``plumb_bob`` with the missing ones zero
    (with 4, a first comment line naming the camera says so: :func:`camera_info_note`).
    ``rectification``, ``(R, P)`` (3x3, 3x4): the camera's stereo rectification instead of
    the identity and ``[K | 0]``.

    Raises
    ------
    InputError
        A model ROS cannot name (12 or 14 coefficients: thin-prism or tilted sensor; unified,
        double-sphere, eucm), or an unknown image size (camera_info needs it).
    """
    _no_wide(intr, "ROS camera_info")
    name = distortion_model_name(intr)
    if name not in _ROS_SIZES:
        raise InputError(f"ROS camera_info names plumb_bob, rational_polynomial and "
                         f"equidistant only; this lens has {intr.dist.size} coefficients "
                         f"(OpenCV's {name.replace('_', '-')} model)")
    if intr.width is None or intr.height is None:
        raise InputError("ROS camera_info needs the image size, which these intrinsics do "
                         "not know")
    dist = np.zeros(_ROS_SIZES[name])
    dist[: intr.dist.size] = intr.dist

    def matrix(key, M):
        M = np.atleast_2d(np.asarray(M, dtype=np.float64))
        return [f"{key}:", f"  rows: {M.shape[0]}", f"  cols: {M.shape[1]}",
                f"  data: {yaml_list(M.reshape(-1))}"]

    note = camera_info_note(intr)
    lines = [f"# {json.dumps(camera_name)}: {note}"] if note else []
    lines += [f"image_width: {int(intr.width)}", f"image_height: {int(intr.height)}",
             f"camera_name: {json.dumps(camera_name)}", *matrix("camera_matrix", intr.K),
             f"distortion_model: {name}", *matrix("distortion_coefficients", dist),
             *matrix("rectification_matrix", np.eye(3) if rectification is None
                     else rectification[0]),
             *matrix("projection_matrix", np.hstack([intr.K, np.zeros((3, 1))])
                     if rectification is None else rectification[1])]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- YAML, JSON


def _kalibr(doc: YamlDocument, camera: str | None, prefer: str | None = None) -> Intrinsics:
    data = doc.data
    if "camera_model" in data:
        return _kalibr_entry(data, doc)
    entries = camchain_entries(doc)
    if camera is None and prefer is not None and len(entries) > 1:
        named = [(k, e) for k, e in entries if e.get("camera_name") == prefer]
        if len(named) == 1:             # the rig camera's own name, as multieye writes it
            return _kalibr_entry(named[0][1], doc, named[0][0])
        if any(prefer == key for key, _ in entries):
            camera = prefer
    if camera is None:
        if len(entries) != 1:
            first = entries[0][0] if entries else "cam0"
            raise doc.error(f"the camchain has {len(entries)} cameras "
                            f"({', '.join(k for k, _ in entries)}); choose one with "
                            f"intrinsics: {{file: {doc.path.name}, camera: {first}}} in "
                            "rig.yaml")
        return _kalibr_entry(entries[0][1], doc, entries[0][0])
    hits = [(k, e) for k, e in entries if camera in (k, e.get("camera_name"))]
    if len(hits) > 1:
        how = [f"entry {k}'s {'key' if k == camera else 'camera_name'}" for k, _ in hits]
        raise doc.error(f"camera {camera!r} is ambiguous in this camchain: {' and '.join(how)}; "
                        "rename a camera so that no key is another entry's camera_name",
                        hits[0][0])
    if hits:
        return _kalibr_entry(hits[0][1], doc, hits[0][0])
    names = ", ".join(k for k, _ in entries)
    raise DatasetError(f"camera {camera!r} not in the camchain; it has {names}", path=doc.path)


def _kalibr_entry(entry: Mapping, doc: YamlDocument, *keys) -> Intrinsics:
    refuse_unknown(doc, entry, _KALIBR_READ, IGNORED_KEYS["Kalibr camchain entry"], *keys)
    intr = intrinsics_from_kalibr(entry, doc, *keys)
    try:
        check_lens_bounds(intr)
    except InputError as exc:
        key = "distortion_coeffs" if str(exc).startswith("distortion") else "intrinsics"
        raise doc.error(str(exc), *keys, key) from None
    return intr


def _json(text: str, path) -> YamlDocument:
    """A JSON text as a document (duplicate keys refused; lines from the YAML parser, which
    reads JSON too, where it can)."""
    def pairs(items):
        out = {}
        for key, value in items:
            if key in out:
                raise DatasetError(f"duplicate key {key!r}", path=path)
            out[key] = value
        return out

    if _nesting(text) > MAX_YAML_DEPTH:
        raise DatasetError(f"JSON nested deeper than {MAX_YAML_DEPTH} levels", path=path)
    try:
        data = json.loads(text, object_pairs_hook=pairs)
    except json.JSONDecodeError as exc:
        try:                          # a YAML flow mapping with a quoted value
            return parse_yaml(text, path)
        except DatasetError:
            raise DatasetError(f"invalid JSON: {exc.msg}", path=path, line=exc.lineno) from None
    except (ValueError, RecursionError) as exc:      # e.g. an integer of 5000 digits
        raise DatasetError(f"invalid JSON: {str(exc)[:120]}", path=path) from None
    try:
        lines = parse_yaml(text, path).lines
    except DatasetError:
        lines = {}
    return YamlDocument(Path(path), data, lines)


_MRCAL = re.compile(r"""['"](lensmodel|lens_model)['"]\s*:|['"]distortion_model['"]\s*:\s*"""
                    r"""['"](DISTORTION|LENSMODEL)_""")


def _load(path) -> tuple[str, object]:
    """The format of an intrinsics file and what its reader takes: ``("opencv", text)``,
    ``("cameramodel", text)``, ``("kalibr", doc)`` or ``("mapping", doc)``."""
    text = _read(path)
    head = text.lstrip("\ufeff \t\r\n")
    if head.startswith(("%YAML", "<?xml", "<opencv_storage")):
        return "opencv", text
    if str(path).endswith(".cameramodel") or _MRCAL.search(text[:100_000]):
        return "cameramodel", text
    if head.startswith("{") and '"' in head[:200]:
        doc = _json(text.lstrip("\ufeff"), path)
    else:
        doc = parse_yaml(text, path)
    if not isinstance(doc.data, Mapping):
        raise DatasetError(f"not an intrinsics file: {_FORMATS}", path=path, line=1)
    if slam_config_kind(doc.data) is not None:     # before Kalibr: EuRoC has camera_model
        return "slam", doc
    if is_basalt(doc.data):
        return "basalt", doc
    if is_camchain(doc.data):
        return "kalibr", doc
    if is_boofcv(doc.data):
        return "boofcv", doc
    if is_boofcv_stereo(doc.data):
        return "boofcv-stereo", doc
    if has_camera_matrix(doc.data):
        return "mapping", doc
    if is_aslam(doc.data):
        return "aslam", doc
    raise DatasetError(f"not an intrinsics file: {_FORMATS}", path=path, line=1)


def _is_calibration_json(path) -> bool:
    """Whether a ``.json`` file starts as multieye's calibration.json (its first keys), judged
    on its first 4 KiB: such a file may be larger than an intrinsics file and has its own
    reader (:func:`multieye.io.calibration_json.read_calibration`)."""
    if not isinstance(path, (str, os.PathLike)) or Path(path).suffix.lower() != ".json" or \
            not Path(path).is_file():
        return False                            # not a path: refused by the reader below
    with open(path, "rb") as f:
        head = f.read(4096).decode("utf-8", "replace")
    return '"format_version"' in head and ('"setup"' in head or '"cameras"' in head)


def _from_calibration_json(path, camera: str | None, prefer: str | None) -> Intrinsics:
    """One camera's lens from a calibration.json of an earlier run (``camera``, else the rig
    camera of the same name ``prefer``, else the only camera)."""
    from multieye.io.calibration_json import read_calibration  # noqa: PLC0415 (only for this)

    lenses = {c.name: c.intrinsics for c in read_calibration(path).cameras
              if c.intrinsics is not None}
    name = camera if camera is not None else prefer if prefer in lenses else (
        next(iter(lenses)) if len(lenses) == 1 else None)
    if name not in lenses:
        what = f"camera {name!r} has no lens here" if name else "choose a camera"
        raise DatasetError(f"calibration.json: {what} (cameras with a lens: "
                           f"{', '.join(lenses) or 'none'}); give intrinsics: {{file: "
                           f"{Path(path).name}, camera: <name>}} in rig.yaml", path=path)
    return lenses[name].intrinsics


def read_camera_info(path: str | os.PathLike) -> Intrinsics:
    """Read ROS ``camera_info`` YAML, a CameraInfo message, or another mapping layout of
    :mod:`multieye.io.intrinsics_mapping` (YAML or JSON)."""
    kind, doc = _load(path)
    if kind != "mapping":
        raise DatasetError(f"not a ROS camera_info file (looks like {kind})", path=path)
    return intrinsics_from_mapping(doc)


def read_kalibr_intrinsics(path: str | os.PathLike, camera: str | None = None) -> Intrinsics:
    """Read one camera of a Kalibr camchain (``camera`` by key ``cam<n>`` or name)."""
    kind, doc = _load(path)
    if kind != "kalibr":
        raise DatasetError(f"not a Kalibr camchain (looks like {kind})", path=path)
    return _kalibr(doc, camera)


def read_intrinsics(path: str | os.PathLike, camera: str | None = None, *,
                    prefer: str | None = None) -> Intrinsics:
    """Read intrinsics from any supported file, recognising the format from the content.

    Parameters
    ----------
    path : path-like
    camera : str, optional
        For a Kalibr camchain with several cameras: the entry (``cam1``) or its
        ``camera_name``.  Ignored by single-camera formats.
    prefer : str, optional
        Without ``camera``, for a camchain with several cameras: the entry with this key or
        ``camera_name`` if there is one (the rig's camera name).

    Returns
    -------
    Intrinsics

    Raises
    ------
    DatasetError
        Missing or unreadable file, unrecognised format (listing the formats), unsupported
        camera or distortion model, wrong number of coefficients; with the line where known.
    """
    if _is_calibration_json(path):
        return _from_calibration_json(path, camera, prefer)
    kind, content = _load(path)
    if kind == "opencv":
        return _opencv(content, Path(path), camera)
    if kind == "slam":
        return intrinsics_from_slam_config(content, camera)
    if kind == "basalt":
        return intrinsics_from_basalt(content, camera, prefer)
    if kind == "cameramodel":
        return cameramodel.intrinsics_from_cameramodel(content, Path(path))
    if kind == "kalibr":
        return _kalibr(content, camera, prefer)
    if kind == "aslam":
        return intrinsics_from_aslam(content)
    if kind == "boofcv":
        return intrinsics_from_boofcv(content)
    if kind == "boofcv-stereo":
        return intrinsics_from_boofcv_stereo(content, camera, prefer)
    return intrinsics_from_mapping(content)
