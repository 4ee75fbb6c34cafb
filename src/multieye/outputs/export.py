"""Export a calibration to the formats other tools read: ``multieye export OUT --format F``.

:func:`export` reads ``OUT/calibration.json`` (and the intrinsics from ``OUT/details.json``,
:mod:`multieye.io.run_details`, where a format holds them) and writes into ``OUT/export/``:

=============  =========================  ==================================================
format         file                       content
=============  =========================  ==================================================
``kalibr``     ``camchain.yaml``          Kalibr camera chain (``T_cn_cnm1``, intrinsics);
                                          :func:`multieye.io.read_camchain` reads it back
``opencv``     ``extrinsics.yaml``        OpenCV FileStorage: per camera ``T_ref_cam`` and
                                          ``T_world_cam`` (or ``T_body_cam``) as 4x4
                                          ``!!opencv-matrix``, with intrinsics when known
``urdf``       ``cameras.urdf``           one fixed joint per camera from the base link;
                                          :func:`~multieye.outputs.export_readers.read_urdf_joints` reads it back
``tf-static``  ``static_transforms.sh``   one ROS 2 ``static_transform_publisher`` command
                                          per camera; :func:`~multieye.outputs.export_readers.read_tf_static` reads it back
``json``       ``calibration.json``       compact ``calibration.json``;
                                          :func:`multieye.io.read_calibration` reads it back
``camera-info`` ``camera_info/<cam>.yaml`` ROS ``sensor_msgs/CameraInfo`` YAML per camera;
                                          :func:`multieye.io.read_camera_info` reads it back
``mrcal``      ``mrcal/<cam>.cameramodel`` mrcal camera model per camera (``rt_cam_ref``
                                          from the reference camera); ``mrcal`` and
                                          :func:`multieye.io.read_intrinsics` read it
=============  =========================  ==================================================

A camera a format cannot hold (Kalibr's and ROS's lens models, no intrinsics) is named with
the reason in a note (``notes``) and, for Kalibr, in a comment in the file; never dropped
silently.

Frames.  The base frame is the one each camera's unknown X is expressed in (docs/conventions.md,
section 2), under the name rig.yaml's ``mocap: pose:`` gives it (``calibration.json``'s
``frames``): the fixed frame for eye-to-base, where ``X = T_world_cam`` (``world``, or
``base`` for ``pose: T_base_marker``), and the tracked frame for eye-on-hand, where
``X = T_body_cam`` (``body``, or ``tool0`` for ``pose: T_base_tool0``; for a calibration.json
of an earlier version, the tracked frame details.json records).  ``parent_frame`` replaces the
base frame's name; ``child_frame`` is the stem of each camera's frames, ``{camera}`` standing
for the camera's name made a ROS name (:func:`ros_name`: ``front left`` -> ``front_left``; default
``{camera}``): ``<stem>_link`` and ``<stem>_optical_frame``.  multieye's camera frame is the
optical frame of OpenCV and of ROS (REP 103: x right, y down, z forward), so in ROS terms the
calibrated pose is that of ``<camera>_optical_frame``.  The URDF adds the usual body-convention
link ``<camera>_link`` (x forward, y left, z up) between the base and the optical frame, with
``T_link_optical`` = rpy ``(-pi/2, 0, -pi/2)``; the tf lines publish base -> optical frame
directly.

Conventions checked against the formats' definitions: a URDF joint ``<origin xyz rpy>`` is the
pose of the child link in the parent link, with ``rpy`` fixed-axis roll about x, then pitch
about y, then yaw about z, i.e. ``R = Rz(yaw) Ry(pitch) Rx(roll)``; ROS 2's
``static_transform_publisher --x --y --z --qx --qy --qz --qw --frame-id P --child-frame-id C``
publishes the pose of C in P (``T_P_C``), translation in metres.  Numbers are written with
``repr`` precision, so every round trip is exact to the last bit of the text.

Synopsis
--------
>>> from multieye.outputs.export import export, FORMATS
>>> export("out", "urdf")                # doctest: +SKIP
[PosixPath('out/export/cameras.urdf')]
"""

from __future__ import annotations

import json
import os
import shlex
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from multieye.core import geometry as g
from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import WIDE_MODELS, Intrinsics
from multieye.core.names import file_stems
from multieye.io.atomic import confined_to, make_folder, write_text_atomic
from multieye.io.intrinsics_files import camera_info_note, camera_info_text, distortion_model_name
from multieye.outputs.folder import claim_output
from multieye.outputs.stereo import opencv_stereo_lines, per_camera, stereo_pairs
from multieye.io.cameramodel import cameramodel_text
from multieye.io.calibration_json import (CalibrationRecord, calibration_to_dict,
                                          read_calibration)
from multieye.io.kalibr import CamchainEntry, kalibr_fields, kalibr_refusal, write_camchain
from multieye.io.run_details import read_run_details
from multieye.io.yamlfile import yaml_list

__all__ = [
    "FORMATS",
    "BASE_FRAME",
    "base_frame",
    "ros_name",
    "T_LINK_OPTICAL",
    "export",
    "frame_names",
    "kalibr_chain",
    "opencv_text",
    "urdf_text",
    "tf_static_text",
]

#: Format names of ``multieye export --format``, and the file each writes in ``OUT/export/``.
FORMATS = {
    "kalibr": "camchain.yaml",
    "opencv": "extrinsics.yaml",
    "urdf": "cameras.urdf",
    "tf-static": "static_transforms.sh",
    "json": "calibration.json",
    "camera-info": "camera_info/<camera>.yaml",
    "mrcal": "mrcal/<camera>.cameramodel",
}

#: setup -> name of the frame the cameras' X is expressed in.
BASE_FRAME = {"eye-to-base": "world", "eye-on-hand": "body", "overlap": "ref"}

_TF_COMMAND = ("ros2", "run", "tf2_ros", "static_transform_publisher")


#: Pose of the ROS optical frame (x right, y down, z forward) in the body-convention camera
#: link (x forward, y left, z up): rpy (-pi/2, 0, -pi/2).
T_LINK_OPTICAL = g.make_transform(g.rotation_from_rpy((-np.pi / 2, 0.0, -np.pi / 2)), np.zeros(3))


def _f(x: float) -> str:
    """A float as the shortest text that reads back to the same double."""
    return repr(float(x))


# --------------------------------------------------------------------------- writers (text)


def _opencv_matrix(name: str, M: np.ndarray, indent: str) -> list[str]:
    M = np.atleast_2d(np.asarray(M, dtype=np.float64))
    return [f"{indent}{name}: !!opencv-matrix", f"{indent}   rows: {M.shape[0]}",
            f"{indent}   cols: {M.shape[1]}", f"{indent}   dt: d",
            f"{indent}   data: {yaml_list(M.reshape(-1))}"]


def opencv_text(rec: CalibrationRecord, intrinsics: dict[str, Intrinsics | None],
                parent: str | None = None) -> str:
    """OpenCV FileStorage YAML of a calibration (what ``extrinsics.yaml`` holds).

    Layout: ``setup``, ``method``, ``reference_camera``, ``base_frame``, the shared unknown
    (``T_marker_target`` or ``T_world_target``) and ``cameras``, a sequence of maps with
    ``name``, ``T_ref_cam``, ``T_world_cam`` (or ``T_body_cam``) and, when known,
    ``camera_matrix``, ``camera_model`` (``pinhole`` or ``fisheye``), ``distortion_model``
    (:func:`multieye.io.intrinsics_files.distortion_model_name`: ``plumb_bob``,
    ``rational_polynomial``, ``thin_prism``, ``tilted`` or ``equidistant``),
    ``distortion_coefficients`` (1 x k), ``image_width`` and ``image_height``.  Read it with
    ``cv2.FileStorage(path, cv2.FILE_STORAGE_READ)``; ``fs.getNode("cameras").at(j)``.
    """
    y_key, x_key = rec.named_keys() if rec.mocap else (None, None)
    lines = ["%YAML:1.0", "---",
             "# multieye calibration: T_a_b maps coordinates in frame b to frame a (metres)",
             f"setup: {json.dumps(rec.setup)}", f"method: {json.dumps(rec.method)}",
             f"reference_camera: {json.dumps(rec.reference_camera)}",
             f"base_frame: {json.dumps(frame_names(rec, parent, cameras=False)[0])}",
             *(_opencv_matrix(y_key, rec.Y, "") if rec.mocap else []), "cameras:"]
    ind = "      "
    for cam in rec.cameras:
        lines += ["   -", f"{ind}name: {json.dumps(cam.name)}",
                  *_opencv_matrix("T_ref_cam", cam.T_ref_cam, ind),
                  *(_opencv_matrix(x_key, cam.X, ind) if cam.X is not None else [])]
        intr = intrinsics.get(cam.name)
        if intr is not None:
            lines += _opencv_matrix("camera_matrix", intr.K, ind)
            lines.append(f"{ind}camera_model: {json.dumps(intr.model)}")
            lines.append(f"{ind}distortion_model: {json.dumps(distortion_model_name(intr))}")
            if intr.dist.size:
                lines += _opencv_matrix("distortion_coefficients", intr.dist[None], ind)
            if intr.width is not None and intr.height is not None:
                lines += [f"{ind}image_width: {int(intr.width)}",
                          f"{ind}image_height: {int(intr.height)}"]
    return "\n".join(lines) + "\n"


def _origin(parent: ET.Element, T: np.ndarray) -> None:
    xyz = " ".join(_f(v) for v in T[:3, 3])
    rpy = " ".join(_f(v) for v in g.rpy_from_rotation(T[:3, :3]))
    ET.SubElement(parent, "origin", xyz=xyz, rpy=rpy)


def _joint(robot: ET.Element, name: str, parent: str, child: str, T: np.ndarray) -> None:
    joint = ET.SubElement(robot, "joint", name=name, type="fixed")
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    _origin(joint, T)


def ros_name(name: str) -> str:
    """``name`` as a ROS graph or frame name: each character other than ASCII letters, digits
    and ``_`` becomes ``_``, and ``cam_`` goes before a name not starting with a letter.

    >>> ros_name("front left"), ros_name("0")
    ('front_left', 'cam_0')
    """
    stem = "".join(ch if ch.isascii() and (ch.isalnum() or ch == "_") else "_" for ch in name)
    return stem if stem[:1].isalpha() else "cam_" + stem


def base_frame(rec: CalibrationRecord) -> str:
    """The frame every camera's X is expressed in, under the user's name (rig.yaml's
    ``pose:``, ``calibration.json``'s ``frames``): the fixed frame for eye-to-base, the
    tracked one for eye-on-hand."""
    role = BASE_FRAME[rec.setup]
    return role if rec.frames is None else rec.frames[role]


def base_pose(cam) -> np.ndarray:
    """The camera's pose in the base frame: its X, or without motion capture ``T_ref_cam``."""
    return cam.T_ref_cam if cam.X is None else cam.X


def frame_names(rec: CalibrationRecord, parent: str | None = None,
                child: str | None = None, *, cameras: bool = True
                ) -> tuple[str, dict[str, str]]:
    """The base frame and, per camera, the stem of its frames (see the module docstring).

    Camera names become frame names through :func:`ros_name` (``front left`` ->
    ``front_left``).

    Raises
    ------
    InputError
        An empty name or one with white space, a ``child`` without ``{camera}`` for several
        cameras, or (``cameras``: the camera frames checked too) two cameras, or a camera
        and the base, given the same frame.
    """
    parent = base_frame(rec) if parent is None else parent
    child = "{camera}" if child is None else child
    for what, name in (("--parent-frame", parent), ("--child-frame", child)):
        if not name or any(c.isspace() for c in name) or name.startswith("/"):
            raise InputError(f"{what} {name!r}: a frame name must be non-empty, without white "
                             "space and without a leading '/' (tf2)")
    if "{camera}" not in child and len(rec.cameras) > 1:
        raise InputError(f"--child-frame {child!r} must contain {{camera}} (the camera's name): "
                         f"the rig has {len(rec.cameras)} cameras")
    stems = {c.name: child.replace("{camera}", ros_name(c.name)) for c in rec.cameras}
    if not cameras:
        return parent, stems
    seen: dict[str, str] = {}
    for name, stem in stems.items():
        for frame in (f"{stem}_link", f"{stem}_optical_frame"):
            if frame == parent:
                raise InputError(f"camera {name!r} and the base are both the frame {frame}; "
                                 "give another --parent-frame")
            if frame in seen:
                raise InputError(
                    f"cameras {seen[frame]!r} and {name!r} are both the frame {frame} (a ROS "
                    "name holds ASCII letters, digits and _ only); rename one in rig.yaml and "
                    "calibrate again to export urdf or tf-static (the other formats name no "
                    "camera frames)")
            seen[frame] = name
    return parent, stems


def urdf_text(rec: CalibrationRecord, parent: str | None = None,
              child: str | None = None) -> str:
    """A URDF ``<robot>`` with the base link, and per camera ``<stem>_link`` (body-aligned:
    x forward, y left, z up) and ``<stem>_optical_frame`` (REP 103: z forward) joined by fixed
    joints (see the module docstring and :func:`frame_names`)."""
    base, stems = frame_names(rec, parent, child)
    robot = ET.Element("robot", name="multieye_cameras")
    robot.append(ET.Comment(
        f" multieye calibration ({rec.setup}, method {rec.method}, reference "
        f"{rec.reference_camera}). The cameras' poses in '{base}'; '<camera>_optical_frame' "
        "is the calibrated camera frame (x right, y down, z forward). Remove the base link "
        "when merging into a description that already has it. "))
    ET.SubElement(robot, "link", name=base)
    T_optical_link = g.inv(T_LINK_OPTICAL)
    for cam in rec.cameras:
        link, optical = f"{stems[cam.name]}_link", f"{stems[cam.name]}_optical_frame"
        ET.SubElement(robot, "link", name=link)
        ET.SubElement(robot, "link", name=optical)
        _joint(robot, f"{stems[cam.name]}_joint", base, link, base_pose(cam) @ T_optical_link)
        _joint(robot, f"{stems[cam.name]}_optical_joint", link, optical, T_LINK_OPTICAL)
    ET.indent(robot, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def tf_static_text(rec: CalibrationRecord, parent: str | None = None,
                   child: str | None = None) -> str:
    """One ROS 2 ``static_transform_publisher`` command per camera, base -> optical frame.

    Each line runs in the background (``&``) and the script waits, so that
    ``sh static_transforms.sh`` publishes every camera; each line also works on its own.
    Frame names as :func:`frame_names` gives them.
    """
    base, stems = frame_names(rec, parent, child)
    lines = ["#!/bin/sh",
             f"# multieye calibration ({rec.setup}, method {rec.method}): pose of each camera's "
             f"optical frame in '{base}'",
             "# (x right, y down, z forward); ROS 2 static_transform_publisher, metres."]
    for cam in rec.cameras:
        X = base_pose(cam)
        q = g.quat_from_transform(X)  # (qx, qy, qz, qw), qw >= 0
        args = [*_TF_COMMAND,
                "--x", _f(X[0, 3]), "--y", _f(X[1, 3]), "--z", _f(X[2, 3]),
                "--qx", _f(q[0]), "--qy", _f(q[1]), "--qz", _f(q[2]), "--qw", _f(q[3]),
                "--frame-id", base, "--child-frame-id", f"{stems[cam.name]}_optical_frame"]
        lines.append(" ".join(shlex.quote(a) for a in args) + " &")
    lines.append("wait")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- export


def _intrinsics(out: Path, rec: CalibrationRecord, *, required: bool) -> dict:
    path = out / "details.json"
    if not path.exists():
        if required:
            raise DatasetError("the intrinsics are in details.json, which this folder does not "
                               "have; rerun `multieye calibrate` to write it", path=path)
        return {}
    details = read_run_details(path)
    found = {c.name: c.intrinsics for c in details.cameras}
    missing = [c.name for c in rec.cameras if found.get(c.name) is None]
    if required and missing:
        raise DatasetError(f"no intrinsics for {', '.join(missing)} (cameras given by poses "
                           "without intrinsics); a Kalibr camchain needs them", path=path)
    return found


def _topic_name(camera: str) -> str:
    """``/<camera>/image_raw`` with characters a ROS name cannot hold replaced by ``_``."""
    return f"/{ros_name(camera)}/image_raw"


def kalibr_chain(rec: CalibrationRecord, intrinsics: dict, topics: dict,
                 overlaps: dict | None) -> tuple[list[CamchainEntry], list[str]]:
    """The camchain entries Kalibr can hold, and ``"<camera>, <camera> (<reason>)"`` for the
    others, one entry per reason (:func:`by_reason`).

    ``rostopic`` is the camera's topic in ``topics`` (rig.yaml), else ``/<camera>/image_raw``;
    ``cam_overlaps`` the chain indices of the cameras ``overlaps`` names (None: unknown, the
    key left out).
    """
    kept, left = [], []
    for c in rec.cameras:
        if intrinsics.get(c.name) is None:
            left.append((c.name, "no intrinsics"))
            continue
        try:
            kalibr_fields(intrinsics[c.name])
        except InputError as exc:
            left.append((c.name, str(exc)))
            continue
        refusal = kalibr_refusal(intrinsics[c.name])
        if refusal is not None:                     # a file Kalibr would not load
            left.append((c.name, refusal))
            continue
        kept.append(c)
    left = by_reason(left)
    index = {c.name: k for k, c in enumerate(kept)}
    entries = [CamchainEntry(
        c.name, intrinsics[c.name], c.T_ref_cam, topics.get(c.name) or _topic_name(c.name),
        None if overlaps is None or overlaps.get(c.name) is None else
        tuple(sorted(index[o] for o in overlaps[c.name] if o in index))) for c in kept]
    return entries, left


def by_reason(left: list[tuple[str, str]]) -> list[str]:
    """``"a, b (reason)"`` per reason of ``(camera, reason)`` pairs, in first-seen order: one
    note per cause, however many cameras share it (eight cameras whose lens Kalibr cannot
    hold make one line)."""
    groups: dict[str, list[str]] = {}
    for name, reason in left:
        groups.setdefault(reason, []).append(name)
    return [f"{', '.join(names)} ({reason})" for reason, names in groups.items()]


def _tracked_frame(out: Path) -> str | None:
    """``marker`` or ``body``: the tracked frame of the motion capture's ``pose:``
    (``T_world_<frame>``) as details.json records it; None without details.json."""
    path = out / "details.json"
    if not path.exists():
        return None
    poses = {t.pose for t in read_run_details(path).trajectories}
    frames = sorted(p.split("_", 2)[2] for p in poses if p.startswith("T_world_"))
    return frames[0] if len(frames) == 1 else None


def _per_camera_files(rec: CalibrationRecord, intr: dict, notes: list[str], *, stems_what: str,
                      suffix: str, note: str, refusal: str, text_of) -> dict[str, str]:
    """File name -> text of one file per camera a tool can describe, named ``<stem><suffix>``
    with the stems of :func:`multieye.core.names.file_stems` (``stems_what`` in its message);
    ``text_of(camera, intrinsics)`` gives the text or an InputError saying why not. The
    cameras left out go into ``notes`` after ``note``, one group per reason; none left raises
    InputError after ``refusal``."""
    stems = file_stems(rec.cameras, what=stems_what)
    texts, left = {}, []
    for cam in rec.cameras:
        try:
            if intr.get(cam.name) is None:
                raise InputError("no intrinsics")
            texts[stems[cam.name] + suffix] = text_of(cam, intr[cam.name])
        except InputError as exc:
            left.append((cam.name, str(exc)))
    left = by_reason(left)
    if left:
        notes.append(note + "; ".join(left))
    if not texts:
        raise InputError(refusal + "; ".join(left))
    return texts


def _camera_infos(rec: CalibrationRecord, intr: dict, notes: list[str],
                  overlaps: dict | None = None) -> dict[str, str]:
    """One ROS camera_info YAML per camera ROS can describe (:func:`_per_camera_files`), a
    camera of a stereo pair with its rectification (:mod:`multieye.outputs.stereo`); a note
    names the cameras whose lens the format names otherwise
    (:func:`~multieye.io.intrinsics_files.camera_info_note`)."""
    pairs, stereo_notes = stereo_pairs(rec, intr, overlaps)
    notes += stereo_notes
    rect, padded = per_camera(pairs), []

    def text_of(cam, k):
        text = camera_info_text(k, cam.name, rect.get(cam.name))
        if camera_info_note(k) is not None:         # a lens the format names otherwise
            padded.append(cam.name)
        return text

    texts = _per_camera_files(
        rec, intr, notes, stems_what="file export/camera_info/<camera>.yaml", suffix=".yaml",
        note="no camera_info for ", refusal="ROS camera_info cannot describe any camera: ",
        text_of=text_of)
    if padded:
        notes.append(f"camera_info of {', '.join(padded)}: "
                     + camera_info_note(intr[padded[0]]))
    return texts


def _overlaps(out: Path) -> dict | None:
    """details.json's ``overlaps`` per camera, when it has them for every camera."""
    if not (out / "details.json").exists():
        return None
    cams = read_run_details(out / "details.json").cameras
    return ({c.name: c.overlaps for c in cams} if all(c.overlaps is not None for c in cams)
            else None)


def _cameramodels(rec: CalibrationRecord, intr: dict, notes: list[str]) -> dict[str, str]:
    """One mrcal ``.cameramodel`` per camera mrcal can describe, ``rt_cam_ref`` from the
    reference camera's frame (:func:`_per_camera_files`)."""
    return _per_camera_files(
        rec, intr, notes, stems_what="export/mrcal/<camera>.cameramodel",
        suffix=".cameramodel", note="no .cameramodel for ",
        refusal="mrcal cannot describe any camera: ",
        text_of=lambda cam, k: cameramodel_text(
            k, g.inv(cam.T_ref_cam), note=f"{cam.name}: written by multieye export --format mrcal"))


def export(out_dir: str | os.PathLike, fmt: str, *,
           dest: str | os.PathLike | None = None,
           notes: list[str] | None = None, parent_frame: str | None = None,
           child_frame: str | None = None) -> list[Path]:
    """Write the calibration in ``out_dir`` in format ``fmt`` (see the module docstring).

    Parameters
    ----------
    out_dir : path-like
        Output folder of ``multieye calibrate`` (``calibration.json``, ``details.json``).
    fmt : str
        One of :data:`FORMATS`.
    dest : path-like, optional
        Folder to write into (created); default ``out_dir/export``.
    notes : list of str, optional
        Receives one line per camera a format cannot hold, with the reason.
    parent_frame, child_frame : str, optional
        Frame names of ``urdf``, ``tf-static`` and ``opencv`` (:func:`frame_names`); by
        default from the setup and the motion capture's ``pose:``.

    Returns
    -------
    list of Path
        The files written (atomically).

    Raises
    ------
    InputError
        Unknown format, or intrinsics that Kalibr's models cannot hold.
    DatasetError
        ``calibration.json`` missing or invalid; ``details.json`` missing for ``kalibr``;
        another multieye run holds ``out_dir`` (:func:`~multieye.outputs.folder.claim_output`).
    """
    if fmt not in FORMATS:
        raise InputError(f"unknown export format {fmt!r}; expected one of {', '.join(FORMATS)}")
    out = Path(out_dir)
    # Holding OUT as a calibration does (refused while one runs: its swap would remove these
    # files, issue 32); re-entrant, so a caller holding it already goes on.
    with claim_output(out, replace=False):
        rec = read_calibration(out / "calibration.json")
        folder = Path(dest) if dest is not None else out / "export"
        # Nothing written through a link below the folder the files belong in (docs/outputs.md).
        with confined_to(out if dest is None else folder):
            return _export(out, rec, fmt, folder, dest, [] if notes is None else notes,
                           parent_frame, child_frame)


def _export(out: Path, rec: CalibrationRecord, fmt: str, folder: Path, dest, notes: list[str],
            parent_frame: str | None, child_frame: str | None) -> list[Path]:
    """:func:`export` once the calibration is read, inside its confined folder: everything
    is read and checked before the folder is created and the first file written."""
    if parent_frame is None and rec.setup == "eye-on-hand" and rec.frames is None:
        parent_frame = _tracked_frame(out)      # calibration.json of an earlier version
    # checked before anything is written; camera frames only where a format names them
    frame_names(rec, parent_frame, child_frame, cameras=fmt in ("urdf", "tf-static"))
    path = folder / FORMATS[fmt]
    if fmt in ("camera-info", "mrcal"):
        intr = _intrinsics(out, rec, required=not (out / "details.json").exists())
        texts = (_camera_infos(rec, intr, notes, _overlaps(out)) if fmt == "camera-info"
                 else _cameramodels(rec, intr, notes))
        sub = FORMATS[fmt].split("/")[0]
        _export_folder(folder, dest)
        make_folder(folder / sub)
        return [write_text_atomic(folder / sub / name, text) for name, text in texts.items()]
    if fmt == "kalibr":
        intr = _intrinsics(out, rec, required=not (out / "details.json").exists())
        cams = read_run_details(out / "details.json").cameras
        kept, left = kalibr_chain(rec, intr, {c.name: c.topic for c in cams}, _overlaps(out))
        if not kept:
            raise InputError("Kalibr cannot hold any camera: " + "; ".join(left))
        _export_folder(folder, dest)
        write_camchain(path, kept, comments=[f"left out of this camchain: {c}" for c in left])
        if left:
            notes.append(f"camchain.yaml holds {', '.join(e.name for e in kept)} only; left "
                         "out: " + "; ".join(left))
        return [path]
    if fmt == "opencv":
        intr = _without_wide(_intrinsics(out, rec, required=False), notes)
        pairs, stereo_notes = stereo_pairs(rec, intr, _overlaps(out))
        notes += stereo_notes
        text = opencv_text(rec, intr, parent_frame) + "".join(
            line + "\n" for line in opencv_stereo_lines(pairs, _opencv_matrix))
    elif fmt == "urdf":
        text = urdf_text(rec, parent_frame, child_frame)
    elif fmt == "tf-static":
        text = tf_static_text(rec, parent_frame, child_frame)
    else:  # json
        text = json.dumps(calibration_to_dict(rec), separators=(",", ":"), allow_nan=False) + "\n"
    _export_folder(folder, dest)
    write_text_atomic(path, text)
    return [path]


def _without_wide(intr: dict, notes: list[str]) -> dict:
    """The lenses OpenCV FileStorage can describe; a wide-angle lens (unified, double-sphere,
    eucm: OpenCV has no such model) is left out with a note naming the camera, never written
    as a different lens."""
    wide = {n: k.model for n, k in intr.items() if k is not None and k.model in WIDE_MODELS}
    for name, model in wide.items():
        notes.append(f"extrinsics.yaml gives no lens for {name} (OpenCV has no {model} model; "
                     "calibration.json and camchain.yaml hold it)")
    return {n: (None if n in wide else k) for n, k in intr.items()}


def _export_folder(folder: Path, dest) -> None:
    """``OUT/export`` (never through a link), or the folder given as ``dest`` (created)."""
    if dest is None:
        make_folder(folder)
        return
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(f"cannot create the export folder: {exc.strerror}",
                           path=folder) from exc
