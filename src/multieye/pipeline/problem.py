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

from multieye.core.errors import DatasetError
from multieye.io import Rig
from multieye.pipeline.camera_data import CameraData, PairedCamera
from multieye.pipeline.options import Options
from multieye.solvers.measurements import Measurements

__all__ = ["Problem", "Pairing", "make_problem"]


@dataclass(frozen=True)
class Problem:
    """The rig, what each camera observed, and how to solve it.

    Attributes
    ----------
    rig : Rig
        rig.yaml as read: setup, target, frames, motion capture, cameras.
    cameras : dict of str to CameraData
        Per camera, in rig.yaml's order.
    options : Options
    reference : str
        The camera whose frame is ``ref``.
    """

    rig: Rig
    cameras: dict[str, CameraData]
    options: Options
    reference: str

    @property
    def setup(self) -> str:
        return self.rig.setup


def make_problem(rig: Rig, cameras: dict[str, CameraData], options: Options) -> Problem:
    """The problem, with the reference camera checked against the cameras."""
    reference = options.reference or next(iter(cameras))
    if reference not in cameras:
        raise DatasetError(f"reference camera {reference!r} is not in rig.yaml (cameras: "
                           f"{', '.join(cameras)})", path=rig.path)
    return Problem(rig=rig, cameras=cameras, options=options, reference=reference)


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
