"""A frequency-coded light's stripes held against the forward model of a beacon.

A beacon's LED blinks a 50 % square wave at its frequency ``f``; the rolling shutter exposes
each sensor line over its own window of time, so the light's mean level on line ``y`` (along
the readout axis) is

    s(y) = a(y) + b(y) q(y; P, phase, e)

with ``q`` the square wave of period ``P = 1 / (f row_time)`` lines integrated over a window
of ``e`` lines (the exposure, the LED's slow edges and the blur: 0 to 1, trapezoids), ``a``
the floor under the light (background, glow, the LED's off level) and ``b`` its on level along
the readout (the light's shape: its chord, a hot core off its centre, vignetting).  ``a`` and
``b`` are smooth: polynomials of :data:`DEGREE` over the light's span.  A real light's shape
leaks into any waveform separated from it under a stricter model (a radial one fails on a core
off the disc's centre); smooth envelopes absorb it, and only the stripes' edges tell ``P``.

:class:`BeaconProfile` fits that model to a light's profile for many waves at once (the
envelopes' least squares per wave from moments of the wave against the profile: one matrix
product for thousands of waves), and :func:`hold_against` decides which of a map's
frequencies, if any, the stripes are: the one that explains them best, by a margin over
every other map frequency, nearly as well as any frequency at all, and explaining most of
them, line by line as well as in the residual's sum.  Data sent by a light, flicker and text
fail one of those tests and are refused with the reason.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre

from camvlp.imaging.levels import CLIP_LEVEL

__all__ = [
    "DEGREE",
    "BeaconProfile",
    "FrequencyTest",
    "hold_against",
    "light_profile",
    "square_wave",
    "stripes_period",
]

#: Degree of the envelopes ``a`` and ``b``: a light's shape over its span (a chord, a hot core
#: off its centre).  On the real photos' 55 small lights (1.3 to 5 periods), degree 4 leaves
#: the true frequency's fit at least 2.5 times better than the next map frequency's; degree 2
#: lets a core off the centre pass into the stripes (1.4 times at worst).
DEGREE = 4
#: Degree of the floor ``a``: smoother than the on level, so that the floor cannot rise to
#: the on level where a disc ends and pass for a stripe.
FLOOR_DEGREE = 2
#: Weight of the ridge on the envelopes' variation, per unit of the profile's weight: how
#: much a change of the on level or floor by the profile's scale costs against the residual.
SMOOTH = 0.01
#: The period is refined with flat envelopes when they leave the residual within this F
#: ratio (per extra envelope term, against the residual per line) of the full ones'.
FLAT_F = 3.0
#: Phases tried per period, windows (fractions of the shorter part of the period) per phase,
#: and duties (the high part's share of the period: a driver's own, or a clipped light's
#: bright stripes widened by their ramps reaching the full scale early).
PHASES = 24
WINDOWS = (0.1, 0.4, 0.7, 1.0)
DUTIES = (0.5,)
#: Rounds of :meth:`BeaconProfile.refine`: its steps shrink to 0.4 ** 6 (0.4 %) of the first.
REFINE_ROUNDS = 7
#: Shortest window, lines: a line samples the wave once, an edge sharper than a line lies
#: anywhere between two lines.
MIN_WINDOW = 1.0
#: Shortest period searched, lines (two lines a half period).
MIN_PERIOD = 2.5
#: Fewest lines with signal a profile needs: on fewer some short period fits anything.
MIN_LINES = 10
#: A line whose pixels clip for this share or more is a bound, not a level: the light
#: reached its mean level there at least.
CLIPPED_LINE = 0.5


def square_wave(lines, period, phase, window, duty=0.5) -> np.ndarray:
    """A square wave (high first, for ``duty`` of each period) integrated over a centred
    window, 0 to 1.

    All arguments broadcast (lines, period, phase and window in lines).  The window is at
    most the shorter part of a period, so that it spans one edge at most: the wave is then a
    trapezoid, ramping over ``window`` lines centred on each edge; ``phase`` is a rising
    edge's line.
    """
    window = np.maximum(window, 1e-3)
    period = np.asarray(period, dtype=float)
    high = 0.5 * duty * period  # half the high part
    # distance from the middle of the nearest high part, 0 to period / 2
    v = np.mod(lines - (phase + high), period)
    v = np.abs(v - 0.5 * period)
    v = 0.5 * period - v
    t = (high + 0.5 * window - v) / window
    return np.clip(t, 0.0, 1.0)


def light_profile(gray: np.ndarray, support: np.ndarray, axis: str) -> tuple[np.ndarray, ...]:
    """A light's mean gray level per line of its support along the readout: the arguments of
    :class:`BeaconProfile`.

    Parameters
    ----------
    gray : ndarray, shape (h, w)
        The light's region of interest, gray levels 0-255 (any real dtype).
    support : ndarray of bool, shape (h, w)
        The light's striped area.
    axis : {"rows", "columns"}
        The readout axis: lines are rows (``"rows"``) or columns.

    Returns
    -------
    lines, level, weight : ndarray, shape (n,)
        The lines (index along the readout) holding support pixels, of which less than
        :data:`CLIPPED_LINE` clip (:data:`~camvlp.imaging.levels.CLIP_LEVEL` or more): their
        mean gray level over the support and their pixel counts.
    bound_lines, bounds, bound_weight : ndarray, shape (m,)
        The same of the lines mostly clipped: the light reached their level at least.
    """
    g = np.asarray(gray, dtype=np.float64)
    m = np.asarray(support, dtype=bool)
    across = 1 if axis == "rows" else 0
    count = m.sum(axis=across)
    total = np.where(m, g, 0.0).sum(axis=across)
    hot = (m & (g >= CLIP_LEVEL)).sum(axis=across)
    lines = np.flatnonzero(count)
    n = count[lines].astype(float)
    level, y = total[lines] / n, lines.astype(float)
    # a line mostly clipped says only that the light reached its level there, at least
    bound = hot[lines] >= CLIPPED_LINE * n
    return y[~bound], level[~bound], n[~bound], y[bound], level[bound], n[bound]


class BeaconProfile:
    """One light's profile, ready for the beacon model's fits.

    Parameters
    ----------
    lines, level, weight : array_like, shape (n,)
        The profile (:func:`light_profile`): line coordinates, levels, weights (0 leaves a
        line out).
    bound_lines, bounds, bound_weight : array_like, shape (m,)
        Lines where the light clipped: it reached at least ``bounds`` there.
    degree : int
        Degree of the on level's envelope ``b``.
    floor_degree : int
        Degree of the floor ``a``.

    Attributes
    ----------
    null_cost : float
        Residual of the floor alone on the unclipped lines (what :meth:`costs` starts from).
    steady_cost : float
        Residual of no stripes at all: :attr:`null_cost` and each clipped line's shortfall
        under the floor, squared; the variation a wave's share is counted against.
    """

    def __init__(
        self,
        lines,
        level,
        weight,
        bound_lines=(),
        bounds=(),
        bound_weight=(),
        degree: int = DEGREE,
        floor_degree: int = FLOOR_DEGREE,
    ) -> None:
        self._data = (lines, level, weight, bound_lines, bounds, bound_weight)
        self.degrees = (degree, floor_degree)
        y, s, w = (np.asarray(v, dtype=float).reshape(-1) for v in (lines, level, weight))
        keep = (w > 0) & np.isfinite(s)
        y, s, w = y[keep], s[keep], w[keep]
        yb, sb, wb = (
            np.asarray(v, dtype=float).reshape(-1) for v in (bound_lines, bounds, bound_weight)
        )
        kb = (wb > 0) & np.isfinite(sb)
        yb, sb, wb = yb[kb], sb[kb], wb[kb]
        every = np.concatenate([y, yb])
        self.span = float(every.max() - every.min() + 1) if every.size else 0.0
        self.lines, self.bound_lines = y, yb
        top = max(float(w.max()) if w.size else 0.0, float(wb.max()) if wb.size else 0.0) or 1.0
        self.weight, self.bound_weight = w / top, wb / top
        # lines the fit has left over: the weighted count less the model's unknowns
        n_eff = float(w.sum()) ** 2 / max(float((w * w).sum()), 1e-300) if w.size else 0.0
        self.free_lines = max(n_eff - (degree + 1) - (floor_degree + 1) - 4, 1.0)
        self.usable = y.size >= MIN_LINES and self.span >= 2 * MIN_PERIOD
        if not self.usable:
            return
        s_all = np.concatenate([s, sb])
        bound = np.r_[np.zeros(y.size, bool), np.ones(yb.size, bool)]
        y_all = every
        ref = np.median(s)
        scale = float(np.percentile(np.abs(s_all - ref), 95)) or 1.0
        s_all = (s_all - ref) / scale  # costs of order 1 per line
        self.level, self.bounds = s_all[~bound], s_all[bound]
        centre = 0.5 * (y_all.max() + y_all.min())
        half = max(0.5 * (y_all.max() - y_all.min()), 1.0)
        u = (y_all - centre) / half
        fa, fb = legendre.legvander(u, floor_degree), legendre.legvander(u, degree)
        self._fa, self._fb = fa[~bound], fb[~bound]
        self._fa_bound, self._fb_bound = fa[bound], fb[bound]
        fa, fb = self._fa, self._fb
        s, w = self.level, self.weight
        w = self.weight
        ma, mb = fa.shape[1], fb.shape[1]
        self._cross = [(i, j) for i in range(ma) for j in range(mb)]
        self._pairs = [(i, j) for i in range(mb) for j in range(i, mb)]
        ci, cj = np.array(self._cross).T
        pi, pj = np.array(self._pairs).T
        # moments of a wave t against the profile: t @ [cross, pairs, s] and t^2 @ [pairs]
        self._moments = np.concatenate(
            [
                w[:, None] * fa[:, ci] * fb[:, cj],
                w[:, None] * fb[:, pi] * fb[:, pj],
                (w * s)[:, None] * fb,
            ],
            axis=1,
        )
        # a ridge on the envelopes' variation (each Legendre term's mean square is 1 / (2k + 1)):
        # a few lines at a disc's end cannot bend them into a stripe's edge
        total = float(w.sum())
        self._ridge_b = np.diag([0.0] + [SMOOTH * total / (2 * k + 1) for k in range(1, mb)])
        ridge_a = np.diag([0.0] + [SMOOTH * total / (2 * k + 1) for k in range(1, ma)])
        gram = fa.T @ (w[:, None] * fa) + ridge_a
        r0 = fa.T @ (w * s)
        self._gram_inv = np.linalg.inv(gram + 1e-12 * np.eye(ma))
        self._a_r0 = self._gram_inv @ r0
        self.null_cost = max(float(s @ (w * s)) - float(r0 @ self._a_r0), 0.0)
        # no stripes at all: the floor alone, the clipped lines' shortfall under it too (a
        # light clipped in its bright stripes keeps only its dark lines unclipped)
        short = np.maximum(self.bounds - self._fa_bound @ self._a_r0, 0.0)
        self.steady_cost = self.null_cost + float((short * short) @ self.bound_weight)

    def with_degrees(self, degree: int, floor_degree: int) -> BeaconProfile:
        """The same profile with envelopes of other degrees."""
        return BeaconProfile(*self._data, degree=degree, floor_degree=floor_degree)

    def wave(self, *params) -> tuple[np.ndarray, np.ndarray]:
        """:func:`square_wave` of ``params`` (period, phase, window, duty; broadcasting) on
        :attr:`lines` and on :attr:`bound_lines`: the arguments of :meth:`costs`."""
        return square_wave(self.lines, *params), square_wave(self.bound_lines, *params)

    def costs(self, t: np.ndarray, tb: np.ndarray | None = None) -> np.ndarray:
        """Weighted residual sum of squares of the best envelopes for each wave ``t`` (shape
        (..., n), on :attr:`lines`), in units of the profile's scale squared; shape (...).
        ``tb``, the waves on :attr:`bound_lines`: each clipped line the fit stays under adds
        its shortfall squared (the envelopes are fitted to the unclipped lines).

        The floor's least squares are eliminated once (its Gram matrix is the same for
        every wave); per wave, the on level's normal equations are the Schur complement, of
        the size of its basis, from moments of the wave against the profile."""
        ma, mb = self._fa.shape[1], self._fb.shape[1]
        nc, npairs = len(self._cross), len(self._pairs)
        mt = t @ self._moments  # (..., cross + pairs + mb)
        mtt = (t * t) @ self._moments[:, nc : nc + npairs]
        lead = t.shape[:-1]
        cross = mt[..., :nc].reshape(*lead, ma, mb)
        c = np.empty((*lead, mb, mb))
        for k, (i, j) in enumerate(self._pairs):
            c[..., i, j] = c[..., j, i] = mtt[..., k]
        r1 = mt[..., nc + npairs :]
        schur = c - np.swapaxes(cross, -1, -2) @ (self._gram_inv @ cross)
        resid = r1 - np.einsum("...ij,i->...j", cross, self._a_r0)
        schur += self._ridge_b + 1e-9 * np.eye(mb)
        beta = np.linalg.solve(schur, resid[..., None])[..., 0]  # (..., mb): the on level's
        cost = np.maximum(self.null_cost - np.einsum("...i,...i->...", resid, beta), 0.0)
        if tb is None or not self.bound_lines.size:
            return cost
        # each clipped line the fit does not reach adds its shortfall, squared
        alpha = self._a_r0 - np.einsum("ij,...jk,...k->...i", self._gram_inv, cross, beta)
        fit = alpha @ self._fa_bound.T + tb * (beta @ self._fb_bound.T)
        short = np.maximum(self.bounds - fit, 0.0)
        return cost + (short * short) @ self.bound_weight

    def grid(self, periods, phases: int = PHASES, windows=WINDOWS, duties=DUTIES) -> np.ndarray:
        """:meth:`costs` over ``periods`` (lines) x ``phases`` phases x ``windows`` (fractions
        of the period) x ``duties``: shape (len(periods), phases, len(windows), len(duties))."""
        p = np.asarray(periods, dtype=float)[:, None, None, None, None]
        ph = (np.arange(phases) / phases)[None, :, None, None, None] * p
        d = np.asarray(duties, dtype=float)[None, None, None, :, None]
        frac = np.asarray(windows, dtype=float)[None, None, :, None, None]
        win = np.maximum(frac * np.minimum(d, 1 - d) * p, MIN_WINDOW)
        return self.costs(*self.wave(p, ph, win, d))

    def best(
        self, periods, phases: int = PHASES, windows=WINDOWS, duties=DUTIES
    ) -> tuple[float, np.ndarray]:
        """The least cost over :meth:`grid`, and its wave ``[period, phase, window, duty]``."""
        cost = self.grid(periods, phases, windows, duties)
        k = np.unravel_index(int(np.argmin(cost)), cost.shape)
        p = float(np.asarray(periods, dtype=float)[k[0]])
        d = float(np.asarray(duties)[k[3]])
        window = max(float(np.asarray(windows)[k[2]]) * min(d, 1 - d) * p, MIN_WINDOW)
        return float(cost[k]), np.array([p, k[1] / phases * p, window, d])

    def refine(self, wave: np.ndarray, lo: float, hi: float) -> tuple[float, np.ndarray]:
        """The wave refined over period (kept within ``lo`` to ``hi`` lines), phase and
        window (its duty kept): a grid of 5 periods x 9 phases x 5 windows about the best so
        far, its steps shrunk at each of :data:`REFINE_ROUNDS` rounds (each round one batched
        :meth:`costs`); (cost, the wave).  The phase is stepped about the edge nearest the
        profile's middle line, which a change of period then leaves in place: the two do
        not trade off."""
        best = np.array(wave, dtype=float)
        best[0] = float(np.clip(best[0], lo, hi))
        cost = float(self.costs(*self.wave(*best)))
        middle = float(0.5 * (self.lines.min() + self.lines.max()))
        step = np.array([0.01 * best[0], 0.05 * best[0], 0.1 * best[0]])
        five, nine = np.linspace(-1.0, 1.0, 5), np.linspace(-1.0, 1.0, 9)
        for _ in range(REFINE_ROUNDS):
            # the rising edge nearest the middle, kept there as the period changes
            edge = best[1] + best[0] * np.round((middle - best[1]) / best[0])
            p = np.clip(best[0] + step[0] * five, lo, hi)[:, None, None]
            ph = (edge + step[1] * nine)[None, :, None] + 0.0 * p
            top = min(best[3], 1.0 - best[3]) * p
            win = np.broadcast_to(
                np.clip(best[2] + step[2] * five[None, None, :], MIN_WINDOW, top), (5, 9, 5)
            )
            grid = self.costs(*self.wave(p[..., None], ph[..., None], win[..., None], best[3]))
            k = np.unravel_index(int(np.argmin(grid)), grid.shape)
            if grid[k] < cost:
                cost = float(grid[k])
                best = np.array(
                    [float(p[k[0], 0, 0]), float(ph[k[0], k[1], 0]), float(win[k]), best[3]]
                )
            step *= 0.4
        return cost, best

    def envelopes(self, wave: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The floor ``a`` and on level ``b`` per line (the profile's scale, less its median)
        of the best fit with ``wave``: shape (n,) each."""
        t = square_wave(self.lines, *wave)
        x = np.concatenate([self._fa, t[:, None] * self._fb], axis=1)
        ma, mb = self._fa.shape[1], self._fb.shape[1]
        w = self.weight
        ridge = np.zeros((ma + mb, ma + mb))
        ridge[ma:, ma:] = self._ridge_b
        ridge[:ma, :ma] = np.diag([0.0] + [SMOOTH * w.sum() / (2 * k + 1) for k in range(1, ma)])
        beta = np.linalg.solve(
            x.T @ (w[:, None] * x) + ridge + 1e-9 * np.eye(ma + mb), x.T @ (w * self.level)
        )
        return self._fa @ beta[:ma], self._fb @ beta[ma:]

    def agreement(self, wave: np.ndarray) -> float:
        """The share of the lines clearly on or off in ``wave`` whose own level says the same:
        the profile less its floor, over its on level, above or below one half.  Only lines
        of many pixels (a disc's caps, few, leave the envelopes loose) where the on level is
        a quarter of its peak or more count."""
        a, b = self.envelopes(wave)
        t = square_wave(self.lines, *wave)
        if b.mean() < 0:  # the wave's complement fits (a + b t = a + b - b (1 - t))
            a, b, t = a + b, -b, 1.0 - t
        wide = self.weight >= 0.3
        strong = wide & (b >= 0.25 * (b[wide].max() if wide.any() else 0.0))
        clear = strong & ((t <= 0.2) | (t >= 0.8))
        if not clear.any():
            return 0.0
        on = (self.level - a) > 0.5 * b
        return float(np.mean(on[clear] == (t[clear] >= 0.5)))


@dataclass(frozen=True)
class FrequencyTest:
    """A light's stripes held against a map's frequencies (:func:`hold_against`).

    Attributes
    ----------
    index : int or None
        The map frequency the stripes are (index into the periods given), None when refused.
    reason : str
        Why no frequency was chosen ("" when one was).
    period_px : float
        The stripes' own period, lines (the best fit over every period; NaN if none).
    periods_seen : float
        The profile's span over that period.
    explained : float
        The share of the profile's variation (about its envelopes) the chosen frequency's
        wave explains, 0 to 1 (the best map frequency's when refused).
    margin : float
        ``1 - cost / next cost``: how much better the chosen frequency explains the stripes
        than the next map frequency (0: as well, 1: the next explains nothing).
    agreement : float
        The share of clearly lit or dark lines the chosen wave agrees with.
    costs : ndarray, shape (K,)
        Each map frequency's least residual (the profile's scale), inf where not searched.
    waves : tuple of (ndarray or None)
        Each map frequency's best wave ``[period, phase, window, duty]`` (None where not
        searched), for :meth:`BeaconProfile.envelopes` and the debug pictures.
    crowded : bool
        Refused because another map frequency lies within twice the tolerance of the one
        that fits: a tighter tolerance (the row time rescaled by the photo's other lights)
        may tell them apart.
    evidence : float
        The next map frequency's excess residual over the chosen one's, in units of the
        residual per free line: twice the natural log of their likelihood ratio
        (:attr:`log_ratio` is its decimal log).
    """

    index: int | None
    reason: str
    period_px: float
    periods_seen: float
    explained: float
    margin: float
    agreement: float
    costs: np.ndarray
    waves: tuple = ()
    crowded: bool = False
    evidence: float = float("nan")

    @property
    def log_ratio(self) -> float:
        """The decimal log of the likelihood ratio of the chosen frequency over the next map
        frequency (:attr:`evidence` / (2 ln 10)): the scale of a Manchester ID's margin."""
        return float(self.evidence) / (2.0 * np.log(10.0))

    def __bool__(self) -> bool:
        return self.index is not None


#: A map frequency is chosen only when it explains this share of the stripes' variation...
MIN_EXPLAINED = 0.6
#: ...leaves every other map frequency this much more residual, in units of its own residual
#: per free line (a likelihood ratio: 25 is five standard deviations where the residual is
#: noise, more where it is the model's misfit)...
MIN_EVIDENCE = 25.0
#: ...is within this factor of the best residual of any frequency at all...
OFF_MAP_RATIO = 1.5
#: ...and agrees with this share of the clearly lit or dark lines.
MIN_AGREEMENT = 0.9
#: Fewest periods a profile must show to be tested: under one a light is steady or too small.
MIN_PERIODS_SEEN = 0.75
#: Each map frequency's period is searched within this relative distance: how well the
#: camera file's row time is known (and the drivers' frequencies: the real photos' LEDs are
#: up to 1.5 % off their nominal ones).
TOLERANCE = 0.03


def _search_periods(target: float, lo: float, hi: float, step: float = 0.005) -> np.ndarray:
    """Periods around ``target`` from ``lo`` to ``hi`` lines, ``step`` apart (relative)."""
    n = max(1, int(np.ceil(np.log(hi / lo) / step)))
    return np.exp(np.linspace(np.log(lo), np.log(hi), n + 1))


def _window(periods: np.ndarray, k: int, tolerance: float) -> tuple[float, float]:
    """The periods (lines) searched for map period ``k``: within ``tolerance`` of it.  Two
    map frequencies closer than the row time is known overlap: a light whose period falls
    where both reach fits both alike, and is refused."""
    p = float(periods[k])
    return p * (1 - tolerance), p * (1 + tolerance)


def _search(profile: BeaconProfile, periods) -> tuple[float, np.ndarray]:
    """:func:`stripes_period`'s search with one model: every period the profile spans 0.75
    of or more (4 % apart, 12 phases, 3 windows); the best, and each of ``periods`` (lines),
    searched finer and refined (:meth:`BeaconProfile.refine`); the best of those."""
    longest = profile.span / MIN_PERIODS_SEEN
    coarse = np.exp(np.arange(np.log(MIN_PERIOD), np.log(longest), 0.04))
    grid = profile.grid(coarse, 12, (0.2, 0.6, 1.0)).reshape(coarse.size, -1).min(1)
    seeds = [float(coarse[int(np.argmin(grid))])]
    seeds += [float(p) for p in np.asarray(periods, dtype=float) if MIN_PERIOD <= p <= longest]
    best = (np.inf, np.full(4, np.nan))
    for p in seeds:  # each refined: a grid's best phase may lie in another period's valley
        got = profile.refine(
            profile.best(_search_periods(p, p * 0.97, p * 1.03))[1], MIN_PERIOD, longest
        )
        if got[0] < best[0]:
            best = got
    return best


def stripes_period(profile: BeaconProfile, periods=()) -> tuple[float, np.ndarray]:
    """The square wave that best fits a light's stripes, any period: (its residual under the
    profile's own envelopes, its ``[period, phase, window, duty]``, lines); (inf, NaNs) for
    a profile too short.

    Searched with the profile's envelopes and with flat ones (:func:`_search`, ``periods``
    the map's, lines, searched too); the flat envelopes' wave is taken where they explain
    the stripes about as well (an F ratio of :data:`FLAT_F` per extra envelope term): a light
    whose waveform is free of its shape has fewer unknowns, a sharper period.
    """
    if not profile.usable:
        return np.inf, np.full(4, np.nan)
    cost, wave = _search(profile, periods)
    flat = profile.with_degrees(0, 0)
    if flat.usable and np.isfinite(cost):
        flat_cost, flat_wave = _search(flat, [*np.atleast_1d(periods), wave[0]])
        extra = sum(profile.degrees)  # the envelopes' terms beyond the flat ones
        dof = max(profile.lines.size - 6 - extra, 1)
        if (flat_cost - cost) * dof <= FLAT_F * extra * max(cost, 1e-12):
            # the flat envelopes' wave, costed with the full ones
            return float(profile.costs(*profile.wave(*flat_wave))), flat_wave
    return cost, wave


def hold_against(
    profile: BeaconProfile,
    periods,
    free: tuple[float, np.ndarray] | None = None,
    tolerance: float = TOLERANCE,
    row_time_s: float | None = None,
) -> FrequencyTest:
    """Which of a map's frequencies a light's stripes are, or why none.

    The map frequency whose wave (its period within ``tolerance``) leaves the least residual
    is chosen when it explains :data:`MIN_EXPLAINED` of the stripes' variation, leaves the
    next map frequency :data:`MIN_EVIDENCE` residuals per line more, is within
    :data:`OFF_MAP_RATIO` of the best residual of any period, and agrees with
    :data:`MIN_AGREEMENT` of the clearly lit or dark lines.

    Parameters
    ----------
    profile : BeaconProfile
        The light's profile.
    periods : array_like, shape (K,)
        The map's frequencies as periods, lines (``1 / (f row_time)``).
    free : tuple, optional
        :func:`stripes_period`'s result when already known.
    tolerance : float
        Relative distance around each period searched (the row time's uncertainty).
    row_time_s : float, optional
        Seconds per line, to give periods as frequencies in the reasons.

    Returns
    -------
    FrequencyTest
    """
    target = np.asarray(periods, dtype=float).reshape(-1)
    nan = float("nan")
    costs = np.full(target.size, np.inf)
    if not profile.usable:
        why = "too few lines with signal to measure stripes"
        return FrequencyTest(None, why, nan, nan, 0.0, 0.0, 0.0, costs, (None,) * target.size)
    null = profile.steady_cost
    free_cost, free_wave = free if free is not None else stripes_period(profile, target)
    period = float(free_wave[0])
    seen = profile.span / period
    longest = profile.span / MIN_PERIODS_SEEN
    # each map frequency within its tolerance, never past half-way to its neighbours
    waves: list[np.ndarray | None] = [None] * target.size
    for k, p in enumerate(target):
        if MIN_PERIOD <= p <= longest * 1.5:
            costs[k], waves[k] = profile.best(_search_periods(p, *_window(target, k, tolerance)))
    for k in range(target.size):  # the stripes' own wave, where its period is in the window
        lo, hi = _window(target, k, tolerance)
        if lo <= period <= hi and free_cost < costs[k]:
            costs[k], waves[k] = free_cost, free_wave
    j = int(np.argmin(costs))
    if waves[j] is not None:  # refined as the stripes' own period was, within its window
        refined = profile.refine(waves[j], *_window(target, j, tolerance))
        if refined[0] < costs[j]:
            costs[j], waves[j] = refined
    free_cost = min(free_cost, float(costs[j]))
    ranked = np.sort(costs)

    def share(cost: float) -> float:
        return float(1.0 - cost / null) if null > 0 and np.isfinite(cost) else 0.0

    explained = share(costs[j])
    nxt = ranked[1] if ranked.size > 1 else np.inf
    margin = float(1.0 - costs[j] / nxt) if np.isfinite(nxt) and nxt > 0 else 1.0
    # the next map frequency's excess residual, in units of the residual per free line
    evidence = (nxt - costs[j]) / max(costs[j] / profile.free_lines, 1e-12)
    agreement = profile.agreement(waves[j]) if waves[j] is not None else 0.0
    own = f"{1.0 / (period * row_time_s):.0f} Hz" if row_time_s else f"a period of {period:.1f} px"

    def refused(why: str) -> FrequencyTest:
        return FrequencyTest(
            None,
            why,
            period,
            seen,
            explained,
            margin,
            agreement,
            costs,
            tuple(waves),
            evidence=evidence,
        )

    if not np.isfinite(period) or seen < MIN_PERIODS_SEEN:
        return refused(f"the light shows {seen:.2f} stripe periods, too few (steady, or too small)")
    off_map = not np.isfinite(costs[j]) or costs[j] > OFF_MAP_RATIO * free_cost
    if off_map and share(free_cost) >= MIN_EXPLAINED:
        return refused(f"its stripes are a square wave of {own}, which is no map frequency")
    if explained < MIN_EXPLAINED:
        return refused(
            f"its stripes are not a square wave of any map frequency (the best explains "
            f"{100 * explained:.0f} % of them): data, flicker or not a beacon"
        )
    if off_map:
        return refused(f"its stripes fit {own} better than any map frequency")
    near = target[(np.abs(np.log(target / target[j])) < 2.0 * tolerance) & (target != target[j])]
    if near.size:
        other = 1.0 / (near[0] * row_time_s) if row_time_s else float("nan")
        mine = 1.0 / (target[j] * row_time_s) if row_time_s else float("nan")
        return FrequencyTest(
            None,
            f"its stripes fit {mine:.0f} Hz, but the map's {other:.0f} Hz is too near it to tell "
            f"apart (closer than twice the {100 * tolerance:.1f} % the row time and drivers "
            "are known to)",
            period,
            seen,
            explained,
            margin,
            agreement,
            costs,
            tuple(waves),
            crowded=True,
            evidence=evidence,
        )
    if evidence < MIN_EVIDENCE:
        return refused(
            f"two map frequencies fit its stripes about equally (margin {margin:.2f}): too "
            "few periods, or too little between them, to tell them apart"
        )
    if agreement < MIN_AGREEMENT:
        return refused(
            f"its stripes are not a regular square wave ({100 * agreement:.0f} % of its lines "
            "agree with the best map frequency's): data, flicker or not a beacon"
        )
    return FrequencyTest(
        j, "", period, seen, explained, margin, agreement, costs, tuple(waves), evidence=evidence
    )
