"""What each camera contributes, item by item: every image or row left out names itself (file,
line) and why, and the run goes on; arguments of calibrate that cannot be right are refused."""

from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest
from pose_dataset import write_pose_dataset

from multieye.core.errors import DatasetError, InputError, TooFewMeasurementsError
from multieye.pipeline import Options, calibrate, calibrate_rig, load_camera_data
from multieye.sim.dataset import DatasetSpec, render_dataset
from multieye.io import load_rig


def _edit_row(path, k, column, value):
    """Set ``column`` of the k-th data row (from 1) of a TUM file; returns its line."""
    lines = path.read_text().splitlines()
    data = [i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")]
    parts = lines[data[k - 1]].split()
    parts[column] = value
    lines[data[k - 1]] = " ".join(parts)
    path.write_text("\n".join(lines) + "\n")
    return data[k - 1] + 1


def test_bad_motion_capture_and_pose_rows_are_left_out_and_listed(tmp_path):
    ds = write_pose_dataset(tmp_path)[0]
    far = _edit_row(ds / "mocap.txt", 4, 1, "1e308")
    nan = _edit_row(ds / "mocap.txt", 20, 7, "nan")
    pose = _edit_row(ds / "cam1.txt", 6, 3, "nan")
    run = calibrate(ds, refine=False)
    rejected = {c.name: {r.item: r.reason for r in c.rejected} for c in run.record.cameras}
    mocap_rows = {
        f"mocap.txt line {far}": "motion-capture row left out: absurd position: tx = 1e+308 m, "
                                 "beyond 10000 m",
        f"mocap.txt line {nan}": "motion-capture row left out: not a finite number: qw = nan"}
    for name in ("cam0", "cam1"):
        assert mocap_rows.items() <= rejected[name].items()
    assert rejected["cam1"]["cam1.txt pose 6"] == f"line {pose}: not a finite number: tz = nan"
    # poses keep the number of their row in the file
    names = [o.name for o in run.paired["cam1"].observations]
    assert "cam1.txt pose 6" not in names and "cam1.txt pose 7" in names
    assert run.record.cameras[1].measurements_used <= 11


def test_images_left_out_each_say_why(tmp_path):
    spec = DatasetSpec(n_cameras=2, images_per_camera=7, width=320, height=240, processes=1)
    render_dataset(tmp_path / "ds", spec, seed=4)
    ds = tmp_path / "ds"
    cam0 = sorted((ds / "cam0").glob("*.png"))
    cam1 = sorted((ds / "cam1").glob("*.png"))
    cam0[1].write_bytes(cam0[1].read_bytes()[:200])                  # truncated
    cam0[2].write_bytes(b"")                                         # empty
    small = cv2.resize(cv2.imread(str(cam1[1])), (160, 120))
    cv2.imwrite(str(cam1[1]), small)                                 # wrong resolution
    cv2.imwrite(str(cam1[2]), np.full((240, 320), 128, np.uint8))    # no target
    late = cam1[3].with_name(f"{float(cam1[3].stem) + 100:.6f}.png")
    shutil.move(cam1[3], late)                                       # no motion capture
    run = calibrate(ds, processes=1, refine=False)
    reasons = {c.name: {r.item: r.reason for r in c.rejected} for c in run.record.cameras}
    assert reasons["cam0"] == {
        cam0[1].name: "unreadable file: the PNG stream is cut short (no IEND chunk)",
        cam0[2].name: "unreadable file: empty (0 bytes)"}
    assert reasons["cam1"][cam1[1].name] == "wrong resolution (160 x 120, intrinsics say 320 x 240)"
    assert reasons["cam1"][cam1[2].name] == "target not detected (chessboard 6x9)"
    assert reasons["cam1"][late.name].startswith(
        "no motion capture within 0.0167 s (after the motion-capture recording")
    assert run.record.cameras[0].measurements_used == 5
    assert run.record.cameras[1].measurements_used == 4

    # a camera without a single usable image: the reasons by kind, not "not detected"
    for p in cam1:
        if p.exists():
            p.write_bytes(b"")
    late.write_bytes(b"")
    with pytest.raises(DatasetError, match=r"camera cam1: none of the 7 images is usable: 7 "
                                           r"unreadable file \(first .*\.png: unreadable file: "
                                           r"empty \(0 bytes\)\)"):
        load_camera_data(load_rig(ds), processes=1)


def test_too_few_paired_images_names_them(tmp_path):
    ds = write_pose_dataset(tmp_path)[0]
    for k in range(3, 13):
        _edit_row(ds / "cam1.txt", k, 0, str(100.0 + k))
    with pytest.raises(TooFewMeasurementsError) as info:
        calibrate(ds)
    text = str(info.value)
    assert "camera cam1: only 2 of 12 images could be used" in text
    assert ("left out: cam1.txt pose 3 (no motion capture within 0.01 s (after the "
            "motion-capture recording") in text and "and 7 more" in text


@pytest.mark.parametrize("kw, message", [
    ({"max_time_offset": None}, "max_time_offset must be a positive number, got None"),
    ({"time_offset": "soon"}, "time_offset must be 'rig', 'auto' or a number of seconds"),
    ({"time_offset": float("nan")}, "time_offset must be a finite number, got nan"),
    ({"time_offset": 1e300}, "time_offset must be within 1e+10 s"),
    ({"method": None}, "method must be one of joint"),
    ({"reference": 0}, "reference must be a camera name, got 0"),
    ({"refine": "yes"}, "refine must be True or False"),
    ({"mocap_rot_sigma_rad": -1.0}, "mocap_rot_sigma_rad must be a positive number"),
])
def test_options_that_cannot_be_right(kw, message):
    with pytest.raises(InputError) as info:
        Options(**kw)
    assert message in str(info.value)


def test_calibrate_arguments(tmp_path):
    for bad in (None, 5, [tmp_path]):
        with pytest.raises(InputError, match=r"dataset \(a folder with rig.yaml, or the "
                                             r"rig.yaml\) must be a path"):
            calibrate(bad)
    ds = write_pose_dataset(tmp_path)[0]
    with pytest.raises(InputError, match="unknown option methd; the options are method, "):
        calibrate(ds, methd="shah")
    rig = load_rig(ds)
    with pytest.raises(InputError, match="options must be a multieye Options, got NoneType"):
        calibrate_rig(rig, load_camera_data(rig), None)


def test_every_camera_is_detected_on_one_pool(tmp_path, monkeypatch):
    """One worker pool for the whole rig (issue 21: a pool per camera left a core idle at the
    end of each camera), and the results are those of detecting camera by camera."""
    import multieye.imaging.batch as batch
    from small_dataset import render_small

    ds = tmp_path / "ds"
    render_small(ds, images_per_camera=6)
    rig = load_rig(ds / "rig.yaml")
    pools = []
    real = batch.worker_pool

    def counted(*args, **kwargs):
        pools.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(batch, "worker_pool", counted)
    together = load_camera_data(rig, processes=2)
    assert len(pools) == 1 and len(together) == 2
    alone = load_camera_data(rig, processes=1)         # this process, no pool
    assert len(pools) == 1
    for name, cam in together.items():
        other = alone[name]
        assert [o.name for o in cam.observations] == [o.name for o in other.observations]
        for a, b in zip(cam.observations, other.observations):
            assert np.array_equal(a.image_points, b.image_points)
            assert np.allclose(a.T_cam_target, b.T_cam_target)
        assert cam.detection_s > 0
