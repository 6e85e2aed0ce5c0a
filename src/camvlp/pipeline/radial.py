"""The centre of a round light's radial shape, fitted where the shape tells it.

:func:`camvlp.pipeline.light_wave.light_wave` fits a light's radial shape ``g(rho)`` and its
stripes ``s(line)`` together, and refines the shape's centre on the way (on every k-th pixel
of a few thousand, with radial bins of 1/40 of the outline's radius, and a shape that starts
from the outline's centre: enough to separate the stripes from the shape).  The centre
itself asks for more when the light clips.  Where a bright stripe clips the disc and the
glow next to it, the rim, the shape's sharpest feature, shows only in the dim lines (the
edges of the stripes), and the rest of what tells the centre is the glow's slow fall beyond
the clipped part, which along a line trades off with the line's own brightness (a clipped
exponential glow brighter by a factor is the same glow moved outward).  So on 1080p renders
of a lamp with a halo of 0.4 clipping at 4 full scales the fit's centres were 0.55 px off
(RMS; 0.07 px unclipped), no better than the outline's 0.66 px: every k-th pixel keeps one
in nine of the few pixels that tell the centre, bins of 2.5 px (the clipped glow's outline
is twice the disc) cannot draw a rim blurred over 1 px, and a shape fitted at the outline's
centre and refitted in two steps holds the centre near the outline's.

:func:`radial_centre` refits the centre from the coarse fit's start with bins of
:data:`_BIN_PX`, on the pixels whose shape and stripe say the most about the centre (the
largest ``(s(line) g'(rho)) ** 2``, the centre's Fisher information per pixel under the
model, from the shape fitted at the start: chosen by the model, not by the pixels' values),
and with the shape refitted in :data:`_ITERS` steps at each trial centre.
"""

from __future__ import annotations

import numpy as np

from camvlp.pipeline.light_wave import (
    LightWave,
    _aggregate,
    _axes,
    _radial,
    _radius,
    _search_centre,
    _shape_fit,
)

__all__ = ["radial_centre"]

#: Width of the radial shape's bins, pixels: finer than a rim blurred over a pixel.
_BIN_PX = 0.5
#: Pixels the centre is fitted on: those that say the most about it.
_PIXELS = 4000
#: Radii of the picked pixels the shape reaches below the least of them at the start, pixels:
#: more than the centre moves while it is fitted (nearer ones fall in the first bin).
_MARGIN_PX = 4.0
#: Steps of the shape's fit at the start, and at each trial centre.
_WARM_ITERS, _ITERS = 8, 12


def radial_centre(gray: np.ndarray, support: np.ndarray, ellipse, axis: str) -> np.ndarray:
    """The centre of a round light's radial shape (core, disc and glow), separated from its
    stripes (the square wave is not fitted), from the pixels that tell it best.

    Parameters
    ----------
    gray : ndarray, shape (h, w)
        The light's region of interest, gray levels 0-255 (any real dtype).
    support : ndarray of bool, shape (h, w)
        The light's whole striped area (:func:`camvlp.pipeline.detect.light_support`).
    ellipse : tuple
        A first outline of the light in the region, as :func:`cv2.fitEllipse` gives it:
        ``((cx, cy), (width, height), angle_deg)``.
    axis : {"rows", "columns"}
        The readout axis.

    Returns
    -------
    ndarray, shape (2,)
        Centre ``[x, y]`` in the region, pixels; NaN when the region has too few pixels with
        signal.
    """
    fitted = _radial(gray, support, ellipse, axis, refine=False)
    if isinstance(fitted, LightWave):
        return fitted.centre
    ly, lx, value = fitted.pixels
    cs, n_lines = fitted.cs, fitted.n_lines
    uv = _axes(lx, ly, cs)

    def fit(p: np.ndarray, g0, iters: int, pick=slice(None), lines=ly, n=n_lines, r0=0.0):
        rho = np.maximum(_radius(uv[:, pick], p, cs) - r0, 0.0)
        return _shape_fit(_aggregate(rho, lines, value[pick], n, _BIN_PX), g0, iters)

    start = np.asarray(fitted.best, dtype=float)  # not refined: the coarse fit's start
    _, s, _, g = fit(start, None, _WARM_ITERS)
    pick, lines, n, r0 = slice(None), ly, n_lines, 0.0
    if ly.size > _PIXELS:
        slope = np.gradient(g)  # per bin; the scale does not matter
        rho = _radius(uv, start, cs)
        info = np.square(s[ly] * np.interp(rho / _BIN_PX, np.arange(g.size), slope, right=0.0))
        pick = np.argpartition(info, ly.size - _PIXELS)[ly.size - _PIXELS :]
        # the shape over the picked pixels' radii and lines only (a big light's bins and
        # lines would cost the most): from _MARGIN_PX within their least radius
        r0 = _BIN_PX * np.floor(max(float(rho[pick].min()) - _MARGIN_PX, 0.0) / _BIN_PX)
        used, lines = np.unique(ly[pick], return_inverse=True)
        n = used.size
    part = {"pick": pick, "lines": lines, "n": n, "r0": r0}
    warm = fit(start, None, _WARM_ITERS, **part)[3]
    centre = _search_centre(lambda p: fit(p, warm, _ITERS, **part)[0], start)[:2]
    return centre[::-1] if axis == "columns" else centre
