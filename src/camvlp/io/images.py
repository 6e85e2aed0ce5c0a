"""Reading photographs: one gate for image files and image arrays.

A photo file is read only when it is a regular file within the size limit, its header (PNG,
JPEG, TIFF, BMP or WebP) names a size within the pixel limit, and its decoder reports no damage;
then it is turned upright as its EXIF says and converted to the working type.  An image array
given to the library passes the same checks on its shape, type and size.  The limits are in
:mod:`camvlp.io.limits`, the header and a JPEG's structure are read by
:mod:`camvlp.io.image_header`.
"""

from __future__ import annotations

import io
import os
import sys
import tempfile
import threading
from pathlib import Path

import cv2
import numpy as np

from camvlp.errors import InputError
from camvlp.io.image_header import ImageHeader, check_jpeg, image_header
from camvlp.io.limits import check_pixels, limit, read_regular_file
from camvlp.model.readout import Readout

__all__ = ["as_image", "decode_image", "exif_readout", "load_image", "read_photo"]

#: Decoder messages that mean the pixels are not the whole picture (libjpeg, libpng, libtiff).
_DAMAGE = ("corrupt", "premature end", "error", "invalid", "bad ", "truncated", "crc")

_STDERR_LOCK = threading.Lock()

#: EXIF orientation -> readout of the upright photo, for a sensor that reads its own rows
#: from the top down: the tag says how the stored (sensor) pixels are turned for display.
#: Orientation 1 (upright as stored) is not here: it says nothing of the sensor, for a phone
#: may turn the pixels itself before storing them (a Lumia 1020's portrait photos are stored
#: upright, their sensor rows along the image's columns).
_EXIF_READOUTS = {
    3: Readout.ROWS_REVERSED,  # turned half a turn: time runs bottom up
    6: Readout.COLUMNS_REVERSED,  # a quarter turn clockwise: the first row is the last column
    8: Readout.COLUMNS,  # a quarter turn counter-clockwise: the first row is the first column
}


def exif_readout(photo: str | Path | bytes) -> Readout | None:
    """The readout a photo's EXIF orientation suggests for it once loaded upright by
    :func:`load_image`: a hint (:attr:`camvlp.pipeline.locate.LocateSettings.readout_hint`)
    that the stripes must bear out, never taken on its own word.

    ``photo`` is the file's path or its bytes as :func:`read_photo` gave them (so that a photo
    is read once).  Assumes a sensor that reads its native rows from the top down (the usual
    one).  None when the file has no orientation tag, orientation 1 (stored upright: the
    phone may have turned the pixels itself, so the tag says nothing of the sensor), a
    mirrored one, or cannot be read.
    """
    if isinstance(photo, bytes):
        data = photo
    else:
        try:  # through the one gate: a named pipe must not block here either
            data = read_photo(photo)
        except InputError:
            return None
    try:
        from PIL import Image

        with Image.open(io.BytesIO(data)) as im:
            tag = im.getexif().get(0x0112)
    except Exception:  # no EXIF is not an error: the direction is found otherwise
        return None
    return _EXIF_READOUTS.get(int(tag)) if isinstance(tag, int) else None


def load_image(path: str | Path, *, max_pixels: int | None = None) -> np.ndarray:
    """Read a photograph, upright as its EXIF says.

    Parameters
    ----------
    path : str or Path
        A PNG, JPEG, TIFF, BMP or WebP file.
    max_pixels : int, optional
        Largest width x height accepted (default: ``CAMVLP_MAX_PIXELS``, else 200 million).

    Returns
    -------
    ndarray, shape (H, W, 3) BGR or (H, W) gray
        ``uint8`` or ``uint16``; other pixel types (signed, 32-bit, float) converted as
        :func:`as_image` says.

    Raises
    ------
    InputError
        Missing, not a regular file, too large, an unknown format, a header over the pixel
        limit, or a truncated or corrupt image.
    """
    p = Path(path)
    return decode_image(read_photo(p), p, max_pixels=max_pixels)


def read_photo(path: str | Path) -> bytes:
    """A photo file's bytes, not decoded: a regular file of at most ``CAMVLP_MAX_IMAGE_BYTES``.

    Raises
    ------
    InputError
        Missing, not a regular file, or too large.
    """
    return read_regular_file(Path(path), "photo", limit("CAMVLP_MAX_IMAGE_BYTES"))


def decode_image(
    raw: bytes | np.ndarray, source: str | Path = "photo", *, max_pixels: int | None = None
) -> np.ndarray:
    """Decode an encoded photograph held in memory (an upload, say) through the same gate as
    :func:`load_image`: header first, limits, damage refused, converted to the working type.

    Parameters
    ----------
    raw : bytes or ndarray of uint8, shape (N,)
        The encoded file's bytes (at most ``CAMVLP_MAX_IMAGE_BYTES``).
    source : str or Path
        Names the photo in error messages.
    max_pixels : int, optional
        Largest width x height accepted (default: ``CAMVLP_MAX_PIXELS``, else 200 million).

    Returns
    -------
    ndarray, shape (H, W, 3) BGR or (H, W) gray, uint8 or uint16
        Upright as the EXIF orientation says.

    Raises
    ------
    InputError
        Empty, too large, an unknown format, a header over the limits, or a truncated or
        corrupt image; naming ``source``.
    """
    try:
        return _decode(np.frombuffer(raw, dtype=np.uint8).reshape(-1), max_pixels)
    except InputError as exc:
        raise InputError(exc.what, source) from None
    except (TypeError, ValueError) as exc:  # not bytes
        raise InputError(f"photo must be bytes: {_first_line(exc)}", source) from None


def _decode(raw: np.ndarray, max_pixels: int | None) -> np.ndarray:
    if raw.size == 0:
        raise InputError("photo is empty")
    most = limit("CAMVLP_MAX_IMAGE_BYTES")
    if raw.size > most:
        raise InputError(f"photo is {raw.size:,} bytes, over the limit of {most:,}")
    header = image_header(raw)
    check_pixels(header.width, header.height, max_pixels)
    _check_decoded_bytes(header, max_pixels)
    if header.format == "jpeg":
        check_jpeg(raw)
    # Not IMREAD_UNCHANGED: the other modes apply the EXIF orientation, so the array is the
    # picture as viewers show it (phones often store landscape pixels with a "rotate" tag).
    img, messages = _decode_quietly(raw)
    fmt = header.format.upper()
    damage = [m for m in messages if any(word in m.lower() for word in _DAMAGE)]
    if damage:
        raise InputError(f"corrupt {fmt} refused: {damage[0]}")
    if img is None:
        raise InputError("not an image, or a corrupt one")
    return as_image(img, max_pixels=max_pixels)


def as_image(image: object, *, max_pixels: int | None = None, name: str = "image") -> np.ndarray:
    """The gate for an image array: shape, type and size checked, converted to the working type.

    Parameters
    ----------
    image : array_like, shape (H, W), (H, W, 1), (H, W, 2), (H, W, 3) or (H, W, 4)
        Gray, gray + alpha, BGR or BGRA pixels of any real type: bool, (u)int8 to (u)int64,
        float16 to float64.
    max_pixels : int, optional
        Largest H x W accepted (default: ``CAMVLP_MAX_PIXELS``, else 200 million).
    name : str
        The argument's name, for the error message.

    Returns
    -------
    ndarray, shape (H, W) or (H, W, 3)
        ``uint8`` and ``uint16`` pass unchanged; ``bool`` becomes ``uint8`` (True -> 255);
        other integers lose their negative values (-> 0) and become ``uint8`` when their
        maximum fits in 8 bits, ``uint16`` when it fits in 16, else ``uint16`` scaled by
        65535 / their maximum; floats become ``uint16``, scaled by 65535 when within [0, 1],
        else by 65535 / their maximum.  Alpha is dropped.

    Raises
    ------
    InputError
        Not an array of numbers, the wrong shape, empty, over the pixel limit, or a float
        image with NaN or infinite pixels.
    """
    if image is None:
        raise InputError(f"{name} is None, not an image array")
    if isinstance(image, (str, bytes, Path)):
        raise InputError(f"{name} must be an image array, got a {type(image).__name__}")
    try:
        img = np.asarray(image)
    except (ValueError, TypeError) as exc:  # a ragged nested list
        raise InputError(f"{name} is not an array of numbers: {_first_line(exc)}") from None
    kind = img.dtype.kind
    if kind not in "biuf":
        raise InputError(f"{name} must hold real numbers, got dtype {img.dtype}")
    if img.ndim == 3 and img.shape[2] in (1, 2):
        img = img[:, :, 0]
    elif img.ndim == 3 and img.shape[2] == 4:
        img = img[:, :, :3]
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3):
        raise InputError(f"{name} must be (H, W) gray or (H, W, 3) BGR, got shape {img.shape}")
    h, w = img.shape[:2]
    if h == 0 or w == 0:
        raise InputError(f"{name} is empty (shape {img.shape})")
    check_pixels(w, h, max_pixels)
    if kind == "b":
        return np.ascontiguousarray(img, dtype=np.uint8) * np.uint8(255)
    if img.dtype == np.uint8 or img.dtype == np.uint16:
        return np.ascontiguousarray(img)
    if kind in "iu":  # other integers: values kept where they fit, else scaled by the maximum
        pos = np.clip(img, 0, None)
        hi = int(pos.max())
        if hi <= 0xFF:
            return pos.astype(np.uint8)
        if hi <= 0xFFFF:
            return pos.astype(np.uint16)
        return np.rint(pos * (65535.0 / hi)).astype(np.uint16)
    bad = int(np.count_nonzero(~np.isfinite(img)))
    if bad:
        raise InputError(f"{name} has {bad} NaN or infinite pixels")
    hi = float(img.max())
    scale = 65535.0 if hi <= 1.0 else 65535.0 / hi
    src = img.astype(np.float32) if img.dtype == np.float16 else img  # float16 tops at 65504
    with np.errstate(over="ignore", under="ignore"):  # huge negatives: -inf, clipped to 0
        f = np.multiply(src, scale)  # in the image's own type: the positive values fit
        np.clip(f, 0, 65535, out=f)  # in place from here on: one float copy at most
    np.rint(f, out=f)
    return f.astype(np.uint16)


def _check_decoded_bytes(header: ImageHeader, max_pixels: int | None) -> None:
    """Refuse an image whose decoded samples would take more bytes than an 8-bit colour image
    at the pixel limit (a 32-bit float TIFF at the limit would otherwise take 2.4 GB)."""
    budget = 3 * limit("CAMVLP_MAX_PIXELS", max_pixels)
    channels = min(header.channels, 3)  # decoded as gray or BGR: alpha is dropped
    decoded = header.width * header.height * channels * header.bytes_per_sample
    if decoded > budget:
        raise InputError(
            f"image is {header.width} x {header.height} x {channels} samples of "
            f"{8 * header.bytes_per_sample} bits = {decoded:,} bytes decoded, over the limit of "
            f"{budget:,} (3 x CAMVLP_MAX_PIXELS)"
        )


def _decode_quietly(raw: np.ndarray) -> tuple[np.ndarray | None, list[str]]:
    """``cv2.imdecode``, with the C libraries' stderr messages captured instead of printed.

    libjpeg and libpng report damage only on the process's stderr (file descriptor 2), so it
    is redirected to a temporary file for the decode.  That is safe only while no other thread
    can write there: with several threads (a server), the photo is decoded without the capture
    and only a decode failure refuses it, within a time budget
    (:func:`_decode_within_budget`).
    """
    flags = cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH
    if threading.active_count() > 1:
        return _decode_within_budget(raw, flags)
    with _STDERR_LOCK, tempfile.TemporaryFile() as capture:
        sys.stderr.flush()
        saved = os.dup(2)
        try:
            os.dup2(capture.fileno(), 2)
            try:
                img = cv2.imdecode(raw, flags)
            except cv2.error as exc:
                img = None
                capture.write(("error: " + _first_line(exc)).encode())
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        capture.seek(0)
        text = capture.read(65536).decode("utf-8", "replace")
    return img, [line.strip() for line in text.splitlines() if line.strip()]


def _decode_within_budget(raw: np.ndarray, flags: int) -> tuple[np.ndarray | None, list[str]]:
    """``cv2.imdecode`` in a thread of its own, waited for at most ``CAMVLP_MAX_DECODE_SECONDS``.

    A decode that runs past the budget is abandoned: the caller (a server's worker thread) gets
    an InputError and is free again, while the decode runs to its end in the background (its
    cost is bounded by the pixel and scan limits checked before it started) and its result is
    dropped.
    """
    budget = limit("CAMVLP_MAX_DECODE_SECONDS")
    done: list[tuple[np.ndarray | None, list[str]]] = []

    def work() -> None:
        try:
            done.append((cv2.imdecode(raw, flags), []))
        except cv2.error as exc:
            done.append((None, ["error: " + _first_line(exc)]))
        except MemoryError:
            done.append((None, ["error: out of memory"]))

    worker = threading.Thread(target=work, name="camvlp-decode", daemon=True)
    worker.start()
    worker.join(budget)
    if not done:
        raise InputError(
            f"photo took over {budget} s to decode; abandoned (set CAMVLP_MAX_DECODE_SECONDS)"
        )
    return done[0]


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[-1] if text else exc.__class__.__name__
