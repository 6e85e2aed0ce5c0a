"""Gray-level percentiles of uint8 images: from their histograms, or by counting pixels.

A region's background and peak levels, and the reduced photo's median, are found by counting
the pixels at or below a level (``cv2.threshold`` and ``cv2.countNonZero``, a few
microseconds) from a guess, which costs less than a histogram (``cv2.calcHist``, about a
nanosecond a pixel) when the guess is near; both give the same levels.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["CLIP_LEVEL", "FULL_SCALE"]

#: Gray level at or above which a pixel counts as clipped (8-bit photos; JPEG rings below 255).
CLIP_LEVEL = 235.0
#: The sensor's full scale (8-bit photos).
FULL_SCALE = 255.0


def percentiles_u8(gray: np.ndarray, qs) -> list[float]:
    """Percentiles (0-100) of a uint8 image from its histogram (much faster than sorting)."""
    hist = cv2.calcHist([gray], [0], None, [256], [0, 256]).reshape(1, 256)
    return hist_percentiles(hist, qs)[0].tolist()


def counted_percentiles(gray: np.ndarray, qs, guesses) -> list[float]:
    """``percentiles_u8(gray, qs)`` of a uint8 image found by counting instead of from its
    histogram: for each ``q``, the smallest level ``v`` with at least ``q`` % of the pixels
    at or below it (counted by OpenCV: ``cv2.threshold`` and ``cv2.countNonZero``), searched
    for from ``guesses`` (one level each) by steps that double, then by halves.  The same
    levels (the share in float32, as the histogram's counts are); a few counts when the
    guess is near, which costs less than the histogram."""
    n = gray.size
    if n >= 1 << 24:  # beyond float32's whole numbers: the histogram's own float32 counts
        return percentiles_u8(gray, qs)

    def enough(v: int, most_above: float) -> bool:  # at least the share at or below v
        # (one frame a count: it is called a few times per region)
        return v >= 255 or (
            cv2.countNonZero(cv2.threshold(gray, v, 255, cv2.THRESH_BINARY)[1]) <= most_above
        )

    out = []
    for q, guess in zip(qs, guesses, strict=True):
        # at least q % at or below v: at most n less that share above it (exact in float64)
        most_above = n - float(np.float32(q / 100.0) * np.float32(n))
        v = min(max(int(guess), 0), 255)
        step = 1  # then: enough(hi), not enough(lo) (lo -1: no level below hi)
        if enough(v, most_above):
            hi, lo = v, v - 1
            while lo >= 0 and enough(lo, most_above):
                hi, step = lo, 2 * step
                lo = max(hi - step, -1)
        else:
            lo, hi = v, v + 1
            while not enough(hi, most_above):
                lo, step = hi, 2 * step
                hi = min(lo + step, 255)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (lo, mid) if enough(mid, most_above) else (mid, hi)
        out.append(float(hi))
    return out


def hist_percentiles(hists: np.ndarray, qs) -> np.ndarray:
    """Percentiles (0-100) of uint8 images from their histograms (K, 256) (float32 counts, as
    ``cv2.calcHist`` gives them): per image and ``q``, the level where its cumulative count
    reaches ``q`` % of its pixels (in float32, as the counts are).  Returns (K, len(qs))."""
    cdf = hists.cumsum(axis=1)
    at = np.array([q / 100.0 for q in qs], np.float32)[None, :] * cdf[:, -1:]
    # np.searchsorted(cdf, at) per image: the levels whose cumulative count is below
    return (cdf[:, None, :] < at[:, :, None]).sum(axis=2).astype(float)
