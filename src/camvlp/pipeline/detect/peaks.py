"""The lights in one lit region: the peaks of its distance transform, and each light's cell.

Lamps whose glows join make one lit region of round shapes joined by narrow necks: its
distance transform (each pixel's distance to the region's edge) has one peak per light, about
the light's radius, and dips between them.  Each light's cell is its part of the power
diagram of those peaks (a pixel goes to the light ``i`` with the least ``|p - c_i|^2 -
r_i^2``): for two overlapping circles the cut is the line through their crossing points,
where their outlines meet.  An elongated single light (a disc seen at a slant) has one peak
on a ridge that falls towards its ends, with no neck, and stays whole.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

__all__ = ["NECK", "distances", "lamp_sized", "light_seeds", "power_cell"]

#: A peak is a light of its own when the distance transform along the line to a larger
#: peak dips below this fraction of the smaller of the two (a neck between them).
NECK = 0.75


def distances(mask: np.ndarray) -> np.ndarray:
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


def light_seeds(
    region: np.ndarray,
    min_radius: float = 2.0,
    outline: np.ndarray | None = None,
    axis: str = "rows",
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
    :func:`~camvlp.pipeline.detect.codes.codes_differ`): glows that clip together at the
    threshold hide the neck, not the codes.

    Parameters
    ----------
    region : ndarray of uint8, shape (h, w)
        The region, nonzero inside, its stripes bridged.
    min_radius : float
        Peaks lower than this (pixels) are not lights.
    outline : ndarray of uint8, shape (h, w), optional
        The region's outline at a lower threshold (nonzero inside, holding ``region``).
    axis : {"rows", "columns"}
        The readout axis: ``"rows"`` when the stripes are horizontal.
    raw : ndarray of uint8, shape (h, w), optional
        The region's pixels lit before its stripes were bridged.
    differ : callable, optional
        ``differ(a, b)``: whether two peaks ``[x, y, r]`` show different codes in their
        stripes (called only for peaks that no neck separates).

    Returns
    -------
    ndarray, shape (k, 3)
        ``[x, y, r]`` of each light: its peak (pixels of ``region``) and radius (pixels),
        largest first; one row at least when the region has a peak of ``min_radius``.
    """
    dist = distances((region > 0).astype(np.uint8))
    peak = (dist >= cv2.dilate(dist, np.ones((3, 3), np.uint8))) & (dist >= min_radius)
    ys, xs = np.nonzero(peak)
    order = np.argsort(-dist[ys, xs], kind="stable")
    cands = np.stack([xs[order], ys[order], dist[ys, xs][order]], axis=1).astype(np.float64)
    if len(cands) > 1:  # within the largest peak's circle (or it within theirs): never lights
        top, rest = cands[0], cands[1:]
        far = np.hypot(rest[:, 0] - top[0], rest[:, 1] - top[1]) > np.maximum(top[2], rest[:, 2])
        cands = np.concatenate([cands[:1], rest[far]])
    # the outline's distance transform only when two peaks are left
    wide = None if outline is None or len(cands) < 2 else distances(outline)

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
                or not _along(s, c, axis)
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


def lamp_sized(seeds: np.ndarray) -> np.ndarray:
    """The seeds ``[x, y, r]`` (k, 3) whose radius is half their median's or more: the
    others are pieces between lights (of a glow, or of a face), not lights."""
    return seeds[seeds[:, 2] >= 0.5 * np.median(seeds[:, 2])] if len(seeds) else seeds
