"""Bounds on the numbers multieye accepts where they enter: rig.yaml, intrinsics files,
motion-capture and pose rows, and on the size of the files it reads (docs/rig-yaml.md,
section 1).

Each bound is far beyond any real rig, board, camera or recording, and close enough that a
value past it is a mistake (a unit read wrong, a corrupted cell, a test value) rather than a
measurement: such values are refused where they enter, with the file, the line and the bound,
instead of overflowing or degenerating somewhere downstream.
"""

from __future__ import annotations

__all__ = [
    "MAX_SPACING_M",
    "MAX_GRID_SIDE",
    "MAX_IMAGE_SIDE_PX",
    "MAX_FOCAL_PX",
    "MIN_FOCAL_FRACTION",
    "MAX_SKEW_FRACTION",
    "MAX_PRINCIPAL_POINT_OUTSIDE",
    "MAX_RADIAL_DISTORTION",
    "MAX_TANGENTIAL_DISTORTION",
    "MAX_TILT_RAD",
    "MAX_XI",
    "MAX_EUCM_BETA",
    "MAX_POSITION_M",
    "MAX_STAMP_S",
    "MAX_TIME_OFFSET_S",
    "MAX_TIME_TOLERANCE_S",
    "MAX_ROTATION_NOISE_DEG",
    "MAX_TRANSLATION_NOISE_M",
    "MAX_YAML_BYTES",
    "MAX_TABLE_BYTES",
    "MAX_JSON_BYTES",
    "MAX_IMAGE_BYTES",
    "MAX_IMAGE_PIXELS",
]

#: Largest target ``spacing`` (and ``marker_size``), metres.
MAX_SPACING_M = 10.0
#: Largest target ``rows`` and ``cols``.
MAX_GRID_SIDE = 200
#: Largest image width or height in intrinsics, pixels.
MAX_IMAGE_SIDE_PX = 100_000
#: Largest focal length and principal point coordinate in intrinsics, pixels.
MAX_FOCAL_PX = 1e6
#: Smallest focal length in intrinsics that give the image size, as a fraction of the larger
#: image side: 0.02 is a pinhole's 175 deg field of view across the image, or an equidistant
#: fisheye's 25 rad; below it the focal length is in another unit (millimetres) or wrong.
MIN_FOCAL_FRACTION = 0.02
#: Largest skew ``K[0][1]`` accepted, as a fraction of ``fx`` (1e-6: a thousandth of a pixel
#: at fx = 1000 px, a rounding in the file). The lens models have no skew (OpenCV's neither),
#: so a larger one would be dropped without a word: it is refused instead.
MAX_SKEW_FRACTION = 1e-6
#: How far outside the image the principal point may lie, as a fraction of the image's width
#: (for cx) or height (for cy), when the intrinsics give the image size: -w <= cx <= 2 w.
MAX_PRINCIPAL_POINT_OUTSIDE = 1.0
#: Largest magnitude of a radial (k1..k6; fisheye k1..k4) or thin-prism (s1..s4) distortion
#: coefficient. Real lenses, even OpenCV's ill-conditioned rational fits, stay within tens.
MAX_RADIAL_DISTORTION = 1e4
#: Largest magnitude of a tangential coefficient (p1, p2): 1 already moves a point at 45 deg
#: off axis by its whole distance from the centre; real lenses have about 1e-3.
MAX_TANGENTIAL_DISTORTION = 1.0
#: Largest sensor tilt (OpenCV's taux, tauy), radians (29 deg; real sensors: a fraction of one).
MAX_TILT_RAD = 0.5
#: Largest magnitude of a unified (Mei-Rives ``xi``, BoofCV's ``mirror_offset``) or
#: double-sphere ``xi``: real lenses have 0 to about 3 (unified) or -1 to 1 (double sphere); at
#: 100 a unified lens is a pinhole of focal length f / 100 over a few degrees.
MAX_XI = 100.0
#: Largest extended-unified (EUCM) ``beta``: real lenses have about 0.5 to 2.
MAX_EUCM_BETA = 100.0
#: Largest translation coordinate of a motion-capture or precomputed pose row, metres (after
#: the unit conversion): a row beyond it is left out, with its line, as absurd.
MAX_POSITION_M = 1e4
#: Largest time stamp of a motion-capture or pose row, seconds (about the year 2286: image
#: names have at most 10 digits of whole seconds); a row beyond it is left out as absurd.
MAX_STAMP_S = 1e10
#: Largest clock offset (``time_offset``), seconds: the distance between any two stamps.
MAX_TIME_OFFSET_S = 1e10
#: Largest ``time_tolerance``, seconds.
MAX_TIME_TOLERANCE_S = 10.0
#: Largest stated motion-capture noise: ``rotation_noise_deg`` and ``translation_noise_m``.
MAX_ROTATION_NOISE_DEG = 30.0
MAX_TRANSLATION_NOISE_M = 1.0

# Sizes of the files read (counted while reading, :mod:`multieye.core.regular_files`).
#: Largest YAML or small text file: rig.yaml, intrinsics, a pose file beside an image, bytes.
MAX_YAML_BYTES = 1_000_000
#: Largest table of rows: motion capture (TUM, CSV, OptiTrack, Vicon), pose tables, bytes
#: (about 14 million TUM rows; tables are read line by line into arrays, about 170 bytes of
#: memory per row).
MAX_TABLE_BYTES = 512 * 2**20
#: Largest JSON file read back (calibration.json, details.json), bytes.
MAX_JSON_BYTES = 256 * 2**20
#: Largest image file, bytes.
MAX_IMAGE_BYTES = 512 * 2**20
#: Largest image, pixels (width x height, from the file's header, checked before decoding);
#: each side is bound by :data:`MAX_IMAGE_SIDE_PX` too.
MAX_IMAGE_PIXELS = 100_000_000
