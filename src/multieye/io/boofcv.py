"""BoofCV's camera YAML (``CalibrationIO``) -> :class:`~multieye.core.intrinsics.Intrinsics`.

Layout, as BoofCV writes it (one camera per file)::

    pinhole: {fx, fy, cx, cy, width, height, skew}
    model: pinhole_radial_tangential       # or omnidirectional_universal
    radial_tangential: {radial: [k1, k2 (, k3)], t1, t2}
    mirror_offset: 1.13                    # omnidirectional_universal only
    version: 0

``model: pinhole`` is a pinhole without distortion.  ``pinhole_radial_tangential`` is
OpenCV's pinhole model (BoofCV's ``t1 t2`` are OpenCV's ``p1 p2``, checked against BoofCV's
``AddBrownNtoN_F64``; ``radial`` gives k1 k2 and optionally k3, the others zero):
``k1 k2 p1 p2`` (at most two radial) or ``k1 k2 p1 p2 k3``.  ``omnidirectional_universal``
is Mei and Rives' unified model: ``xi`` is ``mirror_offset`` and the distortion of the
normalised point ``k1 k2 p1 p2`` (at most two radial coefficients;
:mod:`multieye.core.lens_wide`).  ``kannala_brandt`` (``symmetric``, ``radial``,
``radial_trig``, ``tangent``, ``tangent_trig``; BoofCV's ``KannalaBrandtStoP_F64``: the
radius ``r = s0 theta + s1 theta^3 + ... + s4 theta^9`` of the angle theta from the optical
axis) is OpenCV's fisheye model when its asymmetric terms (``radial``, ``tangent``) are zero:
``fx, fy`` times ``s0`` and ``k_i = s_i / s0``, the same projection; asymmetric terms, more
than five symmetric ones or ``s0 <= 0`` are refused naming the key.  BoofCV's stereo file
(``model: stereo_camera``, its ``left`` and ``right`` cameras in the layout above and
``rightToLeft``, the pair's pose, ignored like every pose in an intrinsics file) gives the
camera chosen by name (:func:`intrinsics_from_boofcv_stereo`).  Numbers may be written as
text (YAML 1.1 reads ``1e-3``, an exponent without a dot, as text); every key is read or
refused.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import Intrinsics, check_lens_bounds
from multieye.io.intrinsics_mapping import NUMBER, refuse_unknown
from multieye.io.yamlfile import YamlDocument, shown

__all__ = ["is_boofcv", "is_boofcv_stereo", "intrinsics_from_boofcv",
           "intrinsics_from_boofcv_stereo", "BOOFCV_MODELS"]

#: BoofCV's camera models read, and the Intrinsics model of each.
BOOFCV_MODELS = {"pinhole": "pinhole", "pinhole_radial_tangential": "pinhole",
                 "omnidirectional_universal": "unified", "kannala_brandt": "fisheye"}
#: The top-level keys of each camera model's file.
_TOP = {"pinhole": ("pinhole", "model", "version"),
        "pinhole_radial_tangential": ("pinhole", "model", "radial_tangential", "version"),
        "omnidirectional_universal": ("pinhole", "model", "radial_tangential",
                                      "mirror_offset", "version"),
        "kannala_brandt": ("pinhole", "model", "version", "symmetric", "radial",
                           "radial_trig", "tangent", "tangent_trig")}
_PINHOLE = ("fx", "fy", "cx", "cy", "width", "height", "skew")
_RADTAN = ("radial", "t1", "t2")
_OTHER_MODELS = ("stereo_camera",)
_STEREO = ("model", "left", "right", "rightToLeft", "version")


def is_boofcv(data) -> bool:
    """A BoofCV camera file: a ``pinhole`` mapping and a ``model`` name (one of BoofCV's is
    read, another refused by name)."""
    return (isinstance(data, Mapping) and isinstance(data.get("pinhole"), Mapping)
            and isinstance(data.get("model"), str) and data["model"] not in _OTHER_MODELS)


def is_boofcv_stereo(data) -> bool:
    """A BoofCV stereo file: ``model: stereo_camera`` with ``left`` and ``right`` cameras."""
    return (isinstance(data, Mapping) and data.get("model") == "stereo_camera"
            and all(isinstance(data.get(k), Mapping) for k in ("left", "right")))


def intrinsics_from_boofcv_stereo(doc: YamlDocument, camera: str | None,
                                  prefer: str | None = None) -> Intrinsics:
    """One camera of a BoofCV stereo file: ``camera`` (``left`` or ``right``), else the one
    named like the rig's camera (``prefer``).

    Raises
    ------
    DatasetError
        No camera chosen, or one the file does not hold; an unknown key; as
        :func:`intrinsics_from_boofcv` for the camera's own keys.
    """
    refuse_unknown(doc, doc.data, _STEREO, ())
    if camera is None and prefer in ("left", "right"):
        camera = prefer
    if camera not in ("left", "right"):
        got = "none was given" if camera is None else f"got {camera!r}"
        raise doc.error("a BoofCV stereo file holds two cameras, left and right; choose one "
                        f"with intrinsics: {{file: {doc.path.name}, camera: left}} in rig.yaml "
                        f"({got})", "model")
    sub = YamlDocument(doc.path, doc.data[camera],
                       {k[1:]: v for k, v in doc.lines.items() if k[:1] == (camera,)})
    try:
        return intrinsics_from_boofcv(sub)
    except DatasetError as exc:
        raise DatasetError(f"{camera}.{exc.reason}", path=exc.path, line=exc.line) from None


def _number(doc: YamlDocument, value, *keys) -> float:
    """A finite number, also written as text (``'1e-3'``); booleans refused."""
    if isinstance(value, str) and NUMBER.fullmatch(value.strip()):
        value = float(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not np.isfinite(value):
        raise doc.error(f"expected a finite number, got {shown(value)}", *keys)
    return float(value)


def _kannala_brandt(doc: YamlDocument, fx: float, fy: float) -> tuple[float, float, list]:
    """BoofCV's symmetric Kannala-Brandt as OpenCV's fisheye: the focal lengths times
    ``symmetric[0]`` and ``k1..k4`` (module docstring)."""
    data = doc.data

    def numbers(key):
        values = data.get(key) or []
        if not isinstance(values, list):
            raise doc.error(f"expected a list of numbers, got {shown(values)}", key)
        return [_number(doc, v, key, i) for i, v in enumerate(values)]

    for key in ("radial", "tangent"):
        if any(numbers(key)):
            raise doc.error(f"BoofCV's asymmetric Kannala-Brandt terms ({key}) have no "
                            "equivalent in multieye's fisheye model (OpenCV's); calibrate "
                            "with symmetric terms only, or with model: in rig.yaml", key)
    numbers("radial_trig"), numbers("tangent_trig")    # numbers, unused with zero terms
    sym = numbers("symmetric")
    if any(sym[5:]):
        raise doc.error(f"{len(sym)} symmetric coefficients; OpenCV's fisheye model holds "
                        "5 (theta .. theta^9)", "symmetric")
    if not sym or not sym[0] > 0:
        raise doc.error("the first symmetric coefficient (of theta) must be positive, got "
                        f"{shown(sym[:1])}", "symmetric")
    s0 = sym[0]
    return fx * s0, fy * s0, [c / s0 for c in (sym[1:] + [0.0] * 4)[:4]]


def _distortion(doc: YamlDocument, rt, kind: str) -> np.ndarray:
    """``k1 k2 p1 p2`` (``k3`` appended when the pinhole file gives it) from
    ``radial_tangential``."""
    if rt is None:
        return np.zeros(4)
    if not isinstance(rt, Mapping):
        raise doc.error("expected a mapping with radial, t1, t2", "radial_tangential")
    refuse_unknown(doc, rt, _RADTAN, (), "radial_tangential")
    radial = rt.get("radial") or []
    if not isinstance(radial, list):
        raise doc.error(f"expected a list of numbers, got {shown(radial)}",
                        "radial_tangential", "radial")
    k = [_number(doc, v, "radial_tangential", "radial", i) for i, v in enumerate(radial)]
    most = 2 if kind == "unified" else 3
    if any(k[most:]):
        raise doc.error(f"{len(k)} radial coefficients; multieye's {kind} model holds "
                        f"{most} (k1 .. k{most})", "radial_tangential", "radial")
    k = (k + [0.0, 0.0, 0.0])[:most]
    out = k[:2] + [_number(doc, rt.get(key, 0.0), "radial_tangential", key)
                   for key in ("t1", "t2")]
    if kind == "pinhole" and len(radial) >= 3:
        out.append(k[2])
    return np.array(out)


def intrinsics_from_boofcv(doc: YamlDocument) -> Intrinsics:
    """Intrinsics from a BoofCV camera YAML (module docstring).

    Raises
    ------
    DatasetError
        An unknown or unsupported key or model, a missing number, more radial coefficients
        than the model holds, or numbers no real camera has; with the key's line.
    """
    data = doc.data
    model = data["model"]
    if model not in BOOFCV_MODELS:
        raise doc.error(f"BoofCV model {model!r} is not supported; expected "
                        f"{' or '.join(BOOFCV_MODELS)}", "model")
    for key in data:
        owners = [m for m, keys in _TOP.items() if key in keys]
        if owners and model not in owners:      # a key of another of BoofCV's models
            raise doc.error(f"{key} belongs to {' and '.join(owners)}, not {model}", key)
    refuse_unknown(doc, data, _TOP[model], ())
    kind = BOOFCV_MODELS[model]
    pin = data["pinhole"]
    refuse_unknown(doc, pin, _PINHOLE, (), "pinhole")
    fx, fy, cx, cy = (_number(doc, pin.get(k), "pinhole", k) for k in ("fx", "fy", "cx", "cy"))
    skew = _number(doc, pin.get("skew", 0.0), "pinhole", "skew")
    size = []
    for key in ("width", "height"):
        v = pin.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int)):
            raise doc.error(f"expected a whole number of pixels, got {shown(v)}", "pinhole", key)
        size.append(v)
    if (size[0] is None) != (size[1] is None):
        given, missing = ("width", "height") if size[1] is None else ("height", "width")
        raise doc.error(f"{given} without {missing}: give both (BoofCV writes both) or "
                        "neither", "pinhole")
    if model == "kannala_brandt":
        f0 = fx
        fx, fy, dist = _kannala_brandt(doc, fx, fy)
        skew *= fx / f0                 # BoofCV's skew multiplies the same radius
    elif model == "pinhole":
        dist = np.zeros(0)
    else:
        dist = _distortion(doc, data.get("radial_tangential"), kind)
    if kind == "unified":
        if "mirror_offset" not in data:
            raise doc.error("missing key 'mirror_offset' (the unified model's xi)")
        dist = np.concatenate([[_number(doc, data["mirror_offset"], "mirror_offset")], dist])
    version = data.get("version", 0)
    if isinstance(version, bool) or not isinstance(version, int):
        raise doc.error(f"expected a whole number, got {shown(version)}", "version")
    K = np.array([[fx, skew, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    try:
        intr = Intrinsics(K, dist, kind, *size)
        check_lens_bounds(intr)
    except InputError as exc:
        raise doc.error(str(exc)) from None
    return intr
