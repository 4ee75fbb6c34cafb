"""How a calibration goes from measurements to the result: :class:`Options`, validated once.

Each field is checked here, when an ``Options`` is made (so ``calibrate(...,
max_time_offset=None)`` fails at once with what was expected, not deep in the pipeline);
the stages take the fields as they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from multieye.core.arguments import one_of, real_number, with_fields
from multieye.core.errors import InputError
from multieye.core.limits import MAX_TIME_OFFSET_S
from multieye.estimate.selection import DEFAULT_BUDGET
from multieye.solvers.methods import METHODS, MIN_MEASUREMENTS

__all__ = ["Options", "updated_options"]


@dataclass(frozen=True)
class Options:
    """How :func:`calibrate_rig` goes from measurements to the result.

    Attributes
    ----------
    method : str
        Closed-form solver (:data:`multieye.METHODS`).
    reference : str or None
        Reference camera; default the first.
    refine : bool
        Follow the closed form with the maximum-likelihood refinement: on the target points
        and motion-capture poses when every camera has images (:func:`multieye.estimate.refine_images.
        refine_images`), else on the pose residuals (:mod:`multieye.solvers.refine_poses`).  Fills the
        uncertainty.
    robust : bool
        Consensus over measurements before solving (:func:`multieye.estimate.consensus.consensus`);
        rejected measurements are listed with the reason.
    time_offset : "rig", "auto" or float
        ``"rig"``: each camera's ``time_offset`` from rig.yaml; ``"auto"``: estimated per
        camera (:func:`multieye.estimate.clock.estimate_offset`); a number: seconds for every camera.
    max_time_offset : float
        With ``time_offset="auto"``: offsets from ``-max_time_offset`` to ``+max_time_offset``
        seconds are searched (an optimum at the edge of that range is refused).
    mocap_rot_sigma_rad, mocap_trans_sigma_m : float or None
        Motion-capture noise for the refinement; None: rig.yaml's ``rotation_noise_deg`` /
        ``translation_noise_m``, else the defaults of :mod:`multieye.estimate.refine_images`.
    select : int or None
        Image budget per camera (docs/recordings.md, section 1): a camera with more images
        keeps this many, chosen by what they add (before decoding, and after detection);
        default :data:`multieye.estimate.selection.DEFAULT_BUDGET` (300); None keeps every
        image.
    """

    method: str = "joint"
    reference: str | None = None
    refine: bool = True
    robust: bool = True
    time_offset: str | float = "rig"
    max_time_offset: float = 0.5
    mocap_rot_sigma_rad: float | None = None
    mocap_trans_sigma_m: float | None = None
    select: int | None = DEFAULT_BUDGET

    def __post_init__(self):
        _check(self)


def _check(opts: Options) -> None:
    """InputError for a field of :class:`multieye.pipeline.Options` that cannot be right
    (run by ``Options`` itself, so ``calibrate(..., max_time_offset=None)`` fails at once with
    what was expected instead of deep in the pipeline)."""
    one_of(opts.method, "method", METHODS)
    if opts.reference is not None and not isinstance(opts.reference, str):
        raise InputError(f"reference must be a camera name, got {opts.reference!r}")
    for name in ("refine", "robust"):
        if not isinstance(getattr(opts, name), (bool, np.bool_)):
            raise InputError(f"{name} must be True or False, got {getattr(opts, name)!r}")
    if not (isinstance(opts.time_offset, str) and opts.time_offset in ("rig", "auto")):
        if isinstance(opts.time_offset, str):
            raise InputError(f"time_offset must be 'rig', 'auto' or a number of seconds, got "
                             f"{opts.time_offset!r}")
        offset = real_number(opts.time_offset, "time_offset")
        if abs(offset) > MAX_TIME_OFFSET_S:
            raise InputError(f"time_offset must be within {MAX_TIME_OFFSET_S:g} s, got {offset:g}")
    real_number(opts.max_time_offset, "max_time_offset", positive=True)
    real_number(opts.mocap_rot_sigma_rad, "mocap_rot_sigma_rad", positive=True, allow_none=True)
    real_number(opts.mocap_trans_sigma_m, "mocap_trans_sigma_m", positive=True, allow_none=True)
    if opts.select is not None and (isinstance(opts.select, (bool, np.bool_))
                                    or not isinstance(opts.select, (int, np.integer))
                                    or opts.select < MIN_MEASUREMENTS):
        raise InputError(f"select must be a whole number of images per camera >= "
                         f"{MIN_MEASUREMENTS}, or None to keep every image; got {opts.select!r}")


def updated_options(options: Options, kw: dict) -> Options:
    """``options`` with the fields in ``kw`` replaced; InputError for anything else than
    Options or for an unknown field (instead of dataclasses' TypeError)."""
    return with_fields(options, kw, Options, "options")
