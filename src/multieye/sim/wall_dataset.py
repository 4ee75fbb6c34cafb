"""The wall-board rig (:mod:`multieye.sim.wall_boards`) rendered to a dataset folder.

Every camera takes an image at every instant (one rig pose), named by the instant's frame
number: ``camN/000012.png`` for instant 12 in every camera (a name that is its stamp too:
12 seconds, so the images of one instant share their stamp exactly).  The images show every
board in the camera's field of view (:func:`multieye.sim.render.render_boards`: lens
distortion, blur, sensor noise), also those too oblique or too cut to count as a view, and
none when the camera faces the empty wall.

Written beside them: ``rig.yaml`` with ``targets:`` (no ``mocap:``; or, with ``mocap``, the
rig's true body pose as ``mocap.txt``, TUM ``T_world_body``, eye-on-hand, for comparison),
``camN.yaml`` (OpenCV intrinsics) and ``ground_truth.json``::

    {"T_ref_cam": {camera: 4x4}, "T_world_board": {board: 4x4},
     "T_world_ref": [4x4 per instant], "T_body_ref": 4x4, "frames": [frame numbers],
     "views": {camera: {board: [instants seen]}}, "spec": {...}}

Synopsis
--------
>>> from multieye.sim.wall_boards import WallSpec
>>> from multieye.sim.wall_dataset import render_wall_dataset
>>> sc = render_wall_dataset("out/walls", WallSpec(n_instants=30), seed=0)   # doctest: +SKIP
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict
from pathlib import Path

import cv2
import numpy as np

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.imaging.targets import Target, target_from_spec
from multieye.imaging.workers import worker_pool
from multieye.io import Trajectory, write_bytes_atomic, write_opencv_intrinsics, write_text_atomic
from multieye.io import write_tum
from multieye.sim.render import board_outline, render_boards
from multieye.sim.wall_boards import WallScenario, WallSpec, simulate_walls

__all__ = ["render_wall_dataset", "wall_rig_yaml"]


def _in_view(target: Target, intr: Intrinsics, T: np.ndarray) -> bool:
    """Whether any of the board's outline is in front of the camera and in the image (so
    that only boards that show are traced)."""
    P = board_outline(target, per_edge=32) @ T[:3, :3].T + T[:3, 3]
    P = P[P[:, 2] > 0.05]
    if not len(P):
        return False
    uv = project_points(P, intr)
    with np.errstate(invalid="ignore"):
        inside = ((uv[:, 0] > -50) & (uv[:, 0] < intr.width + 50) & (uv[:, 1] > -50)
                  & (uv[:, 1] < intr.height + 50))
    return bool(inside.any())


def _render_one(args) -> None:
    specs, poses, intr, seed, path = args
    boards = [(target_from_spec(s), T) for s, T in zip(specs, poses)]
    img = render_boards(boards, intr, rng=np.random.default_rng(seed), blur_sigma=0.7,
                        noise_sigma=2.0)
    ok, buf = cv2.imencode(".png", img)
    if not ok:  # pragma: no cover - cv2 failure
        raise RuntimeError(f"could not encode {path}")
    write_bytes_atomic(path, buf.tobytes())


def _flow(mapping: dict) -> str:
    """A YAML flow mapping of plain values and lists of names."""
    def value(v):
        return f"[{', '.join(v)}]" if isinstance(v, list) else str(v)
    return "{" + ", ".join(f"{k}: {value(v)}" for k, v in mapping.items()) + "}"


def wall_rig_yaml(scenario: WallScenario, *, mocap: bool = False) -> str:
    """The dataset's rig.yaml: ``targets:`` named by wall, the cameras, and with ``mocap``
    the body's motion capture (eye-on-hand)."""
    lines = ["# multieye rig without motion capture before boards on the walls",
             "# (rendered by multieye.sim.wall_dataset)"]
    if mocap:
        lines += ["setup: eye-on-hand", "mocap: {file: mocap.txt, pose: T_world_body, "
                  "time_tolerance: 0.01}"]
    lines.append("targets:")
    lines += [f"  - {_flow({'name': name, **spec})}" for name, spec in scenario.targets.items()]
    lines.append("cameras:")
    lines += [f"  {c}: {{intrinsics: {c}.yaml, images: {c}/}}" for c in scenario.cameras]
    return "\n".join(lines) + "\n"


def render_wall_dataset(out_dir: str | os.PathLike, spec: WallSpec | None = None, *,
                        seed: int = 0, mocap: bool = False, processes: int = 1) -> WallScenario:
    """Render :func:`~multieye.sim.wall_boards.simulate_walls` into ``out_dir`` (module
    docstring); returns the scenario (the truth).

    Parameters
    ----------
    out_dir : path-like
        Created if missing; the files named in the module docstring are (over)written.
    spec : WallSpec, optional
        Default ``WallSpec()``.
    seed : int
        The scenario's and the images' random numbers.
    mocap : bool
        Also the rig's true body pose as motion capture (``mocap.txt``, eye-on-hand).
    processes : int
        Rendering processes.
    """
    spec = WallSpec() if spec is None else spec
    sc = simulate_walls(np.random.default_rng(seed), spec)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    specs = {n: {k: v for k, v in s.items() if k != "cameras"} for n, s in sc.targets.items()}
    boards = {n: target_from_spec(s) for n, s in specs.items()}
    jobs = []
    for j, cam in enumerate(sc.cameras):
        (out / cam).mkdir(exist_ok=True)
        write_opencv_intrinsics(out / f"{cam}.yaml", sc.intrinsics[j])
        for i in range(len(sc.T_world_body)):
            T_cam_world = g.inv(sc.T_world_ref[i] @ sc.T_ref_cam[j])
            shown = [(specs[n], T_cam_world @ sc.board_pose(n)) for n in specs
                     if _in_view(boards[n], sc.intrinsics[j], T_cam_world @ sc.board_pose(n))]
            jobs.append(([s for s, _ in shown], [T for _, T in shown], sc.intrinsics[j],
                         seed * 100003 + j * 1000 + i, out / cam / f"{i:06d}.png"))
    with worker_pool(processes) as pool:
        list(pool.map(_render_one, jobs))
    write_text_atomic(out / "rig.yaml", wall_rig_yaml(sc, mocap=mocap))
    frames = np.arange(len(sc.T_world_body), dtype=np.float64)
    if mocap:
        write_tum(out / "mocap.txt", Trajectory(frames, sc.T_world_body, parent="world",
                                                child="body"))
    views: dict = {c: {} for c in sc.cameras}
    for v in sc.views:
        views[sc.cameras[v.camera]].setdefault(v.target, []).append(v.instant)
    truth = {"T_ref_cam": {c: sc.T_ref_cam[j].tolist() for j, c in enumerate(sc.cameras)},
             "T_world_board": {n: sc.board_pose(n).tolist() for n in sc.targets},
             "T_world_ref": sc.T_world_ref.tolist(), "T_body_ref": sc.T_body_ref.tolist(),
             "frames": frames.astype(int).tolist(), "views": views, "spec": asdict(spec)}
    write_text_atomic(out / "ground_truth.json", json.dumps(truth))
    return sc
