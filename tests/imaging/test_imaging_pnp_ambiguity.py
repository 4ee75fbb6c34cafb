"""The two IPPE poses of a planar target (issue 20, item 5): a single marker keeps both when
the pixels cannot rule the second out, and says when they fit almost equally."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core.geometry import rotation_angle_between, transform_from_rotvec
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import PoseEstimate, ambiguity_warning, estimate_pose

K = np.array([[1000.0, 0, 640], [0, 1000, 480], [0, 0, 1]])
INTR = Intrinsics(K=K, dist=np.array([-0.1, 0.02, 0.0, 0.0]), width=1280, height=960)


def _detection(obj: np.ndarray, T: np.ndarray, rng, sigma_px: float) -> Detection:
    uv = project_points(obj @ T[:3, :3].T + T[:3, 3], INTR)
    uv = uv + rng.normal(scale=sigma_px, size=uv.shape)
    return Detection(ids=np.arange(len(obj)), image_points=uv, object_points=obj)


def _marker_pose(distance: float, tilt_deg: float, size: float) -> np.ndarray:
    T = transform_from_rotvec([np.radians(tilt_deg), 0.0, 0.0], [0, 0, distance])
    T[:3, 3] -= T[:3, :3] @ np.array([size / 2, size / 2, 0.0])     # centre on the axis
    return T


def _square(size: float) -> np.ndarray:
    return np.array([[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0]], dtype=float)


def test_small_far_marker_keeps_its_mirrored_pose():
    """50 mm at 2 m (25 px), tilted 25 deg, 0.3 px noise: both poses fit within the noise;
    one of them is the truth, the other its mirror (tilt about twice 25 deg away)."""
    rng = np.random.default_rng(5)
    obj, T = _square(0.05), _marker_pose(2.0, 25.0, 0.05)
    found_first_wrong = 0
    for _ in range(20):
        pose = estimate_pose(_detection(obj, T, rng, 0.3), INTR)
        assert pose.alternative is not None and pose.ambiguous
        errs = sorted([rotation_angle_between(pose.T_cam_target[:3, :3], T[:3, :3]),
                       rotation_angle_between(pose.alternative[:3, :3], T[:3, :3])])
        assert np.degrees(errs[0]) < 10 and np.degrees(errs[1]) > 30
        found_first_wrong += rotation_angle_between(pose.T_cam_target[:3, :3], T[:3, :3]) > 0.5
        assert pose.alternative_rms_px <= pose.rms_px + 1.0
    # at this size PnP's own choice is often the mirror: why the rig has to choose
    assert found_first_wrong >= 3


def test_near_large_marker_and_boards_have_one_pose():
    rng = np.random.default_rng(6)
    # 200 mm at 0.5 m (400 px), tilted 35 deg: the mirror is many pixels off
    pose = estimate_pose(_detection(_square(0.2), _marker_pose(0.5, 35.0, 0.2), rng, 0.2), INTR)
    assert pose.alternative is None and not pose.ambiguous
    # a 7 x 10 board of 30 mm squares at 1 m: the mirror is ruled out by its RMS ratio
    g = np.mgrid[0:7, 0:10].T.reshape(-1, 2) * 0.03
    obj = np.column_stack([g, np.zeros(len(g))])
    pose = estimate_pose(_detection(obj, _marker_pose(1.0, 30.0, 0.27), rng, 0.2), INTR)
    assert pose.alternative is None and pose.alternative_rms_px is None


def _pose(rms: float, alt: float | None) -> PoseEstimate:
    return PoseEstimate(np.eye(4), rms, rms, 4, None if alt is None else np.eye(4), alt)


@pytest.mark.parametrize("rms, alt, ambiguous", [
    (0.1, 0.15, True), (0.1, 0.39, True), (0.1, 0.45, False),   # within 0.3 px
    (1.0, 1.9, True), (1.0, 2.1, False),                         # within a factor 2
    (0.1, None, False)])
def test_ambiguous_when_the_two_fit_almost_equally(rms, alt, ambiguous):
    assert _pose(rms, alt).ambiguous is ambiguous


def test_warning_when_most_images_are_ambiguous():
    most = [_pose(0.1, 0.12)] * 6 + [_pose(0.1, 2.0)] * 4
    msg = ambiguity_warning("cam3", most)
    assert msg.startswith("cam3: in 6 of 10 images the target's two mirrored poses fit almost "
                          "equally")
    assert "bigger marker" in msg and "closer" in msg and "marker grid" in msg
    assert ambiguity_warning("cam3", [_pose(0.1, 0.12)] * 5 + [_pose(0.1, None)] * 5) is None
    assert ambiguity_warning("cam3", []) is None
