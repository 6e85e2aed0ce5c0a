"""What an image file's header announces (format, size, depth), read without decoding a
pixel; and a JPEG's structure checked before it is decoded (cut short, or too many scans).

The formats: PNG, JPEG, TIFF, BMP and WebP; BigTIFF, HEIF, HEIC and AVIF are named and
refused.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from camvlp.errors import InputError
from camvlp.io.limits import limit

__all__ = ["ImageHeader", "check_jpeg", "image_header"]


@dataclass(frozen=True)
class ImageHeader:
    """What an image file's header announces.

    Attributes
    ----------
    format : str
        "png", "jpeg", "tiff", "bmp" or "webp".
    width, height : int
        Pixels.
    channels : int
        Samples per pixel (1 gray, 3 colour, 4 with alpha ...).
    bytes_per_sample : int
        1 for 8-bit (and fewer bits), 2 for 16-bit, 4 or 8 for 32- and 64-bit samples.
    """

    format: str
    width: int
    height: int
    channels: int = 3
    bytes_per_sample: int = 1


#: ISO base media file brands of HEIF, HEIC and AVIF still images (bytes 8 to 12 of the file).
_HEIF_BRANDS = (b"heic", b"heix", b"heim", b"heis", b"hevc", b"hevx", b"mif1", b"msf1", b"avif")


def image_header(data: bytes | np.ndarray) -> ImageHeader:
    """The format, size and depth a file's header announces, read without decoding any pixel.

    Parameters
    ----------
    data : bytes or ndarray of uint8, shape (N,)
        The file's bytes (read in place: only the signature and the header's segments are
        looked at; a JPEG's marker segments are walked to its frame header).

    Returns
    -------
    ImageHeader

    Raises
    ------
    InputError
        An unknown format, or a header that is cut short or malformed.
    """
    data = memoryview(data).cast("B") if not isinstance(data, bytes) else data
    head = bytes(data[:16])
    try:
        if head.startswith(b"\x89PNG\r\n\x1a\n"):
            if head[12:16] != b"IHDR":
                raise InputError("malformed PNG header: no IHDR chunk first")
            w, h, depth, colour = struct.unpack(">IIBB", data[16:26])
            channels = {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}.get(colour, 4)
            return ImageHeader("png", w, h, channels, 2 if depth == 16 else 1)
        if head.startswith(b"\xff\xd8"):
            return _jpeg_header(data)
        if head[:4] in (b"II*\x00", b"MM\x00*"):
            return _tiff_header(data)
        if head.startswith(b"BM"):
            w, h = struct.unpack("<ii", data[18:26])
            return ImageHeader("bmp", abs(w), abs(h), 3)
        if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
            return ImageHeader("webp", *_webp_size(data), 3)
    except InputError:
        raise
    except (struct.error, ValueError, IndexError):
        raise InputError("image header is cut short or malformed") from None
    if head[:4] in (b"II+\x00", b"MM\x00+"):
        raise InputError("BigTIFF photos are not supported; save as TIFF, PNG or JPEG")
    if head[4:8] == b"ftyp" and head[8:12] in _HEIF_BRANDS:
        raise InputError(
            "HEIF, HEIC and AVIF photos are not read (a phone's default format): save or "
            "convert the photo as JPEG or PNG"
        )
    raise InputError("not an image, or a corrupt one: camvlp reads PNG, JPEG, TIFF, BMP, WebP")


#: A marker in a JPEG's entropy-coded data: FF followed by neither a stuffed 00, a restart
#: marker (D0 to D7) nor a fill byte FF.
_NEXT_MARKER = re.compile(rb"\xff[\x01-\xcf\xd8-\xfe]")


def _jpeg_segments(b: bytes | memoryview) -> Iterator[tuple[int, int]]:
    """The marker segments of a JPEG, in order: ``(marker, offset)`` (the offset of its FF).

    A short walk over the segments' lengths, without decoding: a start of scan (DA) is
    followed to the next marker past its entropy-coded data (stuffed bytes and restart
    markers skipped).  Ends after the end of image (D9), or where the chain of markers is
    lost or the data ends (a truncated or corrupt file: the last item is then
    ``(-1, offset)``).
    """
    i, n = 2, len(b)
    while i + 1 < n:
        if b[i] != 0xFF:
            break  # lost the marker chain
        marker = b[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        yield marker, i
        if marker == 0xD9:
            return
        if 0xD0 <= marker <= 0xD8 or marker == 0x01:  # no length
            i += 2
            continue
        if i + 3 >= n:
            break
        length = (b[i + 2] << 8) | b[i + 3]
        if length < 2:
            break
        i += 2 + length
        if marker == 0xDA:  # skip the scan's entropy-coded data
            found = _NEXT_MARKER.search(b, i)
            if found is None:
                break
            i = found.start()
    yield -1, i


def _jpeg_header(b: bytes) -> ImageHeader:
    """Size, components and precision from a JPEG's first frame header (SOF0 to SOF15, not
    DHT, JPG or DAC)."""
    for marker, i in _jpeg_segments(b):
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            precision, h, w, components = struct.unpack(">BHHB", b[i + 4 : i + 10])
            return ImageHeader("jpeg", w, h, components, 2 if precision > 8 else 1)
        if marker in (0xDA, 0xD9, -1):
            break
    raise InputError("malformed JPEG: no frame header before the image data")


def check_jpeg(raw: np.ndarray) -> None:
    """Refuse a JPEG that is cut short (no end-of-image marker) or whose decoding would cost
    more than its size says: more scans than ``CAMVLP_MAX_JPEG_SCANS`` (each scan is a pass
    over the whole picture: a few hundred bytes of them can take minutes to decode).

    Some phones append data after the image (motion-photo video, vendor trailers): the walk
    ends at the image's end-of-image marker.
    """
    most = limit("CAMVLP_MAX_JPEG_SCANS")
    scans = 0
    for marker, _ in _jpeg_segments(memoryview(raw).cast("B")):
        if marker == 0xDA:
            scans += 1
            if scans > most:
                raise InputError(
                    f"JPEG has more than {most:,} scans (decoding passes); refused before "
                    "decoding (set CAMVLP_MAX_JPEG_SCANS)"
                )
        elif marker == 0xD9:
            return
    raise InputError("photo is a truncated or corrupt JPEG (no end of image)")


def _tiff_header(b: bytes) -> ImageHeader:
    """Size and depth from a TIFF's first image file directory (tags 256, 257, 258, 277)."""
    e = "<" if b[:2] == b"II" else ">"
    (offset,) = struct.unpack(e + "I", b[4:8])
    (count,) = struct.unpack(e + "H", b[offset : offset + 2])
    entries = np.frombuffer(
        b,
        dtype=np.dtype([("tag", e + "u2"), ("type", e + "u2"), ("n", e + "u4"), ("v", "V4")]),
        count=count,
        offset=offset + 2,
    )
    size = {}
    for tag in (256, 257, 258, 277):  # width, height, bits per sample, samples per pixel
        hit = entries[entries["tag"] == tag]
        if hit.size:
            raw = hit[0]["v"].tobytes()
            if hit[0]["type"] != 3:  # LONG
                size[tag] = struct.unpack(e + "I", raw)[0]
            elif hit[0]["n"] <= 2:  # SHORT values that fit in the entry
                size[tag] = struct.unpack(e + "H", raw[:2])[0]
            else:  # SHORT values stored elsewhere (bits per sample of colour images)
                (where,) = struct.unpack(e + "I", raw)
                size[tag] = struct.unpack(e + "H", b[where : where + 2])[0]
    if 256 not in size or 257 not in size:
        raise InputError("malformed TIFF: no image width or height")
    bits = min(size.get(258, 8), 64)
    return ImageHeader("tiff", size[256], size[257], size.get(277, 1), max(1, bits // 8))


def _webp_size(b: bytes) -> tuple[int, int]:
    """Width and height of a WebP's VP8, VP8L or VP8X (extended) chunk."""
    chunk = b[12:16]
    if chunk == b"VP8X":
        w = int.from_bytes(b[24:27], "little") + 1
        h = int.from_bytes(b[27:30], "little") + 1
        return w, h
    if chunk == b"VP8L":
        bits = int.from_bytes(b[21:25], "little")
        return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
    if chunk == b"VP8 ":
        w, h = struct.unpack("<HH", b[26:30])
        return w & 0x3FFF, h & 0x3FFF
    raise InputError("malformed WebP: unknown first chunk")
