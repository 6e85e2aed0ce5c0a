"""Stage 1: find the fixtures in a photograph (thesis section 5.2, made fast and sub-pixel).

Candidates are found on a reduced copy of the image (threshold, then closing so that each
striped disc becomes one blob, then connected components).  Each candidate is then worked at
full resolution inside its region of interest only (:mod:`camvlp.pipeline.detect.refine`): a
threshold of its own, a closing along the sensor's readout axis that fills the dark stripes,
and the disc's outline.  The centre is the centre of an ellipse fitted to sub-pixel edge
points of the lit rows, so it comes from the disc and not from the stripes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.imaging.gray import to_gray
from camvlp.imaging.levels import counted_percentiles, percentiles_u8
from camvlp.pipeline.detect.blob import Blob
from camvlp.pipeline.detect.peaks import power_cell
from camvlp.pipeline.detect.refine import refine_regions
from camvlp.pipeline.detect.touching import CandidateSearch, not_convex, one_per_light
from camvlp.pipeline.settings import MIN_SIDE_PX

__all__ = ["Detection", "detect_fixtures"]


@dataclass(frozen=True)
class Detection:
    """All blobs of one image, and the reduced-image mask they came from (for debugging).

    Attributes
    ----------
    blobs : tuple of Blob
        Detected fixtures, sorted by ``v`` then ``u``.
    scale : int
        Reduction factor of the candidate search (full-resolution px per reduced px).
    candidate_mask : ndarray of uint8, shape (ceil(H / scale), ceil(W / scale))
        The closed binary mask of the reduced image (255 = candidate).
    threshold : float
        Threshold used on the reduced image, 0-255 gray levels.
    """

    blobs: tuple[Blob, ...]
    scale: int
    candidate_mask: np.ndarray
    threshold: float


def _median_u8(gray: np.ndarray) -> float:
    """``percentiles_u8(gray, [50])`` of a large uint8 image without its whole histogram:
    the median of every 4th pixel of every 16th row is a guess, from which the median is
    found by counting the pixels at or below a level in the whole image
    (:func:`counted_percentiles`)."""
    if gray.ndim != 2 or gray.size < 4096:
        return percentiles_u8(gray, [50])[0]
    sample = gray[::16, ::4]
    # the guess by NumPy's partition (8 us against 17 for the sample's histogram): any
    # guess gives the same median, a near one in fewer counts
    guess = np.partition(sample, sample.size // 2, axis=None)[sample.size // 2]
    return counted_percentiles(gray, [50], [guess])[0]


def _blurred_peak(gray: np.ndarray) -> float:
    """``float(cv2.GaussianBlur(gray, (3, 3), 0).max())`` of a uint8 image, without the blur
    when the image is saturated (its maximum 255) in a 3 x 3 block somewhere.

    The blur is a weighted mean of each pixel's 3 x 3 neighbours (OpenCV's fixed-point
    weights sum exactly to one; its border repeats the image's own pixels), so it is nowhere
    above the image's maximum, and it is that maximum where all nine neighbours are: where
    the 3 x 3 erosion is.  The erosion and its maximum cost about half the blur and its
    maximum (27 against 49 us at 640 x 360); tried on saturated photos only (lights often
    are, with flat tops), the others pay one maximum more (4 us) and are blurred whole.
    """
    top = float(np.maximum.reduce(gray, axis=None))
    if top == 255 and cv2.minMaxLoc(cv2.erode(gray, None))[1] == top:
        return top
    return float(cv2.GaussianBlur(gray, (3, 3), 0).max())


def _decimated_gray(img: np.ndarray, s: int) -> np.ndarray:
    """:func:`~camvlp.imaging.gray.to_gray` of the photo reduced ``s`` times by
    OpenCV's nearest-neighbour resize, shape (ceil(H / s), ceil(W / s)): ``img[::s, ::s]``
    when ``s`` divides both sides.

    Then a BGR uint8 photo's sampled pixels are gathered as 4 bytes each, one ``uint32``
    (the pixel and the next one's first byte), which NumPy copies faster than OpenCV
    resizes (3 bytes each); converted as BGRA, the fourth byte is left out: the same gray
    levels.
    """
    h, w = img.shape[:2]
    size = (-(-w // s), -(-h // s))  # ceil
    if s == 1:
        return to_gray(img)
    plain = img.dtype == np.uint8 and img.shape[2:] == (3,) and img.flags.c_contiguous
    if plain and h % s == 0 and w % s == 0:  # (the last pixel sampled is not the last)
        rows, step = img.strides[0] * s, 3 * s
        four = np.ndarray((size[1], size[0]), np.uint32, buffer=img, strides=(rows, step))
        bgra = np.ascontiguousarray(four).view(np.uint8).reshape(size[1], size[0], 4)
        return cv2.cvtColor(bgra, cv2.COLOR_BGRA2GRAY)
    return to_gray(cv2.resize(img, size, interpolation=cv2.INTER_NEAREST))


def _reduction(shape: tuple[int, ...]) -> int:
    return max(1, round(max(shape[:2]) / 640.0))


def detect_fixtures(
    image: np.ndarray,
    *,
    readout: str | None = None,
    kernel_px: int = 16,
    min_diameter_px: float = 8.0,
    relative_threshold: float = 0.25,
    max_blobs: int = 64,
) -> Detection:
    """Find the lit fixtures of a photograph.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3) or (H, W)
        BGR or gray photograph, 8- or 16-bit.
    readout : {"rows", "columns", None}, keyword-only
        The sensor's readout axis in this image; None finds it from each blob.
    kernel_px : int
        Smallest closing length in full-resolution pixels (the thesis uses 16); it grows by
        itself to bridge the widest dark stripe seen.
    min_diameter_px : float
        Blobs smaller than this (pixels across) are ignored.
    relative_threshold : float
        Candidate threshold on the reduced image: background plus this fraction of the span
        from background to the brightest blob.
    max_blobs : int
        At most this many candidates (the largest) are examined.

    Returns
    -------
    Detection
    """
    if readout not in (None, "rows", "columns"):
        raise ValueError(f"readout must be 'rows', 'columns' or None, got {readout!r}")
    img = np.asarray(image)
    if img.ndim not in (2, 3) or min(img.shape[:2]) < MIN_SIDE_PX:
        raise ValueError(f"image must be {MIN_SIDE_PX} x {MIN_SIDE_PX} px or more, got {img.shape}")
    s = _reduction(img.shape)
    # Candidates on every s-th pixel: a decimated view costs nothing, where averaging a
    # 20-megapixel photo down costs more than the rest of the pipeline.  A striped disc
    # keeps about half its sampled rows lit; the closing below joins them.
    small = _decimated_gray(img, s)
    background = _median_u8(small)
    peak = _blurred_peak(small)
    if peak - background < 12:  # nothing stands out of the noise
        return Detection((), s, np.zeros_like(small), peak)
    thr = background + relative_threshold * (peak - background)
    # small > thr as 255 and 0: OpenCV compares with floor(thr), the same for whole levels
    raw = cv2.threshold(small, thr, 255, cv2.THRESH_BINARY)[1]
    k = max(3, int(np.ceil(2.0 * kernel_px / s)) | 1)
    binary, lit_boxes = _close_lit(raw, k)
    boxes, several = _candidate_regions(
        _outlines(binary, lit_boxes), 0.5 * (min_diameter_px / s) ** 2, max_blobs
    )
    high = None  # the lights' brighter parts, where glows that join at ``thr`` stay apart
    if any(several):
        high = cv2.threshold(small, background + 0.6 * (peak - background), 255, 0)[1]
        high = _close_lit(high, k)[0]
    search = CandidateSearch(
        image=img,
        small=small,
        scale=s,
        threshold=thr,
        readout=readout,
        raw=raw,
        binary=binary,
        high=high,
    )
    lights = one_per_light(search, boxes, several)
    regions = _full_resolution(lights, s, pad=kernel_px + 6 + 2 * s, shape=img.shape[:2])
    blobs = refine_regions(
        img,
        [box for box, _, _ in regions],
        readout,
        kernel_px,
        min_diameter_px,
        cells=[cell for _, cell, _ in regions],
        guesses=(background, peak),
        seeds=[seed for _, _, seed in regions],
    )
    blobs.sort(key=lambda b: (round(float(b.pixel[1])), float(b.pixel[0])))
    return Detection(tuple(blobs), s, binary, thr)


def _candidate_regions(
    contours: list, min_area: float, max_blobs: int
) -> tuple[list[tuple[int, int, int, int]], list[bool]]:
    """The candidate regions' boxes ``(x, y, w, h)``, the largest first (at most
    ``max_blobs``; each one's area plus its box's sides at least ``min_area``, reduced
    pixels), and whether each may hold lights whose glows join
    (:func:`~camvlp.pipeline.detect.touching.not_convex`)."""
    rects = [cv2.boundingRect(c) for c in contours]
    areas = [cv2.contourArea(c) for c in contours]
    kept = [
        (r, c, a)
        for r, c, a in zip(rects, contours, areas, strict=True)
        if a + r[2] + r[3] >= min_area
    ]
    kept.sort(key=lambda rca: -rca[0][2] * rca[0][3])
    kept = kept[:max_blobs]
    return [r for r, _, _ in kept], [not_convex(c, a) for _, c, a in kept]


def _full_resolution(
    lights: Iterable[tuple[tuple[int, int, int, int], tuple[np.ndarray, int] | None]],
    s: int,
    pad: int,
    shape: tuple[int, int],
) -> list[tuple[tuple[int, int, int, int], np.ndarray | None, np.ndarray | None]]:
    """Each light's region of interest at full resolution: its box ``(x0, y0, x1, y1)`` (its
    reduced box scaled ``s`` times, grown by ``pad`` pixels, within the photo's ``shape``),
    its cell there (:func:`~camvlp.pipeline.detect.peaks.power_cell`; None when the region
    is all its own) and its seed ``[x, y, r]`` in the box's pixels (None likewise)."""
    height, width = shape
    regions = []
    for (x, y, w, h), cell in lights:
        box = (max(0, x * s - pad), max(0, y * s - pad))
        box += (min(width, (x + w) * s + pad), min(height, (y + h) * s + pad))
        if cell is None:
            regions.append((box, None, None))
            continue
        seeds, i = cell[0] * float(s), cell[1]  # [x, y, r, reach], full resolution
        regions.append((box, power_cell(box, seeds, i), seeds[i, :3] - [box[0], box[1], 0.0]))
    return regions


def _spans(flags: np.ndarray, gap: int) -> list[tuple[int, int]]:
    """Ranges ``(start, end)`` (end exclusive) holding the nonzero entries of a 1-D array,
    split where more than ``gap`` - 1 zeros separate two of them."""
    idx = flags.nonzero()[0]
    if idx.size == 0:
        return []
    cut = (idx[1:] - idx[:-1] > gap).nonzero()[0]
    starts = [int(idx[0]), *idx[cut + 1].tolist()]
    ends = [*idx[cut].tolist(), int(idx[-1])]
    return [(a, b + 1) for a, b in zip(starts, ends, strict=True)]


def _close_lit(
    binary: np.ndarray, k: int, max_boxes: int = 16
) -> tuple[np.ndarray, list[tuple[int, int, int, int]] | None]:
    """``cv2.morphologyEx(binary, MORPH_CLOSE, k x k ellipse)``, computed around the lit
    pixels only (the same result); and the boxes ``(y0, y1, x0, x1)`` (end exclusive) it was
    computed in, None when the image was closed whole.

    The closing at a pixel depends on the pixels within ``2 r`` of it (``r = k // 2``): the
    lit pixels are grouped into boxes more than ``4 r + 1`` apart (bands of rows, then columns
    within each band), each box is closed with a margin of ``r + 1`` around it, and the rest
    stays 0, as the closing of the whole image leaves it.  That margin is enough: the
    dilation is 0 on the margin's outer line (more than ``r`` from the lit pixels), and the
    ellipse's middle row and column are whole, so the erosion of a pixel whose kernel
    reaches past the box (onto OpenCV's border, taken as lit) meets a 0 on that line first,
    as the whole image's does.  The boxes do not overlap (more than ``2 r`` pixels apart),
    and the closing is 0 on each box's outer line but where the image's edge is.  A photo
    with many groups (noise) or large ones is closed whole.
    """
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    h, w = binary.shape
    r = k // 2
    margin, gap = r + 1, 4 * r + 1
    boxes = []
    lit_rows = cv2.reduce(binary, 1, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
    for y0, y1 in _spans(lit_rows, gap):
        band = cv2.reduce(binary[y0:y1], 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
        for x0, x1 in _spans(band, gap):
            ya, yb = max(0, y0 - margin), min(h, y1 + margin)
            xa, xb = max(0, x0 - margin), min(w, x1 + margin)
            boxes.append((ya, yb, xa, xb))
    area = sum((yb - ya) * (xb - xa) for ya, yb, xa, xb in boxes)
    if len(boxes) > max_boxes or area > h * w // 2:
        return cv2.morphologyEx(binary, cv2.MORPH_CLOSE, kernel), None
    out = np.zeros_like(binary)
    for ya, yb, xa, xb in boxes:
        out[ya:yb, xa:xb] = cv2.morphologyEx(binary[ya:yb, xa:xb], cv2.MORPH_CLOSE, kernel)
    return out, boxes


def _outlines(binary: np.ndarray, boxes: list[tuple[int, int, int, int]] | None) -> list:
    """``cv2.findContours(binary, RETR_EXTERNAL, CHAIN_APPROX_SIMPLE)``'s outlines, found box
    by box when the nonzero pixels lie inside separate ``boxes`` ``(y0, y1, x0, x1)`` with a
    0 line around each but at the image's edge (:func:`_close_lit`'s): a box holds whole
    outlines, and the boxes cost less to scan than the whole image.  In OpenCV's order: by
    each outline's first point (its top row's first pixel), the last in the image first."""
    if boxes is None:
        return list(cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)[0])
    found = []
    for ya, yb, xa, xb in boxes:
        part = binary[ya:yb, xa:xb]
        found += cv2.findContours(
            part, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE, offset=(xa, ya)
        )[0]
    found.sort(key=lambda c: (-int(c[0, 0, 1]), -int(c[0, 0, 0])))
    return found
