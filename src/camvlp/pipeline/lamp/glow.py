"""Lights that glow: centred on their radial shape, not on their bright outline.

A real lamp often glows around its disc (light scattered in the diffuser or the lens), and the
glow blinks with the LED.  In the bright stripes it lifts the disc's outline far out (it may
clip there too), in the dark ones not at all, so an ellipse fitted to the outline is pulled
about: 0.2 to 1.2 px from the disc's centre (median; up to 1.9 px) on 1080p renders, where a
plain disc's is 0.02 px.  The light's shape, glow included, is radially symmetric about its
centre, so a glowing light is centred on its radial shape instead
(:func:`camvlp.pipeline.lamp.radial.radial_centre`, which separates the shape from the stripes
over the light's whole striped area, on the pixels that tell the centre; the square wave is
not fitted).  That costs 85 to 125 ms per glowing light on 1080p renders (one core; discs
of 105 px, halo 0.4); a light
without a glow (its ring beyond the outline at the background) is left as detected, at the
cost of some 250 pixels sampled (:func:`glow_levels`).  :func:`camvlp.locate` tells and
centres every light of a photo (a light whose glow the photo's border cuts too, fitted to
the pixels in the photo, and used when its disc's rim lies within the photo; lights whose
glows joined fitted together, :mod:`camvlp.pipeline.lamp.crowded`);
:class:`camvlp.pipeline.track.tracker.Tracker` runs the same stages on every frame, a light
the border cuts told by its fixture's glow as an earlier frame showed it whole.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from camvlp.imaging.gray import to_gray
from camvlp.pipeline.detect.blob import Blob
from camvlp.pipeline.detect.disc import light_support
from camvlp.pipeline.detect.peaks import power_cell
from camvlp.pipeline.lamp.crowded import centred_jointly
from camvlp.pipeline.lamp.radial import radial_fit
from camvlp.pipeline.lamp.rim import boxes_overlap, on_rim, rim_from_chords

__all__ = ["centred_on_glow", "glow_level", "glow_levels", "glowing"]

#: Glow level (see :func:`glow_level`) from which a light counts as glowing.
GLOW_LEVEL = 0.02
#: How far within the photo a glowing light's disc (its fitted rim) must lie for a light
#: whose glow the border cuts to be used, pixels: its rim is found to the pixel (the fall over
#: two bins of half a pixel).
RIM_MARGIN_PX = 1.0


#: Where :func:`glow_level` samples a light, in radii of its outline ellipse: inside, the
#: ring just beyond (past a plain disc's blur), and the background further out.
_RADII = np.array([0.3, 0.5, 0.7, 1.15, 1.25, 1.35, 1.7, 1.9])[:, None]
_IN, _RING, _OUT = slice(0, 3), slice(3, 6), slice(6, 8)
_ANGLES = np.linspace(0.0, 2.0 * np.pi, 32, endpoint=False)
_COS, _SIN = np.cos(_ANGLES), np.sin(_ANGLES)
_LUMA = np.array([0.114, 0.587, 0.299])  # B, G, R


def glow_levels(img: np.ndarray, blobs) -> np.ndarray:
    """How much each light glows beyond its outline, as a fraction of its level.

    The photo is sampled along 32 directions from each outline ellipse's centre: within it
    (0.3 to 0.7 of its radii), in the ring just beyond it (1.15 to 1.35 radii) and further
    out (1.7 and 1.9 radii: the background, their median).  The ring's mean (its brightest
    tenth left out) above the background, over the inside's, is about 0 for a plain disc,
    blurred or not (its blur ends within the ring's inner edge), and a few per cent or more
    for a glow.

    Parameters
    ----------
    img : ndarray, shape (H, W, 3) or (H, W)
        The photo.
    blobs : sequence of Blob
        The detected lights (their centres, axes and angles).

    Returns
    -------
    ndarray, shape (len(blobs),)
        The levels; NaN where too few samples fall in the photo to tell.
    """
    if not len(blobs):
        return np.zeros(0)
    h, w = img.shape[:2]
    centre = np.array([b.pixel for b in blobs], dtype=np.float64)  # (n, 2)
    semi = 0.5 * np.maximum(np.array([b.axes_px for b in blobs], dtype=np.float64), 1.0)
    t = np.deg2rad(np.array([float(b.major_angle) for b in blobs]))
    ct, st = np.cos(t), np.sin(t)
    # x and y as one array (n, 2, radii, angles): the centre plus each radius times
    # (a cos t cos - b sin t sin, a sin t cos + b cos t sin)
    on_cos = np.stack([semi[:, 0] * ct, semi[:, 0] * st], axis=1)  # (n, 2)
    on_sin = np.stack([-(semi[:, 1] * st), semi[:, 1] * ct], axis=1)
    xy = centre[:, :, None, None] + _RADII * (
        on_cos[:, :, None, None] * _COS + on_sin[:, :, None, None] * _SIN
    )
    ok = ((xy > -0.5) & (xy < _column(w - 0.5, h - 0.5))).all(axis=1)
    xi, yi = (
        np.clip(np.rint(xy), 0.0, _column(w - 1.0, h - 1.0)).astype(np.intp).transpose(1, 0, 2, 3)
    )
    px = img[yi, xi].astype(np.float64)
    if px.ndim == 4:  # BGR(A): OpenCV's luma weights
        px = px[..., :3] @ _LUMA
    # samples within the photo, per light: inside, in the ring, and further out
    per_radius = ok.sum(axis=2)  # (n, radii)
    n_in, n_ring, n_out = (per_radius[:, part].sum(axis=1) for part in (_IN, _RING, _OUT))
    inside = np.where(ok[:, _IN], px[:, _IN], 0.0).sum(axis=(1, 2)) / np.maximum(n_in, 1)
    # (a new array: the ring's and the background's samples are sorted in place below, each
    # light's a view of its own contiguous values)
    px = np.where(ok, px, np.nan)
    # the ring's mean without its brightest tenth: a glow lifts the whole ring, while an
    # outline that misses the disc somewhere puts a few ring samples on the disc itself
    ranked = px[:, _RING].reshape(len(blobs), -1)
    ranked.sort(axis=1)  # NaNs last
    n_kept = n_ring - n_ring // 10  # (at most the ring's 96 samples)
    kept = np.arange(ranked.shape[1]) < n_kept[:, None]
    ring = np.where(kept, ranked, 0.0).sum(axis=1) / np.maximum(n_kept, 1)
    out = px[:, _OUT].reshape(len(blobs), -1)
    out.sort(axis=1)  # NaNs last
    background = out[np.arange(len(blobs)), np.maximum(n_out - 1, 0) // 2]
    level = (ring - background) / np.maximum(inside - background, 1.0)
    return np.where((n_ring >= 16) & (n_out >= 16) & (n_in > 0), level, np.nan)


def _column(x: float, y: float) -> np.ndarray:
    """``[x, y]`` as a column (2, 1, 1), against the samples' x and y (n, 2, radii, angles)."""
    return np.array([x, y])[:, None, None]


def glow_level(img: np.ndarray, blob: Blob) -> float:
    """:func:`glow_levels` of one light."""
    return float(glow_levels(img, [blob])[0])


def glowing(img: np.ndarray, blobs) -> tuple[np.ndarray, np.ndarray]:
    """Which lights glow (:func:`glow_levels` at least :data:`GLOW_LEVEL`), and which were
    told surely.

    Parameters
    ----------
    img : ndarray, shape (H, W, 3) or (H, W)
        The photo.
    blobs : sequence of Blob
        The detected lights.

    Returns
    -------
    glows : ndarray of bool, shape (len(blobs),)
        The lights that glow, as :func:`centred_on_glow` tells them by itself: a light
        touching the photo's border measured on a round outline (see :func:`_round`); never
        one whose ring or background the photo lacks.  A photo's lamps are alike: where two
        or more lights were told surely and none of them glows, none does.
    told : ndarray of bool, shape (len(blobs),)
        The lights told surely: enough of their ring and background in the photo, and not
        touching its border (the round outline of a disc the border cuts may be smaller than
        the disc, whose rim then lifts the ring as a glow would).
    """
    levels = glow_levels(img, [_round(b) for b in blobs])
    border = np.array([b.touches_border for b in blobs], dtype=bool)
    glows, told = levels >= GLOW_LEVEL, np.isfinite(levels) & ~border  # (NaN: not glowing)
    if told.sum() >= 2 and not glows[told].any():  # plain discs: a cut one's rim is no glow
        glows[:] = False
    return glows, told


def centred_on_glow(img: np.ndarray, blobs, axis: str, which=None) -> list[Blob]:
    """The blobs, each glowing one (:func:`glowing`) moved to the centre of its radial shape.

    Parameters
    ----------
    img : ndarray, shape (H, W, 3) or (H, W)
        The photo.
    blobs : sequence of Blob
        The detected lights.
    axis : {"rows", "columns"}
        The readout axis.
    which : array_like of bool, shape (len(blobs),), optional
        The blobs to centre, when told otherwise (e.g. a video's lights the border cuts, as
        their fixtures were told whole in earlier frames); None: those that
        :func:`glowing` says glow, those touching the border included.

    Returns
    -------
    list of Blob
        The blobs; a moved one has its new ``pixel``, and a centred one whose region reaches
        the photo's border says in ``touches_border`` whether its disc does (all else as
        detected).

    Each glowing light is centred alone within its own cell first (its radial shape), or on
    its disc's rim where that shows clean and the shape's centre lies off it
    (:func:`~camvlp.pipeline.lamp.rim.rim_from_chords`); those whose glows joined
    (and, where some light glows, any light whose region joined others': its outline, its
    cell's, may hide its glow from :func:`glow_levels`) are then fitted together
    (:func:`~camvlp.pipeline.lamp.crowded.centred_jointly`).  Where some light glows, each
    light not centred on its own glow is first checked against its disc's rim
    (:func:`_to_clean_rim`).
    """
    if which is None:
        which = glowing(img, blobs)[0]
    which = np.asarray(which, dtype=bool)
    if which.shape != (len(blobs),):
        raise ValueError(f"which must have one flag per blob, got shape {which.shape}")
    moved = [
        _on_rim(img, blobs, k, axis, _centred(img, b, axis, _own_cell(blobs, k))) if w else b
        for k, (b, w) in enumerate(zip(blobs, which, strict=True))
    ]
    joined = np.array([b.cell is not None for b in blobs], dtype=bool)
    glows = bool(which.any())
    fitted = which | (joined & glows)
    rims: dict[int, tuple | None] = {}
    if glows:  # each light not centred on its glow, checked against its rim
        rims = {
            k: rim_from_chords(img, moved, k, axis)
            for k, (b, w) in enumerate(zip(moved, which, strict=True))
            if not w and not b.touches_border
        }
        checked = [
            _to_clean_rim(b, rims[k], img.shape) if k in rims else b for k, b in enumerate(moved)
        ]
        # a rim depends on the light's centre (its chords are those through it), box and
        # cell, and the others' masks and boxes: where only other lights moved, the joint
        # fit below would find the same rim again
        rims = {k: rim for k, rim in rims.items() if checked[k] is moved[k]}
        moved = checked
    return moved if fitted.sum() < 2 else centred_jointly(img, moved, axis, fitted, rims)


def _to_clean_rim(b: Blob, rim, shape: tuple[int, ...]) -> Blob:
    """Light ``b`` (not centred on its glow, not touching the border), moved to its disc's
    ``rim`` (:func:`~camvlp.pipeline.lamp.rim.rim_from_chords`, in a photo of ``shape``) when
    that shows clean and its centre is off it (:func:`~camvlp.pipeline.lamp.rim.on_rim`); as
    it was when its region reaches the photo's border and the rim does not lie
    :data:`RIM_MARGIN_PX` within the photo.

    Where lamps glow, a lamp whose outline took in all its glow (through a tone curve, a
    halo a third of the lamp's level stores as more than half of it) shows no ring beyond
    its outline and is not told as glowing, and one whose neighbours found their faces
    is not fitted with them: on crowded phone photos (rendered: of
    ``benchmarks/stress_decode.py --phone``, and of five of its lamps) such lamps' outlines
    came out 1.8 to 38 px off, their rims' within 1 px."""
    if on_rim(b.pixel, rim):
        return b
    if _reaches_border(b.box, shape) and not _rim_inside(*rim, shape):
        return b  # (a rim the border may cut)
    return dataclasses.replace(b, pixel=rim[0])


def _on_rim(img: np.ndarray, blobs, k: int, axis: str, fitted: Blob) -> Blob:
    """Light ``k`` as its radial shape centred it (``fitted``), or centred on its disc's rim
    (:func:`rim_from_chords`) when the rim shows clean and the fit's centre is not on it
    (:func:`on_rim`).  A light whose region reaches the photo's border so centred counts as
    touching it unless its rim lies :data:`RIM_MARGIN_PX` or more within the photo."""
    rim = rim_from_chords(img, blobs, k, axis)
    if on_rim(fitted.pixel, rim):
        return fitted
    b, (centre, radius) = blobs[k], rim
    if not _reaches_border(b.box, img.shape):
        return dataclasses.replace(b, pixel=centre)
    inside = _rim_inside(centre, radius, img.shape)
    return dataclasses.replace(b, pixel=centre, touches_border=not inside)


def _reaches_border(box, shape) -> bool:
    """Whether a region ``(x0, y0, x1, y1)`` reaches the border of a photo of ``shape``."""
    x0, y0, x1, y1 = box
    return x0 == 0 or y0 == 0 or x1 == shape[1] or y1 == shape[0]


def _rim_inside(centre: np.ndarray, radius, shape) -> bool:
    """Whether a rim of ``radius`` (px) about ``centre`` (photo pixels) lies
    :data:`RIM_MARGIN_PX` or more within a photo of ``shape`` (its pixels: -0.5 to size)."""
    size = np.array([shape[1], shape[0]], dtype=float)
    low, high = centre - radius, centre + radius
    return bool(np.all(low >= RIM_MARGIN_PX - 0.5) and np.all(high <= size - 0.5 - RIM_MARGIN_PX))


def _own_cell(blobs, k: int) -> np.ndarray | None:
    """The part of light ``k``'s region of interest that is its own among the photo's other
    lights whose regions overlap it: its cell of their power diagram (each light its outline's
    centre and half its smaller axis, :func:`~camvlp.pipeline.detect.peaks.power_cell`) and its
    own disc (:attr:`Blob.mask`: lit in a region of its own, whatever an outline that is off
    puts in another's cell); None when no other light's region overlaps its own, or when it
    has a cell from detection (:attr:`Blob.cell`, drawn from its joined region's shape, which
    its outline is not).  A glow reaches further than the region the detection gave its
    light, so a light's region may hold a neighbour's disc or its brightest glow, which the
    radial shape must not be fitted to."""
    if blobs[k].cell is not None:
        return None
    near = [j for j, o in enumerate(blobs) if j == k or boxes_overlap(blobs[k].box, o.box)]
    if len(near) < 2:
        return None
    seeds = np.array([(*blobs[j].pixel, 0.5 * float(np.min(blobs[j].axes_px))) for j in near])
    return power_cell(blobs[k].box, seeds, near.index(k)) | blobs[k].mask


def _round(b: Blob) -> Blob:
    """The blob; one touching the border with a round outline of its smaller axis (the
    border cuts the rows its outline was fitted to: the ellipse may come out stretched
    along them without end)."""
    if not b.touches_border:
        return b
    return dataclasses.replace(b, axes_px=np.full(2, float(np.min(b.axes_px))), angle_deg=0.0)


#: Slack of :func:`_within_outline`, pixels: an outline fitted to a blurred edge, and a rim
#: found to a pixel or two (:func:`~camvlp.pipeline.lamp.radial.radial_fit`).
_OUTLINE_SLACK_PX = 3.0


def _within_outline(b: Blob, centre: np.ndarray, rim: np.ndarray) -> bool:
    """Whether a disc fitted at ``centre`` (photo pixels, shape (2,)) with rim half-extents
    ``rim`` (pixels, shape (2,), NaN when not found) can lie within the light's outline
    ellipse (:attr:`Blob.pixel`, :attr:`Blob.axes_px`), up to :data:`_OUTLINE_SLACK_PX`.

    The outline is drawn around the lit pixels, the disc and whatever glow is bright enough,
    bridged across the dark stripes: the disc lies within it.  So the disc's farthest point
    from the outline's centre (the centre's offset plus the rim) is no farther than the
    outline's larger semi-axis; a fit that ran off to a neighbour's glow, or took a
    neighbour's disc for its rim, is not."""
    offset = float(np.hypot(*(np.asarray(centre, dtype=float) - b.pixel)))
    r = float(np.max(rim)) if np.all(np.isfinite(rim)) else 0.0
    return offset + r <= 0.5 * float(np.max(b.axes_px)) + _OUTLINE_SLACK_PX


def _centred(img: np.ndarray, b: Blob, axis: str, cell: np.ndarray | None = None) -> Blob:
    """The blob moved to the centre of its radial shape (as detected when that fails), fitted
    within ``cell`` (bool, its region's shape) when given, else its :attr:`Blob.cell`.

    The fit fails when its centre is off the light's disc (:attr:`Blob.mask`), or when the
    disc it found would not lie within the light's outline (:func:`_within_outline`): a fit
    drawn to a neighbour's glow.

    A blob whose region reaches the photo's border is searched for from further off (its
    outline is pulled away from the border where the border cuts its glow), then moved, and
    counted as not touching the border (:attr:`Blob.touches_border`), only when its disc's
    rim (:func:`radial_fit`) lies :data:`RIM_MARGIN_PX` or more within the photo; else it
    counts as touching it.  A glow the border cuts leaves the shape fitted to the pixels
    that are in the photo, while a disc the border cuts stays set aside, also where its
    bright part missed the border (the part cut off in a dark stripe).
    """
    x0, y0, x1, y1 = b.box
    gray = b.gray if b.gray is not None else to_gray(img[y0:y1, x0:x1])
    support = light_support(gray, b.mask, axis, cell=b.cell if cell is None else cell)
    r = _round(b)
    ellipse = ((r.pixel[0] - x0, r.pixel[1] - y0), tuple(r.axes_px), r.angle_deg)
    far = _reaches_border(b.box, img.shape) and not (b.face and not b.touches_border)
    fit = radial_fit(gray, support, ellipse, axis, far)
    centre = fit.centre
    h, w = b.mask.shape
    if not (np.all(np.isfinite(centre)) and 0 <= centre[0] < w and 0 <= centre[1] < h):
        return b
    # a light's centre lies on its disc: a fit that left it (drawn to a neighbour's glow)
    # failed; so did one whose disc is not within the light's lit outline
    pixel = centre + np.array([x0, y0], dtype=float)
    on_disc = b.mask[min(int(centre[1] + 0.5), h - 1), min(int(centre[0] + 0.5), w - 1)]
    if not on_disc or (not far and not _within_outline(b, pixel, fit.rim)):
        return dataclasses.replace(b, touches_border=True) if far else b
    if not far:
        return dataclasses.replace(b, pixel=pixel)
    if _rim_inside(pixel, fit.rim, img.shape):
        return dataclasses.replace(b, pixel=pixel, touches_border=False)
    return dataclasses.replace(b, touches_border=True)  # its disc cut (or its rim not found)
