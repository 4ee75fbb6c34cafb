"""Where the gap to boofcv_fisheye's reference lens comes from (issue 33).

Run from the repository root::

    MULTIEYE_SHARED_DATA=../shared/data PYTHONPATH=src python benchmarks/bench_boofcv_reference.py \
        [--boofcv-jar PATH/PyBoof-all.jar] [--blur 1.0]

1. ``render``: the 24 views of ``boofcv_fisheye`` whose board multieye detects, posed under
   BoofCV's reference lens (``fisheye.yaml``, its principal point moved by -0.5 px into
   OpenCV's pixel convention, see 2.) and rendered (:func:`multieye.sim.render.render`, blur
   ``--blur`` px, noise 2 grey levels, no image circle) with that lens as the truth: the
   corners multieye detects against the true ones (mean, RMS about the mean, largest), the
   lens each model fits to them against the truth (RMS within 150 and 250 px of the centre
   after the best rotation, :func:`multieye.core.lens_compare.lens_difference_px`), and the
   same after every corner is refined again in a patch rectified through the fitted lens and
   pose (:func:`rectified_corners`: the Datta et al. 2009 remedy for corners biased by
   distortion, not part of multieye).
2. ``boofcv`` (with ``--boofcv-jar``, the BoofCV jar that the PyPI package PyBoof 0.43.1
   ships; needs ``javac``): BoofCV calibrates (``peers/BoofCalibrate.java``: unified model,
   two radial terms, no tangential) the real images and the rendered ones with its X-corner
   chessboard detector (``x``, its default since 0.32) and with its binary one (``b``, the one
   of 2017, when ``fisheye.yaml`` was written): its lens, the lens against ``fisheye.yaml``
   (real) or against the truth (rendered), its corners against multieye's (real) or the truth
   (rendered), and the lens multieye's ``unified`` fit (with p1 = p2 = 0 as BoofCV's)
   gives on BoofCV's own corners.
3. ``timing``: the cost of the saddle check (:func:`multieye.imaging.chessboard_corners.
   saddle_grid`) on the pinhole path: CPU ms per image of :func:`multieye.imaging.detect.
   detect` on 20 rendered 800 x 600 views of a 6 x 9 board through a pinhole lens with
   distortion, with the check and with it replaced by one that passes every grid (three
   alternating runs), and of the check alone.

This is a script, not a test: nothing is asserted.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before numpy is imported

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
from scipy.optimize import least_squares

from multieye.core.geometry import rotation_from_rotvec
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.core.lens_compare import lens_difference_px
from multieye.imaging.detect import detect
from multieye.imaging.generic_start import fit_lens, generic_start
from multieye.imaging.targets import Chessboard

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_wide_lens import BOOFCV_REFERENCE  # noqa: E402

BOARD = Chessboard(rows=6, cols=4, spacing=1.0)
#: BoofCV's pixel coordinates are OpenCV's plus this (measured in section 2 on rendered
#: images: both of BoofCV's detectors put the true corners 0.5 px right and down).
BOOFCV_PIXEL_OFFSET = 0.5


def shifted(lens: Intrinsics, by: float) -> Intrinsics:
    """The lens with its principal point moved by ``by`` px in x and y."""
    p = lens.params.copy()
    p[2:4] += by
    return lens.with_params(p)


REFERENCE = Intrinsics(**BOOFCV_REFERENCE)
TRUTH = shifted(REFERENCE, -BOOFCV_PIXEL_OFFSET)      # in OpenCV's pixel convention


def within(lens: Intrinsics, other: Intrinsics, uv: np.ndarray, radius: float) -> float:
    """RMS of :func:`lens_difference_px` over the pixels ``uv`` within ``radius`` px of the
    reference's principal point."""
    near = np.hypot(*(uv - REFERENCE.K[:2, 2]).T) <= radius
    return float(np.sqrt(np.nanmean(lens_difference_px(lens, other, uv[near]) ** 2)))


def pose_under(lens: Intrinsics, obj: np.ndarray, uv: np.ndarray, T0: np.ndarray) -> np.ndarray:
    """The board pose that fits ``uv`` best under a fixed lens, started at ``T0``."""
    def residual(x):
        P = obj @ (rotation_from_rotvec(x[:3]) @ T0[:3, :3]).T + T0[:3, 3] + x[3:]
        return np.nan_to_num(project_points(P, lens) - uv, nan=100.0).ravel()

    x = least_squares(residual, np.zeros(6)).x
    T = T0.copy()
    T[:3, :3] = rotation_from_rotvec(x[:3]) @ T0[:3, :3]
    T[:3, 3] = T0[:3, 3] + x[3:]
    return T


def fit(views, model: str = "unified", tangential: bool = True):
    """multieye's per-camera fit (generic start, then least squares without a robust loss);
    ``tangential=False``: the unified model with p1 = p2 = 0 held, as BoofCV fits it.
    Returns (lens, poses, reprojection RMS over the corners it projects)."""
    f = generic_start(views, (640, 720), model)
    f = fit_lens(views, f.intrinsics, f.T_cam_target, huber_px=None)
    lens, T = f.intrinsics, f.T_cam_target
    if not tangential:
        n = len(views)

        def residual(x):
            L = lens.with_params(np.r_[x[:7], 0.0, 0.0])
            out = []
            for (obj, uv), Ti, w in zip(views, T, x[7:].reshape(n, 6)):
                P = obj @ (rotation_from_rotvec(w[:3]) @ Ti[:3, :3]).T + Ti[:3, 3] + w[3:]
                out.append(np.nan_to_num(project_points(P, L) - uv, nan=100.0).ravel())
            return np.concatenate(out)

        x = least_squares(residual, np.r_[lens.params[:7], np.zeros(6 * n)], x_scale="jac").x
        lens = lens.with_params(np.r_[x[:7], 0.0, 0.0])
        return lens, T, float(np.sqrt(2 * np.mean(residual(x) ** 2)))
    rms = f.rms_px[np.isfinite(f.rms_px)]
    return lens, T, float(np.sqrt(np.mean(rms ** 2)))


def rectified_corners(gray, obj, T, lens, n: int = 41, half: float = 0.5) -> np.ndarray:
    """Every corner refined again in a patch rectified through the lens and pose: a square of
    the board of side ``2 half`` squares around the corner's board point is sampled on an
    ``n`` x ``n`` grid through the lens (``cv2.remap``, cubic), ``cv2.cornerSubPix`` finds the
    saddle there (straight edges, where the image's are bent), and the board point found is
    projected back.  Pixels, (N, 2); the old corner where the patch leaves the lens."""
    a = np.linspace(-half, half, n)
    A, B = np.meshgrid(a, a)
    out = []
    for X in obj:
        P = np.column_stack([X[0] + A.ravel(), X[1] + B.ravel(), np.zeros(A.size)])
        uv = project_points(P @ T[:3, :3].T + T[:3, 3], lens).reshape(n, n, 2)
        if not np.isfinite(uv).all():
            out.append(np.full(2, np.nan))
            continue
        uv = uv.astype(np.float32)
        patch = cv2.remap(gray, uv[..., 0], uv[..., 1], cv2.INTER_CUBIC,
                          borderMode=cv2.BORDER_REPLICATE)
        c = np.full((1, 1, 2), (n - 1) / 2, np.float32)
        w = int(0.35 * (n - 1) / (2 * half))
        cv2.cornerSubPix(patch, c, (w, w), (-1, -1),
                         (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4))
        d = (c.ravel() - (n - 1) / 2) * (2 * half) / (n - 1)
        Q = np.array([X[0] + d[0], X[1] + d[1], 0.0]) @ T[:3, :3].T + T[:3, 3]
        out.append(project_points(Q[None], lens)[0])
    return np.array(out)


def corner_errors(found: np.ndarray, true: np.ndarray) -> str:
    """Mean, RMS about the mean and largest departure about the mean, pixels."""
    e = found - true
    m = e.mean(axis=0)
    d = np.hypot(*(e - m).T)
    return f"mean ({m[0]:+.3f}, {m[1]:+.3f}), rms {np.sqrt(np.mean(d ** 2)):.3f}, max {d.max():.3f}"


def real_views(shared: Path) -> dict[int, tuple]:
    views = {}
    for k in range(1, 27):
        gray = cv2.imread(str(shared / "boofcv_fisheye" / f"{k}.jpg"), cv2.IMREAD_GRAYSCALE)
        det = detect(gray, BOARD)
        if det is not None:
            views[k] = (det.object_points, det.image_points)
    return views


def render_set(views: dict, out: Path, blur: float) -> dict[int, np.ndarray]:
    """The views posed under :data:`TRUTH` and rendered into ``out/k.png``; the true
    corners (canonical order of the detections), per image."""
    from multieye.sim.render import render  # noqa: PLC0415

    lens, T, _ = fit(list(views.values()))
    rng = np.random.default_rng(7)
    truth = {}
    for (k, (obj, uv)), T0 in zip(views.items(), T):
        Tk = pose_under(TRUTH, obj, uv, T0)
        cv2.imwrite(str(out / f"{k}.png"),
                    render(BOARD, TRUTH, Tk, rng=rng, blur_sigma=blur, noise_sigma=2.0))
        truth[k] = project_points(BOARD.object_points() @ Tk[:3, :3].T + Tk[:3, 3], TRUTH)
    return truth


def matched(found: np.ndarray, true: np.ndarray) -> np.ndarray:
    """For every found corner, the nearest true one (the board's half-turn symmetry leaves
    the order open)."""
    return true[np.linalg.norm(found[:, None] - true[None], axis=2).argmin(axis=1)]


def rendered(folder: Path, truth: dict) -> None:
    print(f"1. rendered: the reference lens as the truth, {len(truth)} views")
    views, grays = {}, {}
    for k in truth:
        grays[k] = cv2.imread(str(folder / f"{k}.png"), cv2.IMREAD_GRAYSCALE)
        det = detect(grays[k], BOARD)
        if det is not None:
            views[k] = (det.object_points, det.image_points)
    uv = np.concatenate([v[1] for v in views.values()])
    true = np.concatenate([matched(views[k][1], truth[k]) for k in views])
    print(f"   multieye detects {len(views)}; corners against the truth: {corner_errors(uv, true)}")
    for model in ("unified", "fisheye", "eucm", "double-sphere"):
        lens, T, rms = fit(list(views.values()), model)
        print(f"   {model:<14} reprojection {rms:.3f} px; lens vs truth within 150 / 250 px: "
              f"{within(lens, TRUTH, uv, 150):.3f} / {within(lens, TRUTH, uv, 250):.3f}")
        if model != "unified":
            continue
        again = []
        for (k, (obj, u)), Tk in zip(views.items(), T):
            r = rectified_corners(grays[k], obj, Tk, lens)
            again.append((obj, np.where(np.isfinite(r), r, u)))
        uv2 = np.concatenate([v[1] for v in again])
        lens2, _, rms2 = fit(again, model)
        print(f"   {model:<14} corners refined in rectified patches: {corner_errors(uv2, true)}; "
              f"reprojection {rms2:.3f} px; lens vs truth within 150 / 250 px: "
              f"{within(lens2, TRUTH, uv2, 150):.3f} / {within(lens2, TRUTH, uv2, 250):.3f}")


def run_boofcv(jar: Path, build: Path, folder: Path, ext: str, detector: str):
    """BoofCV's lens (moved into OpenCV's pixel convention) and its corners per image
    (layout points, pixels in OpenCV's convention)."""
    out = build / f"corners_{detector}.txt"
    done = subprocess.run(["java", "-cp", f"{jar}{os.pathsep}{build}", "BoofCalibrate",
                           str(folder), ext, detector, "26", str(out)],
                          capture_output=True, text=True, check=True)
    line = [s for s in done.stdout.splitlines() if s.startswith("lens ")][-1]
    fx, fy, cx, cy, xi, k1, k2, t1, t2 = map(float, line.split()[1:])
    lens = Intrinsics(K=[[fx, 0, cx - BOOFCV_PIXEL_OFFSET], [0, fy, cy - BOOFCV_PIXEL_OFFSET],
                         [0, 0, 1]], dist=[xi, k1, k2, t1, t2], model="unified", width=640,
                      height=720)
    rows = np.loadtxt(out, ndmin=2)
    corners = {}
    for k in np.unique(rows[:, 0]).astype(int):
        r = rows[rows[:, 0] == k]
        corners[k] = (np.column_stack([r[:, 2], r[:, 3], np.zeros(len(r))]),
                      r[:, 4:6] - BOOFCV_PIXEL_OFFSET)
    return lens, corners


def boofcv(jar: Path, shared: Path, ours: dict, folder: Path, truth: dict) -> None:
    print("\n2. BoofCV 0.43.1 (PyBoof's jar): unified, 2 radial, no tangential")
    build = Path(tempfile.mkdtemp())
    subprocess.run(["javac", "-d", str(build), "-cp", str(jar),
                    str(Path(__file__).parent / "peers" / "BoofCalibrate.java")], check=True)
    uv_ours = np.concatenate([v[1] for v in ours.values()])
    for label, where, ext in (("real", shared / "boofcv_fisheye", ".jpg"),
                              ("rendered", folder, ".png")):
        other, against = (TRUTH, "truth") if label == "rendered" else (TRUTH, "fisheye.yaml")
        for detector in ("x", "b"):
            lens, corners = run_boofcv(jar, build, where, ext, detector)
            uv = np.concatenate([v[1] for v in corners.values()])
            ref_uv = {k: truth[k] for k in corners if k in truth} if label == "rendered" \
                else {k: ours[k][1] for k in corners if k in ours}
            found = np.concatenate([corners[k][1] for k in ref_uv])
            near = np.concatenate([matched(corners[k][1], ref_uv[k]) for k in ref_uv])
            at = uv_ours if label == "real" else uv
            p = lens.params
            print(f"   {label:<8} {detector}: {len(corners)} images; fx {p[0]:.2f} "
                  f"xi {p[4]:.4f} k1 {p[5]:.4f} k2 {p[6]:.4f}; lens vs {against} within "
                  f"150 / 250 px: {within(lens, other, at, 150):.3f} / "
                  f"{within(lens, other, at, 250):.3f}")
            print(f"      its corners vs {'the truth' if label == 'rendered' else 'multieye'}"
                  f"'s (after -{BOOFCV_PIXEL_OFFSET} px): {corner_errors(found, near)}")
            mine, _, rms = fit(list(corners.values()), tangential=False)
            print(f"      multieye's unified fit (p1 = p2 = 0) on its corners (fx "
                  f"{mine.params[0]:.1f}, xi {mine.params[4]:.3f}): reprojection "
                  f"{rms:.3f} px (BoofCV's lens, poses refitted: "
                  f"{_posed_rms(lens, corners):.3f}); vs BoofCV's lens "
                  f"{within(mine, lens, uv, 250):.3f}, vs {against} "
                  f"{within(mine, other, uv, 250):.3f} within 250 px")
            if label == "real" and detector == "x":
                _ours_against(list(ours.values()), lens, uv_ours)


def _ours_against(views, lens: Intrinsics, uv: np.ndarray) -> None:
    """multieye's lens fitted to its own corners against BoofCV's, within 150 / 250 px."""
    n = 2 * len(uv)
    for model, tangential in (("unified", True), ("unified", False), ("fisheye", True),
                              ("eucm", True), ("double-sphere", True)):
        mine, _, rms = fit(views, model, tangential)
        name = model + ("" if tangential else " (p1 = p2 = 0)")
        print(f"      multieye's {name:<22} on its own corners (reprojection {rms:.4f} px, "
              f"{n} residuals) vs BoofCV's lens within 150 / 250 px: "
              f"{within(mine, lens, uv, 150):.3f} / {within(mine, lens, uv, 250):.3f}")


def _posed_rms(lens: Intrinsics, corners: dict) -> float:
    views = list(corners.values())
    _, T, _ = fit(views, tangential=False)
    e = [project_points(o @ Tk[:3, :3].T + Tk[:3, 3], lens) - u
         for (o, u), Tk in ((v, pose_under(lens, v[0], v[1], T0)) for v, T0 in zip(views, T))]
    return float(np.sqrt(np.mean(np.concatenate(e) ** 2) * 2))


def timing() -> None:
    import time  # noqa: PLC0415

    from multieye.core.geometry import transform_from_rotvec  # noqa: PLC0415
    from multieye.imaging import chessboard_corners as cc  # noqa: PLC0415
    from multieye.sim.render import render, visible  # noqa: PLC0415

    cam = Intrinsics(K=[[600, 0, 399.5], [0, 600, 299.5], [0, 0, 1]],
                     dist=[-0.28, 0.09, 0.0008, -0.0005, -0.015], width=800, height=600)
    board = Chessboard(rows=6, cols=9, spacing=0.04)
    images = []
    for k in range(20):
        T = transform_from_rotvec([0.2 * np.sin(k), 0.2 * np.cos(k), 0.05 * k],
                                  [-0.16 + 0.05 * np.cos(k), -0.1 + 0.04 * np.sin(k), 0.8])
        if visible(board, cam, T):
            images.append(render(board, cam, T, rng=np.random.default_rng(k)))
    check = cc.saddle_grid
    print(f"\n3. the saddle check on {len(images)} pinhole views (CPU ms per image)")
    try:
        for _ in range(3):
            for name, f in (("detect, without", lambda *a: True),
                            ("detect, with the check", check)):
                cc.saddle_grid = f
                t = time.process_time()
                found = sum(detect(im, board) is not None for im in images)
                print(f"   {name:<24} {1e3 * (time.process_time() - t) / len(images):.2f} "
                      f"({found} found)")
    finally:
        cc.saddle_grid = check
    corners = [cc.locate(im, board) for im in images]
    t = time.process_time()
    for _ in range(20):
        for im, c in zip(images, corners):
            check(im, c, board)
    print(f"   the check alone          {1e3 * (time.process_time() - t) / 20 / len(images):.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--boofcv-jar", type=Path, help="PyBoof 0.43.1's PyBoof-all.jar")
    ap.add_argument("--blur", type=float, default=1.0, help="rendering blur, px")
    ap.add_argument("--skip", default="", help="comma-separated: render, timing")
    args = ap.parse_args()
    shared = Path(os.environ.get("MULTIEYE_SHARED_DATA", "../shared/data"))
    if "timing" not in args.skip:
        timing()
    if "render" in args.skip:
        return
    ours = real_views(shared)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        truth = render_set(ours, folder, args.blur)
        rendered(folder, truth)
        if args.boofcv_jar is not None:
            boofcv(args.boofcv_jar, shared, ours, folder, truth)


if __name__ == "__main__":
    main()
