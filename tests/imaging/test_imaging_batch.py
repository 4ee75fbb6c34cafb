"""Detection and PnP over files in parallel processes: order, failures as reasons."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from batch_images import BOARD, CAMERA, check, render_image_files

from multieye.core.errors import InputError
from multieye.core.geometry import transform_from_rotvec
from multieye.imaging.batch import detect_and_estimate, detect_and_estimate_arrays, process_image
from multieye.sim.render import render
from multieye.imaging.targets import Chessboard
from multieye.core.intrinsics import Intrinsics


#: four rendered views, a corrupt file, a blank image and a missing path, with the truth
image_files = pytest.fixture(scope="module", name="image_files")(render_image_files)



def test_two_processes_keep_input_order_and_report_failures(image_files):
    results = detect_and_estimate(image_files[0], BOARD, CAMERA, processes=2, progress=False)
    check(results, image_files)
    serial = detect_and_estimate(image_files[0], BOARD, CAMERA, processes=1, progress=False)
    check(serial, image_files)
    for a, b in zip(results, serial):
        if a.ok:
            np.testing.assert_allclose(a.pose.T_cam_target, b.pose.T_cam_target, atol=1e-12)


def test_bad_fit_is_a_reason_and_keeps_the_pose(image_files):
    result = process_image(image_files[0][0], BOARD, CAMERA, max_rms_px=1e-4)
    assert not result.ok and result.reason.startswith("bad fit: reprojection RMS")
    assert result.pose is not None and result.pose.rms_px > 1e-4


def test_image_size_must_match_the_intrinsics(image_files):
    other = Intrinsics(K=CAMERA.K, dist=CAMERA.dist, width=1280, height=720)
    result = process_image(image_files[0][0], BOARD, other)
    assert result.reason == "wrong resolution (640 x 480, intrinsics say 1280 x 720)"


def test_wrong_board_size_is_not_found(image_files):
    result = process_image(image_files[0][0], Chessboard(rows=6, cols=7, spacing=0.04), CAMERA)
    assert result.reason == "target not detected (chessboard 6x7)"


def test_progress_bar_only_when_asked(image_files, capsys):
    detect_and_estimate(image_files[0][:1], BOARD, CAMERA, processes=1, progress=True)
    assert "detecting chessboard" in capsys.readouterr().err
    detect_and_estimate(image_files[0][:1], BOARD, CAMERA, processes=1)   # stderr is not a terminal
    assert capsys.readouterr().err == ""


def test_bad_process_count():
    with pytest.raises(InputError, match="processes must be a positive integer"):
        detect_and_estimate([], BOARD, CAMERA, processes=0)
    assert detect_and_estimate([], BOARD, CAMERA) == []


def test_arrays_in_batches_give_the_same_results_as_files_in_order(tmp_path):
    """detect_and_estimate_arrays (bag frames) = detect_and_estimate (files), in input order,
    with a batch smaller than the stream so that several batches go through the pool."""
    from multieye.imaging.batch import detect_and_estimate_arrays

    board = Chessboard(rows=6, cols=9, spacing=0.03)
    intr = Intrinsics(K=np.array([[500.0, 0, 319.5], [0, 500, 239.5], [0, 0, 1]]),
                      dist=np.array([-0.1, 0.02, 0, 0]), width=640, height=480)
    paths = []
    for k in range(7):
        T = transform_from_rotvec([0.2 * np.sin(k), 0.15 * np.cos(k), 0.1 * k],
                                  [-0.12 + 0.01 * k, -0.07, 0.6])
        img = render(board, intr, T, rng=np.random.default_rng(k)) if k != 3 else \
            np.full((480, 640), 200, np.uint8)           # one image without a board
        paths.append(tmp_path / f"{k}.png")
        cv2.imwrite(str(paths[-1]), img)
    files = detect_and_estimate(paths, board, intr, processes=2)
    arrays = detect_and_estimate_arrays(((p.name, cv2.imread(str(p), cv2.IMREAD_GRAYSCALE))
                                         for p in paths), board, intr, processes=2, batch=3)
    assert [r.path for r in arrays] == [p.name for p in paths]
    assert [r.ok for r in arrays] == [r.ok for r in files] == [True] * 3 + [False] + [True] * 3
    for a, f in zip(arrays, files):
        if a.ok:
            np.testing.assert_allclose(a.pose.T_cam_target, f.pose.T_cam_target, atol=1e-12)


@pytest.mark.parametrize("processes", [0, -1, 1.5, "2", True])
def test_processes_must_be_a_positive_integer(image_files, processes):
    with pytest.raises(InputError, match="processes must be a positive integer"):
        detect_and_estimate(image_files[0][:1], BOARD, CAMERA, processes=processes)
    with pytest.raises(InputError, match="processes must be a positive integer"):
        detect_and_estimate_arrays([], BOARD, CAMERA, processes=processes)


def test_ten_bits_in_a_sixteen_bit_png_keep_their_grey_levels(tmp_path):
    """A machine-vision camera's 10-bit image saved as a 16-bit PNG: OpenCV's 8-bit decoding
    kept its top 8 bits (4 grey levels), which doubled the corners' error on boofcv_stereo.
    Scaled by its brightest pixel, it is read as the 8-bit image is."""
    from multieye.imaging.image_file import read_gray

    T = transform_from_rotvec([0.3, -0.2, 0.1], [0.0, 0.0, 0.5])
    T[:3, 3] -= T[:3, :3] @ [0.14, 0.08, 0.0]
    image = render(BOARD, CAMERA, T, rng=np.random.default_rng(2))
    cv2.imwrite(str(tmp_path / "8.png"), image)
    cv2.imwrite(str(tmp_path / "10.png"), image.astype(np.uint16) * 4)
    eight, ten = read_gray(tmp_path / "8.png")[0], read_gray(tmp_path / "10.png")[0]
    assert ten.dtype == np.uint8 and len(np.unique(ten)) >= len(np.unique(eight))
    expected = np.rint(eight * (255.0 / eight.max()))
    assert np.abs(ten - expected).max() <= 1
    a, b = (process_image(tmp_path / n, BOARD, CAMERA) for n in ("8.png", "10.png"))
    assert a.ok and b.ok
    assert abs(a.pose.rms_px - b.pose.rms_px) < 0.02


def test_a_corrupt_image_is_its_reason_without_opencvs_own_lines(tmp_path):
    """A truncated PNG and JPEG decoded in this process (``--processes 1``, calibrate-many's
    workers) made OpenCV write '[ WARN:0@1.3] ... PNG input buffer is incomplete' and
    '[ERROR:0@11.4] imdecode_ ...' lines of its own beside multieye's reason, per image."""
    import subprocess
    import sys

    image = np.full((480, 640), 100, np.uint8)
    image[::7] = 0
    for ext in (".png", ".jpg"):
        data = cv2.imencode(ext, image)[1].tobytes()
        (tmp_path / f"cut{ext}").write_bytes(data[:len(data) // 3])
    code = ("import sys; from multieye.imaging.image_file import read_gray\n"
            "for p in sys.argv[1:]: print(read_gray(p)[1])")
    res = subprocess.run([sys.executable, "-c", code, str(tmp_path / "cut.png"),
                          str(tmp_path / "cut.jpg")], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and res.stderr == "", res.stderr
    assert res.stdout.count("unreadable file") == 2, res.stdout
