"""Which way a light's stripes run: the sensor's readout axis as the rolling shutter shows
it across a disc, and how much of the disc's variance its stripes explain.

Each sensor line is exposed at its own instant, so a blinking light's level changes from line
to line along the readout axis and stays the same along each line: the mean level per line
varies along that axis far more than along the other.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.polynomial import legendre

__all__ = ["axis_contrast", "find_readout_axis", "stripe_share"]


def find_readout_axis(gray: np.ndarray, mask: np.ndarray) -> tuple[str, float]:
    """Which way the stripes run inside a disc.

    Parameters
    ----------
    gray : ndarray, shape (h, w)
        The region of interest.
    mask : ndarray of bool, shape (h, w)
        The disc.

    Returns
    -------
    axis : str
        ``"rows"`` when intensity changes from row to row (horizontal stripes, sensor rows
        are image rows), ``"columns"`` when it changes from column to column.
    contrast : float
        Ratio of the larger to the smaller variance of the two mean profiles (>= 1).
    """
    g = np.asarray(gray)
    m = np.asarray(mask, dtype=bool).view(np.uint8)
    if g.dtype == np.uint8:
        return axis_contrast(g, m)
    m = m.astype(np.float32)
    g = g.astype(np.float32, copy=False) * m
    return _axis_from_sums(g.sum(1), m.sum(1), g.sum(0), m.sum(0))


def stripe_share(gray8: np.ndarray, mask01: np.ndarray, axis: str) -> float:
    """The share (0 to 1) of the variance of a region's masked pixels explained by their mean
    level per line along ``axis`` (rows, or columns): the stripes of a light alternate along
    it across each line's whole length, a text's strokes and a steady light's shape do not.
    0 for a region of one level.

    Parameters
    ----------
    gray8 : ndarray of uint8, shape (h, w)
        The region.
    mask01 : ndarray of uint8, shape (h, w)
        Its pixels (0 and 1).
    axis : {"rows", "columns"}
        The readout axis.
    """
    g = gray8.astype(np.float64) * mask01
    n = mask01.sum(axis=1 if axis == "rows" else 0, dtype=np.float64)
    per_line = g.sum(axis=1 if axis == "rows" else 0)
    total, count = float(per_line.sum()), float(n.sum())
    if count < 2:
        return 0.0
    spread = float((g * g).sum()) - total * total / count
    used = n > 0
    between = float((per_line[used] ** 2 / n[used]).sum()) - total * total / count
    return float(np.clip(between / spread, 0.0, 1.0)) if spread > 0 else 0.0


def axis_contrast(gray8: np.ndarray, mask01: np.ndarray) -> tuple[str, float]:
    """:func:`find_readout_axis` of a uint8 region and a uint8 mask of 0 and 1: the sums by
    OpenCV, exact in float32 like NumPy's (whole levels, below 2**24).  (The product by
    NumPy: ``cv2.multiply`` of a crop that is not contiguous costs several times as much.)"""
    g = np.multiply(gray8, mask01)
    sums = [
        cv2.reduce(a, dim, cv2.REDUCE_SUM, dtype=cv2.CV_32F).ravel()
        for dim in (1, 0)
        for a in (g, mask01)
    ]
    return _axis_from_sums(*sums)


def _axis_from_sums(row_sums, n_rows, col_sums, n_cols) -> tuple[str, float]:
    """The readout axis and contrast from a disc's gray sums and pixel counts per row and
    per column (float32): which of its mean levels per row and per column varies more from
    line to line (the stripes vary along one axis only); where that leaves the two within
    :data:`_SHARP_CONTRAST` of each other (soft stripes over a hot core, which varies both
    alike), the mean levels less their smooth parts (:func:`_stripe_variance`), if they
    tell the axis more clearly."""
    keep_r, keep_c = n_rows >= 3, n_cols >= 3
    rows, cols = row_sums[keep_r] / n_rows[keep_r], col_sums[keep_c] / n_cols[keep_c]
    found = _by_ratio(
        _diff_var(rows) if rows.size > 2 else 0.0, _diff_var(cols) if cols.size > 2 else 0.0
    )
    if found[1] >= _SHARP_CONTRAST:
        return found
    # (two lights' joined glows vary across as much as a soft light's core: its smooth part
    # is not theirs, so only where the differences do not tell)
    smooth = _by_ratio(
        _stripe_variance(rows, n_rows[keep_r]), _stripe_variance(cols, n_cols[keep_c])
    )
    return smooth if smooth[1] > found[1] else found


#: A contrast of the line-to-line differences this clear is taken as it is.
_SHARP_CONTRAST = 2.0


def _by_ratio(along_rows: float, along_cols: float) -> tuple[str, float]:
    """The axis with the larger variation, and the ratio of the larger to the smaller."""
    if along_rows >= along_cols:
        return "rows", along_rows / max(along_cols, 1e-9)
    return "columns", along_cols / max(along_rows, 1e-9)


def _diff_var(v: np.ndarray) -> float:
    """``np.var(np.diff(v))`` of a 1-D array (3 values or more)."""
    return float(np.var(np.diff(v)))


#: Degree of the smooth part of a light's mean profile: its shape (a chord's level, a hot
#: core, a glow), which varies along both axes alike.
_SHAPE_DEGREE = 2


def _stripe_variance(level: np.ndarray, count: np.ndarray) -> float:
    """The variance (weighted by the pixel counts) of a light's mean level per line about
    its smooth part, a polynomial of :data:`_SHAPE_DEGREE` fitted to it: what stripes add.
    Where a soft light's hot core made its level vary as much along the stripes as across
    (first differences 1.0 to 1.7 times apart on lights of 100 to 250 px), the stripes stand
    out (55 to 180 times).  0 for fewer than four lines."""
    if level.size <= _SHAPE_DEGREE + 1:
        return 0.0
    u = np.linspace(-1.0, 1.0, level.size)
    basis = legendre.legvander(u, _SHAPE_DEGREE)
    w = np.asarray(count, dtype=np.float64)
    sw = np.sqrt(w)
    v = np.asarray(level, dtype=np.float64)
    beta = np.linalg.lstsq(basis * sw[:, None], v * sw, rcond=None)[0]
    r = v - basis @ beta
    return float((w * r * r).sum() / w.sum())
