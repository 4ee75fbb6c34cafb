"""Rigid transforms as 4x4 float64 arrays, batched over leading axes.

Conventions (docs/conventions.md, section 1): ``T_a_b`` maps coordinates of a point in
frame ``b`` into frame ``a`` (``p_a = T_a_b @ p_b``); products chain when the
inner names match, ``T_a_c = T_a_b @ T_b_c``.  Metres and radians inside.
Quaternions are converted here and nowhere else; the order is stated by every function
that takes one.  Quaternions and rotation vectors are converted with numpy, the same
operations in the same order as :class:`scipy.spatial.transform.Rotation` (the same bits for
quaternions; rotation vectors through the unit quaternion, as ``Rotation`` does): they are
on every calibration's path, and importing ``scipy.spatial`` costs about 0.1 CPU-s at
start-up, so ``Rotation`` is imported only by the functions that need it.

Synopsis
--------
>>> import numpy as np
>>> from multieye.core import geometry as g
>>> T_a_b = g.transform_from_rotvec(np.array([0.0, 0.0, np.pi / 2]), [1.0, 0.0, 0.0])
>>> T_b_a = g.inv(T_a_b)
>>> np.allclose(T_a_b @ T_b_a, np.eye(4))
True
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "RIGID_TOLERANCE",
    "rigidity",
    "is_rigid",
    "inv",
    "compose",
    "make_transform",
    "rotation_from_quat",
    "project_to_so3",
    "rotation_angle",
    "rotation_angle_between",
    "translation_distance",
    "transform_from_quat",
    "quat_from_transform",
    "transform_from_rotvec",
    "rotation_from_rotvec",
    "rotvec_from_transform",
    "ypr_from_rotation",
    "rpy_from_rotation",
    "rotation_from_rpy",
    "rotation_mean",
    "random_transforms",
    "skew",
    "det3",
]

F64 = NDArray[np.float64]


#: Largest ``|R^T R - I|`` entry and ``|det R - 1|`` accepted as a rotation: the one test of a
#: rigid transform, for every reader and record.
RIGID_TOLERANCE = 1e-6


def rigidity(T: ArrayLike) -> tuple[F64, F64, F64]:
    """How far each transform of ``T`` (shape (..., 4, 4)) is from rigid.

    Returns
    -------
    ortho : ndarray, shape (...)
        Largest entry of ``|R^T R - I|``.
    det : ndarray, shape (...)
        ``det R`` (1 for a rotation).
    last : ndarray, shape (...)
        Largest entry of ``|T[3] - (0, 0, 0, 1)|`` (exactly 0 for a rigid transform).
    """
    T = np.asarray(T, dtype=np.float64)
    R = T[..., :3, :3]
    ortho = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-2, -1))
    return ortho, np.linalg.det(R), np.abs(T[..., 3, :] - [0.0, 0.0, 0.0, 1.0]).max(axis=-1)


def is_rigid(T: ArrayLike) -> NDArray[np.bool_]:
    """Per transform of ``T`` (shape (..., 4, 4), finite): a rotation within
    :data:`RIGID_TOLERANCE` and the last row exactly ``(0, 0, 0, 1)``."""
    ortho, det, last = rigidity(T)
    return (ortho <= RIGID_TOLERANCE) & (np.abs(det - 1.0) <= RIGID_TOLERANCE) & (last == 0)


def inv(T: ArrayLike) -> F64:
    """Inverse of rigid transforms.

    Parameters
    ----------
    T : array_like, shape (..., 4, 4)
        ``T_a_b``.

    Returns
    -------
    ndarray, shape (..., 4, 4)
        ``T_b_a``, computed as ``[R^T, -R^T t]`` (exact for rigid input).
    """
    T = np.asarray(T, dtype=np.float64)
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    out = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, t)
    out[..., 3, 3] = 1.0
    return out


def compose(*Ts: ArrayLike) -> F64:
    """Product ``Ts[0] @ Ts[1] @ ...`` with broadcasting over batches."""
    if not Ts:
        return np.eye(4)
    out = np.asarray(Ts[0], dtype=np.float64)
    for T in Ts[1:]:
        out = out @ np.asarray(T, dtype=np.float64)
    return out


def make_transform(R: ArrayLike, t: ArrayLike) -> F64:
    """Assemble transforms from rotations ``(..., 3, 3)`` and translations ``(..., 3)``."""
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    shape = np.broadcast_shapes(R.shape[:-2], t.shape[:-1])
    out = np.zeros(shape + (4, 4))
    out[..., :3, :3] = R
    out[..., :3, 3] = t
    out[..., 3, 3] = 1.0
    return out


def project_to_so3(M: ArrayLike) -> F64:
    """Nearest rotation matrix in the Frobenius norm (SVD with the det fix).

    Parameters
    ----------
    M : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``U diag(1, 1, det(U V^T)) V^T`` for ``M = U S V^T``.
    """
    M = np.asarray(M, dtype=np.float64)
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    neg = det3(R) < 0
    if np.any(neg):
        U = U.copy()
        U[..., :, 2] *= np.where(neg, -1.0, 1.0)[..., None]
        R = U @ Vt
    return R


def det3(M: np.ndarray) -> np.ndarray:
    """Determinants of ``(..., 3, 3)``.

    LAPACK for a few matrices; the explicit cofactor formula for large batches, where it is
    several times cheaper than an LU factorisation per matrix.
    """
    if M.size < 9 * 64:
        return np.linalg.det(M)
    return (M[..., 0, 0] * (M[..., 1, 1] * M[..., 2, 2] - M[..., 1, 2] * M[..., 2, 1])
            - M[..., 0, 1] * (M[..., 1, 0] * M[..., 2, 2] - M[..., 1, 2] * M[..., 2, 0])
            + M[..., 0, 2] * (M[..., 1, 0] * M[..., 2, 1] - M[..., 1, 1] * M[..., 2, 0]))


def rotation_angle(R: ArrayLike) -> F64:
    """Angle in radians of rotation matrices ``(..., 3, 3)`` (robust near 0 and pi)."""
    R = np.asarray(R, dtype=np.float64)
    # atan2 of |sin| and cos is accurate at both ends, unlike arccos of the trace.
    c = (np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0
    w = np.stack([R[..., 2, 1] - R[..., 1, 2],
                  R[..., 0, 2] - R[..., 2, 0],
                  R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    s = np.linalg.norm(w, axis=-1) / 2.0
    return np.arctan2(s, c)


def rotation_angle_between(T1: ArrayLike, T2: ArrayLike) -> F64:
    """Angle in radians of ``R1^T R2`` for transforms or rotations (broadcasts)."""
    T1 = np.asarray(T1, dtype=np.float64)
    T2 = np.asarray(T2, dtype=np.float64)
    R1 = T1[..., :3, :3]
    R2 = T2[..., :3, :3]
    return rotation_angle(np.swapaxes(R1, -1, -2) @ R2)


def translation_distance(T1: ArrayLike, T2: ArrayLike) -> F64:
    """Euclidean distance between the translations of two transforms (metres)."""
    T1 = np.asarray(T1, dtype=np.float64)
    T2 = np.asarray(T2, dtype=np.float64)
    return np.linalg.norm(T1[..., :3, 3] - T2[..., :3, 3], axis=-1)


def transform_from_quat(q: ArrayLike, t: ArrayLike, *, scalar_first: bool = False) -> F64:
    """Transforms from unit quaternions and translations.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        ``(qx, qy, qz, qw)``, or ``(qw, qx, qy, qz)`` with ``scalar_first=True``.
        Normalised here; callers that must reject non-unit input check first.
    t : array_like, shape (..., 3)
        Translation, metres.
    """
    q = np.asarray(q, dtype=np.float64)
    if scalar_first:
        q = np.concatenate([q[..., 1:], q[..., :1]], axis=-1)
    shape = q.shape[:-1]
    return make_transform(rotation_from_quat(q.reshape(-1, 4)).reshape(shape + (3, 3)), t)


def rotation_from_quat(q: ArrayLike) -> F64:
    """Rotation matrices ``(n, 3, 3)`` of quaternions ``(n, 4)``, ``(qx, qy, qz, qw)``,
    normalised here.

    The same operations, in the same order, as SciPy's ``Rotation.from_quat(q).as_matrix()``
    (the same bits), without importing scipy.spatial (0.2-0.3 CPU-s): reading a motion
    capture file happens before the detection starts (issue 21).

    Raises
    ------
    ValueError
        A quaternion of norm zero or NaN (as SciPy does).
    """
    q = np.asarray(q, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):   # inf in, NaN out, without a warning
        x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
        norm = np.sqrt(x * x + y * y + z * z + w * w)
        if not np.all(norm > 0):
            raise ValueError("Found zero norm quaternions in `quat`.")
        x, y, z, w = x / norm, y / norm, z / norm, w / norm
        x2, y2, z2, w2 = x * x, y * y, z * z, w * w
        xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
        R = np.stack([x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw),
                      2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw),
                      2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2], axis=-1)
    return R.reshape(-1, 3, 3)


def quat_from_transform(T: ArrayLike, *, scalar_first: bool = False) -> F64:
    """Unit quaternions ``(..., 4)`` of transforms, ``(qx, qy, qz, qw)`` with ``qw >= 0``
    (where ``qw = 0``, the first non-zero of ``qx, qy, qz`` positive).

    SciPy's ``Rotation.from_matrix(R).as_quat(canonical=True)``, the same bits (Shepperd's
    method, :func:`_quat_of_matrix`), without importing scipy.spatial (about 0.1 CPU-s)."""
    T = np.asarray(T, dtype=np.float64)
    shape = T.shape[:-2]
    q = _quat_of_matrix(T[..., :3, :3].reshape(-1, 3, 3))
    half_turn = q[:, 3] == 0.0
    if np.any(half_turn):           # canonical as SciPy's: the first non-zero part positive
        v = q[half_turn, :3]
        first = v[np.arange(len(v)), np.argmax(v != 0.0, axis=1)]
        q[half_turn] = np.where(first[:, None] < 0.0, -q[half_turn], q[half_turn])
    q = q.reshape(shape + (4,))
    if scalar_first:
        q = np.concatenate([q[..., 3:], q[..., :3]], axis=-1)
    return q


def transform_from_rotvec(r: ArrayLike, t: ArrayLike) -> F64:
    """Transforms from rotation vectors ``(..., 3)`` (radians) and translations ``(..., 3)``."""
    return make_transform(rotation_from_rotvec(r), t)


def rotvec_from_transform(T: ArrayLike) -> F64:
    """Rotation vectors ``(..., 3)`` in radians of transforms or rotations."""
    T = np.asarray(T, dtype=np.float64)
    q = _quat_of_matrix(T[..., :3, :3])
    n = np.linalg.norm(q[..., :3], axis=-1)
    angle = 2.0 * np.arctan2(n, q[..., 3])
    small = angle <= 1e-3
    a2 = angle * angle
    # angle / sin(angle / 2), its series near 0 (the factor from the quaternion's vector part)
    scale = np.where(small, 2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0,
                     angle / np.sin(np.where(small, 1.0, angle) / 2.0))
    return scale[..., None] * q[..., :3]


def rotation_from_rotvec(r: ArrayLike) -> F64:
    """Rotation matrices ``(..., 3, 3)`` of rotation vectors ``(..., 3)`` (radians)."""
    r = np.asarray(r, dtype=np.float64)
    angle = np.linalg.norm(r, axis=-1)
    small = angle <= 1e-3
    a2 = angle * angle
    # sin(angle / 2) / angle, its series near 0
    scale = np.where(small, 0.5 - a2 / 48.0 + a2 * a2 / 3840.0,
                     np.sin(angle / 2.0) / np.where(small, 1.0, angle))
    x, y, z = np.moveaxis(scale[..., None] * r, -1, 0)
    w = np.cos(angle / 2.0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def _quat_of_matrix(R: F64) -> F64:
    """Unit quaternions ``(..., 4)``, ``(x, y, z, w)`` with ``w >= 0``, of matrices
    ``(..., 3, 3)`` (Shepperd's method: from the largest of the trace and the diagonal).  As
    ``Rotation.from_matrix``, a matrix that is not orthogonal (to 1e-12) stands for its
    nearest rotation (:func:`project_to_so3`)."""
    R = np.asarray(R, dtype=np.float64)
    off = np.abs(R @ np.swapaxes(R, -1, -2) - np.eye(3)).max(axis=(-2, -1))
    if np.any(off > 1e-12):
        R = np.where((off > 1e-12)[..., None, None], project_to_so3(R), R)
    d = np.stack([R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]], axis=-1)
    tr = d.sum(axis=-1)
    choice = np.argmax(np.concatenate([d, tr[..., None]], axis=-1), axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    for i in range(3):                         # the i-th diagonal entry is the largest
        j, k = (i + 1) % 3, (i + 2) % 3
        m = choice == i
        Rm = R[m]
        q[m, i] = 1 - tr[m] + 2 * Rm[:, i, i]
        q[m, j] = Rm[:, j, i] + Rm[:, i, j]
        q[m, k] = Rm[:, k, i] + Rm[:, i, k]
        q[m, 3] = Rm[:, k, j] - Rm[:, j, k]
    m = choice == 3                            # the trace is the largest
    Rm = R[m]
    q[m, 0] = Rm[:, 2, 1] - Rm[:, 1, 2]
    q[m, 1] = Rm[:, 0, 2] - Rm[:, 2, 0]
    q[m, 2] = Rm[:, 1, 0] - Rm[:, 0, 1]
    q[m, 3] = 1 + tr[m]
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., 3:] < 0, -q, q)


def rpy_from_rotation(R: ArrayLike) -> F64:
    """Roll, pitch, yaw in radians with ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (URDF's fixed-axis
    ``rpy``; the same angles as :func:`ypr_from_rotation`, in the other order).

    Accurate to rounding everywhere, gimbal lock included (pitch = +-90 degrees, a camera
    looking straight up or down): pitch comes from ``atan2(-R20, hypot(R00, R10))``, yaw from
    the first column, and roll from what is left once yaw and pitch are undone, so that an
    ill-determined yaw near the lock is compensated by roll instead of leaking into the
    rotation (at the lock only ``roll - yaw`` or ``roll + yaw`` is defined).  scipy's
    ``Rotation.as_euler`` sets one angle to zero near the lock, and its angles then give the
    rotation back only to about 2e-7.

    Parameters
    ----------
    R : array_like, shape (..., 3, 3) or (..., 4, 4)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    R = np.asarray(R, dtype=np.float64)[..., :3, :3]
    shape = R.shape[:-2]
    R = R.reshape(-1, 3, 3)
    pitch = np.arctan2(-R[:, 2, 0], np.hypot(R[:, 0, 0], R[:, 1, 0]))
    yaw = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    undone = np.swapaxes(_about(1, pitch), 1, 2) @ np.swapaxes(_about(2, yaw), 1, 2)
    M = undone @ R                              # = Rx(roll) up to rounding
    roll = np.arctan2(M[:, 2, 1], M[:, 1, 1])
    return np.column_stack([roll, pitch, yaw]).reshape(shape + (3,))


def rotation_from_rpy(rpy: ArrayLike) -> F64:
    """``R = Rz(yaw) Ry(pitch) Rx(roll)`` of roll, pitch, yaw in radians, shape (..., 3)
    (URDF's fixed-axis ``rpy``; inverse of :func:`rpy_from_rotation`).  Built from the
    three elementary rotations, so that right angles give exact zeros and ones (scipy's
    ``Rotation.from_euler`` goes through a quaternion and leaves 2e-16 there)."""
    rpy = np.asarray(rpy, dtype=np.float64)
    shape = rpy.shape[:-1]
    roll, pitch, yaw = rpy.reshape(-1, 3).T
    return (_about(2, yaw) @ _about(1, pitch) @ _about(0, roll)).reshape(shape + (3, 3))


def _about(axis: int, angle: F64) -> F64:
    """Rotations by ``angle`` (n,) radians about the x, y or z axis (0, 1, 2): (n, 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.zeros((len(angle), 3, 3))
    R[:, axis, axis] = 1.0
    R[:, i, i], R[:, i, j], R[:, j, i], R[:, j, j] = c, -s, s, c
    return R


def ypr_from_rotation(R: ArrayLike) -> F64:
    """Yaw, pitch, roll in radians, ``R = Rz(yaw) Ry(pitch) Rx(roll)``
    (:func:`rpy_from_rotation` in the other order).

    This is the convention of the paper's tx ty tz yaw pitch roll tables.

    Parameters
    ----------
    R : array_like, shape (..., 3, 3) or (..., 4, 4)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    return rpy_from_rotation(R)[..., ::-1] + 0.0     # + 0.0: no -0.0 in the tables


def rotation_mean(Rs: ArrayLike) -> F64:
    """Chordal L2 mean of rotations ``(n, 3, 3)``: projection of their sum onto SO(3)."""
    Rs = np.asarray(Rs, dtype=np.float64)
    return project_to_so3(Rs.sum(axis=0))


def random_transforms(rng: np.random.Generator, n: int | None = None, *,
                      translation_scale: float = 1.0) -> F64:
    """Uniformly random rotations with Gaussian translations of the given scale (metres)."""
    k = 1 if n is None else n
    from scipy.spatial.transform import Rotation  # noqa: PLC0415 (heavy: scipy.spatial, about 0.1 CPU-s at start-up)
    R = Rotation.random(k, random_state=rng).as_matrix()
    t = rng.normal(scale=translation_scale, size=(k, 3))
    T = make_transform(R, t)
    return T[0] if n is None else T


def skew(v: ArrayLike) -> F64:
    """Cross-product matrices ``(..., 3, 3)`` of vectors ``(..., 3)``."""
    v = np.asarray(v, dtype=np.float64)
    z = np.zeros(v.shape[:-1])
    return np.stack([
        np.stack([z, -v[..., 2], v[..., 1]], axis=-1),
        np.stack([v[..., 2], z, -v[..., 0]], axis=-1),
        np.stack([-v[..., 1], v[..., 0], z], axis=-1),
    ], axis=-2)
