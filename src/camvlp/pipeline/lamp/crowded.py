"""Glowing lights whose glows joined: each centred on what its neighbours' looks leave.

The photo is the sum of its lights' looks through the sensor's clipping: each light shines
``g_i(rho_i) * s_i(line)`` (its radially symmetric shape, disc and glow, times its own
stripes, :mod:`camvlp.pipeline.lamp.light_wave`), so where two glows overlap a pixel holds
``A + g_i s_i + g_j s_j``.  A light fitted alone within its own cell of the joined region
(:func:`camvlp.pipeline.lamp.glow.centred_on_glow`) explains its neighbour's glow in its lines
with its own shape, and since its stripes are free per line, a neighbour's glow in a line
where the light itself is dark pulls its centre along the readout (10 to 26 px on the stress
benchmark's crowded photos).  Here the lights' looks are fitted together, by blocks: each
light in turn is fitted (its shape, stripes and centre, :func:`radial_fit`) over its region
grown beyond its box, to the photo less its neighbours' fitted looks, with their discs (where
a fitted look is least sure: hot cores, clipping) and the clipped pixels left out, and so
round after round (:data:`ROUNDS`).  A light only adds to the others, so a neighbour's look
takes away at most what a pixel shows above the background: a look is fitted on the pixels
that do not clip, and in the lines where a light clipped those are its glow's tail, whose
level, told by a few dim pixels, can rise far beyond what the pixels nearer the light show.
(Where a fitted look dips under the background, it is taken away as fitted: a bound at zero
too moved two crowded phone photos of the stress benchmark further, 1.6 -> 4.0 and 51.8 ->
86 mm.)
The first rounds search each centre widely on all its pixels, along the readout first
(:func:`radial_fit`'s ``wide``), and fit the looks on every k-th pixel; the last one also
refines the centre on the pixels that tell it best.  Nothing
is assumed of the glow's profile: each light's shape is the one its own pixels give.  A light
whose joint centre is drawn away from its own clipped pixels keeps its centre alone
(:func:`_held_by_clipped`).

A light whose disc's rim shows clean (:func:`~camvlp.pipeline.lamp.rim.rim_from_chords`:
each line's chord at a share of its own peak, whatever its stripes) is kept within a pixel
of its rim's centre: the sum of looks holds for levels that are light, and a phone's tone
curve, which a camera file may not give, bends it (lamps 10 to 67 px off through such a
curve, where their rims put them within 0.3 px).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from camvlp.imaging.gray import to_gray
from camvlp.imaging.levels import CLIP_LEVEL as _CLIP
from camvlp.pipeline.detect.blob import Blob
from camvlp.pipeline.detect.disc import light_support
from camvlp.pipeline.lamp.radial import RadialFit, radial_fit, radial_model
from camvlp.pipeline.lamp.rim import boxes_overlap, on_rim, paste_mask, rim_from_chords
from camvlp.pipeline.paths import path

__all__ = ["Fitted", "centred_jointly"]

#: Rounds of the block fit (each light refitted once a round).
ROUNDS = 3
#: How far a light's region is grown beyond its box for the joint fit, as a share of the
#: box's smaller side each way: its cell of the joined region may cut its own disc.
GROW = 0.25
#: A neighbour's disc left out of a light's fit, in radii of its fitted rim.
DISC = 1.15
#: How far a light's centre may lie from its clipped pixels' centre whatever its own centre
#: did, in radii of a disc of their area: their centre's own spread (it was 0.1 to 2.2 px
#: from the true centre on discs of 23 to 60 px radius, up to 4 %, with the stripes cutting
#: the disc's ends and neighbours' glows in its cell).
CLIPPED_SLACK = 0.1


@dataclasses.dataclass(frozen=True)
class Fitted:
    """A light's radial fit and the region (``(x0, y0, x1, y1)``, photo pixels) it was
    fitted in."""

    fit: RadialFit
    box: tuple[int, int, int, int]


def _grown(box, shape) -> tuple[int, int, int, int]:
    """``box`` grown by :data:`GROW` of its smaller side each way, within a photo of
    ``shape`` (h, w, ...)."""
    x0, y0, x1, y1 = box
    m = int(GROW * min(x1 - x0, y1 - y0))
    return max(x0 - m, 0), max(y0 - m, 0), min(x1 + m, shape[1]), min(y1 + m, shape[0])


def centred_jointly(
    img: np.ndarray, blobs: list[Blob], axis: str, glows: np.ndarray, rims: dict | None = None
) -> list[Blob]:
    """The blobs, each glowing light whose region meets another glowing light's, where
    glows joined, centred on its own look, fitted jointly with theirs.

    A light is refitted when its grown region overlaps another glowing light's, and it or
    one of those has a cell of a joined region (:attr:`Blob.cell`; a light whose region
    stayed apart is centred on its own, within the cell :func:`centred_on_glow` gives it),
    unless it was found by its face in the dark stripes (:attr:`Blob.face`): there glows
    clip together in the bright stripes, and what those leave unclipped tells little of the
    shape, the face more.  A neighbour found by its face keeps its centre; its look is
    fitted there (not searched for) and taken away from the light's pixels like the
    others': its glow carries its own code's stripes, which no look of the light explains
    (fitted alone beside such a neighbour, a lamp of a stress photo came out 21 px off, and
    0.8 px with the neighbour's look taken away).  A light whose rim shows clean
    (:func:`rim_from_chords`) keeps within
    :data:`~camvlp.pipeline.lamp.rim.RIM_AGREE_PX` of it (:func:`on_rim`): a centre
    further off is moved to the rim's, a refit further off is not taken (its look is
    refitted at the centre it has).

    Parameters
    ----------
    img : ndarray, shape (H, W, 3) or (H, W)
        The photo.
    blobs : list of Blob
        The lights, the glowing ones centred each on its own (:func:`centred_on_glow`).
    axis : {"rows", "columns"}
        The readout axis.
    glows : ndarray of bool, shape (len(blobs),)
        The glowing lights.
    rims : dict, optional
        Lights' rims already found (:func:`rim_from_chords` of these ``blobs``, None for one
        that does not show), by index: not looked for again.

    Returns
    -------
    list of Blob
        The blobs; a light refitted has its new ``pixel`` (all else as given).
    """
    blobs = list(blobs)
    grown = [_grown(b.box, img.shape) for b in blobs]
    near = [
        [j for j in np.flatnonzero(glows) if j != k and boxes_overlap(grown[k], grown[j])]
        for k in range(len(blobs))
    ]
    joined = [
        blobs[k].cell is not None or any(blobs[j].cell is not None for j in near[k])
        for k in range(len(blobs))
    ]
    crowded = [k for k in np.flatnonzero(glows) if near[k] and joined[k] and not blobs[k].face]
    if not crowded:
        return blobs
    small = to_gray(img[::4, ::4])
    background = float(np.percentile(small, 5))
    known = rims or {}
    rims = {k: known[k] if k in known else rim_from_chords(img, blobs, k, axis) for k in crowded}
    for k in crowded:  # a clean rim says where the light is
        if not on_rim(blobs[k].pixel, rims[k]):
            blobs[k] = dataclasses.replace(blobs[k], pixel=rims[k][0])
    fits: list[Fitted | None] = [None] * len(blobs)
    faced = sorted({j for k in crowded for j in near[k] if blobs[j].face})
    for k in faced + crowded:  # each one's look where it was centred (alone, by its rim or face)
        refit = _refitted(img, blobs, fits, k, axis, background, search=False)
        fits[k] = None if refit is None else refit[1]
    alone = list(blobs)
    for r in range(ROUNDS):
        for k in crowded:
            last = r == ROUNDS - 1
            refit = _refitted(img, blobs, fits, k, axis, background, local=last)
            if refit is not None and not on_rim(refit[0].pixel, rims[k]):  # ran off: its look
                refit = _refitted(img, blobs, fits, k, axis, background, search=False)
            if refit is not None:
                blobs[k], fits[k] = refit
    for k in crowded:  # a centre drawn away from the light's own clipped disc ran off
        if not _held_by_clipped(img, blobs[k], alone[k].pixel):
            blobs[k] = alone[k]
    return blobs


def _held_by_clipped(img: np.ndarray, b: Blob, before: np.ndarray) -> bool:
    """Whether the light's centre ``b.pixel`` (photo pixels) is no farther from the centre
    of its own clipped pixels (those of its region within :attr:`Blob.mask`) than the
    centre ``before`` it had alone, or than :data:`CLIPPED_SLACK` of their radius; True
    when it clips nowhere.

    A light bright enough to clip does so on its disc (and on the glow right around it):
    its clipped pixels are its own (a neighbour's disc is in the neighbour's cell), and
    they lie about its centre, which no neighbour's look takes part in.  The joint fit
    explains the pixels that do not clip, where a neighbour's look that is off (a glow
    that rises again far out, a disc that the look leaves dark) can draw a centre along
    its lines, off its disc (27 px on a stress photo whose clipped disc's centre is 0.3 px
    from the lamp's)."""
    x0, y0, x1, y1 = b.box
    ys, xs = np.nonzero((to_gray(img[y0:y1, x0:x1]) >= _CLIP) & b.mask)
    if not ys.size:
        return True
    centre = np.array([xs.mean() + x0, ys.mean() + y0])
    slack = CLIPPED_SLACK * np.sqrt(ys.size / np.pi)
    return np.hypot(*(b.pixel - centre)) <= max(np.hypot(*(before - centre)), slack)


@path("joint fit")
def _refitted(
    img: np.ndarray,
    blobs: list[Blob],
    fits: list[Fitted | None],
    k: int,
    axis: str,
    background: float,
    search: bool = True,
    local: bool = False,
) -> tuple[Blob, Fitted] | None:
    """Light ``k`` fitted over its grown region to the photo less its neighbours' looks
    (their discs and the clipped pixels left out); None when the fit fails or its centre
    leaves the light's disc.  Without ``search``, its look at its centre as given; else its
    centre searched for widely, then (``local``) refined (:func:`radial_fit`)."""
    b = blobs[k]
    x0, y0, x1, y1 = box = _grown(b.box, img.shape)
    gray = to_gray(img[y0:y1, x0:x1]).astype(np.float64)
    clipped = gray >= _CLIP
    out = np.zeros(gray.shape, dtype=bool)  # neighbours' discs
    for j, o in enumerate(blobs):
        if j == k or not boxes_overlap(box, o.box if fits[j] is None else fits[j].box):
            continue
        paste_mask(out, o.mask, o.box, box)
        f = fits[j]
        if f is None or f.fit.model is None:  # no look to take away
            continue
        fx0, fy0, fx1, fy1 = f.box
        ox0, oy0, ox1, oy1 = max(x0, fx0), max(y0, fy0), min(x1, fx1), min(y1, fy1)
        if ox0 >= ox1 or oy0 >= oy1:
            continue
        ys, xs = np.mgrid[oy0:oy1, ox0:ox1].astype(np.float64)
        level, rho = radial_model(f.fit.model, xs - fx0, ys - fy0, axis)
        part = gray[oy0 - y0 : oy1 - y0, ox0 - x0 : ox1 - x0]
        # a light adds to what the others show: its look is at most what is left above the
        # background (a look fitted on lines it barely crosses may rise far beyond)
        part -= np.minimum(level, np.maximum(part - background, 0.0))
        rim = f.fit.model.rim
        if np.isfinite(rim):
            out[oy0 - y0 : oy1 - y0, ox0 - x0 : ox1 - x0] |= rho < DISC * rim
    mask = np.zeros(gray.shape, dtype=bool)
    paste_mask(mask, b.mask, b.box, box, grow=False)
    out &= ~mask
    if not mask.any():
        return None
    kept = ~out & ~clipped
    shown = np.where(clipped, 255.0, np.where(out, background, gray))  # for the support only
    support = light_support(shown, mask, axis) & ~out
    r = np.full(2, float(np.min(b.axes_px))) if b.touches_border else b.axes_px
    ellipse = ((b.pixel[0] - x0, b.pixel[1] - y0), tuple(float(v) for v in r), b.angle_deg)
    fit = radial_fit(
        np.where(kept, gray, np.nan),
        support,
        ellipse,
        axis,
        wide=True,
        local=local,
        background=background,
        search=search,
    )
    c = fit.centre
    if fit.model is None or not np.all(np.isfinite(c)):
        return None
    cx, cy = int(c[0] + x0 + 0.5) - b.box[0], int(c[1] + y0 + 0.5) - b.box[1]
    h, w = b.mask.shape
    if not (0 <= cx < w and 0 <= cy < h and b.mask[cy, cx]):  # drawn off its disc: failed
        return None
    pixel = c + np.array([x0, y0], dtype=float)
    return dataclasses.replace(b, pixel=pixel), Fitted(fit, box)
