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

__all__ = ["consistent_periods", "fit_square_wave", "sharp_period"]

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
    sharp: bool = True,
) -> tuple[float, float, float, float, float]:
    """Fit an integrated 50 % square wave to a light's line profile.

    A coarse search over every period from 2.5 lines to 1.25 times the profile's length (3 %
    steps; the longer periods on binned lines), phase and window; the three best separate
    periods are searched finer, and the best is refined (Nelder-Mead over period, phase and
    window, the levels solved exactly).  A window of ``e`` and one of ``period - e`` give the
    same shape (one is the other's complement, shifted by half a period), so the window is
    sought up to half a period.  Where the fitted window is under :data:`_SHARP` lines, the
    period is the mean over those that fit about as well (:func:`_sharp_mean`; not without
    ``sharp``: :func:`sharp_period` does it after).

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
    prepared = _prepared(lines, signal, weight, bound_lines, bounds, bound_weight)
    if prepared is None:
        return (float("nan"),) * 5
    data, scale = prepared
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
    x = _refine(data, best[1])
    if sharp and x[2] < _SHARP:
        x = _sharp_mean(data, x)
    p, phase, window = (float(v) for v in x)
    _, low, high = _cost(data, p, phase, window)
    return p, phase % p, window, float(low) * scale, float(high) * scale


def _prepared(lines, signal, weight, bound_lines, bounds, bound_weight):
    """:func:`fit_square_wave`'s arguments as a :class:`_Profile` of costs of order 1 per
    line, and the scale of its signal; None when fewer than :data:`_MIN_LINES` lines carry
    weight."""
    y, s, w = (np.asarray(v, dtype=float).reshape(-1) for v in (lines, signal, weight))
    keep = (w > 0) & np.isfinite(s)
    if keep.sum() < _MIN_LINES:
        return None
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
    return data, scale


def sharp_period(lines, signal, weight, bound_lines, bounds, bound_weight, wave) -> np.ndarray:
    """A square wave fitted otherwise (``wave``: period, phase, window, low, high), with the
    period :func:`_sharp_mean` gives on this line profile where its window is under
    :data:`_SHARP` lines (arguments as :func:`fit_square_wave` takes them); shape (5,)."""
    wave = np.asarray(wave, dtype=float)
    prepared = _prepared(lines, signal, weight, bound_lines, bounds, bound_weight)
    if wave[2] >= _SHARP or prepared is None:
        return wave
    data, scale = prepared
    p, phase, window = (float(v) for v in _sharp_mean(data, wave[:3]))
    _, low, high = _cost(data, p, phase, window)
    return np.array([p, phase % p, window, float(low) * scale, float(high) * scale])


def _refine(data: _Profile, x0: np.ndarray) -> np.ndarray:
    """Nelder-Mead over period, phase and window (lines) from ``x0``, windows of
    :data:`_MIN_WINDOW` or more; the end, shape (3,)."""

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
    return np.asarray(res.x, dtype=float)


#: A fitted window shorter than this (lines) may hide a window shorter than a line, whose
#: stripes' edges the lines sample too sparsely to place (:func:`_sharp_mean`).
_SHARP = 1.5
#: :func:`_sharp_mean`'s grid: periods relative to the fit's (step, reach), phases (lines,
#: about the one that keeps the middle edge in place; step, reach) and windows (lines).
_SHARP_STEP, _SHARP_REACH = 0.001, 0.03
_SHARP_PHASE_STEP, _SHARP_PHASE_REACH = 0.005, 0.75
_SHARP_WINDOWS = np.arange(0.05, 1.5, 0.1)
#: Least variance of a line's noise in :func:`_sharp_mean` (the profile's units: its
#: signal's 95th percentile is 1): edges placed to about 2 % of the wave's swing, which the
#: grid's steps resolve.
_SHARP_VAR = 4e-4
#: :func:`_profile`'s steps from period to period: the phases (lines, about the one that
#: keeps the middle edge in place) and windows (lines) its minimisation starts from besides
#: the previous period's best, and its shortest window (lines).
_PROFILE_PHASES = np.linspace(-1.5, 1.5, 31)
_PROFILE_WINDOWS = np.arange(0.05, 2.0, 0.1)
_SHARPEST = 0.02


def _sharp_mean(data: _Profile, x: np.ndarray) -> np.ndarray:
    """The mean period of the waves that fit the lines, under their likelihood.

    A window shorter than a line samples each stripe edge at one line at most: a line caught
    by the edge says where it lies only given the window, and a line that is not says only
    between which two lines it falls.  Then a whole family of periods fits the lines about
    equally well (a shorter window with the edges moved in proportion, or edges anywhere
    between their lines), and the least cost picks one of them at random, often at the
    family's end; no window of one line or more fits them as well.  The mean of the period
    under the likelihood, uniform over period, phase and window, is the estimate of least
    expected error: summed over a grid (:func:`_likelihood`) about the fit ``x`` (period,
    phase, window), the noise's variance from its residual (at least :data:`_SHARP_VAR`,
    which the grid resolves).  Where the grid's least cost lies in the outer half of its
    periods (the fit in a wrong basin), the grid is centred there and summed again, twice
    at most.  Returns ``[period, phase, window]``, lines: the mean period, the fit's phase
    and window.
    """
    p0, phase0, window0 = (float(v) for v in x)
    c0 = float(_cost(data, p0, phase0, window0)[0])
    if not np.isfinite(c0):  # no noise to weigh the grid by: the fit as it is
        return np.array([p0, phase0, window0])
    var = max(c0 / max(data.y.size - 5, 1), _SHARP_VAR)
    centre = (p0, phase0)
    for _ in range(3):
        ks, like, k_least, phase_least = _likelihood(data, *centre, var)
        if 2 * abs(k_least) <= ks.max():
            break
        centre = (centre[0] * (1.0 + k_least * _SHARP_STEP), phase_least)
    if not like.sum() > 0:
        return np.array([p0, phase0, window0])
    mean = centre[0] * (1.0 + _SHARP_STEP * float(like @ ks) / like.sum())
    return np.array([mean, phase0, window0])


def _likelihood(data: _Profile, p0: float, phase0: float, var: float):
    """The likelihood of the waves of a grid about period ``p0`` and phase ``phase0`` (lines),
    summed per period: periods ``p0 * (1 + k * _SHARP_STEP)`` to :data:`_SHARP_REACH`,
    phases about the one that keeps the middle edge in place, every window of
    :data:`_SHARP_WINDOWS`.  Returns ``k`` (K,), the sums (K,), and the period's ``k`` and
    the phase of the grid's least cost."""
    # phases that keep in place the edge nearest the middle of the lines
    m = np.round((0.5 * float(data.lines.min() + data.lines.max()) - phase0) / (0.5 * p0))
    ks = np.arange(-round(_SHARP_REACH / _SHARP_STEP), round(_SHARP_REACH / _SHARP_STEP) + 1)
    steps = np.arange(-_SHARP_PHASE_REACH, _SHARP_PHASE_REACH + 1e-9, _SHARP_PHASE_STEP)
    costs, least = [], (np.inf, 0, phase0)
    for k in ks:
        period = p0 * (1.0 + k * _SHARP_STEP)
        phases = phase0 + 0.5 * m * (p0 - period) + steps
        windows = _SHARP_WINDOWS[_SHARP_WINDOWS <= 0.5 * period]
        cost = _cost(data, period, phases[:, None, None], windows[None, :, None])[0]
        i = int(np.argmin(cost))
        if cost.flat[i] < least[0]:
            least = (float(cost.flat[i]), int(k), float(phases[i // windows.size]))
        costs.append(cost)
    like = np.array([np.exp(-(c - least[0]) / (2.0 * var)).sum() for c in costs])
    return ks, like, least[1], least[2]


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
        The profile, as :func:`fit_square_wave` takes it, the weights each line's inverse
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
