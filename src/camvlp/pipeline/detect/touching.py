"""Lights whose glows touch: one lit region of the candidate search, split into one cell per
light.

Lamps that glow (or sit close in the photo) can join into one lit region at the detection's
threshold.  A region that is convex, or one disc, holds one light: a plain disc, or a glowing
or clipped lamp alone.  Any other is split by what its lights' looks leave apart, in turn:

- glows that join at the threshold stay apart in the lights' brighter parts: the peaks of
  their distance transform (:func:`~camvlp.pipeline.detect.peaks.light_seeds`), told apart
  by a neck between them or by their stripes' codes
  (:func:`~camvlp.pipeline.detect.codes.codes_differ`);
- glows that clip together in the bright stripes stay apart in the dark ones: the lamps'
  faces there (:func:`~camvlp.pipeline.detect.faces.dark_seeds`);
- lamps that clip across their whole disc show it in the chords their lines clip
  (:func:`~camvlp.pipeline.detect.chords.chord_seeds`).

Each light's cell is then its part of the power diagram of the lights found
(:func:`~camvlp.pipeline.detect.peaks.power_cell`).  The region's inputs are named data
(:class:`CandidateSearch`, :class:`JoinedRegion`), worked at full resolution where the
reduced photo does not resolve the stripes.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.imaging.gray import to_gray
from camvlp.pipeline.detect.chords import chord_seeds
from camvlp.pipeline.detect.codes import codes_differ
from camvlp.pipeline.detect.faces import dark_level, dark_seeds
from camvlp.pipeline.detect.peaks import distances, lamp_sized, light_seeds, power_cell
from camvlp.pipeline.detect.readout import axis_contrast
from camvlp.pipeline.paths import path

__all__ = [
    "MIN_LIGHT_RADIUS",
    "ONE_DISC",
    "SOLIDITY",
    "CandidateSearch",
    "JoinedRegion",
    "not_convex",
    "one_disc",
    "one_per_light",
]

#: Smallest radius of a light in a joined region, pixels of the reduced photo: smaller ones
#: the decimation cannot split.
MIN_LIGHT_RADIUS = 3.0


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
    dist = distances((region > 0).astype(np.uint8))
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


@dataclass(frozen=True)
class CandidateSearch:
    """What the candidate search saw of a photo: the inputs of each region's split into lights.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3) or (H, W)
        The photo at full resolution.
    small : ndarray of uint8, shape (h, w)
        Its gray levels, reduced ``scale`` times.
    scale : int
        Full-resolution pixels per reduced pixel.
    threshold : float
        The candidates' threshold, gray levels.
    readout : {"rows", "columns"} or None
        The sensor's readout axis when known; None finds it from each region's stripes.
    raw : ndarray of uint8, shape (h, w)
        ``small`` above the threshold (nonzero), before the stripes were bridged.
    binary : ndarray of uint8, shape (h, w)
        The candidate regions (nonzero), their stripes bridged.
    high : ndarray of uint8, shape (h, w), or None
        The same at a higher threshold, where glows that join in ``binary`` stay apart; None
        when no region may hold several lights.
    """

    image: np.ndarray
    small: np.ndarray
    scale: int
    threshold: float
    readout: str | None
    raw: np.ndarray
    binary: np.ndarray
    high: np.ndarray | None

    def full_gray(self, box: tuple[int, int, int, int]) -> np.ndarray:
        """The gray levels (uint8) of the photo's pixels under a box ``(x, y, w, h)`` of the
        reduced photo, at full resolution."""
        x, y, w, h = box
        s = self.scale
        return to_gray(self.image[y * s : (y + h) * s, x * s : (x + w) * s])


@dataclass(frozen=True)
class JoinedRegion:
    """A candidate region that may hold several lights whose glows join.

    Attributes
    ----------
    search : CandidateSearch
        The photo's candidate search.
    box : tuple of int
        ``(x, y, w, h)``, pixels of the reduced photo.
    inside : ndarray of uint8, shape (h, w)
        The region's pixels in its box (0 and 1).
    """

    search: CandidateSearch
    box: tuple[int, int, int, int]
    inside: np.ndarray

    def part(self, image: np.ndarray) -> np.ndarray:
        """The box's part of an image of the reduced photo's shape."""
        x, y, w, h = self.box
        return image[y : y + h, x : x + w]

    @functools.cached_property
    def axis(self) -> str:
        """The readout axis: the search's, or the one the region's stripes show."""
        small = self.part(self.search.small)
        return self.search.readout or axis_contrast(small, self.inside)[0]

    @functools.cached_property
    def gray(self) -> np.ndarray:
        """The region's gray levels (uint8) at full resolution."""
        return self.search.full_gray(self.box)

    def codes_differ(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether two peaks ``[x, y, r]`` of the region spell different codes in their
        stripes (:func:`~camvlp.pipeline.detect.codes.codes_differ`, at full resolution)."""
        return codes_differ(self.gray, self.inside, a, b, self.axis, self.search.scale)

    def dark_stripes(self) -> tuple[np.ndarray, float] | None:
        """The region's dark-stripe levels in the reduced photo's pixels and the level its
        faces must reach (:func:`~camvlp.pipeline.detect.faces.dark_level`), worked at full
        resolution (the reduced photo does not resolve the stripes), the levels averaged
        down to the region; None where the stripes are not resolved."""
        lit = cv2.threshold(self.gray, self.search.threshold, 1, cv2.THRESH_BINARY)[1]
        got = dark_level(self.gray, lit, self.axis)
        if got is None:
            return None
        return cv2.resize(got[0], self.box[2:], interpolation=cv2.INTER_AREA), got[1]

    def chords(self) -> np.ndarray:
        """The region's lights from its clipped chords
        (:func:`~camvlp.pipeline.detect.chords.chord_seeds`, at full resolution), ``[x, y,
        r]`` (k, 3) in its box's pixels, worked on the box grown by two reduced pixels: a
        chord the box cut is left out, where a light's clipped disc may reach past its
        region's reduced pixels."""
        x, y, w, h = self.box
        rows, cols = self.search.small.shape
        x0, y0 = max(0, x - 2), max(0, y - 2)
        x1, y1 = min(cols, x + w + 2), min(rows, y + h + 2)
        grown = np.pad(self.inside, ((y - y0, y1 - y - h), (x - x0, x1 - x - w)))
        gray = self.search.full_gray((x0, y0, x1 - x0, y1 - y0))
        got = chord_seeds(gray, grown, self.axis, self.search.scale, MIN_LIGHT_RADIUS)
        return got - [x - x0, y - y0, 0.0]


def one_per_light(
    search: CandidateSearch,
    boxes: list[tuple[int, int, int, int]],
    several: list[bool],
) -> Iterator[tuple[tuple[int, int, int, int], tuple[np.ndarray, int] | None]]:
    """The lights of the detection's candidate regions.

    Parameters
    ----------
    search : CandidateSearch
        The photo's candidate search.
    boxes : list of tuple of int
        Each candidate region's bounding box ``(x, y, w, h)`` in the reduced photo's pixels.
    several : list of bool
        Whether each region may hold several lights (is looked at); the others are one.

    Yields
    ------
    box : tuple of int
        ``(x, y, w, h)``: a region's box, or one light's part of it.
    cell : tuple or None
        None for a region that holds one light; else ``(seeds, i)``: the region's lights'
        ``[x, y, r, reach]`` (k, 4) in the reduced photo's pixels (:func:`region_lights`;
        ``reach`` bounds a light's cell, :func:`~camvlp.pipeline.detect.peaks.power_cell`),
        and which of them the box is.
    """
    for box, look in zip(boxes, several, strict=True):
        region = _joined(search, box) if look and search.high is not None else None
        seeds = None if region is None else region_lights(region)
        if seeds is None or len(seeds) < 2:
            yield box, None
        else:
            yield from _cells(region, seeds)


def _joined(search: CandidateSearch, box: tuple[int, int, int, int]) -> JoinedRegion | None:
    """The region in ``box`` (its largest part) as one to split, or None when it holds one
    light: it is one disc (:func:`one_disc`), whatever its bands or dark stripes say."""
    x, y, w, h = box
    n, labels, stats, _ = cv2.connectedComponentsWithStats(
        search.binary[y : y + h, x : x + w], connectivity=8
    )
    if n < 2:
        return None
    main = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    inside = (labels == main).astype(np.uint8)
    return None if one_disc(_hull(inside)) else JoinedRegion(search, box, inside)


@path("joined region")
def region_lights(region: JoinedRegion) -> np.ndarray:
    """The lights of a joined region, ``[x, y, r, reach]`` (k, 4) in its box's pixels: the
    peaks of its brighter parts, or its faces in the dark stripes, or its clipped chords,
    whichever show more lights (``reach``: a clipped disc's radius for a light found by its
    chords, else inf)."""
    seeds = _bright_peaks(region)
    seeds = _dark_faces(region, seeds)
    seeds = np.column_stack([seeds, np.full(len(seeds), np.inf)])  # (no bound)
    return _with_chords(seeds, region.chords())


def _bright_peaks(region: JoinedRegion) -> np.ndarray:
    """The lights ``[x, y, r]`` (k, 3) of a region whose glows join at the threshold: the
    peaks of its part of the brighter pixels (:func:`~camvlp.pipeline.detect.peaks.light_seeds`,
    the region as their outline, its raw pixels as what lies between them)."""
    search = region.search
    return light_seeds(
        region.inside * region.part(search.high),
        MIN_LIGHT_RADIUS,
        outline=region.inside,
        axis=region.axis,
        raw=region.part(search.raw),
        differ=region.codes_differ,
    )


def _dark_faces(region: JoinedRegion, seeds: np.ndarray) -> np.ndarray:
    """The lights ``[x, y, r]`` of a region whose glows clip together in the bright stripes:
    its faces in the dark stripes (:func:`~camvlp.pipeline.detect.faces.dark_seeds`), when
    they are more lights than the bright part's peaks ``seeds`` of a lamp's size (its small
    ones are pieces of glow between lamps, which the faces leave out); else ``seeds``."""
    got = region.dark_stripes()
    dark = None if got is None else dark_seeds(got[0], region.inside, MIN_LIGHT_RADIUS, got[1])
    return dark if dark is not None and len(dark) > len(lamp_sized(seeds)) else seeds


def _with_chords(seeds: np.ndarray, chords: np.ndarray) -> np.ndarray:
    """A region's lights ``[x, y, r, reach]`` (k, 4): when its clipped chords show more
    lights (:func:`~camvlp.pipeline.detect.chords.chord_seeds`) than its peaks ``seeds`` of a
    lamp's size, the chords' lights, each bounded by its clipped disc (``reach`` its
    radius: the region's pixels beyond are glow, its own or its neighbours', which says
    nothing of where its disc lies), and the peaks that hold none of theirs and lie in none
    of their circles (a light that does not clip); else ``seeds``."""
    if len(chords) <= len(lamp_sized(seeds)):
        return seeds
    d = np.hypot(seeds[:, None, 0] - chords[None, :, 0], seeds[:, None, 1] - chords[None, :, 1])
    apart = (d > np.maximum(seeds[:, None, 2], chords[None, :, 2])).all(axis=1)
    return np.concatenate([np.column_stack([chords, chords[:, 2]]), seeds[apart]])


def _cells(
    region: JoinedRegion, seeds: np.ndarray
) -> Iterator[tuple[tuple[int, int, int, int], tuple[np.ndarray, int]]]:
    """Each light's part of a region: the box ``(x, y, w, h)`` of its power cell's pixels in
    the region, and the region's lights ``[x, y, r, reach]`` in the reduced photo's pixels
    with which of them it is."""
    x, y, w, h = region.box
    seeds = seeds.copy()
    seeds[:, :2] += [x, y]
    for i in range(len(seeds)):
        ys, xs = np.nonzero(region.inside & power_cell((x, y, x + w, y + h), seeds, i))
        if ys.size:
            box = (x + int(xs.min()), y + int(ys.min()), int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1)
            yield box, (seeds, i)
