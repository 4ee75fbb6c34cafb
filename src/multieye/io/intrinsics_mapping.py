"""Intrinsics files that are one mapping of keys: ROS ``camera_info`` YAML, a ROS CameraInfo
message, the JSON or YAML layouts of common toolkits, and OpenCV FileStorage (whose keys
:mod:`multieye.io.intrinsics_files` hands over as the same mapping).

Every key is read or refused: a key that gives a lens number is used (:data:`KEYS`), a key of
metadata that does not change the projection is ignored on purpose (:data:`IGNORED_KEYS`, by
the format that writes it), and any other key is refused with one line naming it, so that no
distortion is left at zero because its key had another name.

aslam_cv's camera YAML (ETH Zurich's hand-eye tools, maplab) is read by
:func:`intrinsics_from_aslam`, with its own keys.

Layouts (each one read from JSON or YAML):

- a camera matrix under one of ``camera_matrix``, ``K``, ``k``, ``cameraMatrix``, ``mtx``,
  ``Camera_Matrix`` (OpenCV 2's calibration sample and book):
  9 numbers, a 3 x 3 list, or a matrix mapping ``{rows, cols, data}`` (ROS, and OpenCV's JSON
  ``{type_id: opencv-matrix, rows, cols, dt, data}``);
- or flat numbers ``fx fy cx cy`` (optional ``skew``);
- the distortion under one of ``distortion_coefficients``, ``D``, ``d``, ``dist``,
  ``dist_coeffs``, ``dist_coeff``, ``distCoeffs``, ``distortion_coeffs``,
  ``Distortion_Coefficients`` (OpenCV's order), or
  flat ``k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 taux tauy`` (fisheye: ``k1 k2 k3 k4``), the
  ones left out zero;
- the model as ``distortion_model`` (or ``model``; names of
  :data:`DISTORTION_MODELS`) or OpenCV's ``fisheye_model: 0|1``; ``xi`` (OpenCV's omnidir
  calibration, opencv_contrib's ccalib) makes it Mei's unified model with the distortion's
  k1 k2 p1 p2;
- the image size as ``image_width`` / ``image_height``, ``width`` / ``height``,
  ``resolution: [width, height]`` or ``image_size: [width, height]`` (OpenCV's ``Size``, as
  multieye's calibration.json writes it; a size written ``[height, width]`` shows as every
  image of the wrong resolution); a ROS CameraInfo message's ``binning_x``, ``binning_y``
  and ``roi`` are read and must describe the full image (no binning, no region of interest).
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Mapping

import numpy as np

from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import Intrinsics, check_lens_bounds
from multieye.io.yamlfile import YamlDocument

__all__ = ["DISTORTION_MODELS", "KEYS", "NUMBER", "FLAT_KEYS", "READ_KEYS", "IGNORED_KEYS",
           "intrinsics_from_mapping", "has_camera_matrix",
           "refuse_unknown", "build_intrinsics", "is_aslam", "intrinsics_from_aslam"]

#: ``distortion_model`` names and the camera model they mean.
DISTORTION_MODELS = {
    "plumb_bob": "pinhole", "rational_polynomial": "pinhole", "radtan": "pinhole",
    "pinhole": "pinhole", "equidistant": "fisheye", "fisheye": "fisheye",
    "kannala_brandt": "fisheye", "thin_prism": "pinhole", "tilted": "pinhole",
}

#: What each read key gives, and the names it may have (at most one of them in a file).
KEYS = {
    "camera matrix": ("camera_matrix", "K", "k", "cameraMatrix", "mtx", "Camera_Matrix"),
    "distortion": ("distortion_coefficients", "D", "d", "dist", "dist_coeffs", "dist_coeff",
                   "distCoeffs", "distortion_coeffs", "Distortion_Coefficients"),
    "distortion model": ("distortion_model", "model"),
    "fisheye flag": ("fisheye_model",),
    "image width": ("image_width", "width"),
    "image height": ("image_height", "height"),
    "image size": ("resolution", "image_size"),
    "binning_x": ("binning_x",),
    "binning_y": ("binning_y",),
    "region of interest": ("roi",),
    "mirror offset": ("xi",),
}
#: Flat numbers: the camera matrix's, then the distortion's in OpenCV's order.
_FLAT_K = ("fx", "fy", "cx", "cy", "skew")
_FLAT_DIST = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "taux",
              "tauy")
FLAT_KEYS = _FLAT_K + _FLAT_DIST

#: Metadata keys ignored on purpose, by the format that writes them: none changes how a point
#: projects (rectification and projection for stereo, names, topics, residuals of the
#: calibration that made the file, its board and views).  docs/rig-yaml.md lists them.
IGNORED_KEYS = {
    "OpenCV FileStorage (OpenCV's calibration samples)": (
        "calibration_time", "nframes", "nr_of_frames", "board_width", "board_height",
        "square_size", "aspectRatio", "fix_aspect_ratio", "flags", "avg_reprojection_error",
        "per_view_reprojection_errors", "extrinsic_parameters", "image_points", "grid_points",
        "Calibrate_Accuracy", "nFrames", "used_imgs"),
    "ROS camera_info YAML": ("camera_name", "rectification_matrix", "projection_matrix"),
    "ROS CameraInfo message (YAML or JSON)": ("header", "R", "P", "r", "p"),
    "JSON and YAML layouts": ("rms", "reprojection_error", "rvecs", "tvecs"),
    "aslam_cv camera (ETH Zurich)": ("label", "id"),
}
_IGNORED = frozenset(k for fmt, keys in IGNORED_KEYS.items() for k in keys
                     if not fmt.startswith("aslam"))
#: Every key the mapping layouts read.
READ_KEYS = tuple(k for names in KEYS.values() for k in names) + FLAT_KEYS
_MATRIX_KEYS = ("rows", "cols", "data", "dt", "type_id")
_ROI_KEYS = ("x_offset", "y_offset", "height", "width", "do_rectify")
#: A number written as text (YAML 1.1 reads ``1e-3``, an exponent without a dot, as text).
NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
_WHERE = "docs/rig-yaml.md, section 5"


def has_camera_matrix(data: Mapping) -> bool:
    """Whether a mapping gives a camera matrix (one of its keys, or flat ``fx``)."""
    return any(k in data for k in KEYS["camera matrix"]) or "fx" in data


def refuse_unknown(doc: YamlDocument, keys, read, ignored, *prefix) -> None:
    """Refuse the first of ``keys`` neither in ``read`` nor in ``ignored``, naming it (and the
    closest known key)."""
    for key in keys:
        if key in read or key in ignored:
            continue
        close = difflib.get_close_matches(str(key), [*read, *ignored], n=1, cutoff=0.6)
        if "dist" in str(key).lower() and "distortion" in KEYS and read is READ_KEYS:
            close = ["dist (or D, distortion_coefficients, dist_coeffs)"]
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise doc.error(f"not a key multieye reads or ignores in this intrinsics format{hint}; "
                        f"refused so that no lens number goes unused ({_WHERE})", *prefix, key)


def _number(v):
    if not (isinstance(v, str) and NUMBER.fullmatch(v.strip())) and (
            not isinstance(v, (int, float, np.integer, np.floating)) or isinstance(v, bool)):
        return None
    try:
        return float(v)              # a string too: YAML 1.1 reads 1e-5 as text
    except OverflowError:
        return float("inf")          # refused as not finite


def _numbers(value, doc: YamlDocument, key: str) -> list[float]:
    """A number, a flat or nested list, or a matrix mapping ``{rows, cols, data}`` -> flat
    list of floats (rows x cols checked against the data)."""
    shape = None
    if isinstance(value, Mapping):
        refuse_unknown(doc, value, _MATRIX_KEYS, (), key)
        if "data" not in value:
            raise doc.error("expected a mapping with rows, cols and data", key)
        if value.get("type_id", "opencv-matrix") != "opencv-matrix":
            raise doc.error(f"type_id {value['type_id']!r} is not an opencv-matrix", key,
                            "type_id")
        if "rows" in value or "cols" in value:
            shape = (value.get("rows"), value.get("cols"))
        value = value["data"]
    if not isinstance(value, list):
        value = [value]
    flat = [v for row in value for v in (row if isinstance(row, list) else [row])]
    out = [_number(v) for v in flat]
    if any(v is None for v in out):
        raise doc.error(f"expected numbers, got {value!r}"[:200], key)
    if shape is not None:
        rows, cols = shape
        if not all(isinstance(n, int) and not isinstance(n, bool) for n in shape) \
                or rows * cols != len(out):
            raise doc.error(f"rows x cols ({rows} x {cols}) does not match the {len(out)} "
                            "numbers of data", key)
    return out


def _integer(value, doc: YamlDocument, key: str, *, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise doc.error(f"expected a {'positive' if minimum else 'non-negative'} integer, got "
                        f"{value!r}", key)
    return int(value)


def _one(doc: YamlDocument, role: str) -> str | None:
    """The key of ``role`` present in the file, None if none; refused when several are."""
    present = [k for k in KEYS[role] if k in doc.data]
    if len(present) > 1:
        raise doc.error(f"{' and '.join(present)} both give the {role}; keep one", present[1])
    return present[0] if present else None


def build_intrinsics(doc: YamlDocument, keys, K, dist, model: str, width, height):
    """:class:`Intrinsics` from the numbers read, checked (:func:`check_lens_bounds`); a
    problem is a DatasetError at the line of the key that gave the number: ``keys`` is
    ``(camera matrix key, distortion key, image size key)``, any of them None."""
    k_key, d_key, s_key = keys

    def where(message: str):
        key = (d_key if message.startswith(("distortion", "pinhole distortion", "fisheye")) else
               s_key if message.startswith("image") else k_key) or k_key or d_key
        return doc.error(message, key) if key else DatasetError(message, path=doc.path)

    try:
        K = np.asarray(K, dtype=np.float64).reshape(3, 3)
        dist = np.asarray(dist, dtype=np.float64).reshape(-1)
        Intrinsics(K, np.zeros({"fisheye": 4, "unified": 5}.get(model, 0)), model, width,
                   height)
        intr = Intrinsics(K, dist, model, width, height)
        check_lens_bounds(intr)
    except (InputError, OverflowError, TypeError, ValueError) as exc:
        raise where(str(exc)) from None
    return intr


def _model(doc: YamlDocument) -> str:
    model = None
    key = _one(doc, "distortion model")
    if key is not None:
        name = doc.data[key]
        if not isinstance(name, str) or name.lower() not in DISTORTION_MODELS:
            raise doc.error(f"{name!r} is not a supported distortion model; expected one of "
                            f"{', '.join(DISTORTION_MODELS)}", key)
        model = DISTORTION_MODELS[name.lower()]
    if "fisheye_model" in doc.data:
        flag = doc.data["fisheye_model"]
        if flag not in (0, 1) or (key is not None and model != ("fisheye" if flag else
                                                                 "pinhole")):
            raise doc.error(f"expected 0 or 1 agreeing with {key or 'the file'}, got {flag!r}",
                            "fisheye_model")
        model = "fisheye" if flag else "pinhole"
    return model or "pinhole"


def _size(doc: YamlDocument) -> tuple[int | None, int | None]:
    data = doc.data
    wk, hk, rk = _one(doc, "image width"), _one(doc, "image height"), _one(doc, "image size")
    if rk is not None:
        if wk or hk:
            raise doc.error(f"{rk} and {wk or hk} both give the image size; keep one", rk)
        res = data[rk]
        if not isinstance(res, list) or len(res) != 2:
            raise doc.error(f"expected [width, height], got {res!r}", rk)
        return _integer(res[0], doc, rk), _integer(res[1], doc, rk)
    if (wk is None) != (hk is None):
        raise doc.error(f"without {'image_height' if wk else 'image_width'}: give both or "
                        "neither", wk or hk)
    if wk is None:
        return None, None
    if (wk, hk) not in (("image_width", "image_height"), ("width", "height")):
        raise doc.error(f"{wk} with {hk}: write image_width and image_height, or width and "
                        "height", hk)
    return _integer(data[wk], doc, wk), _integer(data[hk], doc, hk)


def _full_image(doc: YamlDocument, width, height) -> None:
    """A CameraInfo message's binning and region of interest must be the full image."""
    for key in ("binning_x", "binning_y"):
        if key in doc.data and _integer(doc.data[key], doc, key, minimum=0) > 1:
            raise doc.error(f"binning {doc.data[key]} is not supported: give the intrinsics "
                            "of the images as recorded, without binning", key)
    roi = doc.data.get("roi")
    if roi is None:
        return
    if not isinstance(roi, Mapping):
        raise doc.error(f"expected a mapping {{x_offset, y_offset, height, width}}, got {roi!r}",
                        "roi")
    refuse_unknown(doc, roi, _ROI_KEYS, (), "roi")
    vals = {k: _integer(roi.get(k, 0), doc, "roi", minimum=0) for k in _ROI_KEYS[:4]}
    if vals["x_offset"] or vals["y_offset"] or (vals["width"], vals["height"]) not in (
            (0, 0), (width, height)):
        raise doc.error(f"a region of interest {vals} is not supported: give the intrinsics "
                        "of the full images", "roi")


def intrinsics_from_mapping(doc: YamlDocument) -> Intrinsics:
    """Intrinsics from a mapping of keys (module docstring); every key read or refused.

    Raises
    ------
    DatasetError
        A key neither read nor ignored (named, with the closest known key), two keys for one
        number, a value of the wrong form, or intrinsics refused by :class:`Intrinsics` or
        :func:`~multieye.core.intrinsics.check_lens_bounds`; with the line of the key.
    """
    data = doc.data
    refuse_unknown(doc, data, READ_KEYS, _IGNORED)
    model = _model(doc)
    k_key = _one(doc, "camera matrix")
    flat_k = [k for k in _FLAT_K if k in data]
    if k_key is not None and flat_k:
        raise doc.error(f"{k_key} and {flat_k[0]} both give the camera matrix; keep one", flat_k[0])
    if k_key is not None:
        K = _numbers(data[k_key], doc, k_key)
        if len(K) != 9:
            raise doc.error(f"expected 9 numbers, got {len(K)}", k_key)
    else:
        missing = [k for k in _FLAT_K[:4] if k not in data]
        if missing:
            raise doc.error(f"{', '.join(missing)} missing: flat intrinsics need fx, fy, cx "
                            "and cy", flat_k[0] if flat_k else None)
        fx, fy, cx, cy, s = (_numbers(data[k], doc, k) if k in data else [0.0]
                             for k in _FLAT_K)
        if any(len(v) != 1 for v in (fx, fy, cx, cy, s)):
            raise doc.error("expected one number each for fx, fy, cx, cy and skew", "fx")
        K = [fx[0], s[0], cx[0], 0.0, fy[0], cy[0], 0.0, 0.0, 1.0]
        k_key = "fx"
    d_key = _one(doc, "distortion")
    flat_d = [k for k in _FLAT_DIST if k in data]
    if d_key is not None and flat_d:
        raise doc.error(f"{d_key} and {flat_d[0]} both give the distortion; keep one", flat_d[0])
    if d_key is not None:
        dist = _numbers(data[d_key], doc, d_key)
    elif flat_d:
        dist = _flat_distortion(doc, flat_d, model)
    else:
        dist = []
    if "xi" in data:                # OpenCV's omnidir: Mei's unified model
        model, dist = "unified", _unified(doc, model, dist)
    width, height = _size(doc)
    _full_image(doc, width, height)
    s_key = next((k for k in ("resolution", "image_width", "width") if k in data), None)
    return build_intrinsics(doc, (k_key, d_key or (flat_d[0] if flat_d else None), s_key), K,
                            dist, model, width, height)


def _unified(doc: YamlDocument, model: str, dist: list[float]) -> list[float]:
    """``xi`` and the distortion as the unified model's ``(xi, k1, k2, p1, p2)`` (OpenCV's
    omnidir: ``camera_matrix``, ``distortion_coefficients`` k1 k2 p1 p2, ``xi``)."""
    if model != "pinhole":
        raise doc.error(f"xi (the unified model's mirror offset) with a {model} lens: "
                        "give one of them", "xi")
    if len(dist) not in (0, 4) and any(dist[4:]):
        raise doc.error(f"the unified model has k1 k2 p1 p2 only; this file gives {len(dist)} "
                        "distortion coefficients", "xi")
    xi = _numbers(doc.data["xi"], doc, "xi")
    if len(xi) != 1:
        raise doc.error(f"expected one number, got {len(xi)}", "xi")
    return xi + (list(dist) + [0.0] * 4)[:4]


#: aslam_cv's camera YAML (ETH Zurich's hand_eye_calibration, maplab): the keys read, and
#: its distortion types -> (model, number of coefficients).
ASLAM_KEYS = ("type", "intrinsics", "distortion", "image_width", "image_height",
              "line-delay-nanoseconds")
_ASLAM_DISTORTION = {"radial-tangential": ("pinhole", 4), "equidistant": ("fisheye", 4),
                     "none": ("pinhole", 0)}


def is_aslam(data: Mapping) -> bool:
    """Whether a mapping is aslam_cv's camera layout (``type``, ``intrinsics`` as a matrix
    mapping of 4 numbers, ``distortion: {type, parameters}``)."""
    return "type" in data and isinstance(data.get("intrinsics"), Mapping) and (
        isinstance(data.get("distortion"), Mapping))


def intrinsics_from_aslam(doc: YamlDocument) -> Intrinsics:
    """Intrinsics from aslam_cv's camera YAML: ``type: pinhole``, ``intrinsics`` ``[fu, fv,
    cu, cv]``, ``distortion: {type: radial-tangential | equidistant | none, parameters}``,
    ``image_width``, ``image_height``; ``line-delay-nanoseconds`` must be 0 (a rolling
    shutter is not modelled).  aslam's ``fisheye`` distortion is the FOV model, refused."""
    data = doc.data
    refuse_unknown(doc, data, ASLAM_KEYS, IGNORED_KEYS["aslam_cv camera (ETH Zurich)"])
    if data["type"] != "pinhole":
        raise doc.error(f"camera type {data['type']!r} is not supported; expected 'pinhole'",
                        "type")
    dist = data["distortion"]
    refuse_unknown(doc, dist, ("type", "parameters"), (), "distortion")
    if dist.get("type") not in _ASLAM_DISTORTION:
        raise doc.error(f"{dist.get('type')!r} is not supported; expected one of "
                        f"{', '.join(_ASLAM_DISTORTION)} (aslam's fisheye is the FOV model, "
                        "which OpenCV has not)", "distortion", "type")
    model, n = _ASLAM_DISTORTION[dist["type"]]
    coeffs = _numbers(dist["parameters"], doc, "distortion") if n else []
    if len(coeffs) != n:
        raise doc.error(f"expected {n} parameters for {dist['type']}, got {len(coeffs)}",
                        "distortion", "parameters")
    values = _numbers(data["intrinsics"], doc, "intrinsics")
    if len(values) != 4:
        raise doc.error(f"expected 4 numbers [fu, fv, cu, cv], got {len(values)}", "intrinsics")
    delay = data.get("line-delay-nanoseconds", 0)
    if _number(delay) != 0:
        raise doc.error(f"a rolling shutter ({delay!r} ns per line) is not modelled; give a "
                        "global-shutter camera's intrinsics (0)", "line-delay-nanoseconds")
    width, height = _size(doc)
    fu, fv, cu, cv = values
    return build_intrinsics(doc, ("intrinsics", "distortion", "image_width"),
                            [fu, 0.0, cu, 0.0, fv, cv, 0.0, 0.0, 1.0], coeffs, model, width,
                            height)


def _flat_distortion(doc: YamlDocument, keys: list[str], model: str) -> list[float]:
    """``k1 k2 ...`` keys -> OpenCV's vector, the coefficients left out zero (the shortest
    OpenCV length that holds every one given)."""
    names = _FLAT_DIST[:2] + ("k3", "k4") if model == "fisheye" else _FLAT_DIST
    for key in keys:
        if key not in names:
            raise doc.error(f"the fisheye model has k1 k2 k3 k4 only, not {key}", key)
    last = max(names.index(k) for k in keys) + 1
    n = 4 if model == "fisheye" else next(n for n in (4, 5, 8, 12, 14) if n >= last)
    dist = [0.0] * n
    for key in keys:
        value = _numbers(doc.data[key], doc, key)
        if len(value) != 1:
            raise doc.error(f"expected one number, got {len(value)}", key)
        dist[names.index(key)] = value[0]
    return dist
