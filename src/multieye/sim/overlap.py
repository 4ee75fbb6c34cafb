"""A rig whose cameras see the target together: simulated views and a rendered dataset.

Cameras on an arc around a work volume, neighbours ``angle_deg`` apart, each looking at the
arc's centre; a board is shown at ``n_instants`` instants in poses around that centre, turned
so that at most instants several cameras see it at once (docs/rig-yaml.md, section 2: one
instant, one board pose).  Frames: ``ref`` is the first camera's; every camera's pose is
``T_ref_cam``, every instant's board pose ``T_ref_target``.

:func:`simulate_overlap` gives the geometry and which camera sees which instant;
:func:`pixel_views` the exact or noisy pixels of the target points (no images);
:func:`render_overlap_dataset` renders the images into a dataset folder with ``rig.yaml``
(without ``mocap:``, or with a motion-captured board when asked).

Synopsis
--------
>>> import numpy as np
>>> from multieye.sim.overlap import OverlapSpec, simulate_overlap
>>> sc = simulate_overlap(np.random.default_rng(0), OverlapSpec(n_instants=10))
>>> sc.T_ref_cam.shape, sc.seen.shape
((3, 4, 4), (10, 3))
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.imaging.targets import target_from_spec
from multieye.imaging.workers import worker_pool
from multieye.io import Trajectory, write_bytes_atomic, write_intrinsics_file, write_text_atomic
from multieye.io import write_tum
from multieye.sim.dataset import default_intrinsics
from multieye.sim.render import render, visible

__all__ = ["OverlapSpec", "OverlapScenario", "overlap_rig", "simulate_overlap", "pixel_views",
           "render_overlap_dataset"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class OverlapSpec:
    """What to simulate.

    Attributes
    ----------
    n_cameras : int
    angle_deg : float
        Angle between neighbouring optical axes.
    distance_m : float
        From each camera to the arc's centre (where the board is on average).
    n_instants : int
        Board poses (instants), each seen by at least one camera.
    width, height : int
        Image size, pixels.
    fisheye : tuple of int
        Cameras with an equidistant fisheye lens (the others radial-tangential).
    target : dict
        rig.yaml's ``target:``.
    max_obliquity_deg : float
        A camera sees the board only when its view ray to the board's centre is within this
        angle of the board's normal (what a detector manages).
    board_yaw_deg, board_tilt_deg, board_shift_m : float
        Half-ranges of the board's turn about the vertical and horizontal axes and of its
        shift from the centre.
    frame_interval_s : float
        Time between instants.
    jitter_s : float
        Per-image trigger jitter (uniform, +- this), seconds.
    """

    n_cameras: int = 3
    angle_deg: float = 34.0
    distance_m: float = 1.2
    n_instants: int = 50
    width: int = 800
    height: int = 600
    fisheye: tuple[int, ...] = (2,)
    target: dict = field(default_factory=lambda: {"type": "chessboard", "rows": 6, "cols": 9,
                                                  "spacing": 0.05})
    max_obliquity_deg: float = 60.0
    board_yaw_deg: float = 40.0
    board_tilt_deg: float = 25.0
    board_shift_m: float = 0.15
    frame_interval_s: float = 0.25
    jitter_s: float = 0.001


@dataclass(frozen=True)
class OverlapScenario:
    """The true rig and board poses.

    Attributes
    ----------
    T_ref_cam : ndarray, shape (m, 4, 4)
    T_ref_target : ndarray, shape (K, 4, 4)
    seen : ndarray of bool, shape (K, m)
        Which camera sees the whole board at which instant.
    intrinsics : tuple of Intrinsics
    object_points : ndarray, shape (n, 3)
        The target's points (metres, target frame).
    """

    T_ref_cam: F64
    T_ref_target: F64
    seen: NDArray[np.bool_]
    intrinsics: tuple[Intrinsics, ...]
    object_points: F64


def _rot_y(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def overlap_rig(spec: OverlapSpec) -> tuple[F64, F64]:
    """``T_centre_cam`` of every camera (m, 4, 4) and ``T_ref_cam`` (m, 4, 4).

    The ``centre`` frame sits at the arc's centre, axes as the middle camera's (x right,
    y down, z away from the cameras).
    """
    m = spec.n_cameras
    out = np.empty((m, 4, 4))
    for j in range(m):
        a = np.radians(spec.angle_deg) * (j - (m - 1) / 2)
        R = _rot_y(a)
        out[j] = g.make_transform(R, -spec.distance_m * R[:, 2])
    return out, g.inv(out[0]) @ out


def _board_frame(target) -> F64:
    """T_centre_target of a board centred at the origin, facing the cameras."""
    x0, x1, y0, y1 = target.bounds()
    c = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    R = np.eye(3) if target.z_into_board else np.diag([1.0, -1.0, -1.0])
    return g.make_transform(R, -R @ c)


def _sees(target, intr: Intrinsics, T_cam_target: F64, max_obliquity: float, w, h) -> bool:
    if not visible(target, intr, T_cam_target, width=w, height=h, border_px=8):
        return False
    x0, x1, y0, y1 = target.bounds()
    centre = T_cam_target[:3, :3] @ [(x0 + x1) / 2, (y0 + y1) / 2, 0.0] + T_cam_target[:3, 3]
    normal = T_cam_target[:3, 2]
    cos = abs(normal @ centre) / np.linalg.norm(centre)
    return bool(cos >= np.cos(max_obliquity))


def simulate_overlap(rng: np.random.Generator, spec: OverlapSpec = OverlapSpec(), *,
                     intrinsics: list[Intrinsics] | None = None) -> OverlapScenario:
    """Board poses, each seen by at least one camera (module docstring)."""
    target = target_from_spec(spec.target)
    intr = tuple(intrinsics or default_intrinsics(spec.n_cameras, spec.width, spec.height,
                                                  fisheye=spec.fisheye, rng=rng))
    T_centre_cam, T_ref_cam = overlap_rig(spec)
    T_cam_centre = g.inv(T_centre_cam)
    board = _board_frame(target)
    poses, seen = [], []
    for _ in range(200 * spec.n_instants):
        if len(poses) == spec.n_instants:
            break
        yaw, tilt, roll = np.radians(rng.uniform(-1, 1, 3) * [spec.board_yaw_deg,
                                                               spec.board_tilt_deg, 20.0])
        R = _rot_y(yaw) @ g.transform_from_rotvec([tilt, 0, 0], [0, 0, 0])[:3, :3] \
            @ g.transform_from_rotvec([0, 0, roll], [0, 0, 0])[:3, :3]
        shift = rng.uniform(-1, 1, 3) * spec.board_shift_m
        T_centre_target = g.make_transform(R, shift) @ board
        s = [_sees(target, intr[j], T_cam_centre[j] @ T_centre_target,
                   np.radians(spec.max_obliquity_deg), spec.width, spec.height)
             for j in range(spec.n_cameras)]
        if any(s):
            poses.append(T_centre_target)
            seen.append(s)
    T_ref_target = T_cam_centre[0] @ np.asarray(poses)
    return OverlapScenario(T_ref_cam=T_ref_cam, T_ref_target=T_ref_target,
                           seen=np.asarray(seen, dtype=bool), intrinsics=intr,
                           object_points=target.object_points())


def pixel_views(scenario: OverlapScenario, sigma_px: float = 0.0,
                rng: np.random.Generator | None = None) -> list[list[tuple]]:
    """Per camera, the ``(object_points, image_points, instant)`` of every instant it sees,
    with Gaussian pixel noise ``sigma_px`` per coordinate."""
    rng = rng or np.random.default_rng(0)
    out = []
    for j, intr in enumerate(scenario.intrinsics):
        T_cam_ref = g.inv(scenario.T_ref_cam[j])
        views = []
        for t in np.flatnonzero(scenario.seen[:, j]):
            T = T_cam_ref @ scenario.T_ref_target[t]
            uv = project_points(scenario.object_points @ T[:3, :3].T + T[:3, 3], intr)
            views.append((scenario.object_points, uv + sigma_px * rng.standard_normal(uv.shape),
                          int(t)))
        out.append(views)
    return out


def _render_one(args):
    target_spec, intr, T, seed, path = args
    img = render(target_from_spec(target_spec), intr, T, rng=np.random.default_rng(seed),
                 blur_sigma=0.7, noise_sigma=2.0)
    ok, buf = cv2.imencode(".png", img)
    if not ok:  # pragma: no cover - cv2 failure
        raise RuntimeError(f"could not encode {path}")
    write_bytes_atomic(path, buf.tobytes())


def render_overlap_dataset(out_dir: str | os.PathLike, spec: OverlapSpec = OverlapSpec(), *,
                           seed: int = 0, mocap: bool = False, models: bool = False,
                           processes: int = 1) -> OverlapScenario:
    """Render the images of :func:`simulate_overlap` into ``out_dir`` with a ``rig.yaml``.

    Images are ``camN/<stamp>.png`` (seconds, 6 decimals; each camera's stamp jittered by
    ``spec.jitter_s`` around the instant's), intrinsics ``camN.yaml`` (or, with ``models``,
    ``model:`` in rig.yaml: the lenses estimated), and ``ground_truth.json``
    (``{"T_ref_cam": {camera: 4x4}, "T_ref_target": [...]}``).  With ``mocap`` the board
    carries a marker body tracked in a ``world`` frame (``mocap.txt``, TUM ``T_world_marker``,
    one noise-free sample at each instant's stamp), eye-to-base.
    """
    rng = np.random.default_rng(seed)
    sc = simulate_overlap(rng, spec)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = [f"cam{j}" for j in range(spec.n_cameras)]
    t0 = 1_700_000_000.0
    stamps = t0 + spec.frame_interval_s * np.arange(len(sc.T_ref_target))
    jobs = []
    for j, name in enumerate(names):
        (out / name).mkdir(exist_ok=True)
        T_cam_ref = g.inv(sc.T_ref_cam[j])
        for t in np.flatnonzero(sc.seen[:, j]):
            stamp = stamps[t] + rng.uniform(-spec.jitter_s, spec.jitter_s)
            jobs.append((spec.target, sc.intrinsics[j], T_cam_ref @ sc.T_ref_target[t],
                         seed * 100003 + j * 1000 + int(t), out / name / f"{stamp:.6f}.png"))
    with worker_pool(processes) as pool:
        list(pool.map(_render_one, jobs))
    # setup names the motion capture's role: without motion capture there is none to name
    lines = ["# multieye overlapping rig (rendered by multieye.sim.overlap)"]
    lines += ["setup: eye-to-base"] if mocap else []
    lines += ["target:"]
    lines += [f"  {k}: {v}" for k, v in spec.target.items()]
    if mocap:
        T_world_ref = g.transform_from_rotvec([0, 0, 0.4], [0.5, -0.2, 1.0])
        T_marker_target = g.transform_from_rotvec([0.1, -0.2, 0.3], [0.05, 0.02, -0.03])
        T_world_marker = T_world_ref @ sc.T_ref_target @ g.inv(T_marker_target)
        write_tum(out / "mocap.txt", Trajectory(stamps, T_world_marker, parent="world",
                                                child="marker"))
        lines += ["mocap:", "  file: mocap.txt", "  pose: T_world_marker",
                  "  time_tolerance: 0.01"]
    lines.append("cameras:")
    for j, name in enumerate(names):
        if models:
            model = ("pinhole-radtan" if sc.intrinsics[j].model == "pinhole"
                     else sc.intrinsics[j].model)
            lines += [f"  {name}:", f"    model: {model}", f"    images: {name}/"]
        else:
            write_intrinsics_file(out / f"{name}.yaml", sc.intrinsics[j])
            lines += [f"  {name}:", f"    intrinsics: {name}.yaml", f"    images: {name}/"]
    write_text_atomic(out / "rig.yaml", "\n".join(lines) + "\n")
    truth = {"T_ref_cam": {n: sc.T_ref_cam[j].tolist() for j, n in enumerate(names)},
             "T_ref_target": sc.T_ref_target.tolist(), "stamps": stamps.tolist(),
             "seen": sc.seen.tolist(),
             "intrinsics": {n: {"K": sc.intrinsics[j].K.tolist(),
                                "dist": sc.intrinsics[j].dist.tolist(),
                                "model": sc.intrinsics[j].model}
                            for j, n in enumerate(names)}}
    write_text_atomic(out / "ground_truth.json", json.dumps(truth))
    return sc
