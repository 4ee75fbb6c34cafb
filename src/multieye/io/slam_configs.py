"""Camera intrinsics in the configuration files of visual(-inertial) odometry tools and data
sets, which other labs' recordings come with:

- **EuRoC's** ``cam0/sensor.yaml`` (ASL format): ``sensor_type: camera``, ``camera_model:
  pinhole``, ``intrinsics: [fu, fv, cu, cv]``, ``distortion_model: radial-tangential`` (k1 k2
  p1 p2) or ``equidistant`` (fisheye k1..k4), ``distortion_coefficients``, ``resolution``;
  ``T_BS``, ``rate_hz`` and ``comment`` are ignored.
- **camodocal's** YAML (VINS-Mono, VINS-Fusion, OKVIS-era tools): ``model_type`` ``PINHOLE``
  (``projection_parameters: {fx, fy, cx, cy}``, ``distortion_parameters: {k1, k2, p1,
  p2}``), ``MEI`` (the unified model: ``mirror_parameters: {xi}``, ``distortion_parameters``,
  ``projection_parameters: {gamma1, gamma2, u0, v0}``) or ``KANNALA_BRANDT`` (OpenCV's fisheye:
  ``projection_parameters: {k2, k3, k4, k5, mu, mv, u0, v0}``, camodocal's ``k2..k5`` being
  OpenCV's ``k1..k4``); ``image_width``, ``image_height``; ``camera_name`` ignored.
  ``SCARAMUZZA`` has no equivalent here and is refused.
- **ORB-SLAM2/3** settings: ``Camera.fx`` ... (ORB-SLAM2) or ``Camera1.fx`` ... (ORB-SLAM3;
  ``Camera2.*`` the right camera of a stereo pair, chosen by ``camera: Camera2``),
  ``Camera.type`` ``PinHole`` (k1 k2 p1 p2 [k3]), ``KannalaBrandt8`` (fisheye k1..k4) or
  ``Rectified`` (no distortion),
  ``Camera.width`` / ``Camera.height``; the other keys of the file (features, viewer, IMU,
  ``Camera.fps``, ``Camera.RGB``, ``Camera.bf``, ...) change no projection and are ignored;
  an unknown ``CameraN.*`` key is refused.

Each is read into the same :class:`~multieye.core.intrinsics.Intrinsics` and checked by
:func:`~multieye.core.intrinsics.check_lens_bounds`, with messages naming the file and key.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

import numpy as np

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics, check_lens_bounds
from multieye.io.intrinsics_mapping import refuse_unknown
from multieye.io.yamlfile import YamlDocument, shown

__all__ = ["slam_config_kind", "intrinsics_from_slam_config"]

_EUROC_DISTORTION = {"radial-tangential": ("pinhole", 4), "radtan": ("pinhole", 4),
                     "equidistant": ("fisheye", 4), "none": ("pinhole", 0)}
_EUROC_READ = ("sensor_type", "camera_model", "intrinsics", "distortion_model",
               "distortion_coefficients", "resolution")
_EUROC_IGNORED = ("T_BS", "rate_hz", "comment")
_CAMODOCAL = {
    # model_type -> (Intrinsics model, {section: names}, K names, distortion names)
    "PINHOLE": ("pinhole", {"projection_parameters": ("fx", "fy", "cx", "cy"),
                            "distortion_parameters": ("k1", "k2", "p1", "p2")},
                ("fx", "fy", "cx", "cy"), ("k1", "k2", "p1", "p2")),
    "MEI": ("unified", {"mirror_parameters": ("xi",),
                        "projection_parameters": ("gamma1", "gamma2", "u0", "v0"),
                        "distortion_parameters": ("k1", "k2", "p1", "p2")},
            ("gamma1", "gamma2", "u0", "v0"), ("xi", "k1", "k2", "p1", "p2")),
    "KANNALA_BRANDT": ("fisheye", {"projection_parameters": ("k2", "k3", "k4", "k5", "mu",
                                                             "mv", "u0", "v0")},
                       ("mu", "mv", "u0", "v0"), ("k2", "k3", "k4", "k5")),
}
_ORB_TYPES = {"pinhole": ("pinhole", ("k1", "k2", "p1", "p2", "k3")),
              "kannalabrandt8": ("fisheye", ("k1", "k2", "k3", "k4")),
              "rectified": ("pinhole", ())}
_ORB_KEY = re.compile(r"^Camera(\d?)\.(\w+)$")
#: ORB-SLAM keys under ``Camera.`` / ``CameraN.`` that change no projection.
_ORB_IGNORED = ("type", "fps", "RGB", "bf", "newWidth", "newHeight", "width", "height")


def slam_config_kind(data) -> str | None:
    """``"euroc"``, ``"camodocal"``, ``"orb-slam"`` or None for a parsed file's mapping."""
    if not isinstance(data, Mapping):
        return None
    if data.get("sensor_type") == "camera" and "camera_model" in data:
        return "euroc"
    if "model_type" in data and "projection_parameters" in data:
        return "camodocal"
    if any(isinstance(k, str) and _ORB_KEY.match(k) and k.endswith(".fx") for k in data):
        return "orb-slam"
    return None


def _numbers(doc: YamlDocument, value, n: int, *keys) -> np.ndarray:
    """``n`` finite numbers; YAML's booleans (``yes``, ``true``) are not numbers here."""
    items = value if isinstance(value, list) else [value]
    try:
        if any(isinstance(v, bool) for item in items
               for v in (item if isinstance(item, list) else [item])):
            raise TypeError("a boolean")
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    if arr.size != n or not np.all(np.isfinite(arr)):
        raise doc.error(f"expected {n} finite numbers, got {shown(value)}", *keys)
    return arr


def _checked(doc: YamlDocument, K, dist, model: str, width, height, *keys) -> Intrinsics:
    try:
        intr = Intrinsics(np.asarray(K, dtype=np.float64), np.asarray(dist, dtype=np.float64),
                          model, width, height)
        check_lens_bounds(intr)
    except InputError as exc:
        raise doc.error(str(exc), *keys) from None
    return intr


def _size(doc: YamlDocument, width, height, *keys) -> tuple[int | None, int | None]:
    if width is None and height is None:
        return None, None
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v > 0
               for v in (width, height)):
        raise doc.error(f"image width and height must be positive integers, got "
                        f"{shown(width)} x {shown(height)}", *keys)
    return int(width), int(height)


def _K(fx, fy, cx, cy) -> np.ndarray:
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def _euroc(doc: YamlDocument) -> Intrinsics:
    data = doc.data
    refuse_unknown(doc, data, _EUROC_READ, _EUROC_IGNORED)
    if data.get("camera_model") != "pinhole":
        raise doc.error(f"camera_model {shown(data.get('camera_model'))} is not supported in "
                        "a sensor.yaml; expected pinhole", "camera_model")
    dmodel = data.get("distortion_model", "none")
    if dmodel not in _EUROC_DISTORTION:
        raise doc.error(f"distortion_model {shown(dmodel)} is not supported; expected "
                        f"{', '.join(_EUROC_DISTORTION)}", "distortion_model")
    model, n = _EUROC_DISTORTION[dmodel]
    fu, fv, cu, cv = _numbers(doc, data.get("intrinsics"), 4, "intrinsics")
    dist = _numbers(doc, data.get("distortion_coefficients", [0.0] * n), n,
                    "distortion_coefficients")
    res = data.get("resolution")
    width, height = (None, None) if res is None else _size(
        doc, *(res if isinstance(res, list) and len(res) == 2 else (0, 0)), "resolution")
    return _checked(doc, _K(fu, fv, cu, cv), dist, model, width, height)


def _camodocal(doc: YamlDocument) -> Intrinsics:
    data = doc.data
    kind = data.get("model_type")
    if kind not in _CAMODOCAL:
        raise doc.error(f"camodocal model_type {shown(kind)} is not supported; expected "
                        f"{', '.join(_CAMODOCAL)} (SCARAMUZZA has no equivalent: calibrate "
                        "the camera with model: in rig.yaml instead)", "model_type")
    model, sections, k_names, d_names = _CAMODOCAL[kind]
    refuse_unknown(doc, data, ("model_type", "image_width", "image_height", *sections),
                   ("camera_name",))
    values: dict[str, float] = {}
    for section, names in sections.items():
        part = data.get(section)
        if not isinstance(part, Mapping):
            raise doc.error(f"expected a mapping of {', '.join(names)}, got {shown(part)}",
                            section)
        refuse_unknown(doc, part, names, (), section)
        for name in names:
            values[name] = float(_numbers(doc, part.get(name), 1, section, name)[0])
    width, height = _size(doc, data.get("image_width"), data.get("image_height"),
                          "image_width")
    return _checked(doc, _K(*(values[n] for n in k_names)), [values[n] for n in d_names],
                    model, width, height)


def _orb_slam(doc: YamlDocument, camera: str | None) -> Intrinsics:
    data = doc.data
    groups = sorted({m.group(1) for k in data if isinstance(k, str) and (m := _ORB_KEY.match(k))
                     and k.endswith(".fx")})
    names = ", ".join("Camera" + g for g in groups)
    chosen = {"Camera1": "1", "Camera2": "2", "left": "1", "right": "2", "Camera": ""}.get(
        camera or "", None)
    if chosen is not None and chosen not in groups:
        raise doc.error(f"camera {camera!r}: no Camera{chosen}.fx in the file; it holds "
                        f"{names}")
    if chosen is None:
        if len(groups) != 1:
            raise doc.error(f"the file holds cameras {names}; choose one with intrinsics: "
                            f"{{file: {doc.path.name}, camera: Camera{groups[0]}}} in "
                            "rig.yaml")
        chosen = groups[0]
    prefix = f"Camera{chosen}."
    kind = str(data.get("Camera.type", "PinHole")).lower()
    if kind not in _ORB_TYPES:
        raise doc.error(f"Camera.type {shown(data.get('Camera.type'))} is not supported; "
                        "expected PinHole, KannalaBrandt8 or Rectified", "Camera.type")
    model, d_names = _ORB_TYPES[kind]
    known = ("fx", "fy", "cx", "cy", *d_names)
    own = [k for k in data if isinstance(k, str) and k.startswith(prefix)]
    refuse_unknown(doc, own, tuple(prefix + n for n in known),
                   tuple(prefix + n for n in _ORB_IGNORED))
    v = {n: float(_numbers(doc, data.get(prefix + n, 0.0 if n == "k3" else None), 1,
                           prefix + n)[0]) for n in known}
    width, height = _size(doc, data.get("Camera.width", data.get(prefix + "width")),
                          data.get("Camera.height", data.get(prefix + "height")),
                          "Camera.width")
    return _checked(doc, _K(v["fx"], v["fy"], v["cx"], v["cy"]), [v[n] for n in d_names],
                    model, width, height)


def intrinsics_from_slam_config(doc: YamlDocument, camera: str | None = None) -> Intrinsics:
    """Intrinsics from a file :func:`slam_config_kind` recognises (module docstring).

    Raises
    ------
    DatasetError
        An unsupported model, a key that is neither read nor ignored, a value of the wrong
        form, or a lens beyond the bounds; with the key's line.
    """
    kind = slam_config_kind(doc.data)
    if kind == "euroc":
        return _euroc(doc)
    if kind == "camodocal":
        return _camodocal(doc)
    return _orb_slam(doc, camera)
