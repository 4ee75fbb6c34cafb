"""OpenCV on an overlapping rig: per-camera calibration, then stereo pairs (issue 23, item 4).

Run::

    python benchmarks/peers/overlap_opencv.py CORNERS.npz --out result.json

``CORNERS.npz`` as for ``overlap_mrcal.py``, plus ``<name>_model`` (``pinhole-radtan`` or
``fisheye``).  What an OpenCV user writes:

1. per camera ``cv2.calibrateCamera`` (5 radial-tangential coefficients) or
   ``cv2.fisheye.calibrate`` (equidistant k1-k4) on its own corners;
2. per camera j > 0, the pair (camera 0, camera j) on their shared instants:
   ``cv2.stereoCalibrate`` with the lenses fixed (``CALIB_FIX_INTRINSIC``) for two pinhole
   lenses, ``cv2.fisheye.stereoCalibrate`` (``FIX_INTRINSIC``) for two fisheye lenses; for a
   mixed pair, both cameras' corners undistorted to normalised coordinates
   (``undistortPointsIter`` / ``fisheye.undistortPoints``) and ``cv2.stereoCalibrate`` with
   identity camera matrices and no distortion.

Writes per camera ``K``, ``dist``, ``fisheye`` and ``T_ref_cam`` as JSON.  numpy and OpenCV
only.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

_CRIT = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)


def calibrate(obj, img, size, fisheye: bool):
    if fisheye:
        flags = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
        _, K, D, _, _ = cv2.fisheye.calibrate([o[:, None] for o in obj],
                                              [u[:, None] for u in img], size, None, None,
                                              flags=flags, criteria=_CRIT)
    else:
        _, K, D, _, _ = cv2.calibrateCamera(obj, img, size, None, None, criteria=_CRIT)
    return K, D.ravel()


def normalised(img, K, D, fisheye: bool):
    px = np.ascontiguousarray(img, np.float64).reshape(-1, 1, 2)
    if fisheye:
        return cv2.fisheye.undistortPoints(px, K, D, criteria=_CRIT).reshape(-1, 2)
    return cv2.undistortPointsIter(px, K, D, None, None, _CRIT).reshape(-1, 2)


def stereo(obj, img_a, img_b, lens_a, lens_b, size):
    """T_b_a: the pose of camera a in camera b, from the shared views."""
    (Ka, Da, fa), (Kb, Db, fb) = lens_a, lens_b
    if fa and fb:
        out = cv2.fisheye.stereoCalibrate([o[:, None] for o in obj],
                                          [u[:, None] for u in img_a],
                                          [u[:, None] for u in img_b], Ka, Da, Kb, Db, size,
                                          flags=cv2.fisheye.CALIB_FIX_INTRINSIC, criteria=_CRIT)
        R, t = out[5], out[6]
    elif not fa and not fb:
        out = cv2.stereoCalibrate(obj, img_a, img_b, Ka, Da, Kb, Db, size,
                                  flags=cv2.CALIB_FIX_INTRINSIC, criteria=_CRIT)
        R, t = out[5], out[6]
    else:
        na = [normalised(u, Ka, Da, fa).astype(np.float32) for u in img_a]
        nb = [normalised(u, Kb, Db, fb).astype(np.float32) for u in img_b]
        out = cv2.stereoCalibrate(obj, na, nb, np.eye(3), np.zeros(5), np.eye(3), np.zeros(5),
                                  size, flags=cv2.CALIB_FIX_INTRINSIC, criteria=_CRIT)
        R, t = out[5], out[6]
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, np.ravel(t)
    return T


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("corners", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    data = np.load(args.corners)
    names = [str(n) for n in data["cameras"]]
    spacing, size = float(data["spacing"]), tuple(int(s) for s in data["size"])
    rows, cols = data[f"{names[0]}_corners"].shape[1:3]
    grid = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * spacing
    obj1 = np.column_stack([grid, np.zeros(len(grid))]).astype(np.float32)
    lenses, views = [], []
    for name in names:
        c = data[f"{name}_corners"].reshape(len(data[f"{name}_corners"]), -1, 2)
        img = [u.astype(np.float32) for u in c]
        fish = str(data[f"{name}_model"]) == "fisheye"
        K, D = calibrate([obj1] * len(img), img, size, fish)
        lenses.append((K, D, fish))
        views.append(dict(zip(data[f"{name}_instants"].tolist(), img)))
    result = {}
    for j, name in enumerate(names):
        T = np.eye(4)
        if j > 0:
            shared = sorted(set(views[0]) & set(views[j]))
            T_j_0 = stereo([obj1] * len(shared), [views[0][t] for t in shared],
                           [views[j][t] for t in shared], lenses[0], lenses[j], size)
            T = np.linalg.inv(T_j_0)
        K, D, fish = lenses[j]
        result[name] = {"K": K.tolist(), "dist": D.tolist(), "fisheye": fish,
                        "T_ref_cam": T.tolist()}
    args.out.write_text(json.dumps({"cameras": result}))


if __name__ == "__main__":
    sys.exit(main())
