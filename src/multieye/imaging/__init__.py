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

from multieye.imaging.batch import ImageResult, detect_and_estimate, process_image
from multieye.core.lens import distort_points, project_points, undistort_points
from multieye.imaging.detect import Detection
from multieye.imaging.pnp import PoseEstimate, estimate_pose, reprojection_residuals
from multieye.imaging.targets import (
    AprilGrid,
    AsymmetricCircleGrid,
    Charuco,
    Chessboard,
    CircleGrid,
    Target,
    TARGET_TYPES,
    target_from_spec,
)

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
