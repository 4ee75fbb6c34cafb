"""Pose streams and PnP evidence for the plausibility checks (test helper shared by the
plausibility tests): noise 0.1 deg / 1 mm on the target poses, 0.1 deg / 0.3 mm on the motion
capture; a 9 x 6 board's pixels through a pinhole camera."""

from __future__ import annotations

import numpy as np

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.estimate.pairing import pair_in_time
from multieye.estimate.plausibility import CameraEvidence
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import estimate_pose
from multieye.sim.images import simulate_stream

def _stream(seed, setup="eye-to-base", offset=0.0, duration=20.0):
    return simulate_stream(seed, setup=setup, duration_s=duration, camera_rate_hz=10.0,
                           mocap_rate_hz=100.0, time_offset_s=offset)


def _evidence(st, *, name="cam0", used_offset=None, mocap=None, T_cam_target=None,
              setup=None, **kw) -> CameraEvidence:
    """The camera paired with the motion capture at ``used_offset`` (default: the true one)."""
    offset = st.time_offset_s if used_offset is None else used_offset
    M = st.T_world_mocap if mocap is None else mocap
    p = pair_in_time(st.mocap_stamps, M, st.cam_stamps, tolerance=0.02, offset=offset)
    T_ct = (st.T_cam_target if T_cam_target is None else T_cam_target)[p.index]
    A = p.T if (setup or st.setup) == "eye-on-hand" else g.inv(p.T)
    extra = {k: (tuple(v[i] for i in p.index) if isinstance(v, list) else v[p.index])
             if k in ("object_points", "image_points", "rms_px") else v for k, v in kw.items()}
    return CameraEvidence(name, A, g.inv(T_ct), p.T, stamps=st.cam_stamps[p.index],
                          mocap_stamps=st.mocap_stamps, mocap_T=M, time_offset=offset, **extra)


def _scaled(T, k):
    out = T.copy()
    out[:, :3, 3] *= k
    return out


_K = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])


_TRUE = Intrinsics(K=_K, dist=np.zeros(4), width=640, height=480)


def _board():
    x, y = np.meshgrid(np.arange(9) * 0.05, np.arange(6) * 0.05)
    return np.stack([x.ravel() - 0.2, y.ravel() - 0.125, np.zeros(54)], axis=1)


def _with_intrinsics(st, obj, img, intr: Intrinsics) -> CameraEvidence:
    """The camera as PnP with ``intr`` sees it."""
    poses = [estimate_pose(Detection(np.arange(54), p, obj), intr) for p in img]
    T = np.stack([p.T_cam_target for p in poses])
    return _evidence(st, T_cam_target=T, intrinsics=intr, object_points=[obj] * len(img),
                     image_points=list(img), rms_px=np.array([p.rms_px for p in poses]))

