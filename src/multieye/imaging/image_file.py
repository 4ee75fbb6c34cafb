"""Reading one image file: its size from the header, checked before decoding.

A compressed image can claim any size: a 312-byte PNG may say 60000 x 60000, and decoding it
would ask for gigabytes.  :func:`image_header` reads the width and height (and the EXIF
orientation, where the format carries one) from the first bytes of the formats multieye reads
(PNG, JPEG, BMP, TIFF, PGM/PPM/PBM, WebP) without decoding; :func:`read_gray` refuses an image
beyond :data:`~multieye.core.limits.MAX_IMAGE_PIXELS` (or a side beyond
:data:`~multieye.core.limits.MAX_IMAGE_SIDE_PX`), or a file whose header it cannot read, and
only then decodes, from the bytes already read (the file is opened once, as a regular file,
with a byte bound: :mod:`multieye.core.regular_files`).

EXIF orientation is ignored: the pixels are used as the sensor wrote them
(``cv2.IMREAD_IGNORE_ORIENTATION``), since the intrinsics and the target's detections are in
the sensor's frame; an orientation other than 1 (as stored) gives a note.  One exception
(:func:`turns_to_fit`): an image whose orientation turns it by a quarter (5 to 8) and whose
stored size is the intrinsics' size transposed is turned as its EXIF says, as
``cv2.imread`` shows it by default, since the intrinsics can only be of the turned image
(made by a tool that applied the EXIF); a note says so.

A camera's ``crop:`` (its region of a side-by-side stereo frame) is applied here and only here:
to an image file by :func:`read_region` (what the detection workers read), to a video's or a
bag's frames by :func:`cropped_frames` (the stream the detection consumes); both cut with
:func:`cropped`.

>>> from multieye.imaging.image_file import read_gray
>>> image, reason, notes = read_gray("cam0/1700000000.5.png")      # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np

from multieye.core.errors import DatasetError
from multieye.core.image_header import (FORMATS, ImageHeader, cut_short, image_header,
                                        size_problem)
from multieye.core.limits import MAX_IMAGE_BYTES
from multieye.core.regular_files import read_bounded

__all__ = ["ImageHeader", "image_header", "read_gray", "to_8_bits", "read_region", "cropped", "cropped_frames",
           "turns_to_fit", "FORMATS"]


def checked_bytes(path) -> tuple[bytes | None, ImageHeader | None, str | None]:
    """An image file's bytes, read with a bound, and its header, checked before any decoding.

    Returns
    -------
    data : bytes or None
    header : ImageHeader or None
    reason : str or None
        Why the file is not decoded, starting with ``unreadable file:`` (missing, not a
        regular file, empty, too large, a header that is none of :data:`FORMATS`, a size
        beyond the bounds); None when ``data`` and ``header`` may be decoded.
    """
    try:
        data = read_bounded(path, what="image", max_bytes=MAX_IMAGE_BYTES)
    except DatasetError as exc:
        reason = "not found" if exc.reason == "image not found" else exc.reason
        return None, None, f"unreadable file: {reason}"
    if not data:
        return None, None, "unreadable file: empty (0 bytes)"
    header = image_header(data)
    if header is None:
        return None, None, (f"unreadable file: not a {FORMATS} image (or its header is cut "
                            "short)")
    problem = (size_problem(header.width, header.height, f"{header.format} header")
               or cut_short(data, header))
    if problem is not None:
        return None, None, f"unreadable file: {problem}"
    return data, header, None


def turns_to_fit(header: ImageHeader, fit: tuple[int | None, int | None] | None) -> bool:
    """Whether an image is to be turned as its EXIF orientation says: the orientation turns
    it by a quarter (5 to 8) and its stored ``(width, height)`` is ``fit`` (the intrinsics'
    image size) transposed, so only the turned image fits the intrinsics."""
    return (fit is not None and None not in fit and header.orientation in (5, 6, 7, 8)
            and (header.height, header.width) == tuple(fit) and fit[0] != fit[1])


#: Set once OpenCV's log level is set: a truncated or corrupt image made OpenCV write its own
#: lines (``[ WARN:0@1.3] ... PNG input buffer is incomplete``, ``[ERROR:0@11.4] imdecode_
#: ... can't read data``) wherever decoding ran with the terminal's standard error (one
#: process, ``--processes 1``, calibrate-many's workers), one or two per image, beside
#: multieye's one line per cause.
_QUIET: list = []


def decode_gray(data: bytes, reduce: int = 1, *, orient: bool = False
                ) -> tuple[np.ndarray | None, str | None]:
    """Checked bytes (:func:`checked_bytes`) decoded to 8-bit gray pixels as stored (EXIF
    orientation ignored; ``orient``: applied, as OpenCV applies it, :func:`turns_to_fit`),
    at 1/``reduce`` of the size (``reduce`` 1, 2, 4 or 8; JPEG decoders scale while
    decoding, other formats are decoded whole). Returns the image or None and the reason."""
    import cv2  # noqa: PLC0415 (heavy: OpenCV loads only when an image is decoded)

    if not _QUIET:      # OpenCV's own lines below fatal: the reason returned is the message
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_FATAL)
        _QUIET.append(True)
    flag = {1: cv2.IMREAD_GRAYSCALE, 2: cv2.IMREAD_REDUCED_GRAYSCALE_2,
            4: cv2.IMREAD_REDUCED_GRAYSCALE_4, 8: cv2.IMREAD_REDUCED_GRAYSCALE_8}[reduce]
    if not orient:
        flag |= cv2.IMREAD_IGNORE_ORIENTATION
    try:
        image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), flag | cv2.IMREAD_ANYDEPTH)
    except cv2.error as exc:
        lines = str(exc).strip().splitlines()
        return None, f"unreadable file: OpenCV cannot decode it ({lines[-1] if lines else exc})"
    if image is None or image.size == 0:
        return None, "unreadable file: not an image OpenCV can decode (truncated or corrupt?)"
    if image.dtype != np.uint8:     # 16-bit (10 or 12 bits of a machine-vision camera), float
        image = to_8_bits(image)
    return image, None


def to_8_bits(image: np.ndarray) -> np.ndarray:
    """A 16-bit or float gray image scaled to 8 bits by its brightest pixel, as a bag's
    16-bit images are (:func:`multieye.imaging.detect.to_gray`): 10 or 12 bits stored in 16
    keep their contrast (OpenCV's 8-bit decoding keeps the top 8 of the 16 bits: 4 grey
    levels of a 10-bit image)."""
    img = np.nan_to_num(image.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    top = float(img.max())
    return np.clip(np.rint(img * (255.0 / top if top > 0 else 1.0)), 0, 255).astype(np.uint8)


def read_gray(path, fit: tuple[int | None, int | None] | None = None
              ) -> tuple[np.ndarray | None, str | None, tuple[str, ...]]:
    """One image file as 8-bit gray pixels, as the sensor wrote them.

    Parameters
    ----------
    path : path-like
    fit : (width, height), optional
        The intrinsics' image size: an image whose EXIF orientation turns it by a quarter
        and whose stored size is this transposed is turned (:func:`turns_to_fit`).

    Returns
    -------
    image : ndarray, shape (H, W), uint8, or None
    reason : str or None
        Why there is no image, starting with ``unreadable file:`` (missing, not a regular
        file, empty, too large, a header that is none of :data:`FORMATS`, a size beyond the
        bounds, a decoder failure).
    notes : tuple of str
        An EXIF orientation other than 1, which was ignored (or applied).
    """
    data, header, reason = checked_bytes(path)
    if reason is not None:
        return None, reason, ()
    turn = turns_to_fit(header, fit)
    image, reason = decode_gray(data, orient=turn)
    if reason is not None:
        return None, reason, ()
    notes = ()
    if turn:
        notes = (f"EXIF orientation {header.orientation} applied: the stored {header.width} x "
                 f"{header.height} pixels turned to the intrinsics' {fit[0]} x {fit[1]}, as "
                 "cv2.imread shows them",)
    elif header.orientation != 1:
        notes = (f"EXIF orientation {header.orientation} ignored: the pixels are used as "
                 "stored (the sensor's frame)",)
    return image, None, notes


def cropped(image: np.ndarray, crop: tuple[int, int, int, int]
            ) -> tuple[np.ndarray | None, str | None]:
    """The region ``crop = (x, y, width, height)`` of ``image`` (a camera's part of a
    side-by-side or top-bottom stereo frame; its pixel (0, 0) is the image's (x, y)), or
    None and why when the image does not hold it."""
    x, y, w, h = (int(v) for v in crop)
    height, width = image.shape[:2]
    if x + w > width or y + h > height:
        return None, (f"the camera's crop [{x}, {y}, {w}, {h}] reaches beyond the {width} x "
                      f"{height} image")
    return image[y:y + h, x:x + w], None


def read_region(path, fit: tuple[int | None, int | None] | None, crop
                ) -> tuple[np.ndarray | None, str | None, tuple[str, ...]]:
    """:func:`read_gray` of the file, then its region ``crop`` (None: the whole image, which
    ``fit`` then concerns; with a crop ``fit`` is not applied: the region has the lens's size)."""
    image, reason, notes = read_gray(path, None if crop is not None else fit)
    if image is not None and crop is not None:
        image, reason = cropped(image, crop)
    return image, reason, notes


def cropped_frames(items, crop: tuple[int, int, int, int] | None):
    """``(label, image)`` frames of a video or a bag, each cut to the camera's ``crop``
    (:func:`cropped`; None: as they are); DatasetError when a frame does not hold it (a
    video's frames have one size: the crop is wrong, not the frame)."""
    if crop is None:
        yield from items
        return
    for label, image in items:
        part, reason = cropped(image, crop)
        if part is None:
            raise DatasetError(f"{label}: {reason}")
        yield label, part
