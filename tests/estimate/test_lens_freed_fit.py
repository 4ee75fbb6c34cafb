"""The radial refit of a given lens (estimate.lens_freed._radial_fit) on the shared
Levenberg-Marquardt engine (optimize.levenberg_marquardt.minimize), in place of its own
hand-written loop: the same k1, k2 and poses as that loop (kept here as the reference),
exact on noise-free pixels, its Jacobian against central differences, and the fit's own
poses and RMS equal to PnP with the fitted lens (which they replace)."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, project_with_jacobian
from multieye.estimate import lens_freed as lf
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import estimate_pose
from multieye.optimize.blocks import Blocks

_K = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])


def _former_radial_fit(P, img, which, T, intr, iterations=30):
    """The hand-written loop _radial_fit was before (main 5979767), as the reference."""
    n, at = len(T), 4 + lf._RADIAL_AT[intr.model]
    k, R, t = lf._radial(intr), T[:, :3, :3].copy(), T[:, :3, 3].copy()

    def evaluate(k, R, t, jacobian):
        RP = np.einsum("nij,nj->ni", R[which], P)
        lens = lf._with_radial(intr, k)
        if not jacobian:
            r = project_points(RP + t[which], lens) - img
            return float(np.sum(np.where(np.isfinite(r), r, 1e3) ** 2))
        uv, Jp, Ji = project_with_jacobian(RP + t[which], lens)
        r = uv - img
        ok = np.all(np.isfinite(r), axis=1) & np.all(np.isfinite(Jp), axis=(1, 2))
        Jpose = np.concatenate([-Jp @ lf._skew(RP), Jp], axis=2)[ok]
        return r[ok], Jpose, Ji[ok][:, :, at:at + 2], which[ok]

    cost, damping = evaluate(k, R, t, False), 1e-3
    for _ in range(iterations):
        r, Jpose, Jk, w = evaluate(k, R, t, True)
        Hpp, Hpk, gp = np.zeros((n, 6, 6)), np.zeros((n, 6, 2)), np.zeros((n, 6))
        np.add.at(Hpp, w, np.einsum("nai,naj->nij", Jpose, Jpose))
        np.add.at(Hpk, w, np.einsum("nai,naj->nij", Jpose, Jk))
        np.add.at(gp, w, np.einsum("nai,na->ni", Jpose, r))
        Hkk, gk = np.einsum("nai,naj->ij", Jk, Jk), np.einsum("nai,na->i", Jk, r)
        while damping < 1e8:
            Dpp = Hpp + damping * np.einsum("nii->ni", Hpp)[:, :, None] * np.eye(6)
            inv = np.linalg.inv(Dpp)
            S = Hkk + damping * np.diag(np.diag(Hkk)) - np.einsum(
                "nai,nab,nbj->ij", Hpk, inv, Hpk)
            dk = np.linalg.solve(S, -(gk - np.einsum("nai,nab,nb->i", Hpk, inv, gp)))
            dp = -np.einsum("nij,nj->ni", inv, gp + Hpk @ dk)
            k_new, R_new = k + dk, g.rotation_from_rotvec(dp[:, :3]) @ R
            t_new = t + dp[:, 3:]
            new = evaluate(k_new, R_new, t_new, False)
            if new < cost:
                break
            damping *= 5.0
        else:
            break
        done = cost - new <= 1e-12 * cost
        k, R, t, cost, damping = k_new, R_new, t_new, new, max(damping / 3.0, 1e-9)
        if done:
            break
    return k, g.make_transform(R, t)


def _problem(truth: Intrinsics, given: Intrinsics, seed: int, noise: float, views: int = 8,
             poses: list | None = None):
    """Board views by ``truth`` (``noise`` px), started from PnP with ``given``; the true
    poses appended to ``poses`` when given."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(9) * 0.05, np.arange(6) * 0.05)
    obj = np.stack([x.ravel() - 0.2, y.ravel() - 0.125, np.zeros(54)], axis=1)
    P, img, which, T = [], [], [], []
    for i in range(views):
        pose = g.transform_from_rotvec(rng.uniform(-0.4, 0.4, 3),
                                       [*rng.uniform(-0.15, 0.15, 2), rng.uniform(0.5, 0.9)])
        u = project_points(obj @ pose[:3, :3].T + pose[:3, 3], truth)
        u = u + rng.normal(scale=noise, size=u.shape)
        if poses is not None:
            poses.append(pose)
        T.append(estimate_pose(Detection(np.arange(54), u, obj), given).T_cam_target)
        P.append(obj)
        img.append(u)
        which.append(np.full(54, i))
    return np.concatenate(P), np.concatenate(img), np.concatenate(which), np.stack(T)


def _lens(dist, model="pinhole", K=_K) -> Intrinsics:
    return Intrinsics(K=K, dist=np.asarray(dist, dtype=float), model=model, width=640,
                      height=480)


_FISH_K = np.array([[230.0, 0.0, 319.5], [0.0, 230.0, 239.5], [0.0, 0.0, 1.0]])
_CASES = [
    (_lens([-0.17, 0.0087, 0, 0, 0]), _lens(np.zeros(5))),                     # left out
    (_lens([-0.4, 0.048, 0, 0, 0]), _lens([-0.1, 0.012, 0, 0, 0])),            # a quarter
    (_lens([-0.05, 0.0, 0.001, -0.0005, 0.0]), _lens([0, 0, 0.001, -0.0005, 0.0])),
    (_lens([0.05, -0.01, 0.002, -0.0005], "fisheye", _FISH_K),
     _lens(np.zeros(4), "fisheye", _FISH_K)),
]


@pytest.mark.parametrize("case", range(len(_CASES)))
@pytest.mark.parametrize("noise", [0.1, 0.5])
def test_the_engine_fit_equals_the_former_loop(case, noise):
    """k1, k2 within 1e-7 (absolute; their noise spread is about 1e-3) and poses within
    1e-7 rad / 1e-8 m of the hand-written loop's, on pinhole and fisheye lenses with the
    distortion left out or given as a quarter, at 0.1 and 0.5 px of noise."""
    truth, given = _CASES[case]
    P, img, which, T = _problem(truth, given, seed=case, noise=noise)
    k_old, T_old = _former_radial_fit(P, img, which, T, given)
    k_new, T_new, r = lf._radial_fit(P, img, which, T, given)
    assert np.allclose(k_new, k_old, rtol=0, atol=1e-7), (k_new, k_old)
    assert np.max(g.rotation_angle_between(T_old, T_new)) < 1e-7
    assert np.max(np.abs(T_new[:, :3, 3] - T_old[:, :3, 3])) < 1e-8
    assert r.shape == img.shape


@pytest.mark.parametrize("case", range(len(_CASES)))
def test_the_engine_fit_recovers_k1_k2_exactly_without_noise(case):
    """Noise-free pixels, the given lens the truth with k1 and k2 zero: k1, k2 to 1e-9."""
    truth = _CASES[case][0]
    dist = truth.dist.copy()
    dist[:2] = 0.0
    given = _lens(dist, truth.model, truth.K)
    P, img, which, T = _problem(truth, given, seed=10 + case, noise=0.0)
    k, T_fit, r = lf._radial_fit(P, img, which, T, given)
    assert np.allclose(k, truth.dist[:2], rtol=0, atol=1e-9), k
    assert np.abs(r).max() < 1e-8


@pytest.mark.parametrize("case", range(len(_CASES)))
def test_radial_pixels_jacobian_matches_central_differences(case):
    """The Jacobian of the residuals with respect to k (euclidean) and each view's pose
    (se3-left: R <- Exp(phi) R, t <- t + tau) against central differences."""
    truth, given = _CASES[case]
    P, img, which, T = _problem(truth, given, seed=20 + case, noise=0.1, views=3)
    grp = lf._RadialPixels(P, img, which, len(T), given)
    k = np.array([[-0.08, 0.004]])
    values = {"k": k, "T": T}
    _, (J_k, J_T) = grp.evaluate(values, True)
    h = 1e-6
    for j in range(2):
        d = np.zeros((1, 2))
        d[0, j] = h
        num = (grp.evaluate({"k": k + d, "T": T}, False)[0]
               - grp.evaluate({"k": k - d, "T": T}, False)[0]) / (2 * h)
        assert np.allclose(J_k[:, :, j], num, rtol=1e-5, atol=1e-4), j
    poses = Blocks("T", T, "se3-left")
    for j in range(6):
        d = np.zeros((len(T), 6))
        d[:, j] = h                     # each row touches one view: perturb all at once
        plus = grp.evaluate({"k": k, "T": poses.retract(d.ravel()).value}, False)[0]
        minus = grp.evaluate({"k": k, "T": poses.retract(-d.ravel()).value}, False)[0]
        num = (plus - minus) / (2 * h)
        assert np.allclose(J_T[:, :, j], num, rtol=1e-5, atol=1e-3), j


def test_the_fit_poses_and_rms_are_pnp_with_the_fitted_lens():
    """The poses and per-view RMS the lens check takes from the refit (instead of a second
    PnP with the fitted lens) equal PnP's with that lens: poses within 1e-6 rad / 1e-7 m,
    RMS within 1e-6 px."""
    truth, given = _CASES[0]
    P, img, which, T = _problem(truth, given, seed=3, noise=0.2)
    views = [(P[which == i], img[which == i]) for i in range(len(T))]
    freed, T_fit, rms = lf._free_distortion_with_poses(views, T, given)
    for (o, u), T_i, rms_i in zip(views, T_fit, rms):
        est = estimate_pose(Detection(np.arange(len(o)), u, o), freed)
        assert g.rotation_angle_between(est.T_cam_target, T_i) < 1e-6
        assert np.abs(est.T_cam_target[:3, 3] - T_i[:3, 3]).max() < 1e-7
        assert abs(est.rms_px - rms_i) < 1e-6


def test_the_radial_check_runs_no_second_pnp(monkeypatch):
    """A camera whose k1, k2 are refitted: the check takes the refitted lens's poses and RMS
    from the refit (before: PnP again on every view with the refitted lens, a third of the
    check's time on the 4 x 100 rig); the test's figures are those PnP gives."""
    from multieye.estimate.plausibility import CameraEvidence

    truth, given = _CASES[0]
    true = []
    P, img, which, T = _problem(truth, given, seed=4, noise=0.1, views=6, poses=true)
    views = [(P[which == i], img[which == i]) for i in range(len(T))]
    rms = np.array([estimate_pose(Detection(np.arange(len(o)), u, o), given).rms_px
                    for o, u in views])
    M = g.transform_from_rotvec([0.0, 0.6, 0.0], [-0.67, 0.0, 0.2]) @ np.stack(true)
    cam = CameraEvidence("cam1", g.inv(M), g.inv(T), M, intrinsics=given,
                         object_points=tuple(o for o, _ in views),
                         image_points=tuple(u for _, u in views), rms_px=rms)
    expected = lf.free_distortion(views, T, given)
    pnp = lf._pnp_with_rms(cam, expected)
    calls = []
    monkeypatch.setattr(lf, "_pnp_with_rms", lambda *a: calls.append(a) or pnp)
    test = lf.lens_search(cam, (1e-3, 1e-3), radial_only=True)
    assert calls == []
    assert np.allclose(test.intrinsics.dist, expected.dist, rtol=0, atol=1e-9)
    assert abs(test.rms_freed_px - float(np.median(pnp[1]))) < 1e-6



def test_a_view_stuck_in_its_mirror_pose_is_taken_again_by_pnp():
    """A 140-degree fisheye given without its k1 -0.2: PnP with the given lens takes one of
    12 views 64 degrees off (a flat board's mirror pose), and the refit keeps it there (4 px
    against 0.2-0.4 px); with the refit's poses alone the pose residual gain fell from 57 to
    2.7.  That view is taken again by PnP with the refitted lens: the test equals the one
    with PnP on every view."""
    from multieye.estimate import hypotheses as h
    from multieye.estimate.plausibility import CameraEvidence
    from multieye.sim.wide_lens import board_views

    f = 480.0 / np.radians(70.0)
    K = np.array([[f, 0.0, 511.5], [0.0, f, 511.5], [0.0, 0.0, 1.0]])
    truth = Intrinsics(K=K, dist=np.array([-0.2, 0.012, 0, 0]), model="fisheye", width=1024,
                       height=1024)
    given = Intrinsics(K=K, dist=np.zeros(4), model="fisheye", width=1024, height=1024)
    rng = np.random.default_rng(107)
    views, T = board_views(truth, 140.0, 12, rng)
    est = [estimate_pose(Detection(np.arange(len(o)), u, o), given) for o, u in views]
    M = g.transform_from_rotvec([0.0, 0.6, 0.0], [-0.67, 0.0, 0.2]) @ T
    cam = CameraEvidence("cam1", g.inv(M), g.inv(np.stack([e.T_cam_target for e in est])), M,
                         intrinsics=given, object_points=tuple(o for o, _ in views),
                         image_points=tuple(u for _, u in views),
                         rms_px=np.array([e.rms_px for e in est]))
    freed, T_fit, rms = lf._free_distortion_with_poses(views, g.inv(cam.B), given)
    assert rms.max() > 10 * np.median(rms)                # the stuck view
    test = lf.lens_search(cam, h.MOCAP_NOISE, radial_only=True)
    pnp = lf._lens_test(cam, h.MOCAP_NOISE, (g.inv(cam.B), cam.rms_px), freed)
    assert test.rms_freed_px == pytest.approx(pnp.rms_freed_px, rel=1e-6)
    assert np.allclose(test.loop_freed, pnp.loop_freed, rtol=1e-5)
    assert test.loop_given[0] / test.loop_freed[0] > 20
