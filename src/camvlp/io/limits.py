"""Limits on what camvlp reads, and the one way every input file is opened.

Each limit has a default a little above anything a real input needs and an environment
variable to change it (read at each call, so a process can change it while running):

============================  ==============================================  ===========
Environment variable          What it bounds                                  Default
============================  ==============================================  ===========
``CAMVLP_MAX_PIXELS``         Pixels of a photo or a camera (width x height)  200,000,000
``CAMVLP_MAX_RENDER_PIXELS``  Pixels of a rendered photo (``camvlp render``)  100,000,000
``CAMVLP_MAX_IMAGE_BYTES``    Size of a photo file, bytes                     536,870,912
``CAMVLP_MAX_FILE_BYTES``     Size of a camera, map or survey file, bytes     16,777,216
``CAMVLP_MAX_DEPTH``          Nesting of a camera or map file (lists, keys)   32
``CAMVLP_MAX_JPEG_SCANS``     Scans of a JPEG (each one a decoding pass)      100
``CAMVLP_MAX_DECODE_SECONDS`` Decoding one photo in a server, seconds         20
``CAMVLP_MAX_FRAMES``         Frames of a video read or rendered              100,000
============================  ==============================================  ===========

Input files must be regular files: a named pipe, a device or a folder is refused before it is
read, and files are opened non-blocking so that a pipe can never hang the reader.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import BinaryIO

from camvlp.errors import InputError

__all__ = [
    "DEFAULTS",
    "check_pixels",
    "limit",
    "open_regular_file",
    "read_regular_file",
]

#: Default of each limit, by environment variable.
DEFAULTS: dict[str, int] = {
    "CAMVLP_MAX_PIXELS": 200_000_000,
    "CAMVLP_MAX_RENDER_PIXELS": 100_000_000,
    "CAMVLP_MAX_IMAGE_BYTES": 512 * 1024 * 1024,
    "CAMVLP_MAX_FILE_BYTES": 16 * 1024 * 1024,
    "CAMVLP_MAX_DEPTH": 32,
    "CAMVLP_MAX_JPEG_SCANS": 100,
    "CAMVLP_MAX_DECODE_SECONDS": 20,
    "CAMVLP_MAX_FRAMES": 100_000,
}


def limit(name: str, given: int | None = None) -> int:
    """The limit ``name`` (a key of :data:`DEFAULTS`): ``given``, else the environment's, else
    the default.

    Raises
    ------
    InputError
        The environment variable is set but is not a positive integer.
    """
    if given is not None:
        if isinstance(given, bool) or not isinstance(given, int) or given < 1:
            raise InputError(f"{name.removeprefix('CAMVLP_').lower()} must be a positive integer")
        return given
    text = os.environ.get(name)
    if text is None or not text.strip():
        return DEFAULTS[name]
    try:
        value = int(text.strip().replace("_", ""))
    except ValueError:
        value = 0
    if value < 1 or len(text) > 20:
        raise InputError(f"environment variable {name} must be a positive integer, got {text!r}")
    return value


def check_pixels(
    width: int, height: int, max_pixels: int | None = None, source: str | Path | None = None
) -> None:
    """Refuse an image (or a video frame) of ``width`` x ``height`` pixels that is empty or
    over ``max_pixels`` (default ``CAMVLP_MAX_PIXELS``).

    Raises
    ------
    InputError
        Naming ``source`` when given.
    """
    cap = limit("CAMVLP_MAX_PIXELS", max_pixels)
    if width <= 0 or height <= 0:
        raise InputError(f"image header says {width} x {height} pixels", source)
    if width * height > cap:
        raise InputError(
            f"image is {width} x {height} = {width * height:,} pixels, over the limit of "
            f"{cap:,} (set CAMVLP_MAX_PIXELS)",
            source,
        )


def _describe(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a named pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "not a regular file"


def open_regular_file(path: str | Path, kind: str, max_bytes: int | None = None) -> BinaryIO:
    """``path`` opened for reading (binary), once it is known to be a regular file of at most
    ``max_bytes`` bytes (None: any size).

    The file is checked with ``os.stat`` before it is opened, opened with ``O_NONBLOCK`` (a
    named pipe swapped in between cannot block) and checked again on the open descriptor.
    The caller closes the file (``with open_regular_file(...) as fh``).

    Parameters
    ----------
    path : str or Path
        The file.
    kind : str
        What the file is, for the error message ("photo", "video", "camera file", ...).
    max_bytes : int, optional
        Largest size accepted, bytes.

    Raises
    ------
    InputError
        Missing, not a regular file, too large, or unreadable; naming the file.
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise InputError(f"{kind} not found", p) from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        raise InputError(f"cannot read {kind}: {_reason(exc)}", p) from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{kind} is {_describe(st.st_mode)}, not a regular file", p)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise InputError(f"cannot read {kind}: {_reason(exc)}", p) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{kind} is {_describe(st.st_mode)}, not a regular file", p)
        if max_bytes is not None and st.st_size > max_bytes:
            raise InputError(_too_large(kind, st.st_size, max_bytes), p)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular_file(path: str | Path, kind: str, max_bytes: int) -> bytes:
    """The bytes of ``path``, which must be a regular file of at most ``max_bytes`` bytes
    (opened by :func:`open_regular_file`; a file that grows past the limit while it is read
    is refused too).

    Raises
    ------
    InputError
        Missing, not a regular file, too large, or unreadable; naming the file.
    """
    p = Path(path)
    with open_regular_file(p, kind, max_bytes) as fh:
        chunks = []
        total = 0
        try:
            while True:
                chunk = fh.read(min(1 << 20, max_bytes + 1 - total))
                if not chunk:
                    break
                chunks.append(chunk)
                total += len(chunk)
                if total > max_bytes:  # the file grew while being read
                    raise InputError(_too_large(kind, total, max_bytes), p)
        except OSError as exc:
            raise InputError(f"cannot read {kind}: {_reason(exc)}", p) from None
        return b"".join(chunks)


def _too_large(kind: str, size: int, max_bytes: int) -> str:
    variable = "CAMVLP_MAX_IMAGE_BYTES" if kind == "photo" else "CAMVLP_MAX_FILE_BYTES"
    return f"{kind} is {size:,} bytes, over the limit of {max_bytes:,} (set {variable})"


def _reason(exc: BaseException) -> str:
    """An OS error's reason without its file name (the caller names the file)."""
    return getattr(exc, "strerror", None) or exc.__class__.__name__
