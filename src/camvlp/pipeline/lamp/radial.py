"""The centre of a round light's radial shape, fitted where the shape tells it.

:func:`camvlp.pipeline.lamp.light_wave.separated_wave` fits a light's radial shape ``g(rho)`` and
its stripes ``s(line)`` together, and refines the shape's centre on the way (on every k-th pixel of
a few thousand, with radial bins of 1/40 of the outline's radius, and a shape that starts from the
outline's centre: enough to separate the stripes from the shape).  The centre itself asks for more
when the light clips.  Where a bright stripe clips the disc and the glow next to it, the rim, the
shape's sharpest feature, shows only in the dim lines (the edges of the stripes), and the rest of
what tells the centre is the glow's slow fall beyond the clipped part, which along a line trades off
with the line's own brightness (a clipped exponential glow brighter by a factor is the same glow
moved outward).  So on 1080p renders of a lamp with a halo of 0.4 clipping at 4 full scales the
fit's centres were 0.55 px off (RMS; 0.07 px unclipped), no better than the outline's 0.66 px: every
k-th pixel keeps one in nine of the few pixels that tell the centre, bins of 2.5 px (the clipped
glow's outline is twice the disc) cannot draw a rim blurred over 1 px, and a shape fitted at the
outline's centre and refitted in two steps holds the centre near the outline's.

:func:`radial_centre` refits the centre from the coarse fit's start with bins of
:data:`_BIN_PX`, on the pixels whose shape and stripe say the most about the centre (the
largest ``(s(line) g'(rho)) ** 2``, the centre's Fisher information per pixel under the
model, from the shape fitted at the start: chosen by the model, not by the pixels' values),
and with the shape refitted in :data:`_ITERS` steps at each trial centre.  The fit keeps the
light's look, its shape and stripes (:class:`RadialModel`), which :func:`radial_model`
renders: lights whose glows joined are fitted each to what its neighbours' looks leave
(:mod:`camvlp.pipeline.lamp.crowded`), their centres searched for widely first (``wide``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from camvlp.imaging.threads import one_blas_thread
from camvlp.pipeline.lamp.light_wave import (
    MAX_LOG_RATIO,
    LightWave,
    aggregate,
    along_axes,
    elliptical_radius,
    radial_shape,
    search_centre,
    shape_fit,
)
from camvlp.pipeline.paths import path

__all__ = ["RadialFit", "RadialModel", "radial_centre", "radial_fit", "radial_model", "rim_extents"]

#: Width of the radial shape's bins, pixels: finer than a rim blurred over a pixel.
_BIN_PX = 0.5
#: Pixels the centre is fitted on: those that say the most about it.
_PIXELS = 4000
#: Radii of the picked pixels the shape reaches below the least of them at the start, pixels:
#: more than the centre moves while it is fitted (nearer ones fall in the first bin).
_MARGIN_PX = 4.0
#: Fewest pixels of a radial bin the disc's rim is looked for in (near the centre, bins of
#: half a pixel hold a few pixels, or none where the light clips).
_RIM_PIXELS = 8
#: The shape's knots averaged (a pixel), and their distance across the rim (a disc's edge
#: blurred by up to 2 px falls over some 3 px; the noise of a few knots does not grow with
#: the distance).
_RIM_SMOOTH, _RIM_SPAN = 2, 6
#: Pixels (every k-th), first step (a share of the radius) and steps of the shape's fit at
#: each trial centre of the search on all the light's pixels (:func:`_wide_search`).
_WIDE_PIXELS, _WIDE_STEP, _WIDE_ITERS = 8000, 0.05, 4
#: How far along the readout the search on all the pixels looks first, in radii.
_WIDE_REACH = 0.3
#: Steps of the shape's fit that compare the search's end with its start.
_SETTLED_ITERS = 30
#: Steps of the shape's fit at the start, and at each trial centre.
_WARM_ITERS, _ITERS = 8, 12


class RadialModel(NamedTuple):
    """A light's fitted look ``g(rho) * s(line)`` above the background, in readout
    coordinates of its region (lines down axis 0; see :func:`radial_model`)."""

    geometry: np.ndarray  # shape (3,): centre (x, y), log axis ratio (elliptical_radius')
    cs: tuple[float, float]  # cos, sin of the outline's angle
    shape: np.ndarray  # g per knot, bin_px apart from the centre (0 beyond)
    stripes: np.ndarray  # s per line of the region, gray levels (0 beyond)
    rim: float  # the disc's rim, in the shape's radius (pixels); NaN when not found
    bin_px: float = _BIN_PX  # the knots' spacing, pixels


class RadialFit(NamedTuple):
    """A light's radial shape fitted (:func:`radial_fit`), in its region's pixels (x, y)."""

    centre: np.ndarray  # shape (2,): the shape's centre, pixels; NaN when not fitted
    rim: np.ndarray  # shape (2,): half-extents of the disc's rim along x and y (its larger
    # semi-axis both ways), pixels; NaN when not fitted
    model: RadialModel | None = None  # the look fitted at the centre; None when not fitted


def radial_model(model: RadialModel, x: np.ndarray, y: np.ndarray, axis: str):
    """A fitted light's look (gray levels above the background) and its radius at pixels
    ``(x, y)`` of its region (float arrays of one shape, pixels): ``(level, rho)``, the
    level 0 beyond its shape's last knot and on lines outside its region."""
    lx, ly = (y, x) if axis == "columns" else (x, y)
    rho = elliptical_radius(along_axes(lx.ravel(), ly.ravel(), model.cs), model.geometry, model.cs)
    g = np.interp(rho / model.bin_px, np.arange(model.shape.size), model.shape, right=0.0)
    line = np.rint(ly.ravel()).astype(np.intp)
    inside = (line >= 0) & (line < model.stripes.size)
    s = np.where(inside, model.stripes[np.clip(line, 0, model.stripes.size - 1)], 0.0)
    return (g * s).reshape(x.shape), rho.reshape(x.shape)


def radial_centre(gray: np.ndarray, support: np.ndarray, ellipse, axis: str) -> np.ndarray:
    """The centre of a round light's radial shape: :func:`radial_fit`'s ``centre``."""
    return radial_fit(gray, support, ellipse, axis).centre


@path("radial fit")
@one_blas_thread
def radial_fit(
    gray: np.ndarray,
    support: np.ndarray,
    ellipse,
    axis: str,
    far: bool = False,
    background: float | None = None,
    search: bool = True,
    wide: bool = False,
    local: bool = True,
    keep_start: bool = False,
) -> RadialFit:
    """The centre of a round light's radial shape (core, disc and glow), separated from its
    stripes (the square wave is not fitted), from the pixels that tell it best, and its
    disc's rim.

    The rim is where the shape, fitted over all the light's pixels at that centre, falls the
    most steeply (a disc's edge, blurred over a pixel or two, falls from the disc's level to
    the glow's; a hot core and a glow change slowly, over tenths of the radius).  Pixels the
    region lacks (beyond the photo's border) take no part in the fit: the shape is fitted
    to each pixel that is there.

    Parameters
    ----------
    gray : ndarray, shape (h, w)
        The light's region of interest, gray levels 0-255 (any real dtype).
    support : ndarray of bool, shape (h, w)
        The light's whole striped area (:func:`camvlp.pipeline.detect.disc.light_support`).
    ellipse : tuple
        A first outline of the light in the region, as :func:`cv2.fitEllipse` gives it:
        ``((cx, cy), (width, height), angle_deg)``.
    axis : {"rows", "columns"}
        The readout axis.
    far : bool
        The outline's centre may be far from the shape's (e.g. a glow the photo's border
        cuts): a coarse search on every k-th pixel first, in steps of a tenth of the radius.
    background : float, optional
        The photo's background (gray level) under the light, when known (e.g. where glows
        fill the region); else measured around the support.
    search : bool
        Whether to fit the centre; else the shape is fitted at the outline's centre (on
        every k-th pixel, as with ``local`` False).
    wide : bool
        The outline's centre may be off by tenths of the radius (a light whose neighbours'
        glows pulled it): the centre is first searched for on the cost of all the pixels
        (every k-th of :data:`_WIDE_PIXELS`), from steps of :data:`_WIDE_STEP` of the
        radius, and kept when that cost is lower there than at the start.
    local : bool
        Whether the centre is then refined on the pixels that tell it best, and the shape
        fitted on all the pixels in bins of :data:`_BIN_PX` (the rim found); else the
        shape (its bins those of the coarse fit) on every k-th pixel, and no rim.
    keep_start : bool
        Start from the outline's centre (with the better of a round outline and its axis
        ratio), not from the better of it and the support's outline's.

    Returns
    -------
    RadialFit
        Centre ``[x, y]`` in the region, and the half-extents ``[x, y]`` of the rim (the
        ellipse of the shape's axis ratio and angle), pixels; NaN when the region has too
        few pixels with signal.
    """
    fitted = radial_shape(gray, support, ellipse, axis, refine=False, background=background)
    if isinstance(fitted, LightWave):
        return RadialFit(fitted.centre, np.full(2, np.nan))
    ly, lx, value = fitted.pixels
    cs, n_lines = fitted.cs, fitted.n_lines
    uv = along_axes(lx, ly, cs)

    def fit(p: np.ndarray, g0, iters: int, pick=slice(None), lines=ly, n=n_lines, r0=0.0):
        rho = np.maximum(elliptical_radius(uv[:, pick], p, cs) - r0, 0.0)
        return shape_fit(aggregate(rho, lines, value[pick], n, _BIN_PX), g0, iters)

    start = np.asarray(fitted.best, dtype=float)  # not refined: the coarse fit's start
    if not search or keep_start:
        start = np.array([*ellipse[0][:: -1 if axis == "columns" else 1], start[2]], dtype=float)
    radius = 0.25 * float(sum(ellipse[1]))
    if not search or not local:
        return _coarse(fitted, _wide_search(fitted, start, radius) if search else start, axis)
    if far:  # a coarse search first, in steps of a tenth of the radius
        every = max(1, ly.size // _PIXELS)
        radius = 0.25 * float(sum(ellipse[1]))
        coarse = fitted.warm

        def cost(p: np.ndarray) -> float:
            return fitted.fit(p, coarse, 2, every)[0]

        start = search_centre(cost, start, max(1.0, 0.1 * radius))
    if wide:
        start = _wide_search(fitted, start, radius)
    _, s, _, g = fit(start, None, _WARM_ITERS)
    pick, lines, n, r0 = slice(None), ly, n_lines, 0.0
    if ly.size > _PIXELS:
        slope = np.gradient(g)  # per bin; the scale does not matter
        rho = elliptical_radius(uv, start, cs)
        info = np.square(s[ly] * np.interp(rho / _BIN_PX, np.arange(g.size), slope, right=0.0))
        pick = np.argpartition(info, ly.size - _PIXELS)[ly.size - _PIXELS :]
        # the shape over the picked pixels' radii and lines only (a big light's bins and
        # lines would cost the most): from _MARGIN_PX within their least radius
        r0 = _BIN_PX * np.floor(max(float(rho[pick].min()) - _MARGIN_PX, 0.0) / _BIN_PX)
        used, lines = np.unique(ly[pick], return_inverse=True)
        n = used.size
    part = {"pick": pick, "lines": lines, "n": n, "r0": r0}
    warm = fit(start, None, _WARM_ITERS, **part)[3]
    best = search_centre(lambda p: fit(p, warm, _ITERS, **part)[0], start)
    _, s, _, g = fit(best, None, _WARM_ITERS)
    per_bin = np.bincount(
        (elliptical_radius(uv, best, cs) / _BIN_PX).astype(np.intp), minlength=g.size
    )
    rim = rim_extents(g, per_bin[: g.size], best[2])
    r = float(np.clip(abs(best[2]), 0.0, MAX_LOG_RATIO))
    model = RadialModel(best.copy(), cs, g, s, float(rim[0]) * np.exp(-0.5 * r))
    if axis == "columns":
        return RadialFit(best[1::-1].copy(), rim[::-1], model)
    return RadialFit(best[:2].copy(), rim, model)


def _coarse(fitted, p: np.ndarray, axis: str) -> RadialFit:
    """A light's look at ``p`` (readout coordinates and log axis ratio) fitted on every k-th
    pixel (of :data:`_WIDE_PIXELS`) in the coarse fit's bins, without its rim."""
    every = max(1, fitted.pixels[0].size // _WIDE_PIXELS)
    _, s, _, g = fitted.fit(p, fitted.warm, _SETTLED_ITERS, every)
    model = RadialModel(p.copy(), fitted.cs, g, s, float("nan"), fitted.bin_px)
    nan = np.full(2, np.nan)
    return RadialFit(p[1::-1].copy() if axis == "columns" else p[:2].copy(), nan, model)


def _wide_search(fitted, start: np.ndarray, radius: float) -> np.ndarray:
    """The centre of the least cost of all the light's pixels (every k-th of
    :data:`_WIDE_PIXELS`, the shape refitted in :data:`_WIDE_ITERS` steps at each trial
    centre) from ``start`` (readout coordinates and log axis ratio): first along the readout
    (the stripes leave the cost a local minimum every stripe period that way), over
    :data:`_WIDE_REACH` of ``radius`` (pixels) either side in steps of a pixel or a 40th of
    it, then in all three from the best of those; ``start`` when the cost, the shape fitted
    in :data:`_SETTLED_ITERS` steps, is not lower there."""
    every = max(1, fitted.pixels[0].size // _WIDE_PIXELS)
    warm = fitted.warm

    def cost(p: np.ndarray) -> float:
        return fitted.fit(p, warm, _WIDE_ITERS, every)[0]

    reach = _WIDE_REACH * radius
    steps = np.arange(-reach, reach + 1e-9, max(1.0, radius / 40.0))
    trials = [start + np.array([0.0, d, 0.0]) for d in steps]
    found = search_centre(cost, min(trials, key=cost), max(1.0, _WIDE_STEP * radius))

    def settled(p: np.ndarray) -> float:  # the shape fitted to the end
        return fitted.fit(p, None, _SETTLED_ITERS, every)[0]

    return found if settled(found) < settled(start) else start


def rim_extents(g: np.ndarray, per_bin: np.ndarray, log_ratio: float) -> np.ndarray:
    """Half-extents (along the lines, across them) of the rim of a light of radial shape
    ``g`` (knots :data:`_BIN_PX` apart from its centre) and axis ratio ``exp(log_ratio)``,
    pixels: the larger semi-axis both ways.  The rim is the outermost place where the
    shape's mean over a pixel falls over :data:`_RIM_SPAN` knots by half the most it falls
    anywhere, among the bins holding :data:`_RIM_PIXELS` pixels or more (a knot without
    pixels is 0); ``per_bin`` counts the pixels of each bin (as many as ``g``'s knots).
    NaN both ways when the shape falls nowhere (it grows outward, or is flat or not
    finite): such a light shows no rim."""
    n = _RIM_SMOOTH
    if g.size < 2 * n + _RIM_SPAN:
        return np.full(2, np.nan)
    mean = np.convolve(g, np.full(n, 1.0 / n), mode="valid")  # knots k to k + n - 1
    full = np.convolve(per_bin >= _RIM_PIXELS, np.ones(n), mode="valid") == n
    # from the knots k..k+n-1 to k+span..: the fall across the rim, centred at k+(n-1+span)/2
    fall = np.where(
        full[:-_RIM_SPAN] & full[_RIM_SPAN:], mean[:-_RIM_SPAN] - mean[_RIM_SPAN:], -np.inf
    )
    steepest = float(np.max(fall)) if np.isfinite(fall).any() else float("nan")
    if not steepest > 0.0:  # no fall anywhere: no rim (a NaN in the shape counts as none)
        return np.full(2, np.nan)
    # the outermost steep fall: where the light clips, the few pixels left near the centre
    # draw the shape less surely than the many at the rim
    last = int(np.flatnonzero(fall >= 0.5 * steepest)[-1])
    first = max(last - 2 * _RIM_SPAN, 0)  # the peak of that fall
    k = first + int(np.argmax(fall[first : last + 1]))
    radius = _BIN_PX * (float(k) + 0.5 * (n - 1 + _RIM_SPAN))
    # the major axis every way: a light the border cuts shows its axis ratio less surely
    r = float(np.clip(abs(log_ratio), 0.0, MAX_LOG_RATIO))
    return np.full(2, radius * np.exp(0.5 * r))
