"""Reading photographs: upright as their EXIF says, refusing what is not a whole image."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from camvlp.errors import InputError

__all__ = ["decode_image", "load_image"]


def load_image(path: str | Path) -> np.ndarray:
    """Read a photograph, upright as its EXIF says: 8- or 16-bit, BGR (H, W, 3) or gray (H, W).

    Raises
    ------
    InputError
        Missing file, not an image, or a truncated/corrupt image.
    """
    p = Path(path)
    if not p.exists():
        raise InputError("photo not found", p)
    if p.is_dir():
        raise InputError("photo is a directory", p)
    return decode_image(np.fromfile(str(p), dtype=np.uint8), p)


def decode_image(raw: bytes | np.ndarray, source: str | Path = "photo") -> np.ndarray:
    """Decode an encoded photograph (JPEG, PNG, TIFF ... bytes) as :func:`load_image` does.

    Parameters
    ----------
    raw : bytes or ndarray of uint8, shape (N,)
        The encoded file's bytes.
    source : str or Path
        Names the photo in error messages.

    Returns
    -------
    ndarray, shape (H, W, 3) BGR or (H, W) gray, uint8 or uint16
        Upright as the EXIF orientation says.

    Raises
    ------
    InputError
        Empty, not an image, or a truncated/corrupt image.
    """
    p = source
    raw = np.frombuffer(raw, dtype=np.uint8) if isinstance(raw, (bytes, bytearray)) else raw
    if raw.size == 0:
        raise InputError("photo is empty", p)
    if _truncated_jpeg(raw):
        raise InputError("photo is a truncated JPEG", p)
    # Not IMREAD_UNCHANGED: the other modes apply the EXIF orientation, so the array is the
    # picture as viewers show it (phones often store landscape pixels with a "rotate" tag).
    img = cv2.imdecode(raw, cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH)
    if img is not None and img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    if img is None:
        raise InputError("not an image, or a corrupt one", p)
    return img


def _truncated_jpeg(raw: np.ndarray) -> bool:
    """A JPEG (starts with FF D8) whose end-of-image marker FF D9 is missing.

    Some phones append data after the image (motion-photo video, vendor trailers), so when
    the file does not end with FF D9 the marker segments are walked to find the image's end.
    """
    if raw.size < 4 or raw[0] != 0xFF or raw[1] != 0xD8:
        return False
    if b"\xff\xd9" in raw[-64:].tobytes():
        return False
    b = raw.tobytes()
    i = 2
    while i + 1 < len(b):
        if b[i] != 0xFF:
            return True  # lost the marker chain: corrupt or cut
        marker = b[i + 1]
        if marker == 0xD9:
            return False
        if marker == 0xFF or 0xD0 <= marker <= 0xD7 or marker == 0x01:
            i += 1 if marker == 0xFF else 2  # fill byte or marker without a length
            continue
        if i + 3 >= len(b):
            return True
        i += 2 + ((b[i + 2] << 8) | b[i + 3])
        if marker == 0xDA:  # start of scan: skip entropy-coded data to the next marker
            while True:
                j = b.find(b"\xff", i)
                if j < 0 or j + 1 >= len(b):
                    return True
                if b[j + 1] == 0x00 or 0xD0 <= b[j + 1] <= 0xD7:
                    i = j + 2  # stuffed byte or restart marker
                elif b[j + 1] == 0xFF:
                    i = j + 1  # fill byte before a marker
                else:
                    i = j
                    break
    return True
