"""What the dry run (:mod:`multieye.pipeline.dry_run`) measures of a camera's motion
capture: how far the paired poses turn, and how far each image is from its nearest pose.

Synopsis
--------
>>> range_deg, spread_deg = rotation_range(T_world_marker)                 # doctest: +SKIP
>>> gaps_s = nearest_gap(mocap_stamps, image_stamps)                       # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np

from multieye.pipeline.dry_run_sample import evenly_spaced
from multieye.solvers.checks import rotation_spread

__all__ = ["rotation_range", "nearest_gap"]


def rotation_range(T_mocap: np.ndarray) -> tuple[float | None, tuple | None]:
    """Largest rotation between two of the poses (degrees; at most 300 poses evenly spaced)
    and the RMS rotation about the principal axes (degrees, descending)."""
    if len(T_mocap) < 2:
        return None, None
    R = T_mocap[evenly_spaced(len(T_mocap), 300), :3, :3]
    cos = (np.einsum("aij,bij->ab", R, R) - 1.0) / 2.0      # tr(R_a R_b^T) = sum R_a * R_b
    range_deg = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max())
    spread = tuple(float(v) for v in np.degrees(rotation_spread(T_mocap)))
    return range_deg, spread


def nearest_gap(times: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Distance of each of ``q`` to the nearest of the increasing ``times`` (inf without any),
    in memory linear in their lengths (a long bag's images against a long motion capture)."""
    if not len(times):
        return np.full(len(q), np.inf)
    i = np.searchsorted(times, q)
    before = times[np.clip(i - 1, 0, len(times) - 1)]
    after = times[np.clip(i, 0, len(times) - 1)]
    return np.minimum(np.abs(q - before), np.abs(q - after))
