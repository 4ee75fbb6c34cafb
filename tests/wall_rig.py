"""An array-level rig of cameras facing different ways, moved in front of boards on the walls.

Test helper (issue 34): no images, the target points' true pixels (and Gaussian noise).  The
room's frame ``room`` has z up; board ``b`` hangs on the wall in direction ``wall_deg[b]``
(degrees from the room's x axis) at ``wall_m`` from the room's centre, facing it.  The rig's
frame is camera 0's (x right, y down, z forward); camera ``j`` looks ``90 j`` degrees to the
right of camera 0, a few centimetres and degrees off the nominal.  Each instant the rig has a
pose ``T_room_rig``: a heading (yaw about the room's vertical), with ``motion="6dof"`` also a
tilt (pitch and roll up to ``tilt_deg``) and a height, with ``motion="planar"`` neither.  A
camera sees a board when every point projects ``border_px`` inside its image, from the
board's front, within ``max_obliquity_deg`` of its normal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from multieye.core import geometry as g
from multieye.core.lens import project_points
from multieye.sim.dataset import default_intrinsics

F64 = np.ndarray


@dataclass(frozen=True)
class WallRig:
    """The truth and the views.

    T_ref_cam (m, 4, 4); T_room_board (nb, 4, 4); T_room_rig (K, 4, 4); views: camera,
    instant, board (each (n_views,) int), camera by camera; instants numbered 0..K-1 each
    with a view.
    """

    T_ref_cam: F64
    T_room_board: F64
    T_room_rig: F64
    intrinsics: tuple
    object_points: F64
    camera: F64
    instant: F64
    board: F64

    @property
    def T_world_board(self) -> F64:
        """Boards in the first board's frame (the estimation's gauge)."""
        return g.inv(self.T_room_board[0]) @ self.T_room_board

    @property
    def T_world_rig(self) -> F64:
        return g.inv(self.T_room_board[0]) @ self.T_room_rig

    def T_cam_board(self) -> F64:
        """The true pose of the board in the camera of every view, (n_views, 4, 4)."""
        return (g.inv(self.T_ref_cam[self.camera]) @ g.inv(self.T_room_rig[self.instant])
                @ self.T_room_board[self.board])

    def pixels(self, sigma_px: float = 0.0, rng=None) -> list[F64]:
        """Per view the pixels of every target point, with Gaussian noise."""
        rng = rng or np.random.default_rng(0)
        out = []
        for v, T in enumerate(self.T_cam_board()):
            uv = project_points(self.object_points @ T[:3, :3].T + T[:3, 3],
                                self.intrinsics[self.camera[v]])
            out.append(uv + rng.normal(scale=sigma_px, size=uv.shape) if sigma_px else uv)
        return out

    def views(self, sigma_px: float = 0.0, rng=None) -> dict:
        """``{cam<j>: [(object_points, pixels, instant, board), ...]}``, cameras in order."""
        uv = self.pixels(sigma_px, rng)
        out = {f"cam{j}": [] for j in range(len(self.T_ref_cam))}
        for v in range(len(self.camera)):
            out[f"cam{self.camera[v]}"].append((self.object_points, uv[v],
                                                int(self.instant[v]), int(self.board[v])))
        return out


def _board_pose(direction_deg: float, distance: float, height: float) -> F64:
    a = np.radians(direction_deg)
    z = np.array([np.cos(a), np.sin(a), 0.0])            # into the wall
    y = np.array([0.0, 0.0, -1.0])
    R = np.column_stack([np.cross(y, z), y, z])
    return g.make_transform(R, distance * z + [0.0, 0.0, height])


def _rig_rotation(yaw: float, pitch: float = 0.0, roll: float = 0.0) -> F64:
    """R_room_rig: the rig's z (camera 0's optical axis) at heading ``yaw``, y down; then
    turned about its own x (pitch) and z (roll)."""
    z = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    y = np.array([0.0, 0.0, -1.0])
    R0 = np.column_stack([np.cross(y, z), y, z])
    return R0 @ g.rotation_from_rotvec([pitch, 0.0, 0.0]) @ g.rotation_from_rotvec(
        [0.0, 0.0, roll])


def _rig(rng, m: int) -> F64:
    out = np.tile(np.eye(4), (m, 1, 1))
    for j in range(1, m):
        yaw = np.radians(90.0 * j) + rng.normal(scale=0.05)
        R = g.rotation_from_rotvec([0.0, yaw, 0.0]) @ g.rotation_from_rotvec(
            rng.normal(scale=0.03, size=3))
        out[j] = g.make_transform(R, 0.12 * R[:, 2] + rng.normal(scale=0.02, size=3))
    return out


def _sees(T_cam_board, intr, pts, border, max_obliquity) -> bool:
    P = pts @ T_cam_board[:3, :3].T + T_cam_board[:3, 3]
    if np.any(P[:, 2] <= 0.1):
        return False
    normal = T_cam_board[:3, 2]
    centre = P.mean(axis=0)
    if normal @ centre <= 0 or normal @ centre / np.linalg.norm(centre) < np.cos(max_obliquity):
        return False
    uv = project_points(P, intr)
    return bool(np.all((uv >= border) & (uv <= np.array([intr.width, intr.height]) - border)))


def wall_rig(seed: int, *, n_instants: int = 40, m: int = 4, motion: str = "6dof",
             wall_deg=(0.0, 90.0, 180.0), yaw_deg=(0.0, 360.0), tilt_deg: float = 20.0,
             wall_m: float = 1.8) -> WallRig:
    """A rig and its views (module docstring); ``yaw_deg`` the range of headings."""
    rng = np.random.default_rng(seed)
    intr = tuple(default_intrinsics(m, 800, 600, rng=rng))
    T_ref_cam = _rig(rng, m)
    boards = np.stack([_board_pose(w, wall_m, rng.uniform(-0.2, 0.2)) for w in wall_deg])
    gx, gy = np.meshgrid(np.arange(9) * 0.08, np.arange(6) * 0.08)
    pts = np.column_stack([gx.ravel() - 0.32, gy.ravel() - 0.2, np.zeros(gx.size)])
    poses, cams, insts, bds = [], [], [], []
    for _ in range(50 * n_instants):
        if len(poses) == n_instants:
            break
        yaw = np.radians(rng.uniform(*yaw_deg))
        if motion == "6dof":
            R = _rig_rotation(yaw, *np.radians(rng.uniform(-tilt_deg, tilt_deg, 2)))
            t = rng.uniform(-1, 1, 3) * [0.35, 0.35, 0.25]
        else:
            R = _rig_rotation(yaw)
            t = np.append(rng.uniform(-1, 1, 2) * 0.35, 0.0)
        T_room_rig = g.make_transform(R, t)
        seen = [(j, b) for j in range(m) for b in range(len(boards))
                if _sees(g.inv(T_room_rig @ T_ref_cam[j]) @ boards[b], intr[j], pts, 10.0,
                         np.radians(60.0))]
        if not seen:
            continue
        for j, b in seen:
            cams.append(j)
            insts.append(len(poses))
            bds.append(b)
        poses.append(T_room_rig)
    order = np.argsort(cams, kind="stable")          # views camera by camera, as MotionViews
    return WallRig(T_ref_cam, boards, np.stack(poses), intr, pts, np.asarray(cams)[order],
                   np.asarray(insts)[order], np.asarray(bds)[order])
