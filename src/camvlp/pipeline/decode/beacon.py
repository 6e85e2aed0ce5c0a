"""The forward model of a beacon's stripes, fitted to a light's profile line by line.

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
product for thousands of waves).  Which of a map's frequencies the stripes are is decided in
:mod:`camvlp.pipeline.decode.beacon_match`.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre

from camvlp.imaging.levels import CLIP_LEVEL

__all__ = [
    "DEGREE",
    "MIN_PERIOD",
    "BeaconProfile",
    "light_profile",
    "square_wave",
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
#: Phases tried per period, windows (fractions of the shorter part of the period) per phase,
#: and duties (the high part's share of the period: a driver's own, or a clipped light's
#: bright stripes widened by their ramps reaching the full scale early).
PHASES = 24
WINDOWS = (0.1, 0.4, 0.7, 1.0)
DUTIES = (0.5,)
#: Rounds of :meth:`BeaconProfile.refine`: its steps shrink to 0.4 ** 4 (2.6 %) of the first,
#: the periods of its last grid 0.013 % apart, within the precision a light's stripes allow
#: (``benchmarks/bench_frequency.py --quick``: the bound's median sigma 0.008 %, the errors'
#: median 0.05 %; two more rounds changed neither and cost 11 % of the period search).
REFINE_ROUNDS = 5
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


def _kept(lines, level, weight) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lines, levels and weights (flattened, float) of the lines with a weight and a
    finite level."""
    y, s, w = (np.asarray(v, dtype=float).reshape(-1) for v in (lines, level, weight))
    keep = (w > 0) & np.isfinite(s)
    return y[keep], s[keep], w[keep]


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
        self._grids: dict[tuple, np.ndarray] = {}  # grid() by its parameters
        y, s, w = _kept(lines, level, weight)
        yb, sb, wb = _kept(bound_lines, bounds, bound_weight)
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
        clipped = np.r_[np.zeros(y.size, bool), np.ones(yb.size, bool)]  # of every line
        self._set_levels(np.concatenate([s, sb]), clipped)
        self._set_bases(every, clipped, degree, floor_degree)
        self._set_moments()
        self._eliminate_floor()

    def _set_levels(self, s_all: np.ndarray, clipped: np.ndarray) -> None:
        """:attr:`level` and :attr:`bounds` from the levels of every line (``clipped`` ones
        the bounds): less the unclipped lines' median, over the 95th percentile of the
        distance from it (costs of order 1 per line)."""
        ref = np.median(s_all[~clipped])
        scale = float(np.percentile(np.abs(s_all - ref), 95)) or 1.0
        s_all = (s_all - ref) / scale
        self.level, self.bounds = s_all[~clipped], s_all[clipped]

    def _set_bases(
        self, every: np.ndarray, clipped: np.ndarray, degree: int, floor_degree: int
    ) -> None:
        """The envelopes' Legendre bases over the span of ``every`` line: the floor's and
        the on level's, on the unclipped lines and on the ``clipped`` ones."""
        centre = 0.5 * (every.max() + every.min())
        half = max(0.5 * (every.max() - every.min()), 1.0)
        u = (every - centre) / half
        fa, fb = legendre.legvander(u, floor_degree), legendre.legvander(u, degree)
        self._fa, self._fb = fa[~clipped], fb[~clipped]
        self._fa_bound, self._fb_bound = fa[clipped], fb[clipped]

    def _set_moments(self) -> None:
        """The columns whose product with a wave ``t`` gives its moments against the profile:
        ``t @ [cross, pairs, s]`` (the floor's terms times the on level's, the on level's
        pairs, the levels times the on level's terms) and ``t^2 @ [pairs]``."""
        fa, fb, s, w = self._fa, self._fb, self.level, self.weight
        ma, mb = fa.shape[1], fb.shape[1]
        self._cross = [(i, j) for i in range(ma) for j in range(mb)]
        self._pairs = [(i, j) for i in range(mb) for j in range(i, mb)]
        ci, cj = np.array(self._cross).T
        pi, pj = np.array(self._pairs).T
        self._moments = np.concatenate(
            [
                w[:, None] * fa[:, ci] * fb[:, cj],
                w[:, None] * fb[:, pi] * fb[:, pj],
                (w * s)[:, None] * fb,
            ],
            axis=1,
        )

    def _eliminate_floor(self) -> None:
        """The floor's least squares, the same for every wave (its Gram matrix's inverse and
        its fit alone), the ridges on the envelopes' variation, and the residuals of the
        floor alone (:attr:`null_cost`) and of no stripes at all (:attr:`steady_cost`)."""
        fa, s, w = self._fa, self.level, self.weight
        ma, mb = fa.shape[1], self._fb.shape[1]
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

    def grid(
        self, periods, phases: int = PHASES, windows=WINDOWS, duties=DUTIES, waves=None
    ) -> np.ndarray:
        """:meth:`costs` over ``periods`` (lines) x ``phases`` phases x ``windows`` (fractions
        of the period) x ``duties``: shape (len(periods), phases, len(windows), len(duties)).

        Each grid is costed once per profile (kept by its parameters: a light's search and
        its map frequencies' fits try the same grids).  ``waves``, a dict, keeps the grids'
        waves by their parameters for other profiles of the same lines
        (:meth:`with_degrees`), which try the same grids with other envelopes."""
        p = np.asarray(periods, dtype=float)
        key = (p.tobytes(), phases, tuple(windows), tuple(duties))
        if key in self._grids:
            return self._grids[key]
        t = None if waves is None else waves.get(key)
        if t is None:
            p = p[:, None, None, None, None]
            ph = (np.arange(phases) / phases)[None, :, None, None, None] * p
            d = np.asarray(duties, dtype=float)[None, None, None, :, None]
            frac = np.asarray(windows, dtype=float)[None, None, :, None, None]
            win = np.maximum(frac * np.minimum(d, 1 - d) * p, MIN_WINDOW)
            t = self.wave(p, ph, win, d)
            if waves is not None:
                waves[key] = t
        self._grids[key] = cost = self.costs(*t)
        cost.flags.writeable = False  # (kept: read only)
        return cost

    def best(
        self, periods, phases: int = PHASES, windows=WINDOWS, duties=DUTIES, waves=None
    ) -> tuple[float, np.ndarray]:
        """The least cost over :meth:`grid` (``waves`` as there), and its wave ``[period,
        phase, window, duty]``."""
        cost = self.grid(periods, phases, windows, duties, waves)
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
