"""The image side: camera models, targets, detection, PnP, rendering, batch processing.

With the lens models (:mod:`multieye.core.lens`), the only code of multieye that imports
OpenCV (``cv2``). Data flows
images -> :func:`.detect.detect` -> :func:`.pnp.estimate_pose` -> ``T_cam_target`` per image,
which the hand-eye solvers consume; :func:`.batch.detect_and_estimate` does this over many
files in parallel.  Synthetic images are made in :mod:`multieye.sim.render`.

``detect`` is not re-exported here: the name would hide the module
``multieye.imaging.detect``; import it from its module.

Synopsis
--------
>>> from multieye.imaging import target_from_spec, detect_and_estimate    # doctest: +SKIP
>>> board = target_from_spec({"type": "chessboard", "rows": 8, "cols": 11, "spacing": 0.03})  # doctest: +SKIP
>>> results = detect_and_estimate(paths, board, intrinsics)              # doctest: +SKIP
"""

from multieye.core.lazy_names import lazy_names

#: Public names and the module that defines each, imported when first used: OpenCV loads
#: then, so that the detection's fork server can be started (``multieye.imaging.workers``)
#: before this process imports it (issue 21).
_LAZY = {
    "ImageResult": "multieye.imaging.batch",
    "detect_and_estimate": "multieye.imaging.batch",
    "process_image": "multieye.imaging.batch",
    "distort_points": "multieye.core.lens",
    "project_points": "multieye.core.lens",
    "undistort_points": "multieye.core.lens",
    "Detection": "multieye.imaging.detect",
    "PoseEstimate": "multieye.imaging.pnp",
    "estimate_pose": "multieye.imaging.pnp",
    "reprojection_residuals": "multieye.imaging.pnp",
    **dict.fromkeys(("AprilGrid", "AsymmetricCircleGrid", "Charuco", "Chessboard", "CircleGrid",
                     "Target", "TARGET_TYPES", "target_from_spec"), "multieye.imaging.targets"),
}

__all__ = [
    "AprilGrid",
    "AsymmetricCircleGrid",
    "Charuco",
    "Chessboard",
    "CircleGrid",
    "Detection",
    "ImageResult",
    "PoseEstimate",
    "TARGET_TYPES",
    "Target",
    "detect_and_estimate",
    "distort_points",
    "estimate_pose",
    "process_image",
    "project_points",
    "reprojection_residuals",
    "target_from_spec",
    "undistort_points",
]


__getattr__, __dir__ = lazy_names(__name__, _LAZY)
