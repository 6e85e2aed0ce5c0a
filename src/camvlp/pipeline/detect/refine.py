"""Stage 1 at full resolution: each candidate region's disc, readout axis and centre.

A candidate of :func:`camvlp.pipeline.detect.detect_fixtures` is worked inside its region of
interest only: a threshold of its own, a closing along the sensor's readout axis that fills the
dark stripes (:func:`~camvlp.pipeline.detect.disc.disc_mask`), and the disc's outline.  The
centre is the centre of an ellipse fitted to sub-pixel edge points of the lit sensor lines,
where each line's level crosses half-way between the background and the line's own level, so
it comes from the disc and not from the stripes; its covariance comes from the fit's
residuals.  OpenCV's work is done region by region, NumPy's for all the regions of a photo at
once.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.imaging.gray import to_gray
from camvlp.imaging.levels import counted_percentiles, hist_percentiles, percentiles_u8
from camvlp.pipeline.detect.blob import Blob, EllipseFit
from camvlp.pipeline.detect.disc import disc_mask
from camvlp.pipeline.detect.duplicates import drop_duplicates
from camvlp.pipeline.detect.faces import own_face
from camvlp.pipeline.detect.readout import axis_contrast, stripe_share

__all__ = ["refine_regions"]


#: Dilation of a disc's mask that masks other lights out of its rows' crossings, per axis.
_EDGE_KERNELS = {"rows": np.ones((3, 7), np.uint8), "columns": np.ones((7, 3), np.uint8)}
#: The dilation of a region's lit pixels whose stripes say the readout axis.
_AXIS_KERNEL = np.ones((3, 3), np.uint8)


@dataclass(frozen=True)
class _Region:
    """A candidate region's disc, and the sensor rows that cross it (internal).

    Of those rows (image rows or columns, from ``first`` on; :func:`_edge_rows`),
    ``counts`` and ``sums`` are their pixels and gray sums inside the disc, ``lines`` and
    ``near`` their pixels along the row (gray levels of the edge points' image; near the
    disc), one row each, ``near`` from the row's pixel ``near_at`` on (none is near before
    or after it); ``background`` is the edge points' image's background level."""

    box: tuple[int, int, int, int]
    gray8: np.ndarray
    mask: np.ndarray
    area: float
    axis: str
    contrast: float
    share: float
    touches: bool
    background: float
    counts: np.ndarray
    sums: np.ndarray
    lines: np.ndarray
    first: int
    near: np.ndarray
    near_at: int
    cell: np.ndarray | None
    beyond: np.ndarray | None
    face: bool = False


def refine_regions(
    img: np.ndarray,
    boxes: list[tuple[int, int, int, int]],
    readout: str | None,
    kernel_px: int,
    min_diameter_px: float,
    cells: list[np.ndarray | None] | None = None,
    guesses: tuple[float, float] | None = None,
    seeds: list[np.ndarray | None] | None = None,
) -> list[Blob]:
    """The candidate regions at full resolution: each one's disc, readout axis and centre.

    A region is thresholded at a quarter of the way from its background (10th percentile) to its
    peak (99.5th): real lights are brighter in the middle than at the rim.  The dark stripes are
    bridged by :func:`~camvlp.pipeline.detect.disc.disc_mask`; the centre is an ellipse fitted to
    sub-pixel edge points of the lit sensor rows (:func:`_edge_points`), or the mask's centroid when
    fewer than 12 edge points are found.  Of two regions whose discs are the same fixture the larger
    is kept; each ellipse's centre comes with its covariance
    (:class:`~camvlp.pipeline.detect.blob.EllipseFit`).

    Parameters
    ----------
    img : ndarray, shape (H, W) or (H, W, 3)
        The whole photo.
    boxes : list of tuple of int
        The regions, ``(x0, y0, x1, y1)`` in full-resolution pixels (x1, y1 exclusive).
    readout : {"rows", "columns", None}
        The readout axis, or None to find it from each region's stripes.
    kernel_px : int
        Smallest closing length, pixels.
    min_diameter_px : float
        Smallest disc kept, pixels.
    cells : list of (ndarray of bool or None), optional
        Per region, the part of it that is its light's when lights' glows join
        (:func:`~camvlp.pipeline.detect.peaks.power_cell`; None: all of it): the disc is found
        within it, and no edge point is taken where it cuts the light off from another.
    guesses : tuple of float, optional
        Gray levels near the regions' background and peak (the photo's): the two levels are
        then found by counting pixels from them (:func:`counted_percentiles`) rather than
        from each region's histogram (the same levels).
    seeds : list of (ndarray or None), optional
        Per region with a cell, its light's ``[x, y, r]`` in the region's pixels
        (:func:`~camvlp.pipeline.detect.peaks.light_seeds`, at full resolution): the disc is
        then its face in the dark stripes, when they show one that holds the seed's centre
        (:func:`~camvlp.pipeline.detect.faces.own_face`; its edge points on the dark-stripe
        levels), else its lit pixels as above.

    Returns
    -------
    list of Blob
        The discs found, the larger first; regions holding no light large and bright enough
        give none.
    """
    grays = [to_gray(img[y0:y1, x0:x1]) for x0, y0, x1, y1 in boxes]
    usable = [k for k, g in enumerate(grays) if g.shape[0] >= 3 and g.shape[1] >= 3]
    if not usable:
        return []
    cells = cells or [None] * len(boxes)
    seeds = seeds or [None] * len(boxes)
    if guesses is None:
        hists = np.stack(
            [cv2.calcHist([grays[k]], [0], None, [256], [0, 256]).ravel() for k in usable]
        )
        levels = hist_percentiles(hists, [10, 99.5]).tolist()
    else:  # each region's guesses: the previous region's levels (lights look alike)
        levels = []
        for k in usable:
            guesses = counted_percentiles(grays[k], (10, 99.5), guesses)
            levels.append(guesses)
    regions = []
    min_area = 0.5 * min_diameter_px**2
    for k, (background, peak) in zip(usable, levels, strict=True):
        if peak - background < 10:
            continue
        r = _region(
            img,
            boxes[k],
            grays[k],
            (background, peak),
            readout=readout,
            kernel_px=kernel_px,
            min_area=min_area,
            cell=cells[k],
            seed=seeds[k],
        )
        if r is not None:
            regions.append(r)
    found = [_fitted(r, p) for r, p in zip(regions, _edge_points(regions), strict=True)]
    return _blobs(drop_duplicates(found, [r.area for r in regions]))


def _region(
    img: np.ndarray,
    box: tuple[int, int, int, int],
    gray8: np.ndarray,
    levels: tuple[float, float],
    readout: str | None,
    kernel_px: int,
    min_area: float,
    cell: np.ndarray | None,
    seed: np.ndarray | None = None,
) -> _Region | None:
    """A region's disc and its rows for edge points, from its gray levels and its background
    and peak levels, within its light's ``cell`` when it has one (its face in the dark
    stripes when it has a ``seed`` and they show it); None when its disc is smaller than
    ``min_area`` pixels or none is lit."""
    background, peak = levels
    lit, beyond = _lit_pixels(gray8, background, peak, cell)
    lit_box = cv2.boundingRect(lit)
    axis, contrast = _readout(gray8, lit, lit_box, readout)
    edges, edge_bg, on_face = gray8, background, False  # the image of the edge points
    found = None if seed is None or cell is None else own_face(gray8, lit, cell, axis, seed)
    if found is not None:  # its face, unclipped in its dark stripes
        lit, edges, on_face = found[0], found[1], True
        edge_bg = percentiles_u8(edges, [10])[0]
        lit_box = None
    found = disc_mask(lit, axis, kernel_px, lit_box)
    if found is None:
        return None
    mask, disc_box = found
    area = float(np.count_nonzero(mask))
    if area < min_area:
        return None
    return _Region(
        box,
        gray8,
        mask,
        area,
        axis,
        contrast,
        stripe_share(gray8, mask.view(np.uint8), axis),  # over the disc, dark stripes too
        _touches_border(box, img.shape[:2], gray8, mask, background + 0.6 * (peak - background)),
        edge_bg,
        *_edge_rows(edges, mask, disc_box, axis),
        cell,
        beyond,
        on_face,
    )


def _lit_pixels(
    gray8: np.ndarray, background: float, peak: float, cell: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """A region's lit pixels (uint8 0 and 1, within ``cell`` when given) and those of its
    lit pixels that lie beyond its cell (None without one).

    The threshold is low, a quarter of the way from the background to the peak: real lights
    are often brighter in the middle than at the rim."""
    # whole gray levels are above the threshold when they are above its floor
    thr = math.floor(background + 0.25 * (peak - background))
    lit = cv2.threshold(gray8, thr, 1, cv2.THRESH_BINARY)[1]
    if cell is None:
        return lit, None
    return lit & cell, lit & ~cell  # a light whose glow joins others': its own cell only


def _readout(
    gray8: np.ndarray, lit: np.ndarray, lit_box: tuple[int, int, int, int], readout: str | None
) -> tuple[str, float]:
    """The readout axis a region's lit pixels show and its contrast
    (:func:`~camvlp.pipeline.detect.readout.axis_contrast`), or the given ``readout`` with
    the contrast along it (below 1 when the region varies more across it).

    Worked on the lit pixels' box ``lit_box`` ``(x, y, w, h)`` grown by the dilation's reach
    (nothing lies beyond); the lit pixels dilated, so that the dark stripes' pixels next to
    them count, or each line's mean would be only its lit pixels' and the stripes would not
    show."""
    x, y, w, h = lit_box
    near = (slice(max(0, y - 1), y + h + 1), slice(max(0, x - 1), x + w + 1))
    axis, contrast = axis_contrast(gray8[near], cv2.dilate(lit[near], _AXIS_KERNEL))
    if readout is not None and readout != axis:
        return readout, 1.0 / contrast
    return axis, contrast


#: A disc's bright part whose line nearest the photo's edge (a dark stripe's width from it)
#: is this share of its widest line's width or more is cut there: a disc's cap, a dark
#: stripe's width (a few lines) in, is a fraction of its diameter.
CUT_CHORD = 0.7


def _touches_border(
    box: tuple[int, int, int, int],
    shape: tuple[int, int],
    gray8: np.ndarray,
    mask: np.ndarray,
    bright: float,
) -> bool:
    """Whether a region's disc ``mask`` reaches an edge of the region ``box``
    ``(x0, y0, x1, y1)`` that is the photo's (of ``shape`` (H, W)) with its bright part (its
    gray levels ``gray8`` above ``bright``; a glow beyond the disc may reach the border where
    the disc does not), or may reach it under a dark stripe (:func:`_under_a_stripe`)."""
    x0, y0, x1, y1 = box
    height, width = shape
    if not (x0 == 0 or y0 == 0 or x1 == width or y1 == height):
        return False  # (the region lies within the photo)
    lit = mask & (gray8 > bright)
    if not lit.any():
        return False
    across, along = lit.sum(axis=1), lit.sum(axis=0)  # lit pixels per row, per column
    return bool(
        (x0 == 0 and _under_a_stripe(along))
        or (y0 == 0 and _under_a_stripe(across))
        or (x1 == width and _under_a_stripe(along[::-1]))
        or (y1 == height and _under_a_stripe(across[::-1]))
    )


def _under_a_stripe(widths: np.ndarray) -> bool:
    """Whether a disc whose bright part has ``widths`` (lit pixels per line, from the
    photo's edge inward) may reach that edge: it is lit on the edge's line, or its nearest
    lit line is a chord as wide as most of its lines (it does not close as a disc's cap does)
    within the dark run a stripe can leave (twice its longest lit run, or its widest gap:
    the border may cut the disc in a dark stripe)."""
    lines = np.flatnonzero(widths)
    first = int(lines[0])
    if first == 0:
        return True
    runs = np.split(lines, np.flatnonzero(np.diff(lines) > 1) + 1)
    gap = int(np.diff(lines).max()) - 1 if lines.size > 1 else 0
    reach = max(gap, 2 * max(len(r) for r in runs))
    return first <= reach and widths[first] >= CUT_CHORD * widths.max()


def _edge_rows(
    gray: np.ndarray,
    mask: np.ndarray,
    disc_box: tuple[int, int, int, int],
    axis: str,
):
    """The sensor rows that cross a disc, for :func:`_edge_points`: those of its bounding
    box ``disc_box`` ``(x, y, w, h)``.  Returns their pixels inside the disc and their gray
    sums there (float32, exact: whole levels below 2**24), their gray levels (a view, one row
    each), the first one's index, and their pixels near the disc (the mask dilated) from the
    column given last on.

    Worked on the box widened along the rows by the dilation's reach (OpenCV's morphology
    costs by area): the disc has no pixel beyond it, so the rows' sums and the dilation there
    are the whole region's."""
    x, y, w, h = disc_box
    rows_axis = axis == "rows"
    if not rows_axis:  # the same on the transposed box (the rows are columns)
        x, y, w, h = y, x, h, w
    a, b = max(x - 3, 0), x + w + 3  # (_EDGE_KERNELS' reach along a row)
    box = (slice(y, y + h), slice(a, b)) if rows_axis else (slice(a, b), slice(y, y + h))
    m8 = mask.view(np.uint8)[box]
    dim = 1 if rows_axis else 0  # cv2.reduce to one value per sensor row
    counts = cv2.reduce(m8, dim, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
    inside = np.multiply(gray, mask.view(np.uint8))[box]  # the disc's gray levels, 0 outside
    sums = cv2.reduce(inside, dim, cv2.REDUCE_SUM, dtype=cv2.CV_32F).ravel()
    near = cv2.dilate(m8, _EDGE_KERNELS[axis]).view(bool)
    if rows_axis:
        return counts, sums, gray[y : y + h], y, near, a
    return counts, sums, gray[:, y : y + h].T, y, near.T, a


def _edge_points(regions: list[_Region]) -> list[np.ndarray]:
    """Sub-pixel disc edge points along each region's lit sensor rows, each (M, 2) as (x, y).

    A sensor row is lit when it crosses the disc by four pixels or more and its level inside
    it is more than 0.35 of the way from the background to the brightest row's.  Each lit
    row crosses the disc once; its two ends are found where the row's intensity crosses
    half-way between the background and the row's own level inside the disc, so partly lit
    rows (stripe transitions) give the same chord as fully lit ones.  Pixels away from the
    disc (other lights) are left out.  The rows of all regions are worked as one stack;
    each region's points are its rows' left ends, then their right ends.
    """
    sizes = [r.counts.size for r in regions]
    total = sum(sizes)
    if total == 0:
        return [np.zeros((0, 2)) for _ in regions]
    widths = [r.lines.shape[1] for r in regions]
    width = max(widths)
    g = np.zeros((total, width), np.uint8)
    near = np.zeros((total, width), bool)
    at = 0
    for r, n, w in zip(regions, sizes, widths, strict=True):
        g[at : at + n, :w] = r.lines
        near[at : at + n, r.near_at : r.near_at + r.near.shape[1]] = r.near
        at += n
    # the lit rows: each row's level inside its disc, against its region's brightest row's
    counts = np.concatenate([r.counts for r in regions])
    level = np.concatenate([r.sums for r in regions]) / np.maximum(counts, 1)  # 0 outside
    begin = [0, *itertools.accumulate(sizes[:-1])]
    bg = np.array([r.background for r in regions], dtype=np.float64)
    top = np.maximum.reduceat(level, begin)
    rise = (bg + 0.35 * (top - bg)).repeat(sizes)
    lit = ((counts >= 4) & (level > rise)).nonzero()[0]
    background = bg.repeat(sizes)
    half = background + 0.5 * (level - background)
    # above half-way (other lights masked out: the background is below half-way); the
    # half-way levels lie between 0 and 255, and a whole level is above one when it is above
    # its floor: compared as uint8, not as floats.  Compared in the whole stack, the lit
    # rows then copied once (rather than both the stack's gray levels and its mask)
    above = (near & (g > np.floor(half).astype(np.uint8)[:, None]))[lit]
    left = above.argmax(axis=1)  # 0 also when nothing is above: such a row is left out
    right = width - 1 - above[:, ::-1].argmax(axis=1)  # the last above
    last = width - 1 if min(widths) == width else np.array(widths).repeat(sizes)[lit] - 1
    j = ((left > 0) & (right < last) & (right - left >= 3)).nonzero()[0]
    left, right = left[j], right[j]
    k = lit[j]  # the kept rows in the stack
    half = half[k]

    def levels_at(col: np.ndarray) -> np.ndarray:  # the kept rows', other lights masked out
        return np.where(near[k, col], g[k, col], background[k]).astype(np.float32)

    # each end's crossing of half-way between the levels either side of it: the left end's
    # between the column before it and itself, the right end's between itself and the next
    a0, a1, b0, b1 = (levels_at(c) for c in (left - 1, left, right, right + 1))
    pts = np.empty((2, j.size, 2))  # per kept row: its left end, its right end; (along, across)
    pts[0, :, 0] = left - 1 + (half - a0) / np.maximum(a1 - a0, 1e-6)
    pts[1, :, 0] = right + (b0 - half) / np.maximum(b0 - b1, 1e-6)
    first = np.array([r.first - a for r, a in zip(regions, begin, strict=True)])
    pts[:, :, 1] = k + first.repeat(sizes)[k]  # in its region
    # each region's left ends, then its right ends; x in the column its axis says
    ends = k.searchsorted(list(itertools.accumulate(sizes))).tolist()  # its rows' end
    return [
        pts[:, a:b].reshape(-1, 2) if r.axis == "rows" else pts[:, a:b, ::-1].reshape(-1, 2)
        for r, a, b in zip(regions, [0, *ends[:-1]], ends, strict=True)
    ]


def _fitted(r: _Region, points: np.ndarray) -> tuple[dict, tuple | None]:
    """A region's blob (its fields, the centre's covariance still to come) and its ellipse
    fit ``(points, centre, axes, angle_deg)`` in the region's pixels (None for a centroid)."""
    if r.beyond is not None and points.size:  # not where the cell cuts it off from another
        near = cv2.dilate(r.beyond, np.ones((5, 5), np.uint8))
        xy = np.rint(points).astype(np.intp)
        h0, w0 = near.shape
        points = points[near[xy[:, 1].clip(0, h0 - 1), xy[:, 0].clip(0, w0 - 1)] == 0]
    fit = None
    h, w = r.mask.shape
    if points.shape[0] >= 12:
        (cx, cy), (a, b), angle = cv2.fitEllipse(points.astype(np.float32))
        if not (0 <= cx < w and 0 <= cy < h):
            points = np.zeros((0, 2))
        else:
            fit = (points, (cx, cy), (a, b), angle)
    if points.shape[0] < 12:
        m = cv2.moments(r.mask.view(np.uint8), binaryImage=True)
        cx, cy = m["m10"] / m["m00"], m["m01"] / m["m00"]
        a = b = 2.0 * np.sqrt(r.area / np.pi)
        angle = 0.0
    x0, y0 = r.box[:2]
    fields = dict(
        pixel=np.array([x0 + cx, y0 + cy]),
        box=r.box,
        mask=r.mask,
        axes_px=np.array(sorted((float(a), float(b)), reverse=True)),
        angle_deg=float(angle),
        touches_border=r.touches,
        axis=r.axis,
        stripe_contrast=float(r.contrast),
        stripe_share=float(r.share),
        edge_points=int(points.shape[0]),
        gray=r.gray8,
        cell=r.cell,
        face=r.face,
    )
    return fields, fit


def _blobs(found: list[tuple[dict, tuple | None]]) -> list[Blob]:
    """The blobs, each with its ellipse fit ``(points, centre, axes, angle)`` (its centre's
    covariance worked out when first read); a centroid's has none."""
    return [
        Blob(**b, edge_fit=None if fit is None else EllipseFit(*fit, b["axis"])) for b, fit in found
    ]
