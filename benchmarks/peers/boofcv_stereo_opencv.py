"""OpenCV's stereo calibration of BoofCV's stereo set, beside multieye's (docs/results/boofcv_stereo.md).

What a difference from BoofCV's ``stereo.yaml`` owes to the corners, the lens model and the
solver: OpenCV's ``calibrateCamera`` per camera, then ``stereoCalibrate`` refining both lenses
with the extrinsic (``CALIB_USE_INTRINSIC_GUESS``, k3 fixed), on

- OpenCV's corners (``findChessboardCorners`` + ``cornerSubPix`` 5 x 5; the right image's
  order reversed where the board's half-turn symmetry gave the other order), and
- multieye's corners (:func:`multieye.imaging.batch.detect_and_estimate`),

each with BoofCV's lens model (k1 k2, ``CALIB_ZERO_TANGENT_DIST``) and with k1 k2 p1 p2. Then
the stereo RMS at multieye's lenses (from the ``calibration.json`` of a run given with
``--calibration``; extrinsic and board poses re-solved by OpenCV), and OpenCV's joint
solution started from multieye's lenses: which of the two solutions is the least-squares one.

Run::

    multieye calibrate BOOFCV_STEREO -o out    # the published folder + docs/results/boofcv_stereo/rig.yaml
    python benchmarks/peers/boofcv_stereo_opencv.py --data ../shared/data/boofcv_stereo \\
        --calibration out/calibration.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from multieye.imaging import target_from_spec
from multieye.imaging.batch import detect_and_estimate

SIZE = (640, 480)
CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 500, 1e-15)
MODELS = {"k1 k2": cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3,
          "k1 k2 p1 p2": cv2.CALIB_FIX_K3}


def opencv_corners(data: Path):
    obj = np.zeros((24, 3), np.float32)
    obj[:, :2] = np.mgrid[0:4, 0:6].T.reshape(-1, 2) * 0.03
    left, right = [], []
    for k in range(1, 12):
        pts = []
        for side in ("left", "right"):
            g = cv2.imread(str(data / f"{side}{k:02d}.jpg"), cv2.IMREAD_GRAYSCALE)
            ok, c = cv2.findChessboardCorners(g, (4, 6))
            assert ok, (side, k)
            c = cv2.cornerSubPix(g, c, (5, 5), (-1, -1), (cv2.TERM_CRITERIA_EPS
                                                          + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4))
            pts.append(c.reshape(-1, 2))
        a, b = pts
        if np.dot(a[-1] - a[0], b[-1] - b[0]) < 0:    # the other order of a symmetric board
            b = b[::-1].copy()
        left.append(a.reshape(-1, 1, 2))
        right.append(b.reshape(-1, 1, 2))
    return [obj] * 11, left, right


def multieye_corners(data: Path):
    target = target_from_spec({"type": "chessboard", "rows": 6, "cols": 4, "spacing": 0.03})
    res = {s: detect_and_estimate([data / f"{s}{k:02d}.jpg" for k in range(1, 12)], target,
                                  None, processes=1, progress=False) for s in ("left", "right")}
    obj = [r.detection.object_points.astype(np.float32) for r in res["left"]]
    assert all(np.allclose(a, r.detection.object_points) for a, r in zip(obj, res["right"]))
    pts = {s: [r.detection.image_points.astype(np.float32).reshape(-1, 1, 2) for r in res[s]]
           for s in res}
    return obj, pts["left"], pts["right"]


def joint(obj, left, right, flags, start=None):
    """OpenCV's stereo calibration refining both lenses; ``start``: (K1, d1, K2, d2)."""
    if start is None:
        start = []
        for pts in (left, right):
            _, K, d, _, _ = cv2.calibrateCamera(obj, pts, SIZE, None, None, flags=flags)
            start += [K, d]
    rms, K1, d1, K2, d2, R, T, _, _ = cv2.stereoCalibrate(
        obj, left, right, *start, SIZE, flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS,
        criteria=CRITERIA)
    return rms, (K1, d1, K2, d2), R.T, -R.T @ T.ravel()     # T_left_right


def compare(R, t, R_ref, t_ref) -> dict:
    dr = np.degrees(Rotation.from_matrix(R @ R_ref.T).as_rotvec())
    dt = (t - t_ref) * 1000
    return {"rot_diff_deg": dr.round(3).tolist(), "angle_deg": round(float(np.linalg.norm(dr)), 3),
            "t_diff_mm": dt.round(3).tolist(), "distance_mm": round(float(np.linalg.norm(dt)), 3),
            "baseline_mm": round(float(np.linalg.norm(t) * 1000), 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--calibration", type=Path, required=True)
    args = ap.parse_args()
    ref = yaml.safe_load((args.data / "stereo.yaml").read_text())["rightToLeft"]
    R_ref = np.array(ref["rotation"], float).reshape(3, 3)
    t_ref = np.array([ref["x"], ref["y"], ref["z"]], float) / 1000
    out = {}
    corners = {"opencv": opencv_corners(args.data), "multieye": multieye_corners(args.data)}
    for cname, (obj, left, right) in corners.items():
        for mname, flags in MODELS.items():
            rms, lenses, R, t = joint(obj, left, right, flags)
            out[f"{cname} corners, {mname}"] = {
                "stereo_rms_px": round(float(rms), 5), "left_cx_cy": lenses[0][:2, 2].round(2).tolist(),
                **compare(R, t, R_ref, t_ref)}
    cams = json.loads(args.calibration.read_text())["cameras"]
    lens = [np.array(cams[s]["intrinsics"][k], float) for s in ("left", "right")
            for k in ("K", "distortion")]
    obj, left, right = corners["multieye"]
    rms = cv2.stereoCalibrate(obj, left, right, *lens, SIZE, flags=cv2.CALIB_FIX_INTRINSIC,
                              criteria=CRITERIA)[0]
    out["multieye corners, multieye's lenses held"] = {"stereo_rms_px": round(float(rms), 5)}
    rms, lenses, R, t = joint(obj, left, right, MODELS["k1 k2 p1 p2"], start=lens)
    out["multieye corners, k1 k2 p1 p2 started from multieye's lenses"] = {
        "stereo_rms_px": round(float(rms), 5), "left_cx_cy": lenses[0][:2, 2].round(2).tolist(),
        **compare(R, t, R_ref, t_ref)}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
