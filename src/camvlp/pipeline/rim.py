"""A light's shape as the pixel grid sees it, fitted with its square wave to its pixels.

:func:`camvlp.pipeline.light_wave.light_wave` separates a light's waveform ``s(line)`` from
its shape ``g``.  A saturated light shows its waveform only where it does not clip: in its
dark stripes, and in the bright ones at the outer edge of its rim, where the shape falls from
full (four times the clipping level, say) to nothing over a pixel or two.  There the fit must
know the shape to a per cent, and a function of the elliptical radius alone is not one: a
disc's edge crosses each pixel differently and the blur mixes each pixel with its neighbours
on the square grid, so pixels at one radius differ by 2 % of the light's level and more.

Here the shape is modelled as it forms: a radial shape ``h`` (piecewise linear in the
elliptical radius, knots half a pixel apart), sampled at the centres of the pixels, then
blurred on the pixel grid by a Gaussian of ``sigma`` pixels (the 21 pixels within sqrt(5) px):

    g(p) = sum over q of K_sigma(q - p) h(rho(q)).

A disc's edge is a step that a pixel's area turns into a ramp one pixel wide; the knots are
offset by ``phi`` so that two of them fall on the ramp's ends, and the ramp is drawn exactly.
A hot core, a halo or a soft edge are radial shapes too, drawn by ``h``.

The pixels are then fitted with the light's physics as a whole, ``g(p) * S(line)``, ``S`` the
50 % square wave integrated over its window (``low + (high - low) * integrated``, as
:func:`~camvlp.pipeline.light_wave.fit_square_wave` fits it), each clipped pixel next to an
unclipped one a lower bound: ``h``, the centre, the axis ratio, ``phi``, ``sigma`` and the
wave's period, phase, window and levels together, by Levenberg-Marquardt (analytic
derivatives but for the wave's three timing parameters).  The prediction of an unclipped
pixel is clipped at the sensor's full scale: a pixel the light saturates reads the full
scale, less a JPEG's ringing (which can put it under the clipping threshold), not its
light; fitted as a level, such a pixel pulled a saturated light's period by up to 1.9 %.
A wave free per line, as
:func:`~camvlp.pipeline.light_wave.light_wave` fits it, trades a bright line's level against
the light's outline along the readout; the square wave's one high level for every bright
line does not.  The fit starts from the radial fit's centre and from the outline's (round),
and keeps the better.
"""

from __future__ import annotations

from typing import NamedTuple

import cv2
import numpy as np

__all__ = ["GridShape", "grid_shape_at", "refine_wave"]

#: Half-width of the blur's kernel, pixels.
_TAPS = 2
#: Bounds of the fitted blur, pixels.
_SIGMA = (0.3, 1.5)
#: Blur to start from, pixels.
_SIGMA0 = 0.8
#: The knots of the radial shape begin this many bins before the offset ``phi``.
_KNOT0 = 2.0
#: Weight of the radial shape's second differences (its curvature) in the fit, relative to
#: the mean diagonal of the shape's normal equations: only shapes the blur hides are damped.
_SMOOTH = 1e-6
#: Iterations from each start, and for the best one after.
_START_ITERS = 4
_ITERS = 12
#: Relative decrease of the cost under which the fit stops.
_TOL = 1e-3
#: Shortest window of the square wave, lines.
_MIN_WINDOW = 1.0
#: Largest axis ratio (natural log).
_MAX_LOG_RATIO = float(np.log(20.0))


class GridShape(NamedTuple):
    """A light's shape on the pixel grid (:func:`_fit_grid_shape`).

    ``geometry``: centre x, y (pixels, readout coordinates: lines down axis 0), log axis
    ratio, the knots' offset ``phi`` (pixels) and the blur ``sigma`` (pixels); ``h``: the
    radial shape per knot (its largest magnitude 1); ``wave``: the square wave's period,
    phase and window (lines), its low and high level (gray levels where ``h`` is 1);
    ``cost``: the sum of the residuals squared; ``profile``: the waveform per line that the
    shape gives (:func:`_line_profile`; set by :func:`refine_wave`).
    """

    geometry: np.ndarray
    h: np.ndarray
    wave: np.ndarray
    cost: float
    profile: tuple = ()


_OFFSETS = np.arange(-_TAPS, _TAPS + 1, dtype=float)
_DY, _DX = (v.ravel() for v in np.meshgrid(_OFFSETS, _OFFSETS, indexing="ij"))
#: The taps kept: within sqrt(5) px of the centre (a blur of 0.8 px puts 0.4 % of its
#: weight beyond).
_KEEP = _DY**2 + _DX**2 <= 5.0
_DY, _DX = _DY[_KEEP], _DX[_KEEP]


def _kernel(sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """The blur's 2-D taps (offsets ``_DY``, ``_DX``), summing to 1, and their derivative
    in ``sigma``; each shape (T,)."""
    e = np.exp(-0.5 * (_OFFSETS / sigma) ** 2)
    de = e * _OFFSETS**2 / sigma**3
    k2 = np.outer(e, e).ravel()[_KEEP]
    dk2 = (np.outer(de, e) + np.outer(e, de)).ravel()[_KEEP]
    total = k2.sum()
    return k2 / total, (dk2 - k2 * (dk2.sum() / total)) / total


def _knots_at(x, y, geometry, cs, bin_px: float, derivatives: bool = False):
    """Knot coordinate (bins from knot 0) of points ``(x, y)``: their elliptical radius about
    the centre ``geometry[:2]``, with the axis ratio ``exp(geometry[2])`` along ``cs`` = (cos,
    sin), less the offset ``geometry[3]``; with ``derivatives``, also its derivatives in the
    centre, the log ratio and the offset (a list of four arrays of the points' shape)."""
    c, s = cs
    dx, dy = x - geometry[0], y - geometry[1]
    u, v = dx * c + dy * s, dy * c - dx * s
    r = float(np.clip(geometry[2], -_MAX_LOG_RATIO, _MAX_LOG_RATIO))
    a, b = np.exp(-0.5 * r), np.exp(0.5 * r)
    rho = np.hypot(u * a, v * b)
    f = (rho - geometry[3]) / bin_px + _KNOT0
    if not derivatives:
        return f
    inv = 1.0 / (np.maximum(rho, 1e-9) * bin_px)
    ua, vb = u * (a * a) * inv, v * (b * b) * inv
    return f, [
        -c * ua + s * vb,
        -s * ua - c * vb,
        0.5 * (v * vb - u * ua),
        np.full_like(f, -1.0 / bin_px),
    ]


def _interp(f: np.ndarray, h: np.ndarray):
    """``h`` (knots) linearly interpolated at knot coordinates ``f``: (value, slope per knot,
    lower knot, fraction)."""
    i0 = np.clip(f.astype(np.intp), 0, h.size - 2)  # f > 0: truncation is the floor
    t = np.clip(f - i0, 0.0, 1.0)
    lo, hi = h[i0], h[i0 + 1]
    return lo + t * (hi - lo), hi - lo, i0, t


def grid_shape_at(ly, lx, geometry, cs, bin_px: float, h: np.ndarray) -> np.ndarray:
    """The shape ``g`` (N,) at pixels ``(ly, lx)`` (readout coordinates) of a fitted
    :class:`GridShape`'s ``geometry`` and ``h``."""
    if ly.size == 0:
        return np.zeros(0)
    return _shape(_Taps.of(ly, lx), geometry, cs, bin_px, h)


class _Taps(NamedTuple):
    """The pixels the blur's taps reach from pixels ``(ly, lx)`` (N,): each once, ``uy``,
    ``ux`` (U,), and ``nb`` (N, T) the index of each tap's pixel there.  The radial shape is
    evaluated once per pixel reached, not once per tap (T = 21 times as often)."""

    uy: np.ndarray
    ux: np.ndarray
    nb: np.ndarray

    @classmethod
    def of(cls, ly: np.ndarray, lx: np.ndarray) -> _Taps:
        """The taps of pixels ``(ly, lx)``, integer coordinates, shape (N,)."""
        ty = (np.asarray(ly)[:, None] + _DY).astype(np.int64)
        tx = (np.asarray(lx)[:, None] + _DX).astype(np.int64)
        y0, x0 = int(ty.min()), int(tx.min())
        span = int(tx.max()) - x0 + 1
        keys, nb = np.unique((ty - y0) * span + (tx - x0), return_inverse=True)
        return cls(
            (keys // span + y0).astype(float),
            (keys % span + x0).astype(float),
            nb.reshape(ty.shape),
        )


def _shape(taps: _Taps, geometry, cs, bin_px: float, h: np.ndarray) -> np.ndarray:
    """:func:`grid_shape_at` at the pixels of ``taps``, shape (N,)."""
    f = _knots_at(taps.ux, taps.uy, geometry, cs, bin_px)
    return _interp(f, h)[0][taps.nb] @ _kernel(float(geometry[4]))[0]


class _Data(NamedTuple):
    """The pixels of a fit: ``ly``, ``lx`` (N,) unclipped then clipped, ``target`` (N,) the
    unclipped levels and the clipped ones' clipping level, ``n_free`` unclipped pixels, and
    ``root`` (N,) the square root of each pixel's weight, ``taps`` the pixels the blur
    reaches from them, and ``full`` the sensor's full scale (levels above the background): an
    unclipped pixel whose light would pass it reads the full scale, less the error of a JPEG
    (which rings below it), not its light."""

    ly: np.ndarray
    lx: np.ndarray
    target: np.ndarray
    n_free: int
    n_lines: int
    root: np.ndarray
    taps: _Taps
    full: float


class _State(NamedTuple):
    g: np.ndarray  # shape per pixel (N,), unclipped then clipped
    s: np.ndarray  # waveform per line (L,)
    r: np.ndarray  # residual per pixel (0 where a clipped pixel's prediction clips)
    cost: float
    live: np.ndarray  # per pixel (N,): whether its residual moves with the prediction


def _wave(lines: np.ndarray, w: np.ndarray, integrated) -> np.ndarray:
    """The waveform per line: ``low + (high - low) * integrated(lines, period, phase,
    window)`` for ``w`` = (period, phase, window, low, high)."""
    return w[3] + (w[4] - w[3]) * integrated(lines, w[0], w[1], w[2])


def _state(data: _Data, geometry, cs, bin_px, h, w, integrated) -> _State:
    """The shape and waveform of these parameters and their residuals."""
    g = _shape(data.taps, geometry, cs, bin_px, h)
    s = _wave(np.arange(data.n_lines, dtype=float), w, integrated)
    predicted = s[data.ly] * g
    live = predicted < data.full  # an unclipped pixel's light reaching the full scale: clipped
    r = data.target - np.minimum(predicted, data.full)
    r[data.n_free :] = np.maximum(r[data.n_free :], 0.0)  # a clipped pixel: at least
    live[data.n_free :] = r[data.n_free :] > 0  # a clipped pixel whose bound binds
    r *= data.root
    return _State(g, s, r, float(r @ r), live)


def _jacobian(data: _Data, geometry, cs, bin_px, h, w, integrated, st: _State):
    """The prediction's derivatives: in ``h`` as (first knot (N,), weights on the knots from
    it (N, M)), and in (geometry, waveform) as (N, 10)."""
    n, nb = data.ly.size, data.taps.nb
    f, df = _knots_at(data.taps.ux, data.taps.uy, geometry, cs, bin_px, True)
    k, dk = _kernel(float(geometry[4]))
    value, slope, i0, t = _interp(f, h)
    i0, t = i0[nb], t[nb]
    k0 = i0.min(axis=1)
    rel = i0 - k0[:, None]
    m = int(rel.max()) + 2
    base = (np.arange(n) * m)[:, None] + rel
    b = np.bincount(
        np.concatenate([base.ravel(), base.ravel() + 1]),
        np.concatenate([(k * (1.0 - t)).ravel(), (k * t).ravel()]),
        minlength=n * m,
    ).reshape(n, m)
    s_p = st.s[data.ly]
    jo = np.empty((n, 10))
    for j in range(4):
        jo[:, j] = (slope * df[j])[nb] @ k
    jo[:, 4] = value[nb] @ dk
    jo[:, :5] *= s_p[:, None]
    lines = np.arange(data.n_lines, dtype=float)
    step = 1e-3 * w[0]
    for j in range(3):
        wm = w.copy()
        wm[j] += step
        jo[:, 5 + j] = st.g * ((_wave(lines, wm, integrated) - st.s) / step)[data.ly]
    frac = (st.s - w[3]) / (w[4] - w[3]) if w[4] != w[3] else np.zeros(data.n_lines)
    jo[:, 8] = st.g * (1.0 - frac)[data.ly]
    jo[:, 9] = st.g * frac[data.ly]
    active = data.root * st.live
    jo *= active[:, None]
    return k0, b * (s_p * active)[:, None], jo


def _normal_equations(data: _Data, geometry, cs, bin_px, h, w, integrated, st: _State):
    """Gauss-Newton's normal equations in (h, geometry, waveform): (matrix, right side)."""
    n_knots = h.size
    k0, jh, jo = _jacobian(data, geometry, cs, bin_px, h, w, integrated, st)
    cols = np.minimum(k0[:, None] + np.arange(jh.shape[1]), n_knots - 1)
    n = n_knots + jo.shape[1]
    a = np.zeros((n, n))
    pairs = (cols[:, :, None] * n_knots + cols[:, None, :]).ravel()
    a[:n_knots, :n_knots] = np.bincount(
        pairs, (jh[:, :, None] * jh[:, None, :]).ravel(), minlength=n_knots * n_knots
    ).reshape(n_knots, n_knots)
    flat = cols.ravel()
    for i in range(jo.shape[1]):
        a[:n_knots, n_knots + i] = np.bincount(
            flat, (jh * jo[:, i, None]).ravel(), minlength=n_knots
        )
    a[n_knots:, n_knots:] = jo.T @ jo
    a[n_knots:, :n_knots] = a[:n_knots, n_knots:].T
    rhs = np.concatenate(
        [np.bincount(flat, (jh * st.r[:, None]).ravel(), minlength=n_knots), jo.T @ st.r]
    )
    return a, rhs


def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """``x`` with ``a @ x = b`` (a of shape (n, n), b (n,)), None when ``a`` is singular.

    By OpenCV's LU decomposition, on one thread: NumPy's LAPACK runs these systems of a
    hundred unknowns on all the BLAS threads, which took 10 to 70 ms a solve instead of
    0.2 ms on a loaded machine (the threads waiting for cores)."""
    ok, x = cv2.solve(a, b.reshape(-1, 1), flags=cv2.DECOMP_LU)
    return x.reshape(-1) if ok else None


def _curvature(n: int) -> np.ndarray:
    """The second differences' normal matrix, shape (n, n): ``d.T @ d`` for ``d`` the
    (n - 2, n) second differences, summed row by row of ``d`` (no matrix product)."""
    a = np.zeros((n, n))
    c = np.array([1.0, -2.0, 1.0])
    j = np.arange(max(n - 2, 0))[:, None, None]
    p, q = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    np.add.at(a, (j + p, j + q), np.broadcast_to(np.outer(c, c), (j.size, 3, 3)))
    return a


def _fit_grid_shape(
    data: _Data,
    start: np.ndarray,
    wave: np.ndarray,
    cs: tuple[float, float],
    bin_px: float,
    h0,
    integrated,
    iters: int = 12,
    fit_geometry: bool = True,
) -> GridShape:
    """Fit the pixels' levels with the light's shape on the pixel grid times its waveform.

    Parameters
    ----------
    data : _Data
        The pixels.
    start : ndarray, shape (5,)
        Geometry to start from: centre x, y (px), log axis ratio, knots' offset ``phi``
        (px, 0 to ``bin_px``), blur ``sigma`` (px).
    wave : ndarray, shape (5,)
        The waveform to start from: period, phase, window (lines), low and high level.
    cs : tuple of float
        Cos and sin of the angle of the ellipse's first axis from the x axis.
    bin_px : float
        Spacing of the radial shape's knots, pixels.
    h0 : callable
        The radial shape to start from, as a function of the radius (pixels).
    integrated : callable
        ``integrated(lines, period, phase, window)``: the square wave integrated, 0 to 1.
    iters : int
        Levenberg-Marquardt iterations.
    fit_geometry : bool
        Whether the geometry is fitted (else only the shape and the waveform).

    Returns
    -------
    GridShape
    """
    geometry = np.asarray(start, dtype=float).copy()
    w = np.asarray(wave, dtype=float).copy()
    ends = _OFFSETS[[0, -1]]
    reach = _knots_at(data.lx[:, None] + ends, data.ly[:, None] + ends, geometry, cs, bin_px)
    n_knots = int(np.nanmax(reach)) + 6
    h = np.asarray(h0((np.arange(n_knots) - _KNOT0) * bin_px + geometry[3]), dtype=float)
    st = _state(data, geometry, cs, bin_px, h, w, integrated)
    curv = _curvature(n_knots)
    mu = 1e-3
    fixed = np.zeros(n_knots + 10, dtype=bool)
    if not fit_geometry:
        fixed[n_knots : n_knots + 5] = True
    for _ in range(iters):
        a, rhs = _normal_equations(data, geometry, cs, bin_px, h, w, integrated, st)
        a[fixed, :] = 0.0
        a[:, fixed] = 0.0
        rhs[fixed] = 0.0
        diag = np.diag(a).copy()
        weight = _SMOOTH * float(np.mean(diag[:n_knots]))
        a[:n_knots, :n_knots] += weight * curv
        rhs[:n_knots] -= weight * (curv @ h)
        scale = np.maximum(diag, 1e-9 * max(float(diag.max()), 1e-300))
        before = st.cost + weight * float(h @ curv @ h)
        for _ in range(8):
            step = _solve(a + mu * np.diag(scale), rhs)
            if step is None:
                mu *= 10.0
                continue
            hn = h + step[:n_knots]
            gn = geometry + step[n_knots : n_knots + 5]
            gn[4] = float(np.clip(gn[4], *_SIGMA))
            gn[3] = float(np.clip(gn[3], -bin_px, 1.9 * bin_px))
            wn = w + step[n_knots + 5 :]
            wn[2] = float(np.clip(wn[2], _MIN_WINDOW, 0.5 * wn[0]))
            stn = _state(data, gn, cs, bin_px, hn, wn, integrated)
            after = stn.cost + weight * float(hn @ curv @ hn)
            if after <= before:
                h, geometry, w, st = hn, gn, wn, stn
                mu = max(mu * 0.1, 1e-9)
                break
            mu *= 10.0
        else:
            break
        if after > (1.0 - _TOL) * before:
            break
    top = float(np.max(np.abs(h))) or 1.0
    w[3:] *= top
    return GridShape(geometry, h / top, w, st.cost)


def refine_wave(
    free: tuple[np.ndarray, np.ndarray, np.ndarray],
    clipped: tuple[np.ndarray, np.ndarray],
    clip_level: float,
    n_lines: int,
    starts: list[np.ndarray],
    wave: np.ndarray,
    h0,
    cs: tuple[float, float],
    bin_px: float,
    integrated,
    full_level: float = np.inf,
) -> GridShape:
    """The light's shape on the pixel grid and its square wave, fitted to its pixels together
    (:func:`_fit_grid_shape`) from each of ``starts``; the fit with the least cost.

    Parameters
    ----------
    free : tuple of ndarray, each shape (N,)
        Lines, positions along them and levels above the background of the unclipped pixels
        (readout coordinates).
    clipped : tuple of ndarray, each shape (M,)
        Lines and positions of the clipped pixels; those within 2 px of an unclipped one
        enter the fit, as lower bounds.
    clip_level : float
        The clipping level above the background.
    n_lines : int
        Lines of the region.
    starts : list of ndarray, each shape (3,)
        Centres x, y (px) and log axis ratios to start from.
    wave : ndarray, shape (5,)
        The square wave to start from (period, phase, window, low, high).
    h0 : callable
        The radial shape to start from (levels where the wave is 1), of the radius (px).
    cs, bin_px, integrated
        As :func:`_fit_grid_shape` takes them.
    full_level : float
        The sensor's full scale above the background: the fit clips its prediction of the
        unclipped pixels there (inf: no clipping).
    """
    ly, lx, value = free
    cy, cx = clipped
    width = int(max(lx.max(initial=0), cx.max(initial=0))) + 1
    mask = np.zeros((n_lines, width), np.uint8)
    mask[ly, lx] = 1
    near = cv2.dilate(mask, np.ones((5, 5), np.uint8)).astype(bool)[cy, cx]
    # the knots' offset: the ends of a ramp one pixel wide about the shape's steepest fall
    radii = np.arange(0.0, float(np.hypot(*np.ptp([lx, ly], axis=1))) + 1.0, 0.05)
    edge = float(radii[np.argmin(np.gradient(h0(radii)))])
    phi = (edge - 0.5) % bin_px
    all_y, all_x = np.concatenate([ly, cy[near]]), np.concatenate([lx, cx[near]])
    data = _Data(
        all_y,
        all_x,
        np.concatenate([value, np.full(int(near.sum()), float(clip_level))]),
        ly.size,
        n_lines,
        np.ones(all_y.size),
        _Taps.of(all_y, all_x),
        float(full_level),
    )
    fits = [
        _fit_grid_shape(
            data,
            np.array([*start[:3], phi, _SIGMA0]),
            wave,
            cs,
            bin_px,
            h0,
            integrated,
            iters=_START_ITERS,
        )
        for start in starts
    ]
    best = min(fits, key=lambda t: t.cost)
    fit = _continued(data, best, cs, bin_px, integrated, _ITERS)
    return fit._replace(profile=_line_profile(data, fit, cs, bin_px))


def _line_profile(data: _Data, fit: GridShape, cs, bin_px: float) -> tuple[np.ndarray, ...]:
    """The waveform per line given the fitted shape, as
    :func:`~camvlp.pipeline.square_wave.fit_square_wave` takes a profile: ``(lines, signal,
    weight, bound_lines, bounds, bound_weight)``, each shape (L,).

    Per line, the least-squares level of its unclipped pixels (``sum(v g) / sum(g ** 2)``,
    weight ``sum(g ** 2)``: their cost is the profile's, up to a constant; lines with under
    1e-3 of the largest weight are left out), and the bound its
    clipped pixels set (the clipping level over the largest shape among them, weight the sum
    of their shapes squared).
    """
    n, free = data.n_lines, data.n_free
    g = _shape(data.taps, fit.geometry, cs, bin_px, fit.h)
    ly = data.ly.astype(np.intp)
    wg = data.root**2 * g
    den = np.bincount(ly[:free], wg[:free] * g[:free], minlength=n)
    num = np.bincount(ly[:free], data.target[:free] * wg[:free], minlength=n)
    den[den < 1e-3 * den.max(initial=0.0)] = 0.0  # lines with next to nothing
    signal = np.divide(num, den, out=np.zeros(n), where=den > 0)
    top = np.zeros(n)
    np.maximum.at(top, ly[free:], g[free:])
    clip = data.target[free:][0] if data.target.size > free else 0.0
    bounds = np.divide(clip, top, out=np.zeros(n), where=top > 0)
    lines = np.arange(n, dtype=float)
    return (
        lines,
        signal,
        den,
        lines,
        bounds,
        np.bincount(ly[free:], wg[free:] * g[free:], minlength=n),
    )


def _continued(data: _Data, fit: GridShape, cs, bin_px: float, integrated, iters: int):
    """:func:`_fit_grid_shape` continued from ``fit`` for ``iters`` more iterations."""
    knots = (np.arange(fit.h.size) - _KNOT0) * bin_px + fit.geometry[3]
    return _fit_grid_shape(
        data,
        fit.geometry,
        fit.wave,
        cs,
        bin_px,
        lambda rho: np.interp(rho, knots, fit.h),
        integrated,
        iters=iters,
    )
