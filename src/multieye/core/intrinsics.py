"""Camera intrinsics as plain data (no OpenCV here).

File readers (``multieye.io.intrinsics_files``) produce :class:`Intrinsics`; camera models on the
image side (``multieye.imaging``) consume it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from multieye.core.arguments import real_array
from multieye.core.errors import InputError
from multieye.core.limits import (
    MAX_FOCAL_PX,
    MAX_IMAGE_SIDE_PX,
    MAX_PRINCIPAL_POINT_OUTSIDE,
    MAX_RADIAL_DISTORTION,
    MAX_SKEW_FRACTION,
    MAX_TANGENTIAL_DISTORTION,
    MAX_EUCM_BETA,
    MAX_TILT_RAD,
    MAX_XI,
    MIN_FOCAL_FRACTION,
)

__all__ = ["Intrinsics", "PINHOLE_DISTORTION_SIZES", "LENS_MODELS", "WIDE_MODELS",
           "lens_model", "parameter_names", "check_lens_bounds"]

#: Lengths of OpenCV's pinhole distortion vector (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]]).
PINHOLE_DISTORTION_SIZES = (0, 4, 5, 8, 12, 14)

#: Lens models a camera's intrinsics can be estimated in (rig.yaml ``model:``): the
#: :class:`Intrinsics` model and the distortion coefficients, in OpenCV's order and meaning.
LENS_MODELS = {
    "pinhole-radtan": ("pinhole", ("k1", "k2", "p1", "p2", "k3")),
    "pinhole-radtan4": ("pinhole", ("k1", "k2", "p1", "p2")),   # Kalibr's radtan (k3 = 0)
    "pinhole-rational": ("pinhole", ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")),
    "fisheye": ("fisheye", ("k1", "k2", "k3", "k4")),
    "unified": ("unified", ("xi", "k1", "k2", "p1", "p2")),      # Mei-Rives; Kalibr omni-radtan
    "double-sphere": ("double-sphere", ("xi", "alpha")),         # Usenko et al. 2018; Kalibr ds
    "eucm": ("eucm", ("alpha", "beta")),                         # Khomutenko et al. 2016
}
#: The wide-angle models (:mod:`multieye.core.lens_wide`): the :class:`Intrinsics` model is
#: the rig.yaml name, and the model's parameters come first in ``dist``.
WIDE_MODELS = ("unified", "double-sphere", "eucm")
_PINHOLE_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4",
                  "taux", "tauy")


def lens_model(intrinsics: Intrinsics) -> str:
    """The rig.yaml name of an intrinsics' lens model (``pinhole-radtan`` for 0 or 5
    coefficients, ``pinhole-radtan4`` for 4 (Kalibr's ``radtan``), ``pinhole-rational`` for 8,
    ``pinhole-thin-prism`` for 12, ``pinhole-tilted`` for 14, ``fisheye``, ``unified``,
    ``double-sphere``, ``eucm``)."""
    if intrinsics.model != "pinhole":
        return intrinsics.model
    return {0: "pinhole-radtan", 4: "pinhole-radtan4", 5: "pinhole-radtan",
            8: "pinhole-rational", 12: "pinhole-thin-prism", 14: "pinhole-tilted"}[
        intrinsics.dist.size]


def parameter_names(intrinsics: Intrinsics) -> tuple[str, ...]:
    """Names of :attr:`Intrinsics.params` in order: fx fy cx cy, then the distortion."""
    dist = (LENS_MODELS[intrinsics.model][1] if intrinsics.model != "pinhole"
            else _PINHOLE_NAMES[:intrinsics.dist.size])
    return ("fx", "fy", "cx", "cy") + dist


def _bounds(model: str, n: int) -> list[tuple[str, float, str]]:
    """Per distortion coefficient: its name, its bound and what kind of coefficient it is."""
    if model == "fisheye":
        return [(f"k{i + 1}", MAX_RADIAL_DISTORTION, "radial") for i in range(n)]
    if model == "double-sphere":
        return [("xi", MAX_XI, "double-sphere xi"), ("alpha", 1.0, "double-sphere alpha")]
    if model == "eucm":
        return [("alpha", 1.0, "EUCM alpha"), ("beta", MAX_EUCM_BETA, "EUCM beta")]
    kinds = {"p": (MAX_TANGENTIAL_DISTORTION, "tangential"), "k": (MAX_RADIAL_DISTORTION, "radial"),
             "s": (MAX_RADIAL_DISTORTION, "thin-prism"), "t": (MAX_TILT_RAD, "tilt (radians)")}
    if model == "unified":
        return [("xi", MAX_XI, "unified xi (mirror offset)")] + [
            (name, *kinds[name[0]]) for name in ("k1", "k2", "p1", "p2")]
    return [(name, *kinds[name[0]]) for name in _PINHOLE_NAMES[:n]]


def check_lens_bounds(intrinsics: Intrinsics) -> None:
    """Refuse intrinsics whose numbers no real camera has (:mod:`multieye.core.limits`).

    :class:`Intrinsics` itself checks the form (finite, positive focal lengths, no skew); this
    checks what a file may still get wrong by a unit or a corrupted number: a focal length
    below :data:`~multieye.core.limits.MIN_FOCAL_FRACTION` of the image, a principal point
    more than :data:`~multieye.core.limits.MAX_PRINCIPAL_POINT_OUTSIDE` image sides outside
    the image (both only when the image size is known), and distortion coefficients beyond
    :data:`~multieye.core.limits.MAX_RADIAL_DISTORTION` (radial, thin prism),
    :data:`~multieye.core.limits.MAX_TANGENTIAL_DISTORTION` (tangential),
    :data:`~multieye.core.limits.MAX_TILT_RAD` (sensor tilt), and a wide-angle model's
    ``xi`` beyond :data:`~multieye.core.limits.MAX_XI` or EUCM ``beta`` beyond
    :data:`~multieye.core.limits.MAX_EUCM_BETA`.  Readers call it where
    intrinsics enter; estimation does not (its trial steps may pass anywhere).

    Raises
    ------
    InputError
        One line naming the number, its value and the bound.
    """
    K, w, h = intrinsics.K, intrinsics.width, intrinsics.height
    if w is not None and h is not None:
        side = max(w, h)
        for name, f in (("fx", K[0, 0]), ("fy", K[1, 1])):
            if f < MIN_FOCAL_FRACTION * side:
                raise InputError(f"focal length {name} = {f:g} px is below "
                                 f"{MIN_FOCAL_FRACTION:g} x the {w}x{h} image's larger side "
                                 f"({MIN_FOCAL_FRACTION * side:g} px): a focal length in "
                                 "pixels is expected (not millimetres)")
        m = MAX_PRINCIPAL_POINT_OUTSIDE
        for name, c, size in (("cx", K[0, 2], w), ("cy", K[1, 2], h)):
            if not -m * size <= c <= (1 + m) * size:
                raise InputError(f"principal point {name} = {c:g} px is far outside the {w}x{h} "
                                 f"image (accepted: {-m * size:g} to {(1 + m) * size:g} px)")
    for (name, bound, kind), value in zip(_bounds(intrinsics.model, intrinsics.dist.size),
                                          intrinsics.dist):
        if abs(value) > bound:
            raise InputError(f"{_coefficient(intrinsics.model, name)} {name} = {value:g} is beyond any "
                             f"real lens (a {kind} coefficient's magnitude is at most {bound:g})")


def _coefficient(model: str, name: str) -> str:
    """What a coefficient is called in messages (readers point at their key by it)."""
    wide = model in WIDE_MODELS and name[0] not in "kp"       # not the unified's radtan
    return "lens parameter" if wide else "distortion coefficient"


def _check_wide(model: str, dist: np.ndarray) -> None:
    """The form of a wide-angle model's parameters (:data:`WIDE_MODELS`)."""
    names = LENS_MODELS[model][1]
    if dist.size != len(names):
        raise InputError(f"{model} lens parameters must be {len(names)} numbers "
                         f"({', '.join(names)}), got {dist.size}")
    if not np.all(np.isfinite(dist)):
        raise InputError(f"{model} lens parameters must be finite")
    if model == "unified" and not dist[0] >= 0:
        raise InputError(f"unified xi (mirror offset) must be >= 0, got {dist[0]:g}")
    if model == "double-sphere" and not dist[0] > -1:
        raise InputError(f"double-sphere xi must be > -1, got {dist[0]:g}")
    alpha = dist[1] if model == "double-sphere" else dist[0]
    if model != "unified" and not 0 <= alpha <= 1:
        raise InputError(f"{model} alpha must be within [0, 1], got {alpha:g}")
    if model == "eucm" and not dist[1] > 0:
        raise InputError(f"eucm beta must be > 0, got {dist[1]:g}")


@dataclass(frozen=True)
class Intrinsics:
    """Intrinsics of one camera.

    Attributes
    ----------
    K : ndarray, shape (3, 3)
        Camera matrix, pixels; pixel (0, 0) is the centre of the top-left pixel.
    dist : ndarray, shape (k,)
        ``model="pinhole"``: OpenCV's coefficients, k in (0, 4, 5, 8, 12, 14).
        ``model="fisheye"``: equidistant k1..k4 (OpenCV ``cv2.fisheye``, Kalibr ``equidistant``).
        ``model="unified"``: (xi, k1, k2, p1, p2), Mei-Rives (Kalibr ``omni`` + ``radtan``,
        BoofCV ``mirror_offset``; xi >= 0).
        ``model="double-sphere"``: (xi, alpha), Usenko et al. 2018 (Kalibr ``ds``; xi > -1,
        alpha in [0, 1]).
        ``model="eucm"``: (alpha, beta), Khomutenko et al. 2016 (Kalibr ``eucm``; alpha in
        [0, 1], beta > 0).  :mod:`multieye.core.lens_wide` gives the formulas.
    model : {"pinhole", "fisheye", "unified", "double-sphere", "eucm"}
    width, height : int or None
        Image size in pixels, when the file gives it.
    """

    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(0))
    model: Literal["pinhole", "fisheye", "unified", "double-sphere", "eucm"] = "pinhole"
    width: int | None = None
    height: int | None = None

    def __post_init__(self):
        K = real_array(self.K, "camera matrix", expected="a 3x3 array")
        dist = real_array(self.dist, "distortion coefficients").reshape(-1)
        if K.shape != (3, 3):
            raise InputError(f"camera matrix must be a 3x3 array, got shape {K.shape}")
        if not np.all(np.isfinite(K)):
            raise InputError("camera matrix must be finite, got NaN or inf entries")
        if not (0 < K[0, 0] <= MAX_FOCAL_PX and 0 < K[1, 1] <= MAX_FOCAL_PX):
            raise InputError(f"focal lengths must be positive and at most {MAX_FOCAL_PX:g} px, "
                             f"got fx={K[0, 0]:g}, fy={K[1, 1]:g}")
        if np.abs(K[:2, 1:]).max() > MAX_FOCAL_PX:
            raise InputError(f"principal point and skew must be within {MAX_FOCAL_PX:g} px, got "
                             f"cx={K[0, 2]:g}, cy={K[1, 2]:g}, skew={K[0, 1]:g}")
        if K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1:
            raise InputError(f"camera matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got "
                             f"rows 2 and 3 {K[1].tolist()}, {K[2].tolist()}")
        if abs(K[0, 1]) > MAX_SKEW_FRACTION * K[0, 0]:
            raise InputError(f"camera matrix has skew {K[0, 1]:g} px (row 1, column 2); the lens "
                             "models have no skew (neither has OpenCV's), so it cannot be used: "
                             "calibrate without skew, or give 0")
        for name in ("width", "height"):
            v = getattr(self, name)
            if v is None:
                continue
            if (isinstance(v, bool) or not isinstance(v, (int, np.integer))
                    or not 0 < v <= MAX_IMAGE_SIDE_PX):
                raise InputError(f"image {name} must be a positive integer of at most "
                                 f"{MAX_IMAGE_SIDE_PX} pixels, got {v!r}")
            object.__setattr__(self, name, int(v))
        if self.model == "pinhole":
            if dist.size not in PINHOLE_DISTORTION_SIZES:
                raise InputError("pinhole distortion must have 0, 4, 5, 8, 12 or 14 coefficients, "
                                 f"got {dist.size}")
        elif self.model == "fisheye":
            if dist.size not in (0, 4):
                raise InputError(f"fisheye (equidistant) distortion must have 4 coefficients, got {dist.size}")
            if dist.size == 0:
                dist = np.zeros(4)
        elif self.model in WIDE_MODELS:
            _check_wide(self.model, dist)
        else:
            raise InputError("camera model must be 'pinhole', 'fisheye', 'unified', "
                             f"'double-sphere' or 'eucm', got {self.model!r}")
        if not np.all(np.isfinite(dist)):
            raise InputError("distortion coefficients must be finite")
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "dist", dist)

    @property
    def params(self) -> np.ndarray:
        """``(fx, fy, cx, cy, dist...)``: the parameters estimated when the intrinsics are
        (the order of :func:`multieye.core.lens.project_with_jacobian`'s derivative)."""
        K = self.K
        return np.concatenate([[K[0, 0], K[1, 1], K[0, 2], K[1, 2]], self.dist])

    def with_params(self, params) -> Intrinsics:
        """The same model and image size with ``(fx, fy, cx, cy, dist...)`` replaced (the
        skew kept); raises InputError for parameters the model does not accept."""
        p = np.asarray(params, dtype=np.float64).reshape(-1)
        if p.size != 4 + self.dist.size:
            raise InputError(f"expected {4 + self.dist.size} intrinsic parameters, got {p.size}")
        K = self.K.copy()
        K[0, 0], K[1, 1], K[0, 2], K[1, 2] = p[:4]
        return Intrinsics(K=K, dist=p[4:], model=self.model, width=self.width,
                          height=self.height)
