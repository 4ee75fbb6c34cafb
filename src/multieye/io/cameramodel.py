"""mrcal's ``.cameramodel`` files: read one camera's intrinsics, write one per camera.

The format (mrcal's documentation of ``mrcal.cameramodel``) is a Python dictionary literal,
read here as mrcal reads it, with :func:`ast.literal_eval`::

    # comments
    {
        'lensmodel':  'LENSMODEL_OPENCV8',
        # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....
        'intrinsics': [ 1052.25, 1049.5, 641.75, 362.125, -0.118, 0.179, ...],
        'rt_cam_ref': [ rx, ry, rz, tx, ty, tz],
        'extrinsics': [ rx, ry, rz, tx, ty, tz],   # mrcal < 2.5's name of rt_cam_ref
        'imagersize': [ 1280, 720],
    }

Lens models: ``LENSMODEL_PINHOLE`` (no distortion) and ``LENSMODEL_OPENCV4``, ``_OPENCV5``,
``_OPENCV8``, ``_OPENCV12``, whose coefficients are OpenCV's pinhole distortion in OpenCV's
order; mrcal's other models (CAHVOR, CAHVORE, stereographic, lon/lat, splined) have no OpenCV
equivalent and are refused with their name.  mrcal has no model for OpenCV's fisheye or tilted
sensor, so :func:`cameramodel_text` refuses those.

Read keys: ``lensmodel`` (mrcal's older names ``distortion_model`` and ``lens_model`` too, and
``DISTORTION_`` for ``LENSMODEL_``), ``intrinsics``, ``imagersize``.  Ignored on purpose
(:data:`IGNORED_KEYS`): the pose (``rt_cam_ref``, ``extrinsics``), ``valid_intrinsics_region``,
``optimization_inputs`` and ``icam_intrinsics``.  Any other key is refused with its name.
"""

from __future__ import annotations

import ast

import numpy as np

from multieye.core import geometry
from multieye.core.errors import DatasetError, InputError
from multieye.core.intrinsics import Intrinsics
from multieye.io.intrinsics_mapping import build_intrinsics, refuse_unknown
from multieye.io.yamlfile import YamlDocument

__all__ = ["LENSMODELS", "READ_KEYS", "IGNORED_KEYS", "intrinsics_from_cameramodel",
           "cameramodel_text"]

#: mrcal lens model -> number of OpenCV pinhole distortion coefficients.
LENSMODELS = {"LENSMODEL_PINHOLE": 0, "LENSMODEL_OPENCV4": 4, "LENSMODEL_OPENCV5": 5,
              "LENSMODEL_OPENCV8": 8, "LENSMODEL_OPENCV12": 12}
_NAMES = {n: name for name, n in LENSMODELS.items()}
#: Keys read, with mrcal's older names of ``lensmodel``.
READ_KEYS = ("lensmodel", "distortion_model", "lens_model", "intrinsics", "imagersize")
#: Keys ignored on purpose: the camera's pose, where mrcal trusts the fit, and the
#: calibration's own data.
IGNORED_KEYS = ("rt_cam_ref", "extrinsics", "valid_intrinsics_region", "optimization_inputs",
                "icam_intrinsics", "icam_intrinsics_optimization_inputs")


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def intrinsics_from_cameramodel(text: str, path) -> Intrinsics:
    """Intrinsics from the text of a ``.cameramodel`` file (``path`` names it in messages).

    Raises
    ------
    DatasetError
        Not a Python dictionary literal, a key neither read nor ignored, a lens model with no
        OpenCV equivalent, or numbers of the wrong count or range.
    """
    try:
        data = ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError) as exc:
        line = getattr(exc, "lineno", None)
        raise DatasetError(f"not a mrcal .cameramodel: not a Python dictionary literal "
                           f"({type(exc).__name__})", path=path, line=line) from None
    if not isinstance(data, dict) or not all(isinstance(k, str) for k in data):
        raise DatasetError("not a mrcal .cameramodel: expected a dictionary with text keys",
                           path=path, line=1)
    doc = YamlDocument(path, data, {})
    refuse_unknown(doc, data, READ_KEYS, IGNORED_KEYS)
    names = [k for k in ("lensmodel", "distortion_model", "lens_model") if k in data]
    if len(names) != 1:
        raise doc.error("expected exactly one of lensmodel (or mrcal's older distortion_model, "
                        f"lens_model), got {len(names)}")
    lensmodel = data[names[0]]
    if not isinstance(lensmodel, str):
        raise doc.error(f"expected a name such as LENSMODEL_OPENCV8, got {lensmodel!r}",
                        names[0])
    lensmodel = lensmodel.replace("DISTORTION", "LENSMODEL", 1)
    if lensmodel not in LENSMODELS:
        raise doc.error(f"{lensmodel} has no OpenCV equivalent; multieye reads "
                        f"{', '.join(LENSMODELS)}", names[0])
    n = LENSMODELS[lensmodel]
    values = data.get("intrinsics")
    if not isinstance(values, (list, tuple)) or len(values) != 4 + n \
            or not all(_number(v) for v in values):
        raise doc.error(f"expected {4 + n} numbers (fx fy cx cy and {n} distortion "
                        f"coefficients of {lensmodel}), got {values!r}"[:240], "intrinsics")
    size = data.get("imagersize")
    if size is None:
        width = height = None
    elif (isinstance(size, (list, tuple)) and len(size) == 2
          and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in size)):
        width, height = size
    else:
        raise doc.error(f"expected [width, height], positive integers, got {size!r}",
                        "imagersize")
    fx, fy, cx, cy = values[:4]
    K = [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]
    return build_intrinsics(doc, ("intrinsics", "intrinsics", "imagersize"), K,
                            list(values[4:]), "pinhole", width, height)


def _numbers(values) -> str:
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def cameramodel_text(intr: Intrinsics, T_cam_ref=None, *, note: str | None = None) -> str:
    """A ``.cameramodel`` as mrcal writes it (``mrcal.cameramodel`` reads it).

    Parameters
    ----------
    intr : Intrinsics
        Pinhole with 0, 4, 5, 8 or 12 coefficients, and the image size.
    T_cam_ref : ndarray, shape (4, 4), optional
        The reference frame in the camera's (metres), written as mrcal's ``rt_cam_ref``
        (rotation vector, translation) and, for mrcal before 2.5, ``extrinsics``; identity
        by default.
    note : str, optional
        Comment lines at the top.

    Raises
    ------
    InputError
        A lens mrcal has no model for (fisheye, tilted sensor, unified, double-sphere, eucm),
        no image size (mrcal needs ``imagersize``), or a camera matrix with skew (mrcal has
        none; the lens models ignore a skew small enough for
        :class:`~multieye.core.intrinsics.Intrinsics` to take, but the file would hold another
        camera matrix).
    """
    if intr.model != "pinhole" or intr.dist.size not in _NAMES:
        kind = ("OpenCV's fisheye" if intr.model == "fisheye"
                else "a tilted sensor (14 coefficients)" if intr.model == "pinhole"
                else f"the {intr.model} lens (only its own splined or CAHVORE models, which "
                     "this lens is not)")
        raise InputError(f"mrcal has no lens model for {kind}")
    if intr.width is None or intr.height is None:
        raise InputError("mrcal's .cameramodel needs the image size, which these intrinsics do "
                         "not know")
    if intr.K[0, 1] != 0:           # written without it, the file would be another K
        raise InputError(f"mrcal's lens models have no skew; camera matrix has skew "
                         f"{intr.K[0, 1]:g}")
    T = np.eye(4) if T_cam_ref is None else np.asarray(T_cam_ref, dtype=np.float64)
    rt = np.concatenate([geometry.rotvec_from_transform(T), T[:3, 3]])
    K = intr.K
    lines = [f"# {line}" for line in (note or "").splitlines()]
    lines += ["{", f"    'lensmodel':  '{_NAMES[intr.dist.size]}',",
              "    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....",
              f"    'intrinsics': {_numbers([K[0, 0], K[1, 1], K[0, 2], K[1, 2], *intr.dist])},",
              f"    'rt_cam_ref': {_numbers(rt)},",
              f"    'extrinsics': {_numbers(rt)}, # for compatibility with mrcal < 2.5",
              f"    'imagersize': [{int(intr.width)}, {int(intr.height)}],", "}"]
    return "\n".join(lines) + "\n"
