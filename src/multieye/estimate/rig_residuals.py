"""The views of a rig linked by co-observations of one target (no motion capture).

What is measured are the target points' pixels.  The unknowns are each camera's pose in the
reference camera ``T_ref_cam^j`` (the reference camera's is the identity, not an unknown),
the target's pose ``T_ref_target(t)`` at every instant ``t`` (one per instant, however many
cameras saw it: docs/rig-yaml.md, section 2) and, when estimated, the lenses::

    p_cam = inv(T_ref_cam^j) @ T_ref_target(t) @ p          u = pi_j(p_cam)

This is the problem of :mod:`multieye.estimate.motion_residuals` with one board: the board is
the world (held at the identity) and the world in the rig at each instant, its ``S(t)``, is
``T_ref_target(t)``.  :class:`RigViews` gives the views in that problem's layout (every view
of board 0); its residuals, Jacobians and block families are that module's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from multieye.core.errors import InputError
from multieye.core.intrinsics import Intrinsics
from multieye.estimate.motion_residuals import MotionViews

__all__ = ["RigViews"]


class RigViews(MotionViews):
    """Target points and pixels of every view (one image of one camera at one instant).

    Views are numbered camera by camera; points view by view.  A
    :class:`~multieye.estimate.motion_residuals.MotionViews` whose views all show board 0
    (its attributes; ``board`` all zero, no board estimated).

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
    """

    def __init__(self, views: Mapping[str, Sequence], intrinsics: Sequence[Intrinsics],
                 reference: int = 0, *, free_intrinsics: Sequence[bool] | None = None):
        if not isinstance(views, Mapping):
            raise InputError(f"views must be a mapping of camera name to views, got "
                             f"{type(views).__name__}")
        one_board = {}
        for name, images in views.items():
            items = []
            for i, item in enumerate(images):
                try:
                    o, u, t = item
                except (TypeError, ValueError):
                    raise InputError(f"camera {name}, image {i}: expected (object_points, "
                                     "image_points, instant)") from None
                items.append((o, u, t, 0))
            one_board[name] = items
        super().__init__(one_board, intrinsics, reference, free_intrinsics=free_intrinsics)
