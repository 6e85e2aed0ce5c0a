"""Stripe periods: how many sensor rows one on/off period of a blinking light spans.

A rolling shutter draws a light blinking at ``f`` Hz as stripes with a period of
``1 / (f * row_time)`` sensor rows.  :func:`estimate_stripe_period` measures that period
inside any masked region, to a fraction of a percent; the row-time calibration
(``calibrate.py``) uses it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.imaging.gray import gray_float

__all__ = ["AXES", "StripePeriod", "estimate_stripe_period", "spectral_peak"]


#: Axis names: "rows" = stripes horizontal, the period is measured down the image rows
#: (the sensor reads out row by row); "columns" = stripes vertical (a portrait photo).
AXES = ("rows", "columns")


@dataclass(frozen=True)
class StripePeriod:
    """The period of a region's stripes (:func:`estimate_stripe_period`).  Falsy on failure.

    Attributes
    ----------
    period_px : float
        Stripe period (one bright plus one dark stripe) in pixels along ``axis``; NaN on
        failure.
    axis : str
        ``"rows"`` when the stripes are horizontal (the profile runs down the rows),
        ``"columns"`` when they are vertical.
    strength : float
        Fraction (0-1) of the masked pixels' variance about the profile's trend that the
        periodic model explains: near 1 for clean stripes across ``axis``, near 0 for
        none (or for stripes along the other axis).
    periods_seen : float
        How many periods the region spans along ``axis`` (NaN on failure).
    message : str
        Why the estimate failed ("" on success).
    """

    period_px: float
    axis: str
    strength: float
    periods_seen: float = float("nan")
    message: str = ""

    def __bool__(self) -> bool:
        return bool(np.isfinite(self.period_px)) and not self.message


def _line_sums(
    img: np.ndarray, mask: np.ndarray, axis: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Count, sum and sum of squares of the masked pixels of each row ('rows') or column."""
    a = 1 if axis == "rows" else 0
    v = np.where(mask, img, 0.0)
    return mask.sum(axis=a).astype(np.float64), v.sum(axis=a), (v * v).sum(axis=a)


def _design(x: np.ndarray, f: float, n_trend: int = 3, max_harmonics: int = 3) -> np.ndarray:
    """Columns: polynomial trend, then cos/sin of the harmonics of f below Nyquist."""
    cols = [x**p for p in range(n_trend)]
    for k in range(1, max_harmonics + 1):
        if k * f >= 0.48:
            break
        ph = 2.0 * np.pi * k * f * x
        cols += [np.cos(ph), np.sin(ph)]
    return np.column_stack(cols)


def _fit(x: np.ndarray, y: np.ndarray, w: np.ndarray, f: float) -> tuple[float, np.ndarray]:
    """Weighted least squares of the profile on :func:`_design`: (weighted RSS, model)."""
    d = _design(x, f)
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(d * sw[:, None], y * sw, rcond=None)
    model = d @ coef
    r = (y - model) * sw
    return float(r @ r), model


def _refine(x: np.ndarray, y: np.ndarray, w: np.ndarray, f0: float, n: int) -> float:
    """The frequency (cycles per pixel) near ``f0`` minimising :func:`_fit`'s residual."""
    from scipy.optimize import minimize_scalar  # here: SciPy's import costs 0.3 s

    lo_f, hi_f = max(f0 - 0.5 / n, 1.0 / n), min(f0 + 0.5 / n, 0.49)
    grid = np.linspace(lo_f, hi_f, 25)
    g = int(np.argmin([_fit(x, y, w, fg)[0] for fg in grid]))
    step = grid[1] - grid[0]
    res = minimize_scalar(
        lambda fr: _fit(x, y, w, fr)[0],
        bounds=(max(grid[g] - step, lo_f), min(grid[g] + step, hi_f)),
        method="bounded",
        options={"xatol": 1e-9},
    )
    return float(res.x)


def spectral_peak(
    signal: np.ndarray, f_min: float, f_max: float, *, pad: int, min_nfft: int
) -> float:
    """Frequency of the highest peak of a profile's spectrum within ``[f_min, f_max]``.

    The spectrum of ``signal`` (Hann-windowed, zero-padded to at least ``pad`` times its
    length and ``min_nfft`` samples, a power of two); the peak refined by a parabola through
    the log spectrum.

    Parameters
    ----------
    signal : ndarray, shape (n,)
        The profile, one sample per line (its mean or trend removed).
    f_min, f_max : float
        The band searched, cycles per sample.
    pad, min_nfft : int, keyword-only
        Zero padding: the FFT length is the power of two at or above ``max(pad * n,
        min_nfft)``.

    Returns
    -------
    float
        Cycles per sample; NaN when the band holds no frequency.
    """
    n = signal.size
    nfft = 1 << int(np.ceil(np.log2(max(pad * n, min_nfft))))
    spec = np.abs(np.fft.rfft(signal * np.hanning(n), nfft))
    freqs = np.fft.rfftfreq(nfft)
    band = np.flatnonzero((freqs >= f_min) & (freqs <= f_max))
    if not band.size:
        return float("nan")
    k = int(band[np.argmax(spec[band])])
    f0 = float(freqs[k])
    if 0 < k < len(spec) - 1:  # parabolic interpolation of the log spectrum's peak
        a, b, c = np.log(spec[k - 1 : k + 2] + 1e-300)
        den = a - 2 * b + c
        if den < 0:
            f0 = float(freqs[k] + 0.5 * (a - c) / den * (freqs[1] - freqs[0]))
    return f0


def _period_along(img: np.ndarray, mask: np.ndarray, axis: str, near: float | None) -> StripePeriod:
    nan = float("nan")
    counts, sums, sq = _line_sums(img, mask, axis)
    if counts.max() <= 0:
        return StripePeriod(nan, axis, 0.0, message="the mask is empty")
    ok = counts >= 0.25 * counts.max()
    idx = np.flatnonzero(ok)
    lo, hi = idx[0], idx[-1] + 1
    n = hi - lo
    if n < 6:
        return StripePeriod(
            nan, axis, 0.0, message=f"the region spans only {n} px along the {axis}"
        )
    x = np.arange(lo, hi, dtype=np.float64) - (lo + hi - 1) / 2.0
    w = np.where(ok[lo:hi], counts[lo:hi], 0.0)  # the mean's noise variance ~ 1 / count
    c, s1, s2 = w, np.where(w > 0, sums[lo:hi], 0.0), np.where(w > 0, sq[lo:hi], 0.0)
    y = np.where(w > 0, s1 / np.maximum(c, 1.0), 0.0)

    def pixel_ss(line_value: np.ndarray) -> float:
        """Sum over the used pixels of (pixel - its line's model value) ** 2."""
        return float(np.sum(s2 - 2.0 * line_value * s1 + c * line_value**2))

    # Weighted quadratic trend, then a Hann-windowed, zero-padded spectrum of the residual.
    xs = x / max(n / 2.0, 1.0)
    t = np.column_stack([np.ones(n), xs, xs**2])
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(t * sw[:, None], y * sw, rcond=None)
    trend = t @ coef
    total = pixel_ss(trend)
    resid = (y - trend) * (w > 0)
    if total <= 0 or float((resid * sw) @ (resid * sw)) <= 1e-12 * total:
        return StripePeriod(nan, axis, 0.0, message="the region has no stripes")
    if near is not None and np.isfinite(near) and near > 0:
        f0 = min(1.0 / near, 0.48)
    else:
        f0 = spectral_peak(resid, 1.5 / n, 0.48, pad=64, min_nfft=4096)
        if not np.isfinite(f0):
            return StripePeriod(nan, axis, 0.0, message="the region is too short")

    # Refine: least-squares fit of trend + harmonics, optimised over the frequency.
    f = _refine(x, y, w, f0, n)
    _, model = _fit(x, y, w, f)
    strength = float(np.clip(1.0 - pixel_ss(model) / total, 0.0, 1.0))
    return StripePeriod(1.0 / f, axis, strength, periods_seen=n * f)


def estimate_stripe_period(
    image: np.ndarray,
    mask: np.ndarray | None = None,
    axis: str | None = None,
    *,
    near: float | None = None,
) -> StripePeriod:
    """Period of the stripes a rolling shutter draws across a blinking light.

    The masked pixels are averaged along each row (or column) into a profile; the profile's
    weighted quadratic trend is removed, and the peak of its Hann-windowed, zero-padded
    spectrum (refined by parabolic interpolation) seeds a weighted least-squares fit of a
    periodic model (the fundamental and its harmonics below Nyquist, plus the trend) whose
    frequency is optimised.  The harmonics let a square wave, clipped or not, fit exactly.

    Precision: largest error of 20 synthetic discs per case (50 % square wave, blur sigma
    1 px, noise 1 % of the stripe contrast, mask = the disc less 1.5 px), by the number of
    periods the disc spans:

    ===============  ========  ========  ========  ========
    period (px)      2         2.5       3         5
    ===============  ========  ========  ========  ========
    4                fails     fails     1.4 %     0.3 %
    6                fails     1.1 %     0.9 %     0.2 %
    8                1.7 %     0.6 %     0.3 %     0.09 %
    12               1.2 %     0.3 %     0.15 %    0.04 %
    20               0.2 %     0.07 %    0.04 %    0.01 %
    ===============  ========  ========  ========  ========

    Over 10 periods the error is under 0.05 %.  The used rows must span at least 1.5
    periods (a disc under about 12 px fails); periods under about 2.1 px cannot be told
    from their aliases.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3)
        The photograph or a region of it (any dtype; colour is averaged to gray).
    mask : ndarray of bool, shape (H, W), optional
        The pixels of the light; default all.  Rows (columns) with fewer than a quarter of
        the widest row's pixels are left out.
    axis : {"rows", "columns", None}
        ``"rows"`` for horizontal stripes (period down the rows), ``"columns"`` for
        vertical ones; None tries both and keeps the stronger periodic component.
    near : float, optional, keyword-only
        A first estimate of the period, pixels (e.g. measured over a smaller region): the
        search starts there instead of at the spectrum's peak, which a light's own shape
        (a hot core, a glow) can dominate over a wide region.

    Returns
    -------
    StripePeriod
        Falsy, with a message, when the region is empty, too short, or flat.

    Raises
    ------
    ValueError
        A bad image shape, a mask of another shape, or an unknown axis.
    """
    img = gray_float(image)
    if mask is None:
        m = np.ones(img.shape, dtype=bool)
    else:
        m = np.asarray(mask).astype(bool)
        if m.shape != img.shape:
            raise ValueError(f"mask shape {m.shape} differs from the image's {img.shape}")
    if axis is not None and axis not in AXES:
        raise ValueError(f"axis must be 'rows', 'columns' or None, got {axis!r}")
    axes = AXES if axis is None else (axis,)
    results = [_period_along(img, m, a, near) for a in axes]
    good = [r for r in results if r]
    if not good:
        return results[0]
    return max(good, key=lambda r: r.strength)
