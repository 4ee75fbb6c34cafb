"""Informative image selection (multieye.estimate.selection): budgets, reasons, instants kept
whole, and the result of a long uneven recording calibrated from the selected images against
all of them (within 2 sigma per camera) and against a fixed stride of the same count."""

from __future__ import annotations

import numpy as np
import pytest

import multieye
from multieye.core import geometry as g
from multieye.core.errors import InputError
from multieye.core.metrics import relative_extrinsics
from multieye.estimate.refine_images import refine_images
from multieye.estimate.selection import (
    KEPT,
    LEFT_OUT,
    grid_cells,
    hand_eye_jacobians,
    select_after_detection,
    select_before_decoding,
    select_images,
    stride_selection,
)
from multieye.estimate.uncertainty import relative_covariance
from multieye.sim.recordings import simulate_recording


def _poses(rng, n, *, rich=True):
    rot = rng.normal(scale=0.5 if rich else 0.02, size=(n, 3))
    return g.transform_from_rotvec(rot, rng.normal(scale=0.2, size=(n, 3)))


def test_budget_reasons_and_small_cameras(rng):
    T = {"a": _poses(rng, 400), "b": _poses(rng, 30)}
    stamps = {"a": np.arange(400.0), "b": 1000.0 + np.arange(30.0)}
    sel = select_images({n: hand_eye_jacobians(T[n]) for n in T}, stamps, 50)
    assert sel["a"].n_kept == 50 and sel["a"].n_seen == 400
    assert sel["b"].n_kept == 30            # at or under the budget: everything
    for n in T:
        for k, why in zip(sel[n].keep, sel[n].reasons):
            assert why.startswith(KEPT if k else LEFT_OUT)
    assert "no more than 50" in sel["b"].reasons[0]


def test_informative_images_are_chosen_over_dull_ones(rng):
    """Half the images barely move: the selection takes its images from the rich half."""
    T = np.concatenate([_poses(rng, 300, rich=False), _poses(rng, 300, rich=True)])
    sel = select_images({"a": hand_eye_jacobians(T)}, {"a": np.arange(600.0)}, 60)
    assert sel["a"].keep[300:].sum() >= 55


def test_instants_are_kept_or_left_out_whole(rng):
    """Cameras triggered together: an image is kept exactly when its instant's images are."""
    n = 200
    stamps = np.arange(n) * 0.05
    T = {c: _poses(rng, n) for c in ("a", "b", "c")}
    st = {"a": stamps, "b": stamps.copy(), "c": np.concatenate([stamps[:100], 100 + stamps[100:]])}
    sel = select_images({c: hand_eye_jacobians(T[c]) for c in T}, st, 40)
    np.testing.assert_array_equal(sel["a"].keep, sel["b"].keep)
    np.testing.assert_array_equal(sel["a"].keep[:100], sel["c"].keep[:100])
    kept_shared = np.flatnonzero(sel["a"].keep)
    assert any("instant shared with b, c" in sel["a"].reasons[i] for i in kept_shared)
    for c in T:                              # the budget holds but for instants kept whole
        assert 40 <= sel[c].n_kept <= 80


def test_before_decoding_leaves_out_images_without_motion_capture(rng):
    stamps = {"a": np.arange(500.0)}
    paired = {"a": np.arange(0, 500, 2)}     # every other image has a pose
    sel = select_before_decoding(stamps, paired, {"a": _poses(rng, 250)}, 100,
                                 unpaired_reason={"a": "no motion capture within 0.03 s"})
    assert sel["a"].n_kept == 100 and not sel["a"].keep[1::2].any()
    assert sel["a"].reasons[1] == "no motion capture within 0.03 s"


def test_after_detection_covers_the_image_first(rng):
    """With a lens to estimate, the images that alone reach a corner of the image are kept,
    even where the motion there adds little."""
    n = 400
    uv = [rng.uniform([300, 200], [340, 240], size=(20, 2)) for _ in range(n)]
    uv[7] = rng.uniform([0, 0], [40, 40], size=(20, 2))            # the only top-left view
    cells = grid_cells(uv, 640, 480)
    T = _poses(rng, n)
    T[7] = np.eye(4)
    sel = select_after_detection({"a": np.arange(n, dtype=float)}, {"a": T}, 30,
                                 cells={"a": cells})
    assert sel["a"].keep[7] and "covers a part of the image" in sel["a"].reasons[7]
    assert sel["a"].n_kept == 30


def test_bad_budget_is_refused(rng):
    with pytest.raises(InputError, match="budget"):
        select_images({"a": hand_eye_jacobians(_poses(rng, 10))}, {"a": np.arange(10.0)}, 0)


def test_stride_is_evenly_spaced():
    keep = stride_selection(1000, 100)
    assert keep.sum() == 100 and np.ptp(np.diff(np.flatnonzero(keep))) <= 1


def _refined(rec, keep):
    A, B = rec.AB(keep)
    sol = multieye.solve(A, B)
    res = refine_images(rec.setup, rec.observations(keep), rec.intrinsics, sol.X, sol.Y,
                        mocap_rot_sigma_rad=rec.mocap_rot_sigma_rad,
                        mocap_trans_sigma_m=rec.mocap_trans_sigma_m, pixel_sigma=rec.pixel_sigma)
    return res, relative_covariance(res.X, res.covariance)


def _distance(Ta, Tb):
    """Rotation (deg) and translation (m) between two sets of poses, per camera."""
    D = g.inv(Ta) @ Tb
    return (np.degrees(np.linalg.norm(g.rotvec_from_transform(D), axis=1)),
            np.linalg.norm(D[:, :3, 3], axis=1))


@pytest.mark.parametrize("seed", [0, 1])
def test_selected_images_give_the_all_images_result_and_beat_a_stride(seed):
    """A recording of 3 cameras x 900 images at 30 Hz, the board waved richly in a fifth of
    each camera's segment: 100 images per camera chosen before decoding (from the motion
    capture alone) give every T_ref_cam within 2 sigma (the selected run's own) of all 900,
    and a smaller predicted and actual error than every 9th image (the same count)."""
    rec = simulate_recording(seed, n_cameras=3, images=900)
    names = ["cam0", "cam1", "cam2"]
    sel = select_before_decoding({n: rec.stamps[j] for j, n in enumerate(names)},
                                 {n: np.arange(900) for n in names},
                                 {n: rec.T_world_mocap[j] for j, n in enumerate(names)}, 100)
    keep = [sel[n].keep for n in names]
    assert [int(k.sum()) for k in keep] == [100, 100, 100]
    stride = [stride_selection(900, 100) for _ in names]
    every, every_unc = _refined(rec, None)
    chosen, chosen_unc = _refined(rec, keep)
    strided, strided_unc = _refined(rec, stride)
    rot, trans = _distance(relative_extrinsics(every.X), relative_extrinsics(chosen.X))
    assert np.all(rot[1:] <= 2 * chosen_unc.std_rot_deg[1:])
    assert np.all(trans[1:] <= 2 * np.asarray(chosen_unc.std_trans_m[1:]))
    # predicted: the chosen images determine every camera better than the stride
    assert np.all(chosen_unc.std_rot_deg[1:] < 0.7 * strided_unc.std_rot_deg[1:])
    assert np.all(np.asarray(chosen_unc.std_trans_m[1:]) < 0.7 * np.asarray(strided_unc.std_trans_m[1:]))
    # actual: against the truth, squared errors summed over the cameras in units of the
    # all-images sigma (rotation and translation)
    def error(res):
        rot, trans = _distance(rec.T_ref_cam, relative_extrinsics(res.X))
        return float(np.sum((rot[1:] / every_unc.std_rot_deg[1:]) ** 2
                            + (trans[1:] / np.asarray(every_unc.std_trans_m[1:])) ** 2))

    assert error(chosen) < error(strided)
