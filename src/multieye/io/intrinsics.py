"""Camera intrinsics files -> :class:`~multieye.core.intrinsics.Intrinsics`.

:func:`read_intrinsics` recognises the format from the content:

OpenCV FileStorage (YAML starting ``%YAML:1.0``, or XML)
    Read with ``cv2.FileStorage``, the maintained reader of that format.  Keys:
    ``camera_matrix`` (or ``K``), ``distortion_coefficients`` (or ``D``) with 0, 4, 5, 8, 12 or
    14 coefficients in OpenCV's order, optional ``image_width`` / ``image_height`` and an
    optional ``distortion_model`` string (see below; without it the model is pinhole).
Kalibr camchain (``camera_model: pinhole``)
    A single entry or a chain of ``cam0``, ``cam1``...; ``camera`` selects one by key or
    by ``camera_name`` (see :mod:`multieye.io.kalibr`).
ROS ``camera_info`` YAML (``camera_matrix: {rows, cols, data}``)
    ``distortion_model`` ``plumb_bob`` / ``rational_polynomial`` (pinhole) or ``equidistant``
    (fisheye), ``distortion_coefficients: {rows, cols, data}``, ``image_width``,
    ``image_height``.  Plain YAML with ``K`` / ``D`` lists is read the same way.

``distortion_model`` names accepted everywhere: ``plumb_bob``, ``rational_polynomial``,
``radtan``, ``pinhole`` -> pinhole; ``equidistant``, ``fisheye``, ``kannala_brandt`` ->
fisheye.

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
from multieye.core.intrinsics import Intrinsics
from multieye.io.atomic import write_text_atomic
from multieye.io.kalibr import camchain_entries, intrinsics_from_kalibr, is_camchain
from multieye.io.textfile import read_text
from multieye.io.yamlfile import MAX_YAML_BYTES, YamlDocument, parse_yaml, yaml_list

__all__ = [
    "DISTORTION_MODELS",
    "read_intrinsics",
    "read_opencv_intrinsics",
    "read_camera_info",
    "read_kalibr_intrinsics",
    "write_opencv_intrinsics",
    "distortion_model_name",
    "camera_info_text",
]

#: ``distortion_model`` names and the camera model they mean.
DISTORTION_MODELS = {
    "plumb_bob": "pinhole", "rational_polynomial": "pinhole", "radtan": "pinhole",
    "pinhole": "pinhole", "equidistant": "fisheye", "fisheye": "fisheye",
    "kannala_brandt": "fisheye", "thin_prism": "pinhole", "tilted": "pinhole",
}

#: Name of a pinhole camera's distortion model by its number of OpenCV coefficients.
_PINHOLE_NAMES = {0: "plumb_bob", 4: "plumb_bob", 5: "plumb_bob", 8: "rational_polynomial",
                  12: "thin_prism", 14: "tilted"}
#: The distortion models ROS's camera_info (image_geometry) knows, and their coefficient count.
_ROS_SIZES = {"plumb_bob": 5, "rational_polynomial": 8, "equidistant": 4}

_FORMATS = ("expected OpenCV FileStorage (%YAML:1.0 or XML with camera_matrix), a Kalibr "
            "camchain (camera_model, intrinsics) or ROS camera_info (camera_matrix: "
            "{rows, cols, data})")


def _model(name, path, line=None) -> str:
    if name is None:
        return "pinhole"
    try:
        return DISTORTION_MODELS[str(name).lower()]
    except KeyError:
        raise DatasetError(f"distortion_model {name!r} is not supported; expected one of "
                           f"{', '.join(DISTORTION_MODELS)}", path=path, line=line) from None


def _build(K, dist, model, width, height, path, line=None) -> Intrinsics:
    try:
        K = np.asarray(K, dtype=np.float64).reshape(3, 3)
    except (TypeError, ValueError):
        count = len(K) if isinstance(K, (list, tuple, np.ndarray)) else 1
        raise DatasetError(f"camera matrix must have 9 numbers, got {count}", path=path,
                           line=line) from None
    try:
        return Intrinsics(K, np.asarray(dist, dtype=np.float64).reshape(-1), model,
                          None if width is None else int(width),
                          None if height is None else int(height))
    except (InputError, TypeError, ValueError) as exc:
        raise DatasetError(str(exc), path=path, line=line) from None


# --------------------------------------------------------------------------- OpenCV


#: Deepest nesting of ``[``/``{`` (YAML) or elements (XML) handed to OpenCV's FileStorage
#: parser, which recurses without a limit (and crashes the process on tens of thousands).
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
    import cv2

    cause = exc if isinstance(exc, cv2.error) else (exc.__cause__ or exc.__context__ or exc)
    lines = str(cause).strip().splitlines()
    text = lines[-1].strip() if lines else type(exc).__name__
    m = _CV_WHERE.search(text)
    if m:
        return m.group(2).strip(), int(m.group(1))
    return text.split("error: ", 1)[-1], None


def read_opencv_intrinsics(path: str | os.PathLike) -> Intrinsics:
    """Read OpenCV FileStorage YAML or XML (``camera_matrix``/``K``, ``distortion_*``/``D``).

    Raises
    ------
    DatasetError
        The file is missing, larger than :data:`~multieye.io.yamlfile.MAX_YAML_BYTES`, nested
        deeper than OpenCV's parser survives, OpenCV cannot parse it, a required key is
        missing (the message lists the keys present), or a value has the wrong type.
    """
    import cv2

    p = Path(path)
    text = read_text(p, what="intrinsics file", max_bytes=MAX_YAML_BYTES)
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
    try:
        root = fs.root()
        if not root.isMap():
            raise DatasetError("expected a FileStorage map with camera_matrix (or K)", path=p)
        keys = list(root.keys())

        def node(*names):
            return next((fs.getNode(n) for n in names if not fs.getNode(n).empty()), None)

        def numbers(n):
            if n.isSeq():
                items = [n.at(i) for i in range(n.size())]
                if not all(i.isReal() or i.isInt() for i in items):
                    raise DatasetError(f"{n.name()} must be a matrix or a list of numbers",
                                       path=p)
                return np.array([i.real() for i in items])
            try:
                mat = n.mat() if n.isMap() else None
            except cv2.error as exc:
                raise DatasetError(f"{n.name()}: OpenCV cannot read this matrix "
                                   f"({_cv_message(exc)[0]}); rows x cols must match data",
                                   path=p) from None
            if mat is None:
                raise DatasetError(f"{n.name()} must be a matrix or a list of numbers", path=p)
            return np.asarray(mat, dtype=np.float64).reshape(-1)

        def size(n):
            if n is None:
                return None
            if not n.isInt() or n.real() <= 0:
                shown = (n.string() if n.isString() else int(n.real()) if n.isInt()
                         else n.real() if n.isReal() else "not a number")
                raise DatasetError(f"{n.name()} must be a positive integer, got {shown}",
                                   path=p)
            return int(n.real())

        k_node = node("camera_matrix", "K")
        if k_node is None:
            raise DatasetError("no camera_matrix (or K); keys present: "
                               f"{', '.join(keys) or 'none'}", path=p)
        d_node = node("distortion_coefficients", "D")
        dist = numbers(d_node) if d_node is not None else np.zeros(0)
        m_node = node("distortion_model", "model")
        if m_node is not None and not m_node.isString():
            raise DatasetError(f"{m_node.name()} must be a name such as plumb_bob", path=p)
        model = _model(m_node.string() if m_node is not None else None, p)
        width, height = size(node("image_width")), size(node("image_height"))
        return _build(numbers(k_node), dist, model, width, height, p)
    except (cv2.error, SystemError) as exc:
        message, line = _cv_message(exc)
        raise DatasetError(f"OpenCV cannot read this FileStorage file: {message}", path=p,
                           line=line) from None
    finally:
        fs.release()


def write_opencv_intrinsics(path: str | os.PathLike, intr: Intrinsics) -> None:
    """Write OpenCV FileStorage YAML atomically (``cv2.FileStorage`` reads it).

    Keys: ``image_width``, ``image_height`` (when known), ``camera_matrix``,
    ``distortion_coefficients`` and, for fisheye cameras, ``distortion_model: fisheye``.
    """
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


def distortion_model_name(intr: Intrinsics) -> str:
    """The true name of an intrinsics' distortion model: ``equidistant`` (fisheye),
    ``plumb_bob`` (pinhole, 0/4/5 coefficients), ``rational_polynomial`` (8), ``thin_prism``
    (12) or ``tilted`` (14); every one reads back through :data:`DISTORTION_MODELS`."""
    if intr.model == "fisheye":
        return "equidistant"
    return _PINHOLE_NAMES[int(intr.dist.size)]


def camera_info_text(intr: Intrinsics, camera_name: str) -> str:
    """ROS ``sensor_msgs/CameraInfo`` YAML (``camera_calibration_parsers``' layout).

    Keys: ``image_width``, ``image_height``, ``camera_name``, ``camera_matrix``,
    ``distortion_model``, ``distortion_coefficients``, ``rectification_matrix`` (identity)
    and ``projection_matrix`` (``[K | 0]``), each matrix ``{rows, cols, data}``.  A pinhole
    lens with 0 or 4 coefficients is written as ``plumb_bob`` with the missing ones zero.

    Raises
    ------
    InputError
        A model ROS cannot name (12 or 14 coefficients: thin-prism or tilted sensor), or an
        unknown image size (camera_info needs it).
    """
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

    lines = [f"image_width: {int(intr.width)}", f"image_height: {int(intr.height)}",
             f"camera_name: {json.dumps(camera_name)}", *matrix("camera_matrix", intr.K),
             f"distortion_model: {name}", *matrix("distortion_coefficients", dist),
             *matrix("rectification_matrix", np.eye(3)),
             *matrix("projection_matrix", np.hstack([intr.K, np.zeros((3, 1))]))]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- YAML formats


def _matrix_data(value, doc: YamlDocument, key: str) -> list:
    """``{rows, cols, data}`` (ROS), a flat list, or a nested list -> flat list of numbers."""
    if isinstance(value, Mapping):
        if "data" not in value:
            raise doc.error("expected a mapping with rows, cols and data", key)
        value = value["data"]
    if not isinstance(value, list):
        raise doc.error(f"expected a list of numbers, got {value!r}", key)
    flat = [v for row in value for v in (row if isinstance(row, list) else [row])]
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in flat):
        raise doc.error(f"expected numbers, got {value!r}", key)
    return flat


def _camera_info(doc: YamlDocument) -> Intrinsics:
    data = doc.data
    k_key = "camera_matrix" if "camera_matrix" in data else "K"
    d_key = next((k for k in ("distortion_coefficients", "D") if k in data), None)
    K = _matrix_data(data[k_key], doc, k_key)
    if len(K) != 9:
        raise doc.error(f"expected 9 numbers, got {len(K)}", k_key)
    dist = _matrix_data(data[d_key], doc, d_key) if d_key else []
    model = _model(data.get("distortion_model"), doc.path, doc.line("distortion_model"))
    width, height = data.get("image_width"), data.get("image_height")
    for key, v in (("image_width", width), ("image_height", height)):
        if v is not None and (not isinstance(v, int) or isinstance(v, bool) or v <= 0):
            raise doc.error(f"expected a positive integer, got {v!r}", key)
    return _build(K, dist, model, width, height, doc.path, doc.line(d_key or k_key))


def _kalibr(doc: YamlDocument, camera: str | None, prefer: str | None = None) -> Intrinsics:
    data = doc.data
    if "camera_model" in data:
        return intrinsics_from_kalibr(data, doc)
    entries = camchain_entries(doc)
    if camera is None and prefer is not None and len(entries) > 1:
        if any(prefer in (key, entry.get("camera_name")) for key, entry in entries):
            camera = prefer
    if camera is None:
        if len(entries) != 1:
            raise doc.error(f"the camchain has {len(entries)} cameras "
                            f"({', '.join(k for k, _ in entries)}); choose one by name")
        return intrinsics_from_kalibr(entries[0][1], doc, entries[0][0])
    for key, entry in entries:
        if camera in (key, entry.get("camera_name")):
            return intrinsics_from_kalibr(entry, doc, key)
    names = ", ".join(k for k, _ in entries)
    raise DatasetError(f"camera {camera!r} not in the camchain; it has {names}", path=doc.path)


def _load(path) -> tuple[str, YamlDocument | None]:
    text = read_text(path, what="intrinsics file", max_bytes=MAX_YAML_BYTES)
    head = text.lstrip()[:32]
    if head.startswith(("%YAML", "<?xml", "<opencv_storage")):
        return "opencv", None
    doc = parse_yaml(text, path)
    if not isinstance(doc.data, Mapping):
        raise DatasetError(f"not an intrinsics file: {_FORMATS}", path=path, line=1)
    if is_camchain(doc.data):
        return "kalibr", doc
    if "camera_matrix" in doc.data or "K" in doc.data:
        return "camera_info", doc
    raise DatasetError(f"not an intrinsics file: {_FORMATS}", path=path, line=1)


def read_camera_info(path: str | os.PathLike) -> Intrinsics:
    """Read ROS ``camera_info`` YAML (or plain YAML with ``K`` / ``D`` lists)."""
    kind, doc = _load(path)
    if kind != "camera_info":
        raise DatasetError(f"not a ROS camera_info file (looks like {kind})", path=path)
    return _camera_info(doc)


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
    kind, doc = _load(path)
    if kind == "opencv":
        return read_opencv_intrinsics(path)
    if kind == "kalibr":
        return _kalibr(doc, camera, prefer)
    return _camera_info(doc)
