"""A photo's width and height from its PNG or JPEG header, without decoding it."""

from __future__ import annotations

__all__ = ["ImageHeader", "read_image_header"]

from dataclasses import dataclass

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: JPEG start-of-frame markers (baseline, progressive, lossless, arithmetic ...): C0-CF but
#: C4 (Huffman tables), C8 (reserved) and CC (arithmetic conditioning).
_SOF_MARKERS = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


@dataclass(frozen=True)
class ImageHeader:
    """What a photo's header says: ``kind`` ("png" or "jpeg"), ``width`` and ``height`` (px).

    A JPEG's EXIF orientation may swap width and height when it is shown upright; the pixel
    count is the same either way.
    """

    kind: str
    width: int
    height: int

    @property
    def pixels(self) -> int:
        """width x height."""
        return self.width * self.height


def read_image_header(data: bytes) -> ImageHeader | None:
    """Width and height of a PNG (its IHDR chunk) or a JPEG (its first SOFn segment).

    Parameters
    ----------
    data : bytes
        The file's bytes (or at least its beginning up to the frame header).

    Returns
    -------
    ImageHeader or None
        None when the bytes are neither a PNG nor a JPEG with a readable frame header.
    """
    if data.startswith(_PNG_SIGNATURE):
        # signature (8), chunk length (4), "IHDR" (4), width (4), height (4), big-endian
        if len(data) < 24 or data[12:16] != b"IHDR":
            return None
        width, height = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
        return ImageHeader("png", width, height) if width and height else None
    if data[:2] != b"\xff\xd8":
        return None
    i, n = 2, len(data)
    while i + 3 < n:
        if data[i] != 0xFF:
            return None  # lost the marker chain: not a JPEG we can read
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker == 0x01 or 0xD0 <= marker <= 0xD7:  # markers without a length
            i += 2
            continue
        if marker in (0xD9, 0xDA):  # end of image, or the scan before any frame header
            return None
        length = (data[i + 2] << 8) | data[i + 3]
        if marker in _SOF_MARKERS:
            # length (2), precision (1), height (2), width (2)
            if i + 9 > n:
                return None
            height = (data[i + 5] << 8) | data[i + 6]
            width = (data[i + 7] << 8) | data[i + 8]
            return ImageHeader("jpeg", width, height) if width and height else None
        if length < 2:
            return None
        i += 2 + length
    return None
