"""Motion capture of the rig in the motion-linked problem (issue 34, item 1: overlap, motion
and motion capture in one problem): Jacobians against central differences, the start of
its unknowns, exact recovery without noise."""

from __future__ import annotations

import numpy as np
import pytest
from wall_rig import wall_rig

from multieye.core import geometry as g
from multieye.estimate.motion_mocap import MocapPoseResiduals, RigMocap, mocap_families
from multieye.estimate.motion_residuals import MotionViews
from multieye.estimate.motion_links import MotionStart, Link
from multieye.estimate.refine_motion import refine_motion
from multieye.optimize.blocks import Blocks
from multieye.optimize.gradient_check import numerical_jacobians


def _mocap(s, rng, rot=0.0, trans=0.0, every=1):
    Ym, Xm = g.random_transforms(rng, 2)
    inst = np.arange(0, len(s.T_world_rig), every)
    M = Ym @ s.T_world_rig[inst] @ Xm
    M = M @ g.transform_from_rotvec(rng.normal(scale=rot or 1e-300, size=(len(M), 3)),
                                    np.zeros((len(M), 3)))
    M[:, :3, 3] += rng.normal(scale=trans or 1e-300, size=(len(M), 3))
    return RigMocap(inst, M, max(rot, 1e-4), max(trans, 1e-4)), Ym, Xm


def test_mocap_jacobians_match_central_differences():
    s = wall_rig(0, n_instants=10)
    rng = np.random.default_rng(1)
    mocap, Ym, Xm = _mocap(s, rng, 0.01, 0.01)
    S = g.inv(s.T_world_rig) @ g.transform_from_rotvec(rng.normal(scale=0.05, size=(10, 3)),
                                                        rng.normal(scale=0.05, size=(10, 3)))
    fams = [Blocks("S", S, "se3-left", eliminate=True), Blocks("Ym", Ym[None]),
            Blocks("Xm", (Xm @ g.transform_from_rotvec([0.1, 0, 0], [0, 0.1, 0]))[None])]
    grp = MocapPoseResiduals(mocap)
    analytic = grp.evaluate({f.name: f.value for f in fams}, True)[1]
    for a, n in zip(analytic, numerical_jacobians(fams, grp)):
        assert np.abs(a - n).max() < 1e-5 * max(1.0, float(np.abs(n).max()))


def test_the_start_of_the_mocap_unknowns_is_exact():
    s = wall_rig(2)
    mocap, Ym, Xm = _mocap(s, np.random.default_rng(3))
    f = {b.name: b.value[0] for b in mocap_families(mocap, s.T_world_rig)}
    assert np.abs(f["Ym"] - Ym).max() < 1e-9 and np.abs(f["Xm"] - Xm).max() < 1e-9


@pytest.mark.parametrize("start_off", [False, True])
def test_noise_free_pixels_and_mocap_give_the_rig_back_exactly(start_off):
    s = wall_rig(4)
    rng = np.random.default_rng(5)
    mocap, Ym, Xm = _mocap(s, rng)
    T = s.T_cam_board() @ g.transform_from_rotvec(rng.normal(scale=0.01, size=(len(s.camera), 3)),
                                                  rng.normal(scale=0.01, size=(len(s.camera), 3)))
    mv = MotionViews(s.views(), s.intrinsics)
    start = None
    if start_off:
        # camera 3 started 5 degrees and 5 cm off: the one problem pulls it in
        off = g.transform_from_rotvec([0.09, 0, 0], [0.05, 0, 0])
        start = MotionStart(np.concatenate([s.T_ref_cam[:3], s.T_ref_cam[3:] @ off]),
                            s.T_world_board, s.T_world_rig, (Link("reference"),) * 4)
    res = refine_motion(mv, T, pixel_sigma=0.5, loss="linear", mocap=mocap, start=start)
    assert np.abs(res.T_ref_cam - s.T_ref_cam).max() < 1e-8
    assert np.abs(res.T_world_board - s.T_world_board).max() < 1e-8
    assert np.abs(res.T_mocap_world - Ym).max() < 1e-8
    assert np.abs(res.T_rig_marker - Xm).max() < 1e-8
