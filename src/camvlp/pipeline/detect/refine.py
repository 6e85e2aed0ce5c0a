"""Stage 1 at full resolution: each candidate region's disc, readout axis and centre.

A candidate of :func:`camvlp.pipeline.detect.detect_fixtures` is worked inside its region of
interest only: a threshold of its own, a closing along the sensor's readout axis that fills the
dark stripes, and the disc's outline.  The centre is the centre of an ellipse fitted to
sub-pixel edge points of the lit rows, so it comes from the disc and not from the stripes; its
covariance comes from the fit's residuals.  OpenCV's work is done region by region, NumPy's
for all the regions of a photo at once.

Also here: what a detected fixture is (:class:`Blob`), gray levels of a photo, the readout
axis a disc's stripes show, and a light's whole striped area (:func:`light_support`).
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.polynomial import legendre

from camvlp.geometry.disc import centre_sigma, ellipse_centre_covariance
from camvlp.imaging.levels import counted_percentiles, hist_percentiles, percentiles_u8
from camvlp.pipeline.detect.touching import own_face

__all__ = [
    "Blob",
    "find_readout_axis",
    "gray_float",
    "light_support",
    "refine_regions",
    "to_gray",
]


@dataclass(frozen=True)
class Blob:
    """One detected fixture.

    Attributes
    ----------
    pixel : ndarray, shape (2,)
        Centre of the disc ``[u, v]`` in full-resolution pixels (sub-pixel).
    box : tuple of int
        Region of interest ``(x0, y0, x1, y1)``, full resolution, end exclusive.
    mask : ndarray of bool, shape (y1 - y0, x1 - x0)
        The disc, stripes filled, inside the region of interest.
    axes_px : ndarray, shape (2,)
        Full lengths of the fitted ellipse's axes, pixels (major first).
    angle_deg : float
        Orientation of the fitted ellipse as :func:`cv2.fitEllipse` gives it, degrees: of the
        first axis it returns, which may be the minor one (``axes_px`` is sorted).  The
        consumers of the pair (the glow check, the row profiles' rings, the radial fit's
        starts) were measured with it as it is.
    touches_border : bool
        The disc is cut by the image border (its centre would be biased).
    axis : str
        Readout axis seen in this blob: ``"rows"`` (horizontal stripes) or ``"columns"``.
    stripe_contrast : float
        Variance ratio of the profile along the readout axis to the profile across it; high
        for a striped disc, near 1 for a steady light, below 1 when the readout was given and
        the blob varies more across it.
    edge_points : int
        Edge points the ellipse was fitted to (0 when the centroid was used instead).
    centre_cov_px2 : ndarray, shape (2, 2)
        Covariance of ``pixel`` from the ellipse fit's residuals, pixels squared (read-only:
        ``centre_cov`` when given, else :attr:`EllipseFit.covariance` of ``edge_fit``); NaN
        when the centroid was used or the fit cannot tell.
    gray : ndarray of uint8, shape (y1 - y0, x1 - x0), or None
        The region of interest in gray levels (:func:`to_gray`), kept so that later stages
        need not convert it again.
    cell : ndarray of bool, shape (y1 - y0, x1 - x0), or None
        The part of the region that is this light's when its glow joins other lights'
        (:mod:`camvlp.pipeline.detect.touching`); None when the region is all its own.
    face : bool
        ``mask`` is the light's face as its dark stripes show it
        (:func:`~camvlp.pipeline.detect.touching.own_face`: a light whose glow joins others'),
        not its lit pixels.
    stripe_share : float
        The share (0 to 1) of the variance of the light's pixels that its mean level per line
        along ``axis`` explains (:func:`stripe_share`): near 1 for a striped light (its
        lines alternate bright and dark across their whole length; 0.6 to 0.98 on the real
        photos' lights and the renders), low for text or a steady light.
    """

    pixel: np.ndarray
    box: tuple[int, int, int, int]
    mask: np.ndarray
    axes_px: np.ndarray
    angle_deg: float
    touches_border: bool
    axis: str
    stripe_contrast: float
    edge_points: int
    gray: np.ndarray | None = field(default=None, repr=False, compare=False)
    cell: np.ndarray | None = field(default=None, repr=False, compare=False)
    face: bool = field(default=False, repr=False, compare=False)
    stripe_share: float = field(default=float("nan"), compare=False)
    edge_fit: EllipseFit | None = field(default=None, repr=False, compare=False)
    centre_cov: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def centre_cov_px2(self) -> np.ndarray:
        """:attr:`centre_cov` when given, else the ellipse fit's (NaN without one), (2, 2)."""
        if self.centre_cov is not None:
            return self.centre_cov
        if self.edge_fit is None:
            return np.full((2, 2), np.nan)
        return self.edge_fit.covariance.copy()

    @property
    def centre_sigma_px(self) -> float:
        """The centre's uncertainty, pixels (1-sigma per axis, the RMS of the two): from
        :attr:`centre_cov_px2`, at least
        :data:`~camvlp.geometry.disc.CENTRE_SIGMA_FLOOR_PX`; NaN when unknown."""
        return centre_sigma(self.centre_cov_px2)


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


@functools.lru_cache(maxsize=64)
def structuring_element(shape: int, ksize: tuple[int, int]) -> np.ndarray:
    """``cv2.getStructuringElement(shape, ksize)``, made once per shape and size."""
    k = cv2.getStructuringElement(shape, ksize)
    k.flags.writeable = False
    return k


def _disc_mask(
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
        if lit_lines.size >= 2:  # (the ufunc's reduce: ndarray.max() goes through Python)
            gap = int(np.maximum.reduce(lit_lines[1:] - lit_lines[:-1])) - 1
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
    closed = cv2.morphologyEx(part, cv2.MORPH_CLOSE, structuring_element(cv2.MORPH_RECT, ksize))
    closed = cv2.morphologyEx(
        closed, cv2.MORPH_CLOSE, structuring_element(cv2.MORPH_ELLIPSE, (5, 5))
    )
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
        The detected disc (:attr:`Blob.mask`).
    axis : {"rows", "columns"}
        The readout axis (stripes across it).
    kernel_px : int
        Smallest closing length bridging the dark stripes, pixels.
    k_sigma : float
        Threshold above the background, in noise standard deviations.
    cell : ndarray of bool, shape (h, w), optional
        The light's own part of the region (:attr:`Blob.cell`): the support stays within it.

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
    found = _disc_mask(lit, axis, kernel_px)
    if found is None or not (found[0] & m).any():
        return m
    return found[0] | m


#: Dilation of a disc's mask that masks other lights out of its rows' crossings, per axis.
_EDGE_KERNELS = {"rows": np.ones((3, 7), np.uint8), "columns": np.ones((7, 3), np.uint8)}
#: The dilation of a region's lit pixels whose stripes say the readout axis.
_AXIS_KERNEL = np.ones((3, 3), np.uint8)


@dataclass(slots=True)  # (not frozen: a frozen dataclass sets each of its fields by a call)
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

    A region is thresholded at a quarter of the way from its background (10th percentile)
    to its peak (99.5th): real lights are brighter in the middle than at the rim.  The dark
    stripes are bridged by :func:`_disc_mask`; the centre is an ellipse fitted to sub-pixel
    edge points of the lit sensor rows (:func:`_edge_points`), or the mask's centroid when
    fewer than 12 edge points are found.  Of two regions whose discs are the same fixture the
    larger is kept; each ellipse's centre comes with its covariance
    (:class:`EllipseFit`).

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
        (:func:`~camvlp.pipeline.detect.touching.power_cell`; None: all of it): the disc is found
        within it, and no edge point is taken where it cuts the light off from another.
    guesses : tuple of float, optional
        Gray levels near the regions' background and peak (the photo's): the two levels are
        then found by counting pixels from them (:func:`counted_percentiles`) rather than
        from each region's histogram (the same levels).
    seeds : list of (ndarray or None), optional
        Per region with a cell, its light's ``[x, y, r]`` in the region's pixels
        (:func:`~camvlp.pipeline.detect.touching.light_seeds`, at full resolution): the disc is
        then its face in the dark stripes, when they show one that holds the seed's centre
        (:func:`~camvlp.pipeline.detect.touching.own_face`; its edge points on the dark-stripe
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
        if peak - background >= 10:
            levels_k = (background, peak)
            r = _region(
                img, boxes[k], grays[k], levels_k, readout, kernel_px, min_area, cells[k], seeds[k]
            )
            if r is not None:
                regions.append(r)
    found = [_fitted(r, p) for r, p in zip(regions, _edge_points(regions), strict=True)]
    return _blobs(_drop_duplicates(found, [r.area for r in regions]))


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
    # a low threshold: real lights are often brighter in the middle than at the rim; whole
    # gray levels are above it when they are above its floor
    thr = math.floor(background + 0.25 * (peak - background))
    lit = cv2.threshold(gray8, thr, 1, cv2.THRESH_BINARY)[1]  # 0 and 1
    beyond = None
    if cell is not None:  # a light whose glow joins others': its own cell only
        beyond = lit & ~cell
        lit = lit & cell
    lit_box = cv2.boundingRect(lit)
    # the readout axis on the lit pixels' box grown by the dilation's reach (nothing beyond)
    x, y, w, h = lit_box
    near = (slice(max(0, y - 1), y + h + 1), slice(max(0, x - 1), x + w + 1))
    # (dilated: the dark stripes' pixels next to the lit ones count, or each line's mean
    # would be only its lit pixels' and the stripes would not show)
    axis, contrast = axis_contrast(gray8[near], cv2.dilate(lit[near], _AXIS_KERNEL))
    if readout is not None and readout != axis:  # along the given axis: less than across
        axis, contrast = readout, 1.0 / contrast
    edges, edge_bg, on_face = gray8, background, False  # the image of the edge points
    found = None if seed is None or cell is None else own_face(gray8, lit, cell, axis, seed)
    if found is not None:  # its face, unclipped in its dark stripes
        lit, edges, on_face = found[0], found[1], True
        edge_bg = percentiles_u8(edges, [10])[0]
        lit_box = None
    found = _disc_mask(lit, axis, kernel_px, lit_box)
    if found is None:
        return None
    mask, disc_box = found
    area = float(np.count_nonzero(mask))
    if area < min_area:
        return None
    share = stripe_share(gray8, mask.view(np.uint8), axis)  # over the disc, dark stripes too
    x0, y0, x1, y1 = box
    height, width = img.shape[:2]
    # the disc reaches an edge of its region that is the image's: its bright part, for a
    # glow beyond the disc may reach the border where the disc does not (the rows the
    # border cuts give no edge points, the rest are whole)
    bright = background + 0.6 * (peak - background)

    def lit_at(edge: tuple) -> bool:  # the disc's bright part on one edge of the region
        return bool((mask[edge] & (gray8[edge] > bright)).any())

    touches = (
        (x0 == 0 and lit_at((slice(None), 0)))
        or (y0 == 0 and lit_at((0,)))
        or (x1 == width and lit_at((slice(None), -1)))
        or (y1 == height and lit_at((-1,)))
    )
    return _Region(
        box,
        gray8,
        mask,
        area,
        axis,
        contrast,
        share,
        touches,
        edge_bg,
        *_edge_rows(edges, mask, disc_box, axis),
        cell,
        beyond,
        on_face,
    )


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
    # the product by NumPy, of the whole region (contiguous: of the crops it takes twice as
    # long, by OpenCV more still)
    inside = np.multiply(gray, mask.view(np.uint8))[box]
    sums = cv2.reduce(inside, dim, cv2.REDUCE_SUM, dtype=cv2.CV_32F).ravel()
    near = cv2.dilate(m8, _EDGE_KERNELS[axis]).view(bool)
    if rows_axis:
        return counts, sums, gray[y : y + h], y, near, a
    return counts, sums, gray[:, y : y + h].T, y, near.T, a


#: For :func:`_edge_points`, shapes (2, 2, 1) and (2, 1): the columns either side of a
#: row's crossings from its two ends (the left end's one before and itself, the right
#: end's itself and one after), each end's sign of the steps along the row (float32, as the
#: levels), and each end's offset of the crossing from the first of its columns.
_SIDES = np.array([[[-1], [0]], [[0], [1]]])
_SIGNS = np.array([[1], [-1]], np.float32)
_BEFORE = np.array([[1], [0]])


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
    # (the regions' few levels as Python floats)
    counts = np.concatenate([r.counts for r in regions])
    level = np.concatenate([r.sums for r in regions]) / np.maximum(counts, 1)  # 0 outside
    begin = [0, *itertools.accumulate(sizes[:-1])]
    bg = [r.background for r in regions]
    top = np.maximum.reduceat(level, begin).tolist()
    rise = np.array([b + 0.35 * (t - b) for b, t in zip(bg, top, strict=True)]).repeat(sizes)
    lit = ((counts >= 4) & (level > rise)).nonzero()[0]
    background = np.array(bg).repeat(sizes)
    half = background + 0.5 * (level - background)
    # above half-way (other lights masked out: the background is below half-way); the
    # half-way levels lie between 0 and 255, and a whole level is above one when it is above
    # its floor: compared as uint8, not as floats.  Compared in the whole stack, the lit
    # rows then copied once (rather than both the stack's gray levels and its mask)
    above = (near & (g > np.floor(half).astype(np.uint8)[:, None]))[lit]
    left = above.argmax(axis=1)  # 0 also when nothing is above: such a row is left out
    # the last above: the first of the rows flipped (by OpenCV, contiguous, which NumPy's
    # argmax of bools scans fast, where it steps through a reversed view one by one)
    right = width - 1 - cv2.flip(above.view(np.uint8), 1).view(bool).argmax(axis=1)
    last = width - 1 if min(widths) == width else np.array(widths).repeat(sizes)[lit] - 1
    j = ((left > 0) & (right < last) & (right - left >= 3)).nonzero()[0]
    ends = np.array([left[j], right[j]])  # (2, m): each kept row's left, right end
    k = lit[j]  # the kept rows in the stack
    half = half[k]
    # the rows' levels either side of both crossings, other lights masked out (gathered from
    # the flat stack: NumPy's 2-D fancy indexing costs several times as much): (2, 2, m),
    # the left end's [a0, a1], the right end's [b0, b1]
    cols = (ends + k * width)[:, None] + _SIDES
    v = np.where(near.take(cols), g.take(cols), background[k]).astype(np.float32)
    # per kept row: its left end, its right end, along the row; its row across.  The right
    # end's steps are the left's negated (exact): (b0 - half) / max(b0 - b1, 1e-6)
    pts = np.empty((2, j.size, 2))
    step = np.maximum((v[:, 1] - v[:, 0]) * _SIGNS, 1e-6)
    pts[:, :, 0] = ends - _BEFORE + (half - v[:, 0]) * _SIGNS / step
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


def _drop_duplicates(
    found: list[tuple[dict, tuple | None]], areas: list[float]
) -> list[tuple[dict, tuple | None]]:
    """Two candidates whose refined discs are the same fixture: keep the larger (each blob's
    fields with its ellipse fit; ``areas``: each one's disc's pixels), the larger first.

    A photo has a few candidates: their centres' distances are taken in Python floats, each
    pair's when it is asked (NumPy's calls cost more than the arithmetic on a few values)."""
    order = sorted(range(len(found)), key=lambda i: -areas[i])
    xy = [b["pixel"].tolist() for b, _ in found]
    r = [0.5 * float(b["axes_px"][1]) for b, _ in found]
    keep: list[int] = []
    for i in order:
        (x, y), ri = xy[i], r[i]
        if all(
            math.hypot(x - xy[j][0], y - xy[j][1]) > max(ri, r[j])
            or _two_cells(found[i][0], found[j][0])
            for j in keep
        ):
            keep.append(i)
    return [found[i] for i in keep]


#: Least ratio of a disc's outline's axes: a round fixture seen at most 60 degrees from
#: face-on (the ratio is the cosine of that angle).
MIN_AXIS_RATIO = 0.5


#: Two outlines are one disc when their centres lie within this share of its radius and
#: their axes differ by at most this share.
SAME_OUTLINE = 0.1


def _one_outline(a: dict, b: dict) -> bool:
    """Whether two candidates' fitted outlines are one ellipse (:data:`SAME_OUTLINE`): a
    light whose wide bands were taken for several lights, each cell of it fitted with the
    whole light's edges."""
    ra, rb = np.asarray(a["axes_px"], dtype=float), np.asarray(b["axes_px"], dtype=float)
    if not (np.all(np.isfinite(ra)) and np.all(np.isfinite(rb))):
        return False
    radius = 0.25 * float(ra.sum() + rb.sum()) / 2.0
    near = math.dist(a["pixel"].tolist(), b["pixel"].tolist()) <= SAME_OUTLINE * radius
    return near and bool(np.all(np.abs(ra - rb) <= SAME_OUTLINE * np.maximum(ra, rb)))


def _two_cells(a: dict, b: dict) -> bool:
    """Whether candidate ``a`` is a light of its own beside ``b``, however close their
    centres: both are lights that a joined region was split into (each has a
    :attr:`Blob.cell`), their discs share less than half the smaller one's pixels, and
    ``a``'s outline is a disc's (its axes' ratio at least :data:`MIN_AXIS_RATIO`).

    An outline fitted to a cell's edge, where the cell cut its light off from the other, may
    come out far too large: half its smaller axis reached past the other light's centre, and
    the other light, 7 px from its lamp, was dropped as its duplicate.  A piece of glow that
    a split took for a light stays dropped (a sliver 315 x 76 px beside a lamp of 458 x 347:
    kept, it drew the joint fit of the glows 11 px off that lamp)."""
    if a["cell"] is None or b["cell"] is None:
        return False
    if a["axes_px"][1] < MIN_AXIS_RATIO * a["axes_px"][0]:
        return False
    if _one_outline(a, b):  # each cell's edge points drew the whole of one light
        return False
    (ax0, ay0, ax1, ay1), (bx0, by0, bx1, by1) = a["box"], b["box"]
    x0, y0, x1, y1 = max(ax0, bx0), max(ay0, by0), min(ax1, bx1), min(ay1, by1)
    shared = 0
    if x0 < x1 and y0 < y1:
        ma = a["mask"][y0 - ay0 : y1 - ay0, x0 - ax0 : x1 - ax0]
        mb = b["mask"][y0 - by0 : y1 - by0, x0 - bx0 : x1 - bx0]
        shared = np.count_nonzero(ma & mb)
    return shared < 0.5 * min(np.count_nonzero(a["mask"]), np.count_nonzero(b["mask"]))


def _blobs(found: list[tuple[dict, tuple | None]]) -> list[Blob]:
    """The blobs, each with its ellipse fit ``(points, centre, axes, angle)`` (its centre's
    covariance worked out when first read); a centroid's has none."""
    return [
        Blob(**b, edge_fit=None if fit is None else EllipseFit(*fit, b["axis"])) for b, fit in found
    ]


@dataclass(frozen=True)
class EllipseFit:
    """The ellipse fitted to a disc's edge points, whose scatter tells how sure its centre is.

    Attributes
    ----------
    points : ndarray, shape (M, 2)
        The edge points fitted, pixels.
    centre : ndarray, shape (2,)
    axes : ndarray, shape (2,)
        Full lengths of the axes, as :func:`cv2.fitEllipse` gives them.
    angle_deg : float
    axis : {"rows", "columns"}
        The readout axis: the points of a run of sensor lines share their errors.
    """

    points: np.ndarray
    centre: np.ndarray
    axes: np.ndarray
    angle_deg: float
    axis: str

    @functools.cached_property
    def covariance(self) -> np.ndarray:
        """The centre's covariance, pixels squared, shape (2, 2)
        (:func:`~camvlp.geometry.disc.ellipse_centre_covariance`, the points grouped by
        :func:`row_groups`); worked out when first read (most calls never read it)."""
        groups = row_groups(self.points, self.axis)
        return ellipse_centre_covariance(
            self.points, self.centre, self.axes, self.angle_deg, groups
        )


def row_groups(points: np.ndarray, axis: str) -> np.ndarray:
    """The groups of edge points (M, 2) whose errors an ellipse's centre covariance takes as
    shared (:func:`~camvlp.geometry.disc.ellipse_centre_covariance`): runs of about sqrt(n)
    consecutive sensor lines out of the n they span (batch means).  A line's two ends share
    its exposure, and the stripes make neighbouring lines' errors depend on each other,
    while runs far apart do not.  One label per point, shape (M,)."""
    lines = points[:, 1] if axis == "rows" else points[:, 0]
    low = lines.min()
    step = max(1.0, math.sqrt(lines.max() - low + 1.0))
    return np.floor((lines - low) / step).astype(np.int64)
