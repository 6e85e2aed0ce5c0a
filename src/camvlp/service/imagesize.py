"""A photo's width and height from its PNG or JPEG header, without decoding it.

The service accepts only PNG and JPEG uploads; the header is read by the package's one
header reader, :func:`camvlp.io.image_header.image_header`.
"""

from __future__ import annotations

from dataclasses import dataclass

from camvlp.errors import InputError
from camvlp.io.image_header import image_header

__all__ = ["ImageHeader", "read_image_header"]


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
    try:
        header = image_header(data)
    except InputError:
        return None
    if header.format not in ("png", "jpeg") or not (header.width and header.height):
        return None
    return ImageHeader(header.format, header.width, header.height)
