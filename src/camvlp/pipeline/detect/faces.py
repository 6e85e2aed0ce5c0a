"""Lights' faces in their dark stripes: where glows clip together in the bright stripes, each
lamp's face still shows in the dark ones, at its LED's off level above its glow.

The gray levels are opened along the readout over a window of about six chips
(:func:`dark_level`), the faces are the levels above Otsu's threshold there (:func:`faces`),
and each face is one light (:func:`dark_seeds`; :func:`own_face` for one light's cell).
"""

from __future__ import annotations

import cv2
import numpy as np

from camvlp.pipeline.detect.peaks import distances, lamp_sized, light_seeds, power_cell

__all__ = ["CLIPPED", "dark_level", "dark_seeds", "faces", "own_face"]


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


def dark_seeds(
    dark: np.ndarray, inside: np.ndarray, min_radius: float, reach: float = 0.0
) -> np.ndarray | None:
    """The lights of one lit region from its faces in the dark stripes (:func:`faces`).

    Each face is a disc: its peak of the faces' distance transform
    (:func:`~camvlp.pipeline.detect.peaks.light_seeds`) is its inscribed circle, and its part
    of the faces (its power cell's) covers 0.6 to 1.6 times that circle's area; a region whose
    faces are not all such discs (stripes the window missed, a glow's pieces) gives
    None.  Peaks under half the median's radius are pieces between faces, left out.

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
        ``[x, y, r]`` of each light, as :func:`~camvlp.pipeline.detect.peaks.light_seeds`;
        None when fewer than two.
    """
    face = faces(dark, inside, reach)
    if face is None:
        return None
    seeds = light_seeds(face, min_radius)
    if len(seeds) < 2:
        return None
    seeds = lamp_sized(seeds)
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
        The light's cell (:func:`~camvlp.pipeline.detect.peaks.power_cell`).
    axis : {"rows", "columns"}
        The readout axis.
    seed : ndarray, shape (3,)
        The light's ``[x, y, r]`` in the region
        (:func:`~camvlp.pipeline.detect.peaks.light_seeds`, full resolution).

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
    dist = distances(face)
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
