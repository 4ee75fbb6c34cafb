"""The measurements of ``A_i^j X^j = Y B_i^j`` for every camera, as the solvers take them:
:class:`Measurements`, made once by :func:`multieye.solvers.checks.check_measurements`
(which validates them) and passed as they are from there on."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np

from multieye.core.errors import InputError, TooFewMeasurementsError
from multieye.solvers.kronecker import CameraStats, camera_stats, transform_entries
from multieye.solvers.methods import MIN_MEASUREMENTS

__all__ = ["Measurements", "MIN_MEASUREMENTS", "default_names"]

@lru_cache(maxsize=64)
def default_names(m: int) -> tuple[str, ...]:
    """``cam0, cam1, ...``: the names of cameras given without names."""
    return tuple(f"cam{j}" for j in range(m))


@dataclass(frozen=True)
class Measurements:
    """Validated measurements of all cameras, concatenated camera by camera.

    Attributes
    ----------
    entries : ndarray, shape (16, 2N)
        :func:`multieye.solvers.kronecker.transform_entries` of ``[A; B]``; bottom rows
        exactly (0, 0, 0, 1).
    counts : ndarray, shape (m,), int
        Measurements per camera.
    names : tuple of str
        Camera names used in messages.
    stats : CameraStats
        Per-camera sums the closed forms need (formed by the constructor).
    A, B : ndarray, shape (N, 4, 4)
        The transforms (formed on first use, like everything below).
    starts : ndarray, shape (m,), int
        Index of each camera's first row (for ``np.add.reduceat``).
    RA, RB, tA, tB, camera
        Contiguous rotation blocks ``(N, 3, 3)``, translations ``(N, 3)`` in metres, and
        the camera index of each row ``(N,)``.
    """

    entries: np.ndarray = field(repr=False)
    counts: np.ndarray
    names: tuple[str, ...]
    stats: CameraStats = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "stats", camera_stats(self.entries,
                                                       [int(c) for c in self.counts]))

    @property
    def m(self) -> int:
        return int(self.counts.size)

    @cached_property
    def _AB(self) -> np.ndarray:
        return np.ascontiguousarray(self.entries.T).reshape(-1, 4, 4)

    @property
    def A(self) -> np.ndarray:
        return self._AB[:self._AB.shape[0] // 2]

    @property
    def B(self) -> np.ndarray:
        return self._AB[self._AB.shape[0] // 2:]

    @cached_property
    def starts(self) -> np.ndarray:
        return np.concatenate([[0], np.cumsum(self.counts[:-1])]).astype(int)

    @cached_property
    def RA(self) -> np.ndarray:
        return np.ascontiguousarray(self.A[:, :3, :3])

    @cached_property
    def RB(self) -> np.ndarray:
        return np.ascontiguousarray(self.B[:, :3, :3])

    @cached_property
    def tA(self) -> np.ndarray:
        return np.ascontiguousarray(self.A[:, :3, 3])

    @cached_property
    def tB(self) -> np.ndarray:
        return np.ascontiguousarray(self.B[:, :3, 3])

    @cached_property
    def camera(self) -> np.ndarray:
        return np.repeat(np.arange(self.m), self.counts)

    def split(self, arr: np.ndarray) -> list[np.ndarray]:
        """Split a per-row array back into per-camera arrays."""
        return np.split(arr, self.starts[1:])

    def select(self, keep) -> Measurements:
        """The measurements where ``keep[j]`` (a boolean mask per camera) is True.

        Subsets of validated transforms need no new checks; the motion of the subset is
        not checked here (:func:`check_motion`, which :func:`multieye.solve` runs).

        Raises
        ------
        InputError
            Not one mask of the camera's length per camera.
        TooFewMeasurementsError
            A camera left with fewer than 3 measurements.
        """
        masks = [np.asarray(k, dtype=bool) for k in keep]
        if len(masks) != self.m or any(k.shape != (int(c),) for k, c in zip(masks, self.counts)):
            raise InputError(f"select needs one boolean mask per camera of lengths "
                             f"{self.counts.tolist()}, got shapes {[k.shape for k in masks]}")
        counts = [int(k.sum()) for k in masks]
        for name, n in zip(self.names, counts):
            if n < MIN_MEASUREMENTS:
                raise TooFewMeasurementsError(
                    f"camera {name} keeps {n} measurements, at least {MIN_MEASUREMENTS} are needed")
        idx = np.flatnonzero(np.concatenate(masks))
        N = int(self.counts.sum())
        return Measurements(entries=self.entries[:, np.concatenate([idx, N + idx])],
                            counts=np.array(counts), names=self.names)

    @classmethod
    def from_arrays(cls, A: np.ndarray, B: np.ndarray, counts) -> Measurements:
        """Build from concatenated arrays ``(N, 4, 4)`` of rigid transforms (no checks), the
        cameras named ``cam0, cam1, ...`` (``dataclasses.replace(meas, names=...)`` renames)."""
        return cls(entries=transform_entries(A, B, exact_bottom=True),
                   counts=np.array([int(c) for c in counts]), names=default_names(len(counts)))

    @classmethod
    def from_cameras(cls, A: list[np.ndarray], B: list[np.ndarray]) -> Measurements:
        """Build from per-camera arrays ``(N_j, 4, 4)`` of rigid transforms (no checks), the
        cameras named ``cam0, cam1, ...`` (``dataclasses.replace(meas, names=...)`` renames)."""
        return cls(entries=transform_entries(*A, *B, exact_bottom=True),
                   counts=np.array([len(a) for a in A]), names=default_names(len(A)))
