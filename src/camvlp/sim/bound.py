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

import numpy as np

from camvlp.model.camera import Camera, Pose
from camvlp.model.fixtures import FixtureMap
from camvlp.sim.render import LightPatch, RenderSettings, light_patches

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
    (:func:`camvlp.pipeline.square_wave.consistent_periods`); those whose best fit costs at
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
    from camvlp.pipeline.square_wave import consistent_periods  # SciPy's optimiser

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
