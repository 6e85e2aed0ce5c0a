"""Where the video tracker (:mod:`camvlp.pipeline.track.tracker`) expects each fixture in a
frame, and when each image row was read.

Every map fixture is predicted in the image from the track's pose when the track is fresh,
else from where it was last seen and how it moved (:class:`Sighting`).  A fixture imaged on
sensor row ``k`` was seen ``(k - (N - 1) / 2) * row_time`` after the frame's middle row
(:func:`row_offset_s`); with the track's velocity its pixel moves by :func:`rs_shift` between
then and the frame's time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.geometry.pnp import project_moving
from camvlp.model.camera import Camera
from camvlp.model.readout import Readout
from camvlp.pipeline.track.motion import MotionState

__all__ = [
    "Sighting",
    "predicted_pixels",
    "remember",
    "row_offset_s",
    "rs_shift",
    "sighted_pixels",
]


@dataclass
class Sighting:
    """Where a fixture was last seen.

    Attributes
    ----------
    pixel : ndarray, shape (2,)
        Its pixel in the processing image.
    t : float
        The frame's time, s.
    velocity : ndarray, shape (2,)
        Its motion in the image, pixels per s.
    """

    pixel: np.ndarray
    t: float
    velocity: np.ndarray


def row_offset_s(
    camera: Camera, readout: Readout | None, pixels: np.ndarray, shape: tuple[int, int]
) -> np.ndarray:
    """Time (s) of each pixel's (N, 2) sensor row after the frame's middle row, (N,); zeros
    without the camera's row time or a readout direction. ``shape``: the image's (H, W)."""
    rt = camera.row_time_s
    if rt is None or readout is None:
        return np.zeros(len(pixels))
    h, w = shape
    n = h if readout.by_rows else w
    k = pixels[:, readout.pixel_index]
    if readout.reversed:
        k = n - 1 - k
    return (k - 0.5 * (n - 1)) * rt


def rs_shift(
    camera: Camera,
    readout: Readout | None,
    state: MotionState,
    obj: np.ndarray,
    pixels: np.ndarray,
    shape: tuple[int, int],
) -> np.ndarray:
    """Pixel motion (N, 2) of each fixture (``obj`` (N, 3), map units; seen at ``pixels``
    (N, 2)) between its row's time and the frame's time, with the predicted ``state``."""
    dts = row_offset_s(camera, readout, pixels, shape)
    values, rates = state[0], state[1]
    moved = project_moving(camera, values, rates, obj, dts)
    return np.nan_to_num(moved - project_moving(camera, values, rates, obj, 0 * dts))


def predicted_pixels(
    camera: Camera,
    readout: Readout | None,
    state: MotionState | None,
    fixtures: tuple[np.ndarray, np.ndarray],
    shape: tuple[int, int],
    *,
    rolling_shutter: bool,
) -> dict[int, np.ndarray]:
    """Each map fixture's predicted pixel (2,) from a fresh track's ``state``, keyed by ID.

    Parameters
    ----------
    camera : Camera
    readout : Readout or None
        The video's readout direction (the rows' times with ``rolling_shutter``).
    state : MotionState
        The track's prediction at the frame's time.
    fixtures : (ndarray, ndarray)
        The map's IDs (M,) and positions (M, 3), map units.
    shape : (int, int)
        The processing image's (H, W).
    rolling_shutter : bool
        Project each fixture at the time of the rows that see it.
    """
    ids, positions = fixtures
    values, rates = state[0], state[1]
    zero = np.zeros(len(positions))
    uv = project_moving(camera, values, rates, positions, zero)
    if rolling_shutter:  # where the rows that see them are read
        dts = row_offset_s(camera, readout, np.nan_to_num(uv), shape)
        uv = project_moving(camera, values, rates, positions, dts)
    return {int(fid): p for fid, p in zip(ids, uv, strict=True) if np.all(np.isfinite(p))}


def sighted_pixels(seen: dict[int, Sighting], t: float, max_gap_s: float) -> dict[int, np.ndarray]:
    """Each fixture seen within ``max_gap_s`` of ``t`` (s): where it was, moved on at its
    velocity to ``t`` (pixels (2,), keyed by ID)."""
    return {
        fid: s.pixel + (t - s.t) * s.velocity for fid, s in seen.items() if t - s.t <= max_gap_s
    }


def remember(seen: dict[int, Sighting], blobs, ids, t: float, max_gap_s: float) -> None:
    """Record, in place in ``seen``, where each identified blob's fixture was at ``t`` (s),
    with its velocity since it was last seen (within ``max_gap_s``; else still)."""
    for k, b in enumerate(blobs):
        fid = ids[k]
        if fid is None:
            continue
        prev = seen.get(fid)
        vel = np.zeros(2)
        if prev is not None and 0 < t - prev.t <= max_gap_s:
            vel = (b.pixel - prev.pixel) / (t - prev.t)
        seen[fid] = Sighting(np.asarray(b.pixel, dtype=float), t, vel)
