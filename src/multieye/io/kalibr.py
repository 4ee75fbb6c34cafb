"""Kalibr camera chains (``camchain.yaml``): read and write, so results drop into Kalibr tools.

Layout (as Kalibr documents it): one entry per camera, keyed ``cam0``, ``cam1``, ...::

    cam1:
      camera_model: pinhole
      intrinsics: [fu, fv, pu, pv]
      distortion_model: radtan          # or equidistant
      distortion_coeffs: [k1, k2, r1, r2]
      resolution: [width, height]
      T_cn_cnm1: [[...4x4...]]          # n >= 1
      rostopic: /cam1/image_raw         # optional
      cam_overlaps: [0]                 # optional: cameras seeing the target at once

``T_cn_cnm1`` maps points in camera n-1 into camera n, i.e. ``T_cam<n>_cam<n-1>``; with
poses relative to a reference camera, ``T_cn_cnm1 = inv(T_ref_cn) @ T_ref_cnm1``.

Mapping to :class:`~multieye.core.intrinsics.Intrinsics`: ``camera_model: pinhole`` with
``radtan`` is OpenCV's pinhole model with 4 coefficients ``k1 k2 p1 p2``, with
``equidistant`` the fisheye model ``k1..k4``, with ``none`` a pinhole without distortion.
The wide-angle models (:mod:`multieye.core.lens_wide`), their parameters first in
``intrinsics``::

    camera_model: omni    intrinsics: [xi, fu, fv, pu, pv]            -> unified
                          distortion_model: radtan (k1 k2 r1 r2) or none
    camera_model: ds      intrinsics: [xi, alpha, fu, fv, pu, pv]     -> double-sphere
                          distortion_model: none
    camera_model: eucm    intrinsics: [alpha, beta, fu, fv, pu, pv]   -> eucm
                          distortion_model: none

Kalibr's ``fov`` distortion and any other pairing are rejected with a message.

Choices: multieye's camera names are kept in an extra ``camera_name`` field (Kalibr ignores
unknown fields); ``resolution`` is written only when the intrinsics know the image size; a
pinhole without coefficients is written with ``distortion_model: none`` (read back as the
same lens).  Reading, as Kalibr's ``CameraParameters`` does: ``distortion_coeffs`` is needed
with ``radtan`` and ``equidistant`` (never taken as zeros); YAML's booleans and nested lists
are refused where numbers are expected.  :func:`kalibr_refusal` says why Kalibr would refuse
to load an entry multieye can write (no ``resolution``, a principal point below 0, ``ds`` /
``eucm`` alpha not below 1): the output camchains leave such cameras out with a note.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from multieye.core import geometry
from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import Intrinsics
from multieye.io.atomic import write_text_atomic
from multieye.io.yamlfile import YamlDocument, load_yaml, shown, yaml_list

__all__ = [
    "CamchainEntry",
    "read_camchain",
    "write_camchain",
    "intrinsics_from_kalibr",
    "kalibr_fields",
    "kalibr_refusal",
    "is_camchain",
    "camchain_entries",
    "overlaps_in_time",
]

_DISTORTION = {"radtan": "pinhole", "equidistant": "fisheye", "none": "pinhole"}
#: Kalibr camera model -> (Intrinsics model, its parameters before fu fv pu pv, the
#: distortion models Kalibr pairs it with here).
_CAMERAS = {"pinhole": ("pinhole", (), ("radtan", "equidistant", "none")),
            "omni": ("unified", ("xi",), ("radtan", "none")),
            "ds": ("double-sphere", ("xi", "alpha"), ("none",)),
            "eucm": ("eucm", ("alpha", "beta"), ("none",))}
_KALIBR_NAME = {"unified": "omni", "double-sphere": "ds", "eucm": "eucm"}


@dataclass(frozen=True)
class CamchainEntry:
    """One camera of a chain.

    Attributes
    ----------
    name : str
        multieye's camera name (``cam<n>`` when the file has no ``camera_name``).
    intrinsics : Intrinsics
    T_ref_cam : ndarray, shape (4, 4)
        Pose of the camera in the reference camera's frame (metres).  Read back from a file,
        the reference is the chain's first camera.
    rostopic : str or None
    cam_overlaps : tuple of int, or None
        Indices in the chain of the cameras that saw the target at the same time as this
        one (Kalibr's ``cam_overlaps``); None leaves the key out.
    """

    name: str
    intrinsics: Intrinsics
    T_ref_cam: np.ndarray
    rostopic: str | None = None
    cam_overlaps: tuple[int, ...] | None = None

    def __post_init__(self):
        T = np.asarray(self.T_ref_cam, dtype=np.float64)
        if T.shape != (4, 4):
            raise InputError(f"camera {self.name}: T_ref_cam must be 4x4, got {T.shape}")
        object.__setattr__(self, "T_ref_cam", T)


def is_camchain(data) -> bool:
    """True for a Kalibr entry (``camera_model`` key) or a mapping of such entries."""
    if not isinstance(data, Mapping):
        return False
    return "camera_model" in data or any(
        isinstance(v, Mapping) and "camera_model" in v for v in data.values())


def _numbers(value, n: int | None, what: str, doc: YamlDocument, *keys,
             flat: bool = True) -> np.ndarray:
    """``n`` finite numbers (a flat list unless ``flat`` is False); YAML's booleans
    (``yes``, ``true``) are refused, numbers written as text (``'1e-3'``: YAML 1.1 reads an
    exponent without a dot as text) read as numbers."""
    items = value if isinstance(value, list) else [value]
    nested = [v for v in items if isinstance(v, list)]
    if flat and nested:
        raise doc.error(f"{what} must be a flat list of {n} numbers, got {shown(value)}", *keys)
    for v in (x for item in items for x in (item if isinstance(item, list) else [item])):
        if isinstance(v, bool):
            raise doc.error(f"{what} must be numbers, got {v} (YAML reads yes, no, true and "
                            "false as booleans)", *keys)
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise doc.error(f"{what} must be numbers, got {shown(value)}", *keys) from None
    if (n is not None and arr.size != n) or not np.all(np.isfinite(arr)):
        raise doc.error(f"{what} must be {n} finite numbers, got {shown(value)}", *keys)
    return arr.reshape(-1) if flat else arr


def intrinsics_from_kalibr(entry: Mapping, doc: YamlDocument, *keys) -> Intrinsics:
    """Intrinsics from one Kalibr camera entry (``doc`` and ``keys`` locate it for messages)."""
    model = entry.get("camera_model")
    if not isinstance(model, str) or model not in _CAMERAS:
        raise doc.error(f"camera_model {shown(model)} is not supported; expected pinhole, "
                        "omni, ds or eucm", *keys, "camera_model")
    kind, first, dmodels = _CAMERAS[model]
    for key in ("intrinsics", "distortion_model"):
        if key not in entry:
            raise doc.error(f"missing key {key!r}", *keys)
    names = ", ".join(first + ("fu", "fv", "pu", "pv"))
    *params, fu, fv, pu, pv = _numbers(entry["intrinsics"], 4 + len(first),
                                       f"intrinsics [{names}]", doc, *keys, "intrinsics")
    dmodel = entry["distortion_model"]
    if not isinstance(dmodel, str) or dmodel not in dmodels:
        raise doc.error(f"distortion_model {shown(dmodel)} is not supported with camera_model "
                        f"{model}; expected {' or '.join(dmodels)}", *keys, "distortion_model")
    n = 0 if dmodel == "none" else 4
    if n and "distortion_coeffs" not in entry:      # Kalibr needs them too: no silent zeros
        raise doc.error(f"missing key 'distortion_coeffs' (the {n} coefficients of {dmodel})",
                        *keys)
    coeffs = _numbers(entry.get("distortion_coeffs", []), n, "distortion_coeffs",
                      doc, *keys, "distortion_coeffs")
    width = height = None
    if "resolution" in entry:
        res = _numbers(entry["resolution"], 2, "resolution [width, height]", doc, *keys,
                       "resolution")
        if not all(v > 0 and v == int(v) for v in res):
            raise doc.error(f"resolution [width, height] must be positive integers, got "
                            f"{res.tolist()}", *keys, "resolution")
        width, height = int(res[0]), int(res[1])
    K = np.array([[fu, 0.0, pu], [0.0, fv, pv], [0.0, 0.0, 1.0]])
    if kind == "unified":
        coeffs = np.concatenate([params, coeffs if n else np.zeros(4)])
    elif kind != "pinhole":
        coeffs = np.asarray(params, dtype=np.float64)
    try:
        return Intrinsics(K, coeffs, _DISTORTION[dmodel] if kind == "pinhole" else kind,
                          width, height)
    except InputError as exc:
        raise doc.error(str(exc), *keys) from None


def kalibr_fields(intr: Intrinsics) -> dict:
    """The Kalibr entry fields of intrinsics (without ``T_cn_cnm1``).

    Raises
    ------
    InputError
        A pinhole model with non-zero coefficients beyond ``k1 k2 p1 p2`` (Kalibr's radtan
        cannot hold them).
    """
    K = intr.K
    first: list[float] = []
    if intr.model == "fisheye":
        dmodel, coeffs = "equidistant", intr.dist[:4]
    elif intr.model == "unified":
        first, dmodel, coeffs = [float(intr.dist[0])], "radtan", intr.dist[1:]
    elif intr.model in _KALIBR_NAME:
        first, dmodel, coeffs = [float(v) for v in intr.dist], "none", intr.dist[:0]
    elif intr.dist.size == 0:            # read back as the same lens: no coefficients
        dmodel, coeffs = "none", intr.dist
    else:
        coeffs = np.zeros(4)
        coeffs[: min(4, intr.dist.size)] = intr.dist[:4]
        if np.any(intr.dist[4:] != 0):
            raise InputError("Kalibr radtan holds k1 k2 p1 p2 only; these intrinsics have "
                             f"{intr.dist.size} non-trivial coefficients (model: "
                             "pinhole-radtan4 in rig.yaml estimates a lens Kalibr can hold)")
        dmodel = "radtan"
    if K[0, 1] != 0:
        raise InputError(f"Kalibr's camera models have no skew; camera matrix has skew "
                         f"{K[0, 1]}")
    fields = {
        "camera_model": _KALIBR_NAME.get(intr.model, "pinhole"),
        "intrinsics": first + [float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])],
        "distortion_model": dmodel,
        "distortion_coeffs": [float(c) for c in coeffs],
    }
    if intr.width is not None and intr.height is not None:
        fields["resolution"] = [int(intr.width), int(intr.height)]
    return fields


def kalibr_refusal(intr: Intrinsics) -> str | None:
    """Why Kalibr would refuse to load these intrinsics from a camchain (its
    ``CameraParameters`` checks), or None: no ``resolution`` (a required key), a principal
    point below 0, or ``ds`` / ``eucm`` alpha not below 1 (Kalibr needs ``0 <= alpha < 1``;
    the models themselves admit 1).  multieye reads such an entry back as written."""
    if intr.width is None or intr.height is None:
        return ("Kalibr's camchain needs the image size (resolution), which these intrinsics "
                "do not know")
    for name, c in (("cx", intr.K[0, 2]), ("cy", intr.K[1, 2])):
        if c < 0:
            return f"Kalibr refuses a principal point below 0: {name} = {c:g}"
    alpha = {"double-sphere": 1, "eucm": 0}.get(intr.model)
    if alpha is not None and not intr.dist[alpha] < 1:
        return f"Kalibr's ds and eucm need alpha < 1, this lens has alpha = {intr.dist[alpha]:g}"
    return None


def write_camchain(path: str | os.PathLike, cameras: Sequence[CamchainEntry], *,
                   comments: Sequence[str] = ()) -> None:
    """Write a Kalibr ``camchain.yaml`` atomically, cameras in the given order.

    Parameters
    ----------
    path : path-like
    cameras : sequence of CamchainEntry
        ``cam<n>`` is ``cameras[n]``; ``T_cn_cnm1 = inv(T_ref_cn) @ T_ref_cnm1``.
    comments : sequence of str
        Lines written first as YAML comments (e.g. the cameras left out, and why).
    """
    lines = [f"# {c}" for c in comments]
    for n, cam in enumerate(cameras):
        lines.append(f"cam{n}:")
        lines.append(f"  camera_name: {json.dumps(cam.name)}")  # JSON strings are YAML
        for key, value in kalibr_fields(cam.intrinsics).items():
            if key == "resolution":
                text = f"[{value[0]}, {value[1]}]"
            else:
                text = yaml_list(value) if isinstance(value, list) else value
            lines.append(f"  {key}: {text}")
        if n > 0:
            T = geometry.inv(cam.T_ref_cam) @ cameras[n - 1].T_ref_cam
            lines.append("  T_cn_cnm1:")
            lines.extend(f"  - {yaml_list(row)}" for row in T)
        if cam.cam_overlaps is not None:
            lines.append(f"  cam_overlaps: [{', '.join(str(int(k)) for k in cam.cam_overlaps)}]")
        if cam.rostopic:
            lines.append(f"  rostopic: {json.dumps(cam.rostopic)}")
    write_text_atomic(path, "\n".join(lines) + "\n")


def _rigid(value, doc: YamlDocument, *keys) -> np.ndarray:
    T = _numbers(value, 16, "T_cn_cnm1 (4x4)", doc, *keys, flat=False).reshape(4, 4)
    if not geometry.is_rigid(T):
        raise doc.error("T_cn_cnm1 is not a rigid transform", *keys)
    return T


def camchain_entries(doc: YamlDocument) -> list[tuple[str, Mapping]]:
    """``(key, entry)`` of a camchain document in chain order (``cam0``, ``cam1``, ...)."""
    data = doc.data
    keys = sorted((k for k in data if k.startswith("cam") and k[3:].isdigit()),
                  key=lambda k: int(k[3:]))
    if [int(k[3:]) for k in keys] != list(range(len(keys))) or not keys:
        raise doc.error(f"camera keys must be cam0, cam1, ... without gaps, got "
                        f"{', '.join(data) or 'none'}")
    for k in keys:
        if not isinstance(data[k], Mapping):
            raise doc.error("expected a mapping with camera_model, intrinsics, ...", k)
    return [(k, data[k]) for k in keys]


def read_camchain(path: str | os.PathLike) -> tuple[CamchainEntry, ...]:
    """Read a Kalibr camchain; poses are chained from ``cam0`` (``T_ref_cam0 = I``).

    Raises
    ------
    DatasetError
        Missing keys, unsupported models, malformed numbers or a non-rigid ``T_cn_cnm1``,
        with the line of the offending key.
    """
    doc = load_yaml(path, what="Kalibr camchain")
    if not isinstance(doc.data, Mapping):
        raise DatasetError("expected a mapping of cam0, cam1, ...", path=path, line=1)
    out = []
    T_ref = np.eye(4)
    for n, (key, entry) in enumerate(camchain_entries(doc)):
        intr = intrinsics_from_kalibr(entry, doc, key)
        if n > 0:
            if "T_cn_cnm1" not in entry:
                raise doc.error("missing key 'T_cn_cnm1'", key)
            T_ref = T_ref @ geometry.inv(_rigid(entry["T_cn_cnm1"], doc, key, "T_cn_cnm1"))
        name = str(entry.get("camera_name", key))
        rostopic, overlaps = entry.get("rostopic"), entry.get("cam_overlaps")
        if overlaps is not None:
            if not isinstance(overlaps, list) or not all(
                    isinstance(k, int) and not isinstance(k, bool) for k in overlaps):
                raise doc.error(f"cam_overlaps must be a list of camera indices, got "
                                f"{shown(overlaps)}", key, "cam_overlaps")
            overlaps = tuple(overlaps)
        out.append(CamchainEntry(name, intr, T_ref.copy(), None if rostopic is None else
                                 str(rostopic), overlaps))
    return tuple(out)


def overlaps_in_time(stamps: Sequence[np.ndarray], tolerances: Sequence[float]) -> list[list[int]]:
    """Per camera, the indices of the others that saw the target at the same time: a stamp
    of each within the smaller of their time tolerances (stamps in one clock, seconds)."""
    sorted_stamps = [np.sort(np.asarray(s, dtype=np.float64)) for s in stamps]
    out = [[] for _ in stamps]
    for j, sj in enumerate(sorted_stamps):
        for k in range(j + 1, len(sorted_stamps)):
            sk, tol = sorted_stamps[k], min(tolerances[j], tolerances[k])
            if sj.size == 0 or sk.size == 0:
                continue
            pos = np.clip(np.searchsorted(sk, sj), 1, max(sk.size - 1, 1))
            near = np.minimum(np.abs(sk[pos - 1] - sj), np.abs(sk[np.minimum(pos, sk.size - 1)] - sj))
            if np.any(near <= tol):
                out[j].append(k)
                out[k].append(j)
    return [sorted(o) for o in out]
