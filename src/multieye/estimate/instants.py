"""Images of different cameras taken at one instant: by stamp within a tolerance, or by name.

An *instant* is one pose of the target (docs/rig-yaml.md, section 2): images of different
cameras whose stamps differ by at most ``sync_tolerance`` seconds, or whose names (without the
extension) are equal.  A camera contributes at most one image to an instant.

Synopsis
--------
>>> import numpy as np
>>> inst, k = instants_from_stamps([np.array([0.0, 1.0]), np.array([0.001, 2.0])], 0.005)
>>> [a.tolist() for a in inst], k
([[0, 1], [0, 2]], 3)
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError

__all__ = ["default_sync_tolerance", "instants_from_stamps", "instants_from_names",
           "MAX_DEFAULT_SYNC_S"]

#: The default ``sync_tolerance`` is a quarter of the shortest interval between two images of
#: one camera, at most this (seconds).
MAX_DEFAULT_SYNC_S = 0.01


def default_sync_tolerance(stamps: Sequence[NDArray[np.float64]]) -> float:
    """A quarter of the shortest interval between two images of one camera, at most
    :data:`MAX_DEFAULT_SYNC_S` (seconds); that bound for cameras with one image each."""
    gaps = [np.diff(np.sort(np.asarray(s, dtype=np.float64))) for s in stamps if len(s) > 1]
    gaps = np.concatenate(gaps) if gaps else np.zeros(0)
    gaps = gaps[gaps > 0]
    if gaps.size == 0:
        return MAX_DEFAULT_SYNC_S
    return float(min(MAX_DEFAULT_SYNC_S, gaps.min() / 4))


def _check_camera_count(per_camera, what: str) -> list:
    per_camera = list(per_camera)
    if not per_camera:
        raise InputError(f"no cameras given: {what} is empty")
    return per_camera


def instants_from_stamps(stamps: Sequence, tolerance: float
                         ) -> tuple[list[NDArray[np.int64]], int]:
    """Number the instants of images by their stamps.

    Images are taken in time order; an image joins the open instant when it is at most
    ``tolerance`` after the instant's first image and its camera has none there yet, else it
    opens a new one.

    Parameters
    ----------
    stamps : sequence over cameras of array_like, shape (n_j,)
        Each image's time, seconds (on one clock: each camera's offset applied).
    tolerance : float
        ``sync_tolerance``, seconds, >= 0.

    Returns
    -------
    instants : list of ndarray of int, shape (n_j,)
        Instant of each image of each camera, numbered 0..K-1 in time order.
    K : int
    """
    stamps = [np.asarray(s, dtype=np.float64).reshape(-1)
              for s in _check_camera_count(stamps, "stamps")]
    tol = float(tolerance)
    if not (np.isfinite(tol) and tol >= 0):
        raise InputError(f"sync_tolerance must be a number >= 0 seconds, got {tolerance!r}")
    if any(not np.all(np.isfinite(s)) for s in stamps):
        raise InputError("image stamps must be finite")
    t = np.concatenate(stamps) if stamps else np.zeros(0)
    cam = np.concatenate([np.full(len(s), j) for j, s in enumerate(stamps)])
    order = np.argsort(t, kind="stable")
    instant = np.empty(t.size, dtype=np.int64)
    k, start, members = -1, -np.inf, set()
    for i in order:
        if t[i] - start <= tol and cam[i] not in members:
            members.add(int(cam[i]))
        else:
            k, start, members = k + 1, t[i], {int(cam[i])}
        instant[i] = k
    bounds = np.cumsum([0] + [len(s) for s in stamps])
    return [instant[a:b] for a, b in zip(bounds[:-1], bounds[1:])], k + 1


def instants_from_names(names: Sequence[Sequence[str]]) -> tuple[list[NDArray[np.int64]], int]:
    """Number the instants of images by their names (stems): equal names, one instant.

    Parameters
    ----------
    names : sequence over cameras of sequence of str
        Each image's name without its extension; unique within a camera.

    Returns
    -------
    instants : list of ndarray of int, shape (n_j,)
        Numbered 0..K-1 in the order of the sorted names.
    K : int
    """
    names = [list(n) for n in _check_camera_count(names, "names")]
    for j, ns in enumerate(names):
        if len(set(ns)) != len(ns):
            dup = next(n for n in ns if ns.count(n) > 1)
            raise InputError(f"camera {j}: two images named {dup!r}; names must be unique "
                             "within a camera to be matched across cameras")
    key = {n: k for k, n in enumerate(sorted(set().union(*names)))}
    return [np.asarray([key[n] for n in ns], dtype=np.int64) for ns in names], len(key)
