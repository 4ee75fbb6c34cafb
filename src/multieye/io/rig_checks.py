"""The type and presence checks of ``rig.yaml`` (:mod:`multieye.io.rig`): each raises a
:class:`DatasetError` at the line of the key concerned, naming the dotted key path and what
was expected."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path

from multieye.core.arguments import did_you_mean
from multieye.core.errors import DatasetError
from multieye.io.image_folder import SYNC_MODES, check_pattern
from multieye.io.pose_files import STEM
from multieye.io.yamlfile import YamlDocument, shown
from multieye.core.limits import (MAX_ROTATION_NOISE_DEG, MAX_STAMP_S, MAX_TIME_TOLERANCE_S,
                                  MAX_TRANSLATION_NOISE_M)

__all__ = ["Checker", "sensor_keys", "links_keys", "camera_link", "video_keys", "MOCAP_SENSORS",
           "MOCAP_NOISE_BOUND_KEYS", "crop_key", "images_key", "model_key", "stem_pattern", "sync_keys"]

#: What ``mocap.sensor`` may name, and the keys of ``mocap.noise_bounds`` (docs/rig-yaml.md).
MOCAP_SENSORS = ("motion-capture", "robot")
MOCAP_NOISE_BOUND_KEYS = ("rotation_deg", "translation_m")

_FLOAT_TEXT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")


class Checker:
    """Type and presence checks that raise at the line of the key concerned."""

    def __init__(self, doc: YamlDocument):
        self.doc = doc
        self.folder = doc.path.parent.resolve()

    def error(self, message, keys):
        return self.doc.error(message, *keys)

    def mapping(self, value, keys, allowed, required=()):
        if not isinstance(value, Mapping):
            raise self.error(f"expected a mapping, got {type(value).__name__}", keys)
        for key in value:
            if key not in allowed:
                raise self.error(f"unknown key{did_you_mean(key, allowed)}; expected one of "
                                 f"{', '.join(allowed)}", keys + (key,))
        for key in required:
            if key not in value:
                raise self.error(f"missing key {key!r}", keys)
        return value

    def string(self, value, keys):
        if not isinstance(value, str) or not value.strip():
            raise self.error(f"expected a non-empty string, got {shown(value)}", keys)
        return value.strip()

    def boolean(self, value, keys) -> bool:
        if not isinstance(value, bool):
            raise self.error(f"expected true or false, got {shown(value)}", keys)
        return value

    def choice(self, value, keys, options):
        if isinstance(value, (list, dict)) or value not in options:
            raise self.error(f"expected one of {', '.join(options)}, got {shown(value)}"
                             f"{did_you_mean(value, options)}", keys)
        return value

    def number(self, value, keys, *, positive=False, integer=False, maximum=None, unit=""):
        """A finite number (``integer``: an int), > 0 if ``positive``, and at most ``maximum``
        (in magnitude when it may be negative); ``unit`` names it in the message."""
        ok = isinstance(value, int) if integer else isinstance(value, (int, float))
        ok = ok and not isinstance(value, bool) and math.isfinite(value)
        ok = ok and (not positive or value > 0)
        ok = ok and (maximum is None or (value if positive else abs(value)) <= maximum)
        if not ok:
            kind = "integer" if integer else "number"
            article = "an" if integer else "a"
            unit = f" {unit}" if unit else ""
            if maximum is None:
                what = f"a positive {kind}{unit}" if positive else f"{article} {kind}{unit}"
            elif positive:
                what = f"a positive {kind} of at most {maximum:g}{unit}"
            else:
                what = f"{article} {kind} between {-maximum:g} and {maximum:g}{unit}"
            hint = ""
            if isinstance(value, str) and _FLOAT_TEXT.match(value.strip()):
                hint = (" (YAML 1.1 reads an exponent without a dot and a sign as text: write "
                        "1.0e-3, not 1e-3)")
            raise self.error(f"expected {what}, got {shown(value)}{hint}", keys)
        return value if integer else float(value)

    def path(self, value, keys, kind):
        """The path ``value`` (relative to the folder of rig.yaml), resolved; messages name
        it as the user typed it."""
        typed = self.string(value, keys)
        shown = typed if Path(typed).is_absolute() else f"{typed} (relative to rig.yaml's folder)"
        try:
            p = (self.folder / typed).resolve()
        except (RuntimeError, OSError) as exc:     # a link loop (RuntimeError before 3.13)
            raise self.error(f"{kind} is a symbolic link loop (or cannot be resolved: "
                             f"{getattr(exc, 'strerror', None) or 'loop'}): {shown}",
                             keys) from None
        except ValueError as exc:                  # a NUL byte
            raise self.error(f"invalid path {shown!r}: {exc}", keys) from None
        if not p.exists():
            raise self.error(f"{kind} not found: {shown}", keys)
        if kind == "folder" and not p.is_dir():
            raise self.error(f"expected a folder, found a file: {shown}", keys)
        if kind == "file" and p.is_dir():
            raise self.error(f"expected a file, found a folder: {shown}", keys)
        return p


def sensor_keys(c: Checker, raw: Mapping, at) -> dict:
    """``sensor`` and ``noise_bounds`` of a ``mocap`` mapping, checked (``at(key)``: the key
    path of ``key``), as :class:`multieye.io.mocap.MocapSpec` fields (radians, metres)."""

    kw = {}
    if "sensor" in raw:
        kw["sensor"] = c.choice(raw["sensor"], at("sensor"), MOCAP_SENSORS)
    if "noise_bounds" in raw:
        here = at("noise_bounds")
        bounds = c.mapping(raw["noise_bounds"], here, MOCAP_NOISE_BOUND_KEYS)
        if not bounds:
            raise c.error(f"expected {' and/or '.join(MOCAP_NOISE_BOUND_KEYS)}", here)
        rot = (math.radians(c.number(bounds["rotation_deg"], here + ("rotation_deg",),
                                     positive=True, maximum=MAX_ROTATION_NOISE_DEG,
                                     unit="degrees")) if "rotation_deg" in bounds else None)
        trans = (c.number(bounds["translation_m"], here + ("translation_m",), positive=True,
                          maximum=MAX_TRANSLATION_NOISE_M, unit="metres")
                 if "translation_m" in bounds else None)
        kw["noise_bounds"] = (rot, trans)
    return kw


def video_keys(c: Checker, raw: Mapping, keys) -> dict:
    """A video camera's ``stamps`` (a frame stamps file) or ``start_time`` (seconds, the
    first frame's stamp), each only with ``video`` and not both; or an image folder's
    ``stamps`` (its images' stamps, when their names are not)."""
    if "start_time" in raw and "video" not in raw:
        raise c.error("'start_time' goes with 'video' (the first frame's stamp of a video "
                      "file)", keys + ("start_time",))
    if "stamps" in raw and "video" not in raw and "images" not in raw:
        raise c.error("'stamps' goes with 'video' or 'images' (the stamps of a video's frames "
                      "or of a folder's images)", keys + ("stamps",))
    if "stamps" in raw and "start_time" in raw:
        raise c.error("give either 'stamps' (a stamp per frame) or 'start_time' (the first "
                      "frame's, the others at the video's frame rate), not both", keys)
    out: dict = {}
    if "stamps" in raw:
        out["stamps"] = c.path(raw["stamps"], keys + ("stamps",), "file")
    if "start_time" in raw:
        start = c.number(raw["start_time"], keys + ("start_time",), maximum=MAX_STAMP_S,
                         unit="seconds")
        if start < 0:
            raise c.error(f"expected a time stamp >= 0 seconds, got {start}",
                          keys + ("start_time",))
        out["start_time"] = float(start)
    return out


#: Lens model names other tools use, and what multieye calls that lens (rig.yaml's ``model``).
OTHER_MODEL_NAMES = {
    "pinhole": "pinhole-radtan4 (Kalibr's pinhole with radtan: k1 k2 p1 p2), pinhole-radtan "
               "(OpenCV's and ROS plumb_bob's k1 k2 p1 p2 k3) or pinhole-rational (OpenCV's 8)",
    "radtan": "pinhole-radtan4 (Kalibr's radtan: k1 k2 p1 p2) or pinhole-radtan (with k3)",
    "plumb_bob": "pinhole-radtan", "rational_polynomial": "pinhole-rational",
    "equidistant": "fisheye", "kannala_brandt": "fisheye", "kannala-brandt": "fisheye",
    "kb4": "fisheye", "omni": "unified", "omni-radtan": "unified", "mei": "unified",
    "ds": "double-sphere", "double_sphere": "double-sphere", "extended-unified": "eucm",
}


def model_key(c: Checker, value, keys, models) -> str:
    """A camera's ``model``: one of ``models``; another tool's name for a lens is refused
    naming multieye's (``pinhole`` -> ``pinhole-radtan4`` for Kalibr's pinhole with radtan)."""
    name = value.strip().lower() if isinstance(value, str) else None
    if name in OTHER_MODEL_NAMES and value not in models:
        raise c.error(f"expected one of {', '.join(models)}, got {value!r}, another tool's "
                      f"name: multieye's is {OTHER_MODEL_NAMES[name]}", keys)
    return c.choice(value, keys, models)


#: Fewest pixels across a camera's ``crop`` (no board is found in fewer).
MIN_CROP_PX = 32


def crop_key(c: Checker, raw: Mapping, keys) -> dict:
    """A camera's ``crop``: ``[x, y, width, height]`` of the recorded images (integers,
    pixels; a side-by-side stereo frame's half), only with images, a video or a bag."""
    if "crop" not in raw:
        return {}
    if "poses" in raw:
        raise c.error("'crop' goes with 'images', 'video' or 'rosbag' (the camera's region "
                      "of each recorded image)", keys + ("crop",))
    value = raw["crop"]
    if not isinstance(value, list) or len(value) != 4:
        raise c.error(f"expected [x, y, width, height] (pixels of the recorded images), got "
                      f"{shown(value)}", keys + ("crop",))
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        raise c.error(f"expected [x, y, width, height] in whole pixels (integers such as 640, "
                      f"not 640.0, '640' or true), got {shown(value)}", keys + ("crop",))
    x, y, w, h = (c.number(v, keys + ("crop",), integer=True, maximum=100_000) for v in value)
    if min(x, y) < 0 or min(w, h) < MIN_CROP_PX:
        raise c.error(f"expected x, y >= 0 and width, height >= {MIN_CROP_PX} pixels, got "
                      f"{shown(value)}", keys + ("crop",))
    return {"crop": (x, y, w, h)}


def no_link_loop(p: Path) -> None:
    """Refuse rig.yaml ``p`` when it is a symbolic link loop (or cannot be resolved), in one
    line naming it as typed."""
    try:
        p.resolve()
    except (RuntimeError, OSError) as exc:          # a link loop (RuntimeError before 3.13)
        raise DatasetError("rig.yaml is a symbolic link loop (or cannot be resolved: "
                           f"{getattr(exc, 'strerror', None) or 'loop'})", path=p) from None


def links_keys(c: Checker, raw: Mapping, setups: tuple[str, ...]
               ) -> tuple[str, float | None, bool]:
    """The top-level keys that say how the rig is linked: ``setup`` (required with motion
    capture; without it the setup names nothing the calibration uses, and defaults to the
    first of ``setups``), ``sync_tolerance`` (seconds, or None for the default) and whether
    any motion capture is given (top-level ``mocap`` or a camera's own)."""
    cams = raw.get("cameras")
    any_mocap = "mocap" in raw or any(isinstance(cam, Mapping) and "mocap" in cam for cam in (
        cams.values() if isinstance(cams, Mapping) else ()))
    if "setup" not in raw and any_mocap:
        raise c.error("missing key 'setup' (eye-to-base or eye-on-hand: what the motion "
                      "capture tracks)", ())
    setup = c.choice(raw.get("setup", setups[0]), ("setup",), setups)
    sync = (c.number(raw["sync_tolerance"], ("sync_tolerance",), positive=True,
                     maximum=MAX_TIME_TOLERANCE_S, unit="seconds")
            if "sync_tolerance" in raw else None)
    return setup, sync, any_mocap


def camera_link(c: Checker, name: str, mocap, source: str, any_mocap: bool) -> None:
    """A rig has motion capture for every camera or for none; without it a camera needs
    target points (images), which ``poses`` do not give."""
    if mocap is None and any_mocap:
        raise c.error("no motion capture: add a top-level 'mocap' section or a 'mocap' key to "
                      "this camera (a rig has motion capture for every camera, or none)",
                      ("cameras", name))
    if not any_mocap and source == "poses":
        raise c.error("a rig without motion capture is linked by the target points its "
                      "cameras see together; a camera given by 'poses' has none (give it "
                      "'images' or 'rosbag', or add 'mocap')", ("cameras", name))


_GLOB = set("*?[")


def _inside(c: Checker, typed: str, keys, what: str) -> Path:
    """The folder ``typed`` (a folder part of a pattern), which must lie in rig.yaml's folder:
    relative, without ``..``, not leaving it through a link."""
    if Path(typed).is_absolute() or ".." in Path(typed).parts or _GLOB & set(typed):
        raise c.error(f"{what}: the folder of a pattern is a folder of the dataset (relative to "
                      f"rig.yaml, no '..', no pattern in it), got {typed!r}; give a folder "
                      "path without a pattern instead", keys)
    folder = c.path(typed or ".", keys, "folder")
    if not folder.is_relative_to(c.folder):
        raise c.error(f"{what}: folder {typed!r} leads out of the dataset folder (a link to "
                      f"{folder})", keys)
    return folder


def images_key(c: Checker, value, keys) -> tuple[Path, str | None]:
    """A camera's ``images``: a folder, or a file-name pattern (``left*.jpg``, or
    ``raw/left*.jpg`` in a folder of the dataset, or ``frames/*/left.jpg`` through its
    sub-folders) as ``(folder, pattern)``: the folder is the path before the first part
    with a wildcard."""
    typed = c.string(value, keys)
    if not _GLOB & set(typed):
        return c.path(typed, keys, "folder"), None
    parts = typed.rstrip("/").split("/")
    first = next(i for i, part in enumerate(parts) if _GLOB & set(part))
    try:
        pattern = check_pattern("/".join(parts[first:]))
    except ValueError as exc:
        raise c.error(str(exc), keys) from None
    return _inside(c, "/".join(parts[:first]), keys, "images"), pattern


def stem_pattern(c: Checker, typed: str, keys) -> Path:
    """A ``{stem}`` pose-file name: beside each image (no folder, kept relative), or in a
    folder of the dataset (``poses/{stem}.yaml``: that folder, absolute, and the name)."""
    head, _, name = typed.rpartition("/")
    if STEM in head or STEM not in name:
        raise c.error(f"expected a pose-file name with {STEM} in its name "
                      f"(\"{STEM}.yaml\", or \"poses/{STEM}.yaml\" in a folder of the dataset), "
                      f"got {typed!r}", keys)
    return Path(name) if not head else _inside(c, head, keys, "file") / name


def sync_keys(c: Checker, raw: Mapping, cameras: Mapping, mocap) -> str:
    """``sync`` (default ``time``), checked against the cameras (``CameraSpec`` by name;
    ``mocap``: the top-level ``MocapSpec`` or None): pairing by name needs images in folders,
    and cameras paired with motion capture in time need stamps in their names."""
    if "sync" not in raw:
        return "time"
    sync = c.choice(raw["sync"], ("sync",), SYNC_MODES)
    if sync == "time":
        return sync
    for name, cam in cameras.items():
        if cam.stamps is not None:
            raise c.error(f"sync: {sync} pairs images by their file names; camera {name} has "
                          "'stamps' (leave out 'sync' to pair by those stamps)", ("sync",))
        if cam.source != "images":
            raise c.error(f"sync: {sync} pairs images by their file names; camera {name} has "
                          f"{cam.source}, not images (leave out 'sync' to pair by time)",
                          ("sync",))
        spec = cam.mocap if cam.mocap is not None else mocap
        if spec is not None and not spec.by_name:
            raise c.error(f"sync: {sync} names images without time stamps, but camera {name} "
                          "pairs with motion capture in time (its image names are its stamps); "
                          "leave out 'sync', or match its poses by name", ("sync",))
    return sync

