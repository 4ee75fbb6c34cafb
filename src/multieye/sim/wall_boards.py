"""A rig without motion capture moved in front of boards on the walls of a room.

The rig most users have: a vehicle or robot with cameras facing different ways (here
``n_cameras`` cameras ``360 / n_cameras`` degrees apart about the vertical, none of them
overlapping), no motion capture, moved rigidly in a room whose walls hold several boards
that stand still.  The reference camera's own board poses then give the rig's motion,
which plays the motion capture's part in ``A_i^j X^j = Y B_i^j``.

Frames (docs/conventions.md): ``world`` is the room, x east, y north, z up, origin on the
floor at the room's centre; ``body`` the rig's gravity-aligned frame (x forward of camera
0, z up) that the motion moves; ``ref`` the reference camera (camera 0); ``cam`` a camera
(x right, y down, z along the optical axis); each board's frame is its canonical target
frame (:mod:`multieye.imaging.targets`).  Every instant ``i`` has one rig pose
``T_world_ref[i]``; board ``k`` stands still at ``T_world_board[k]``.

Variants (:class:`WallSpec`): ``boards="charuco"`` (default, three ChArUco boards of one
dictionary with disjoint id ranges on the north, west and south walls; the rig turns
freely, so each camera sees several boards over the recording and some images show two; no
point is seen by two cameras, but a wide board may show its two ends to two neighbouring
cameras at one instant),
``boards="chessboard"`` (one chessboard per camera on the wall it faces; the rig turns
only ``yaw_range_deg`` either way, so each board is seen by one known camera: rig.yaml's
``cameras:`` of a target); ``motion="6dof"`` (turns about every axis, moves in 3-D) or
``motion="planar"`` (a vehicle driven on the floor: rotation about the vertical only, no
height change).

:func:`simulate_walls` gives the geometry and the exact pixels of every view (no images,
fast: for tests of the estimation); :func:`noisy_views` adds pixel noise.  The rendered
dataset is :func:`multieye.sim.wall_dataset.render_wall_dataset`.

Synopsis
--------
>>> import numpy as np
>>> from multieye.sim.wall_boards import WallSpec, simulate_walls
>>> sc = simulate_walls(np.random.default_rng(0), WallSpec(n_instants=12))
>>> sc.T_ref_cam.shape, sc.T_world_ref.shape, sc.T_world_board.shape
((4, 4, 4), (12, 4, 4), (3, 4, 4))
>>> sorted({v.target for v in sc.views})
['north', 'south', 'west']
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from multieye.core import geometry as g
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens import project_points
from multieye.imaging.targets import Target, target_from_spec

__all__ = ["WallSpec", "WallView", "WallScenario", "simulate_walls", "noisy_views",
           "wall_targets", "wall_intrinsics", "WALL_DIRECTIONS"]

F64 = NDArray[np.float64]

#: Wall name -> unit vector from the room's centre towards the wall (world frame).
WALL_DIRECTIONS = {"north": (0.0, 1.0, 0.0), "west": (-1.0, 0.0, 0.0),
                   "south": (0.0, -1.0, 0.0), "east": (1.0, 0.0, 0.0)}


@dataclass(frozen=True)
class WallSpec:
    """What to simulate.

    Attributes
    ----------
    n_cameras : int
        Cameras ``360 / n_cameras`` degrees apart about the vertical, camera 0 facing north
        when the rig's yaw is 0, the others turning west (counter-clockwise seen from above).
    n_instants : int
        Rig poses (instants).
    boards : {"charuco", "chessboard"}
        Three 6 x 9 ChArUco boards of 0.16 m squares (north, west, south walls; ids 0-26,
        32-58, 64-90 of DICT_4X4_100), or one 6 x 9 chessboard of 0.1 m squares per camera
        on the wall it faces at yaw 0.
    motion : {"6dof", "planar"}
        6-DoF motion, or driven on the floor (yaw only, constant height).
    room_half_m : float
        From the room's centre to each wall, metres.
    board_height_m : float
        Height of the boards' centres (and of the rig on average), metres.
    travel_m : float
        Half-range of the rig's horizontal position about the centre, metres.
    yaw_range_deg : float or None
        Half-range of the rig's yaw about 0; None: it turns freely (spread evenly over the
        circle) with ChArUco boards, 20 degrees with chessboards (each seen by one camera).
    tilt_deg : float
        ``6dof`` only: half-range of roll and pitch, degrees (and of the height change,
        ``travel_m / 3``).
    width, height : int
        Image size, pixels.
    hfov_deg : float
        Horizontal field of view of each camera (pinhole, slight radial distortion); below
        90 degrees less the roll, so that neighbouring cameras do not overlap.
    max_obliquity_deg : float
        A view counts only when the ray to the board's centre is within this angle of the
        board's normal (what a detector manages).
    min_points : int
        Fewest board points in the image for a view (chessboards: the whole board).
    """

    n_cameras: int = 4
    n_instants: int = 40
    boards: str = "charuco"
    motion: str = "6dof"
    room_half_m: float = 2.0
    board_height_m: float = 1.2
    travel_m: float = 0.5
    yaw_range_deg: float | None = None
    tilt_deg: float = 12.0
    width: int = 800
    height: int = 600
    hfov_deg: float = 80.0
    max_obliquity_deg: float = 65.0
    min_points: int = 8

    def __post_init__(self):
        if self.boards not in ("charuco", "chessboard"):
            raise ValueError(f"boards must be charuco or chessboard, got {self.boards!r}")
        if self.motion not in ("6dof", "planar"):
            raise ValueError(f"motion must be 6dof or planar, got {self.motion!r}")
        if self.boards == "chessboard" and self.n_cameras > 4:
            raise ValueError("the chessboard variant has one wall per camera: at most 4")


@dataclass(frozen=True)
class WallView:
    """One camera's view of one board at one instant (exact pixels).

    Attributes
    ----------
    camera : int
    instant : int
    target : str
        The board's name (a key of :attr:`WallScenario.targets`).
    ids : ndarray of int, shape (n,)
        Point ids of the board's points in the image.
    object_points : ndarray, shape (n, 3)
        Metres, board frame.
    image_points : ndarray, shape (n, 2)
        Pixels.
    """

    camera: int
    instant: int
    target: str
    ids: NDArray[np.int64]
    object_points: F64
    image_points: F64


@dataclass(frozen=True)
class WallScenario:
    """The truth and the views.

    Attributes
    ----------
    spec : WallSpec
    cameras : tuple of str
        ``cam0``, ``cam1``, ...; ``cam0`` is the reference.
    targets : dict of str to dict
        Board name -> rig.yaml target mapping (plus ``cameras`` for chessboards).
    T_world_board : ndarray, shape (B, 4, 4)
        In the order of ``targets``.
    T_ref_cam : ndarray, shape (m, 4, 4)
        ``T_ref_cam[0]`` is the identity.
    T_world_body : ndarray, shape (K, 4, 4)
        The rig's gravity-aligned body frame at each instant (what motion capture on the
        rig would track).
    T_body_ref : ndarray, shape (4, 4)
    intrinsics : tuple of Intrinsics
    views : tuple of WallView
        Ordered by instant, then camera, then board.
    """

    spec: WallSpec
    cameras: tuple[str, ...]
    targets: dict
    T_world_board: F64
    T_ref_cam: F64
    T_world_body: F64
    T_body_ref: F64
    intrinsics: tuple[Intrinsics, ...]
    views: tuple[WallView, ...]

    @property
    def T_world_ref(self) -> F64:
        """The reference camera's pose at each instant, shape (K, 4, 4)."""
        return self.T_world_body @ self.T_body_ref

    def board_pose(self, name: str) -> F64:
        """``T_world_board`` of the board ``name``."""
        return self.T_world_board[list(self.targets).index(name)]

    def seen(self) -> NDArray[np.bool_]:
        """Shape (K, m): whether camera j sees at least one board at instant i."""
        out = np.zeros((len(self.T_world_body), len(self.cameras)), dtype=bool)
        for v in self.views:
            out[v.instant, v.camera] = True
        return out


def wall_targets(spec: WallSpec) -> dict:
    """Board name -> rig.yaml target mapping (chessboards with their ``cameras``)."""
    if spec.boards == "charuco":
        base = {"type": "charuco", "rows": 6, "cols": 9, "spacing": 0.16,
                "marker_size": 0.12, "dictionary": "DICT_4X4_100"}
        return {wall: {**base, "first_id": 32 * k}
                for k, wall in enumerate(("north", "west", "south"))}
    walls = list(WALL_DIRECTIONS)
    return {walls[j]: {"type": "chessboard", "rows": 6, "cols": 9, "spacing": 0.1,
                       "cameras": [f"cam{j}"]} for j in range(spec.n_cameras)}


def _board_pose(target: Target, wall: str, spec: WallSpec) -> F64:
    """``T_world_board``: the board centred on its wall at ``board_height_m``, printed face
    towards the room, its x axis horizontal (to the right seen from the room)."""
    d = np.asarray(WALL_DIRECTIONS[wall])
    up = np.array([0.0, 0.0, 1.0])
    R = np.column_stack([np.cross(d, up), -up, d])    # z into the wall, y down the face
    if not target.z_into_board:
        R = R @ np.diag([1.0, -1.0, -1.0])
    x0, x1, y0, y1 = target.bounds()
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    origin = spec.room_half_m * d + spec.board_height_m * up
    return g.make_transform(R, origin - R @ centre)


def _rot_z(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _camera_mounts(n: int, rng: np.random.Generator) -> F64:
    """``T_body_cam`` of every camera: on a ring of 0.2 m radius, facing outwards ``360/n``
    degrees apart, each turned and shifted a little (a real rig is not exact)."""
    out = np.empty((n, 4, 4))
    for j in range(n):
        heading = 2 * np.pi * j / n                   # camera 0 along the body's +y
        f = _rot_z(heading) @ [0.0, 1.0, 0.0]
        R = np.column_stack([np.cross(f, [0.0, 0.0, 1.0]), [0.0, 0.0, -1.0], f])
        R = R @ g.transform_from_rotvec(rng.uniform(-0.04, 0.04, 3), [0, 0, 0])[:3, :3]
        out[j] = g.make_transform(R, 0.2 * f + rng.uniform(-0.03, 0.03, 3))
    return out


def _body_poses(spec: WallSpec, rng: np.random.Generator) -> F64:
    """``T_world_body`` of every instant (module docstring)."""
    K = spec.n_instants
    limit = spec.yaw_range_deg
    if limit is None and spec.boards == "chessboard":
        limit = 20.0
    if limit is None:       # spread evenly over the circle (stratified), in random order
        yaw = rng.permutation(2 * np.pi * (np.arange(K) + rng.uniform(0, 1, K)) / K - np.pi)
    else:
        yaw = np.radians(limit) * rng.uniform(-1, 1, K)
    xy = spec.travel_m * rng.uniform(-1, 1, (K, 2))
    out = np.empty((K, 4, 4))
    for i in range(K):
        R = _rot_z(yaw[i])
        z = spec.board_height_m
        if spec.motion == "6dof":
            roll, pitch = np.radians(spec.tilt_deg) * rng.uniform(-1, 1, 2)
            R = R @ g.transform_from_rotvec([roll, pitch, 0.0], [0, 0, 0])[:3, :3]
            z += spec.travel_m / 3 * rng.uniform(-1, 1)
        out[i] = g.make_transform(R, [xy[i, 0], xy[i, 1], z])
    return out


def wall_intrinsics(spec: WallSpec, rng: np.random.Generator) -> tuple[Intrinsics, ...]:
    """A pinhole lens per camera of ``hfov_deg``, slight radial distortion, varied a little."""
    out = []
    for _ in range(spec.n_cameras):
        f = spec.width / (2 * np.tan(np.radians(spec.hfov_deg) / 2)) * rng.uniform(0.98, 1.02)
        K = np.array([[f, 0, spec.width / 2 - 0.5 + rng.uniform(-6, 6)],
                      [0, f * rng.uniform(0.998, 1.002), spec.height / 2 - 0.5 + rng.uniform(-6, 6)],
                      [0, 0, 1]])
        dist = np.array([rng.uniform(-0.06, -0.02), rng.uniform(0.0, 0.01),
                         rng.uniform(-5e-4, 5e-4), rng.uniform(-5e-4, 5e-4)])
        out.append(Intrinsics(K=K, dist=dist, model="pinhole", width=spec.width,
                              height=spec.height))
    return tuple(out)


def _view(target: Target, intr: Intrinsics, T_cam_board: F64, spec: WallSpec,
          whole: bool) -> tuple[NDArray[np.int64], F64] | None:
    """The ids and pixels of the board's points a camera sees, or None (too few, too
    oblique, behind; chessboards: not whole)."""
    P = target.object_points()
    x0, x1, y0, y1 = target.bounds()
    centre = T_cam_board[:3, :3] @ [(x0 + x1) / 2, (y0 + y1) / 2, 0.0] + T_cam_board[:3, 3]
    if centre[2] <= 0:
        return None
    normal = T_cam_board[:3, 2] * (1.0 if target.z_into_board else -1.0)
    if normal @ centre <= np.cos(np.radians(spec.max_obliquity_deg)) * np.linalg.norm(centre):
        return None                                  # seen from behind or too obliquely
    Pc = P @ T_cam_board[:3, :3].T + T_cam_board[:3, 3]
    front = Pc[:, 2] > 0.05
    uv = np.full((len(P), 2), np.nan)
    uv[front] = project_points(Pc[front], intr)
    border = 10.0
    with np.errstate(invalid="ignore"):
        inside = (front & (uv[:, 0] >= border) & (uv[:, 0] <= spec.width - 1 - border)
                  & (uv[:, 1] >= border) & (uv[:, 1] <= spec.height - 1 - border))
    if whole and not inside.all():
        return None
    if inside.sum() < spec.min_points:
        return None
    ids = np.flatnonzero(inside)
    return ids, uv[ids]


def simulate_walls(rng: np.random.Generator, spec: WallSpec = WallSpec(),
                   T_world_body: F64 | None = None) -> WallScenario:
    """The rig, the boards, the motion and every view with its exact pixels.

    Parameters
    ----------
    rng : numpy.random.Generator
        The rig's mounts, lenses and motion.
    spec : WallSpec
    T_world_body : ndarray, shape (K, 4, 4), optional
        The body's pose at each instant instead of ``spec.motion``'s (e.g. a smooth path in
        time, for clock offsets); ``spec.n_instants`` is then ignored.

    Returns
    -------
    WallScenario
    """
    specs = wall_targets(spec)
    boards = {name: target_from_spec({k: v for k, v in s.items() if k != "cameras"})
              for name, s in specs.items()}
    T_world_board = np.stack([_board_pose(boards[n], n, spec) for n in specs])
    T_body_cam = _camera_mounts(spec.n_cameras, rng)
    intr = wall_intrinsics(spec, rng)
    T_world_body = _body_poses(spec, rng) if T_world_body is None else np.asarray(
        T_world_body, dtype=np.float64)
    cameras = tuple(f"cam{j}" for j in range(spec.n_cameras))
    views = []
    for i, T_wb in enumerate(T_world_body):
        for j, cam in enumerate(cameras):
            T_cam_world = g.inv(T_wb @ T_body_cam[j])
            for k, (name, s) in enumerate(specs.items()):
                if "cameras" in s and cam not in s["cameras"]:
                    continue
                seen = _view(boards[name], intr[j], T_cam_world @ T_world_board[k], spec,
                             whole=s["type"] == "chessboard")
                if seen is not None:
                    ids, uv = seen
                    views.append(WallView(j, i, name, ids, boards[name].object_points()[ids],
                                          uv))
    return WallScenario(spec=spec, cameras=cameras, targets=specs, T_world_board=T_world_board,
                        T_ref_cam=g.inv(T_body_cam[0]) @ T_body_cam, T_world_body=T_world_body,
                        T_body_ref=T_body_cam[0], intrinsics=intr, views=tuple(views))


def noisy_views(scenario: WallScenario, sigma_px: float,
                rng: np.random.Generator) -> tuple[WallView, ...]:
    """The scenario's views with independent Gaussian pixel noise ``sigma_px`` per
    coordinate."""
    return tuple(WallView(v.camera, v.instant, v.target, v.ids, v.object_points,
                          v.image_points + sigma_px * rng.standard_normal(v.image_points.shape))
                 for v in scenario.views)
