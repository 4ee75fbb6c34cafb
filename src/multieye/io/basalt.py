"""Camera intrinsics from Basalt's calibration JSON (``basalt_calibrate``'s
``calibration.json``, the files Basalt ships for EuRoC, TUM-VI and the T265).

The file is a cereal archive: ``{"value0": {"T_imu_cam": [...], "intrinsics": [...],
"resolution": [[w, h], ...], ...}}``; camera ``i`` is ``intrinsics[i]``, ``{"camera_type":
..., "intrinsics": {...}}``, with ``resolution[i]``.  Read, per ``camera_type``
(Usenko, Demmel and Cremers 2018, the double sphere paper, for ``ds``, ``eucm`` and
``unified``):

- ``ds``: ``fx fy cx cy xi alpha`` -> ``double-sphere`` (the same parameters);
- ``eucm``: ``fx fy cx cy alpha beta`` -> ``eucm`` (the same parameters);
- ``kb4``: ``fx fy cx cy k1 k2 k3 k4`` -> ``fisheye`` (Kannala-Brandt as OpenCV's fisheye);
- ``pinhole``: ``fx fy cx cy`` -> a pinhole without distortion;
- ``unified``: ``fx fy cx cy alpha`` (the unified model with ``alpha``: ``u = fx x /
  (alpha d + (1 - alpha) z) + cx``) -> ``unified`` (Mei-Rives) with ``xi = alpha / (1 -
  alpha)`` and the focal lengths ``fx / (1 - alpha)``, ``fy / (1 - alpha)``, no distortion:
  ``alpha d + (1 - alpha) z = (1 - alpha)(z + xi d)``.

Other camera types (``fov``, ``pinhole-radtan8``, ...) are refused naming these.  The other
keys of the file (``T_imu_cam``, the IMU's noise and biases, ``vignette``, the time offsets)
change no projection and are not read.  With several cameras, rig.yaml chooses one:
``intrinsics: {file: calibration.json, camera: cam1}`` (or ``1``: its index); a rig camera
named ``cam1`` takes the file's ``cam1`` without it, as with a Kalibr camchain.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

import numpy as np

from multieye.core.intrinsics import Intrinsics
from multieye.io.intrinsics_mapping import refuse_unknown
from multieye.io.slam_configs import _K, _checked, _size
from multieye.io.yamlfile import YamlDocument, shown

__all__ = ["is_basalt", "intrinsics_from_basalt", "BASALT_TYPES"]

#: camera_type -> (multieye model, the names of its parameters after fx fy cx cy).
BASALT_TYPES = {"ds": ("double-sphere", ("xi", "alpha")),
                "eucm": ("eucm", ("alpha", "beta")),
                "kb4": ("fisheye", ("k1", "k2", "k3", "k4")),
                "pinhole": ("pinhole", ()),
                "unified": ("unified", ("alpha",))}


def is_basalt(data) -> bool:
    """Whether a parsed file is Basalt's calibration (``value0`` with an ``intrinsics`` list)."""
    inner = data.get("value0") if isinstance(data, Mapping) else None
    return isinstance(inner, Mapping) and isinstance(inner.get("intrinsics"), list)


def _index(doc: YamlDocument, camera: str | None, n: int, prefer: str | None = None) -> int:
    """The camera chosen by rig.yaml (``cam1``, ``1``), else the one named as the rig's
    camera (``prefer``: ``cam1``), else the only one."""
    m = re.fullmatch(r"cam(\d+)", str(prefer or ""))
    if camera is None and m is not None and int(m.group(1)) < n:
        return int(m.group(1))
    if camera is None:
        if n != 1:
            raise doc.error(f"the file holds {n} cameras (0 to {n - 1}); choose one with "
                            f"intrinsics: {{file: {doc.path.name}, camera: cam0}} in rig.yaml",
                            "value0", "intrinsics")
        return 0
    m = re.fullmatch(r"(?:cam)?(\d+)", str(camera).strip())
    if m is None or int(m.group(1)) >= n:
        raise doc.error(f"camera {camera!r}: the file holds cameras cam0 to cam{n - 1} (or "
                        f"their index, 0 to {n - 1})", "value0", "intrinsics")
    return int(m.group(1))


def _resolution(doc: YamlDocument, data: Mapping, i: int) -> tuple[int | None, int | None]:
    res = data.get("resolution")
    if res is None:
        return None, None
    size = res[i] if isinstance(res, list) and i < len(res) else None
    if not (isinstance(size, list) and len(size) == 2):
        raise doc.error(f"expected resolution[{i}] as [width, height] in pixels, got "
                        f"{shown(size)}", "value0", "resolution")
    return _size(doc, *size, "value0", "resolution")


def intrinsics_from_basalt(doc: YamlDocument, camera: str | None = None,
                           prefer: str | None = None) -> Intrinsics:
    """One camera's intrinsics from a file :func:`is_basalt` recognises (module docstring):
    ``camera`` as rig.yaml's ``intrinsics: {file, camera}`` gives it; without it, the rig's
    camera name (``prefer``) when it is ``cam<i>`` of the file, else the only camera.

    Raises
    ------
    DatasetError
        Several cameras and none chosen, an unknown camera, an unsupported ``camera_type``, a
        parameter missing, unknown or not a number, a lens beyond the bounds; with its line.
    """
    data = doc.data["value0"]
    cams = data["intrinsics"]
    i = _index(doc, camera, len(cams), prefer)
    at = ("value0", "intrinsics", i)
    entry = cams[i]
    kind = entry.get("camera_type") if isinstance(entry, Mapping) else None
    if kind not in BASALT_TYPES:
        raise doc.error(f"Basalt camera_type {shown(kind)} is not supported; expected "
                        f"{', '.join(BASALT_TYPES)}", *at, "camera_type")
    model, names = BASALT_TYPES[kind]
    params = entry.get("intrinsics")
    if not isinstance(params, Mapping):
        raise doc.error(f"expected a mapping of fx, fy, cx, cy{''.join(', ' + n for n in names)}"
                        f", got {shown(params)}", *at, "intrinsics")
    known = ("fx", "fy", "cx", "cy", *names)
    refuse_unknown(doc, params, known, (), *at, "intrinsics")
    v = {}
    for n in known:
        x = params.get(n)
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x):
            raise doc.error(f"expected a number, got {shown(x)}", *at, "intrinsics", n)
        v[n] = float(x)
    scale, dist = 1.0, [v[n] for n in names]
    if kind == "unified":                       # alpha form -> Mei's xi, focal lengths
        if not 0.0 <= v["alpha"] < 1.0:
            raise doc.error(f"unified alpha must be in [0, 1), got {v['alpha']}", *at,
                            "intrinsics", "alpha")
        scale = 1.0 / (1.0 - v["alpha"])
        dist = [v["alpha"] * scale, 0.0, 0.0, 0.0, 0.0]
    width, height = _resolution(doc, data, i)
    return _checked(doc, _K(v["fx"] * scale, v["fy"] * scale, v["cx"], v["cy"]), dist, model,
                    width, height, *at)
