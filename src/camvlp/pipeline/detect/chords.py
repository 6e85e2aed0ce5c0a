"""Lights whose glows clip together: found by the chords their lines clip.

Lamps that glow brightly enough clip over their discs and the glow around them; close
lamps' clipped glows join into one region with no neck between them at any threshold of the
bright stripes (a stress photo's upper half was one such region holding four lamps, found as
one light).  What tells them apart is time: each line across the readout is exposed at one
instant, when some lamps are on and others dark, so the lamps' clipped discs show one by one,
line by line, each clipped run a chord about its lamp's centre (:func:`chord_seeds`).
"""

from __future__ import annotations

import cv2
import numpy as np

from camvlp.imaging.levels import CLIP_LEVEL
from camvlp.pipeline.paths import path

__all__ = ["CHORD_END_PX", "CHORD_LINES", "CHORD_SHARE", "chord_seeds"]

#: Fewest clipped chords (lines) that make a light of :func:`chord_seeds`.
CHORD_LINES = 6
#: Least share of its lines (two per radius) in which a light of :func:`chord_seeds` shows
#: a chord of its own: a light is on in about half of them.
CHORD_SHARE = 0.1
#: Closing along each line that fills holes of up to 2 px in its clipped runs.
_GAP_KERNEL = np.ones((1, 3), np.uint8)
#: How far (px) a chord's end may lie from its light's clipped disc (:func:`_chords_circle`):
#: the ends are whole pixels, on an edge blurred by 0.5 to 2 px.
CHORD_END_PX = 1.5


def _clipped_chords(gray: np.ndarray, axis: str, min_len: float):
    """The clipped runs of each line across the readout (a line exposed at one instant),
    as their lines, middles and half-lengths (pixels, 1-D arrays): the runs of pixels at
    the clipping level or above, those shorter than ``min_len`` or cut by the box's ends
    left out."""
    lines = gray if axis == "rows" else gray.T  # a line per row
    clip = (lines >= CLIP_LEVEL).astype(np.uint8)
    # a clipped disc's line is clipped from rim to rim; a pixel or two under the level inside
    # it is noise, JPEG or a colour mosaic's, not its end: such holes are closed along the line
    clip = cv2.morphologyEx(clip, cv2.MORPH_CLOSE, _GAP_KERNEL).astype(np.int8)
    d = np.diff(np.pad(clip, ((0, 0), (1, 1))), axis=1)
    r, c = np.nonzero(d)  # along a line the changes alternate: up, down, up, ...
    up = d[r, c] > 0
    line, start, end = r[up], c[up], c[~up]  # the run [start, end)
    keep = (end - start >= min_len) & (start > 0) & (end < lines.shape[1])
    line, start, end = line[keep], start[keep], end[keep]
    return line, 0.5 * (start + end - 1), 0.5 * (end - start)


def _chords_circle(line: np.ndarray, half: np.ndarray, step: int) -> tuple[float, float]:
    """Where along the readout a light's chords (their lines and half-lengths, pixels, all
    with their middles at its centre) put its centre, and its clipped disc's radius.

    In a line where the light is fully on, its chord is its clipped disc's: its ends lie on
    the disc's circle, ``half**2 + (line - centre)**2 = radius**2``.  Lines caught on a
    stripe's edge (the light part on) clip a shorter chord, inside it, and a neighbour's
    glow that makes a line clip further does so on one side, off the middle, or now and
    then on both, outside it: so the centre is where most chords' ends lie on one circle,
    within :data:`CHORD_END_PX` (searched every ``step`` lines, then to the line)."""

    def best(centres: np.ndarray) -> tuple[int, float, float]:
        rho = np.sqrt(half[None, :] ** 2 + (line[None, :] - centres[:, None]) ** 2)
        width = 2.0 * CHORD_END_PX
        top = (-1, 0.0, 0.0)
        for shift in (0.0, 0.5 * width):  # two binnings, so that no pile falls on an edge
            bins = np.floor((rho + shift) / width).astype(np.intp)
            counts = np.zeros((len(centres), int(bins.max()) + 1), np.int32)
            np.add.at(counts, (np.arange(len(centres))[:, None], bins), 1)
            k, b = np.unravel_index(int(np.argmax(counts)), counts.shape)
            if counts[k, b] > top[0]:
                top = (int(counts[k, b]), float(centres[k]), (b + 0.5) * width - shift)
        return top

    line = line.astype(np.float64)
    _, centre, _ = best(np.arange(line.min(), line.max() + 1.0, step))
    _, centre, radius = best(np.arange(centre - step, centre + step + 1.0))
    return centre, radius


@path("chords")
def chord_seeds(
    gray: np.ndarray, inside: np.ndarray, axis: str, scale: int, min_radius: float
) -> np.ndarray:
    """The lights of a region whose glows clip together, from the chords their lines clip.

    Each line across the readout is exposed at one instant, when some lights are on and the
    others dark: where a light is on and its neighbours along the line are not, the line's
    clipped run is a chord of its own clipped disc, and whatever the line, that chord's
    middle is the light's centre across the readout.  Glows that clip together into one
    region hide every neck between the lights, not these middles: counted over the region's
    lines, they pile up at each light's centre, one pile per light (a run that joins two
    lights, in lines where both are on, has its middle between them, where it piles up
    less, and its half-length holds their centres).  A pile's lines (those within two
    reduced pixels of its top, which holds :data:`CHORD_LINES` / 2 or more), split where a
    gap wider than their chords' radius separates them (lights one above the other along
    the readout; a dark stripe within a light is narrower), are one light when they are
    :data:`CHORD_LINES` or more and :data:`CHORD_SHARE` of the lines its radius spans: its
    centre and radius those of the circle its chords' ends lie on (:func:`_chords_circle`).
    A light whose circle holds the centre of a smaller one is a run that joined two lights
    (or a duplicate) and is left out, and so is one whose centre lies outside the region.

    Parameters
    ----------
    gray : ndarray of uint8, shape (h * scale, w * scale) (less where the photo ends)
        The photo's gray levels under ``inside``'s box, at full resolution.
    inside : ndarray of uint8, shape (h, w)
        The region (nonzero), in pixels of the photo reduced ``scale`` times.
    axis : {"rows", "columns"}
        The readout axis.
    scale : int
        Full-resolution pixels per reduced pixel.
    min_radius : float
        Smallest radius of a light, reduced pixels.

    Returns
    -------
    ndarray, shape (k, 3)
        ``[x, y, r]`` of each light in ``inside``'s pixels (``r`` its clipped disc's
        radius), the most lines first.
    """
    line, middle, half = _clipped_chords(gray, axis, 2.0 * min_radius * scale)
    none = np.zeros((0, 3))
    if line.size < CHORD_LINES:
        return none
    bins = np.rint(middle / scale).astype(np.intp)
    pile = np.convolve(np.bincount(bins), [0.25, 0.5, 0.25])[1:-1]  # (bins, blurred by one)
    tops = np.flatnonzero(
        (pile >= np.maximum(np.roll(pile, 1), np.roll(pile, -1))) & (pile >= CHORD_LINES / 2)
    )
    found = []
    for top in tops:
        near = np.flatnonzero(np.abs(bins - top) <= 2)
        near = near[np.argsort(line[near], kind="stable")]
        cut = np.flatnonzero(np.diff(line[near]) > np.percentile(half[near], 90)) + 1
        for part in np.split(near, cut):
            r = float(np.percentile(half[part], 90)) if part.size else 0.0
            if part.size >= CHORD_LINES and part.size >= CHORD_SHARE * 2.0 * r:
                along, r = _chords_circle(line[part], half[part], max(1, scale // 3))
                across = float(np.median(middle[part]))
                xy = (across, along) if axis == "rows" else (along, across)
                found.append([*xy, r, part.size])
    if not found:
        return none
    c = np.array(found) / [scale, scale, scale, 1]
    d = np.hypot(c[:, None, 0] - c[None, :, 0], c[:, None, 1] - c[None, :, 1])
    smaller = (c[None, :, 2] < c[:, None, 2]) | (
        (c[None, :, 2] == c[:, None, 2]) & (np.arange(len(c))[None, :] < np.arange(len(c))[:, None])
    )
    holds = (d < c[:, None, 2]) & smaller
    c = c[~holds.any(axis=1)]
    h, w = inside.shape
    ix, iy = np.clip(np.rint(c[:, 0]), 0, w - 1), np.clip(np.rint(c[:, 1]), 0, h - 1)
    c = c[inside[iy.astype(np.intp), ix.astype(np.intp)] > 0]
    return c[np.argsort(-c[:, 3], kind="stable"), :3]
