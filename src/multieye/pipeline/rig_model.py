"""The rig's targets and given lenses, built once from rig.yaml and carried along the data path.

:func:`build_rig_model` turns each target spec of rig.yaml into its
:class:`~multieye.imaging.targets.Target` and reads each camera's given intrinsics (checked
against its ``model``) once; detection (:mod:`multieye.pipeline.detection`), the cameras'
loading (:mod:`multieye.pipeline.camera_data`), the dry run and the problem
(:attr:`multieye.pipeline.problem.Problem.model`) take them from the :class:`RigModel`
instead of building them again where each needs one.

Synopsis
--------
>>> model = build_rig_model(load_rig("dataset"))       # doctest: +SKIP
>>> model.target, model.lenses["cam0"]                  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from multieye.core.intrinsics import Intrinsics
from multieye.imaging.targets import Target, target_from_spec
from multieye.io import Rig, read_camera_intrinsics
from multieye.pipeline.estimated_lens import check_model

__all__ = ["RigModel", "build_rig_model", "TARGET"]

#: The name of the rig's target when rig.yaml gives one ``target:``.
TARGET = "target"


@dataclass(frozen=True)
class RigModel:
    """What the rig's files describe, built once.

    Attributes
    ----------
    targets : mapping of str to Target
        The rig's targets by name (``"target"`` for rig.yaml's ``target:``), in file order.
    intrinsics_targets : mapping of str to Target
        By camera name, the board of its ``intrinsics_images`` when it is not the rig's.
    lenses : mapping of str to (Intrinsics or None)
        By camera name, its given intrinsics in the form its ``model`` names (None: none
        given, the lens is estimated from the recording, or a camera of ``poses`` without).
    """

    targets: Mapping[str, Target] = field(default_factory=dict)
    intrinsics_targets: Mapping[str, Target] = field(default_factory=dict)
    lenses: Mapping[str, Intrinsics | None] = field(default_factory=dict)

    @property
    def target(self) -> Target | None:
        """The rig's (first) target; None when no camera has images."""
        return next(iter(self.targets.values()), None)

    def intrinsics_target(self, camera: str) -> Target | None:
        """The board of a camera's ``intrinsics_images``: its own, else the rig's."""
        return self.intrinsics_targets.get(camera, self.target)


def build_rig_model(rig: Rig) -> RigModel:
    """Every target of ``rig`` built and every given lens read, once.

    Raises
    ------
    DatasetError
        A target the detectors cannot build, an intrinsics file that cannot be read or holds
        another model than the camera's ``model`` (naming the file and the camera).
    """
    specs = getattr(rig, "targets", None) or ({TARGET: rig.target} if rig.target else {})
    targets = {name: target_from_spec(spec, path=rig.path) for name, spec in specs.items()}
    own = {name: target_from_spec(cam.intrinsics_target, path=rig.path)
           for name, cam in rig.cameras.items() if cam.intrinsics_target is not None}
    lenses = {name: (check_model(name, read_camera_intrinsics(cam), cam.model, cam.intrinsics)
                     if cam.intrinsics is not None else None)
              for name, cam in rig.cameras.items()}
    return RigModel(MappingProxyType(targets), MappingProxyType(own), MappingProxyType(lenses))
