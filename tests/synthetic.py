"""Minimal frame-chain generators for solver tests (no physical realism needed here).

``multieye.sim.rigs`` builds the paper's realistic rigs; these helpers only build
measurements that satisfy the loop of docs/conventions.md, section 2, exactly, from random frames.
"""

from __future__ import annotations


from multieye.core import geometry as g


def eye_to_base(rng, counts, *, rot_noise=0.0, trans_noise=0.0):
    """Eye-to-base rig: returns (A list, B list, X (m,4,4) = T_world_cam, Y = T_marker_target).

    A = inv(T_world_marker), B = inv(T_cam_target); noise is a right perturbation of B
    (rotation vector std in radians, translation std in metres).
    """
    m = len(counts)
    T_world_cam = g.random_transforms(rng, m, translation_scale=2.0)
    T_marker_target = g.random_transforms(rng, translation_scale=0.2)
    A, B = [], []
    for j, n in enumerate(counts):
        T_world_marker = g.random_transforms(rng, n, translation_scale=1.0)
        T_cam_target = g.inv(T_world_cam[j]) @ T_world_marker @ T_marker_target
        Bj = g.inv(T_cam_target)
        if rot_noise or trans_noise:
            Bj = Bj @ g.transform_from_rotvec(rng.normal(scale=rot_noise, size=(n, 3)),
                                              rng.normal(scale=trans_noise, size=(n, 3)))
        A.append(g.inv(T_world_marker))
        B.append(Bj)
    return A, B, T_world_cam, T_marker_target


def eye_on_hand(rng, counts, *, rot_noise=0.0, trans_noise=0.0):
    """Eye-on-hand rig: returns (A list, B list, X = T_body_cam, Y = T_world_target).

    A = T_world_body, B = inv(T_cam_target) = T_target_cam.
    """
    m = len(counts)
    T_body_cam = g.random_transforms(rng, m, translation_scale=0.5)
    T_world_target = g.random_transforms(rng, translation_scale=2.0)
    A, B = [], []
    for j, n in enumerate(counts):
        T_world_body = g.random_transforms(rng, n, translation_scale=1.0)
        T_cam_target = g.inv(T_body_cam[j]) @ g.inv(T_world_body) @ T_world_target
        Bj = g.inv(T_cam_target)
        if rot_noise or trans_noise:
            Bj = Bj @ g.transform_from_rotvec(rng.normal(scale=rot_noise, size=(n, 3)),
                                              rng.normal(scale=trans_noise, size=(n, 3)))
        A.append(T_world_body)
        B.append(Bj)
    return A, B, T_body_cam, T_world_target
