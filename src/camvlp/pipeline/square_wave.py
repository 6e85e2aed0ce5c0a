"""A light's line profile fitted with what it is: a 50 % square wave integrated over a window.

:func:`fit_square_wave` fits a light's waveform per line ``s(y)`` (separated from its shape
by :func:`camvlp.pipeline.light_wave.light_wave`) with a 50 % square wave of period ``P``
lines, integrated over a window of ``e`` lines (the exposure, plus the LED's slow edges), with
a low and a high level, by least squares; each clipped line enters as a lower bound.  The
period comes from every edge of every stripe, rising and falling.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from camvlp.pipeline.stripes import spectral_peak

__all__ = ["fit_square_wave"]

#: Shortest window of the square wave, lines.  Lines sample the wave once each: an edge
#: sharper than a line lies anywhere between two lines at the same cost, and a ramp of one
#: line puts it half-way (and makes the cost smooth in the period).
_MIN_WINDOW = 1.0
#: Fewest lines with signal a square wave (five parameters) is fitted to: on fewer, some
#: short period fits any profile.
_MIN_LINES = 10


def _integrated(lines: np.ndarray, period, phase, window) -> np.ndarray:
    """A 50 % square wave (high first) integrated over a centred window, 0 to 1.

    All arguments broadcast; ``lines``, ``phase`` and ``window`` in lines, ``period`` too.  The
    window is at most half a period, so that it spans one edge at most: the integral is then a
    trapezoid, ramping over ``window`` lines centred on each edge.  The distances to the edges
    broadcast over ``lines``, ``period`` and ``phase`` only (the window's axes, if it has its
    own, are broadcast last).
    """
    window = np.maximum(window, 1e-3)
    quarter = 0.25 * period
    # distance from the middle of the nearest high half-period, 0 to period / 2
    v = np.mod(lines - (phase - quarter), period)
    v -= 2.0 * quarter
    np.abs(v, out=v)
    t = (quarter + 0.5 * window) - v
    t *= 1.0 / window
    np.maximum(t, 0.0, out=t)
    return np.minimum(t, 1.0, out=t)


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
    t = _integrated(data.lines, period, phase, window)
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


def _grid(data: _Profile, periods: np.ndarray, n_phase: int, windows) -> np.ndarray:
    """Cost over periods x phases (``n_phase`` per period) x windows (fractions of a period)."""
    p = np.asarray(periods, dtype=float)[:, None, None, None]
    phase = (np.arange(n_phase) / n_phase)[None, :, None, None] * p
    window = np.maximum(np.asarray(windows, dtype=float)[None, None, :, None] * p, _MIN_WINDOW)
    return _cost(data, p, phase, window)[0]


#: The coarse period search's line binning: (lines per bin, shortest, longest period).
_COARSE_BINS = ((1, 0.0, 16.0), (2, 16.0, 32.0), (4, 32.0, np.inf))


def _binned(data: _Profile, k: int) -> _Profile:
    """:func:`_cost`'s data with lines binned ``k`` at a time (weighted means; k = 1 as is)."""
    if k == 1:
        return data
    yc = data.lines[data.y.size :]
    out = []
    for lines, values, weights in ((data.y, data.s, data.w), (yc, data.bc, data.wc)):
        if lines.size == 0:
            out += [lines, values, weights]
            continue
        b = ((lines - lines.min()) // k).astype(np.intp)
        tw = np.bincount(b, weights)
        ok = tw > 0
        out += [
            (np.bincount(b, weights * lines)[ok] / tw[ok]),
            (np.bincount(b, weights * values)[ok] / tw[ok]),
            tw[ok],
        ]
    return _Profile.of(*out)


#: A profile showing this many periods or more (by its spectrum's peak) is also searched
#: around that peak: the coarse 3 % steps would miss the phase over so many periods.
_MANY_PERIODS = 12.0


def _spectral_period(y: np.ndarray, s: np.ndarray, w: np.ndarray) -> float:
    """The period (lines) of the weighted profile's highest spectral peak; inf if none.

    The profile on its dense line grid (missing lines 0), :func:`spectral_peak` over 2
    cycles across it to 0.4 cycles per line.
    """
    y0 = float(y.min())
    n = int(y.max() - y0 + 1)
    dense = np.zeros(n)
    dense[(y - y0).astype(np.intp)] = (s - np.average(s, weights=w)) * np.sqrt(w)
    f = spectral_peak(dense, 2.0 / n, 0.4, pad=16, min_nfft=1024)
    return float(1.0 / f) if f > 0 else float("inf")


def _seeds(per_period: np.ndarray, levels: np.ndarray) -> list[int]:
    """Indices of the periods to search finer: the three best separate ones, and the best of
    each binning level.

    Binned lines hide the variance within their bins: a short period's wave averaged over
    half its period looks flat, which a long period fits cheaply, so the costs of two levels
    are not compared here, only after the finer search on every line.
    """
    seeds: list[int] = []
    order = np.argsort(per_period)
    for i in order:
        if np.isfinite(per_period[i]) and all(abs(int(i) - j) > 2 for j in seeds):
            seeds.append(int(i))
        if len(seeds) == 3:
            break
    for level in np.unique(levels):
        for i in order[levels[order] == level]:
            if np.isfinite(per_period[i]) and all(abs(int(i) - j) > 2 for j in seeds):
                seeds.append(int(i))
            break
    return seeds


def fit_square_wave(
    lines,
    signal,
    weight,
    bound_lines=None,
    bounds=None,
    bound_weight=None,
) -> tuple[float, float, float, float, float]:
    """Fit an integrated 50 % square wave to a light's line profile.

    A coarse search over every period from 2.5 lines to 1.25 times the profile's length (3 %
    steps; the longer periods on binned lines), phase and window; the three best separate
    periods are searched finer, and the best is refined (Nelder-Mead over period, phase and
    window, the levels solved exactly).  A window of ``e`` and one of ``period - e`` give the
    same shape (one is the other's complement, shifted by half a period), so the window is
    sought up to half a period.

    Parameters
    ----------
    lines : array_like, shape (N,)
        Line coordinates along the readout axis, pixels.
    signal : array_like, shape (N,)
        The light's waveform per line (any scale).
    weight : array_like, shape (N,)
        Weight per line (inverse variance up to a factor; 0 to leave a line out).
    bound_lines, bounds, bound_weight : array_like, shape (M,), optional
        Lines where the light clipped: the waveform reached at least ``bounds`` there.

    Returns
    -------
    period, phase, window, low, high : float
        Period, phase (a rising edge's line, modulo the period) and window, lines; the levels
        in ``signal``'s units.  NaN when fewer than :data:`_MIN_LINES` lines carry weight.
    """
    y, s, w = (np.asarray(v, dtype=float).reshape(-1) for v in (lines, signal, weight))
    keep = (w > 0) & np.isfinite(s)
    if keep.sum() < _MIN_LINES:
        return (float("nan"),) * 5
    top = float(w[keep].max())
    if bound_lines is None:
        bound_lines = bounds = bound_weight = np.zeros(0)
    yc, bc, wc = (
        np.asarray(v, dtype=float).reshape(-1) for v in (bound_lines, bounds, bound_weight)
    )
    kc = wc > 0
    scale = float(np.percentile(np.abs(s[keep]), 95)) or 1.0  # costs of order 1 per line
    data = _Profile.of(
        y[keep], s[keep] / scale, w[keep] / top, yc[kc], bc[kc] / scale, wc[kc] / top
    )
    span = float(data[0].max() - data[0].min() + 1)
    if span < 2.5 / 0.8:
        return (float("nan"),) * 5
    # every period the lines could show at least 0.8 of; the longer ones on binned lines
    periods = np.exp(np.arange(np.log(2.5), np.log(span / 0.8), 0.03))
    per_period = np.empty(periods.size)
    levels = np.zeros(periods.size, dtype=np.intp)
    for level, (k, lo, hi) in enumerate(_COARSE_BINS):
        sel = (periods >= lo) & (periods < hi)
        levels[sel] = level
        if sel.any():
            coarse = _grid(_binned(data, k), periods[sel], 12, (0.05, 0.25, 0.45))
            per_period[sel] = coarse.reshape(int(sel.sum()), -1).min(1)
    seeds = _seeds(per_period, levels)
    if not seeds:
        return (float("nan"),) * 5
    fractions = np.linspace(0.02, 0.5, 8)
    starts = [(periods[i], 0.03) for i in seeds]
    peak = _spectral_period(data[0], data[1], data[2])
    if span / peak >= _MANY_PERIODS:  # the coarse steps are too coarse for this many periods
        starts.append((peak, 0.01))
    best = (np.inf, None)
    for period, reach in starts:
        fine = period * np.exp(np.linspace(-reach, reach, 9))
        cost = _grid(data, fine, 16, fractions)
        k = np.unravel_index(int(np.argmin(cost)), cost.shape)
        if cost[k] < best[0]:
            p = fine[k[0]]
            window = max(fractions[k[2]] * p, _MIN_WINDOW)
            best = (float(cost[k]), np.array([p, k[1] / 16 * p, window]))
    x0 = best[1]

    def objective(x: np.ndarray) -> float:
        p, phase, window = x
        if p <= 2.0 or not _MIN_WINDOW <= window <= 0.5 * p:
            return 1e300
        return float(_cost(data, p, phase, window)[0])

    from scipy.optimize import minimize  # here: SciPy's import costs 0.3 s

    steps = np.diag([0.01, 0.05, 0.05]) * x0[0]
    simplex = x0 + np.vstack([np.zeros(3), steps])
    res = minimize(
        objective,
        x0,
        method="Nelder-Mead",
        options={"xatol": 1e-4, "fatol": 1e-9, "maxiter": 600, "initial_simplex": simplex},
    )
    p, phase, window = (float(v) for v in res.x)
    _, low, high = _cost(data, p, phase, window)
    return p, phase % p, window, float(low) * scale, float(high) * scale
