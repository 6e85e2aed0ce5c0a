"""The best precision any measurement of a light's frequency could reach (Cramér-Rao bound).

A frequency-coded light's image is ``ambient + brightness * colour * shape(u, v) *
on(line)``, clipped at full scale, plus noise (:mod:`camvlp.sim.render`'s physics).  Its
frequency is measured from ``on``, the fraction of each sensor line's exposure window the
LED is on.  How well that can be done at best depends on how many stripe edges the light
shows, how many pixels see them unclipped, and the noise: the Cramér-Rao bound gives the
smallest standard deviation an unbiased measurement can have.

This module computes it from the renderer's own physics, with the light's shape taken as
known (a measurement must also find it, so the true limit is, if anything, looser) and
with these unknowns besides the frequency: the LED's phase, the exposure window (exposure
plus a slow driver's smoothing), the brightness, the ambient level and the LED's off level.
A clipped pixel (mean at full scale or above) tells nothing; the noise of each pixel is
shot noise, read noise, 8-bit quantisation and, when given, JPEG's error.  The bound is
local (small errors) and Gaussian: for a light whose every edge falls in clipped rows it
is loose, and sharp stripes make it slightly optimistic between rows.  Where the pixels
leave the frequency undetermined (a null direction of the information that moves it) it is
infinite: stripes sharper than a line, each edge caught by one line at most, fit as well a
shorter window with every edge moved in proportion (:func:`_frequency_sigma`).  It answers "could
any method have measured this light within 1 %?", the reference against which
``benchmarks/bench_frequency.py`` reads its misses.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.decode.beacon import square_wave
from camvlp.sim.render import LightPatch, light_patches
from camvlp.sim.settings import RenderSettings

__all__ = ["frequency_bounds", "frequency_intervals", "share_within"]

#: Relative step of the numerical derivatives (of the frequency, and of the window).
_STEP = 1e-5
#: Relative step of the derivatives of the light's look (blur, hot core, halo).
_SHAPE_STEP = 1e-3


def frequency_bounds(
    camera: Camera,
    fixture_map: FixtureMap,
    pose: Pose,
    settings: RenderSettings,
    jpeg_error: np.ndarray | None = None,
) -> np.ndarray:
    """Cramér-Rao bound of each light's relative frequency error.

    Parameters
    ----------
    camera, fixture_map, pose, settings
        The scene as given to :func:`camvlp.sim.render.render` (a ``"frequency"`` map).
    jpeg_error : ndarray, shape (H, W) or (H, W, 3), optional
        The error JPEG added to the rendered image (decoded minus original, in 8-bit levels);
        its mean square over each light's box joins that light's pixel noise.

    Returns
    -------
    ndarray of float64, shape (N,)
        Per fixture in map order, the smallest standard deviation of ``measured / true - 1``
        an unbiased measurement could have (a fraction: 0.01 is 1 %); ``inf`` when its
        pixels tell nothing of the frequency, NaN for a fixture not drawn or sending data
        (``settings.data_lights``: it has no frequency).
    """
    if fixture_map.mode != "frequency":
        raise ValueError("frequency bounds need a frequency-coded map")
    s = settings.resolved(camera)
    out = np.full(len(fixture_map.fixtures), np.nan)
    lights = light_patches(camera, fixture_map, pose, s)
    moved = {  # the lights rendered with one shape setting a little smaller and larger
        name: [
            {p.index: p for p in light_patches(camera, fixture_map, pose, _scaled(s, name, k))}
            for k in (-_SHAPE_STEP, _SHAPE_STEP)
        ]
        for name in ("blur_px", "core", "halo")
        if getattr(s, name) > 0
    }
    for light in _beacons(lights, fixture_map, s):
        extra = _jpeg_variance(light, jpeg_error)
        d_shape = _geometry_derivatives(light.shape)
        for name, (lower, upper) in moved.items():
            a, b = lower.get(light.index), upper.get(light.index)
            if a is not None and b is not None and a.box == light.box == b.box:
                d_shape.append(
                    (b.shape.astype(np.float64) - a.shape)
                    / (2.0 * _SHAPE_STEP * getattr(s, name))
                    * getattr(s, name)
                )
        out[light.index] = _bound(light, s, extra, d_shape)
    return out


def _beacons(lights: list, fixture_map: FixtureMap, s: RenderSettings) -> list[LightPatch]:
    """The lights of ``lights`` that blink their frequency (not those sending data)."""
    return [p for p in lights if fixture_map.fixtures[p.index].id not in s.data_lights]


def _jpeg_variance(light: LightPatch, jpeg_error: np.ndarray | None) -> float:
    """The mean square of JPEG's error over the light's box, full-scale units squared."""
    if jpeg_error is None:
        return 0.0
    u0, u1, v0, v1 = light.box
    return float(np.mean((np.asarray(jpeg_error, dtype=np.float64)[v0:v1, u0:u1] / 255.0) ** 2))


def _variance(mean: np.ndarray, s: RenderSettings, extra_var: float) -> np.ndarray:
    """Each pixel's noise variance at its mean level ``mean`` (full-scale units): shot noise,
    read noise, 8-bit steps and ``extra_var``."""
    var = np.maximum(mean, 0.0) / s.full_well_e if s.full_well_e > 0 else 0.0
    return var + s.read_noise**2 + 1.0 / (12.0 * 255.0**2) + extra_var


def frequency_intervals(
    camera: Camera,
    fixture_map: FixtureMap,
    pose: Pose,
    settings: RenderSettings,
    jpeg_error: np.ndarray | None = None,
) -> np.ndarray:
    """The frequencies each light's pixels cannot tell from its own, within their noise.

    Where the bound (:func:`frequency_bounds`) is local, this is global along the frequency:
    the light's noise-free waveform per line (the renderer's on-fraction), each line weighted
    by its information (the sum over its unclipped pixels of their level squared over their
    variance), is fitted with a 50 % square wave integrated over a window at frequencies
    stepping away from the true one, phase, window and levels free
    (:func:`consistent_periods`); those whose best fit costs at
    most one (one standard deviation of the noise) more than the truth are consistent with
    it.  Stripes sharper than a line make a whole range consistent, however little the noise.
    The shape is taken as known and the clipped pixels as telling nothing.

    Parameters are as :func:`frequency_bounds` takes them.

    Returns
    -------
    ndarray of float64, shape (N, 2)
        Per fixture in map order, the least and largest ``frequency / true - 1`` consistent
        with its pixels (fractions; searched to +-5 %: a range reaching that far may reach
        further); NaN for a fixture not drawn, without information, or sending data.
    """
    s = settings.resolved(camera)
    out = np.full((len(fixture_map.fixtures), 2), np.nan)
    for light in _beacons(light_patches(camera, fixture_map, pose, s), fixture_map, s):
        on = light.on_fraction(s.row_time_s, s.exposure_s, s.off_level)
        info = np.zeros(on.size)
        for c in np.asarray(light.colour, dtype=np.float64):
            lit = s.brightness * c * light.shape.astype(np.float64)
            mean = s.ambient + lit * (on[:, None] if s.readout.by_rows else on[None, :])
            w = np.where(
                mean < 1.0, lit**2 / _variance(mean, s, _jpeg_variance(light, jpeg_error)), 0.0
            )
            info += w.sum(axis=1 if s.readout.by_rows else 0) if c > 0 else 0.0
        if not info.any():
            continue
        rt = s.row_time_s
        period = light.chips.size * light.chip_s / rt
        window = (s.exposure_s + light.smooth_s) / rt
        # the renderer's window starts at the line's time; the fit's is centred on it
        phase = -(light.phase_s + 0.5 * s.exposure_s) / rt
        if window > 0.5 * period:  # the same shape, up to its levels
            window = period - window
        lo, hi = consistent_periods(light.lines, on, info, (period, phase, window))
        out[light.index] = (1.0 / (1.0 + hi) - 1.0, 1.0 / (1.0 + lo) - 1.0)
    return out


def _scaled(s: RenderSettings, name: str, k: float) -> RenderSettings:
    """``s`` with setting ``name`` scaled by ``1 + k``."""
    return dataclasses.replace(s, **{name: getattr(s, name) * (1.0 + k)})


def _geometry_derivatives(shape: np.ndarray) -> list[np.ndarray]:
    """Derivatives of a light's image (shape (h, w)) when it moves one pixel across, one
    down, and when it grows by a fraction (about its centre of light)."""
    f = shape.astype(np.float64)
    dv, du = np.gradient(f)
    total = f.sum()
    if total <= 0:
        return [-du, -dv]
    vv, uu = np.indices(f.shape, dtype=np.float64)
    cu, cv = (f * uu).sum() / total, (f * vv).sum() / total
    return [-du, -dv, -((uu - cu) * du + (vv - cv) * dv)]


def share_within(sigma: np.ndarray, tolerance: float = 0.01) -> np.ndarray:
    """Probability that a Gaussian, unbiased error of standard deviation ``sigma`` (a
    fraction, any shape) stays within ``tolerance``; NaN where ``sigma`` is NaN."""
    sigma = np.asarray(sigma, dtype=np.float64)
    with np.errstate(divide="ignore"):
        z = tolerance / (np.sqrt(2.0) * sigma)  # 0 for an infinite sigma
    return np.vectorize(math.erf, otypes=[np.float64])(z)


def _bound(
    light: LightPatch, s: RenderSettings, extra_var: float, d_shape: list[np.ndarray]
) -> float:
    """The bound of one light (see :func:`frequency_bounds`); ``extra_var``: added pixel
    variance, full-scale units squared; ``d_shape``: derivatives of the light's shape with
    respect to the unknowns of its geometry and look, each of the shape's shape."""
    on = light.on_fraction(s.row_time_s, s.exposure_s, s.off_level)
    period = light.chips.size * light.chip_s
    window = s.exposure_s + light.smooth_s
    d_on = {  # derivatives of the on-fraction per line, shape (K,)
        "log frequency": _central(light, s, "log_f", _STEP),
        "phase (periods)": _central(light, s, "phase", _STEP * period) * period,
        "window (log)": _central(light, s, "window", _STEP * window) * window,
        "off level": 1.0 - (on - s.off_level) / max(1.0 - s.off_level, 1e-12),
    }
    by_rows = s.readout.by_rows

    def lines(a: np.ndarray) -> np.ndarray:  # a per-line array against the box's pixels
        return a[:, None] if by_rows else a[None, :]

    n = 6 + len(d_shape)
    info = np.zeros((n, n))
    for c in np.asarray(light.colour, dtype=np.float64):
        if c <= 0:
            continue
        lit = s.brightness * c * light.shape.astype(np.float64)
        mean = s.ambient + lit * lines(on)
        unclipped = mean < 1.0
        grads = [lit * lines(d) for d in d_on.values()]
        grads.append(lit * lines(on))  # d / d log brightness
        grads.append(np.ones_like(mean))  # d / d ambient
        grads += [s.brightness * c * d * lines(on) for d in d_shape]
        var = _variance(mean, s, extra_var)
        g = np.stack([np.where(unclipped, x, 0.0).ravel() for x in grads])
        w = (np.ones_like(mean) / var).ravel()
        info += (g * w) @ g.T
    info[np.abs(info) < 1e-300] = 0.0
    return _frequency_sigma(info)


def _frequency_sigma(info: np.ndarray) -> float:
    """The bound's standard deviation of the first unknown (the log frequency) from the
    Fisher information ``info`` (n, n): ``inf`` when the information leaves it undetermined.

    A singular information has a null direction: a change of the unknowns the pixels do not
    see.  If that change moves the frequency (sharp stripes sampled at one line per edge: a
    shorter window with the edges moved in proportion looks the same), the frequency is not
    determined at all; otherwise the null direction is left out (a pseudo-inverse).
    """
    if info[0, 0] <= 0:
        return float("inf")
    d = np.sqrt(np.maximum(np.diag(info), 1e-300))
    try:
        value, vector = np.linalg.eigh(info / np.outer(d, d))
    except np.linalg.LinAlgError:
        return float("inf")
    null = value <= 1e-10 * value.max()
    if np.any(np.abs(vector[0, null]) > 1e-6):
        return float("inf")
    v0 = vector[0, ~null]
    return float(np.sqrt(max(float(v0 * v0 @ (1.0 / value[~null])), 0.0)) / d[0])


def _central(light: LightPatch, s: RenderSettings, what: str, h: float) -> np.ndarray:
    """Central difference of the on-fraction per line with respect to ``what``: the log
    frequency (step ``h``), the phase (s) or the window (s)."""

    def at(sign: float) -> np.ndarray:
        chip_s, phase, exposure = light.chip_s, light.phase_s, s.exposure_s
        if what == "log_f":
            chip_s = chip_s * math.exp(-sign * h)
        elif what == "phase":
            phase = phase + sign * h
        else:
            exposure = exposure + sign * h
        moved = dataclasses.replace(light, chip_s=chip_s, phase_s=phase)
        return moved.on_fraction(s.row_time_s, exposure, s.off_level)

    return (at(1.0) - at(-1.0)) / (2.0 * h)


# The periods a noise-free line profile fits about as well as its own: a 50 % square wave
# integrated over a window, its phase, window and levels free, at periods stepping away.

#: Phases (lines, about the one that keeps the middle edge in place) and windows (lines) of
#: the grid from which :func:`_least_at` also descends.
_PROFILE_PHASES = np.linspace(-1.5, 1.5, 31)
_PROFILE_WINDOWS = np.arange(0.05, 2.0, 0.1)
#: Shortest window the fits of :func:`_least_at` take, lines.
_SHARPEST = 0.02


class _Profile(NamedTuple):
    """A light's line profile for :func:`_cost`.

    ``y``, ``s``, ``w``: the lines (shape (N,)), their signal and weights; ``bc``, ``wc``: the
    bounds and weights of the clipped lines (shape (M,)); ``lines``: both sets of lines,
    shape (N + M,), with ``wz`` the weights there and ``weights`` (shape (N + M, 2)) the
    weights and the weights times the signal (0 on the clipped lines); ``s0``, ``b0``,
    ``ss``: the sums of ``w``, ``w * s`` and ``w * s * s``.
    """

    y: np.ndarray
    s: np.ndarray
    w: np.ndarray
    bc: np.ndarray
    wc: np.ndarray
    lines: np.ndarray
    wz: np.ndarray
    weights: np.ndarray
    s0: float
    b0: float
    ss: float

    @classmethod
    def of(cls, y, s, w, yc, bc, wc) -> _Profile:
        """The profile of these lines (shape (N,)) and clipped lines (shape (M,))."""
        ws = w * s
        zeros = np.zeros(yc.size)
        lines, wz, wsz = (
            np.concatenate([y, yc]),
            np.concatenate([w, zeros]),
            np.concatenate([ws, zeros]),
        )
        weights = np.stack([wz, wsz], axis=1)
        return cls(
            y, s, w, bc, wc, lines, wz, weights, float(w.sum()), float(ws.sum()), float(ws @ s)
        )


def _cost(data: _Profile, period, phase, window) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted residual of the best low/high levels for each wave; (cost, low, high).

    The levels are the weighted least squares over the unclipped lines; each clipped line
    whose bound the wave does not reach adds its shortfall squared, weighted.  Shapes
    broadcast over the leading axes of ``period``, ``phase``, ``window`` (lines on the last
    axis); scalars give scalars.
    """
    t = square_wave(data.lines, period, phase, window)
    s0, b0 = data.s0, data.b0
    s1, b1 = np.moveaxis(t @ data.weights, -1, 0)
    if data.bc.size:
        tc = t[..., data.y.size :].copy()
    np.square(t, out=t)
    s2 = t @ data.wz
    det = s0 * s2 - s1 * s1
    with np.errstate(divide="ignore", invalid="ignore"):  # a singular fit: masked below
        low = (s2 * b0 - s1 * b1) / det
        amp = (s0 * b1 - s1 * b0) / det
        # the residual of the least squares, from the sums
        cost = np.maximum(data.ss - low * b0 - amp * b1, 0.0)
        if data.bc.size:
            short = data.bc - low[..., None] - amp[..., None] * tc
            np.maximum(short, 0.0, out=short)
            cost = cost + (data.wc * short * short).sum(-1)
        high = low + amp
    # a singular fit (one level fits all) or a light darker when on fits nothing
    bad = (np.abs(det) < 1e-12 * s0 * s0) | ~(amp > 0)
    if np.ndim(cost):
        cost[bad] = np.inf
    elif bad:
        return np.inf, 0.0, 0.0
    return cost, low, high


def _profile(data: _Profile, x, var: float, stop: float, step: float, reach: float):
    """The least cost over phase and window (:func:`_least_at`, to a hundredth of ``var``) at
    periods ``x[0] * (1 + k * step)``, ``k`` outwards from 0 (the wave ``x``: period, phase,
    window) both ways until ``|k| step`` passes ``reach`` or the cost exceeds the least so
    far by ``stop`` times ``var`` twice in a row.  Returns ``k`` (shape (K,), increasing),
    the costs (K,) and per ``k`` the ``(cost, phase, window)`` of the least."""
    p0 = float(x[0])
    # phases that keep in place the edge nearest the middle of the lines
    m = np.round((0.5 * float(data.lines.min() + data.lines.max()) - x[1]) / (0.5 * p0))
    profile = {0: (float(_cost(data, *x)[0]), float(x[1]), float(x[2]))}
    for sign in (1, -1):
        k, prev, above = sign, profile[0], 0
        while abs(k) * step <= reach + 1e-12 and above < 2:
            period = p0 * (1.0 + k * step)
            anchor = float(x[1]) + 0.5 * m * (p0 - period)
            prev = _least_at(data, period, anchor, prev[1:], 0.01 * var)
            profile[k] = prev
            least = min(v[0] for v in profile.values())
            above = above + 1 if prev[0] - least > stop * var else 0
            k += sign
    ks = np.array(sorted(profile))
    return ks, np.array([profile[k][0] for k in ks]), [profile[k] for k in ks]


def consistent_periods(
    lines, signal, weight, wave, within: float = 1.0, step: float = 5e-4, reach: float = 0.05
) -> tuple[float, float]:
    """The periods that fit a line profile about as well as ``wave`` does.

    Parameters
    ----------
    lines, signal, weight : array_like, shape (N,)
        The profile, as a line profile, the weights each line's inverse
        variance (no clipped lines).
    wave : array_like, shape (3,)
        Period, phase and window (lines) of a wave that fits it (the true one, say).
    within : float
        Largest excess of the least cost (over phase, window and levels; weighted squares)
        over the least at any period: 1 is one standard deviation.
    step, reach : float
        Step and reach of the relative periods tried, outwards from ``wave``'s.

    Returns
    -------
    lo, hi : float
        The least and largest period fitting within ``within``, relative to ``wave``'s
        (``-reach`` or ``reach`` where the fits reach that far).
    """
    y, s, w = (np.asarray(v, dtype=float).reshape(-1) for v in (lines, signal, weight))
    keep = (w > 0) & np.isfinite(s)
    empty = np.zeros(0)
    data = _Profile.of(y[keep], s[keep], w[keep], empty, empty, empty)
    ks, cost, _ = _profile(data, np.asarray(wave, dtype=float)[:3], 1.0, within, step, reach)
    ok = ks[cost - cost.min() <= within] * step
    return float(ok.min()), float(ok.max())


def _least_at(data: _Profile, period: float, anchor: float, start, fatol: float):
    """The least cost at ``period`` over phase and window, ``(cost, phase, window)``, by
    Nelder-Mead (to ``fatol`` in the cost) from ``start`` (phase, window), and from the best
    of a grid of phases about ``anchor`` and of windows (:data:`_PROFILE_PHASES`,
    :data:`_PROFILE_WINDOWS`) where that is better."""
    from scipy.optimize import minimize  # here: SciPy's import costs 0.3 s

    def objective(z: np.ndarray) -> float:
        if not _SHARPEST <= z[1] <= 0.5 * period:
            return 1e300
        return min(float(_cost(data, period, z[0], z[1])[0]), 1e300)  # inf: a singular fit

    def descend(z0: np.ndarray) -> tuple[float, float, float]:
        z0[1] = min(max(z0[1], _SHARPEST), 0.5 * period)
        simplex = z0 + np.array([[0.0, 0.0], [0.05, 0.0], [0.0, 0.05]])
        res = minimize(
            objective,
            z0,
            method="Nelder-Mead",
            options={"xatol": 1e-4, "fatol": fatol, "maxiter": 200, "initial_simplex": simplex},
        )
        return float(res.fun), float(res.x[0]), float(res.x[1])

    best = descend(np.array(start, dtype=float))
    windows = _PROFILE_WINDOWS[_PROFILE_WINDOWS <= 0.5 * period]
    phases = anchor + _PROFILE_PHASES
    grid = _cost(data, period, phases[:, None, None], windows[None, :, None])[0]
    i, j = np.unravel_index(int(np.argmin(grid)), grid.shape)
    if grid[i, j] < best[0]:
        best = min(best, descend(np.array([phases[i], windows[j]])))
    return best
