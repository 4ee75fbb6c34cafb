"""Informative image selection: which images of a long recording to calibrate from.

A 30 Hz recording of 10 cameras for 3 minutes holds 54,000 images, most of them near
copies of their neighbours.  A fixed stride keeps the dull stretches as often as the rich
ones; here images are kept by what they add to the unknowns of the hand-eye problem
``A_i X = Y B_i`` (docs/conventions.md, section 2), greedily (the information's log
determinant is submodular, so greedy choice is within 1 - 1/e of the best set; a stochastic
greedy search keeps it fast).

Two passes:

1. **Before decoding** (:func:`select_before_decoding`), from the image stamps and the
   motion-capture poses paired with them: an image without a motion-capture sample within
   the tolerance cannot be used and is not decoded; of the others, each camera keeps up to
   ``budget`` images by the information they add (:func:`hand_eye_jacobians`).  Images of
   several cameras with the same stamp (one instant, which the refinement gives one pose)
   are kept or left out together.
2. **After detection** (:func:`select_after_detection`): the same information, plus, for a
   camera whose lens is estimated, the lens's own information (:func:`lens_information`,
   from the detected pixels with each image's pose as a nuisance) and the coverage of the
   image (:func:`grid_cells`): images that alone cover a cell of the image are kept first.

Information proxy
-----------------
Linearised about the truth, the loop of image ``i`` (rotation and translation, in the
world frame) moves with the unknowns as::

    r_rot   = -dtheta_L + R_i dtheta_R
    r_trans = [p_i]x dtheta_L - drho_L + R_i drho_R

where ``L`` is the unknown on the left of the loop (``X = T_world_cam`` eye-to-base, ``Y =
T_world_target`` eye-on-hand), ``R`` the one on the right of the motion-capture pose
(``Y = T_marker_target``, ``X = T_body_cam``), ``R_i`` the motion-capture rotation and
``p_i`` its position (the target, or the camera, is near the marker or the body; the
rotation of ``R`` and a shift of the world frame are changes of variables with unit
determinant, so the log determinant needs neither).  Rows are whitened by a rotation and a
translation noise (:data:`SIGMA_ROT_RAD`, :data:`SIGMA_TRANS_M`).  The proxy needs no
decoded image, and it is the information of the loop residuals only: how well the target
is seen in each image is not in it (the second pass adds the lens's part).

Synopsis
--------
>>> import numpy as np
>>> from multieye.core import geometry as g
>>> T = g.random_transforms(np.random.default_rng(0), 500)
>>> sel = select_images({"cam0": hand_eye_jacobians(T)}, {"cam0": np.arange(500.0)}, budget=50)
>>> int(sel["cam0"].keep.sum())
50
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core.errors import InputError

__all__ = ["Selection", "DEFAULT_BUDGET", "SIGMA_ROT_RAD", "SIGMA_TRANS_M", "KEPT", "LEFT_OUT",
           "hand_eye_jacobians", "lens_information", "grid_cells", "select_images",
           "select_before_decoding", "select_after_detection", "stride_selection"]

F64 = NDArray[np.float64]

#: Images per camera kept when a camera has more (docs/recordings.md, section 1).
DEFAULT_BUDGET = 300
#: Rotation and translation noise that weight the rows of the information proxy (radians,
#: metres): a PnP pose of a board at about 1 m.
SIGMA_ROT_RAD = 0.002
SIGMA_TRANS_M = 0.001
#: Prior information on every unknown of the proxy (a tiny ridge, so the first log
#: determinants exist).
_RIDGE = 1e-6
#: How the reasons start.
KEPT = "selected"
LEFT_OUT = "not selected"


@dataclass(frozen=True)
class Selection:
    """Which of one camera's images a selection keeps, and why.

    Attributes
    ----------
    keep : ndarray of bool, shape (n,)
        Per image (in the order given).
    reasons : tuple of str
        Per image: why it is kept (starts with :data:`KEPT`) or left out.
    budget : int
        Images per camera asked for (a camera keeps a few more when instants shared with
        other cameras must stay whole).
    """

    keep: NDArray[np.bool_]
    reasons: tuple[str, ...]
    budget: int

    @property
    def n_seen(self) -> int:
        return int(self.keep.size)

    @property
    def n_kept(self) -> int:
        return int(self.keep.sum())


def _skew(v: F64) -> F64:
    """Cross-product matrices of ``v`` (n, 3) -> (n, 3, 3)."""
    z = np.zeros(len(v))
    return np.stack([np.stack([z, -v[:, 2], v[:, 1]], -1),
                     np.stack([v[:, 2], z, -v[:, 0]], -1),
                     np.stack([-v[:, 1], v[:, 0], z], -1)], axis=1)


def hand_eye_jacobians(T_world_mocap: F64, *, sigma_rot_rad: float = SIGMA_ROT_RAD,
                       sigma_trans_m: float = SIGMA_TRANS_M) -> F64:
    """Whitened Jacobians of each image's loop residual (module docstring).

    Parameters
    ----------
    T_world_mocap : ndarray, shape (n, 4, 4)
        The motion-capture pose at each image (``T_world_marker`` or ``T_world_body``),
        metres.
    sigma_rot_rad, sigma_trans_m : float
        Noise of the loop's rotation (radians) and translation (metres).

    Returns
    -------
    ndarray, shape (n, 6, 12)
        Rows: rotation then translation residual; columns: rotation and translation of the
        left unknown, then of the right one.
    """
    T = np.asarray(T_world_mocap, dtype=np.float64)
    if T.ndim != 3 or T.shape[1:] != (4, 4) or not np.all(np.isfinite(T)):
        raise InputError(f"T_world_mocap must be finite poses of shape (n, 4, 4), got {T.shape}")
    if not (sigma_rot_rad > 0 and sigma_trans_m > 0):
        raise InputError("the noise levels of the information proxy must be positive")
    n = len(T)
    R = T[:, :3, :3]
    p = T[:, :3, 3] - (T[:, :3, 3].mean(axis=0) if n else 0.0)   # a shift of the world frame
    J = np.zeros((n, 6, 12))
    J[:, :3, 0:3] = -np.eye(3) / sigma_rot_rad
    J[:, :3, 6:9] = R / sigma_rot_rad
    J[:, 3:, 0:3] = _skew(p) / sigma_trans_m
    J[:, 3:, 3:6] = -np.eye(3) / sigma_trans_m
    J[:, 3:, 9:12] = R / sigma_trans_m
    return J


def lens_information(J_lens: F64, J_pose: F64) -> F64:
    """The information one view gives its lens, its pose a nuisance (Schur complement).

    Parameters
    ----------
    J_lens : ndarray, shape (2n, k)
        Whitened Jacobian of the view's pixels with respect to the lens parameters.
    J_pose : ndarray, shape (2n, 6)
        Whitened Jacobian with respect to the view's pose.

    Returns
    -------
    ndarray, shape (k, k)
        ``J_lens^T J_lens - J_lens^T J_pose (J_pose^T J_pose)^+ J_pose^T J_lens``.
    """
    a = J_lens.T @ J_lens
    b = J_lens.T @ J_pose
    return a - b @ np.linalg.pinv(J_pose.T @ J_pose) @ b.T


def grid_cells(image_points: Sequence[F64], width: int, height: int, *, cols: int = 8,
               rows: int = 6) -> list[frozenset[int]]:
    """The cells of a ``cols`` x ``rows`` grid over the image that each view's points fall in.

    Parameters
    ----------
    image_points : sequence of ndarray, shape (n_i, 2)
        Pixels of each view.
    width, height : int
        Image size, pixels.

    Returns
    -------
    list of frozenset of int
        Cell numbers ``row * cols + col`` per view.
    """
    out = []
    for uv in image_points:
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        uv = uv[np.all(np.isfinite(uv), axis=1)]
        c = np.clip((uv[:, 0] + 0.5) * cols // width, 0, cols - 1).astype(int)
        r = np.clip((uv[:, 1] + 0.5) * rows // height, 0, rows - 1).astype(int)
        out.append(frozenset((r * cols + c).tolist()))
    return out


def _instants(stamps: Mapping[str, F64], sync_tolerance: float) -> list[list[tuple[str, int]]]:
    """Groups of ``(camera, image index)``: images of different cameras with stamps within
    ``sync_tolerance`` (0: bitwise equal) form one instant; every other image is alone.
    Images with a non-finite stamp are alone."""
    items = [(float(t), name, i) for name, ts in stamps.items() for i, t in enumerate(ts)]
    items.sort(key=lambda x: (not np.isfinite(x[0]), x[0]))
    groups: list[list[tuple[str, int]]] = []
    last = None
    for t, name, i in items:
        if (last is not None and np.isfinite(t) and t - last <= sync_tolerance
                and name not in {c for c, _ in groups[-1]}):
            groups[-1].append((name, i))
        else:
            groups.append([(name, i)])
            last = t if np.isfinite(t) else None
    return groups


@dataclass
class _CameraState:
    info: F64                  # (k, k) information so far
    cov: F64                   # its inverse
    kept: int = 0

    def gains(self, J: F64) -> F64:
        """log det of the information after adding each ``J[p]`` (r, k) alone, minus before."""
        S = np.eye(J.shape[1]) + J @ self.cov @ np.swapaxes(J, 1, 2)
        return np.linalg.slogdet(S)[1]

    def add(self, J: F64) -> None:
        self.info = self.info + J.T @ J
        self.cov = np.linalg.inv(self.info)


#: The stochastic greedy search's tolerance (its expected shortfall from the greedy
#: guarantee), and the seed of its samples.
_EPSILON = 0.01
_SEED = 20221


def select_images(jacobians: Mapping[str, F64], stamps: Mapping[str, F64], budget: int, *,
                  sync_tolerance: float = 0.0, first: Mapping[str, NDArray[np.bool_]] | None = None,
                  first_reason: str = "covers a part of the image no other kept image covers"
                  ) -> dict[str, Selection]:
    """Greedy selection of the images that add most information, per camera, instants whole.

    Parameters
    ----------
    jacobians : mapping of camera name to ndarray, shape (n_j, r, k)
        Whitened Jacobian of each image's residuals (:func:`hand_eye_jacobians`; ``r`` rows,
        ``k`` unknowns of that camera).
    stamps : mapping of camera name to ndarray, shape (n_j,)
        Image stamps, seconds; images of different cameras within ``sync_tolerance`` are one
        instant and are kept or left out together.
    budget : int
        Images each camera keeps at most (more only to keep an instant whole); a camera with
        no more than ``budget`` images keeps them all.
    sync_tolerance : float
        Seconds; 0 groups bitwise-equal stamps only.
    first : mapping of camera name to ndarray of bool, shape (n_j,), optional
        Images kept before the greedy search starts (within the budget), with reason
        ``first_reason``.

    Returns
    -------
    dict of str to Selection
    """
    if int(budget) != budget or budget < 1:
        raise InputError(f"the image budget must be a whole number >= 1, got {budget!r}")
    for name in jacobians:
        if len(jacobians[name]) != len(stamps[name]):
            raise InputError(f"camera {name}: {len(jacobians[name])} Jacobians for "
                             f"{len(stamps[name])} stamps")
    greedy = _Greedy(jacobians, {n: np.asarray(stamps[n], dtype=np.float64) for n in jacobians},
                     int(budget), sync_tolerance)
    greedy.search(greedy.seed(first, first_reason))
    return greedy.selections()


class _Greedy:
    """The greedy search of :func:`select_images`: per camera the information so far,
    the images kept and why; instants (groups of ``(camera, image)``) kept whole."""

    def __init__(self, jacobians, stamps, budget: int, sync_tolerance: float):
        self.jac, self.budget = jacobians, budget
        self.groups = _instants(stamps, sync_tolerance)
        self.keep = {n: np.zeros(len(stamps[n]), dtype=bool) for n in jacobians}
        self.reasons = {n: [""] * len(stamps[n]) for n in jacobians}
        self.state = {}
        for n in jacobians:
            k = jacobians[n].shape[-1] if len(jacobians[n]) else 1
            self.state[n] = _CameraState(info=_RIDGE * np.eye(k), cov=np.eye(k) / _RIDGE)
        self.small = {n for n in jacobians if len(stamps[n]) <= budget}

    def is_open(self, name: str) -> bool:
        return name not in self.small and self.state[name].kept < self.budget

    def accept(self, group, why: str) -> None:
        for name, i in group:
            others = sorted({c for c, _ in group if c != name})
            self.keep[name][i] = True
            self.reasons[name][i] = why + (f" (instant shared with {', '.join(others)})"
                                           if others else "")
        for name in {c for c, _ in group}:
            rows = [i for c, i in group if c == name]
            self.state[name].add(self.jac[name][rows].reshape(-1, self.jac[name].shape[-1]))
            self.state[name].kept += len(rows)

    def gains(self, gids: list[int]) -> F64:
        """Each group's gain (a group holds at most one image per camera), batched by camera."""
        out = np.zeros(len(gids))
        by_cam: dict[str, tuple[list[int], list[int]]] = {}
        for k, gi in enumerate(gids):
            for name, i in self.groups[gi]:
                if self.is_open(name):
                    slots, rows = by_cam.setdefault(name, ([], []))
                    slots.append(k)
                    rows.append(i)
        for name, (slots, rows) in by_cam.items():
            np.add.at(out, slots, self.state[name].gains(self.jac[name][rows]))
        return out

    def seed(self, first, first_reason: str) -> list[int]:
        """Keep what is kept whatever happens (cameras at or under the budget, with their
        instants; the ``first`` images); the other groups' numbers."""
        pending = []
        for gi, group in enumerate(self.groups):
            if any(c in self.small for c, _ in group):
                self.accept(group, f"{KEPT}: the camera has no more than {self.budget} images")
            elif (first is not None and any(first.get(c, np.zeros(0, bool))[i] for c, i in group)
                  and any(self.is_open(c) for c, _ in group)):
                self.accept(group, f"{KEPT}: {first_reason}")
            else:
                pending.append(gi)
        return pending

    def components(self, pending: list[int]) -> list[list[int]]:
        """``pending`` split by the cameras their instants link (cameras that share no
        instant are chosen apart: one camera's choice does not change another's gains)."""
        parent: dict[str, str] = {}

        def root(c: str) -> str:
            while parent.setdefault(c, c) != c:
                c = parent[c]
            return c

        for gi in pending:
            cams = [root(c) for c, _ in self.groups[gi]]
            for c in cams[1:]:
                parent[c] = cams[0]
        out: dict[str, list[int]] = {}
        for gi in pending:
            out.setdefault(root(self.groups[gi][0][0]), []).append(gi)
        return list(out.values())

    def search(self, pending: list[int]) -> None:
        """Stochastic greedy (Mirzasoleiman et al., "Lazier than lazy greedy", AAAI 2015),
        per set of cameras linked by instants: each choice is the best of a random sample of
        ``n / k * ln(1 / EPSILON)`` candidates (``n`` candidates, ``k`` choices to make),
        which is within ``EPSILON`` of the greedy guarantee in expectation at a fraction of
        its cost; the whole of them when the sample would hold every candidate.  Seeded: a
        rerun chooses the same images."""
        self.rank = 0
        rng = np.random.default_rng(_SEED)
        for part in self.components(pending):
            self._search(np.array(part, dtype=np.int64), rng)

    def _search(self, left: NDArray[np.int64], rng: np.random.Generator) -> None:
        cameras = {c for gi in left for c, _ in self.groups[gi]}
        opened = sum(self.is_open(c) for c in cameras)
        while len(left) and opened:
            k = sum(self.budget - self.state[c].kept for c in cameras if self.is_open(c))
            size = int(np.ceil(len(left) / max(k, 1) * np.log(1.0 / _EPSILON)))
            at = (np.arange(len(left)) if size >= len(left)
                  else rng.choice(len(left), size, replace=False))
            fresh = self.gains(left[at].tolist())
            best = int(at[int(np.argmax(fresh))])
            self.rank += 1
            self.accept(self.groups[left[best]], f"{KEPT}: informative (choice {self.rank}, "
                        f"adds {float(fresh.max()):.2g} nats)")
            left = np.delete(left, best)
            now = sum(self.is_open(c) for c in cameras)
            if now < opened:            # a camera is full: its images are no candidates
                left = np.array([gi for gi in left
                                 if any(self.is_open(c) for c, _ in self.groups[gi])],
                                dtype=np.int64)
                opened = now

    def selections(self) -> dict[str, Selection]:
        out = {}
        for n, keep in self.keep.items():
            for i in np.flatnonzero(~keep):
                self.reasons[n][i] = (f"{LEFT_OUT}: adds little beyond the {self.budget} "
                                      "images kept of this camera")
            out[n] = Selection(keep=keep, reasons=tuple(self.reasons[n]), budget=self.budget)
        return out


def select_before_decoding(stamps: Mapping[str, F64], paired: Mapping[str, NDArray[np.int_]],
                           T_world_mocap: Mapping[str, F64], budget: int, *,
                           unpaired_reason: Mapping[str, str] | None = None,
                           sync_tolerance: float = 0.0, sigma_rot_rad: float = SIGMA_ROT_RAD,
                           sigma_trans_m: float = SIGMA_TRANS_M) -> dict[str, Selection]:
    """Choose the images to decode, from their stamps and motion-capture poses alone.

    Parameters
    ----------
    stamps : mapping of camera name to ndarray, shape (n_j,)
        Every listed image's stamp, camera clock, seconds.
    paired : mapping of camera name to ndarray of int, shape (p_j,)
        Indices (into ``stamps[name]``) of the images with a motion-capture pose within the
        tolerance; the others are left out (nothing decoded that cannot be used).
    T_world_mocap : mapping of camera name to ndarray, shape (p_j, 4, 4)
        The motion-capture pose of each paired image.
    budget : int
        Images kept per camera (:func:`select_images`).
    unpaired_reason : mapping of camera name to str, optional
        Reason given to the images without a pose (default "no motion capture").

    Returns
    -------
    dict of str to Selection
        Over every listed image of each camera.
    """
    jac = {n: hand_eye_jacobians(np.asarray(T_world_mocap[n]).reshape(-1, 4, 4),
                                 sigma_rot_rad=sigma_rot_rad, sigma_trans_m=sigma_trans_m)
           for n in stamps}
    sub = {n: np.asarray(stamps[n], dtype=np.float64)[np.asarray(paired[n], dtype=int)]
           for n in stamps}
    chosen = select_images(jac, sub, budget, sync_tolerance=sync_tolerance)
    out = {}
    for n in stamps:
        keep = np.zeros(len(stamps[n]), dtype=bool)
        why = [(unpaired_reason or {}).get(n, "no motion capture")] * len(stamps[n])
        idx = np.asarray(paired[n], dtype=int)
        keep[idx] = chosen[n].keep
        for k, i in enumerate(idx):
            why[i] = chosen[n].reasons[k]
        out[n] = Selection(keep=keep, reasons=tuple(why), budget=chosen[n].budget)
    return out


def select_after_detection(stamps: Mapping[str, F64], T_world_mocap: Mapping[str, F64],
                           budget: int, *, cells: Mapping[str, Sequence[frozenset]] | None = None,
                           lens: Mapping[str, F64] | None = None, sync_tolerance: float = 0.0,
                           sigma_rot_rad: float = SIGMA_ROT_RAD,
                           sigma_trans_m: float = SIGMA_TRANS_M) -> dict[str, Selection]:
    """Choose among the images in which the target was found.

    Parameters
    ----------
    stamps, T_world_mocap : mapping of camera name to ndarray
        Per detected and paired image: stamp (seconds) and motion-capture pose.
    budget : int
    cells : mapping of camera name to sequence of frozenset, optional
        Per image, the grid cells its points cover (:func:`grid_cells`); given for a camera
        whose lens is estimated: the fewest images that together cover every cell any image
        covers are kept first.
    lens : mapping of camera name to ndarray, shape (n_j, k, k), optional
        Per image, the information it gives the camera's lens (:func:`lens_information`),
        added to the hand-eye information (its square root joins the image's rows).

    Returns
    -------
    dict of str to Selection
    """
    jac = {}
    for n in stamps:
        J = hand_eye_jacobians(np.asarray(T_world_mocap[n]).reshape(-1, 4, 4),
                               sigma_rot_rad=sigma_rot_rad, sigma_trans_m=sigma_trans_m)
        if lens is not None and n in lens and len(J):
            L = np.asarray(lens[n], dtype=np.float64)
            k = L.shape[-1]
            w, V = np.linalg.eigh(L)                        # L = V diag(w) V^T
            root = np.sqrt(np.clip(w, 0, None))[:, :, None] * np.swapaxes(V, 1, 2)
            top = np.concatenate([J, np.zeros((len(J), 6, k))], axis=2)
            bottom = np.concatenate([np.zeros((len(J), k, 12)), root], axis=2)
            J = np.concatenate([top, bottom], axis=1)       # (n, 6 + k, 12 + k)
        jac[n] = J
    first = None
    if cells is not None:
        first = {n: _covering(list(cells[n]), budget // 3) for n in cells}
    return select_images(jac, {n: np.asarray(stamps[n], dtype=np.float64) for n in stamps},
                         budget, sync_tolerance=sync_tolerance, first=first)


def _covering(cells: list[frozenset], limit: int) -> NDArray[np.bool_]:
    """Greedy set cover: at most ``limit`` views that together cover the cells of all."""
    keep = np.zeros(len(cells), dtype=bool)
    left = frozenset().union(*cells) if cells else frozenset()
    while left and keep.sum() < limit:
        best = max(range(len(cells)), key=lambda i: len(cells[i] & left))
        if not cells[best] & left:
            break
        keep[best] = True
        left = left - cells[best]
    return keep


def stride_selection(n: int, count: int) -> NDArray[np.bool_]:
    """Every ``n / count``-th image (evenly spaced indices): the fixed stride that
    :func:`select_images` is compared with."""
    keep = np.zeros(n, dtype=bool)
    keep[np.unique(np.linspace(0, n - 1, min(count, n)).round().astype(int))] = True
    return keep
