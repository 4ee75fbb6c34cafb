"""mrcal per camera, then OpenCV's hand-eye: the job with the lenses unknown (issue 21, item 4).

Run by an interpreter with mrcal (a peer, never a dependency of multieye; on Python 3.12:
``pip install --no-deps mrcal && pip install numpy numpysane scipy gnuplotlib
opencv-python-headless``)::

    python benchmarks/peers/mrcal_script.py CORNERS.npz MOCAP.txt --out result.json

``CORNERS.npz`` is what ``opencv_script.py --corners-out`` saves (mrcal's own detector,
mrgingham, is not on the package index): per camera the corners of every image where the
board was found and the image stamps. Per camera:

1. mrcal's calibration as ``mrcal-calibrate-cameras`` runs it: ``mrcal.seed_stereographic``,
   two preliminary ``mrcal.optimize`` (geometry, then the stereographic core), then the lens
   ``--lensmodel`` (default ``LENSMODEL_OPENCV5``, OpenCV's 5 radial-tangential
   coefficients) with every board pose, mrcal's outlier rejection and regularisation (board
   warp not estimated: the rendered board is flat);
2. the board poses of that solve (``rt_ref_frame``: the camera is mrcal's reference, so
   these are ``T_cam_target``) with the motion-capture pose nearest in time, into
   ``cv2.calibrateRobotWorldHandEye`` as in ``opencv_script.py``.

Also importable: :func:`calibrate_camera` (``bench_lens_sweep.py`` runs it on simulated
corners through ``--lens-only``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import mrcal
import numpy as np
import numpysane as nps

from opencv_script import hand_eye, nearest, read_mocap


def calibrate_cameras(corners: np.ndarray, ifc: np.ndarray, sizes, spacing: float,
                      lensmodel: str, focal: float):
    """mrcal's solve as ``mrcal-calibrate-cameras`` runs it, for one camera or several.

    ``seed_stereographic`` of every camera and frame, two preliminary ``mrcal.optimize``
    (geometry, then the stereographic core), then ``lensmodel`` with every extrinsic and
    board pose, mrcal's outlier rejection and regularisation (board warp not estimated).

    Parameters
    ----------
    corners : (k, rows, cols, 2)
        Every observation's corner pixels, sorted by frame then camera.
    ifc : (k, 2) int32
        mrcal's ``indices_frame_camera`` of each observation.
    sizes : sequence of (width, height), one per camera
    spacing, lensmodel, focal
        Corner spacing (metres), mrcal's lens model, seed focal length (pixels).

    Returns
    -------
    intrinsics : (m, p), rt_cam_ref : (m - 1, 6), rt_ref_frame : (frames, 6)
    """
    obs = nps.glue(corners, np.ones(corners.shape[:-1] + (1,)), axis=-1)
    imagersizes = np.array(sizes, dtype=np.int32)
    intr, rt_cam_ref, rt_ref_frame = mrcal.seed_stereographic(
        imagersizes=imagersizes, focal_estimate=focal, indices_frame_camera=ifc,
        observations=obs, object_spacing=spacing)
    idx = nps.glue(ifc, ifc[:, (1,)] - 1, axis=-1)
    common = dict(observations_board=obs, indices_frame_camintrinsics_camextrinsics=idx,
                  imagersizes=imagersizes, calibration_object_spacing=spacing,
                  do_optimize_calobject_warp=False, verbose=False)
    for core in (False, True):
        mrcal.optimize(intrinsics=intr, rt_cam_ref=rt_cam_ref, rt_ref_frame=rt_ref_frame,
                       lensmodel="LENSMODEL_STEREOGRAPHIC", do_optimize_intrinsics_core=core,
                       do_optimize_intrinsics_distortions=False,
                       do_apply_outlier_rejection=False, do_apply_regularization=False,
                       **common)
    extra = mrcal.lensmodel_num_params(lensmodel) - intr.shape[-1]
    intr = nps.glue(intr, np.zeros((len(imagersizes), extra)), axis=-1)
    mrcal.optimize(intrinsics=intr, rt_cam_ref=rt_cam_ref, rt_ref_frame=rt_ref_frame,
                   lensmodel=lensmodel, do_optimize_intrinsics_core=True,
                   do_optimize_intrinsics_distortions=True, do_optimize_extrinsics=True,
                   do_optimize_frames=True, do_apply_outlier_rejection=True,
                   do_apply_regularization=True, **common)
    return intr, rt_cam_ref, rt_ref_frame


def calibrate_camera(corners: np.ndarray, spacing: float, size, lensmodel: str,
                     focal: float = 700.0):
    """mrcal's monocular calibration.

    Parameters
    ----------
    corners : (n, rows, cols, 2)
        Pixels of the board's corners, row by row, x along the columns (mrcal's order).
    spacing : float
        Corner spacing, metres.
    size : (width, height)
    lensmodel : str
    focal : float
        Seed focal length, pixels.

    Returns
    -------
    intrinsics : (k,) mrcal's intrinsics vector of ``lensmodel``
    T_cam_target : (n, 4, 4)
    """
    n = len(corners)
    ifc = np.column_stack([np.arange(n), np.zeros(n)]).astype(np.int32)
    intr, _, rt_ref_frame = calibrate_cameras(np.asarray(corners, float), ifc, [size], spacing,
                                              lensmodel, focal)
    Rt = mrcal.Rt_from_rt(rt_ref_frame)                  # (n, 4, 3): R then t
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3], T[:, :3, 3] = Rt[:, :3, :], Rt[:, 3, :]
    return intr[0], T


def lens_only(args) -> None:
    data, out = np.load(args.corners), {}
    for key in data.files:
        name, lensmodel = key.split("|")
        intr = calibrate_camera(data[key], args.spacing, args.size, lensmodel)[0]
        fx, fy, cx, cy = intr[:4]
        out[name] = {"K": [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]],
                     "dist": intr[4:].tolist()}
    args.out.write_text(json.dumps(out))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("corners", type=Path)
    ap.add_argument("mocap", type=Path, nargs="?")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--lensmodel", default="LENSMODEL_OPENCV5")
    ap.add_argument("--lens-only", action="store_true",
                    help="CORNERS holds arrays named KEY|LENSMODEL (n, rows, cols, 2): write "
                         "each one's lens as {KEY: {K, dist}} (no hand-eye)")
    ap.add_argument("--spacing", type=float, default=0.05, help="with --lens-only, metres")
    ap.add_argument("--size", type=int, nargs=2, default=[1280, 960],
                    help="with --lens-only, pixels")
    args = ap.parse_args(argv)
    if args.lens_only:
        return lens_only(args)
    data = np.load(args.corners)
    rows, cols, spacing = int(data["rows"]), int(data["cols"]), float(data["spacing"])
    size = [int(s) for s in data["size"]]
    t_mocap, T_mocap = read_mocap(args.mocap)
    result = {}
    for name in data["cameras"]:
        name = str(name)
        corners = data[f"{name}_corners"].reshape(-1, rows, cols, 2)
        intr, T_cam_target = calibrate_camera(corners, spacing, size, args.lensmodel)
        i, ok = nearest(t_mocap, data[f"{name}_stamps"])
        T_world_cam = hand_eye(T_mocap[i[ok]], T_cam_target[ok])
        fx, fy, cx, cy = intr[:4]
        result[name] = {"T_world_cam": T_world_cam,
                        "K": [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]],
                        "dist": intr[4:].tolist(), "size": size, "used": int(ok.sum())}
    names = list(result)
    T_ref = np.linalg.inv(result[names[0]]["T_world_cam"])
    for name in names:
        result[name]["T_ref_cam"] = (T_ref @ result[name].pop("T_world_cam")).tolist()
    args.out.write_text(json.dumps({"cameras": result}, indent=1))


if __name__ == "__main__":
    sys.exit(main())
