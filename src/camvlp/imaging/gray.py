"""Gray levels of a photo: one channel from gray or BGR(A) pixels by the sensor's luma
weights, as 8-bit levels for detection or as raw levels for measurements.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["gray_float", "luma", "to_gray"]


def luma(image: np.ndarray, dtype=None) -> np.ndarray:
    """One channel (H, W) from gray or BGR(A) pixels, OpenCV's luma weights (0.299 R +
    0.587 G + 0.114 B), optionally converted to ``dtype`` first."""
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if dtype is not None:
        img = img.astype(dtype, copy=False)
    if img.ndim == 3 and img.shape[2] in (3, 4):
        code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        img = cv2.cvtColor(img, code)
    if img.ndim != 2:
        raise ValueError(f"image must be (H, W) or (H, W, 3), got shape {np.shape(image)}")
    return img


def gray_float(image: np.ndarray) -> np.ndarray:
    """Gray ``float64`` (H, W) from a BGR (H, W, 3) or gray image, in its own units (no
    rescaling): the same weights as :func:`to_gray`, for measurements on raw levels."""
    return luma(image, np.float32).astype(np.float64)


def to_gray(image: np.ndarray) -> np.ndarray:
    """Gray ``uint8`` (H, W) from a BGR (H, W, 3) or gray image, 8- or 16-bit."""
    if isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.shape[2:] == (3,):
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)  # the usual photo: as luma does it
    img = luma(image)
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    elif img.dtype != np.uint8:
        f = img.astype(np.float32)
        hi = float(f.max()) if f.size else 1.0
        img = np.clip(f * (255.0 / hi if hi > 1.0 else 255.0), 0, 255).astype(np.uint8)
    return img
