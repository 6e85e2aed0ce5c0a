"""Lights whose glows touch: one lit region, split into one cell per light.

Lamps that glow (or sit close in the photo) can join into one lit region at the detection's
threshold.  The region is then two or more round shapes joined by narrow necks: its distance
transform (each pixel's distance to the region's edge) has one peak per light, about the
light's radius, and dips between them.  Each light's cell is its part of the power diagram
of those peaks (a pixel goes to the light ``i`` with the least ``|p - c_i|^2 - r_i^2``): for
two overlapping circles the cut is the line through their crossing points, where their
outlines meet.  An elongated single light (a disc seen at a slant) has one peak on a ridge
that falls towards its ends, with no neck, and stays whole.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import cv2
import numpy as np

__all__ = [
    "CODES_APART",
    "CODES_CLEAR",
    "NECK",
    "ONE_DISC",
    "SOLIDITY",
    "codes_differ",
    "dark_level",
    "dark_seeds",
    "faces",
    "light_seeds",
    "not_convex",
    "one_disc",
    "one_per_light",
    "own_face",
    "power_cell",
]

#: A peak is a light of its own when the distance transform along the line to a larger
#: peak dips below this fraction of the smaller of the two (a neck between them).
NECK = 0.75


#: A candidate region less solid than this (its area over its convex hull's) may hold several
#: lights (two discs that just touch: 0.88).
SOLIDITY = 0.95


def not_convex(contour: np.ndarray, area: float) -> bool:
    """Whether a region's outline (OpenCV contour) of ``area`` (pixels) is less solid than
    :data:`SOLIDITY`: one that may hold several lights."""
    return area < SOLIDITY * cv2.contourArea(cv2.convexHull(contour))


#: A region whose area is within this factor of its inscribed circle's is one disc.  A disc
#: whose stripes' bridged ends roughen its outline by ``b`` pixels comes out about
#: ``1 + 2 b / R`` (1.15 for a lamp of 43 reduced pixels); two discs of radius ``R``
#: whose centres lie ``d`` apart make 1.31 at ``d = R / 2`` and 2 where they just touch.
ONE_DISC = 1.25


def one_disc(region: np.ndarray) -> bool:
    """Whether a lit region (uint8, nonzero inside) is one disc: its area at most
    :data:`ONE_DISC` times its inscribed circle's (the largest of its distance transform).

    Such a region holds one light, whatever the chords its lines clip say
    (:func:`~camvlp.pipeline.detect.chords.chord_seeds`): two lights' glows make a region longer
    than wide, by the distance between them.  A lamp that clips only in part (its level
    about full scale, a phone's vignetting and tone curve) clips runs that are no chords of
    its disc, whose middles pile up off its centre: a 1080p phone photo's lamp (0.85 chip,
    8 rows per chip, brightness 0.99, vignetting 0.37) was cut into two lights there, 69 and
    113 px from it, neither read."""
    dist = _distances((region > 0).astype(np.uint8))
    r = float(dist.max()) if dist.size else 0.0
    return r > 0 and np.count_nonzero(region) <= ONE_DISC * np.pi * r * r


def _hull(region: np.ndarray) -> np.ndarray:
    """A region (uint8, nonzero inside) filled out to its convex hull: a light whose wide
    dark bands cut notches in its rim is a disc again, two lights side by side are not."""
    points = cv2.findNonZero(region)
    out = np.zeros_like(region)
    if points is not None:
        cv2.fillConvexPoly(out, cv2.convexHull(points), 1)
    return out


def _distances(mask: np.ndarray) -> np.ndarray:
    """Each pixel's distance (pixels) to the nearest pixel outside ``mask`` (uint8, nonzero
    inside), the box around it counted as outside: OpenCV's distance transform sees nothing
    beyond the image's edge, where a region that fills its box would look deep."""
    padded = cv2.copyMakeBorder(mask, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
    return cv2.distanceTransform(padded, cv2.DIST_L2, 5)[1:-1, 1:-1]


def _segment(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pixels ``(x, y)`` (index arrays) on the segment between two points ``[x, y, ...]``,
    one at every pixel along it, ends included."""
    n = int(np.ceil(np.hypot(*(b[:2] - a[:2])))) + 1
    t = np.linspace(0.0, 1.0, max(n, 2))
    x = np.rint(a[0] + t * (b[0] - a[0])).astype(np.intp)
    y = np.rint(a[1] + t * (b[1] - a[1])).astype(np.intp)
    return x, y


def _neck(dist: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """The least distance-transform value on the segment between two peaks ``[x, y, r]``,
    sampled at every pixel along it."""
    x, y = _segment(a, b)
    return float(dist[y, x].min())


def _not_cut(region: np.ndarray, raw: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the segment between two peaks ``[x, y, ...]`` is not cut by a dark stripe:
    it has no gap in ``region`` (the peaks are joined there, by a neck), or its gap holds
    pixels lit in ``raw`` (away from the gap's ends): light dimmer than the lights, such as
    glow, where a dark stripe through one light would be dark."""
    x, y = _segment(a, b)
    gap = np.flatnonzero(region[y, x] == 0)
    return bool(gap.size == 0 or raw[y[gap[1:-1]], x[gap[1:-1]]].any())


def _along(a: np.ndarray, b: np.ndarray, axis: str) -> bool:
    """Whether two points ``[x, y, ...]`` lie apart mostly along the readout axis (across
    the stripes)."""
    dx, dy = abs(b[0] - a[0]), abs(b[1] - a[1])
    return dy > dx if axis == "rows" else dx > dy


#: Two peaks are two lights when the stripes along the readout through them correlate less
#: than this fraction of what each one's stripes correlate with a line nearby in its own light.
CODES_APART = 0.5
#: Least correlation of a line's stripes with a nearby line of its own light for the stripes
#: to tell two lights apart (below it, noise would).
CODES_CLEAR = 0.8
#: Fewest stripes (runs) two lines along the readout must share to be compared.
_CODE_RUNS = 6


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two 1-D arrays (0 when one is constant)."""
    a, b = a - a.mean(), b - b.mean()
    den = float(np.sqrt(np.dot(a, a) * np.dot(b, b)))
    return float(np.dot(a, b)) / den if den > 0 else 0.0


def codes_differ(
    gray: np.ndarray, inside: np.ndarray, a: np.ndarray, b: np.ndarray, axis: str, scale: int
) -> bool:
    """Whether two peaks of one lit region show different codes in their stripes.

    Every line along the readout is exposed at the same instants, so one light's stripes
    are the same on every line through it, and two lights (two IDs, or two frequencies)
    make different ones.  The lines through the two peaks (three lines each, averaged) are
    compared over the stretch of the readout both lie in the region, their smooth shape
    (the light's envelope) taken out; they differ when their correlation is under
    :data:`CODES_APART` times the least of each line's correlation with a line half its
    peak's radius towards the other peak (within its own light), and that is at least
    :data:`CODES_CLEAR`.  Peaks apart along the readout share too little of it: False.

    Parameters
    ----------
    gray : ndarray of uint8, shape (h * scale, w * scale) or larger
        The region at full resolution, gray levels.
    inside : ndarray of uint8, shape (h, w)
        The region (nonzero) in the reduced photo's pixels.
    a, b : ndarray, shape (3,)
        The peaks ``[x, y, r]`` in ``inside``'s pixels.
    axis : {"rows", "columns"}
        The readout axis.
    scale : int
        Full-resolution pixels per reduced pixel.
    """
    g = gray if axis == "columns" else gray.T  # g[line, t]: t along the readout
    m = inside if axis == "columns" else inside.T
    ia = 1 if axis == "columns" else 0  # the peaks' coordinate across the readout
    n_lines, n_t = g.shape

    def lines(p: np.ndarray, toward: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The line through ``p`` and the line half its radius towards ``toward`` (each
        three lines averaged), and where each lies in the region, along the readout."""
        step = 0.5 * float(p[2]) * np.sign(toward[ia] - p[ia])
        at = [float(p[ia]), float(p[ia]) + step]  # reduced pixels
        full = [round(a * scale) for a in at]
        if not all(1 <= f < n_lines - 1 for f in full):
            return None
        rows = [min(round(a), m.shape[0] - 1) for a in at]
        lit = np.repeat(m[rows] > 0, scale, axis=1)[:, :n_t]
        lit = np.pad(lit, ((0, 0), (0, n_t - lit.shape[1])))
        return np.stack([g[f - 1 : f + 2].mean(axis=0) for f in full]), lit

    got_a, got_b = lines(a, b), lines(b, a)
    if got_a is None or got_b is None:
        return False
    (pair_a, lit_a), (pair_b, lit_b) = got_a, got_b
    common = np.all(lit_a, axis=0) & np.all(lit_b, axis=0)
    if np.count_nonzero(common) < 4 * _CODE_RUNS:
        return False
    la = pair_a[0][common]
    cut = la > 0.5 * (la.min() + la.max())  # (a median is the clipping level where it clips)
    runs = np.count_nonzero(cut[1:] != cut[:-1]) + 1
    if runs < _CODE_RUNS:
        return False
    sigma = 2.0 * np.count_nonzero(common) / runs  # two runs' length
    four = np.concatenate([pair_a, pair_b]).astype(np.float32)
    smooth = cv2.GaussianBlur(four, (0, 0), sigmaX=sigma, sigmaY=1e-3)
    hp = (four - smooth)[:, common]
    ref = min(_correlation(hp[0], hp[1]), _correlation(hp[2], hp[3]))
    return ref >= CODES_CLEAR and _correlation(hp[0], hp[2]) < CODES_APART * ref


def light_seeds(
    region: np.ndarray,
    min_radius: float = 2.0,
    outline: np.ndarray | None = None,
    axis: str | Callable[[], str] = "rows",
    raw: np.ndarray | None = None,
    differ: Callable[[np.ndarray, np.ndarray], bool] | None = None,
) -> np.ndarray:
    """The lights in one lit region: the peaks of its distance transform.

    Peaks are taken largest first; one becomes a light of its own when it lies outside the
    inscribed circle of every light taken so far (its centre farther from theirs than either
    radius, in ``region`` and in ``outline``: pieces of one striped light lie within its
    outline's) and a neck (:data:`NECK`) separates it from each in ``region``.  Two peaks
    apart mostly along the readout (``axis``) may be the halves of one light cut by a wide
    dark stripe: they must be necked in ``outline`` too, when given (the same lights at a
    lower threshold, their stripes bridged, where one light has no neck), unless nothing
    dark cuts the segment between them: they are joined by a neck in ``region``, or the gap
    between them there holds pixels lit in ``raw`` (a dark stripe through one light is dark,
    where two lights whose glows join show glow between them).  Without a neck, two peaks
    are two lights when their stripes spell different codes (``differ``, e.g.
    :func:`codes_differ`): glows that clip together at the threshold hide the neck, not
    the codes.

    Parameters
    ----------
    region : ndarray of uint8, shape (h, w)
        The region, nonzero inside, its stripes bridged.
    min_radius : float
        Peaks lower than this (pixels) are not lights.
    outline : ndarray of uint8, shape (h, w), optional
        The region's outline at a lower threshold (nonzero inside, holding ``region``).
    axis : {"rows", "columns"} or callable
        The readout axis: ``"rows"`` when the stripes are horizontal; or a function giving
        it, called (once) only when two peaks could be apart along it.
    differ : callable, optional
        ``differ(a, b)``: whether two peaks ``[x, y, r]`` show different codes in their
        stripes (called only for peaks that no neck separates).

    Returns
    -------
    ndarray, shape (k, 3)
        ``[x, y, r]`` of each light: its peak (pixels of ``region``) and radius (pixels),
        largest first; one row at least when the region has a peak of ``min_radius``.
    """
    dist = _distances((region > 0).astype(np.uint8))
    peak = (dist >= cv2.dilate(dist, np.ones((3, 3), np.uint8))) & (dist >= min_radius)
    ys, xs = np.nonzero(peak)
    order = np.argsort(-dist[ys, xs], kind="stable")
    cands = np.stack([xs[order], ys[order], dist[ys, xs][order]], axis=1).astype(np.float64)
    if len(cands) > 1:  # within the largest peak's circle (or it within theirs): never lights
        top, rest = cands[0], cands[1:]
        far = np.hypot(rest[:, 0] - top[0], rest[:, 1] - top[1]) > np.maximum(top[2], rest[:, 2])
        cands = np.concatenate([cands[:1], rest[far]])
    # the outline's distance transform only when two peaks are left, the axis only when
    # two peaks lie apart along it
    wide = None if outline is None or len(cands) < 2 else _distances(outline)
    readout = functools.cache(axis) if callable(axis) else lambda: axis

    def necked(d: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
        ra, rb = d[int(a[1]), int(a[0])], d[int(b[1]), int(b[0])]
        return _neck(d, a, b) < NECK * min(ra, rb)

    def outside(d: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
        """Each centre outside the other's inscribed circle in ``d``."""
        ra, rb = d[int(a[1]), int(a[0])], d[int(b[1]), int(b[0])]
        return bool(np.hypot(*(b[:2] - a[:2])) > max(ra, rb))

    seeds: list[np.ndarray] = []
    for c in cands:
        apart = all(
            np.hypot(*(c[:2] - s[:2])) > max(s[2], c[2])
            and (wide is None or outside(wide, s, c))
            and (necked(dist, s, c) or (differ is not None and differ(s, c)))
            and (
                wide is None
                or not _along(s, c, readout())
                or necked(wide, s, c)
                or (raw is not None and _not_cut(region, raw, s, c))
            )
            for s in seeds
        )
        if apart:
            seeds.append(c)
    return np.array(seeds, dtype=np.float64).reshape(-1, 3)


def power_cell(box: tuple[int, int, int, int], seeds: np.ndarray, i: int) -> np.ndarray:
    """Light ``i``'s cell of the seeds' power diagram, inside a box.

    Parameters
    ----------
    box : tuple of int
        ``(x0, y0, x1, y1)``, pixels (end exclusive), in the seeds' frame.
    seeds : ndarray, shape (k, 3) or (k, 4)
        ``[x, y, r]`` of each light, pixels; a fourth column, when given, bounds each
        light's cell to the disc of that radius about it (inf: no bound).
    i : int
        The light.

    Returns
    -------
    ndarray of bool, shape (y1 - y0, x1 - x0)
        The pixels nearer light ``i`` than any other in power distance (and within its
        bound).
    """
    x0, y0, x1, y1 = box
    x = np.arange(x0, x1, dtype=np.float32)[None, :]
    y = np.arange(y0, y1, dtype=np.float32)[:, None]
    s = seeds.astype(np.float32)
    own = (x - s[i, 0]) ** 2 + (y - s[i, 1]) ** 2 - s[i, 2] ** 2
    cell = np.ones(own.shape, dtype=bool)
    if s.shape[1] > 3 and np.isfinite(s[i, 3]):
        cell = own + s[i, 2] ** 2 <= s[i, 3] ** 2
    for j in range(len(s)):
        if j != i:
            cell &= own <= (x - s[j, 0]) ** 2 + (y - s[j, 1]) ** 2 - s[j, 2] ** 2
    return cell


def one_per_light(
    comps,
    several,
    binary: np.ndarray,
    high: np.ndarray | None,
    min_radius: float,
    axis_of: Callable,
    raw: np.ndarray | None = None,
    dark_of: Callable | None = None,
    differ_of: Callable | None = None,
    chords_of: Callable | None = None,
):
    """The lights of the detection's candidate regions.

    Parameters
    ----------
    comps : iterable of tuple
        Each candidate region's bounding box ``(x, y, w, h)`` in ``binary``'s pixels.
    several : iterable of bool
        Whether each region may hold several lights (is looked at); the others are one.
    binary : ndarray of uint8, shape (h, w)
        The candidate regions (nonzero), their stripes bridged.
    high : ndarray of uint8, shape (h, w), or None
        The same at a higher threshold: where glows that join in ``binary`` stay apart
        (needed when any region is looked at).
    min_radius : float
        Smallest radius of a light, pixels.
    axis_of : callable
        ``axis_of(inside, (x, y, w, h))``: the readout axis (``"rows"`` or ``"columns"``)
        of a region, from its pixels ``inside`` (uint8 0/1 of the box).
    raw : ndarray of uint8, shape (h, w), optional
        ``binary`` before its stripes were bridged (see :func:`light_seeds`).
    dark_of : callable, optional
        ``dark_of((x, y, w, h), axis)``: a region's dark-stripe levels in ``binary``'s
        pixels and the level its faces must reach (:func:`dark_level`), or None.
    differ_of : callable, optional
        ``differ_of((x, y, w, h), inside, axis)``: the ``differ`` of :func:`light_seeds` for
        a region (e.g. :func:`codes_differ` on its pixels at full resolution).
    chords_of : callable, optional
        ``chords_of((x, y, w, h), inside, axis)``: a region's lights from the chords its
        lines clip (:func:`~camvlp.pipeline.detect.chords.chord_seeds`), ``[x, y, r]`` (k, 3) in
        the box's pixels; taken when they are more lights than the region's peaks found
        (:func:`_with_chords`), unless the region is one disc (:func:`one_disc`).

    Yields
    ------
    box : tuple of int
        ``(x, y, w, h)``: a region's box, or one light's part of it.
    cell : tuple or None
        None for a region that holds one light; else ``(seeds, i)``: the region's lights'
        ``[x, y, r, reach]`` (k, 4) in ``binary``'s pixels (:func:`light_seeds` of its part
        of ``high``, or of its faces or clipped chords; ``reach`` bounds a light's cell,
        :func:`power_cell`: its clipped disc's radius for a light found by its chords, else
        inf), and which of them the box is.
    """
    for (x, y, w, h), look in zip(comps, several, strict=True):
        if not look or high is None:
            yield (x, y, w, h), None
            continue
        region = binary[y : y + h, x : x + w]
        n, labels, stats, _ = cv2.connectedComponentsWithStats(region, connectivity=8)
        if n < 2:
            yield (x, y, w, h), None
            continue
        main = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        inside = (labels == main).astype(np.uint8)
        if one_disc(_hull(inside)):  # one light, whatever its bands or dark stripes say
            yield (x, y, w, h), None
            continue
        axis = functools.partial(axis_of, inside, (x, y, w, h))  # when needed
        lit = None if raw is None else raw[y : y + h, x : x + w]
        differ = None if differ_of is None else differ_of((x, y, w, h), inside, axis)
        seeds = light_seeds(
            inside * high[y : y + h, x : x + w], min_radius, inside, axis, lit, differ
        )
        if dark_of is not None:  # more lights apart in the dark stripes?
            got = dark_of((x, y, w, h), axis())
            dark = None if got is None else dark_seeds(got[0], inside, min_radius, got[1])
            # (more than the bright part's peaks of a lamp's size: its small ones are
            # pieces of glow between lamps, which the faces leave out)
            if dark is not None and len(dark) > len(_lamp_sized(seeds)):
                seeds = dark
        seeds = np.column_stack([seeds, np.full(len(seeds), np.inf)])  # (no bound)
        if chords_of is not None:  # more lights in the chords?
            seeds = _with_chords(seeds, chords_of((x, y, w, h), inside, axis()))
        if len(seeds) < 2:
            yield (x, y, w, h), None
            continue
        seeds[:, :2] += [x, y]
        for i in range(len(seeds)):
            ys, xs = np.nonzero(inside & power_cell((x, y, x + w, y + h), seeds, i))
            if ys.size:
                box = (
                    x + int(xs.min()),
                    y + int(ys.min()),
                    int(np.ptp(xs)) + 1,
                    int(np.ptp(ys)) + 1,
                )
                yield box, (seeds, i)


def _with_chords(seeds: np.ndarray, chords: np.ndarray) -> np.ndarray:
    """A region's lights ``[x, y, r, reach]`` (k, 4): when its clipped chords show more
    lights (:func:`~camvlp.pipeline.detect.chords.chord_seeds`) than its peaks ``seeds`` of a
    lamp's size, the chords' lights, each bounded by its clipped disc (``reach`` its
    radius: the region's pixels beyond are glow, its own or its neighbours', which says
    nothing of where its disc lies), and the peaks that hold none of theirs and lie in none
    of their circles (a light that does not clip); else ``seeds``."""
    if len(chords) <= len(_lamp_sized(seeds)):
        return seeds
    d = np.hypot(seeds[:, None, 0] - chords[None, :, 0], seeds[:, None, 1] - chords[None, :, 1])
    apart = (d > np.maximum(seeds[:, None, 2], chords[None, :, 2])).all(axis=1)
    return np.concatenate([np.column_stack([chords, chords[:, 2]]), seeds[apart]])


def _run_modes(lit: np.ndarray, axis: str) -> tuple[int, int]:
    """The commonest lengths (pixels) of the lit runs, and of the dark runs between two lit
    ones, along the readout (``axis``: ``"rows"`` or ``"columns"``) of a region of 0 and 1
    (uint8, shape (h, w)); 0 when it has none.

    Where a level sits at the threshold (a soft stripe edge or a glow, with noise, JPEG's
    ringing and a phone's sharpening) the pixels flicker in runs of one pixel, which in a
    large region can outnumber the stripes' dark runs.  When one pixel is the commonest dark
    run, the runs are counted again with every pixel the majority of itself and its two
    neighbours along the readout (the runs of one pixel removed, the others as they were).
    Were the runs of one pixel the stripes' own single dark chips (a long exposure's), the
    lit runs' commonest length ``L`` would make a chip ``(L + 1) / 2`` pixels long, and the
    dark runs left, of two chips, ``(L + 3) / 2``: when the commonest of them is further
    than the modes' rounding (1.5 pixels) from that, the runs of one pixel were flicker, and
    the modes counted again are the stripes'.  Where the stripes' own single dark chips are
    about that long (lit runs of ``p + e`` and dark ones of ``p - e`` pixels with
    ``p`` about ``3 e + 3``: 8 rows per chip at 0.1 chip, lit 9 and dark 7 against 6) the two
    cannot be told apart this way, and the modes stay as counted, one-pixel runs and all."""
    lines = lit if axis == "columns" else lit.T  # one line along the readout per row
    lit_mode, dark_mode = _modes(lines)
    if dark_mode == 1:
        edged = np.pad(lines.astype(np.uint8), ((0, 0), (1, 1)), mode="edge")
        again = _modes((edged[:, :-2] + edged[:, 1:-1] + edged[:, 2:]) >= 2)
        if abs(again[1] - 0.5 * (lit_mode + 3)) > 1.5:
            return again
    return lit_mode, dark_mode


def _modes(lines: np.ndarray) -> tuple[int, int]:
    """:func:`_run_modes` of lines along the readout (0 and 1, shape (n, length))."""
    d = np.diff(np.pad(lines.astype(np.int8), ((0, 0), (1, 1))), axis=1)
    r, c = np.nonzero(d)  # along a line the changes alternate: up, down, up, ...
    up = d[r, c] > 0
    lengths, same = np.diff(c), r[1:] == r[:-1]
    runs = (lengths[same & up[:-1]], lengths[same & ~up[:-1]])
    lit_mode, dark_mode = (int(np.argmax(np.bincount(x)[1:])) + 1 if x.size else 0 for x in runs)
    return lit_mode, dark_mode


#: At long exposures a face counts only when its dark-stripe levels reach this fraction of
#: the region's brightest level (where it clips; JPEG's ringing lowers a clipped area a little).
CLIPPED = 0.95


def dark_level(gray: np.ndarray, lit: np.ndarray, axis: str) -> tuple[np.ndarray, float] | None:
    """Each pixel's level in its light's dark stripes.

    Lights whose glows clip together in their bright stripes stay apart in their dark ones:
    a light's stripes are shared by its face and its glow, and where the LED is not fully off
    its face shows there at its off level, above its glow (a halo is dimmer than the face).
    The gray levels are opened along the readout (each pixel takes the least level over a
    window, then the most of those over the windows that hold it) over six chips or more:
    three times a lit and a dark run's commonest lengths, which together span two chips
    whatever the exposure (a chip's bright stripe grows by the exposure, a dark one shrinks
    by it), while no bright run of the default frame is longer than four chips.  The window
    then holds a dark chip of the light wherever it lies within its face, and a face as long
    as the window along the readout keeps its extent.

    At long exposures (a third of a chip or more: dark runs under half the lit ones) a single
    dark chip leaves only a shallow dip, and a face that does not clip shows there at levels
    that change with the chips the window holds (bands along the stripes, which cut a face
    in pieces).  But a face that clips stays clipped across its dark chips (the LED not
    fully off, or the chip smeared by the exposure) where its glow, dimmer by about the
    halo, goes dark: there only the faces that reach the clipping level count
    (:data:`CLIPPED` of the region's brightest level).

    Parameters
    ----------
    gray : ndarray of uint8, shape (h, w)
        A region of the photo, gray levels.
    lit : ndarray of uint8, shape (h, w)
        Its lit pixels (0 and 1): the stripes whose runs tell the chip's length.
    axis : {"rows", "columns"}
        The readout axis.

    Returns
    -------
    tuple, or None
        The dark-stripe levels (uint8, shape (h, w)) and the least level a face must reach
        somewhere to count (0 at short exposures; gray levels); None where the dark runs are
        shorter than 2 pixels (stripes the pixels do not resolve).
    """
    lit_mode, dark_mode = _run_modes(lit, axis)
    if dark_mode < 2:
        return None
    n = 3 * (lit_mode + dark_mode) | 1
    ksize = (n, 1) if axis == "columns" else (1, n)
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, ksize)
    reach = CLIPPED * float(gray.max()) if 2 * dark_mode < lit_mode else 0.0
    return cv2.morphologyEx(gray, cv2.MORPH_OPEN, kernel), reach


def faces(dark: np.ndarray, inside: np.ndarray, reach: float = 0.0) -> np.ndarray | None:
    """The lights' faces in a region's dark-stripe levels (:func:`dark_level`): the levels
    inside it (``inside``, nonzero) above Otsu's threshold of them, as uint8 0 and 1, each
    face (8-connected) one whose levels reach ``reach`` somewhere; None when the two
    classes' means lie under 12 gray levels apart (no face stands out of the glow and the
    background, e.g. an LED fully off) or no face is left."""
    vals = dark[inside > 0]
    if vals.size < 16:
        return None
    thr, _ = cv2.threshold(vals.reshape(-1, 1), 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    above = vals > thr
    if above.all() or not above.any() or vals[above].mean() - vals[~above].mean() < 12:
        return None
    face = ((dark > thr) & (inside > 0)).astype(np.uint8)
    if reach > 0:
        n, labels = cv2.connectedComponents(face, connectivity=8)
        top = np.zeros(n, dark.dtype)
        np.maximum.at(top, labels.ravel(), dark.ravel())
        face = (top >= reach)[labels].astype(np.uint8) & face
        if not face.any():
            return None
    return face


def _lamp_sized(seeds: np.ndarray) -> np.ndarray:
    """The seeds ``[x, y, r]`` (k, 3) whose radius is half their median's or more: the
    others are pieces between lights (of a glow, or of a face), not lights."""
    return seeds[seeds[:, 2] >= 0.5 * np.median(seeds[:, 2])] if len(seeds) else seeds


def dark_seeds(
    dark: np.ndarray, inside: np.ndarray, min_radius: float, reach: float = 0.0
) -> np.ndarray | None:
    """The lights of one lit region from its faces in the dark stripes (:func:`faces`).

    Each face is a disc: its peak of the faces' distance transform (:func:`light_seeds`) is
    its inscribed circle, and its part of the faces (its power cell's) covers 0.6 to 1.6
    times that circle's area; a region whose faces are not all such discs (stripes the
    window missed, a glow's pieces) gives None.  Peaks under half the median's radius are
    pieces between faces, left out.

    Parameters
    ----------
    dark : ndarray of uint8, shape (h, w)
        The region's dark-stripe levels (:func:`dark_level`).
    inside : ndarray of uint8, shape (h, w)
        The region (nonzero).
    min_radius : float
        Smallest radius of a light, pixels.
    reach : float
        The level each face must reach somewhere (:func:`dark_level`, :func:`faces`).

    Returns
    -------
    ndarray, shape (k, 3), or None
        ``[x, y, r]`` of each light, as :func:`light_seeds`; None when fewer than two.
    """
    face = faces(dark, inside, reach)
    if face is None:
        return None
    seeds = light_seeds(face, min_radius)
    if len(seeds) < 2:
        return None
    seeds = _lamp_sized(seeds)
    h, w = face.shape
    for i in range(len(seeds)):
        area = np.count_nonzero(face & power_cell((0, 0, w, h), seeds, i))
        if not 0.6 <= area / (np.pi * seeds[i, 2] ** 2) <= 1.6:
            return None
    return seeds if len(seeds) >= 2 else None


def own_face(
    gray: np.ndarray, lit: np.ndarray, cell: np.ndarray, axis: str, seed: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """A light's face in its cell of a region where glows join, from its dark stripes.

    The faces in the cell (:func:`faces` of :func:`dark_level`), opened by a disc of 0.8
    times the largest one's inscribed diameter and kept within 1.2 times its inscribed
    radius of its centre: what a window missed (a band along the stripes where two lights'
    glows are never dark together) is thinner than a face, and lies beyond its rim.

    Parameters
    ----------
    gray : ndarray of uint8, shape (h, w)
        The light's region of interest, gray levels.
    lit : ndarray of uint8, shape (h, w)
        Its lit pixels within the cell (0 and 1).
    cell : ndarray of bool, shape (h, w)
        The light's cell (:func:`power_cell`).
    axis : {"rows", "columns"}
        The readout axis.
    seed : ndarray, shape (3,)
        The light's ``[x, y, r]`` in the region (:func:`light_seeds`, full resolution).

    Returns
    -------
    tuple of ndarray, or None
        The face (uint8 0 and 1, shape (h, w)) and the dark-stripe levels (uint8, the same
        shape); None when the dark stripes show no face, when it covers less than 0.6 of its
        inscribed circle, or when it does not hold the seed's centre (another light's).
    """
    got = dark_level(gray, lit, axis)
    face = None if got is None else faces(got[0], cell.view(np.uint8), got[1])
    if face is None:
        return None
    level = got[0]
    dist = _distances(face)
    y, x = np.unravel_index(int(np.argmax(dist)), dist.shape)
    depth = float(dist[y, x])
    if depth < 2:
        return None
    # opened by a disc of radius 0.8 depth: the pixels within it of a centre that deep
    deep = (dist < 0.8 * depth).astype(np.uint8)
    face &= cv2.distanceTransform(deep, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) <= 0.8 * depth
    disc = np.zeros_like(face)
    cv2.circle(disc, (int(x), int(y)), int(1.2 * depth), 1, -1)
    face &= disc
    h, w = face.shape
    sx, sy = int(np.clip(seed[0], 0, w - 1)), int(np.clip(seed[1], 0, h - 1))
    if depth < 0.5 * seed[2] or np.count_nonzero(face) < 0.6 * np.pi * depth**2:
        return None  # a hot core, or pieces
    if not face[sy, sx]:  # another light's
        return None
    return face, level
