"""The dry run (multieye check): per camera what calibrating would find, and what would fail."""

from __future__ import annotations

import subprocess
import sys

import pytest
import yaml

import real_datasets
from multieye.core.errors import InputError
from multieye.io import list_images
from multieye.outputs.summary import check_table
from multieye.pipeline.dry_run import check_dataset
from pose_dataset import write_pose_dataset
from small_dataset import render_small


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    folder = tmp_path_factory.mktemp("check") / "ds"
    render_small(folder)
    return folder


def _copy(src, dst):
    import shutil

    shutil.copytree(src, dst)
    return dst


def test_small_rendered_dataset_is_ok(small):
    result = check_dataset(small, processes=1)
    assert result.ok and result.reasons == () and result.setup == "eye-to-base"
    assert [c.name for c in result.cameras] == ["cam0", "cam1"]
    for c in result.cameras:
        assert (c.source, c.listed, c.sampled, c.found, c.with_mocap, c.paired,
                c.expected_usable) == ("images", 8, 8, 8, 8, 8, 8)
        assert c.found_percent == 100.0 and c.failures == () and c.problems == ()
        assert c.rotation_range_deg > 30 and c.rotation_spread_deg[1] > 5
    text = check_table(result)
    assert "target found" in text and "rotation range deg" in text
    assert text.splitlines()[-1] == "verdict: ok, calibrating can run"


def test_sample_takes_evenly_spaced_images(small):
    result = check_dataset(small, sample=3, processes=1)
    c = result.cameras[0]
    assert (c.listed, c.sampled, c.found, c.paired, c.expected_usable) == (8, 3, 3, 3, 8)
    assert result.ok


def test_truncated_motion_capture_names_the_images_without_pose(small, tmp_path):
    folder = _copy(small, tmp_path / "ds")
    lines = (folder / "mocap.txt").read_text().splitlines()
    (folder / "mocap.txt").write_text("\n".join(lines[:40]) + "\n")
    result = check_dataset(folder, processes=1)
    assert not result.ok
    for c in result.cameras:
        assert c.with_mocap < 3 and c.found == 8
        assert any("of 8 images have no motion capture within 0.0167 s (nearest" in p
                   for p in c.problems)
    assert any("fewer than 3 usable images would remain" in r for r in result.reasons)


def test_wrong_target_size_finds_no_target(small, tmp_path):
    folder = _copy(small, tmp_path / "ds")
    rig = folder / "rig.yaml"
    rig.write_text(rig.read_text().replace("rows: 6", "rows: 7"))
    result = check_dataset(folder, processes=1)
    assert not result.ok
    for c in result.cameras:
        assert c.found == 0 and c.failures == (("target not detected", 8),)
        assert any(p.startswith("target found in only 0 of 8 sampled images")
                   for p in c.problems)
        assert c.fatal and "fewer than 3 usable images" in c.fatal[0]
        # the images were searched: what to write in rig.yaml, in the chessboard's terms
        hint = next(p for p in c.problems if p.startswith("target found in only"))
        assert ("rows and cols count the inner corners" in hint
                and "write in rig.yaml target: {type: chessboard, rows: 6, cols: 9, "
                "spacing: 0.05}" in hint), hint


def test_camera_given_by_poses(tmp_path):
    folder, _, _ = write_pose_dataset(tmp_path)
    result = check_dataset(folder)
    assert result.ok
    for c in result.cameras:
        assert (c.source, c.listed, c.sampled, c.found, c.paired) == ("poses", 12, 12, 12, 12)


def test_bad_arguments_and_input(small, tmp_path):
    with pytest.raises(InputError, match="sample"):
        check_dataset(small, sample=0)
    from multieye.core.errors import DatasetError

    with pytest.raises(DatasetError):
        check_dataset(tmp_path / "nothing")


def test_rotation_about_one_axis_is_warned_not_fatal(shared_data, tmp_path):
    folder = real_datasets.young_mocap_cam(shared_data, tmp_path / "young")
    result = check_dataset(folder, sample=10)
    c = result.cameras[0]
    assert result.ok and (c.listed, c.sampled, c.found) == (30, 10, 10)
    assert any("rotation about one axis" in p for p in c.problems)


def test_rotation_about_one_axis_with_the_lens_estimated(shared_data, tmp_path):
    """No intrinsics: detection only, the pairing and the motion as with them."""
    folder = real_datasets.young_mocap_cam(shared_data, tmp_path / "young")
    text = (folder / "rig.yaml").read_text().replace("intrinsics: cam0.yaml",
                                                     "model: pinhole-radtan")
    (folder / "rig_model.yaml").write_text(text)
    result = check_dataset(folder / "rig_model.yaml", sample=5)
    c = result.cameras[0]
    assert result.ok and (c.sampled, c.found, c.paired) == (5, 5, 5)


def test_a_lens_to_estimate_from_too_few_views_is_said(small, tmp_path):
    """model: without intrinsics: the dry run counts the views the lens would be estimated
    from against what its model needs, as calibrate will warn, without failing the check."""
    folder = _copy(small, tmp_path / "ds")
    text = (folder / "rig.yaml").read_text()
    (folder / "rig.yaml").write_text(text.replace("intrinsics: cam0.yaml",
                                                  "model: pinhole-rational"))
    result = check_dataset(folder, processes=1)
    cam0, cam1 = result.cameras
    assert result.ok
    assert any(p.startswith("lens pinhole-rational estimated from about 8 views with the "
                            "target; 20 recommended") for p in cam0.problems), cam0.problems
    assert cam1.problems == ()          # its intrinsics are given
    # lens-only views count towards it
    extra = folder / "extra"
    extra.mkdir()
    for k, p in enumerate(sorted((folder / "cam1").iterdir()) * 2):
        (extra / f"{k:03d}{p.suffix}").write_bytes(p.read_bytes())
    (folder / "rig.yaml").write_text(text.replace(
        "intrinsics: cam0.yaml", "model: pinhole-rational\n    intrinsics_images: extra/"))
    result = check_dataset(folder, processes=1)
    assert not any(p.startswith("lens ") for p in result.cameras[0].problems)


def _among_unusable(folder, n: int):
    """``n`` images of the wrong size (8 x 8) added to cam0 at motion-capture stamps away
    from its rendered images: the rendered ones become a small minority."""
    import cv2
    import numpy as np

    mocap = np.loadtxt(folder / "mocap.txt", usecols=0)
    images = np.array([t for t, _, _ in list_images(folder / "cam0")])
    free = mocap[np.min(np.abs(mocap[:, None] - images[None]), axis=1) > 0.05]
    for t in free[np.linspace(0, len(free) - 1, n).round().astype(int)]:
        cv2.imwrite(str(folder / "cam0" / f"{t:.6f}.png"), np.full((8, 8), 128, np.uint8))
    return folder


def test_a_camera_whose_target_is_in_a_tiny_minority_is_sampled_on(small, tmp_path):
    """Issue 32: calibrate chooses again from the rest until its budget of usable images is
    met; the dry run's evenly spaced sample of such a camera (8 of about 500 images usable)
    held none with the target, and it said calibrating would fail (exit 2)."""
    folder = _among_unusable(_copy(small, tmp_path / "ds"), 500)
    listed = len(list_images(folder / "cam0"))
    result = check_dataset(folder, processes=1)
    assert result.ok, result.reasons
    c = result.cameras[0]
    assert c.listed == listed and 20 < c.sampled < listed and 3 <= c.found == c.paired <= 8
    assert c.failures == (("wrong resolution", c.sampled - c.found),)
    assert result.cameras[1].sampled == 8                   # nothing more where all were seen
    for _, _, path in list_images(folder / "cam0"):
        if path.stat().st_size > 1000:                       # the rendered ones: none left
            path.unlink()
    c = check_dataset(folder, sample=50, processes=1).cameras[0]     # budget 500: all fit
    assert (c.listed, c.sampled, c.found) == (listed - 8, listed - 8, 0)  # every one tried
    assert c.fatal and "fewer than 3 usable images would remain (0 of" in c.fatal[0]
    assert any(p.startswith(f"target found in only 0 of {listed - 8} sampled images;")
               for p in c.problems)                  # no budget note: none left unsearched


def test_a_camera_without_the_board_in_any_image_is_searched_within_its_budget(
        small, tmp_path, monkeypatch):
    """Sampling on stops at 10 x --sample images per camera: a camera none of whose many
    images shows the board is not decoded whole (counted decodes), and the problem line
    says in how many sampled images the board was not found and that the rest went unsearched."""
    import multieye.imaging.batch as batch

    folder = _among_unusable(_copy(small, tmp_path / "ds"), 300)
    for _, _, path in list_images(folder / "cam0"):
        if path.stat().st_size > 1000:                       # the rendered ones: none left
            path.unlink()
    decoded: list[str] = []
    read_region = batch.read_region            # what a worker decodes each image file with

    def counting(path, *args, **kwargs):
        decoded.append(str(path))
        return read_region(path, *args, **kwargs)

    monkeypatch.setattr(batch, "read_region", counting)
    result = check_dataset(folder, sample=4, processes=1)
    c = result.cameras[0]
    assert (c.listed, c.sampled, c.found) == (300, 40, 0)
    assert sum(f"{folder / 'cam0'}" in p for p in decoded) == 40        # not 300
    assert any(p.startswith("target found in only 0 of 40 sampled images (sampling stopped at "
                            "its budget of 40 images per camera, 10 x --sample: 260 of 300 "
                            "images not searched); check the target section") for p in c.problems)
    # the images not searched may hold the board (calibrate searches them all): undecided,
    # not "would fail" (before: exit 2 on a sample of 40 of 300)
    assert result.ok and not c.fatal
    assert c.undecided == ("fewer than 3 usable images among the 40 searched (0 usable); 260 of "
                           "its 300 images were not searched (the check's budget): calibrating "
                           "may fail, and searches them all (--sample 30 searches them here)",)
    assert result.doubts == (f"{c.name}: {c.undecided[0]}",)
    assert check_table(result).splitlines()[-1] == f"verdict: calibrating may fail: {c.name}: " \
        + c.undecided[0]


def test_a_board_of_other_corners_in_the_images_searched_decides_even_past_the_budget(
        small, tmp_path):
    """The budget leaves the verdict open only when the images not searched may hold the
    target: where those searched show a board of other corner counts than rig.yaml's, the
    target section is wrong whatever the rest hold, and calibrating would fail (exit 2)."""
    folder = _among_unusable(_copy(small, tmp_path / "ds"), 300)
    text = (folder / "rig.yaml").read_text()
    rig = yaml.safe_load(text)
    rows, cols = rig["target"]["rows"], rig["target"]["cols"]
    (folder / "rig.yaml").write_text(text.replace(f"rows: {rows}", f"rows: {rows + 1}")
                                     .replace(f"cols: {cols}", f"cols: {cols + 1}"))
    result = check_dataset(folder, processes=1)
    c = result.cameras[0]
    assert c.sampled < c.listed and c.found == 0            # the budget stopped the search
    assert not result.ok and not c.undecided
    assert "squares counted instead of inner corners" in " ".join(c.problems)
    assert c.fatal[0].startswith("fewer than 3 usable images would remain (0 of ")


def test_check_says_may_fail_and_exits_0_where_its_budget_missed_a_tiny_minority(
        small, tmp_path):
    """8 usable images among 500 of the wrong size, searched with a budget of 40 that the
    evenly spaced sample misses them in: `calibrate` searches every image and calibrates, so
    `check` must not say it would fail (exit 2); it says that it may, and why."""
    folder = _among_unusable(_copy(small, tmp_path / "ds"), 500)
    done = subprocess.run([sys.executable, "-m", "multieye", "check", str(folder), "--sample",
                           "4", "--processes", "1"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "verdict: calibrating may fail: cam0: fewer than 3 usable images among the 40 " \
        "searched" in done.stdout
    assert done.stderr.startswith("multieye: calibrating may fail: cam0: ")
    assert "would fail" not in done.stdout + done.stderr




def test_a_toolkits_config_json_beside_the_pose_files_is_no_problem(shared_data, tmp_path):
    """yizhong's folder as published: ``k.jpg`` + ``k.json`` and the toolkit's
    ``chessboard_config.json``, read with ``{stem}.json``: that file has no image, which costs
    calibrating nothing, so check names no problem for it; an image without its pose file
    still is one."""
    import shutil

    src = shared_data / "yizhong_toolkit" / "sample_data" / "eye_in_hand_test_data"
    ds = tmp_path / "ds"
    shutil.copytree(src, ds)
    (ds / "rig.yaml").write_text(
        "setup: eye-on-hand\ntarget: {type: chessboard, rows: 8, cols: 11, spacing: 0.02}\n"
        'mocap: {file: "{stem}.json", key: end2base, pose: T_base_tool0}\n'
        "cameras:\n  cam0: {model: pinhole-radtan, images: ./}\n")
    c = check_dataset(ds, sample=6).cameras[0]
    assert not any("chessboard_config" in p for p in c.problems), c.problems
    (ds / "8.json").unlink()
    c = check_dataset(ds, sample=6).cameras[0]
    assert any("1 images without a pose (first 8.jpg" in p for p in c.problems), c.problems
