"""A photo's sidecar: ``PHOTO.json`` beside ``PHOTO.jpg`` with the direction of gravity.

See ``docs/formats.md`` ("Photo sidecar").  ``{"gravity": [gx, gy, gz]}`` in the camera's frame
(OpenCV axes), any length; optionally ``"gravity_sigma_deg"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camvlp.errors import InputError
from camvlp.io.textfiles import read_mapping

__all__ = ["PhotoSidecar", "load_sidecar", "sidecar_path"]


@dataclass(frozen=True)
class PhotoSidecar:
    """What a photo's sidecar says.

    Attributes
    ----------
    gravity : ndarray, shape (3,)
        Gravity in the camera frame, as written (any length).
    gravity_sigma_deg : float or None
        The accelerometer's uncertainty, degrees; None when not given.
    source : str
        The sidecar's path.
    """

    gravity: np.ndarray
    gravity_sigma_deg: float | None
    source: str


def sidecar_path(photo: str | Path) -> Path | None:
    """The sidecar of a photo, if one exists: ``PHOTO.json``, else ``PHOTO.jpg.json``."""
    p = Path(photo)
    for candidate in (p.with_suffix(".json"), p.with_name(p.name + ".json")):
        if candidate != p and candidate.is_file():
            return candidate
    return None


def load_sidecar(photo: str | Path) -> PhotoSidecar | None:
    """Read a photo's sidecar; None when it has none, or when the JSON file beside the photo
    has no ``gravity`` key (such as the truth ``camvlp render`` writes there).

    Raises
    ------
    InputError
        The file is not JSON, its ``gravity`` is not three finite numbers, not all zero, or
        its ``gravity_sigma_deg`` is not a positive number (naming the file).
    """
    path = sidecar_path(photo)
    if path is None:
        return None
    data = read_mapping(path, "sidecar")
    if "gravity" not in data:
        return None  # another file of the same name (the simulator's truth): no gravity
    g = data["gravity"]
    if not (
        isinstance(g, list)
        and len(g) == 3
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in g)
    ):
        raise InputError(f"gravity must be three numbers [gx, gy, gz], got {g!r}", path)
    if not all(math.isfinite(v) for v in g):
        raise InputError(f"gravity must be finite, got {g!r}", path)
    if not any(g):
        raise InputError("gravity has zero length: its direction is not known", path)
    sigma = data.get("gravity_sigma_deg")
    if sigma is not None and (
        isinstance(sigma, bool)
        or not isinstance(sigma, (int, float))
        or not (math.isfinite(sigma) and sigma > 0)
    ):
        raise InputError(f"gravity_sigma_deg must be a positive number, got {sigma!r}", path)
    return PhotoSidecar(
        np.asarray(g, dtype=float), None if sigma is None else float(sigma), str(path)
    )
