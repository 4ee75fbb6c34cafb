"""Consensus over measurements: corrupted measurements found, clean ones kept."""

from __future__ import annotations

import re

import numpy as np
import pytest

import multieye
from multieye.core import geometry as g
from multieye.core.errors import InputError, TooFewMeasurementsError
from multieye.sim.images import corrupt, simulate_images
from multieye.core.metrics import extrinsic_errors, relative_extrinsics
from multieye.estimate.refine_images import refine_images
from multieye.estimate.consensus import choose_poses, consensus, measurement_residuals

from synthetic import eye_to_base


def _rms_errors(X, X_true):
    rot, trans = extrinsic_errors(relative_extrinsics(X)[1:], relative_extrinsics(X_true)[1:])
    return np.sqrt(np.mean(rot ** 2)), np.sqrt(np.mean(trans ** 2))


@pytest.mark.parametrize("setup", ["eye-to-base", "eye-on-hand"])
def test_twenty_percent_corrupted_found_and_result_within_twice_clean(setup):
    clean = simulate_images(31, n_cameras=4, images=20, setup=setup)
    bad = corrupt(clean, 0.2, 32)
    assert [int(c.sum()) for c in bad.corrupted] == [4, 4, 4, 4]
    cons = consensus(bad.A, bad.B)
    for inl, corrupted in zip(cons.inliers, bad.corrupted):
        np.testing.assert_array_equal(~inl, corrupted)
    assert len(cons.rejected) == 16
    assert all(r.reason.startswith("outlier by consensus (loop residual ")
               and r.reason.endswith("above threshold 5 deg / 0.05 m)") for r in cons.rejected)
    assert consensus(clean.A, clean.B).rejected == ()

    # Refining on the inliers only: within 2x of refining the clean data.
    sol_clean = multieye.solve(clean.A, clean.B)
    ref_clean = refine_images(setup, clean.observations, clean.intrinsics, sol_clean.X,
                              sol_clean.Y, pixel_sigma=0.3)
    obs = [[o for o, k in zip(cam, inl) if k] for cam, inl in zip(bad.observations, cons.inliers)]
    ref = refine_images(setup, obs, bad.intrinsics, cons.X, cons.Y, pixel_sigma=0.3)
    e_clean, e_bad = _rms_errors(ref_clean.X, clean.X), _rms_errors(ref.X, clean.X)
    assert e_bad[0] < 2 * e_clean[0] and e_bad[1] < 2 * e_clean[1], (e_clean, e_bad)


def test_reason_names_the_residuals(rng):
    A, B, X, Y = eye_to_base(rng, [12, 12])
    B[1] = B[1].copy()
    B[1][7] = B[1][7] @ g.transform_from_rotvec([0.0, 0.0, np.radians(12.3)], [0.0, 0.0, 0.0])
    cons = consensus(A, B, names=["left", "right"])
    (r,) = cons.rejected
    assert (r.camera, r.index) == ("right", 7)
    rot, trans = measurement_residuals(A[1][7:8], B[1][7:8], X[1], Y)
    assert r.rot_deg == pytest.approx(12.3, abs=1e-6) == pytest.approx(float(rot[0]))
    assert r.trans_m == pytest.approx(float(trans[0]), abs=1e-9)
    assert r.reason == (f"outlier by consensus (loop residual 12.3 deg / {r.trans_m:.3f} m "
                        "above threshold 5 deg / 0.05 m)")
    # Exact data otherwise: the consensus solution is the exact one.
    np.testing.assert_allclose(cons.X, X, atol=1e-9)
    np.testing.assert_allclose(cons.Y, Y, atol=1e-9)


def test_camera_without_agreeing_measurements_is_named(rng):
    A, B, _, _ = eye_to_base(rng, [10, 10])
    B[1] = g.random_transforms(rng, 10)
    with pytest.raises(TooFewMeasurementsError, match=r"camera cam1: only \d of 10 measurements "
                       r"agree within 5 deg / 0.05 m"):
        consensus(A, B)
    # with labels the message names the measurements that disagree
    labels = [[f"{c}/{i}.png" for i in range(10)] for c in ("a", "b")]
    with pytest.raises(TooFewMeasurementsError, match=r"\(outliers: b/\d\.png, b/\d\.png, "
                       r".* and \d more\)") as info:
        consensus(A, B, labels=labels)
    assert "a/" not in str(info.value)


@pytest.mark.parametrize("kw, message", [
    ({"names": ["a"]}, "names has 1 entries but there are 2 cameras"),
    ({"names": "ab"}, "names must be a list of 2 strings"),
    ({"names": ["a", "a"]}, "names must be distinct"),
    ({"threshold_rot_deg": None}, "threshold_rot_deg must be a real number, got None"),
    ({"threshold_trans_m": "0.05"}, "threshold_trans_m must be a real number"),
    ({"threshold_trans_m": -1.0}, "threshold_trans_m must be a positive number"),
    ({"confidence": 1.0}, "confidence must be in (0, 1)"),
    ({"max_samples": 0}, "max_samples must be a positive integer, got 0"),
    ({"max_samples": 2.5}, "max_samples must be a positive integer"),
    ({"seed": "x"}, "seed must be an int, a numpy Generator or None"),
    ({"labels": [["x"], ["y"]]}, "labels must hold one name per measurement"),
])
def test_bad_arguments_are_input_errors(rng, kw, message):
    A, B, _, _ = eye_to_base(rng, [6, 6])
    with pytest.raises(InputError, match=re.escape(message)):
        consensus(A, B, **kw)


@pytest.mark.parametrize("A, B, message", [
    (None, None, "A is None"),
    ("AB", None, "B is missing"),
    ("AB", "AB", "A must be a list with one (N, 4, 4) array"),
])
def test_missing_or_wrong_measurements(A, B, message):
    with pytest.raises(InputError, match=re.escape(message)):
        consensus(A, B)


def test_complex_measurements_are_refused(rng):
    A, B, _, _ = eye_to_base(rng, [6, 6])
    with pytest.raises(InputError, match=r"A\[cam0\] must be real, got complex"):
        consensus([a + 0j for a in A], B)


def _mirrored(T_cam_target: np.ndarray) -> np.ndarray:
    """The target's pose with its normal reflected about the line of sight (the other IPPE
    pose of a small target), about the target origin."""
    R, t = T_cam_target[:3, :3], T_cam_target[:3, 3]
    n, v = R[:, 2], t / np.linalg.norm(t)
    if n @ v < 0:
        n = -n
    axis = np.cross(n, v)
    angle = 2 * np.arctan2(np.linalg.norm(axis), n @ v)
    flip = g.transform_from_rotvec(axis / np.linalg.norm(axis) * angle, [0, 0, 0])[:3, :3]
    return g.make_transform(flip @ R, t)


def _flipped_set(seed: int, share: float = 1 / 3):
    """Measurements of which ``share`` carry the mirrored pose, the other in B_alternative
    (flipped only where the mirror is more than 10 deg off, a gross error)."""
    scene = simulate_images(seed, n_cameras=3, images=18)
    rng = np.random.default_rng(seed)
    B, alt, flipped = [], [], []
    for b in scene.B:
        T = g.inv(b)
        mirror = g.inv(np.stack([_mirrored(t) for t in T]))
        off = np.degrees(g.rotation_angle_between(T[:, :3, :3], g.inv(mirror)[:, :3, :3]))
        f = (rng.random(len(b)) < share) & (off > 10)
        B.append(np.where(f[:, None, None], mirror, b))
        alt.append(np.where(f[:, None, None], b, mirror))
        flipped.append(f)
    return scene, B, alt, flipped


def test_mirrored_poses_chosen_per_image_by_the_rig():
    scene, B, alt, flipped = _flipped_set(41)
    assert sum(int(f.sum()) for f in flipped) >= 12
    # without the second poses the flipped images are outliers ...
    plain = consensus(scene.A, B)
    for inl, f in zip(plain.inliers, flipped):
        np.testing.assert_array_equal(~inl, f)
    # ... with them every image is kept, on its true pose
    cons = consensus(scene.A, B, B_alternative=alt)
    assert cons.rejected == ()
    for chosen, f in zip(cons.alternative, flipped):
        np.testing.assert_array_equal(chosen, f)
    clean = consensus(scene.A, scene.B)
    np.testing.assert_allclose(cons.X, clean.X, atol=1e-9)
    np.testing.assert_allclose(cons.Y, clean.Y, atol=1e-9)
    for r, rc in zip(cons.rot_deg, clean.rot_deg):
        np.testing.assert_allclose(r, rc, atol=1e-9)
    # and the choice for a given X, Y
    for j, (a, b, al, f) in enumerate(zip(scene.A, B, alt, flipped)):
        np.testing.assert_array_equal(choose_poses(a, b, al, clean.X[j], clean.Y), f)


def test_second_poses_missing_or_absent():
    scene, B, alt, flipped = _flipped_set(43)
    # no second pose (rows of NaN) where the first is right: the same choice
    partial = [np.where(f[:, None, None], a, np.nan) for a, f in zip(alt, flipped)]
    cons = consensus(scene.A, B, B_alternative=partial)
    assert cons.rejected == ()
    assert all(np.array_equal(c, f) for c, f in zip(cons.alternative, flipped))
    # all NaN: as without second poses
    none = consensus(scene.A, B, B_alternative=[np.full_like(b, np.nan) for b in B])
    plain = consensus(scene.A, B)
    assert [r.index for r in none.rejected] == [r.index for r in plain.rejected]
    assert not any(c.any() for c in none.alternative)


@pytest.mark.parametrize("bad, message", [
    (lambda alt: alt[:2], "one array per camera"),
    (lambda alt: [a[1:] for a in alt], "must have shape"),
    (lambda alt: [a * 2 for a in alt], "neither all NaN nor a rigid transform"),
    (lambda alt: "poses", "one array per camera"),
])
def test_bad_second_poses(bad, message):
    scene, B, alt, _ = _flipped_set(44)
    with pytest.raises(InputError, match=message):
        consensus(scene.A, B, B_alternative=bad(alt))
