"""Undoing a camera's tone curve: the light that made a photo's levels.

A phone stores ``x = light ** (1 / tone_gamma)`` (its tone curve, about sRGB's 2.2), not the
light itself.  The stripes of a lamp add its glow, its LED's off level and the background as
light adds, and a lamp's shape multiplies its LED's on-fraction only in light: after the tone
curve, a glow that is a quarter of the lamp's level comes out more than half of it, and a
dark stripe's depth depends on what lies under it.  ``locate`` therefore maps the levels back
to light first when the camera file gives its ``tone_gamma``.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

__all__ = ["linear_light"]


@functools.lru_cache(maxsize=8)
def _table(gamma: float, levels: int) -> np.ndarray:
    """uint16 (levels,): level ``i`` of ``levels`` mapped to ``65535 * (i / (levels - 1)) **
    gamma``."""
    x = np.arange(levels, dtype=np.float64) / (levels - 1)
    table = np.rint(65535.0 * x**gamma).astype(np.uint16)
    table.flags.writeable = False
    return table


def linear_light(image: np.ndarray, tone_gamma: float) -> np.ndarray:
    """The light that made an image's levels under the tone curve ``x ** (1 / tone_gamma)``.

    Parameters
    ----------
    image : ndarray of uint8 or uint16, shape (H, W) or (H, W, 3)
        The stored levels.
    tone_gamma : float
        The camera's tone-curve exponent (1 returns the image as it is).

    Returns
    -------
    ndarray of uint16, same shape
        The light, 0 to 65535 for none to the level that stores as full scale (16 bits, so
        that the dark levels a gamma squeezes together stay apart).
    """
    if tone_gamma == 1:
        return image
    if image.dtype == np.uint8:
        return cv2.LUT(image, _table(float(tone_gamma), 256))
    return _table(float(tone_gamma), 65536)[image]
