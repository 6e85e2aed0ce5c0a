"""Stage 2: each fixture's row profile, one value per sensor row across its disc.

The plain profile is the mean of each row inside the disc (its anti-aliased rim trimmed); a
lamp whose level varies across it (a hot core, a glow) is measured against its own radial
shape instead (:func:`shape_profile`).  A photo's lights are worked together where NumPy
can (:func:`shape_profiles`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from camvlp.imaging.levels import CLIP_LEVEL as _CLIP
from camvlp.imaging.levels import FULL_SCALE as _FULL
from camvlp.imaging.ragged import pieces, starts

__all__ = ["row_profile", "shape_profile", "shape_profiles"]


#: The erosion that trims a disc's anti-aliased rim before its rows are averaged.
_RIM_KERNEL = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))


def _trimmed(mask: np.ndarray) -> np.ndarray:
    """A disc's mask (uint8 0/1) with its anti-aliased rim trimmed by a small erosion, unless
    that would leave less than 30 % of it."""
    return _trim(mask)[0]


def _trim(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """:func:`_trimmed`, and the pixels it keeps."""
    m = mask.view(np.uint8) if mask.dtype == bool else mask.astype(np.uint8)
    eroded = cv2.erode(m, _RIM_KERNEL)
    n, whole = cv2.countNonZero(eroded), cv2.countNonZero(m)
    return (eroded, n) if n >= 0.3 * whole else (m, whole)


def _filled(prof: np.ndarray) -> np.ndarray:
    """A profile (n,) with the rows its mask skips (NaN) interpolated from their neighbours."""
    if np.isnan(prof).any():
        idx = np.arange(prof.size)
        good = ~np.isnan(prof)
        prof = np.interp(idx, idx[good], prof[good])
    return prof


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
    return _mean_profile(gray, _trimmed(mask), axis)[:2]


def _mean_profile(gray: np.ndarray, m: np.ndarray, axis: str) -> tuple[np.ndarray, int, np.ndarray]:
    """:func:`row_profile` of a mask already trimmed (uint8 0/1), and each line's weight (its
    pixels: a mean of ``c`` pixels of equal noise has ``1 / c`` of their variance)."""
    dim = 1 if axis != "columns" else 0  # cv2.reduce to one value per sensor row
    # pixels of the disc in each sensor row (an image row, or column)
    counts = cv2.reduce(m, dim, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
    rows = (counts >= 2).nonzero()[0]
    if rows.size == 0:
        return np.zeros(0), 0, np.zeros(0)
    first, last = int(rows[0]), int(rows[-1]) + 1
    c = counts[first:last].astype(np.float64)
    if gray.dtype == np.uint8:  # whole levels: the sums exact, as NumPy's in float64
        lines = (slice(first, last), slice(None)) if dim == 1 else (slice(None), slice(first, last))
        s = cv2.reduce(cv2.multiply(gray[lines], m[lines]), dim, cv2.REDUCE_SUM, dtype=cv2.CV_32S)
        s = s.ravel()  # int32: exact in float64, where the division below takes it
    else:
        g = gray.astype(np.float32)
        if axis == "columns":
            g, m = g.T, m.T
        s = (g[first:last] * m[first:last]).sum(axis=1, dtype=np.float64)
    # a line between the first and the last without pixels: NaN, filled (float levels may be
    # NaN themselves); when ``rows`` holds every line, each has two pixels or more
    if gray.dtype != np.uint8 or (rows.size != last - first and not np.logical_and.reduce(c)):
        return _filled(np.where(c == 0, np.nan, s / np.maximum(c, 1))), first, c
    return np.divide(s, c), first, c


#: Pixels per ring of :func:`shape_profile`'s envelope (at least 16 rings, at most 256); the
#: quantile of a ring's pixels taken as the light's level there when its LED is on; the pixels
#: sampled to tell a flat light (every k-th row and column), and to measure a shaped one.
_RING_PIXELS = 150
_ENVELOPE_QUANTILE = 0.9
_FLAT_SAMPLE, _SHAPE_SAMPLE = 1000, 20000
#: A light whose rings' levels all lie within this fraction of the brightest is flat.
_FLAT = 0.05
#: A light clips over its face (not only at a hot core) when its clipped pixels (those whose
#: on-level is at the clipping level) are more than this fraction of the pixels of the lines
#: they span: most of them.
_FACE = 0.5
#: ... and when, in the lines where they do not reach full scale, they read at least this many
#: times the on-fraction that the light's other pixels of those lines read: their on-level is
#: twice full scale or more, so that a dark chip leaves them a dip under half as deep.
_OWN_RESPONSE = 2.0

#: A shaped profile's first and last lines are dropped while their noise is more than this
#: many times the median line's: a line's value is its pixels' sum divided by their on-levels'
#: sum, so its noise grows as sqrt(pixels) / (on-levels' sum), and the lines that cross only a
#: faint rim or glow (a few pixels, levels near zero) come out many times brighter or darker
#: than the LED ever is, which the decoder's fit, weighing every line alike, cannot absorb.
_NOISIEST_END = 8.0


def _radial_envelopes(values: list, rho: list) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each light's on-level against radius: the upper quantile of its pixels at about it.

    A light's pixels are cut into rings of equal area (so that each holds pixels of many
    sensor rows, the middle one too, and the rings are thin where the rim's step is), about
    ``_RING_PIXELS`` pixels each.  Per light ``values`` (n,) uint8 and ``rho`` (n,) radii (any
    unit, >= 0; n >= 1); returns per light its rings' mean radii and their levels, float64
    (k,) each.  All the lights' rings are worked at once (each light's after the previous
    lights'): the pixels sorted by ring, then by level (one sort of ``ring * 256 + level``,
    a radix sort of 16-bit keys for up to 256 rings), each ring's quantile is the level at
    its rank among its own.
    """
    sizes = np.array([v.size for v in values], dtype=np.intp)
    bins = np.minimum(np.maximum(sizes // _RING_PIXELS, 16), 256)
    r = np.concatenate(rho)
    r2 = r * r
    top = np.maximum.reduceat(r2, starts(sizes))
    first = starts(bins)  # each light's rings after the previous lights'
    # per light: rings per unit of r2, its last ring, its first; repeated once per pixel
    scale, last, offset = np.array([bins / np.where(top != 0.0, top, 1.0), bins - 1, first]).repeat(
        sizes, axis=1
    )
    k = (r2 * scale).astype(np.intp)
    np.minimum(k, last.astype(np.intp), out=k)
    k += offset.astype(np.intp)
    n_rings = int(bins.sum())
    key = k * 256 + np.concatenate(values)  # by ring, then by level
    key = key.astype(np.uint16) if n_rings <= 256 else key  # its own array: sorted in place
    key.sort(kind="stable")
    counts = np.bincount(k, minlength=n_rings)
    ring = counts.nonzero()[0]
    c = counts[ring]
    rank = ((c - 1) * _ENVELOPE_QUANTILE).astype(np.intp)  # in the ring's order
    level = (key[starts(counts)[ring] + rank] & 255).astype(np.float64)
    middle = np.bincount(k, weights=r, minlength=n_rings)[ring] / c
    cut = ring.searchsorted(first[1:])  # each light's first ring among those with pixels
    return [(middle[a:b], level[a:b]) for a, b in pieces(cut, ring.size)]


def _nonzero(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.nonzero`` of a uint8 mask (h, w), in the same (row-major) order, by OpenCV."""
    xy = cv2.findNonZero(np.ascontiguousarray(mask))
    if xy is None:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    xy = xy.reshape(-1, 2)
    return xy[:, 1], xy[:, 0]


def _radii(masks: list, steps: list[int], centres, axes, angles) -> list[tuple]:
    """Each mask's pixels on every ``step``-th row and column: rows, columns, and radii in
    its outline ellipse's units (centre, full axes and angle in degrees as OpenCV gives
    them); worked for all the masks at once."""
    found = [_nonzero(m[::st, ::st]) for m, st in zip(masks, steps, strict=True)]
    sizes = np.array([ys.size for ys, _ in found], dtype=np.intp)
    step = np.array(steps, dtype=np.intp).repeat(sizes)
    ys = np.concatenate([ys for ys, _ in found]) * step
    xs = np.concatenate([xs for _, xs in found]) * step
    # per mask: centre, cos and sin of its angle, semi-axes; repeated once per pixel
    geo = [
        (
            float(c[0]),
            float(c[1]),
            math.cos(math.radians(t)),
            math.sin(math.radians(t)),
            0.5 * max(float(ax[0]), 1.0),
            0.5 * max(float(ax[1]), 1.0),
        )
        for t, c, ax in zip(angles, centres, axes, strict=True)
    ]
    cx, cy, cos, sin, a, b = np.array(geo).reshape(-1, 6).T.repeat(sizes, axis=1)
    dx, dy = xs - cx, ys - cy
    u, v = dx * cos, dy * cos  # u = dx cos + dy sin, v = dy cos - dx sin
    u += dy * sin
    v -= dx * sin
    u /= a
    v /= b
    rho = np.sqrt(np.square(u, out=u) + np.square(v, out=v))
    cut = sizes.cumsum()[:-1]
    return [(ys[a:b], xs[a:b], rho[a:b]) for a, b in pieces(cut, ys.size)]


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

    A light whose face clips (a bright disc in a glow) is measured on its clipped pixels
    alone (see :func:`_clipped_face`): a pixel's response to the on-fraction depends on its
    level, and the model decodes a profile through one response.

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
    return shape_profiles([gray], [mask], axis, [centre], [axes], [angle_deg])[0][:2]


def shape_profiles(
    grays: list, masks: list, axis: str, centres: list, axes: list, angles: list
) -> list[tuple[np.ndarray, int, np.ndarray]]:
    """:func:`shape_profile` of several lights (one entry each in every list): whether each
    light is flat is told for all of them at once.  Each entry also gives its lines'
    weights (shape (n,)): the inverse of their variance under pixels of equal noise, up to
    a constant, 0 for a line without pixels."""
    trims = [_trim(m) for m in masks]
    trimmed, counts = [m for m, _ in trims], [n for _, n in trims]
    out: list[tuple[np.ndarray, int, np.ndarray]] = [(np.zeros(0), 0, np.zeros(0))] * len(masks)
    live = [k for k, n in enumerate(counts) if n]
    if not live:
        return out
    steps = [math.ceil(math.sqrt(counts[k] / _FLAT_SAMPLE)) for k in live]
    where = [centres[k] for k in live], [axes[k] for k in live], [angles[k] for k in live]
    sampled = _radii([trimmed[k] for k in live], steps, *where)
    envelopes = _radial_envelopes(
        [grays[k][ys, xs] for k, (ys, xs, _) in zip(live, sampled, strict=True)],
        [rho for _, _, rho in sampled],
    )
    for k, (middle, level) in zip(live, envelopes, strict=True):
        lowest, highest = level.min(), level.max()
        if lowest >= (1.0 - _FLAT) * highest:  # a flat light: its row mean
            out[k] = _mean_profile(grays[k], trimmed[k], axis)
        else:
            out[k] = _shaped(
                grays[k],
                trimmed[k],
                counts[k],
                axis,
                centres[k],
                axes[k],
                angles[k],
                (middle, level),
            )
    return out


def _shaped(gray, m, n, axis, centre, axes, angle_deg, envelope) -> tuple[np.ndarray, int]:
    """:func:`shape_profile` of a light that is not flat (its trimmed mask ``m`` of ``n``
    pixels, its envelope from the flat test's sample)."""
    middle, level = envelope
    if n > _FLAT_SAMPLE:
        step = math.ceil(math.sqrt(n / _SHAPE_SAMPLE))
        ((ys, xs, rho),) = _radii([m], [step], [centre], [axes], [angle_deg])
        ((middle, level),) = _radial_envelopes([gray[ys, xs]], [rho])
    ((ys, xs, rho),) = _radii([m], [1], [centre], [axes], [angle_deg])
    values = gray[ys, xs]
    rings = middle[level < _CLIP]  # the rings that do not clip
    level = np.maximum(np.interp(rho, middle, level), 1.0)
    line = ys if axis != "columns" else xs
    face = _clipped_face(level, line, values, rho, rings)
    if face is not None:
        values, level, line = values[face], level[face], line[face]
    counts = np.bincount(line)
    rows = (counts >= 2).nonzero()[0]
    if rows.size == 0:
        return np.zeros(0), 0, np.zeros(0)
    first, last = int(rows[0]), int(rows[-1]) + 1
    num = np.bincount(line, weights=values, minlength=last)[first:last]
    den = np.bincount(line, weights=level, minlength=last)[first:last]
    den = np.where(den > 0, den, np.nan)  # (a line without pixels: NaN, filled below)
    noise = np.sqrt(counts[first:last]) / den
    calm = (noise <= _NOISIEST_END * np.nanmedian(noise)).nonzero()[0]
    a, b = (int(calm[0]), int(calm[-1]) + 1) if calm.size >= 2 else (0, den.size)
    prof = num[a:b] / den[a:b] * float(level.max())  # between the calm end lines
    # a line's weight: 1 / its variance, (on-levels' sum)^2 / pixels up to a constant
    weight = np.nan_to_num(1.0 / np.square(noise[a:b]), nan=0.0, posinf=0.0)
    return _filled(prof), first + a, weight


def _clipped_face(
    level: np.ndarray, line: np.ndarray, values: np.ndarray, rho: np.ndarray, rings: np.ndarray
) -> np.ndarray | None:
    """The pixels of a light whose face clips, or None when it does not.

    A pixel of on-level ``L`` reads ``min(L * s, full scale)`` for an on-fraction ``s``: where
    the light clips a dark chip between bright ones leaves a shallow dip, where it does not
    (its glow) the dip is deep.  A bright disc in a glow clips over its whole face, and the
    lines beyond it along the readout cross only its glow: a profile over both reads the
    stripes through two responses, which no single saturation knee describes (the model's
    fit leaves half of such a profile unexplained).  When most pixels of the lines the
    clipped pixels span are clipped ones (:data:`_FACE`: the face clips, not only a hot core
    at its centre) and they read the stripes through a response of their own
    (:func:`_own_response`), the profile is taken over the clipped pixels alone, all read
    through the disc's own knee; else over all of them, as a light that clips at its core
    only, or barely, is read as one.  A light whose brightest ring does not reach the
    sensor's full scale (:data:`~camvlp.imaging.levels.FULL_SCALE`) does not clip at all.

    Parameters
    ----------
    level : ndarray, shape (n,)
        Each pixel's on-level (its ring's), gray levels; a pixel at
        :data:`~camvlp.imaging.levels.CLIP_LEVEL` or more counts as clipped.
    line : ndarray of int, shape (n,)
        Each pixel's line along the readout.
    values : ndarray, shape (n,)
        Each pixel's gray level.
    rho : ndarray, shape (n,)
        Each pixel's radius (in its outline's radii).
    rings : ndarray, shape (k,)
        The radii of the envelope's rings that do not clip, ascending (each pixel's on-level
        is interpolated between the two rings about it).

    Returns
    -------
    ndarray of bool, shape (n,), or None
        The clipped pixels, when the light's face clips.
    """
    if level.max() < _FULL:  # it does not reach the sensor's full scale: no pixel clips
        return None
    clipped = level >= _CLIP
    lines = line[clipped]
    span = (line >= lines.min()) & (line <= lines.max())
    if np.count_nonzero(clipped) <= _FACE * np.count_nonzero(span):
        return None
    # the others: beyond the clipped pixels' rings (whose on-levels are their own ring's,
    # not drawn from a clipped one's)
    beyond = rings[rings > rho[clipped].max()]
    other = span & ~clipped & (rho >= (beyond[0] if beyond.size else np.inf))
    return clipped if _own_response(level, line, values, clipped, other) else None


def _own_response(level, line, values, clipped, other) -> bool:
    """Whether a light's clipped pixels read the stripes through a response of their own
    (:data:`_OWN_RESPONSE`), each array (n,) as in :func:`_clipped_face` (``clipped``: the
    clipped pixels, ``other``: the unclipped ones of the lines they span, beyond them).

    In a line whose clipped pixels all read under full scale (a dark chip's), a pixel of
    on-level ``L`` reads ``L * s``, the light's other pixels of the line ``s`` times their
    on-levels: the clipped ones' reading over their on-level (full scale: their true on-level
    is not seen) over the others' gives how many times full scale the clipped pixels' true
    on-level is (a least-squares ratio over such lines, three pixels of each kind at least).
    True when it is :data:`_OWN_RESPONSE` or more, or when no line tells (the face clips
    wherever the light has other pixels).
    """
    n = int(line.max()) + 1

    def per_line(pick: np.ndarray, w: np.ndarray) -> np.ndarray:
        return np.bincount(line[pick], weights=w[pick], minlength=n)

    ones = np.ones(line.size)
    under = per_line(clipped & (values >= _CLIP), ones) == 0  # no clipped pixel at full scale
    told = (per_line(clipped, ones) >= 3) & (per_line(other, ones) >= 3) & under
    if not told.any():
        return True
    c = per_line(clipped, values)[told] / per_line(clipped, level)[told]
    u = per_line(other, values)[told] / per_line(other, level)[told]
    return float(np.dot(c, u)) >= _OWN_RESPONSE * float(np.dot(u, u))
