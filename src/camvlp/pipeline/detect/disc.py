"""The disc under a striped light: its lit pixels with the dark stripes bridged by a closing
along the readout axis, and the light's whole striped area down to the background.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["disc_mask", "light_support"]


def disc_mask(
    lit: np.ndarray, axis: str, kernel_px: int, lit_box: tuple[int, int, int, int] | None = None
) -> tuple[np.ndarray, tuple[int, int, int, int]] | None:
    """The disc under a striped light: lit pixels with the dark stripes bridged.

    A closing along the readout axis as long as the widest dark gap across the middle third
    of the region (at least ``kernel_px``), a small round closing, and the largest outline
    with its holes filled.  ``lit`` is bool, or uint8 of 0 and 1; ``lit_box`` its
    bounding box ``(x, y, w, h)`` (``cv2.boundingRect``) when already known.  Returns a bool
    mask (h, w) and its bounding box ``(x, y, w, h)`` (the outline's), or None when nothing
    is lit.
    """
    lit_u8 = lit.view(np.uint8) if lit.dtype == bool else lit
    # Bridge the dark stripes: a closing along the readout axis, as long as the widest gap.
    rows = axis == "rows"
    n = lit_u8.shape[1 if rows else 0]  # pixels across the readout: its middle third
    a, b = n // 3, max(n // 3 + 1, 2 * n // 3)
    centre = lit_u8[:, a:b] if rows else lit_u8[a:b]
    gap = 0
    if centre.size:
        # lines more than half lit (the lit pixels counted by OpenCV); the widest dark run
        # between two of them
        counts = cv2.reduce(centre, 1 if rows else 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
        lit_lines = (counts > (min(n, b) - a) // 2).nonzero()[0]  # 2 c > m: c > m // 2
        if lit_lines.size >= 2:
            gap = int(np.diff(lit_lines).max()) - 1
    length = max(kernel_px, gap + 3) | 1
    closed, offset = _bridged(lit_u8, length, rows, box=lit_box)
    # the largest outline, holes filled
    contours, _ = cv2.findContours(
        closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE, offset=offset
    )
    if not contours:
        return None
    outline = contours[0] if len(contours) == 1 else max(contours, key=cv2.contourArea)
    filled = np.zeros(lit_u8.shape, np.uint8)
    cv2.drawContours(filled, [outline], -1, 1, thickness=cv2.FILLED)
    return filled.view(bool), cv2.boundingRect(outline)


def _bridged(
    lit: np.ndarray,
    length: int,
    rows: bool,
    crop: bool = True,
    box: tuple[int, int, int, int] | None = None,
) -> tuple[np.ndarray, tuple[int, int]]:
    """The lit pixels closed along the readout axis (``length`` pixels), then by a 5 x 5
    ellipse; returns the closed part and its offset ``(x, y)`` in ``lit``, zero elsewhere.
    ``box``: the lit pixels' bounding box ``(x, y, w, h)`` when already known.

    The whole region is closed as a copy padded by repeating its edge: OpenCV's own border
    keeps whatever the dilation brought to the edge, which would join a disc near the border
    to it.  When the lit pixels stay far enough from the region's edge (so that edge is dark
    and its padding too), only their bounding box is closed, with a margin one pixel wider
    than the two dilations reach (``r + 2`` along, 2 across, ``r = length // 2``): on the
    margin's outer line both dilations are 0, and each kernel's middle line is whole, so an
    erosion whose kernel reaches past the box (onto OpenCV's border, taken as lit) meets a
    0 on that line first, as the whole region's does.  The same values, where the closing
    of the whole region is zero outside that box (``crop``: allowed).
    """
    r = length // 2
    ksize = (1, length) if rows else (length, 1)  # (width, height): across the stripes
    x, y, w, h = cv2.boundingRect(lit) if box is None else box
    along, across = r + 3, 3
    my, mx = (along, across) if rows else (across, along)
    height, width = lit.shape
    inside = y >= my and x >= mx and y + h + my <= height and x + w + mx <= width
    if crop and w and inside:
        part, offset = lit[y - my : y + h + my, x - mx : x + w + mx], (x - mx, y - my)
    else:
        m = r + 3
        part, offset = cv2.copyMakeBorder(lit, m, m, m, m, cv2.BORDER_REPLICATE), (-m, -m)
    along = cv2.getStructuringElement(cv2.MORPH_RECT, ksize)
    closed = cv2.morphologyEx(part, cv2.MORPH_CLOSE, along)
    round_ = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
    closed = cv2.morphologyEx(closed, cv2.MORPH_CLOSE, round_)
    if offset[0] < 0:  # the padding cut off again
        return np.ascontiguousarray(closed[-offset[1] : offset[1], -offset[0] : offset[0]]), (0, 0)
    return closed, offset


def light_support(
    gray: np.ndarray,
    mask: np.ndarray,
    axis: str,
    kernel_px: int = 16,
    k_sigma: float = 8.0,
    cell: np.ndarray | None = None,
) -> np.ndarray:
    """A light's whole striped area, down to the background, inside its region of interest.

    A detected disc's mask is thresholded well up its brightness; a real light with a hot
    core, a glow and soft stripes shows its stripes further out, down to where they sink into
    the background.  Here the region's background is its 10th percentile outside the disc
    (dilated), its noise the spread of neighbouring pixels' differences there (so that a
    smooth glow does not count as noise); the pixels (lightly smoothed) more than
    ``k_sigma`` noise levels above the background, with the dark stripes bridged as in
    detection, form the support.  Its outline that overlaps ``mask`` is kept (filled), joined
    with ``mask``.

    Parameters
    ----------
    gray : ndarray, shape (h, w)
        The region of interest, gray levels (any real dtype).
    mask : ndarray of bool, shape (h, w)
        The detected disc (:attr:`~camvlp.pipeline.detect.blob.Blob.mask`).
    axis : {"rows", "columns"}
        The readout axis (stripes across it).
    kernel_px : int
        Smallest closing length bridging the dark stripes, pixels.
    k_sigma : float
        Threshold above the background, in noise standard deviations.
    cell : ndarray of bool, shape (h, w), optional
        The light's own part of the region (:attr:`~camvlp.pipeline.detect.blob.Blob.cell`):
        the support stays within it.

    Returns
    -------
    ndarray of bool, shape (h, w)
        The support; ``mask`` itself when the region has too little background to tell.
    """
    g = np.asarray(gray, dtype=np.float32)
    m = np.asarray(mask, dtype=bool)
    if g.shape != m.shape or not m.any():
        return m
    outside = cv2.dilate(m.astype(np.uint8), np.ones((9, 9), np.uint8)) == 0
    if outside.sum() < 50:
        return m
    background = float(np.percentile(g[outside], 10))
    # noise: neighbouring pixels across the readout axis see the same stripe phase
    d = np.diff(g, axis=1) if axis == "rows" else np.diff(g, axis=0)
    both = outside[:, 1:] & outside[:, :-1] if axis == "rows" else outside[1:] & outside[:-1]
    dd = d[both]
    noise = 1.4826 * float(np.median(np.abs(dd - np.median(dd)))) / np.sqrt(2.0)
    lit = cv2.GaussianBlur(g, (0, 0), 1.0) > background + max(k_sigma * noise, 2.0)
    lit |= m
    if cell is not None:
        lit &= cell
    found = disc_mask(lit, axis, kernel_px)
    if found is None or not (found[0] & m).any():
        return m
    return found[0] | m
