"""Image file headers: format, size and EXIF orientation from the first bytes, no decoding.

A compressed image can claim any size: a 312-byte PNG may say 60000 x 60000, and decoding it
would ask for gigabytes.  :func:`image_header` reads the width and height (and the EXIF
orientation, where the format carries one) of the formats multieye reads (PNG, JPEG, BMP,
TIFF, PGM/PPM/PBM, WebP) with :mod:`struct` only; :func:`size_problem` says why a stated size
is refused (beyond :data:`~multieye.core.limits.MAX_IMAGE_PIXELS` or
:data:`~multieye.core.limits.MAX_IMAGE_SIDE_PX`).  Used for image files
(:mod:`multieye.imaging.image_file`) and for the compressed images of bags
(:mod:`multieye.io.rosbag`), before either is decoded.

"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass

from multieye.core.limits import MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE_PX

__all__ = ["ImageHeader", "image_header", "size_problem", "cut_short", "FORMATS"]

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



def size_problem(width: int, height: int, what: str) -> str | None:
    """Why an image of ``width`` x ``height`` pixels, as ``what`` states, is not decoded.

    Returns
    -------
    str or None
        ``"the <what> states W x H pixels, more than ..."`` (or not a positive size); None
        when the size is within :data:`~multieye.core.limits.MAX_IMAGE_PIXELS` and
        :data:`~multieye.core.limits.MAX_IMAGE_SIDE_PX` per side.
    """
    if width <= 0 or height <= 0:
        return f"the {what} states {width} x {height} pixels"
    if max(width, height) > MAX_IMAGE_SIDE_PX or width * height > MAX_IMAGE_PIXELS:
        return (f"the {what} states {width} x {height} pixels, more than the "
                f"{MAX_IMAGE_PIXELS / 1e6:g} megapixels (or {MAX_IMAGE_SIDE_PX} per side) "
                "accepted; not decoded")
    return None


def cut_short(data: bytes, header: ImageHeader) -> str | None:
    """Why a stream whose header was read is not decoded because its end is missing: a PNG
    without its ``IEND`` chunk (a file or a bag message cut short; libpng would write
    ``libpng error: PNG input buffer is incomplete`` on the process's standard error, below
    OpenCV's log level, beside multieye's one line).  None otherwise (other formats'
    decoders fail silently)."""
    if header.format != "PNG":
        return None
    view = memoryview(data).cast("B")
    # IEND is the last chunk: look at the tail first, the whole stream only when it is not
    # there (bytes after IEND are allowed), so a whole file is not copied per image
    if bytes(view[-_PNG_TAIL:]).rfind(b"IEND") < 0 and bytes(view).rfind(b"IEND") < 0:
        return "the PNG stream is cut short (no IEND chunk)"
    return None


#: Bytes at a PNG stream's end searched first for its IEND chunk (12 bytes in a whole file).
_PNG_TAIL = 4096
