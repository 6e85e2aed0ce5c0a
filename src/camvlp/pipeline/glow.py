"""Lights that glow: centred on their radial shape, not on their bright outline.

A real lamp often glows around its disc (light scattered in the diffuser or the lens), and the
glow blinks with the LED.  In the bright stripes it lifts the disc's outline far out (it may
clip there too), in the dark ones not at all, so an ellipse fitted to the outline is pulled
about: 0.2 to 1.2 px from the disc's centre (median; up to 1.9 px) on the renders of
``tests/pipeline/test_glow.py``, where a plain disc's is 0.02 px.  The light's shape, glow
included, is radially symmetric about its centre, so a glowing light is centred on its
radial shape instead (:func:`camvlp.pipeline.light_wave.light_wave`, which separates the
shape from the stripes over the light's whole striped area).  That costs a tenth of a second
or more per glowing light; a light without a glow (its ring beyond the outline at the
background) is left as detected, at the cost of a few small image operations.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from camvlp.pipeline.detect import Blob, light_support, to_gray
from camvlp.pipeline.light_wave import light_wave

__all__ = ["centred_on_glow", "glow_level"]

#: Glow level (see :func:`glow_level`) from which a light counts as glowing.
GLOW_LEVEL = 0.02


#: Where :func:`glow_level` samples a light, in radii of its outline ellipse: inside, the
#: ring just beyond (past a plain disc's blur), and the background further out.
_RADII = np.array([0.3, 0.5, 0.7, 1.15, 1.25, 1.35, 1.7, 1.9])[:, None]
_ANGLES = np.linspace(0.0, 2.0 * np.pi, 32, endpoint=False)
_COS, _SIN = np.cos(_ANGLES), np.sin(_ANGLES)
_LUMA = np.array([0.114, 0.587, 0.299])  # B, G, R


def glow_level(img: np.ndarray, blob: Blob) -> float:
    """How much a light glows beyond its outline, as a fraction of its level.

    The photo is sampled along 32 directions from the outline ellipse's centre: within it
    (0.3 to 0.7 of its radii), in the ring just beyond it (1.15 to 1.35 radii) and further
    out (1.7 and 1.9 radii: the background, their median).  The ring's mean above the
    background, over the inside's, is about 0 for a plain disc, blurred or not (its blur ends
    within the ring's inner edge), and a few per cent or more for a glow.  NaN when too few
    samples fall in the photo to tell.

    Parameters
    ----------
    img : ndarray, shape (H, W, 3) or (H, W)
        The photo.
    blob : Blob
        The detected light (its centre, axes and angle).
    """
    h, w = img.shape[:2]
    a, b = (max(float(v), 1.0) * 0.5 for v in blob.axes_px)
    t = np.deg2rad(blob.angle_deg)
    ct, st = np.cos(t), np.sin(t)
    x = blob.pixel[0] + _RADII * (a * ct * _COS - b * st * _SIN)
    y = blob.pixel[1] + _RADII * (a * st * _COS + b * ct * _SIN)
    ok = (x > -0.5) & (x < w - 0.5) & (y > -0.5) & (y < h - 0.5)
    xi = np.clip(np.rint(x), 0, w - 1).astype(np.intp)
    yi = np.clip(np.rint(y), 0, h - 1).astype(np.intp)
    px = img[yi, xi].astype(np.float64)
    if px.ndim == 3:  # BGR(A): OpenCV's luma weights
        px = px[..., :3] @ _LUMA
    n_ring, n_out = int(ok[3:6].sum()), int(ok[6:].sum())
    if n_ring < 16 or n_out < 16 or not ok[:3].any():
        return float("nan")
    inside = float(px[:3][ok[:3]].sum()) / int(ok[:3].sum())
    ring = float(px[3:6][ok[3:6]].sum()) / n_ring
    out = px[6:][ok[6:]]
    background = float(np.partition(out, out.size // 2)[out.size // 2])
    return (ring - background) / max(inside - background, 1.0)


def centred_on_glow(img: np.ndarray, blobs, axis: str) -> list[Blob]:
    """The blobs, each glowing one (:func:`glow_level` at least :data:`GLOW_LEVEL`, not
    touching the image's border) moved to the centre of its radial shape.

    Parameters
    ----------
    img : ndarray, shape (H, W, 3) or (H, W)
        The photo.
    blobs : sequence of Blob
        The detected lights.
    axis : {"rows", "columns"}
        The readout axis.

    Returns
    -------
    list of Blob
        The blobs; a moved one has its new ``pixel`` (all else as detected).
    """
    out = []
    for b in blobs:
        if b.touches_border or not glow_level(img, b) >= GLOW_LEVEL:
            out.append(b)
            continue
        x0, y0, x1, y1 = b.box
        gray = b.gray if b.gray is not None else to_gray(img[y0:y1, x0:x1])
        support = light_support(gray, b.mask, axis)
        ellipse = ((b.pixel[0] - x0, b.pixel[1] - y0), tuple(b.axes_px), b.angle_deg)
        centre = light_wave(gray, support, ellipse, axis).centre
        h, w = b.mask.shape
        if np.all(np.isfinite(centre)) and 0 <= centre[0] < w and 0 <= centre[1] < h:
            b = dataclasses.replace(b, pixel=centre + np.array([x0, y0], dtype=float))
        out.append(b)
    return out
