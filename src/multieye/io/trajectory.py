"""Time-stamped rigid poses with frame names: what every trajectory reader returns.

A :class:`Trajectory` holds ``T_parent_child[i]`` at time ``stamps[i]``.  Unlike trajectory
types that carry no frame names, the direction of every pose is part of the value, so
``traj.name`` reads ``"T_world_marker"`` and :meth:`Trajectory.inverted` gives
``"T_marker_world"``.

>>> import numpy as np
>>> from multieye.io.trajectory import Trajectory
>>> traj = Trajectory(np.array([0.0, 0.1]), np.stack([np.eye(4)] * 2), "world", "marker")
>>> traj.name, len(traj)
('T_world_marker', 2)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from multieye.core import geometry
from multieye.core.errors import InputError
from multieye.core.geometry import RIGID_TOLERANCE

__all__ = ["Trajectory", "SkippedRow", "RIGID_TOLERANCE"]


def _check_rigid(T: np.ndarray, block: int = 1 << 16) -> None:
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise InputError(f"poses must be an array of shape (N, 4, 4), got {T.shape}")
    for start in range(0, len(T), block):       # blocks: no (N, 3, 3) temporaries
        _check_rigid_block(T[start:start + block], start)


def _check_rigid_block(T: np.ndarray, start: int) -> None:
    if not np.all(np.isfinite(T)):
        raise InputError(f"pose {start + int(np.argwhere(~np.isfinite(T))[0, 0])} has NaN or "
                         "inf entries")
    bad = ~geometry.is_rigid(T)
    if np.any(bad):
        i = int(np.argmax(bad))
        ortho, det, _ = geometry.rigidity(T[i])
        raise InputError(f"pose {start + i} is not a rigid transform (|R^T R - I| = "
                         f"{ortho:.2e}, det R = {det:.6f}, last row {T[i, 3].tolist()})")


@dataclass(frozen=True)
class SkippedRow:
    """A row of a pose file that a reader left out as unusable (the rest is still read).

    Attributes
    ----------
    where : str
        The row within its file: ``"line 17"``, or for a bag ``"sample 3 (1700000000.5 s)"``.
    reason : str
        Why: a value that is not finite, or absurd (docs/rig-yaml.md, section 1).
    line : int or None
        1-based line, for text files.
    row : int
        1-based index of the row among the file's pose rows (``k`` of ``"<file> pose <k>"``).
    """

    where: str
    reason: str
    line: int | None = None
    row: int = 0


@dataclass(frozen=True)
class Trajectory:
    """Poses ``T_parent_child`` sampled at strictly increasing times.

    Attributes
    ----------
    stamps : ndarray, shape (N,), float64
        Seconds (any epoch; readers keep the source's clock).
    T : ndarray, shape (N, 4, 4), float64
        ``T_parent_child[i]``: maps child coordinates into parent coordinates, metres.
    parent, child : str
        Frame names, e.g. ``"world"`` and ``"marker"``.
    stamps_ns : ndarray, shape (N,), int64, or None
        The stamps in integer nanoseconds when the source had them exactly (ROS headers,
        nanosecond file names); ``stamps == stamps_ns * 1e-9`` then.
    skipped : tuple of SkippedRow
        Rows of the source file left out as unusable (non-finite or absurd values), which
        the poses above do not include.

    Raises
    ------
    InputError
        Shapes disagree, a pose is not rigid, or the stamps are not strictly increasing (the
        message names the first offending pair).  Use :meth:`from_unsorted` for samples in
        arbitrary order.
    """

    stamps: np.ndarray
    T: np.ndarray
    parent: str = "world"
    child: str = "marker"
    stamps_ns: np.ndarray | None = field(default=None)
    skipped: tuple[SkippedRow, ...] = ()

    def __post_init__(self):
        stamps = np.asarray(self.stamps, dtype=np.float64).reshape(-1)
        T = np.asarray(self.T, dtype=np.float64)
        if T.ndim == 3 and T.shape[0] != stamps.shape[0]:
            raise InputError(f"{stamps.shape[0]} stamps but {T.shape[0]} poses")
        _check_rigid(T)
        if not np.all(np.isfinite(stamps)):
            raise InputError("time stamps must be finite")
        back = stamps[1:] <= stamps[:-1]           # booleans: no float copy of the stamps
        if np.any(back):
            i = int(np.argmax(back))
            kind = ("duplicate time stamp" if stamps[i + 1] == stamps[i]
                    else "time stamps out of order")
            raise InputError(f"{kind}: sample {i + 1} at {float(stamps[i + 1])!r} s follows "
                             f"sample {i} at {float(stamps[i])!r} s; stamps must be strictly "
                             "increasing")
        ns = self.stamps_ns
        if ns is not None:
            ns = np.asarray(ns).reshape(-1)
            if ns.dtype.kind not in "iu" or ns.shape != stamps.shape:
                raise InputError("stamps_ns must be integers, one per stamp")
            ns = ns.astype(np.int64)
            if np.any(np.abs(ns * 1e-9 - stamps) > 1e-6):
                raise InputError("stamps_ns and stamps disagree")
        for name in ("parent", "child"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise InputError(f"frame name {name} must be a non-empty string")
        object.__setattr__(self, "stamps", stamps)
        object.__setattr__(self, "T", T)
        object.__setattr__(self, "stamps_ns", ns)
        object.__setattr__(self, "skipped", tuple(self.skipped))

    @classmethod
    def from_unsorted(cls, stamps, T, parent: str = "world", child: str = "marker",
                      stamps_ns=None, skipped: tuple[SkippedRow, ...] = ()) -> Trajectory:
        """Sort samples by time (stable); equal stamps still raise :class:`InputError`."""
        stamps = np.asarray(stamps, dtype=np.float64).reshape(-1)
        if stamps_ns is not None:
            stamps_ns = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
            order = np.argsort(stamps_ns, kind="stable")
            stamps_ns = stamps_ns[order]
        else:
            order = np.argsort(stamps, kind="stable")
        return cls(stamps[order], np.asarray(T, dtype=np.float64)[order], parent, child, stamps_ns,
                   tuple(skipped))

    def __len__(self) -> int:
        return int(self.stamps.shape[0])

    @property
    def name(self) -> str:
        """``"T_<parent>_<child>"``."""
        return f"T_{self.parent}_{self.child}"

    def inverted(self) -> Trajectory:
        """The same samples as ``T_child_parent``."""
        return Trajectory(self.stamps, geometry.inv(self.T), self.child, self.parent,
                          self.stamps_ns, self.skipped)
