"""Stage 2: read a fixture's ID from its stripes (thesis section 5.3 and 5.4, made robust).

Per fixture:

1. reduce each sensor row inside the disc to one value (the row profile);
2. binarise it with a threshold of the fixture's own (Otsu's two-class split of the profile,
   the principled form of the thesis' "two peaks of the histogram");
3. find the stripe edges to a fraction of a row, and the run lengths between them;
4. measure the chip length from edges of the same polarity (rising to rising, falling to
   falling: in Manchester they are 2, 3 or 4 chips apart whatever the bleeding), then the
   bleeding (how much wider bright runs are than dark ones), and decide one chip or two per
   run with separate thresholds for bright and dark runs;
5. decode the chips cyclically against every ID's frame (:meth:`FrameFormat.decode`), with
   the runs cut by the disc's edge entered only for the chips they surely hold.

The result says which ID, or why none, with the Hamming distance, the margin, and the
measured chip length and bleeding.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.model.linecode import FrameFormat

__all__ = [
    "Runs",
    "StripeDecode",
    "decode_profile",
    "find_runs",
    "row_profile",
    "shape_profile",
    "stripe_levels",
    "stripe_threshold",
]


#: The erosion that trims a disc's anti-aliased rim before its rows are averaged.
_RIM_KERNEL = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))


def _trimmed(mask: np.ndarray) -> np.ndarray:
    """A disc's mask (uint8 0/1) with its anti-aliased rim trimmed by a small erosion, unless
    that would leave less than 30 % of it."""
    m = mask.view(np.uint8) if mask.dtype == bool else mask.astype(np.uint8)
    eroded = cv2.erode(m, _RIM_KERNEL)
    return eroded if np.count_nonzero(eroded) >= 0.3 * np.count_nonzero(m) else m


def row_profile(gray: np.ndarray, mask: np.ndarray, axis: str = "rows") -> tuple[np.ndarray, int]:
    """Mean intensity of each sensor row inside a disc.

    Parameters
    ----------
    gray : ndarray, shape (h, w)
        The region of interest (any real dtype).
    mask : ndarray of bool, shape (h, w)
        The disc; its anti-aliased rim is trimmed by a small erosion first.
    axis : {"rows", "columns"}
        Readout axis: ``"rows"`` averages each image row, ``"columns"`` each column.

    Returns
    -------
    profile : ndarray of float, shape (n,)
        One value per sensor row that crosses the disc, in readout order.
    first : int
        Index, in the region of interest, of the first row of the profile.
    """
    return _mean_profile(gray, _trimmed(mask), axis)


def _mean_profile(gray: np.ndarray, m: np.ndarray, axis: str) -> tuple[np.ndarray, int]:
    """:func:`row_profile` of a mask already trimmed (uint8 0/1)."""
    dim = 1 if axis != "columns" else 0  # cv2.reduce to one value per sensor row
    # pixels of the disc in each sensor row (an image row, or column)
    counts = cv2.reduce(m, dim, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
    rows = np.flatnonzero(counts >= 2)
    if rows.size == 0:
        return np.zeros(0), 0
    first, last = int(rows[0]), int(rows[-1]) + 1
    c = counts[first:last].astype(np.float64)
    if gray.dtype == np.uint8:  # whole levels: the sums exact, as NumPy's in float64
        s = cv2.reduce(cv2.multiply(gray, m), dim, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
        s = s[first:last].astype(np.float64)
    else:
        g = gray.astype(np.float32)
        if axis == "columns":
            g, m = g.T, m.T
        s = (g[first:last] * m[first:last]).sum(axis=1, dtype=np.float64)
    prof = np.where(c > 0, s / np.maximum(c, 1), np.nan)
    if np.isnan(prof).any():  # rows the mask skips: interpolate
        idx = np.arange(prof.size)
        good = ~np.isnan(prof)
        prof = np.interp(idx, idx[good], prof[good])
    return prof, first


#: Pixels per ring of :func:`shape_profile`'s envelope (at least 16 rings, at most 256); the
#: quantile of a ring's pixels taken as the light's level there when its LED is on; the pixels
#: sampled to tell a flat light (every k-th row and column), and to measure a shaped one.
_RING_PIXELS = 150
_ENVELOPE_QUANTILE = 0.9
_FLAT_SAMPLE, _SHAPE_SAMPLE = 1000, 20000
#: A light whose rings' levels all lie within this fraction of the brightest is flat.
_FLAT = 0.05


def _radial_envelope(values: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A light's on-level against radius: the upper quantile of the pixels at about it.

    The pixels are cut into rings of equal area (so that each holds pixels of many sensor
    rows, the middle one too, and the rings are thin where the rim's step is), about
    ``_RING_PIXELS`` pixels each.  ``values`` (n,) uint8 and ``rho`` (n,) radii (any unit,
    >= 0); returns the rings' mean radii and their levels, float64 (k,) each.
    """
    bins = min(max(values.size // _RING_PIXELS, 16), 256)
    r2 = rho * rho
    k = (r2 * (bins / (float(r2.max()) or 1.0))).astype(np.intp)
    np.minimum(k, bins - 1, out=k)
    key = k * 256 + values  # by ring, then by level
    key.sort()
    counts = np.bincount(k, minlength=bins)
    full = counts > 0
    picks = np.cumsum(counts) - counts + ((counts - 1) * _ENVELOPE_QUANTILE).astype(np.intp)
    level = (key[picks[full]] & 255).astype(np.float64)
    middle = np.bincount(k, weights=rho, minlength=bins)[full] / counts[full]
    return middle, level


def _radii(m: np.ndarray, step: int, centre, axes, angle_deg: float):
    """The pixels of mask ``m`` on every ``step``-th row and column: rows, columns, and
    radii in the outline ellipse's units."""
    ys, xs = np.nonzero(m[::step, ::step])
    ys, xs = ys * step, xs * step
    t = math.radians(angle_deg)
    dx, dy = xs - float(centre[0]), ys - float(centre[1])
    a, b = 0.5 * max(float(axes[0]), 1.0), 0.5 * max(float(axes[1]), 1.0)
    u, v = dx * math.cos(t) + dy * math.sin(t), dy * math.cos(t) - dx * math.sin(t)
    return ys, xs, np.sqrt((u / a) ** 2 + (v / b) ** 2)


def shape_profile(
    gray: np.ndarray,
    mask: np.ndarray,
    axis: str,
    centre: np.ndarray,
    axes: np.ndarray,
    angle_deg: float,
) -> tuple[np.ndarray, int]:
    """The row profile of a light whose level varies across it (a hot core, a glow): each
    sensor row's sum over the disc, over the sum of the light's on-level at the same pixels.

    A light's image is its shape (the same whatever its LED does) times the LED's on-fraction
    during each row's exposure.  The mean of a row (:func:`row_profile`) mixes the two: rows
    that cross only the rim of a glow come out dim whatever the LED did.  Here each pixel is
    set against the light's level at its distance from the centre when the LED is on (the
    upper tenth of the pixels at about that distance, in rings of the outline ellipse), so
    the profile follows the on-fraction alone (through the sensor's clipping).  For a plain
    disc the level is the same everywhere and the profile is the row mean.

    Parameters
    ----------
    gray : ndarray of uint8, shape (h, w)
        The region of interest.
    mask : ndarray of bool, shape (h, w)
        The light's area; its rim is trimmed as in :func:`row_profile`.
    axis : {"rows", "columns"}
        Readout axis.
    centre : ndarray, shape (2,)
        The light's centre ``[x, y]`` in the region's pixels.
    axes : ndarray, shape (2,)
        Full lengths of its outline ellipse's axes, pixels.
    angle_deg : float
        Orientation of the ellipse (OpenCV's convention), degrees.

    Returns
    -------
    profile : ndarray of float, shape (n,)
        One value per sensor row that crosses the disc, in the image's order, in gray levels
        (the on-fraction times the brightest ring's level).
    first : int
        Index, in the region of interest, of the first row of the profile.
    """
    m = _trimmed(mask)
    n = cv2.countNonZero(m)
    if n == 0:
        return np.zeros(0), 0
    ys, xs, rho = _radii(m, math.ceil(math.sqrt(n / _FLAT_SAMPLE)), centre, axes, angle_deg)
    middle, level = _radial_envelope(gray[ys, xs], rho)
    if level.min() >= (1.0 - _FLAT) * level.max():  # a flat light: its row mean
        return _mean_profile(gray, m, axis)
    if n > _FLAT_SAMPLE:
        ys, xs, rho = _radii(m, math.ceil(math.sqrt(n / _SHAPE_SAMPLE)), centre, axes, angle_deg)
        middle, level = _radial_envelope(gray[ys, xs], rho)
    ys, xs, rho = _radii(m, 1, centre, axes, angle_deg)
    values = gray[ys, xs]
    level = np.maximum(np.interp(rho, middle, level), 1.0)
    line = ys if axis != "columns" else xs
    counts = np.bincount(line)
    rows = np.flatnonzero(counts >= 2)
    if rows.size == 0:
        return np.zeros(0), 0
    first, last = int(rows[0]), int(rows[-1]) + 1
    num = np.bincount(line, weights=values, minlength=last)[first:last]
    den = np.bincount(line, weights=level, minlength=last)[first:last]
    prof = num / np.where(den > 0, den, np.nan) * float(level.max())
    if np.isnan(prof).any():  # rows the mask skips: interpolate
        idx = np.arange(prof.size)
        good = ~np.isnan(prof)
        prof = np.interp(idx, idx[good], prof[good])
    return prof, first


def _otsu(values: np.ndarray) -> float:
    """Otsu's threshold of a 1-D sample (between its two classes)."""
    v = np.sort(np.asarray(values, dtype=float))
    n = v.size
    csum = np.cumsum(v)
    k = np.arange(1, n)
    w0 = k / n
    m0 = csum[:-1] / k
    m1 = (csum[-1] - csum[:-1]) / (n - k)
    between = w0 * (1 - w0) * (m0 - m1) ** 2
    i = int(np.argmax(between))
    return 0.5 * (v[i] + v[i + 1])


def stripe_levels(profile: np.ndarray) -> tuple[float, float]:
    """Dark and bright levels of a row profile: its 2nd and 98th percentiles."""
    v = np.sort(np.asarray(profile, dtype=float).reshape(-1))
    last = v.size - 1
    out = []
    for q in (0.02, 0.98):  # NumPy's default (linear) percentiles, in Python floats
        x = q * last
        i = min(math.floor(x), last)
        a, b = float(v[i]), float(v[min(i + 1, last)])
        out.append(a + (x - i) * (b - a))
    return out[0], out[1]


def stripe_threshold(profile: np.ndarray, level: float = 0.6) -> float:
    """Binarisation threshold ``level`` of the way from the dark to the bright level.

    Above one half by default, so that dark stripes narrowed by a saturated neighbour's
    bleeding still cross it.
    """
    lo, hi = stripe_levels(profile)
    return lo + level * (hi - lo)


@dataclass(frozen=True)
class Runs:
    """Bright and dark runs of a binarised row profile.

    Attributes
    ----------
    edges : ndarray, shape (E,)
        Sub-row positions of the threshold crossings.
    rising : ndarray of bool, shape (E,)
        True where the profile goes from dark to bright.
    lengths : ndarray, shape (E + 1,)
        Run lengths in rows; the first and last are cut by the disc's edge.
    bright : ndarray of bool, shape (E + 1,)
        Which runs are bright.
    threshold : float
        The binarisation threshold, profile units.
    """

    edges: np.ndarray
    rising: np.ndarray
    lengths: np.ndarray
    bright: np.ndarray
    threshold: float


def find_runs(profile: np.ndarray, threshold: float | None = None) -> Runs:
    """Binarise a row profile and measure its runs to a fraction of a row.

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Row profile (see :func:`row_profile`).
    threshold : float, optional
        Binarisation threshold; Otsu's by default.

    Returns
    -------
    Runs
    """
    p = np.asarray(profile, dtype=float)
    thr = _otsu(p) if threshold is None else float(threshold)
    above = p > thr
    i = np.flatnonzero(above[1:] != above[:-1])  # crossing between i and i+1
    a, b = p[i], p[i + 1]
    edges = i + (thr - a) / np.where(b != a, b - a, 1.0)
    bounds = np.concatenate([[-0.5], edges, [p.size - 0.5]])
    lengths = np.diff(bounds)
    bright = np.empty(edges.size + 1, bool)
    bright[0] = above[0]
    bright[1:] = above[i + 1]
    return Runs(edges, above[i + 1], lengths, bright, thr)


@dataclass(frozen=True)
class StripeDecode:
    """What the stripes of one fixture say.

    Attributes
    ----------
    id : int or None
        Decoded ID, or None.
    reason : str
        Why there is no ID ("" when decoded).
    hamming : int
        Chips that disagree with the decoded (or nearest) ID; -1 when no chips were read.
    margin : float
        Confidence in [0, 1]: how far the worst run length is from a decision boundary
        (1 = every run exactly one or two chips long, 0 = a run on the boundary), times 0 when
        another ID fits as well.
    rows_per_chip : float
        Measured chip length in sensor rows (NaN when it could not be measured).
    bleed_rows : float
        How much longer bright runs are than their chip count says (and dark runs shorter).
    chips : str
        The chips read, ``"?"`` where a run's count was uncertain.
    frames : float
        Frames of the code covered by the chips read.
    """

    id: int | None
    reason: str
    hamming: int
    margin: float
    rows_per_chip: float
    bleed_rows: float
    chips: str
    frames: float

    def __bool__(self) -> bool:
        return self.id is not None


def _chip_length(runs: Runs, max_rows_per_chip: float) -> float:
    """Chip length in rows from same-polarity edge spacings (2, 3 or 4 chips each)."""
    # the crossings alternate, so same-polarity spacings are those two crossings apart:
    # the rising edges' first, then the falling edges'
    e = runs.edges
    two = e[2:] - e[:-2]
    first = 0 if runs.rising.size and runs.rising[0] else 1  # ``two``'s first rising spacing
    d = np.concatenate([two[first::2], two[1 - first :: 2]])
    d = d[d > 0]
    if d.size < 2:
        return float("nan")
    shortest = d.min()
    lo, hi = max(0.8, shortest / 4.6), min(max_rows_per_chip, shortest / 1.6)
    if hi <= lo:
        return float("nan")
    grid = np.arange(lo, hi, 0.01)
    x = d[None, :] / grid[:, None]
    n = np.round(x)
    np.minimum(np.maximum(n, 2, out=n), 4, out=n)  # np.clip, without its overhead
    x -= n
    x *= grid[:, None]
    cost = np.square(x, out=x).sum(axis=1)  # squared residual in rows
    t = float(grid[int(np.argmin(cost))])
    n = np.minimum(np.maximum(np.round(d / t), 2), 4)
    return float((d * n).sum() / (n * n).sum())  # least squares refinement


@functools.lru_cache(maxsize=4)
def _counting(num: int) -> np.ndarray:
    a = np.arange(num, dtype=float)
    a.flags.writeable = False
    return a


def _linspace(start: float, stop: float, num: int) -> np.ndarray:
    """``np.linspace(start, stop, num)`` for Python floats, the same arithmetic without its
    set-up (steps of ``(stop - start) / (num - 1)`` from ``start``, ``stop`` itself last)."""
    y = _counting(num) * ((stop - start) / (num - 1))
    y += start
    y[-1] = stop
    return y


def decode_profile(
    profile: np.ndarray,
    frame: FrameFormat,
    *,
    rows_per_chip: float | None = None,
    max_rows_per_chip: float = 64.0,
    threshold_level: float = 0.6,
) -> StripeDecode:
    """Decode the ID carried by a fixture's row profile.

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Mean intensity per sensor row across the disc, in readout order.
    frame : FrameFormat
        The frame format of the map.
    rows_per_chip : float, optional
        Known chip length in rows (chip duration / row time); measured when None.
    max_rows_per_chip : float
        Longest chip length considered when measuring it.
    threshold_level : float
        Binarisation threshold (see :func:`stripe_threshold`).

    Returns
    -------
    StripeDecode
        Falsy, with a reason, when the stripes do not give one ID with confidence.
    """
    p = np.asarray(profile, dtype=float)
    nan = float("nan")

    def fail(reason: str, **kw) -> StripeDecode:
        fields = dict(
            hamming=-1, margin=0.0, rows_per_chip=nan, bleed_rows=nan, chips="", frames=0.0
        )
        fields.update(kw)
        return StripeDecode(None, reason, **fields)

    if p.size < 8:
        return fail(f"too small to decode ({p.size} rows)")
    lo, hi = stripe_levels(p)
    if hi - lo < 8:
        return fail("no stripes (a steady light, or too little contrast)")
    runs = find_runs(p, lo + threshold_level * (hi - lo))  # stripe_threshold's
    if runs.edges.size < 4:
        return fail("no stripes (a steady light, or too few stripes)")
    t = float(rows_per_chip) if rows_per_chip else _chip_length(runs, max_rows_per_chip)
    if not np.isfinite(t) or t <= 0:
        return fail("stripes too irregular to measure the chip length")
    lengths, bright = runs.lengths, runs.bright  # four edges or more: three interior runs
    # bleeding: bright runs are b rows longer, dark ones b rows shorter, than n chips; the
    # b that makes every interior run closest to one or two chips (both kinds occur in
    # every frame, which pins b down)
    li, bi = lengths[1:-1], bright[1:-1]
    grid = _linspace(-0.95 * t, 0.95 * t, 191)
    xs = np.where(bi[None, :], li[None, :] - grid[:, None], li[None, :] + grid[:, None]) / t
    n = np.round(xs)
    xs -= np.minimum(np.maximum(n, 1, out=n), 2, out=n)
    cost = np.square(xs, out=xs).sum(axis=1)
    b = float(grid[int(np.argmin(cost))])
    x = np.where(bright, lengths - b, lengths + b) / t
    counts = np.round(x).astype(int)
    # runs cut by the disc's edge: count only the chips surely inside
    for k in (0, lengths.size - 1):
        counts[k] = min(max(math.floor(float(x[k]) + 0.25), 0), 2)
    sure = np.ones(counts.size, bool)
    inner = counts[1:-1]
    sure[1:-1] = (inner >= 1) & (inner <= 2)
    np.minimum(np.maximum(inner, 1, out=inner), 2, out=inner)  # in counts itself
    chip_vals = np.repeat(bright.astype(np.uint8), counts)
    known = np.repeat(sure, counts)
    frames = chip_vals.size / frame.n_chips
    chip_str = np.where(known, chip_vals + ord("0"), ord("?")).astype(np.uint8).tobytes().decode()
    res = frame.decode(chip_vals, known=known)
    xi = x[1:-1]
    worst = float(np.abs(xi - np.round(xi)).max()) if xi.size else 0.5
    margin = min(max(1.0 - 2.0 * worst, 0.0), 1.0)
    common = dict(rows_per_chip=t, bleed_rows=b, chips=chip_str, frames=frames)
    if not res:
        return fail(res.reason, hamming=res.distance, **common)
    # every whole copy of the frame must agree: none may decode to another ID
    n = frame.n_chips
    for start in range(0, chip_vals.size - n + 1, n):
        sub = frame.decode(chip_vals[start : start + n], known=known[start : start + n])
        if sub.id is not None and sub.id != res.id:
            return fail(
                f"copies of the frame disagree ({res.id} and {sub.id})",
                hamming=res.distance,
                **common,
            )
    return StripeDecode(res.id, "", res.distance, margin, **common)
