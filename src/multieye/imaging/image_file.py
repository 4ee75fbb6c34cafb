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
the sensor's frame; an orientation other than 1 (as stored) gives a note.

>>> from multieye.imaging.image_file import read_gray
>>> image, reason, notes = read_gray("cam0/1700000000.5.png")      # doctest: +SKIP
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

import numpy as np

from multieye.core.errors import DatasetError
from multieye.core.limits import MAX_IMAGE_BYTES, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE_PX
from multieye.core.regular_files import read_bounded

__all__ = ["ImageHeader", "image_header", "read_gray", "FORMATS"]

#: The formats whose header is read (OpenCV decodes them).
FORMATS = "PNG, JPEG, BMP, TIFF, PGM/PPM/PBM or WebP"

_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
_PNM_TOKEN = re.compile(rb"(?:\s|#[^\n]*\n?)*(\S+)")


@dataclass(frozen=True)
class ImageHeader:
    """What an image file's header states.

    Attributes
    ----------
    format : str
        ``"PNG"``, ``"JPEG"``, ``"BMP"``, ``"TIFF"``, ``"PNM"`` or ``"WebP"``.
    width, height : int
        Pixels, as stored.
    orientation : int
        EXIF orientation tag (1 to 8; 1, as stored, when absent).
    """

    format: str
    width: int
    height: int
    orientation: int = 1


def _tiff_entries(data: bytes, base: int = 0) -> dict[int, int]:
    """Tags of the first IFD of a TIFF structure (``base``: where it starts in ``data``)."""
    head = data[base:base + 16]
    if head[:4] in (b"II*\x00", b"MM\x00*"):
        e = "<" if head[:2] == b"II" else ">"
        (offset,) = struct.unpack(e + "I", head[4:8])
        big = False
    elif head[:4] in (b"II+\x00", b"MM\x00+"):          # BigTIFF
        e = "<" if head[:2] == b"II" else ">"
        (offset,) = struct.unpack(e + "Q", head[8:16])
        big = True
    else:
        return {}
    pos = base + offset
    count_fmt, entry_size, count_size = (("Q", 20, 8) if big else ("H", 12, 2))
    (n,) = struct.unpack(e + count_fmt, data[pos:pos + count_size])
    sizes = {1: "B", 3: "H", 4: "I", 16: "Q"}
    tags = {}
    for k in range(min(n, 4096)):
        at = pos + count_size + k * entry_size
        entry = data[at:at + entry_size]
        if len(entry) < entry_size:
            break
        tag, typ = struct.unpack(e + "HH", entry[:4])
        if typ in sizes:
            value_at = 12 if big else 8        # after tag, type and the value count
            (value,) = struct.unpack(e + sizes[typ], entry[value_at:value_at
                                                           + struct.calcsize(sizes[typ])])
            tags[tag] = int(value)
    return tags


def _jpeg(data: bytes) -> ImageHeader | None:
    pos, orientation = 2, 1
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            return None
        marker = data[pos + 1]
        if marker == 0xFF:                     # fill byte
            pos += 1
            continue
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            pos += 2
            continue
        (length,) = struct.unpack(">H", data[pos + 2:pos + 4])
        segment = data[pos + 4:pos + 2 + length]
        if marker == 0xE1 and segment[:6] == b"Exif\x00\x00":
            orientation = _tiff_entries(segment, 6).get(274, 1)
        if marker in _JPEG_SOF and len(segment) >= 5:
            height, width = struct.unpack(">HH", segment[1:5])
            return ImageHeader("JPEG", width, height, orientation)
        if marker == 0xDA:                     # start of scan before any frame header
            return None
        pos += 2 + length
    return None


def _png(data: bytes) -> ImageHeader | None:
    if data[12:16] != b"IHDR":
        return None
    width, height = struct.unpack(">II", data[16:24])
    orientation, pos = 1, 8
    while pos + 8 <= len(data):                # an eXIf chunk before the pixels
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        if kind == b"eXIf":
            orientation = _tiff_entries(data[pos + 8:pos + 8 + length]).get(274, 1)
        if kind in (b"IDAT", b"IEND"):
            break
        pos += 12 + length
    return ImageHeader("PNG", width, height, orientation)


def _webp(data: bytes) -> ImageHeader | None:
    kind = data[12:16]
    if kind == b"VP8 " and data[23:26] == b"\x9d\x01\x2a":
        w, h = struct.unpack("<HH", data[26:30])
        return ImageHeader("WebP", w & 0x3FFF, h & 0x3FFF)
    if kind == b"VP8L" and data[20:21] == b"\x2f":
        (bits,) = struct.unpack("<I", data[21:25])
        return ImageHeader("WebP", (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1)
    if kind == b"VP8X":
        w = int.from_bytes(data[24:27], "little") + 1
        h = int.from_bytes(data[27:30], "little") + 1
        return ImageHeader("WebP", w, h)
    return None


def _pnm(data: bytes) -> ImageHeader | None:
    tokens, pos = [], 2
    for _ in range(2):
        m = _PNM_TOKEN.match(data, pos)
        if m is None or not m.group(1).isdigit():
            return None
        tokens.append(int(m.group(1)))
        pos = m.end()
    return ImageHeader("PNM", tokens[0], tokens[1])


def image_header(data: bytes) -> ImageHeader | None:
    """Format, size and EXIF orientation from an image file's first bytes, without decoding.

    Parameters
    ----------
    data : bytes
        The file's content (the first few kilobytes suffice for most files; a JPEG's frame
        header may follow large metadata segments).

    Returns
    -------
    ImageHeader or None
        None when the bytes are none of :data:`FORMATS`, or their header is cut short.
    """
    try:
        if data[:8] == b"\x89PNG\r\n\x1a\n":
            return _png(data)
        if data[:2] == b"\xff\xd8":
            return _jpeg(data)
        if data[:2] == b"BM" and len(data) >= 26:
            (dib,) = struct.unpack("<I", data[14:18])
            if dib == 12:
                w, h = struct.unpack("<HH", data[18:22])
            else:
                w, h = struct.unpack("<ii", data[18:26])
            return ImageHeader("BMP", abs(w), abs(h))
        if data[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
            tags = _tiff_entries(data)
            if 256 not in tags or 257 not in tags:
                return None
            return ImageHeader("TIFF", tags[256], tags[257], tags.get(274, 1))
        if data[:1] == b"P" and data[1:2] in b"123456" and len(data) > 2:
            return _pnm(data)
        if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
            return _webp(data)
    except struct.error:           # cut short inside a header
        return None
    return None


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
    w, h = header.width, header.height
    if w <= 0 or h <= 0:
        return None, None, f"unreadable file: the {header.format} header states {w} x {h} pixels"
    if max(w, h) > MAX_IMAGE_SIDE_PX or w * h > MAX_IMAGE_PIXELS:
        return None, None, (f"unreadable file: the {header.format} header states {w} x {h} "
                            f"pixels, more than the {MAX_IMAGE_PIXELS / 1e6:g} megapixels (or "
                            f"{MAX_IMAGE_SIDE_PX} per side) accepted; not decoded")
    return data, header, None


def decode_gray(data: bytes, reduce: int = 1) -> tuple[np.ndarray | None, str | None]:
    """Checked bytes (:func:`checked_bytes`) decoded to 8-bit gray pixels as stored (EXIF
    orientation ignored), at 1/``reduce`` of the size (``reduce`` 1, 2, 4 or 8; JPEG decoders
    scale while decoding, other formats are decoded whole). Returns the image or None and
    the reason."""
    import cv2  # noqa: PLC0415 (heavy: OpenCV loads only when an image is decoded)

    flag = {1: cv2.IMREAD_GRAYSCALE, 2: cv2.IMREAD_REDUCED_GRAYSCALE_2,
            4: cv2.IMREAD_REDUCED_GRAYSCALE_4, 8: cv2.IMREAD_REDUCED_GRAYSCALE_8}[reduce]
    try:
        image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8),
                             flag | cv2.IMREAD_IGNORE_ORIENTATION)
    except cv2.error as exc:
        lines = str(exc).strip().splitlines()
        return None, f"unreadable file: OpenCV cannot decode it ({lines[-1] if lines else exc})"
    if image is None or image.size == 0:
        return None, "unreadable file: not an image OpenCV can decode (truncated or corrupt?)"
    return image, None


def read_gray(path) -> tuple[np.ndarray | None, str | None, tuple[str, ...]]:
    """One image file as 8-bit gray pixels, as the sensor wrote them.

    Returns
    -------
    image : ndarray, shape (H, W), uint8, or None
    reason : str or None
        Why there is no image, starting with ``unreadable file:`` (missing, not a regular
        file, empty, too large, a header that is none of :data:`FORMATS`, a size beyond the
        bounds, a decoder failure).
    notes : tuple of str
        An EXIF orientation other than 1, which was ignored.
    """
    data, header, reason = checked_bytes(path)
    if reason is not None:
        return None, reason, ()
    image, reason = decode_gray(data)
    if reason is not None:
        return None, reason, ()
    notes = ()
    if header.orientation != 1:
        notes = (f"EXIF orientation {header.orientation} ignored: the pixels are used as "
                 "stored (the sensor's frame)",)
    return image, None, notes
