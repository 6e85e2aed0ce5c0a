"""A light's stripes matched to a map's frequencies under the beacon model.

:func:`stripes_period` finds the square wave that best fits a light's stripes at any period
(the stripes' own frequency); :func:`hold_against` decides which of a map's frequencies, if
any, the stripes are: the one that explains them best, by a margin over every other map
frequency, nearly as well as any frequency at all, and explaining most of them, line by line
as well as in the residual's sum.  Data sent by a light, flicker and text fail one of those
tests and are refused with the reason.  Both fit the model of
:mod:`camvlp.pipeline.decode.beacon` (:class:`~camvlp.pipeline.decode.beacon.BeaconProfile`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from camvlp.pipeline.decode.beacon import MIN_PERIOD, BeaconProfile
from camvlp.pipeline.paths import path

__all__ = [
    "FLAT_F",
    "MIN_AGREEMENT",
    "MIN_EVIDENCE",
    "MIN_EXPLAINED",
    "MIN_PERIODS_SEEN",
    "OFF_MAP_RATIO",
    "TOLERANCE",
    "FrequencyTest",
    "hold_against",
    "stripes_period",
]


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
#: The period is refined with flat envelopes when they leave the residual within this F
#: ratio (per extra envelope term, against the residual per line) of the full ones'.
FLAT_F = 3.0


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


def _search(profile: BeaconProfile, periods, waves: dict) -> tuple[float, np.ndarray]:
    """:func:`stripes_period`'s search with one model: every period the profile spans 0.75
    of or more (4 % apart, 12 phases, 3 windows); the best, and each of ``periods`` (lines),
    searched finer and refined (:meth:`BeaconProfile.refine`); the best of those.  ``waves``
    keeps the grids' waves for the search with the other model (:meth:`BeaconProfile.grid`)."""
    longest = profile.span / MIN_PERIODS_SEEN
    coarse = np.exp(np.arange(np.log(MIN_PERIOD), np.log(longest), 0.04))
    grid = profile.grid(coarse, 12, (0.2, 0.6, 1.0), waves=waves).reshape(coarse.size, -1)
    seeds = [float(coarse[int(np.argmin(grid.min(1)))])]
    seeds += [float(p) for p in np.asarray(periods, dtype=float) if MIN_PERIOD <= p <= longest]
    best = (np.inf, np.full(4, np.nan))
    for p in seeds:  # each refined: a grid's best phase may lie in another period's valley
        # (its grid over the window a map frequency's fit searches, :func:`_window`: costed
        # once for both)
        start = profile.best(_search_periods(p, *_window([p], 0, TOLERANCE)), waves=waves)
        got = profile.refine(start[1], MIN_PERIOD, longest)
        if got[0] < best[0]:
            best = got
    return best


@path("stripe period search")
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
    waves: dict = {}  # the grids' waves, tried by both models
    cost, wave = _search(profile, periods, waves)
    flat = profile.with_degrees(0, 0)
    if flat.usable and np.isfinite(cost):
        flat_cost, flat_wave = _search(flat, [*np.atleast_1d(periods), wave[0]], waves)
        extra = sum(profile.degrees)  # the envelopes' terms beyond the flat ones
        dof = max(profile.lines.size - 6 - extra, 1)
        if (flat_cost - cost) * dof <= FLAT_F * extra * max(cost, 1e-12):
            # the flat envelopes' wave, costed with the full ones
            return float(profile.costs(*profile.wave(*flat_wave))), flat_wave
    return cost, wave


@path("frequencies held against the map")
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
    if not profile.usable:
        nan, costs = float("nan"), np.full(target.size, np.inf)
        why = "too few lines with signal to measure stripes"
        return FrequencyTest(None, why, nan, nan, 0.0, 0.0, costs, (None,) * target.size)
    free_cost, free_wave = free if free is not None else stripes_period(profile, target)
    j, costs, waves = _map_fits(profile, target, free_cost, free_wave, tolerance)
    best_cost = min(free_cost, float(costs[j]))  # of any period, map frequency or not
    chosen = _weighed(profile, j, costs, waves, float(free_wave[0]))
    off_map = not np.isfinite(costs[j]) or costs[j] > OFF_MAP_RATIO * best_cost
    reason, crowded = _refusal(
        chosen, target, off_map, _explained(profile, best_cost), tolerance, row_time_s
    )
    if reason:
        return replace(chosen, index=None, reason=reason, crowded=crowded)
    return chosen


def _map_fits(
    profile: BeaconProfile,
    target: np.ndarray,
    free_cost: float,
    free_wave: np.ndarray,
    tolerance: float,
) -> tuple[int, np.ndarray, list[np.ndarray | None]]:
    """Each map period's best wave within its window (:func:`_window`), the stripes' own
    wave (``free_cost``, ``free_wave``) where its period lies in the window and fits better;
    the best of them refined as the stripes' own period was.  Returns the best's index,
    each map period's cost (inf where not searched: the profile spans too few of its
    periods) and wave (None there)."""
    costs = np.full(target.size, np.inf)
    waves: list[np.ndarray | None] = [None] * target.size
    longest = profile.span / MIN_PERIODS_SEEN
    for k, p in enumerate(target):
        if MIN_PERIOD <= p <= longest * 1.5:
            costs[k], waves[k] = profile.best(_search_periods(p, *_window(target, k, tolerance)))
    period = float(free_wave[0])
    for k in range(target.size):
        lo, hi = _window(target, k, tolerance)
        if lo <= period <= hi and free_cost < costs[k]:
            costs[k], waves[k] = free_cost, free_wave
    j = int(np.argmin(costs))
    if waves[j] is not None:
        refined = profile.refine(waves[j], *_window(target, j, tolerance))
        if refined[0] < costs[j]:
            costs[j], waves[j] = refined
    return j, costs, waves


def _explained(profile: BeaconProfile, cost: float) -> float:
    """The share of the profile's variation (:attr:`BeaconProfile.steady_cost`) a wave of
    residual ``cost`` explains; 0 for an infinite cost or a profile without variation."""
    null = profile.steady_cost
    return float(1.0 - cost / null) if null > 0 and np.isfinite(cost) else 0.0


def _weighed(
    profile: BeaconProfile,
    j: int,
    costs: np.ndarray,
    waves: list[np.ndarray | None],
    period: float,
) -> FrequencyTest:
    """Map frequency ``j`` weighed against the others: a :class:`FrequencyTest` choosing it,
    with its share of the variation explained, its evidence over the next map frequency, its
    agreement line by line, and the stripes' own ``period`` (lines)."""
    nxt = np.sort(costs)[1] if costs.size > 1 else np.inf
    # the next map frequency's excess residual, in units of the residual per free line
    evidence = (nxt - costs[j]) / max(costs[j] / profile.free_lines, 1e-12)
    agreement = profile.agreement(waves[j]) if waves[j] is not None else 0.0
    return FrequencyTest(
        j,
        "",
        period,
        profile.span / period,
        _explained(profile, costs[j]),
        agreement,
        costs,
        tuple(waves),
        evidence=evidence,
    )


def _refusal(
    t: FrequencyTest,
    target: np.ndarray,
    off_map: bool,
    best_explained: float,
    tolerance: float,
    row_time_s: float | None,
) -> tuple[str, bool]:
    """Why the chosen map frequency of ``t`` is refused ("" when it is not), and whether for
    a map frequency too near it (crowded).  ``off_map``: some period off the map fits the
    stripes clearly better; ``best_explained``: the share of their variation the best period
    of all explains."""
    period, seen, j = t.period_px, t.periods_seen, t.index
    own = f"{1.0 / (period * row_time_s):.0f} Hz" if row_time_s else f"a period of {period:.1f} px"
    if not np.isfinite(period) or seen < MIN_PERIODS_SEEN:
        return f"the light shows {seen:.2f} stripe periods, too few (steady, or too small)", False
    if off_map and best_explained >= MIN_EXPLAINED:
        return f"its stripes are a square wave of {own}, which is no map frequency", False
    if t.explained < MIN_EXPLAINED:
        return (
            f"its stripes are not a square wave of any map frequency (the best explains "
            f"{100 * t.explained:.0f} % of them): data, flicker or not a beacon"
        ), False
    if off_map:
        return f"its stripes fit {own} better than any map frequency", False
    near = target[(np.abs(np.log(target / target[j])) < 2.0 * tolerance) & (target != target[j])]
    if near.size:
        other = 1.0 / (near[0] * row_time_s) if row_time_s else float("nan")
        mine = 1.0 / (target[j] * row_time_s) if row_time_s else float("nan")
        return (
            f"its stripes fit {mine:.0f} Hz, but the map's {other:.0f} Hz is too near it to tell "
            f"apart (closer than twice the {100 * tolerance:.1f} % the row time and drivers "
            "are known to)"
        ), True
    if t.evidence < MIN_EVIDENCE:
        return (
            f"two map frequencies fit its stripes about equally (margin {t.log_ratio:.1f}, at "
            f"least {MIN_EVIDENCE / (2.0 * np.log(10.0)):.1f} needed): too few periods, or too "
            "little between them, to tell them apart"
        ), False
    if t.agreement < MIN_AGREEMENT:
        return (
            f"its stripes are not a regular square wave ({100 * t.agreement:.0f} % of its lines "
            "agree with the best map frequency's): data, flicker or not a beacon"
        ), False
    return "", False
