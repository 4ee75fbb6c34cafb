"""Per-camera data (``CameraData``) from a wall-board scene of :mod:`multieye.sim.wall_boards`.

Test helper: each noisy view of the scene becomes an ``Observation`` whose ``T_cam_target``
is the true board pose perturbed by a small random motion (a PnP start, not the answer), so
that the pipeline's estimation runs from a start that is off.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from multieye.core import geometry as g
from multieye.pipeline.camera_data import CameraData, Observation
from multieye.sim.wall_boards import noisy_views


def wall_camera_data(sc, sigma_px: float, rng: np.random.Generator, *,
                     stamp: Callable[[int, int], float], start_noise: tuple[float, float],
                     mocap=None, time_tolerance: float = 0.03) -> dict[str, CameraData]:
    """Every camera's data from the views of ``sc`` (a ``WallScene``).

    Parameters
    ----------
    sc : WallScene
        The scene (:func:`multieye.sim.wall_boards.simulate_walls`).
    sigma_px : float
        Corner noise, pixels (:func:`~multieye.sim.wall_boards.noisy_views`).
    rng : numpy.random.Generator
        Draws the corner noise, then per view the start's perturbation.
    stamp : callable
        ``stamp(instant, camera index) -> seconds``, the image's stamp.
    start_noise : (float, float)
        Standard deviations of the start's rotation (rad) and translation (m) perturbation.
    mocap : Trajectory, optional
        The motion capture every camera pairs with (None: none).
    time_tolerance : float
        ``CameraData.time_tolerance``, seconds.
    """
    obs = {n: [] for n in sc.cameras}
    for v in noisy_views(sc, sigma_px, rng):
        b = list(sc.targets).index(v.target)
        T = g.inv(sc.T_world_ref[v.instant] @ sc.T_ref_cam[v.camera]) @ sc.T_world_board[b]
        T = T @ g.transform_from_rotvec(rng.normal(scale=start_noise[0], size=3),
                                        rng.normal(scale=start_noise[1], size=3))
        obs[sc.cameras[v.camera]].append(Observation(
            name=f"{v.instant:04d}.png", stamp=float(stamp(v.instant, v.camera)),
            T_cam_target=T, rms_px=sigma_px, object_points=v.object_points,
            image_points=v.image_points, target=v.target))
    return {n: CameraData(name=n, intrinsics=sc.intrinsics[j], observations=tuple(obs[n]),
                          rejected=(), n_inputs=len(obs[n]), mocap=mocap, time_offset=0.0,
                          time_tolerance=time_tolerance) for j, n in enumerate(sc.cameras)}
