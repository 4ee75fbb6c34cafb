"""Parameter blocks on manifolds and residual groups: what a problem hands the engine.

A problem is a set of *families* of parameter blocks (every camera's ``X``, the shared ``Y``,
one motion-capture pose per image, ...) and a set of *residual groups*.  Each family declares
its manifold once; a residual group says which blocks every row touches and returns its
residuals and their Jacobians with respect to the blocks' local perturbations at the current
values (Ceres' and GTSAM's split: the engine knows nothing about cameras).

Manifolds (parameters per block, radians and metres):

===============  ===  ==========================================================================
``se3-left``     6    ``R <- Exp(phi) R``, ``t <- t + tau``: rotation perturbed on the left, in the
                      frame the pose maps into (docs/conventions.md, covariance convention)
``se3-right``    6    ``R <- R Exp(phi)``, ``t <- t + tau``: rotation perturbed in the pose's own
                      frame (the motion-capture noise model: rotation noise in the marker frame)
``euclidean``    n    ``v <- v + d``
===============  ===  ==========================================================================

A family marked ``eliminate=True`` holds per-measurement blocks (one motion-capture pose per
measurement): the engine removes them from the normal equations by a Schur complement, so each
residual group may touch at most one such block per row; the rows (of any groups) that share
one may touch different other blocks (one pose seen by several cameras, each with its ``X``).

Synopsis
--------
>>> import numpy as np
>>> X = Blocks("X", np.eye(4)[None].repeat(3, axis=0), "se3-left")
>>> X.size, X.count
(6, 3)
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.geometry import make_transform
from multieye.core.lie import exp_so3

__all__ = ["SegmentRange", "MANIFOLDS", "Blocks", "ResidualGroup"]

F64 = NDArray[np.float64]

#: Manifolds a family of blocks can live on (module docstring).
MANIFOLDS = ("se3-left", "se3-right", "euclidean")


@dataclass(frozen=True)
class Blocks:
    """A family of parameter blocks of one kind, with their current values.

    Attributes
    ----------
    name : str
        How residual groups refer to the family.
    value : ndarray, shape (count, 4, 4) or (count, n)
        Current values: rigid transforms (``se3-*``) or vectors (``euclidean``).
    manifold : {"se3-left", "se3-right", "euclidean"}
    eliminate : bool
        Per-measurement blocks, eliminated by the Schur complement.
    """

    name: str
    value: F64
    manifold: str = "se3-left"
    eliminate: bool = False

    def __post_init__(self):
        v = np.asarray(self.value, dtype=np.float64)
        if self.manifold not in MANIFOLDS:
            raise InputError(f"blocks {self.name!r}: manifold must be one of {MANIFOLDS}, "
                             f"got {self.manifold!r}")
        if self.manifold == "euclidean":
            if v.ndim != 2:
                raise InputError(f"blocks {self.name!r}: euclidean values must be (count, n), "
                                 f"got shape {v.shape}")
        elif v.ndim != 3 or v.shape[1:] != (4, 4):
            raise InputError(f"blocks {self.name!r}: pose values must be (count, 4, 4), "
                             f"got shape {v.shape}")
        if not np.all(np.isfinite(v)):
            raise InputError(f"blocks {self.name!r}: values must be finite")
        object.__setattr__(self, "value", v)

    @property
    def size(self) -> int:
        """Parameters per block."""
        return 6 if self.manifold != "euclidean" else int(self.value.shape[1])

    @property
    def count(self) -> int:
        """Number of blocks."""
        return int(self.value.shape[0])

    def retract(self, delta: F64) -> Blocks:
        """The family moved by ``delta`` (count * size,), block by block (module docstring)."""
        d = np.asarray(delta, dtype=np.float64).reshape(self.count, self.size)
        v = self.value
        if self.manifold == "euclidean":
            new = v + d
        elif self.manifold == "se3-left":
            new = make_transform(exp_so3(d[:, :3]) @ v[:, :3, :3], v[:, :3, 3] + d[:, 3:])
        else:
            new = make_transform(v[:, :3, :3] @ exp_so3(d[:, :3]), v[:, :3, 3] + d[:, 3:])
        return Blocks(self.name, new, self.manifold, self.eliminate)


class ResidualGroup(ABC):
    """Rows of residuals of one kind, each touching one block of each of its slots.

    Rows are grouped into *segments*: consecutive rows that touch the same blocks (all the
    target points of one image).  The engine forms the normal equations segment by segment.

    Parameters
    ----------
    slots : sequence of str
        Family names of the blocks each row touches, in the order of the Jacobians that
        :meth:`evaluate` returns.
    index : array_like of int, shape (n_segments, n_slots)
        Block of each slot's family that each segment touches.
    segment : array_like of int, shape (n_rows,)
        Segment of each row, non-decreasing (rows stored segment by segment).
    dim : int
        Residual components per row.
    """

    def __init__(self, slots: Sequence[str], index, segment, dim: int):
        self.slots = tuple(slots)
        self.index = np.asarray(index, dtype=np.int64).reshape(-1, len(self.slots))
        self.segment = np.asarray(segment, dtype=np.int64).reshape(-1)
        self.dim = int(dim)
        n_seg = len(self.index)
        if self.segment.size and (np.any(np.diff(self.segment) < 0) or self.segment[0] < 0
                                  or self.segment[-1] >= n_seg):
            raise InputError("residual rows must be stored segment by segment, with segments "
                             f"numbered 0..{n_seg - 1}")
        starts = np.searchsorted(self.segment, np.arange(n_seg))
        #: Position of each row inside its segment, and the longest segment.
        self.position = np.arange(self.segment.size) - starts[self.segment]
        self.longest = int(self.position.max()) + 1 if self.segment.size else 0

    @property
    def n_rows(self) -> int:
        return int(self.segment.size)

    def pad(self, rows: F64) -> F64:
        """Per-row array (n_rows, dim, ...) to zero-padded segment blocks (S, longest * dim, ...)."""
        return _pad(self, rows)

    def linearize(self, values: Mapping[str, F64]) -> tuple[F64, F64, F64]:
        """Residuals and their Jacobian laid out per segment, as the engine consumes them.

        Returns
        -------
        residuals : ndarray, shape (n_rows, dim)
        blocks : ndarray, shape (n_segments, longest * dim, c)
            Each segment's rows stacked (zero rows where a segment is shorter), against the
            concatenated parameters of its slots (c = sum of the slots' block sizes).
        padded : ndarray, shape (n_segments, longest * dim)
            The residuals in the same layout.

        The default pads what :meth:`evaluate` returns; a group that can compute the padded
        layout directly (all the points of an image at once) overrides it.
        """
        r, jac = self.evaluate(values, True)
        return r, self.pad(np.concatenate(jac, axis=2)), self.pad(r)

    def linearize_chunks(self, values: Mapping[str, F64], max_segments: int):
        """:meth:`linearize` a piece at a time, for the engine to sum the normal equations
        without holding the whole Jacobian.

        Yields ``(piece, residuals, blocks, padded)``: ``piece`` has this group's ``slots``,
        ``index``, ``n_rows`` and ``pad`` for its segments (the group itself, or a
        :class:`SegmentRange`).  The default yields the whole group as one piece; a group
        whose rows can be computed for a range of segments alone overrides it.
        """
        yield (self, *self.linearize(values))

    @abstractmethod
    def evaluate(self, values: Mapping[str, F64], jacobians: bool
                 ) -> tuple[F64, list[F64] | None]:
        """Residuals at the current values, and their Jacobians when asked.

        Parameters
        ----------
        values : mapping of family name to ndarray
            Current values of every family (:attr:`Blocks.value`).
        jacobians : bool

        Returns
        -------
        residuals : ndarray, shape (n_rows, dim)
            Normalised by their noise (unit variance for a correct noise model); NaN where a
            row cannot be evaluated (the engine then rejects the step).
        jacobians : list of ndarray, shape (n_rows, dim, size of slot k), or None
            Derivative with respect to each slot's block perturbation at its current value.
        """


class SegmentRange:
    """Segments ``lo:hi`` of a residual group, as the engine's assembly sees them (the
    ``slots``, ``index``, ``n_rows`` and ``pad`` of those segments alone)."""

    def __init__(self, group: ResidualGroup, lo: int, hi: int):
        starts = np.searchsorted(group.segment, [lo, hi])
        rows = slice(int(starts[0]), int(starts[1]))
        self.slots, self.dim, self.longest = group.slots, group.dim, group.longest
        self.index = group.index[lo:hi]
        self.index_range = (lo, hi)
        self.segment = group.segment[rows] - lo
        self.position = group.position[rows]
        self.rows = rows
        #: Every segment has ``longest`` rows (no padding: the padded layout is a reshape).
        self.full = self.segment.size == (hi - lo) * self.longest

    def gather(self, padded: F64) -> F64:
        """The rows (n_rows, ...) of a padded (S, longest, ...) array."""
        if self.full:
            return padded.reshape((-1,) + padded.shape[2:])
        return padded[self.segment, self.position]

    @property
    def n_rows(self) -> int:
        return int(self.segment.size)

    def pad(self, rows: F64) -> F64:
        """As :meth:`ResidualGroup.pad`, for these segments' rows."""
        return _pad(self, rows)


def _pad(layout: ResidualGroup | SegmentRange, rows: F64) -> F64:
    """``rows`` (n_rows, dim, ...) of ``layout`` (its ``index``, ``segment``, ``position``,
    ``longest`` and ``dim``) to zero-padded segment blocks (S, longest * dim, ...)."""
    S, m = len(layout.index), layout.longest
    if rows.shape[0] == S * m:                        # every segment full: no padding
        return rows.reshape((S, m * layout.dim) + rows.shape[2:])
    out = np.zeros((S, m) + rows.shape[1:])
    out[layout.segment, layout.position] = rows
    return out.reshape((S, m * layout.dim) + rows.shape[2:])
