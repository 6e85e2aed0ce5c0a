"""Stage 1: find the fixtures in a photograph (thesis section 5.2, made fast and sub-pixel).

Candidates are found on a reduced copy of the image (threshold, then closing so that each
striped disc becomes one blob, then connected components).  Each candidate is then worked at
full resolution inside its region of interest only: a threshold of its own, a closing along
the sensor's readout axis that fills the dark stripes, and the disc's outline.  The centre is
the centre of an ellipse fitted to sub-pixel edge points of the lit rows, so it comes from the
disc and not from the stripes.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from camvlp.geometry.disc import centre_sigma, ellipse_centre_covariances
from camvlp.pipeline.touching import not_convex, one_per_light, power_cell

__all__ = [
    "Blob",
    "Detection",
    "detect_fixtures",
    "find_readout_axis",
    "gray_float",
    "light_support",
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
        Orientation of the fitted ellipse (OpenCV's convention), degrees.
    touches_border : bool
        The disc is cut by the image border (its centre would be biased).
    axis : str
        Readout axis seen in this blob: ``"rows"`` (horizontal stripes) or ``"columns"``.
    stripe_contrast : float
        Variance ratio of the profile along the readout axis to the profile across it; high
        for a striped disc, near 1 for a steady light.
    edge_points : int
        Edge points the ellipse was fitted to (0 when the centroid was used instead).
    centre_cov_px2 : ndarray, shape (2, 2)
        Covariance of ``pixel`` from the ellipse fit's residuals, pixels squared
        (:func:`~camvlp.geometry.disc.ellipse_centre_covariance`); NaN when the centroid was
        used or the fit cannot tell.
    gray : ndarray of uint8, shape (y1 - y0, x1 - x0), or None
        The region of interest in gray levels (:func:`to_gray`), kept so that later stages
        need not convert it again.
    cell : ndarray of bool, shape (y1 - y0, x1 - x0), or None
        The part of the region that is this light's when its glow joins other lights'
        (:mod:`camvlp.pipeline.touching`); None when the region is all its own.
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
    centre_cov_px2: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))

    gray: np.ndarray | None = field(default=None, repr=False, compare=False)
    cell: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def centre_sigma_px(self) -> float:
        """The centre's uncertainty, pixels (1-sigma per axis, the RMS of the two): from
        :attr:`centre_cov_px2`, at least
        :data:`~camvlp.geometry.disc.CENTRE_SIGMA_FLOOR_PX`; NaN when unknown."""
        return centre_sigma(self.centre_cov_px2)


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


def _luma(image: np.ndarray, dtype=None) -> np.ndarray:
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
    return _luma(image, np.float32).astype(np.float64)


def to_gray(image: np.ndarray) -> np.ndarray:
    """Gray ``uint8`` (H, W) from a BGR (H, W, 3) or gray image, 8- or 16-bit."""
    if isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.shape[2:] == (3,):
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)  # the usual photo: as _luma does it
    img = _luma(image)
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
        return _axis_contrast(g, m)
    m = m.astype(np.float32)
    g = g.astype(np.float32, copy=False) * m
    return _axis_from_sums(g.sum(1), m.sum(1), g.sum(0), m.sum(0))


def _axis_contrast(gray8: np.ndarray, mask01: np.ndarray) -> tuple[str, float]:
    """:func:`find_readout_axis` of a uint8 region and a uint8 mask of 0 and 1: the sums by
    OpenCV, exact in float32 like NumPy's (whole levels, below 2**24)."""
    g = cv2.multiply(gray8, mask01)
    sums = [
        cv2.reduce(a, dim, cv2.REDUCE_SUM, dtype=cv2.CV_32F).ravel()
        for dim in (1, 0)
        for a in (g, mask01)
    ]
    return _axis_from_sums(*sums)


def _axis_from_sums(row_sums, n_rows, col_sums, n_cols) -> tuple[str, float]:
    """The readout axis and contrast from a disc's gray sums and pixel counts per row and
    per column (float32)."""
    keep_r, keep_c = n_rows >= 3, n_cols >= 3
    rows = row_sums[keep_r] / n_rows[keep_r]
    cols = col_sums[keep_c] / n_cols[keep_c]
    vr = _diff_var(rows) if rows.size > 2 else 0.0
    vc = _diff_var(cols) if cols.size > 2 else 0.0
    if vr >= vc:
        return "rows", vr / max(vc, 1e-9)
    return "columns", vc / max(vr, 1e-9)


def _diff_var(v: np.ndarray) -> float:
    """``np.var(np.diff(v))`` with NumPy's own steps (mean, squared deviations, mean), in
    the array's dtype, without ``np.var``'s set-up."""
    d = v[1:] - v[:-1]
    x = d - np.add.reduce(d, keepdims=True) / d.size
    return float(np.add.reduce(x * x) / d.size)


def _percentiles_u8(gray: np.ndarray, qs) -> list[float]:
    """Percentiles (0-100) of a uint8 image from its histogram (much faster than sorting)."""
    cdf = cv2.calcHist([gray], [0], None, [256], [0, 256]).ravel().cumsum()
    # each level where the count reaches q % of the pixels, in float32 as the counts are
    at = np.array([q / 100.0 for q in qs], np.float32) * cdf[-1]
    return np.searchsorted(cdf, at).astype(float).tolist()


def _median_u8(gray: np.ndarray, max_steps: int = 4) -> float:
    """``_percentiles_u8(gray, [50])`` of a large uint8 image without its whole histogram.

    The median of every fourth row is a guess, checked (and moved level by level) by
    counting the pixels at or below a level in the whole image: the smallest level with at
    least half the pixels at or below it, as the histogram's cumulative sum finds it.  After
    ``max_steps`` moves, the whole histogram is counted instead.
    """
    n = gray.size
    if gray.ndim != 2 or n < 4096:
        return _percentiles_u8(gray, [50])[0]
    (level,) = _percentiles_u8(gray[::4], [50])
    v = int(level)

    def enough(v: int) -> bool:  # at least half the pixels at or below level v
        above = cv2.countNonZero(cv2.threshold(gray, v, 255, cv2.THRESH_BINARY)[1])
        return 2 * (n - above) >= n

    step = -1 if enough(v) else 1
    for _ in range(max_steps):
        if step < 0:  # v is enough: is v - 1 too?
            if v == 0 or not enough(v - 1):
                return float(v)
            v -= 1
        else:  # v is not enough: v + 1?
            v += 1
            if enough(v):
                return float(v)
    return _percentiles_u8(gray, [50])[0]


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
    if img.ndim not in (2, 3) or img.shape[0] < 8 or img.shape[1] < 8:
        raise ValueError(f"image must be at least 8 x 8 pixels, got shape {img.shape}")
    height, width = img.shape[:2]
    s = _reduction(img.shape)
    # Candidates on every s-th pixel: a decimated view costs nothing, where averaging a
    # 20-megapixel photo down costs more than the rest of the pipeline.  A striped disc
    # keeps about half its sampled rows lit; the closing below joins them.
    small = img
    if s > 1:
        size = (-(-width // s), -(-height // s))  # ceil: the pixels img[::s, ::s]
        small = cv2.resize(img, size, interpolation=cv2.INTER_NEAREST)
    small = to_gray(small)
    background = _median_u8(small)
    peak = float(cv2.GaussianBlur(small, (3, 3), 0).max())
    if peak - background < 12:  # nothing stands out of the noise
        return Detection((), s, np.zeros_like(small), peak)
    thr = background + relative_threshold * (peak - background)
    # small > thr as 255 and 0: OpenCV compares with floor(thr), the same for whole levels
    binary = cv2.threshold(small, thr, 255, cv2.THRESH_BINARY)[1]
    k = max(3, int(np.ceil(2.0 * kernel_px / s)) | 1)
    binary = _close_lit(binary, k)
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    min_area = 0.5 * (min_diameter_px / s) ** 2
    rects = [cv2.boundingRect(c) for c in contours]
    areas = [cv2.contourArea(c) for c in contours]
    kept = [
        (r, c, a)
        for r, c, a in zip(rects, contours, areas, strict=True)
        if a + r[2] + r[3] >= min_area
    ]
    kept.sort(key=lambda rca: -rca[0][2] * rca[0][3])
    kept = kept[:max_blobs]
    comps = [r for r, _, _ in kept]
    several = [not_convex(c, a) for _, c, a in kept]  # may hold lights whose glows join
    found = []
    pad = kernel_px + 6 + 2 * s
    high = None  # the lights' brighter parts, where glows that join at ``thr`` stay apart
    if any(several):
        high = cv2.threshold(small, background + 0.6 * (peak - background), 255, 0)[1]
        high = _close_lit(high, k)

    def axis_of(inside: np.ndarray, box: tuple[int, int, int, int]) -> str:
        x, y, w, h = box
        return readout or _axis_contrast(small[y : y + h, x : x + w], inside)[0]

    # lights of 3 reduced pixels' radius at least: smaller ones the decimation cannot split
    lights = one_per_light(comps, several, binary, high, 3.0, axis_of)
    for (x, y, w, h), cell in lights:
        box = (
            max(0, x * s - pad),
            max(0, y * s - pad),
            min(width, (x + w) * s + pad),
            min(height, (y + h) * s + pad),
        )
        seeds = None if cell is None else cell[0] * np.array([s, s, s], dtype=np.float64)
        own = None if seeds is None else power_cell(box, seeds, cell[1])
        refined = _refine(img, box, readout, kernel_px, min_diameter_px, own)
        if refined is not None:
            found.append(refined)
    blobs = _with_covariances(_drop_duplicates(found))
    blobs.sort(key=lambda b: (round(float(b.pixel[1])), float(b.pixel[0])))
    return Detection(tuple(blobs), s, binary, thr)


def _spans(flags: np.ndarray, gap: int) -> list[tuple[int, int]]:
    """Ranges ``(start, end)`` (end exclusive) holding the nonzero entries of a 1-D array,
    split where more than ``gap`` - 1 zeros separate two of them."""
    idx = np.flatnonzero(flags)
    if idx.size == 0:
        return []
    cut = np.flatnonzero(np.diff(idx) > gap)
    starts = [int(idx[0]), *idx[cut + 1].tolist()]
    ends = [*idx[cut].tolist(), int(idx[-1])]
    return [(a, b + 1) for a, b in zip(starts, ends, strict=True)]


def _close_lit(binary: np.ndarray, k: int, max_boxes: int = 16) -> np.ndarray:
    """``cv2.morphologyEx(binary, MORPH_CLOSE, k x k ellipse)``, computed around the lit
    pixels only (the same result).

    The closing at a pixel depends on the pixels within ``2 r`` of it (``r = k // 2``): the
    lit pixels are grouped into boxes more than ``4 r + 1`` apart (bands of rows, then columns
    within each band), each box is closed with a margin of ``2 r + 1`` around it, and the rest
    stays 0, as the closing of the whole image leaves it.  A photo with many groups (noise)
    or large ones is closed whole.
    """
    kernel = _kernel(cv2.MORPH_ELLIPSE, (k, k))
    h, w = binary.shape
    r = k // 2
    margin, gap = 2 * r + 1, 4 * r + 1
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
        return cv2.morphologyEx(binary, cv2.MORPH_CLOSE, kernel)
    out = np.zeros_like(binary)
    for ya, yb, xa, xb in boxes:  # where two overlap, both give the whole closing's values
        out[ya:yb, xa:xb] = cv2.morphologyEx(binary[ya:yb, xa:xb], cv2.MORPH_CLOSE, kernel)
    return out


def _with_covariances(found: list[tuple[Blob, tuple | None]]) -> list[Blob]:
    """The blobs with their centres' covariances, all worked at once
    (:func:`~camvlp.geometry.disc.ellipse_centre_covariances`); each blob comes with its
    ellipse fit as :func:`_refine` gives it (None for a centroid: its covariance stays NaN)."""
    blobs = [b for b, _ in found]
    k = [i for i, (_, fit) in enumerate(found) if fit is not None]
    if not k:
        return blobs
    covs = ellipse_centre_covariances([found[i][1] for i in k])
    for i, cov in zip(k, covs, strict=True):
        blobs[i] = dataclasses.replace(blobs[i], centre_cov_px2=cov)
    return blobs


def _drop_duplicates(found: list[tuple[Blob, tuple | None]]) -> list[tuple[Blob, tuple | None]]:
    """Two candidates whose refined discs are the same fixture: keep the larger (each blob
    with its ellipse fit)."""
    keep: list[tuple[Blob, tuple | None]] = []
    for b, fit in sorted(found, key=lambda bf: -np.count_nonzero(bf[0].mask)):
        r = 0.5 * float(b.axes_px[1])
        if all(np.hypot(*(b.pixel - k.pixel)) > max(r, 0.5 * float(k.axes_px[1])) for k, _ in keep):
            keep.append((b, fit))
    return keep


def _refine(
    img: np.ndarray,
    box: tuple[int, int, int, int],
    readout: str | None,
    kernel_px: int,
    min_diameter_px: float,
    cell: np.ndarray | None = None,
) -> tuple[Blob, tuple | None] | None:
    """One candidate region at full resolution: its disc, readout axis and centre.

    The region is thresholded at a quarter of the way from its background (10th percentile)
    to its peak (99.5th): real lights are brighter in the middle than at the rim.  The dark
    stripes are bridged by :func:`_disc_mask`; the centre is an ellipse fitted to sub-pixel
    edge points of the lit sensor rows (:func:`_edge_points`), or the mask's centroid when
    fewer than 12 edge points are found.

    Parameters
    ----------
    img : ndarray, shape (H, W) or (H, W, 3)
        The whole photo.
    box : tuple of int
        The region, ``(x0, y0, x1, y1)`` in full-resolution pixels (x1, y1 exclusive).
    readout : {"rows", "columns", None}
        The readout axis, or None to find it from the region's stripes.
    kernel_px : int
        Smallest closing length, pixels.
    min_diameter_px : float
        Smallest disc kept, pixels.

    Returns
    -------
    blob : Blob
        The disc, its centre's covariance not yet worked out (NaN).
    fit : tuple or None
        ``(points, centre, axes, angle_deg, groups)`` of the ellipse fit, in the region's
        pixels, as :func:`~camvlp.geometry.disc.ellipse_centre_covariances` takes it; None
        when the centroid was used.
    None
        When the region holds no light large and bright enough.
    """
    x0, y0, x1, y1 = box
    gray8 = to_gray(img[y0:y1, x0:x1])
    if gray8.shape[0] < 3 or gray8.shape[1] < 3:
        return None
    background, peak = _percentiles_u8(gray8, [10, 99.5])
    if peak - background < 10:
        return None
    # a low threshold: real lights are often brighter in the middle than at the rim; whole
    # gray levels are above it when they are above its floor
    thr = math.floor(background + 0.25 * (peak - background))
    lit = cv2.threshold(gray8, thr, 1, cv2.THRESH_BINARY)[1]  # 0 and 1
    beyond = None
    if cell is not None:  # a light whose glow joins others': its own cell only
        beyond = lit & ~cell
        lit = lit & cell
    axis = readout
    if axis is None:
        axis, contrast = _axis_contrast(gray8, cv2.dilate(lit, np.ones((3, 3), np.uint8)))
    else:
        contrast = _axis_contrast(gray8, lit)[1]
    mask = _disc_mask(lit, axis, kernel_px)
    if mask is None:
        return None
    area = float(np.count_nonzero(mask))
    if area < 0.5 * min_diameter_px**2:
        return None
    height, width = img.shape[:2]
    # the disc reaches an edge of its region that is the image's: its bright part, for a
    # glow beyond the disc may reach the border where the disc does not (the rows the
    # border cuts give no edge points, the rest are whole)
    disc = mask & (gray8 > background + 0.6 * (peak - background))
    touches = bool(
        (x0 == 0 and disc[:, 0].any())
        or (y0 == 0 and disc[0].any())
        or (x1 == width and disc[:, -1].any())
        or (y1 == height and disc[-1].any())
    )
    points = _edge_points(gray8, mask, background, axis)
    if beyond is not None and points.size:  # not where the cell cuts it off from another
        near = cv2.dilate(beyond, np.ones((5, 5), np.uint8))
        xy = np.rint(points).astype(np.intp)
        h0, w0 = near.shape
        points = points[near[xy[:, 1].clip(0, h0 - 1), xy[:, 0].clip(0, w0 - 1)] == 0]
    fit = None
    if points.shape[0] >= 12:
        (cx, cy), (a, b), angle = cv2.fitEllipse(points.astype(np.float32))
        if not (0 <= cx < mask.shape[1] and 0 <= cy < mask.shape[0]):
            points = np.zeros((0, 2))
        else:
            fit = (points, (cx, cy), (a, b), angle, _row_groups(points, axis))
    if points.shape[0] < 12:
        m = cv2.moments(mask.astype(np.uint8), binaryImage=True)
        cx, cy = m["m10"] / m["m00"], m["m01"] / m["m00"]
        d = 2.0 * np.sqrt(area / np.pi)
        a = b = d
        angle = 0.0
    axes = np.array(sorted((float(a), float(b)), reverse=True))
    blob = Blob(
        pixel=np.array([x0 + cx, y0 + cy]),
        box=box,
        mask=mask,
        axes_px=axes,
        angle_deg=float(angle),
        touches_border=touches,
        axis=axis,
        stripe_contrast=float(contrast),
        edge_points=int(points.shape[0]),
        gray=gray8,
        cell=cell,
    )
    return blob, fit


def _row_groups(points: np.ndarray, axis: str) -> np.ndarray:
    """The groups of edge points whose errors an ellipse's centre covariance takes as shared
    (:func:`~camvlp.geometry.disc.ellipse_centre_covariance`): runs of about sqrt(n)
    consecutive sensor rows out of the n they span (batch means).  A row's two ends share
    its exposure, and the stripes make neighbouring rows' errors depend on each other, while
    runs far apart do not."""
    rows = points[:, 1] if axis == "rows" else points[:, 0]
    span = float(np.ptp(rows)) + 1.0
    return np.floor((rows - rows.min()) / max(1.0, np.sqrt(span))).astype(np.int64)


@functools.lru_cache(maxsize=64)
def _kernel(shape: int, ksize: tuple[int, int]) -> np.ndarray:
    """``cv2.getStructuringElement(shape, ksize)``, made once per shape and size."""
    k = cv2.getStructuringElement(shape, ksize)
    k.flags.writeable = False
    return k


def _disc_mask(lit: np.ndarray, axis: str, kernel_px: int) -> np.ndarray | None:
    """The disc under a striped light: lit pixels with the dark stripes bridged.

    A closing along the readout axis as long as the widest dark gap across the middle third
    of the region (at least ``kernel_px``), a small round closing, and the largest outline
    with its holes filled.  Returns a bool mask (h, w), or None when nothing is lit.
    """
    lit_u8 = lit.view(np.uint8) if lit.dtype == bool else lit
    # Bridge the dark stripes: a closing along the readout axis, as long as the widest gap.
    rows = axis == "rows"
    n = lit_u8.shape[1 if rows else 0]  # pixels across the readout: its middle third
    a, b = n // 3, max(n // 3 + 1, 2 * n // 3)
    centre = lit_u8[:, a:b] if rows else lit_u8[a:b]
    gap = 0
    if centre.size:
        # lines more than half lit (the lit pixels counted by OpenCV: any nonzero level
        # counts as 1 through the threshold); the widest dark run between two of them
        ones = cv2.threshold(centre, 0, 1, cv2.THRESH_BINARY)[1]
        counts = cv2.reduce(ones, 1 if rows else 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
        lit_lines = np.flatnonzero(counts * 2 > min(n, b) - a)
        if lit_lines.size >= 2:
            gap = int((lit_lines[1:] - lit_lines[:-1]).max()) - 1
    length = max(kernel_px, gap + 3) | 1
    ksize = (1, length) if axis == "rows" else (length, 1)  # (width, height): across stripes
    # Close a copy padded by repeating its edge: OpenCV's own border keeps whatever the
    # dilation brought to the edge, which would join a disc near the border to it.
    m = length // 2 + 3
    closed = cv2.copyMakeBorder(lit_u8, m, m, m, m, cv2.BORDER_REPLICATE)
    closed = cv2.morphologyEx(closed, cv2.MORPH_CLOSE, _kernel(cv2.MORPH_RECT, ksize))
    closed = cv2.morphologyEx(closed, cv2.MORPH_CLOSE, _kernel(cv2.MORPH_ELLIPSE, (5, 5)))
    closed = np.ascontiguousarray(closed[m:-m, m:-m])
    # the largest outline, holes filled
    contours, _ = cv2.findContours(closed, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return None
    filled = np.zeros_like(closed)
    cv2.drawContours(filled, [max(contours, key=cv2.contourArea)], -1, 1, thickness=cv2.FILLED)
    return filled.view(bool)


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
    support = _disc_mask(lit, axis, kernel_px)
    if support is None or not (support & m).any():
        return m
    return support | m


#: Dilation of a disc's mask that masks other lights out of its rows' crossings, per axis.
_EDGE_KERNELS = {"rows": np.ones((3, 7), np.uint8), "columns": np.ones((7, 3), np.uint8)}


def _edge_points(gray: np.ndarray, mask: np.ndarray, background: float, axis: str) -> np.ndarray:
    """Sub-pixel disc edge points along the lit sensor rows, shape (M, 2) as ``(x, y)``.

    Each lit sensor row crosses the disc once; its two ends are found where the row's
    intensity crosses half-way between the background and the row's own level inside the
    disc, so partly lit rows (stripe transitions) give the same chord as fully lit ones.
    ``gray`` is the region's uint8 gray levels (h, w), ``mask`` the disc (bool, h x w).
    """
    m8 = np.ascontiguousarray(mask).view(np.uint8)
    dim = 1 if axis == "rows" else 0  # cv2.reduce to one value per sensor row
    counts = cv2.reduce(m8, dim, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
    # whole levels: the float32 sums are exact (below 2**24)
    sums = cv2.reduce(cv2.multiply(gray, m8), dim, cv2.REDUCE_SUM, dtype=cv2.CV_32F).ravel()
    level = sums / np.maximum(counts, 1)  # 0 in rows outside the disc, the levels >= 0
    top = level.max()
    rows = np.flatnonzero((counts >= 4) & (level > background + 0.35 * (top - background)))
    if rows.size == 0:
        return np.zeros((0, 2))
    dilated = cv2.dilate(m8, _EDGE_KERNELS[axis]).view(bool)
    if axis == "rows":
        g, near = gray[rows], dilated[rows]
    else:
        g, near = gray[:, rows].T, dilated[:, rows].T
    half = background + 0.5 * (level[rows] - background)
    # above half-way (other lights masked out: the background is below half-way)
    above = near & (g > half[:, None])
    w = g.shape[1]
    left = above.argmax(axis=1)  # 0 also when nothing is above: such a row is left out
    right = w - 1 - above[:, ::-1].argmax(axis=1)
    ok = (left > 0) & (right < w - 1) & (right - left >= 3)
    rows, left, right, half = rows[ok], left[ok], right[ok], half[ok]
    j = np.flatnonzero(ok)
    # the rows' levels either side of both crossings, other lights masked out
    cols = np.stack([left - 1, left, right, right + 1])
    a0, a1, b0, b1 = np.where(near[j, cols], g[j, cols], background).astype(np.float32)
    u = 0 if axis == "rows" else 1  # the column of pts that holds x
    pts = np.empty((2 * rows.size, 2))
    pts[: rows.size, u] = left - 1 + (half - a0) / np.maximum(a1 - a0, 1e-6)
    pts[rows.size :, u] = right + (b0 - half) / np.maximum(b0 - b1, 1e-6)
    pts[:, 1 - u] = np.concatenate([rows, rows])
    return pts
