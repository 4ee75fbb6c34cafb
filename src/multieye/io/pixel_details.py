"""``details.json`` per camera: where the target was seen, how well it fits, how sure the lens is.

Three optional parts of a camera's entry in ``details.json`` (docs/outputs.md, section 3),
read and written by :mod:`multieye.io.run_details`:

- ``points`` (:class:`ImagePoints`): the detected target points of every used image, in
  pixels, with their reprojection residuals (projection minus observation) after the
  image-level refinement (``source: "refined"``) or, without it, after each image's PnP
  (``"pnp"``); the image size; the RMS of every image over all its points.  Rounded (pixels to
  0.01 px, residuals to 0.001 px) and, for big recordings, evenly subsampled to at most
  :data:`MAX_POINTS` points per camera (``n_points`` says how many there were);
- the intrinsics' covariance (over ``Intrinsics.params``: fx fy cx cy, then the distortion)
  when they were estimated, inside ``intrinsics``;
- ``projection_std`` (:class:`ProjectionStd`): the standard deviation of the projection over
  a grid of cells on the image, from that covariance (:func:`multieye.outputs.details.
  projection_std_grid`: ``sqrt(trace(J Sigma J^T) / 2)`` for the ray each cell centre sees,
  ``J = d uv / d params``).

Files written before these keys existed read with them as None.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ImagePoints", "ProjectionStd", "MAX_POINTS", "points_to_dict", "points_from_dict",
           "projection_to_dict", "projection_from_dict", "rounded", "plain"]

#: Most target points kept per camera in ``details.json`` (evenly subsampled above).
MAX_POINTS = 20_000
#: Sources of the residuals.
SOURCES = ("refined", "pnp")


@dataclass(frozen=True)
class ImagePoints:
    """The target points of one camera's used images and their residuals.

    Attributes
    ----------
    source : {"refined", "pnp"}
        Residuals of the refined rig (the refined intrinsics, camera pose, ``Y`` and
        motion-capture pose of each image) or of each image's own PnP pose.
    image_size : (int, int) or None
        Width and height, pixels; None when the intrinsics do not say.
    n_points : int
        Target points in the used images before subsampling.
    uv : tuple of ndarray, shape (k_i, 2)
        Per used image (the order of the measurements), the points kept, pixels.
    residual_px : tuple of ndarray, shape (k_i, 2)
        Their projection minus their observation, pixels (NaN where the projection is not
        defined).
    rms_px : ndarray, shape (n,)
        Per used image, the RMS of the residual lengths over all its points (before
        subsampling), pixels; NaN for an image without points.
    """

    source: str
    image_size: tuple[int, int] | None
    n_points: int
    uv: tuple[np.ndarray, ...]
    residual_px: tuple[np.ndarray, ...]
    rms_px: np.ndarray

    @property
    def kept(self) -> int:
        """Points kept (``<= n_points``)."""
        return sum(len(u) for u in self.uv)


@dataclass(frozen=True)
class ProjectionStd:
    """Standard deviation of the projection over the image, from the intrinsics' covariance.

    Attributes
    ----------
    u : ndarray, shape (nu,)
        Column centres of the cells, pixels.
    v : ndarray, shape (nv,)
        Row centres, pixels.
    std_px : ndarray, shape (nv, nu)
        Pixels; NaN where the lens model cannot be inverted.
    """

    u: np.ndarray
    v: np.ndarray
    std_px: np.ndarray

    @property
    def mean_px(self) -> float:
        """Mean over the cells with a value (NaN if none)."""
        s = self.std_px[np.isfinite(self.std_px)]
        return float(s.mean()) if s.size else math.nan

    @property
    def max_px(self) -> float:
        """Largest over the cells (NaN if none)."""
        s = self.std_px[np.isfinite(self.std_px)]
        return float(s.max()) if s.size else math.nan


def plain(a) -> list | float | None:
    """``a`` as nested lists of Python floats, full precision (NaN and inf -> None): JSON.
    Made by ``ndarray.tolist`` (an element at a time in Python took 25 ms for a 4 x 100
    rig's ``details.json``)."""
    a = np.asarray(a, dtype=np.float64)
    out = a.tolist()
    if a.ndim == 0:
        return out if math.isfinite(out) else None
    if np.all(np.isfinite(a)):
        return out

    def clean(x):
        return [clean(y) for y in x] if isinstance(x, list) else (x if math.isfinite(x) else None)
    return clean(out)


def rounded(a, decimals: int) -> list:
    """Nested lists of floats rounded to ``decimals`` (NaN -> None): compact JSON."""
    return plain(np.round(np.asarray(a, dtype=np.float64), decimals))


def points_to_dict(p: ImagePoints) -> dict:
    return {"source": p.source, "image_size": None if p.image_size is None else list(p.image_size),
            "n_points": p.n_points, "uv": [rounded(u, 2) for u in p.uv],
            "residual_px": [rounded(r, 3) for r in p.residual_px], "rms_px": rounded(p.rms_px, 4)}


def projection_to_dict(p: ProjectionStd) -> dict:
    return {"u": rounded(p.u, 2), "v": rounded(p.v, 2), "std_px": rounded(p.std_px, 4),
            "mean_px": rounded(p.mean_px, 4), "max_px": rounded(p.max_px, 4)}


def _size(r, value, name: str):
    if value is None:
        return None
    if (not isinstance(value, list) or len(value) != 2
            or any(isinstance(v, bool) or not isinstance(v, int) or v <= 0 for v in value)):
        raise r.error(f"points.image_size must be [width, height] in pixels or null, got "
                      f"{value!r}", name)
    return (value[0], value[1])


def _per_image(r, value, n: int, what: str, name: str, nan_ok: bool) -> tuple:
    if not isinstance(value, list) or len(value) != n:
        raise r.error(f"{what} must be a list with one entry per measurement ({n})", name)
    out = []
    for i, item in enumerate(value):
        a = r.array(item if item else np.zeros((0, 2)), (-1, 2), f"{what}[{i}]", name,
                    nan_ok=nan_ok)
        out.append(a)
    return tuple(out)


def points_from_dict(r, obj, n: int, name: str) -> ImagePoints | None:
    """Validate ``points`` of camera ``name`` with ``n`` measurements (``r``: the reader of
    :mod:`multieye.io.run_details`, which names the file and camera in errors)."""
    if obj is None:
        return None
    source = r.get(obj, "source", "points", name)
    if source not in SOURCES:
        raise r.error(f"points.source must be one of {', '.join(SOURCES)}, got {source!r}", name)
    uv = _per_image(r, r.get(obj, "uv", "points", name), n, "points.uv", name, False)
    res = _per_image(r, r.get(obj, "residual_px", "points", name), n, "points.residual_px",
                     name, True)
    for i, (a, b) in enumerate(zip(uv, res)):
        if a.shape != b.shape:
            raise r.error(f"points.residual_px[{i}] must have one row per point of "
                          f"points.uv[{i}] ({len(a)}), got {len(b)}", name)
    kept = sum(len(a) for a in uv)
    total = r.get(obj, "n_points", "points", name)
    if isinstance(total, bool) or not isinstance(total, int) or total < kept:
        raise r.error(f"points.n_points must be an integer >= {kept}, got {total!r}", name)
    rms = r.array(r.get(obj, "rms_px", "points", name), (n,), "points.rms_px", name, nan_ok=True)
    return ImagePoints(source=source, image_size=_size(r, obj.get("image_size"), name),
                       n_points=total, uv=uv, residual_px=res, rms_px=rms)


def projection_from_dict(r, obj, name: str) -> ProjectionStd | None:
    """Validate ``projection_std`` of camera ``name`` (see :func:`points_from_dict`)."""
    if obj is None:
        return None
    u = r.array(r.get(obj, "u", "projection_std", name), (-1,), "projection_std.u", name)
    v = r.array(r.get(obj, "v", "projection_std", name), (-1,), "projection_std.v", name)
    std = r.array(r.get(obj, "std_px", "projection_std", name), (v.size, u.size),
                  "projection_std.std_px", name, nan_ok=True)
    if np.any(std[np.isfinite(std)] < 0):
        raise r.error("projection_std.std_px must not be negative", name)
    return ProjectionStd(u=u, v=v, std_px=std)
