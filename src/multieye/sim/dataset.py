"""Render a realistic synthetic calibration dataset in the ``rig.yaml`` layout.

A rig of static, outward-facing cameras (eye-to-base, the paper's main case) is calibrated
with a board carried by a motion-captured marker body that is moved in front of one camera
after the other.  The board moves continuously (smooth sums of sines in position and
orientation); images are taken at the camera rate and the motion capture samples the marker
body at its own, unrelated rate and phase, with small noise.  Images carry lens distortion,
optical blur and sensor noise.  Everything a user would have is written to disk:

``rig.yaml``, ``camN.yaml`` (OpenCV FileStorage intrinsics), ``camN/<stamp>.png``,
``mocap.txt`` (TUM, ``T_world_marker``) and ``ground_truth.json`` (the calibration.json
schema, docs/outputs.md, section 2).

Synopsis
--------
>>> from multieye.sim.dataset import DatasetSpec, render_dataset
>>> truth = render_dataset("out/dataset", DatasetSpec(), seed=0)   # doctest: +SKIP
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from multieye.core import geometry as g
from multieye.core.intrinsics import WIDE_MODELS, Intrinsics
from multieye.core.errors import InputError
from multieye.core.lens import project_points
from multieye.io import (
    CalibrationRecord,
    CameraRecord,
    Residuals,
    Trajectory,
    write_bytes_atomic,
    write_calibration,
    write_intrinsics_file,
    write_text_atomic,
    write_tum,
)
from multieye.core.metrics import relative_extrinsics
from multieye.sim.rigs import surround_rig
from multieye.sim.render import render, visible
from multieye.sim.warped import render_warped
from multieye.imaging.targets import target_from_spec
from multieye.imaging.workers import worker_pool

__all__ = ["DatasetSpec", "GroundTruth", "render_dataset", "default_intrinsics"]


def default_intrinsics(n_cameras: int, width: int, height: int, *, fisheye: tuple[int, ...] = (),
                       rng: np.random.Generator | None = None) -> list[Intrinsics]:
    """Plausible intrinsics: ~75 deg horizontal field of view, radial-tangential distortion
    (k1 k2 p1 p2, which Kalibr's ``radtan`` can hold too) varying per camera; cameras listed
    in ``fisheye`` use the equidistant model with a wider field of view."""
    rng = rng or np.random.default_rng(0)
    out = []
    for j in range(n_cameras):
        if j in fisheye:
            f = width / 2.6
            K = np.array([[f, 0, width / 2 - 0.5 + rng.uniform(-8, 8)],
                          [0, f * rng.uniform(0.995, 1.005), height / 2 - 0.5 + rng.uniform(-8, 8)],
                          [0, 0, 1]])
            dist = np.array([0.05, -0.01, 0.002, -0.0005]) * rng.uniform(0.7, 1.3, 4)
            out.append(Intrinsics(K=K, dist=dist, model="fisheye", width=width, height=height))
        else:
            f = width / (2 * np.tan(np.radians(37.5))) * rng.uniform(0.95, 1.05)
            K = np.array([[f, 0, width / 2 - 0.5 + rng.uniform(-10, 10)],
                          [0, f * rng.uniform(0.995, 1.005), height / 2 - 0.5 + rng.uniform(-10, 10)],
                          [0, 0, 1]])
            dist = np.array([rng.uniform(-0.3, -0.15), rng.uniform(0.05, 0.12),
                             rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3)])
            out.append(Intrinsics(K=K, dist=dist, model="pinhole", width=width, height=height))
    return out


@dataclass(frozen=True)
class DatasetSpec:
    """What to render.

    Attributes
    ----------
    n_cameras : int
    images_per_camera : int
    width, height : int
        Image size, pixels.
    target : dict
        The ``target:`` mapping of rig.yaml.
    board_distance_m : float
        Mean distance of the board from a camera with a 75 degree field of view; cameras with
        shorter focal lengths see it proportionally closer.
    camera_rate_hz, mocap_rate_hz : float
        Image rate while the board is in front of a camera, and motion-capture rate.
    mocap_noise : (float, float)
        Motion-capture noise: rotation std (radians), translation std (metres).
    blur_sigma, noise_sigma : float
        Optical blur (pixels) and sensor noise (grey levels).
    fisheye : tuple of int
        Cameras rendered with the equidistant fisheye model.
    nanosecond_names : bool
        Image files named by integer nanoseconds (otherwise seconds with 6 decimals).
    start_time_s : float
        Clock value at the start (a realistic epoch by default).
    decoy_samples : int
        Extra motion-capture samples far (> 5 s) from any image, which pairing must ignore.
    processes : int or None
        Rendering processes (default: one per core).
    image_format : {"png", "jpg"}
        Image files written: PNG (lossless), or JPEG at quality 92 (a third of the bytes, for
        long recordings).
    renderer : {"rays", "warp"}
        How the images are made: ``"rays"`` traces every sub-pixel to the board
        (:func:`multieye.sim.render.render`); ``"warp"`` resamples a picture of the board
        through its homography and the lens, over a cluttered scene
        (:func:`multieye.sim.warped.render_warped`, chessboards only): another look, for
        benchmarks and tests that must not depend on one renderer.
    """

    n_cameras: int = 4
    images_per_camera: int = 40
    width: int = 800
    height: int = 600
    # 7 x 10 squares: one count odd, one even, so the board's 180-degree flip is resolvable
    target: dict = field(default_factory=lambda: {"type": "chessboard", "rows": 6, "cols": 9,
                                                  "spacing": 0.05})
    board_distance_m: float = 1.0
    camera_rate_hz: float = 4.0
    mocap_rate_hz: float = 120.0
    mocap_noise: tuple[float, float] = (np.radians(0.03), 0.0001)
    blur_sigma: float = 0.7
    noise_sigma: float = 2.0
    fisheye: tuple[int, ...] = ()
    nanosecond_names: bool = False
    start_time_s: float = 1_700_000_000.0
    decoy_samples: int = 0
    processes: int | None = None
    image_format: str = "png"
    renderer: str = "rays"

    def __post_init__(self) -> None:
        if self.renderer not in ("rays", "warp"):
            raise InputError(f"renderer must be 'rays' or 'warp', not {self.renderer!r}")


@dataclass(frozen=True)
class GroundTruth:
    """The true rig of a rendered dataset.

    Attributes
    ----------
    T_world_cam : ndarray, shape (m, 4, 4)
    T_marker_target : ndarray, shape (4, 4)
    T_ref_cam : ndarray, shape (m, 4, 4)
        Relative to the first camera.
    names : tuple of str
    intrinsics : tuple of Intrinsics
    images_written : tuple of int
        Per camera.
    """

    T_world_cam: np.ndarray
    T_marker_target: np.ndarray
    T_ref_cam: np.ndarray
    names: tuple[str, ...]
    intrinsics: tuple[Intrinsics, ...]
    images_written: tuple[int, ...]


def _motion(rng: np.random.Generator, center: np.ndarray, duration: float):
    """Smooth board motion around ``center`` (T_cam_target): returns pose(t) for t in [0, T]."""
    w_rot = rng.uniform(0.35, 0.9, 3) * 2 * np.pi / duration * 3
    w_tr = rng.uniform(0.35, 0.9, 3) * 2 * np.pi / duration * 3
    ph_rot, ph_tr = rng.uniform(0, 2 * np.pi, (2, 3))
    amp_rot = np.radians([28.0, 28.0, 15.0])
    amp_tr = np.array([0.10, 0.08, 0.15])

    def pose(t):
        t = np.atleast_1d(t)
        rv = amp_rot * np.sin(np.outer(t, w_rot) + ph_rot)
        tr = amp_tr * np.sin(np.outer(t, w_tr) + ph_tr)
        return center @ g.transform_from_rotvec(rv, tr)

    return pose


def _centered_board(target, distance: float) -> np.ndarray:
    """T_cam_target with the board centre on the optical axis, facing the camera."""
    x0, x1, y0, y1 = target.bounds()
    c = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    R = np.eye(3) if target.z_into_board else np.diag([1.0, -1.0, -1.0])
    return g.make_transform(R, np.array([0.0, 0.0, distance]) - R @ c)


def _axis_focal(intrinsics: Intrinsics) -> float:
    """Pixels per radian along x at the optical axis: ``fx`` for pinhole and fisheye lenses;
    for the wide models ``fx`` divided by their stretch there (unified: ``1 + xi``;
    double-sphere: ``alpha + (1 - alpha)(1 + xi)``; eucm: 1), measured by projection."""
    if intrinsics.model not in WIDE_MODELS:
        return float(intrinsics.K[0, 0])
    uv = project_points(np.array([[0.0, 0.0, 1.0], [1e-4, 0.0, 1.0]]), intrinsics)
    return float(uv[1, 0] - uv[0, 0]) / 1e-4


def _render_one(args):
    target_spec, intr, T, seed, blur, noise, path, renderer = args
    target = target_from_spec(target_spec)
    draw = render_warped if renderer == "warp" else render
    img = draw(target, intr, T, rng=np.random.default_rng(seed), blur_sigma=blur,
               noise_sigma=noise)
    params = [cv2.IMWRITE_JPEG_QUALITY, 92] if path.suffix == ".jpg" else []
    ok, buf = cv2.imencode(path.suffix, img, params)
    if not ok:  # pragma: no cover - cv2 failure
        raise RuntimeError(f"could not encode {path}")
    write_bytes_atomic(path, buf.tobytes())
    return path


def _stamp_name(t: float, ns: bool) -> str:
    return f"{int(round(t * 1e9))}" if ns else f"{t:.6f}"


def render_dataset(out_dir: str | os.PathLike, spec: DatasetSpec = DatasetSpec(), *,
                   seed: int = 0, intrinsics: list[Intrinsics] | None = None) -> GroundTruth:
    """Render a dataset into ``out_dir`` (created) and return its ground truth.

    Parameters
    ----------
    out_dir : path-like
    spec : DatasetSpec
    seed : int
    intrinsics : list of Intrinsics, optional
        One per camera; default :func:`default_intrinsics`.
    """
    rng = np.random.default_rng(seed)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    m = spec.n_cameras
    target = target_from_spec(spec.target)
    intr = intrinsics or default_intrinsics(m, spec.width, spec.height, fisheye=spec.fisheye,
                                            rng=rng)
    names = tuple(f"cam{j}" for j in range(m))
    # Rig: cameras on a vehicle body placed somewhere in the motion-capture world.
    T_body_cam = surround_rig(rng, m)
    T_world_body = g.transform_from_rotvec([0, 0, rng.uniform(-np.pi, np.pi)],
                                           [rng.uniform(-1, 1), rng.uniform(-1, 1), 0.6])
    T_world_cam = T_world_body @ T_body_cam
    T_marker_target = g.transform_from_rotvec(rng.normal(scale=0.3, size=3),
                                              rng.uniform(-0.15, 0.15, 3))
    T_target_marker = g.inv(T_marker_target)

    duration = spec.images_per_camera / spec.camera_rate_hz
    gap = 3.0                                   # walking from one camera to the next
    jobs, mocap_t, mocap_T, written = [], [], [], []
    t0 = spec.start_time_s
    for j, name in enumerate(names):
        (out / name).mkdir(exist_ok=True)
        # same apparent board size in every camera: closer to short focal lengths (fisheye)
        distance = max(0.4, spec.board_distance_m * _axis_focal(intr[j]) / (0.65 * spec.width))
        pose = _motion(rng, _centered_board(target, distance), duration)
        # images at the camera rate, with a little trigger jitter
        t_img = (np.arange(spec.images_per_camera) + 0.5) / spec.camera_rate_hz
        t_img = t_img + rng.uniform(-0.01, 0.01, t_img.size)
        T_ct = pose(t_img)
        n_ok = 0
        for k, (t, T) in enumerate(zip(t_img, T_ct)):
            if not visible(target, intr[j], T, border_px=8):
                continue
            path = out / name / f"{_stamp_name(t0 + t, spec.nanosecond_names)}.{spec.image_format}"
            jobs.append((spec.target, intr[j], T, seed * 100003 + j * 1000 + k, spec.blur_sigma,
                         spec.noise_sigma, path, spec.renderer))
            n_ok += 1
        written.append(n_ok)
        # motion capture of the marker body during this camera's segment, own rate and phase
        t_m = np.arange(-0.2, duration + 0.2, 1.0 / spec.mocap_rate_hz) + rng.uniform(0, 1 / spec.mocap_rate_hz)
        T_wm = T_world_cam[j] @ pose(t_m) @ T_target_marker
        mocap_t.append(t0 + t_m)
        mocap_T.append(T_wm)
        t0 += duration + gap
    T_all = np.concatenate(mocap_T)
    t_all = np.concatenate(mocap_t)
    rot_n, tr_n = spec.mocap_noise
    T_all = T_all @ g.transform_from_rotvec(rng.normal(scale=rot_n, size=(len(T_all), 3)),
                                            rng.normal(scale=tr_n, size=(len(T_all), 3)))
    if spec.decoy_samples:
        k = np.arange(spec.decoy_samples) / spec.mocap_rate_hz
        before = spec.start_time_s - 30.0 + k          # well before the first image
        after = t0 + 10.0 + k                          # well after the last one
        t_all = np.concatenate([before, t_all, after])
        decoys = g.random_transforms(rng, 2 * spec.decoy_samples)
        T_all = np.concatenate([decoys[:spec.decoy_samples], T_all, decoys[spec.decoy_samples:]])

    with worker_pool(spec.processes or os.cpu_count() or 1) as pool:
        list(pool.map(_render_one, jobs, chunksize=max(1, len(jobs) // (4 * (os.cpu_count() or 1)))))

    write_tum(out / "mocap.txt", Trajectory(t_all, T_all, parent="world", child="marker"))
    for j, name in enumerate(names):
        write_intrinsics_file(out / f"{name}.yaml", intr[j])
    rig_lines = ["# multieye synthetic dataset (rendered by multieye.sim.dataset)",
                 "setup: eye-to-base", "target:"]
    rig_lines += [f"  {k}: {v}" for k, v in spec.target.items()]
    rig_lines += ["mocap:", "  file: mocap.txt", "  pose: T_world_marker",
                  f"  time_tolerance: {2.0 / spec.mocap_rate_hz:.4f}",
                  f"  rotation_noise_deg: {np.degrees(spec.mocap_noise[0]):.6g}",
                  f"  translation_noise_m: {spec.mocap_noise[1]:.6g}", "cameras:"]
    for name in names:
        rig_lines += [f"  {name}:", f"    intrinsics: {name}.yaml", f"    images: {name}/"]
    write_text_atomic(out / "rig.yaml", "\n".join(rig_lines) + "\n")

    T_ref_cam = relative_extrinsics(T_world_cam)
    zero = Residuals(e_R_deg=0.0, e_t_m=0.0)
    record = CalibrationRecord(
        setup="eye-to-base", method="ground-truth", reference_camera=names[0], Y=T_marker_target,
        cameras=tuple(CameraRecord(name=n, X=T_world_cam[j], T_ref_cam=T_ref_cam[j],
                                   measurements_used=written[j], residuals=zero)
                      for j, n in enumerate(names)),
        residuals=zero)
    write_calibration(out / "ground_truth.json", record)
    return GroundTruth(T_world_cam=T_world_cam, T_marker_target=T_marker_target,
                       T_ref_cam=T_ref_cam, names=names, intrinsics=tuple(intr),
                       images_written=tuple(written))
