"""A round light's waveform, separated from its shape.

A round light whose LED blinks shines ``L(x, y) * w(t)``: its shape times its waveform.  A
rolling shutter exposes sensor line ``y`` over its own window of time, so the photo holds

    I(x, y) = A + L(x, y) * s(y),   clipped at the sensor's full scale,

with ``A`` the background and ``s(y)`` the waveform integrated over line ``y``'s exposure
window.  A disc, a hot core and a halo around it are all radially symmetric about the light's
centre, so ``L = g(rho)``, with ``rho`` the elliptical radius of the light's outline as the
camera sees it.  :func:`separated_wave` fits ``g`` and ``s`` together (alternating least
squares over the unclipped pixels, the ellipse's centre and axis ratio refined to the best
fit), so that ``s`` comes out free of the light's shape: a hot core or a glow no longer
masquerades as a stripe, and a stripe seen only in the glow still counts.  A clipped pixel is
not dropped: it says that ``s`` reached at least the level that clips it there.  What the
radial shape leaves (a core off the light's centre) the beacon model's envelopes take
(:mod:`camvlp.pipeline.decode.beacon`), which fits ``s``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from camvlp.imaging.levels import CLIP_LEVEL, FULL_SCALE
from camvlp.imaging.threads import one_blas_thread
from camvlp.pipeline.paths import path

__all__ = ["LightWave", "outline_ellipse", "separated_wave"]

#: Width of the bins of the light's radial shape ``g``: at least half a pixel, at most
#: 1/40 of its radius (a big light needs no finer shape).
_BIN_PX = 0.5
_BINS_PER_RADIUS = 40
_CLIP, _FULL = CLIP_LEVEL, FULL_SCALE
#: Pixels (at most, every k-th) whose fit refines the light's outline.
_GEOMETRY_PIXELS = 4000
#: Largest axis ratio of the light's outline (natural log): a degenerate outline (an axis
#: of 0) would otherwise stretch the radial bins without end.
MAX_LOG_RATIO = float(np.log(20.0))


@dataclass(frozen=True)
class LightWave:
    """A light's stripes as a square wave (:func:`light_wave`).  Falsy on failure.

    Attributes
    ----------
    period_px : float
        Stripe period along the readout axis, pixels (NaN on failure).
    window_px : float
        Length of the window the square wave is integrated over (exposure plus the LED's own
        slowness), pixels along the readout axis.
    phase_px : float
        Offset of a rising edge from the region's first line, pixels (modulo the period).
    levels : tuple of float
        The waveform's low and high level, gray levels above the background where the
        light's shape is brightest (the high level may lie above the clipping level).
    centre : ndarray, shape (2,)
        Centre ``[x, y]`` of the light's radial shape in the region, pixels.
    periods_seen : float
        How many periods the lines with signal span.
    message : str
        Why the fit failed ("" on success).
    conclusive : bool
        Whether a failure says the light has no period to measure (clipped all over, or
        steady or too small to show a whole period), not only that this fit found none.
    """

    period_px: float
    window_px: float
    phase_px: float
    levels: tuple[float, float]
    centre: np.ndarray
    periods_seen: float
    message: str = ""
    conclusive: bool = False

    def __bool__(self) -> bool:
        return bool(np.isfinite(self.period_px)) and not self.message


def outline_ellipse(support: np.ndarray, axis: str):
    """An ellipse fitted to the sides of a light's support, or None when they are too few.

    The sides are where the outline runs along the readout axis; its caps are cut wherever
    a dark stripe falls and are left out.

    Parameters
    ----------
    support : ndarray of bool, shape (h, w)
        The light's pixels.
    axis : {"rows", "columns"}
        The readout axis.

    Returns
    -------
    tuple or None
        ``((cx, cy), (width, height), angle_deg)`` as :func:`cv2.fitEllipse` gives it,
        region pixels.
    """
    contours, _ = cv2.findContours(
        np.asarray(support, dtype=np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
    )
    if not contours:
        return None
    pts = max(contours, key=cv2.contourArea)[:, 0, :].astype(float)  # (M, 2) as (x, y)
    if pts.shape[0] < 20:
        return None
    j = 1 if axis == "rows" else 0  # coordinate along the readout: y for rows
    tangent = np.roll(pts, -2, axis=0) - np.roll(pts, 2, axis=0)
    sides = pts[np.abs(tangent[:, j]) > np.abs(tangent[:, 1 - j])]
    if sides.shape[0] < 12:
        return None
    return cv2.fitEllipse(sides.astype(np.float32))


#: The (line, knot) sums of :func:`aggregate` are kept per cell that holds a pixel, not as a
#: (lines, knots) array, when that array would have more than this many cells per pixel: a
#: big light's fine bins (hundreds of knots) over a few thousand picked pixels fill one cell
#: in 75 (a 20 MP lamp's fit: 380 x 811 cells, 4,134 of them with pixels, at the median).
_DENSE_CELLS_PER_PIXEL = 32


class Cells(NamedTuple):
    """:func:`aggregate`'s sums of the (line, knot) cells that hold a pixel: each cell's line
    and knot, and its sums ``A``, ``D``, ``O`` (shape (M,) each)."""

    line: np.ndarray
    knot: np.ndarray
    a: np.ndarray
    d: np.ndarray
    o: np.ndarray
    n_lines: int


def aggregate(rho: np.ndarray, line: np.ndarray, value: np.ndarray, n_lines: int, bin_px: float):
    """Sums per (line, knot of the radial shape) for :func:`shape_fit`.

    The shape is piecewise linear over bins of ``bin_px``: a pixel at ``t`` (0 to 1) between
    knots ``k`` and ``k + 1`` sees ``(1 - t) g[k] + t g[k + 1]``.  Returns the knot count
    ``K`` (the bins plus one), the sums per line and knot: ``A`` of ``value`` times the
    knot's weight, ``D`` of the weight squared, and ``O`` of the product of the weights of
    the knot and the next one (0 at the last knot), and the sum of ``value ** 2``.  The sums
    are an array of shape (3, n_lines, K), or :class:`Cells` when few of its cells would
    hold a pixel (:data:`_DENSE_CELLS_PER_PIXEL`).
    """
    f = rho / bin_px
    i0 = f.astype(np.intp)  # rho >= 0: truncation is the floor
    t = f - i0
    u = 1.0 - t
    knots = int(i0.max()) + 2
    size = n_lines * knots
    key = line * knots + i0
    if size > _DENSE_CELLS_PER_PIXEL * key.size:
        cells, at = np.unique(np.concatenate([key, key + 1]), return_inverse=True)
        m, first = cells.size, at[: key.size]
        sums = Cells(
            cells // knots,
            cells % knots,
            np.bincount(at, np.concatenate([value * u, value * t]), minlength=m),
            np.bincount(at, np.concatenate([u * u, t * t]), minlength=m),
            np.bincount(first, t * u, minlength=m),
            n_lines,
        )
        return knots, sums, float(value @ value)
    keys = np.concatenate([key, key + 1, key + size, key + (size + 1), key + 2 * size])
    weights = np.concatenate([value * u, value * t, u * u, t * t, t * u])
    sums = np.bincount(keys, weights, minlength=3 * size).reshape(3, n_lines, knots)
    return knots, sums, float(value @ value)


def _per_line(sums, gv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per line, the sum of ``value * g(rho)`` and of ``g(rho) ** 2`` over its pixels, from
    :func:`aggregate`'s sums and ``gv`` (3, K, 1): g, g ** 2, and 2 g times the next knot's g."""
    if isinstance(sums, Cells):
        g, g2, g2x = gv[:, :, 0]
        num = np.bincount(sums.line, sums.a * g[sums.knot], minlength=sums.n_lines)
        den = sums.d * g2[sums.knot]
        den += sums.o * g2x[sums.knot]
        return num, np.bincount(sums.line, den, minlength=sums.n_lines)
    num, den, den_o = np.matmul(sums, gv)[:, :, 0]
    den += den_o
    return num, den


def _per_knot(sums, sv: np.ndarray, knots: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per knot, the sums of ``A s``, ``D s ** 2`` and ``O s ** 2`` over the lines, from
    :func:`aggregate`'s sums and ``sv`` (3, 1, n_lines): s, s ** 2, s ** 2."""
    if isinstance(sums, Cells):
        s = sv[0, 0][sums.line]
        s2 = s * s
        return (
            np.bincount(sums.knot, sums.a * s, minlength=knots),
            np.bincount(sums.knot, sums.d * s2, minlength=knots),
            np.bincount(sums.knot, sums.o * s2, minlength=knots),
        )
    num_k, den_k, o = np.matmul(sv, sums)[:, 0, :]
    return num_k, den_k, o


def shape_fit(agg, g0, iters: int):
    """Alternating least squares of ``value = g(rho) * s(line)`` on :func:`aggregate`'s sums.

    ``g`` is piecewise linear over the radial bins.  Returns (residual sum of squares, s per
    line, its weight, g per bin knot).
    """
    knots, sums, vv = agg
    n_lines = sums.n_lines if isinstance(sums, Cells) else sums.shape[1]
    gv = np.zeros((3, knots, 1))  # g, g ** 2, and 2 g times the next knot's g
    g = gv[0, :, 0]
    g[:] = 1.0
    if g0 is not None:
        k = min(knots, g0.size)
        g[:k] = g0[:k]
    sv = np.empty((3, 1, n_lines))  # s, s ** 2, s ** 2
    for it in range(iters + 1):
        np.multiply(g, g, out=gv[1, :, 0])
        np.multiply(g[:-1], g[1:], out=gv[2, :-1, 0])
        gv[2, :-1, 0] *= 2.0
        # per line: num = sum of value * g(rho), den = sum of g(rho) ** 2
        num, den = _per_line(sums, gv)
        s = np.divide(num, den, out=np.zeros(n_lines), where=den > 0)
        if it == iters:
            break
        sv[0, 0] = s
        np.multiply(s, s, out=sv[1, 0])
        sv[2, 0] = sv[1, 0]
        # each knot: a Jacobi step of the normal equations (its bin below and above)
        num_k, den_k, o = _per_knot(sums, sv, knots)
        den_k += o
        den_k[1:] += o[:-1]
        np.divide(num_k, den_k, out=g, where=den_k > 0)
        g[den_k <= 0] = 0.0
        g /= float(np.max(np.abs(g))) or 1.0
    rss = vv - 2.0 * float(s @ num) + float(s * s @ den)
    return rss, s, den, g


def _pixels(g: np.ndarray, m: np.ndarray, background: float | None = None):
    """The pixels within 2 px of the support ``m``: ``(ly, lx, value)`` of the unclipped ones
    (``value`` above the background), ``(ly, lx)`` of the clipped ones, and the background
    (the median gray level beyond 4 px of it; the region's least when it has too few pixels
    there; ``background`` when given).  A pixel that is not finite is left out."""
    finite = np.isfinite(g)
    near = cv2.dilate(m.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & finite
    outside = (cv2.dilate(m.astype(np.uint8), np.ones((9, 9), np.uint8)) == 0) & finite
    if background is None and outside.sum() >= 50:
        background = float(np.median(g[outside]))
    elif background is None:
        background = float(g[finite].min()) if finite.any() else float("nan")
    ly, lx = np.nonzero(near & (g < _CLIP))
    return (ly, lx, g[ly, lx] - background), np.nonzero(near & (g >= _CLIP)), background


def _clip_bounds(f: np.ndarray, line: np.ndarray, shape: np.ndarray, full: float, n_lines: int):
    """Lower bounds on the waveform from the clipped pixels: (lines, bounds, weights).

    ``f`` is each clipped pixel's radius in bins of the radial shape ``shape`` (knots),
    ``line`` its line, ``full`` the clipping level above the background.  A line's bound is
    ``full`` over the brightest shape among its clipped pixels; its weight the sum of their
    shapes squared.
    """
    if not line.size:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    f = np.minimum(f, shape.size - 1.001)
    j = np.floor(f).astype(np.intp)
    env = shape[j] * (j + 1 - f) + shape[j + 1] * (f - j)
    top = np.zeros(n_lines)
    np.maximum.at(top, line, env)
    bounds = np.where(top > 0, full / np.maximum(top, 1e-300), 0.0)
    return np.arange(n_lines, dtype=float), bounds, np.bincount(line, env * env, minlength=n_lines)


def along_axes(x: np.ndarray, y: np.ndarray, cs: tuple[float, float]) -> np.ndarray:
    """Pixels ``(x, y)`` (shape (N,)) along the axes of an ellipse at angle ``cs`` = (cos, sin)
    from the x axis, shape (2, N): for :func:`elliptical_radius`."""
    c, s = cs
    return np.stack([x * c + y * s, y * c - x * s])


def elliptical_radius(uv: np.ndarray, p: np.ndarray, cs: tuple[float, float]) -> np.ndarray:
    """Elliptical radius of pixels ``uv`` (:func:`along_axes`, shape (2, N)), pixels, shape (N,).

    About the centre ``(p[0], p[1])`` (x, y), the axis ratio ``exp(p[2])`` (clipped to
    :data:`MAX_LOG_RATIO`), the ellipse's first axis along ``cs`` = (cos, sin) of its angle.
    """
    c, s = cs
    u = uv[0] - (p[0] * c + p[1] * s)
    v = uv[1] - (p[1] * c - p[0] * s)
    r = float(np.clip(p[2], -MAX_LOG_RATIO, MAX_LOG_RATIO))
    return np.hypot(u * np.exp(-0.5 * r), v * np.exp(0.5 * r))


class RadialShape(NamedTuple):
    """The light's radial fit (:func:`radial_shape`), in readout coordinates (lines down axis 0)."""

    best: np.ndarray  # centre x, y (pixels) and log axis ratio
    warm: np.ndarray  # the radial shape fitted at the start, per bin knot
    fit: Callable  # fit(p, g0, iters, step=1) -> (rss, s per line, its weight, g per knot)
    clipped: tuple[np.ndarray, np.ndarray]  # (lines, x) of the clipped pixels
    cs: tuple[float, float]  # cos, sin of the outline's angle
    bin_px: float
    background: float
    n_lines: int
    pixels: tuple[np.ndarray, np.ndarray, np.ndarray]  # (lines, x, level) of the unclipped


def radial_shape(
    gray: np.ndarray,
    support: np.ndarray,
    ellipse,
    axis: str,
    refine: bool = True,
    background: float | None = None,
) -> RadialShape | LightWave:
    """The light's radial shape and its centre fitted (see :func:`light_wave`), or a failed
    :class:`LightWave`; without ``refine``, ``best`` is the start (the centre not fitted);
    ``background`` (gray level) when known, else measured around the support."""
    nan = float("nan")
    g = np.asarray(gray, dtype=np.float64)
    m = np.asarray(support, dtype=bool)
    (cx, cy), (aw, ah), angle = ellipse
    cx, cy, aw, ah, angle = (float(v) for v in (cx, cy, aw, ah, angle))
    if not np.all(np.isfinite([cx, cy, aw, ah, angle])):
        return _failed(np.array([nan, nan]), "the light's outline is not finite")
    theta = np.deg2rad(angle)
    if axis == "columns":  # work in readout coordinates: lines down axis 0
        g, m, cx, cy, theta = g.T, m.T, cy, cx, 0.5 * np.pi - theta
    (ly, lx, value), clipped, background = _pixels(g, m, background)
    radius = 0.25 * (aw + ah)
    if ly.size < 30 or not np.isfinite(background) or radius <= 0:
        return _failed(np.array([nan, nan]), "too few pixels")
    if not (m[ly, lx]).any():  # only the background around a disc clipped all over
        return _failed(np.array([nan, nan]), "the light is clipped all over", conclusive=True)
    cs = (float(np.cos(theta)), float(np.sin(theta)))

    n_lines = g.shape[0]
    bin_px = max(_BIN_PX, radius / _BINS_PER_RADIUS)
    every = max(1, ly.size // _GEOMETRY_PIXELS)  # the geometry needs a few thousand pixels

    uv = along_axes(lx, ly, cs)
    pixels = (ly, lx, value)

    def fit(p: np.ndarray, g0, iters: int, step: int = 1):
        y, v = ly[::step], value[::step]
        return shape_fit(
            aggregate(elliptical_radius(uv[:, ::step], p, cs), y, v, n_lines, bin_px), g0, iters
        )

    # starts: the given outline and the support's, each round and with the given axis ratio
    ratio = np.clip(np.log(max(aw, 1e-6) / max(ah, 1e-6)), -MAX_LOG_RATIO, MAX_LOG_RATIO)
    centres = [(cx, cy)]
    other = outline_ellipse(m, "rows")  # m is in readout coordinates already
    if other is not None:
        centres.append(other[0])
    starts = [np.array([x, y, r]) for x, y in centres for r in (0.0, ratio)]
    start = min(starts, key=lambda p: fit(p, None, 6, every)[0])
    warm = fit(start, None, 8)[3]

    if refine:
        start = search_centre(lambda p: fit(p, warm, 2, every)[0], start)
    return RadialShape(start, warm, fit, clipped, cs, bin_px, background, n_lines, pixels)


def search_centre(cost, start: np.ndarray, step_px: float = 1.0) -> np.ndarray:
    """Nelder-Mead over a light's ``[x, y, log axis ratio]`` from ``start`` (pixels, pixels,
    natural log), on ``cost`` relative to the start's, first steps of ``step_px`` and 0.1;
    the end, shape (3,)."""
    unit = max(cost(start), 1e-12)

    from scipy.optimize import minimize  # here: SciPy's import costs 0.3 s

    simplex = start + np.vstack([np.zeros(3), np.diag([step_px, step_px, 0.1])])
    res = minimize(
        lambda p: cost(p) / unit,
        start,
        method="Nelder-Mead",
        options={"xatol": 0.03, "fatol": 1e-5, "maxfev": 80, "initial_simplex": simplex},
    )
    return np.asarray(res.x, dtype=float)


@path("light's waveform")
@one_blas_thread
def separated_wave(gray: np.ndarray, support: np.ndarray, ellipse, axis: str):
    """A round light's waveform per line, separated from its radial shape: the lines with
    signal, the waveform and its weight, the clipped lines' lower bounds and their weights,
    and the shape's centre ``[x, y]`` in the region; or a failed :class:`LightWave` with
    why.  The arguments are as :func:`light_wave`'s, whose first step this is."""
    fitted = radial_shape(gray, support, ellipse, axis)
    if isinstance(fitted, LightWave):
        return fitted
    cy_, cx_ = fitted.clipped
    _, s, weight, shape = fitted.fit(fitted.best, fitted.warm, 12)
    bound_lines, bounds, bound_weight = _clip_bounds(
        elliptical_radius(along_axes(cx_, cy_, fitted.cs), fitted.best, fitted.cs) / fitted.bin_px,
        cy_,
        shape,
        _CLIP - fitted.background,
        fitted.n_lines,
    )
    weight = np.where(weight >= 1e-3 * weight.max(), weight, 0.0)
    centre = np.array(fitted.best[:2], dtype=float)
    if axis == "columns":
        centre = centre[::-1]
    lines = np.arange(fitted.n_lines, dtype=float)
    return lines, s, weight, bound_lines, bounds, bound_weight, centre


def _failed(centre: np.ndarray, message: str, conclusive: bool = False) -> LightWave:
    """A failed :class:`LightWave` with its ``message``."""
    nan = float("nan")
    return LightWave(nan, nan, nan, (nan, nan), centre, nan, message, conclusive)
