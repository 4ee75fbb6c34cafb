"""The calibration problem as the pipeline's stages hold it, keyed by camera name.

:class:`Problem` is what was read: the rig (setup, target, frames, motion capture) and, per
camera, what it observed (:class:`~multieye.pipeline.camera_data.CameraData`: target points
per image, image names and stamps, the lens or its model, the clock, the motion capture it
pairs with), with the options and the reference camera.  :class:`Pairing` is what the
pairing and the consensus made of it: per camera the measurements ``A_i X = Y B_i``, and
the same validated once as the solvers' :class:`~multieye.solvers.checks.Measurements`.
The array-level description the solvers share (setups, measurement groups) is
:mod:`multieye.core.problem`, one layer down.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

from multieye.core.errors import DatasetError
from multieye.io import Rig
from multieye.pipeline.camera_data import CameraData, PairedCamera
from multieye.pipeline.options import Options
from multieye.pipeline.overlap import assign_instants
from multieye.pipeline.rig_model import RigModel, build_rig_model
from multieye.solvers.measurements import Measurements

__all__ = ["Problem", "Pairing", "Instant", "View", "make_problem", "group_instants"]


class View(NamedTuple):
    """One camera's image: ``problem.cameras[camera].observations[index]``."""

    camera: str
    index: int


@dataclass(frozen=True)
class Instant:
    """The images of every camera taken at one instant (one :attr:`Observation.instant`
    key): the target has one pose for all of them.

    Attributes
    ----------
    key : str
    views : tuple of View
        In rig.yaml's camera order, then image order.
    """

    key: str
    views: tuple[View, ...]


@dataclass(frozen=True)
class Problem:
    """The rig, what each camera observed, and how to solve it.

    Attributes
    ----------
    rig : Rig
        rig.yaml as read: setup, target, frames, motion capture (``rig.mocap``; None when
        every camera names its own), cameras.
    cameras : dict of str to CameraData
        Per camera, in rig.yaml's order: what it observed (target points per image, image
        names, stamps and instants, the lens or its model, the clock, the motion capture it
        pairs with, None for none).
    options : Options
    reference : str
        The camera whose frame is ``ref``.
    instants : dict of str to Instant
        The images of every camera grouped by :attr:`Observation.instant`, in the order of
        first appearance (keys set by :func:`multieye.pipeline.overlap.assign_instants`:
        stamps within ``sync_tolerance``): where cameras that see the target together share
        one target pose (the pairing's shared motion-capture pose, the record's links).
    unknown_x : dict of str to (str or None)
        Per camera, the unknown ``X`` its measurements determine: its own name (every camera
        today, ``MeasurementGroup.x_name`` of :mod:`multieye.core.problem`); None for a
        camera without an ``X`` of its own, placed only through the instants it shares with
        cameras that have one.
    model : RigModel
        The targets and given lenses, built once from rig.yaml
        (:func:`multieye.pipeline.rig_model.build_rig_model`) and carried here.
    """

    rig: Rig
    cameras: dict[str, CameraData]
    options: Options
    reference: str
    instants: dict[str, Instant] = field(default_factory=dict)
    unknown_x: dict[str, str | None] = field(default_factory=dict)
    model: RigModel = field(default_factory=RigModel)

    @property
    def setup(self) -> str:
        return self.rig.setup


def make_problem(rig: Rig, cameras: dict[str, CameraData], options: Options,
                 model: RigModel | None = None) -> Problem:
    """The problem, with the reference camera checked against the cameras, the images
    grouped by instant (by stamp within ``sync_tolerance``; with rig.yaml's ``sync`` other
    than ``time``, by the keys their names gave), each camera its own ``X``, and the targets
    and lenses ``model`` (the one the cameras were loaded with; built when not given)."""
    reference = options.reference or next(iter(cameras))
    if reference not in cameras:
        raise DatasetError(f"reference camera {reference!r} is not in rig.yaml (cameras: "
                           f"{', '.join(cameras)})", path=rig.path)
    if rig.sync == "time":
        cameras = assign_instants(cameras, rig.sync_tolerance)   # within sync_tolerance
    return Problem(rig=rig, cameras=cameras, options=options, reference=reference,
                   instants=group_instants(cameras), unknown_x={n: n for n in cameras},
                   model=build_rig_model(rig) if model is None else model)


def group_instants(cameras: dict[str, CameraData]) -> dict[str, Instant]:
    """Every camera's images grouped by :attr:`Observation.instant`."""
    views: dict[str, list[View]] = {}
    for name, data in cameras.items():
        for k, o in enumerate(data.observations):
            views.setdefault(o.instant, []).append(View(name, k))
    return {key: Instant(key, tuple(v)) for key, v in views.items()}


@dataclass(frozen=True)
class Pairing:
    """The measurements per camera, and what was left out.

    Attributes
    ----------
    offsets : dict of str to float
        The clock offset each camera was paired with (motion-capture clock minus camera
        clock, seconds).
    paired : dict of str to PairedCamera
        The measurements kept (after the consensus, when it ran).
    measurements : Measurements
        The same, validated once, in the order of ``paired``: what the closed form takes.
    warnings : tuple of str
        What the cameras' loading and the consensus doubt.
    selection : dict of str to SelectionSummary
        The cameras whose paired images were chosen among after detection
        (:func:`multieye.pipeline.selection.select_paired`).
    """

    offsets: dict[str, float]
    paired: dict[str, PairedCamera]
    measurements: Measurements
    warnings: tuple[str, ...] = ()
    selection: dict = field(default_factory=dict)
