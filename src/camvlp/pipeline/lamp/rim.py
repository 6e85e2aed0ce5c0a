"""A light's disc's rim from the chords each line of it shows: where the light is, whatever
its stripes, its glow or a tone curve.

Every line along the readout is exposed at the same instants, so along one line a light is its
radial shape times one level: the chords its lines leave bright end on its disc's rim, and
their ends lie on an ellipse about its centre (:func:`rim_from_chords`).  A crowded glowing
lamp is kept within :data:`RIM_AGREE_PX` of a rim that shows clean
(:func:`camvlp.pipeline.lamp.crowded.centred_jointly`, :func:`on_rim`), and a lamp not
centred on its glow is moved to it (:func:`camvlp.pipeline.lamp.glow.centred_on_glow`).
"""

from __future__ import annotations

import cv2
import numpy as np

from camvlp.geometry.disc import sampson_distances
from camvlp.imaging.gray import to_gray
from camvlp.imaging.levels import CLIP_LEVEL as _CLIP
from camvlp.pipeline.detect.blob import Blob
from camvlp.pipeline.paths import path

__all__ = ["boxes_overlap", "on_rim", "paste_mask", "rim_from_chords"]

#: Where a line's chord of a light's disc ends: this share of the line's peak (or the
#: clipping level, where the line clips), on the disc's blurred edge, above its glow.
RIM_SHARE = 0.85
#: A chord's end moves out to a steeper fall beyond it where the level falls there by this
#: share of itself or more within :data:`RIM_DROP_PX` pixels: a disc's edge to a dark
#: ceiling (a hot core's flanks and a glow fall by a few percent a pixel).
RIM_DROP = 0.5
RIM_DROP_PX = 3
#: ...from a level of at least this share of the line's peak: a disc beside a hot core up to
#: twice as bright in its line (its moved ends: 0.33 and up at the 5th percentile on the
#: sites benchmark's dim lamps), not a glow's outer edge that a phone's black point cuts
#: (0.11 to 0.31 of the peak, on a stress photo whose glows fill the lamps' outlines).
RIM_FLOOR = 0.33
#: Fewest lines whose chords make a rim.
RIM_LINES = 6
#: A chord's end further than this (px) from the rim's ellipse is off it: the ellipse is
#: the one through five ends that most ends lie within half of this of, fitted again to
#: those without the ends this far off (at most :data:`RIM_TRIMS` times), and at least
#: :data:`RIM_KEPT` of all the ends must lie within it.  Neighbours' glows through a phone's
#: tone curve put up to a third of a lamp's ends off (on a crowded phone photo of 15 lamps,
#: each rim then within 0.5 px of its lamp's centre).
RIM_OUT_PX = 3.0
RIM_KEPT = 2.0 / 3.0
#: ... and at least this share of the ends on each side within half of :data:`RIM_OUT_PX`:
#: a glow that carries off the ends of most lines on one side can bend an ellipse through
#: some of them (57 % of each side or more within it on the lamps of crowded phone photos).
RIM_SIDE = 0.5
#: Narrowest rim, its smaller semi-axis over its larger: a disc seen 75 degrees off its axis
#: (a lamp that far off the view is a sliver whose stripes no decoder reads).
RIM_ASPECT = 0.25
#: Most fits of a rim's ellipse, each without the ends off the last: a rim still losing
#: ends after these is no clean rim.
RIM_TRIMS = 6
#: Root-mean-square distance (px) of a clean rim's chord ends from their ellipse: the ends
#: are whole pixels (a uniform error of 1 px has an RMS of 0.29 px), where a blurred edge
#: (0.5 to 2 px), noise, JPEG and a phone's sharpening cross the line's share: 0.5 to 1.2 px
#: on clean rims, rendered plain or through a phone's processing.
RIM_RMS_PX = 1.5
#: How near a light's centre must lie to its clean rim's (px): a rim's centre is within
#: 0.3 px on the stress photos, and a fit of the light's shape is kept where it agrees (it
#: is the finer, 0.08 against 0.11 px at the median on the glowing lamps of
#: ``stress_centres.py --seed 3``), the rim's taken where it does not.
RIM_AGREE_PX = 1.0


def boxes_overlap(a, b) -> bool:
    """Whether two boxes ``(x0, y0, x1, y1)`` overlap."""
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def paste_mask(dst: np.ndarray, src: np.ndarray, src_box, dst_box, grow: bool = True) -> None:
    """``dst`` (bool, ``dst_box``'s shape) |= ``src`` (bool, ``src_box``'s) where the two
    boxes ``(x0, y0, x1, y1)`` overlap, dilated by 2 px (the disc's blur) when ``grow``."""
    x0, y0 = max(src_box[0], dst_box[0]), max(src_box[1], dst_box[1])
    x1, y1 = min(src_box[2], dst_box[2]), min(src_box[3], dst_box[3])
    if x0 >= x1 or y0 >= y1:
        return
    part = src[y0 - src_box[1] : y1 - src_box[1], x0 - src_box[0] : x1 - src_box[0]]
    if grow:
        part = cv2.dilate(part.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    dst[y0 - dst_box[1] : y1 - dst_box[1], x0 - dst_box[0] : x1 - dst_box[0]] |= part


def on_rim(pixel: np.ndarray, rim) -> bool:
    """Whether a centre lies within :data:`RIM_AGREE_PX` of a clean rim's centre (True when
    there is no clean rim: ``rim`` None)."""
    return rim is None or bool(np.hypot(*(np.asarray(pixel) - rim[0])) <= RIM_AGREE_PX)


@path("rim from chords")
def rim_from_chords(img: np.ndarray, blobs: list[Blob], k: int, axis: str):
    """The centre and radius of light ``k``'s disc from its rim, where each line shows it:
    None when the rim does not show as a clean ellipse.

    Every line along the readout is exposed at the same instants, so along one line the
    light is its radial shape times one level: in each line its stripes leave bright, the
    pixels at :data:`RIM_SHARE` of the line's own peak or more are one chord of its disc
    (or of its hot core), whatever the stripes, since the glow stays under the disc's
    level; where the disc clips, the chord is its clipped part, or more where the glow
    clips too, still concentric.  A hot core off the centre would give chords of the core
    (their ellipse 11 to 21 px off on the sites benchmark's dim lamps): where the level
    falls by half or more (:data:`RIM_DROP`) beyond a chord's end, the disc's edge to a
    dark ceiling, the end is that fall's (:func:`_edges_beyond`).  The chords' ends, two
    per line, lie on an ellipse about the light's centre: they fix it along the readout by
    how their lengths change from line to line, and across it by their middles.  Ends that
    a neighbour's glow (in lines where the light itself is dark) or a cell's edge put off
    the ellipse are left out of its fit: it is the ellipse most ends lie on
    (:func:`_trimmed_ellipse`); when more than a third of the ends, or half of one side's,
    are off it, or those on it lie further from it than :data:`RIM_RMS_PX`
    (root-mean-square), the rim says nothing.
    Only the chord through the light's centre counts in each line, and an end that is an
    edge of the light's own pixels (its region's, its cell's, a neighbour's mask) is a cut,
    not the rim, and is left out.

    Parameters
    ----------
    img : ndarray, shape (H, W, 3) or (H, W)
        The photo.
    blobs : list of Blob
        The lights; ``k``'s own pixels are those of its mask (its cell of a joined region)
        outside the others' masks (grown by the blur).
    k : int
        The light.
    axis : {"rows", "columns"}
        The readout axis (the lines are rows, or columns).

    Returns
    -------
    tuple of (ndarray, shape (2,), float) or None
        The rim's centre (photo pixels) and the mean of its semi-axes (px).
    """
    b = blobs[k]
    x0, y0, x1, y1 = b.box
    gray = to_gray(img[y0:y1, x0:x1]).astype(np.float32)
    others = np.zeros(gray.shape, dtype=bool)
    for j, o in enumerate(blobs):
        if j != k and boxes_overlap(b.box, o.box):
            paste_mask(others, o.mask, o.box, b.box)
    own = ~others if b.cell is None else b.cell & ~others
    lines, own = (gray, own) if axis == "rows" else (gray.T, own.T)  # a line per row
    lines = np.where(own, lines, 0.0)
    c = int(np.round(b.pixel[0] - x0 if axis == "rows" else b.pixel[1] - y0))
    if not 0 < c < lines.shape[1] - 1:
        return None
    peak = lines.max(axis=1)
    bright = peak >= RIM_SHARE * peak.max()  # the lines the stripes leave bright
    chord = lines >= np.minimum(RIM_SHARE * peak, _CLIP)[:, None]
    shown = np.flatnonzero(bright & chord[:, c])  # the lines whose chord holds the centre
    if shown.size < RIM_LINES:
        return None
    # each line's chord through the centre: its ends where the level first falls below the
    # line's share, on each side, or further out where it then falls by half or more (a
    # disc's edge beyond its hot core's flank); an end that is the region's edge, a
    # neighbour's or a cell's, is a cut, not the rim
    n = lines.shape[1]
    left = c - np.argmin(chord[shown, c::-1], axis=1)  # first below, leftwards
    right = c + np.argmin(chord[shown, c:], axis=1)
    left = np.where(left == c, -1, left)  # (chord[:, c] holds: no fall, it runs off the edge)
    right = np.where(right == c, n, right)
    left, right = _edges_beyond(lines[shown], own[shown], left, right)
    ok_l = (left >= 0) & own[shown, np.clip(left, 0, n - 1)]
    ok_r = (right < n) & own[shown, np.clip(right, 0, n - 1)]
    ends = np.concatenate(
        [
            np.stack([left[ok_l] + 0.5, shown[ok_l]], axis=1),
            np.stack([right[ok_r] - 0.5, shown[ok_r]], axis=1),
        ]
    ).astype(np.float64)
    if ends.shape[0] < 2 * RIM_LINES:
        return None
    got = _trimmed_ellipse(ends, ok_l.sum())
    if got is None:
        return None
    fit, d = got
    if not np.sqrt(np.mean(np.square(d))) <= RIM_RMS_PX:
        return None
    cu, cv, a, b_ = fit[:4]
    centre = np.array([cu, cv] if axis == "rows" else [cv, cu]) + np.array([x0, y0], float)
    return centre, 0.5 * (a + b_)


def _edges_beyond(lines: np.ndarray, own: np.ndarray, left: np.ndarray, right: np.ndarray):
    """Each line's chord ends moved out to the steepest fall beyond them, within the line's
    own pixels, where the level falls there by :data:`RIM_DROP` or more over
    :data:`RIM_DROP_PX` pixels from :data:`RIM_FLOOR` of the line's peak or more; else as
    they were.

    ``lines`` (m, n) are the lines' levels, ``own`` (m, n) their light's own pixels, and
    ``left``, ``right`` (m,) the pixel beyond each chord's end (-1 or ``n``: none); returns
    the new ``left`` and ``right``."""
    n = lines.shape[1]
    x = np.arange(n - 1)
    rise = np.diff(lines, axis=1)  # (level[x + 1] - level[x]: a fall between them)
    # (the pairs of pixels beyond each end up to the first pixel that is not the line's own)
    idx = np.arange(n)[None, :]
    cut_l = np.max(np.where(~own & (idx < left[:, None]), idx, -1), axis=1)
    cut_r = np.min(np.where(~own & (idx > right[:, None]), idx, n), axis=1)
    stop_l = (x[None, :] > cut_l[:, None]) & (x[None, :] < left[:, None])
    stop_r = (x[None, :] >= right[:, None]) & (x[None, :] < cut_r[:, None] - 1)
    at = np.arange(lines.shape[0])
    # the steepest fall each way, the nearest to the chord of equally steep ones (the levels
    # are whole gray levels: ties are common, and either side's choice moves the centre)
    new_l = (n - 2) - np.argmax(np.where(stop_l, rise, -np.inf)[:, ::-1], axis=1)  # (leftwards)
    new_r = 1 + np.argmin(np.where(stop_r, rise, np.inf), axis=1)
    out_l = np.clip(new_l - RIM_DROP_PX + 1, 0, n - 1)  # (the level RIM_DROP_PX out)
    out_r = np.clip(new_r + RIM_DROP_PX - 1, 0, n - 1)
    inner_l = lines[at, np.clip(new_l + 1, 0, n - 1)]
    inner_r = lines[at, np.clip(new_r - 1, 0, n - 1)]
    floor = RIM_FLOOR * lines.max(axis=1)
    drop_l = (lines[at, out_l] <= (1 - RIM_DROP) * inner_l) & (inner_l >= floor)
    drop_r = (lines[at, out_r] <= (1 - RIM_DROP) * inner_r) & (inner_r >= floor)
    take_l = stop_l.any(axis=1) & (left >= 0) & drop_l & (out_l > cut_l)
    take_r = stop_r.any(axis=1) & (right < n) & drop_r & (out_r < cut_r)
    return np.where(take_l, new_l, left), np.where(take_r, new_r, right)


def _trimmed_ellipse(ends: np.ndarray, n_left: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The ellipse of a rim's chord ends (M, 2), its left ends first (``n_left`` of them):
    the ellipse through five of them that most ends lie within half of :data:`RIM_OUT_PX`
    of (:func:`_consensus`), fitted again to those, then again without the ends
    :data:`RIM_OUT_PX` or more off it until none is.  Returns (the ellipse as
    :func:`_ellipse` gives it, the Sampson distances of all the ends within
    :data:`RIM_OUT_PX` of it), or None when fewer than :data:`RIM_KEPT` of the ends, or
    fewer than :data:`RIM_SIDE` of one side's within half as far, or fewer than
    :data:`RIM_LINES` on either side, are within it (a neighbour's glow, a ring: the rim
    does not show), or when its centre lies outside the box of those ends or a semi-axis
    is longer than the box's diagonal, or it is narrower than :data:`RIM_ASPECT` (chords of
    a pixel or two, whose ends lie on two lines: a long thin ellipse passes through them).
    Ends are only ever left out of the fit, never taken back: an end a glow carried a few
    pixels off, taken back, draws the ellipse toward the others."""
    fitted = _consensus(ends)
    for _ in range(RIM_TRIMS):
        if fitted.sum() < 2 * RIM_LINES:  # (fewer than the ends of a rim: none to fit)
            return None
        fit = _ellipse(ends[fitted])
        if fit is None:
            return None
        d = sampson_distances(fit[None], ends[None, :, 0], ends[None, :, 1])[0][0]
        near = np.abs(d) <= RIM_OUT_PX
        if near[fitted].all():
            break
        fitted &= near
    else:
        return None  # (still changing: no clean rim)
    close = np.abs(d) <= 0.5 * RIM_OUT_PX
    sides = (slice(None, n_left), slice(n_left, None))
    if min(near[s].sum() for s in sides) < RIM_LINES:  # (first: then no side is empty)
        return None
    if near.mean() < RIM_KEPT or min(close[s].mean() for s in sides) < RIM_SIDE:
        return None
    low, high = ends[near].min(axis=0), ends[near].max(axis=0)
    if not (np.all(fit[:2] > low) and np.all(fit[:2] < high)):
        return None  # (its centre outside its ends: ends on a line or two, not a rim)
    if max(fit[2], fit[3]) > float(np.hypot(*(high - low))):
        return None
    if min(fit[2], fit[3]) < RIM_ASPECT * max(fit[2], fit[3]):
        return None  # (no disc's outline: one seen this far off its axis is not read)
    return fit, d[near]


#: Ellipses through five chord ends tried by :func:`_consensus` (a fixed draw: the same
#: ends, the same rim).  With four ends in ten off the rim, five clean ends come up in
#: 7.8 % of the draws: 200 draws miss them once in 10^7.
RIM_DRAWS = 200


def _consensus(ends: np.ndarray) -> np.ndarray:
    """The ends (M, 2) within half of :data:`RIM_OUT_PX` of the ellipse through five of
    them that the most lie within (RANSAC; first-order geometric distances to each conic,
    of :data:`RIM_DRAWS` fixed draws of five; conics that are no ellipse left out), as a
    mask; all False when there are fewer than five ends."""
    m = ends.shape[0]
    out = np.zeros(m, bool)
    if m < 5:
        return out
    rng = np.random.default_rng(0)
    pick = np.argsort(rng.uniform(size=(RIM_DRAWS, m)), axis=1)[:, :5]
    centre, scale = ends.mean(axis=0), max(float(ends.std()), 1e-9)
    x, y = ((ends - centre) / scale).T  # (conditioned)
    rows = np.stack([x * x, x * y, y * y, x, y, np.ones(m)], axis=1)  # (M, 6)
    conic = np.linalg.svd(rows[pick])[2][:, -1]  # (D, 6): each draw's conic, its null vector
    a, b, c = conic[:, 0], conic[:, 1], conic[:, 2]
    value = conic @ rows.T  # (D, M)
    gx = 2 * a[:, None] * x + b[:, None] * y + conic[:, 3:4]
    gy = b[:, None] * x + 2 * c[:, None] * y + conic[:, 4:5]
    dist = scale * np.abs(value) / np.maximum(np.hypot(gx, gy), 1e-12)
    within = (dist <= 0.5 * RIM_OUT_PX) & (b * b < 4 * a * c)[:, None]
    return within[int(np.argmax(within.sum(axis=1)))]


def _ellipse(points: np.ndarray) -> np.ndarray | None:
    """:func:`cv2.fitEllipse` of ``points`` (M, 2) as (centre, semi-axes, angle in radians),
    shape (5,); None when degenerate."""
    (cu, cv), (w, h), angle = cv2.fitEllipse(points.astype(np.float32))
    p = np.array([cu, cv, 0.5 * w, 0.5 * h, np.radians(angle)])
    return p if np.all(np.isfinite(p)) and min(w, h) > 0 else None
