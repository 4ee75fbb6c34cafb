"""The rig linked by co-observations as residual groups for the engine (no motion capture).

What is measured are the target points' pixels.  The unknowns are each camera's pose in the
reference camera ``T_ref_cam^j`` (the reference camera's is the identity, not an unknown),
the target's pose ``T_ref_target(t)`` at every instant ``t`` (one per instant, however many
cameras saw it: docs/rig-yaml.md, section 2) and, when estimated, the lenses::

    p_cam = inv(T_ref_cam^j) @ T_ref_target(t) @ p          u = pi_j(p_cam)

:class:`RigPixelResiduals` holds one camera's ``(pi_j(p_cam) - u) / sigma_px`` (2 components
per point, one segment per image) touching its ``C`` block (not for the reference camera), the
instant's ``S`` block and, when estimated, its intrinsics family ``K:<camera>`` (the
parameters :attr:`multieye.core.intrinsics.Intrinsics.params`, the family name of
:func:`multieye.estimate.image_residuals.intrinsics_family`).

Block families (:class:`multieye.optimize.blocks.Blocks`): ``C`` (the m - 1 cameras other
than the reference, in camera order) and ``S`` (one per instant, eliminated by the Schur
complement), both ``se3-left``: ``R = Exp(phi) R_hat``, ``t = t_hat + tau``, the covariance
convention of docs/conventions.md (rotation perturbed in the reference camera's frame).

Jacobians at zero perturbation, with ``q = R_S p + t_S`` (the point in ``ref``),
``d = q - t_C`` and ``a^T [v]_x = (a x v)^T``::

    d p_cam / d phi_C = R_C^T [d]_x           d p_cam / d tau_C = -R_C^T
    d p_cam / d phi_S = -R_C^T [R_S p]_x      d p_cam / d tau_S = R_C^T

chained with the lens model's ``d uv / d p_cam`` and ``d uv / d intrinsics`` from OpenCV
(:func:`multieye.core.lens.project_with_jacobian`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points, project_with_jacobian
from multieye.estimate.image_data import view_points
from multieye.estimate.image_residuals import cross_rows, intrinsics_family
from multieye.optimize.blocks import Blocks, ResidualGroup

__all__ = ["RigViews", "RigPixelResiduals"]

F64 = NDArray[np.float64]


class RigViews:
    """Target points and pixels of every view (one image of one camera at one instant).

    Views are numbered camera by camera; points view by view.

    Parameters
    ----------
    views : mapping of camera name to sequence of (object_points, image_points, instant)
        ``views[name][i]``: target points of image i of that camera, (n, 3), metres in the
        ``target`` frame; their pixels, (n, 2); the instant (0..K-1) the image belongs to.
        Points with non-finite coordinates are left out; a camera sees an instant once.
        Camera j is the mapping's j-th.
    intrinsics : sequence of Intrinsics
        One per camera, in the order of ``views`` (the starting values of the estimated ones).
    reference : int
        The camera whose frame is ``ref``.
    free_intrinsics : sequence of bool, optional
        Per camera: estimate its lens (default: all held fixed).

    Attributes
    ----------
    camera, instant : ndarray of int, shape (n_views,)
    n_instants : int
    object_points, image_points : ndarray, shape (P, 3), (P, 2)
    view : ndarray of int, shape (P,)
        View of each point.
    """

    def __init__(self, views: Mapping[str, Sequence], intrinsics: Sequence[Intrinsics],
                 reference: int = 0, *, free_intrinsics: Sequence[bool] | None = None):
        if not isinstance(views, Mapping):
            raise InputError(f"views must be a mapping of camera name to views, got "
                             f"{type(views).__name__}")
        names, views, intrinsics = tuple(views), list(views.values()), list(intrinsics)
        m = len(views)
        if m == 0 or len(intrinsics) != m:
            raise InputError(f"{m} cameras of views and {len(intrinsics)} intrinsics; give "
                             "one of each per camera")
        if not 0 <= int(reference) < m:
            raise InputError(f"reference camera {reference} is not one of the {m} cameras")
        self.m, self.names, self.reference = m, names, int(reference)
        self.intrinsics = tuple(intrinsics)
        free = [False] * m if free_intrinsics is None else [bool(f) for f in free_intrinsics]
        if len(free) != m:
            raise InputError(f"free_intrinsics has {len(free)} entries for {m} cameras")
        self.free = tuple(free)
        obj, uv, of_point, cams, insts, keep = [], [], [], [], [], []
        for j, images in enumerate(views):
            for i, item in enumerate(images):
                where = f"camera {names[j]}, image {i}"
                o, u, t, ok = view_points(item, where, "instant", 4)
                if isinstance(t, bool) or not isinstance(t, (int, np.integer)) or t < 0:
                    raise InputError(f"{where}: instant must be a whole number >= 0, got {t!r}")
                obj.append(o[ok])
                uv.append(u[ok])
                keep.append(ok)
                of_point.append(np.full(int(ok.sum()), len(cams)))
                cams.append(j)
                insts.append(int(t))
        if not cams:
            raise InputError("no views given")
        self.camera = np.asarray(cams, dtype=np.int64)
        self.instant = np.asarray(insts, dtype=np.int64)
        used = np.unique(self.instant)
        if used.size != self.instant.max() + 1:
            raise InputError("instants must be numbered 0..K-1, each with a view")
        self.n_instants = int(used.size)
        self.object_points = np.concatenate(obj)
        self.image_points = np.concatenate(uv)
        self.view = np.concatenate(of_point)
        self.keep = keep
        self.n_views = len(cams)
        self.counts = np.bincount(self.camera, minlength=m)

    @property
    def others(self) -> list[int]:
        """The cameras other than the reference, in order: the blocks of family ``C``."""
        return [j for j in range(self.m) if j != self.reference]

    def families(self, T_ref_cam: F64, T_ref_target: F64,
                 intrinsics: Sequence[Intrinsics] | None = None) -> list[Blocks]:
        """``C`` (m - 1), ``K:<camera>`` per estimated lens, ``S`` (K, eliminated)."""
        intrinsics = self.intrinsics if intrinsics is None else intrinsics
        fams = []
        if self.m > 1:
            fams.append(Blocks("C", np.asarray(T_ref_cam)[self.others], "se3-left"))
        fams += [Blocks(intrinsics_family(n), intrinsics[j].params[None], "euclidean")
                 for j, n in enumerate(self.names) if self.free[j]]
        fams.append(Blocks("S", T_ref_target, "se3-left", eliminate=True))
        return fams

    def groups(self, sigma_px: float) -> list[ResidualGroup]:
        """One :class:`RigPixelResiduals` per camera with views."""
        return [RigPixelResiduals(self, j, sigma_px) for j in range(self.m) if self.counts[j]]

    def T_ref_cam(self, values: Mapping[str, F64]) -> F64:
        """Every camera's ``T_ref_cam`` (m, 4, 4) from the values of family ``C``."""
        out = np.tile(np.eye(4), (self.m, 1, 1))
        if self.m > 1:
            out[self.others] = values["C"]
        return out

    def current_intrinsics(self, values: Mapping[str, F64]) -> tuple[Intrinsics, ...]:
        """Every camera's lens at the values (the estimated ones from ``K:<camera>``)."""
        return tuple(self.intrinsics[j].with_params(values[intrinsics_family(n)][0])
                     if self.free[j] else self.intrinsics[j]
                     for j, n in enumerate(self.names))


class RigPixelResiduals(ResidualGroup):
    """One camera's target-point pixel residuals over ``sigma_px`` (module docstring).

    Parameters
    ----------
    data : RigViews
    camera : int
    sigma_px : float
    """

    def __init__(self, data: RigViews, camera: int, sigma_px: float):
        views = np.flatnonzero(data.camera == camera)
        self.first = int(views[0])
        pts = np.flatnonzero(data.camera[data.view] == camera)
        self.is_ref = camera == data.reference
        self.free = data.free[camera]
        name = data.names[camera]
        slots = ([] if self.is_ref else ["C"]) + ["S"] + ([intrinsics_family(name)]
                                                         if self.free else [])
        cols = []
        if not self.is_ref:
            cols.append(np.full(views.size, data.others.index(camera)))
        cols.append(data.instant[views])
        if self.free:
            cols.append(np.zeros(views.size, dtype=np.int64))
        super().__init__(slots, np.column_stack(cols), data.view[pts] - self.first, 2)
        self.data, self.camera, self.name = data, camera, name
        self.blocks = data.instant[views]
        self.sigma = float(sigma_px)
        self._obj = np.zeros((views.size, self.longest, 3))
        self._obj[self.segment, self.position] = data.object_points[pts]
        self._uv = data.image_points[pts]

    def _pose_C(self, values: Mapping[str, F64]) -> F64:
        if self.is_ref:
            return np.eye(4)
        return values["C"][self.data.others.index(self.camera)]

    def _intrinsics(self, values: Mapping[str, F64]) -> Intrinsics | None:
        if not self.free:
            return self.data.intrinsics[self.camera]
        try:
            return self.data.intrinsics[self.camera].with_params(
                values[intrinsics_family(self.name)][0])
        except InputError:
            return None

    def _chain(self, C: F64, S: F64):
        """Per view (n, n_max, 3): ``R_S p``, ``d = q - t_C`` and ``p_cam``."""
        RS, tS = S[self.blocks, :3, :3], S[self.blocks, :3, 3]
        rs = self._obj @ np.swapaxes(RS, 1, 2)
        d = rs + tS[:, None] - C[:3, 3]
        return rs, d, d @ C[:3, :3]                                     # p_cam = R_C^T d

    def camera_points(self, values: Mapping[str, F64]) -> F64:
        """The camera's target points in its frame, (P_j, 3), metres."""
        return self._chain(self._pose_C(values), values["S"])[2][self.segment, self.position]

    def _linear(self, values: Mapping[str, F64], intr: Intrinsics):
        C = self._pose_C(values)
        rs, d, pc = self._chain(C, values["S"])
        seg, pos = self.segment, self.position
        uv, Jp, Jk = project_with_jacobian(pc[seg, pos], intr)
        r = (uv - self._uv) / self.sigma
        n_img, n = int(self.index.shape[0]), self.longest
        Jp_pad = np.zeros((n_img, n, 2, 3))
        Jp_pad[seg, pos] = Jp / self.sigma
        JpR = (Jp_pad.reshape(n_img, 2 * n, 3) @ C[:3, :3].T).reshape(n_img, n, 2, 3)
        parts = [] if self.is_ref else [cross_rows(JpR, d), -JpR]
        parts += [-cross_rows(JpR, rs), JpR]
        if self.free:
            Jk_pad = np.zeros((n_img, n, 2, Jk.shape[2]))
            Jk_pad[seg, pos] = Jk / self.sigma
            parts.append(Jk_pad)
        return r, np.concatenate(parts, axis=3)                          # (n_img, n, 2, c)

    def linearize(self, values: Mapping[str, F64]):
        intr = self._intrinsics(values)
        if intr is None:
            raise InputError(f"camera {self.name}: intrinsics outside the model's valid range")
        r, blocks = self._linear(values, intr)
        n_img, n, _, c = blocks.shape
        return r, blocks.reshape(n_img, 2 * n, c), self.pad(r)

    def evaluate(self, values: Mapping[str, F64], jacobians: bool):
        intr = self._intrinsics(values)
        if intr is None:
            return np.full((self.n_rows, 2), np.nan), None
        if jacobians:
            r, blocks = self._linear(values, intr)
            rows = blocks[self.segment, self.position]                   # (P_j, 2, c)
            sizes = ([] if self.is_ref else [6]) + [6] + ([rows.shape[2] - 6 * (
                1 if self.is_ref else 2)] if self.free else [])
            cuts = np.cumsum([0] + sizes)
            return r, [rows[:, :, a:b] for a, b in zip(cuts[:-1], cuts[1:])]
        pc = self.camera_points(values)
        return (project_points(pc, intr) - self._uv) / self.sigma, None
