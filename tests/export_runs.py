"""Calibration runs built in memory from known frames (test helper shared by the output tests)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from synthetic import eye_on_hand, eye_to_base

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.io import RejectedItem, Trajectory
from multieye.io.rig import Rig
from multieye.pipeline import CameraData, Observation, calibrate_rig

NAMES = ("cam0", "front left", "rear<&>\"q\"")


def make_run(tmp: Path, setup: str, *, names=NAMES, counts=(6, 7, 5), seed: int = 3,
             noise: float = 0.0, mocap_per_image: int = 1, warnings: tuple[str, ...] = ()):
    """A calibration run of known frames through the real pairing and solver.

    Every camera sees the target every 0.5 s (camera clock), one camera after the other;
    the motion capture samples the marker (or body) at those times and ``mocap_per_image - 1``
    more in between; one extra image per camera has no motion capture near it (rejected in
    pairing) and one "was not detected" (rejected before).  ``warnings`` are the first
    camera's (they end up in the record's warnings).

    Returns
    -------
    run : CalibrationRun
    truth : dict
        ``X`` (m, 4, 4), ``Y`` (4, 4), ``T_world_mocap`` list of (n_j, 4, 4) at the used images.
    """
    rng = np.random.default_rng(seed)
    make = eye_to_base if setup == "eye-to-base" else eye_on_hand
    A, B, X, Y = make(rng, list(counts), rot_noise=noise, trans_noise=noise / 10)
    stamps, poses, cameras, mocap_at_images = [], [], {}, []
    start = 100.0
    for j, name in enumerate(names):
        T_world_mocap = g.inv(A[j]) if setup == "eye-to-base" else A[j]
        t = start + 0.5 * np.arange(len(A[j]))
        start = t[-1] + 5.0   # the next camera's segment, well after this one's lonely image
        for _i, (ti, Ti) in enumerate(zip(t, T_world_mocap)):
            stamps.append(ti)
            poses.append(Ti)
            for k in range(1, mocap_per_image):  # filler samples between images
                stamps.append(ti + 0.5 * k / mocap_per_image)
                poses.append(Ti)
        mocap_at_images.append(T_world_mocap)
        obs = [Observation(name=f"{ti:.6f}.png", stamp=float(ti), T_cam_target=g.inv(Bi),
                           rms_px=0.1 + 0.01 * i)
               for i, (ti, Bi) in enumerate(zip(t, B[j]))]
        obs.append(Observation(name="lonely.png", stamp=float(t[-1] + 2.0),
                               T_cam_target=g.inv(B[j][0])))
        K = np.array([[500.0 + 10 * j, 0, 319.5], [0, 501.0 + 10 * j, 239.5], [0, 0, 1]])
        cameras[name] = (obs, Intrinsics(K, [-0.2, 0.05, 1e-4, -2e-4], "pinhole", 640, 480))
    order = np.argsort(stamps)
    mocap = Trajectory(np.asarray(stamps)[order], np.stack(poses)[order], "world",
                       "marker" if setup == "eye-to-base" else "body")
    data = {name: CameraData(name=name, intrinsics=intr, observations=tuple(obs),
                             rejected=(RejectedItem("blurred.png", "target not detected"),),
                             n_inputs=len(obs) + 1, mocap=mocap, time_offset=0.0,
                             time_tolerance=0.01, warnings=warnings if name == names[0] else ())
            for name, (obs, intr) in cameras.items()}
    rig = Rig(path=tmp / "rig.yaml", setup=setup, cameras={})
    run = calibrate_rig(rig, data)
    return run, {"X": X, "Y": Y, "A": A, "B": B, "T_world_mocap": mocap_at_images}

