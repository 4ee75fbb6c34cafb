"""The file boundary: readers and writers of every format multieye touches.

Units and quaternion orders are converted here only (docs/conventions.md, section 4): what
leaves this package is in metres, radians and seconds, with poses as 4x4 ``T_a_b`` arrays
whose frames are named.  Every user-facing problem is a :class:`~multieye.core.errors.DatasetError`
naming the file, the line (where the format has lines) and what was expected.  Every writer is
atomic (:mod:`multieye.io.atomic`).

Modules: :mod:`~.trajectory` (the Trajectory type), :mod:`~.tum`, :mod:`~.mocap_csv`
(generic CSV), :mod:`~.mocap_exports` (OptiTrack, Vicon), :mod:`~.rosbag`, :mod:`~.mocap` (one entry point for the
``mocap:`` section), :mod:`~.intrinsics`, :mod:`~.kalibr`, :mod:`~.rig` (``rig.yaml``),
:mod:`~.image_folder` (time-stamped image names), :mod:`~.calibration_json`.
OpenCV (``cv2.FileStorage``, ``cv2.imdecode``) and ``rosbags`` are imported only when a
function needs them.
"""

from multieye.io.atomic import atomic_output, write_bytes_atomic, write_text_atomic
from multieye.io.calibration_json import (
    BoardRecord,
    CalibrationRecord,
    CameraRecord,
    IntrinsicsRecord,
    PlausibilityItem,
    PoseUncertainty,
    RejectedItem,
    Residuals,
    read_calibration,
    write_calibration,
)
from multieye.io.image_folder import list_image_files, list_images, skipped_entries
from multieye.io.intrinsics_files import (
    read_camera_info,
    read_intrinsics,
    read_kalibr_intrinsics,
    read_opencv_intrinsics,
    write_intrinsics_file,
    write_opencv_intrinsics,
)
from multieye.io.kalibr import CamchainEntry, read_camchain, write_camchain
from multieye.io.mocap import MocapSpec, read_mocap, sniff_mocap_format
from multieye.io.mocap_csv import read_pose_csv
from multieye.io.mocap_exports import read_optitrack_csv, read_vicon_csv
from multieye.io.rig import CameraSpec, Rig, TargetSpec, load_rig, read_camera_intrinsics
from multieye.io.rosbag import (bag_image_count, bag_topics, iter_bag_images, read_bag_trajectory,
                                sample_bag_images)
from multieye.io.trajectory import Trajectory
from multieye.io.tum import read_tum, write_tum

__all__ = [
    # trajectories
    "Trajectory",
    "read_tum",
    "write_tum",
    "read_pose_csv",
    "read_optitrack_csv",
    "read_vicon_csv",
    "read_bag_trajectory",
    "MocapSpec",
    "read_mocap",
    "sniff_mocap_format",
    # images
    "list_images",
    "list_image_files",
    "skipped_entries",
    "iter_bag_images",
    "sample_bag_images",
    "bag_image_count",
    "bag_topics",
    # intrinsics and camera chains
    "read_intrinsics",
    "read_opencv_intrinsics",
    "read_camera_info",
    "read_kalibr_intrinsics",
    "write_opencv_intrinsics",
    "write_intrinsics_file",
    "CamchainEntry",
    "read_camchain",
    "write_camchain",
    # datasets
    "Rig",
    "CameraSpec",
    "TargetSpec",
    "load_rig",
    "read_camera_intrinsics",
    # results
    "CalibrationRecord",
    "BoardRecord",
    "CameraRecord",
    "Residuals",
    "PlausibilityItem",
    "PoseUncertainty",
    "IntrinsicsRecord",
    "RejectedItem",
    "read_calibration",
    "write_calibration",
    # writing
    "atomic_output",
    "write_text_atomic",
    "write_bytes_atomic",
]
