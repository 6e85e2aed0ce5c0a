"""Which ID a light's stripes are, from the forward model's fits of every candidate ID.

The leading candidates (the best of the map, those close to it, and the best outside it)
are refined on finer templates, each at its own saturation knee; the best one's residual
gives the noise (its residuals' variance, inflated by their correlation from line to line).
The ID is the best fit when its likelihood ratio over the best other ID of the map
(``margin``, decimal log) is at least :data:`MIN_MARGIN`, the fit explains enough of the
profile's variance, and no ID outside the map fits clearly better; otherwise there is no
ID, with the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.decode.stripe_model import (
    Fit,
    SensorModel,
    direct_fit,
    knee_templates,
)

__all__ = [
    "FINE_PHASE",
    "FIXTURE_KNEES",
    "MAX_UNEXPLAINED",
    "MIN_MARGIN",
    "decide_id",
]

#: Smallest margin (decimal log of the likelihood ratio of the best ID over the runner-up)
#: for which an ID is returned.
MIN_MARGIN = 4.0

#: Largest fraction of a profile's variance the best fit may leave unexplained.
MAX_UNEXPLAINED = 0.5

#: Saturation knees every fixture is also fitted at, besides the photo's.  The knee is a
#: fixture's own: an LED of brightness ``B`` times the sensor's full scale and off level ``o``
#: clips from on-fraction ``(1 / B - o) / (1 - o)`` on, and fixtures differ in brightness
#: (distance, angle, the LED itself).  Each candidate ID is judged at its best knee, so an ID
#: is never preferred only because the photo's knee suits it better than its rivals.
FIXTURE_KNEES = (*(round(0.02 * 1.25**k, 4) for k in range(18)), 1.0)

_LN10 = math.log(10.0)

#: The leading candidates' phases are refined on templates this many times finer than the
#: search's: with short exposures a stripe edge spans a row or two, and the residual changes
#: by tens of per cent over 1/100 of a chip, so a coarse phase would judge IDs by their luck
#: with the grid rather than by their fit.
FINE_PHASE = 8

#: Most candidates of the map refined (those whose coarse residual is within
#: :data:`LEAD_FACTOR` of the best), besides the best one outside the map.
MAX_LEADERS = 8
LEAD_FACTOR = 3.0


@dataclass(frozen=True)
class _Leaders:
    """The leading candidates' refined fits (internal): ``per_id`` and ``phase`` (I,), the
    residual and the phase (template grid points of ``samples`` per chip) of every candidate,
    refined for the leaders; ``fine`` the leaders' templates on the fine grid; ``knees`` (I,)
    each candidate's saturation knee, refined for the leaders."""

    per_id: np.ndarray
    phase: np.ndarray
    fine: dict
    knees: np.ndarray


def _refine_leaders(fit: Fit, chips, knees, model: SensorModel, in_map, p, w, samples):
    """Each candidate's best residual and phase; the leading candidates' (the best of the map
    and those close to it, and the best outside it) refined on templates
    :data:`FINE_PHASE` times finer, to a parabola's minimum between their points, so that
    neither the best nor its rivals are judged at a grid point's misalignment."""
    per_id = fit.rss.min(axis=1)
    phase = 2.0 * fit.rss.argmin(axis=1)  # the search grid is every other template point
    map_rows = np.flatnonzero(in_map)
    ranked = map_rows[np.argsort(per_id[map_rows], kind="stable")]
    close = per_id[ranked] <= LEAD_FACTOR * max(float(per_id[ranked[0]]), 1e-300)
    lead = list(ranked[: max(2, min(MAX_LEADERS, int(close.sum())))])
    others = np.flatnonzero(~in_map)
    if others.size:
        lead.append(int(others[np.argmin(per_id[others])]))
    f = FINE_PHASE
    xf = fit.x * f
    steps = np.arange(-2 * f, 2 * f + 1, dtype=np.float64)  # +-2 template points
    grid = np.asarray(FIXTURE_KNEES)
    knees = np.array(knees, dtype=np.float64)
    fine = {}
    for k in lead:
        # the knee too: at the coarse phase its choice is as much luck as the phase's
        near = int(np.argmin(np.abs(np.log(grid / knees[k]))))
        kn = np.unique(np.append(grid[max(near - 2, 0) : near + 3], knees[k]))
        tfs = knee_templates(chips[k : k + 1], model, kn, samples * f)[:, 0]
        ph = phase[k] * f + steps
        rss_v = direct_fit(p, w, tfs, xf, ph)[0]  # (knees, phases)
        v, i = np.unravel_index(int(np.argmin(rss_v)), rss_v.shape)
        rss_k, tf = rss_v[v], tfs[v]
        best, at = float(rss_k[i]), float(ph[i])
        if 0 < i < steps.size - 1:  # the parabola through the minimum and its neighbours
            c0, c1, c2 = rss_k[i - 1 : i + 2]
            den = c0 - 2 * c1 + c2
            if den > 0:
                x = float(ph[i] + np.clip(0.5 * (c0 - c2) / den, -0.5, 0.5))
                r = float(direct_fit(p, w, tf, xf, np.array([x]))[0][0])
                if r < best:
                    best, at = r, x
        per_id[k], phase[k], fine[k], knees[k] = best, at / f, tf, kn[v]
    return _Leaders(per_id, phase, fine, knees)


def _noise(resid: np.ndarray, w: np.ndarray, fit: Fit) -> tuple[float, float, float, int]:
    """The best fit's own weighted residual sum of squares, the noise variance it implies, the
    variance inflation of its correlated residuals (AR(1), of the residuals each scaled by
    the square root of its row's weight, which makes them alike in variance) and its degrees
    of freedom."""
    wn = w > 0
    rss1 = float(np.sum(w * resid * resid))  # the best fit's own residual, not the parabola's
    dof = max(int(wn.sum()) - 4, 1)
    sigma2 = max(rss1 / dof, 1e-12 * max(fit.tss / max(fit.n, 1), 1e-300))
    r = (resid * np.sqrt(w))[wn]
    rho = 0.0
    if r.size > 3:
        rho = float(np.clip(np.dot(r[1:], r[:-1]) / max(np.dot(r, r), 1e-300), 0.0, 0.95))
    return rss1, sigma2, (1 + rho) / (1 - rho), dof


@dataclass(frozen=True)
class _Best:
    """The best ID's fit at its refined phase (internal): its model of the profile, gain and
    offset, residual, and the noise it implies (:func:`_noise`)."""

    model_rows: np.ndarray
    gain: float
    offset: float
    rss: float
    sigma2: float
    inflation: float
    dof: int

    def log_ratio(self, rss_other: float) -> float:
        """The decimal log of the likelihood ratio of this fit over one of residual
        ``rss_other`` (the noise this fit's)."""
        return (rss_other - self.rss) / (2 * self.sigma2 * self.inflation) / _LN10


def _best_fit(fit: Fit, leaders: _Leaders, k1: int, p: np.ndarray, w: np.ndarray) -> _Best:
    """Candidate ``k1``'s refined template fitted to the profile ``p`` (weights ``w``) at its
    refined phase: its model per row, gain, offset, residual and noise."""
    j1 = float(leaders.phase[k1])
    tf = leaders.fine[k1]
    xs = (fit.x + j1) * FINE_PHASE % tf.size
    model_rows = np.interp(xs, np.arange(tf.size + 1), np.append(tf, tf[0]))
    _, g1, o1 = direct_fit(p, w, tf, fit.x * FINE_PHASE, np.array([j1 * FINE_PHASE]))
    gain1, offset1 = float(g1[0]), float(o1[0])
    resid = p - (gain1 * model_rows + offset1)
    return _Best(model_rows, gain1, offset1, *_noise(resid, w, fit))


def _ranking(leaders: _Leaders, in_map: np.ndarray) -> np.ndarray:
    """The map's candidates, best fit first: the best refined one, then the others by their
    fits.  A refined fit can come out above an unrefined (coarse) one, which then stays in
    the ranking as the runner-up, a margin below 0: refused."""
    map_rows = np.flatnonzero(in_map)
    order = map_rows[np.argsort(leaders.per_id[map_rows], kind="stable")]
    k1 = int(next(k for k in order if k in leaders.fine))
    return np.concatenate([[k1], order[order != k1]])


def decide_id(
    fit: Fit,
    chips: np.ndarray,
    cand_ids: np.ndarray,
    in_map: np.ndarray,
    p: np.ndarray,
    w: np.ndarray,
    model: SensorModel,
    n_chips: int,
    samples: int,
    min_margin: float,
    codebook: np.ndarray,
    knees: np.ndarray,
) -> StripeDecode:
    """Pick the ID from the fits of every candidate, each at its own knee (internal)."""
    leaders = _refine_leaders(fit, chips, knees, model, in_map, p, w, samples)
    per_id = leaders.per_id
    order = _ranking(leaders, in_map)
    k1 = int(order[0])
    best = _best_fit(fit, leaders, k1, p, w)
    runner = int(order[1]) if order.size > 1 else None
    margin = best.log_ratio(float(per_id[runner])) if runner is not None else float("inf")
    phase = (float(leaders.phase[k1]) / samples) % n_chips
    chips_str = "".join(
        str(int(x)) for x in np.roll(codebook[cand_ids[k1]], -round(phase) % n_chips)
    )
    common = dict(
        frame_rss=float(min(per_id.min(), best.rss)),
        noise_var=float(best.sigma2 * best.inflation),
        method="model",
        runner_up=int(cand_ids[runner]) if runner is not None else None,
        phase_chips=float(phase),
        gain=float(best.gain),
        offset=float(best.offset),
        residual_rms=math.sqrt(best.rss / max(float(w.sum()), 1e-300)),
        unexplained=float(best.rss / fit.tss if fit.tss > 0 else 1.0),
        rows_per_chip=model.rows_per_chip,
        frames=float(fit.n / (n_chips * model.rows_per_chip)),
        chips=chips_str,
        fitted=best.gain * best.model_rows + best.offset,
        knee=float(leaders.knees[k1]),
    )
    margin = float(min(margin, 99.0))
    best_id = int(cand_ids[k1])
    outside = _outside_map(per_id, cand_ids, in_map, best, min_margin)
    if outside is not None:
        why = (
            f"fits ID {outside[0]}, which is not in the map, better than any of the "
            f"map's (nearest in the map: {best_id})"
        )
        return StripeDecode(None, why, margin=margin, outside_id=outside[1], **common)
    if common["unexplained"] > MAX_UNEXPLAINED:
        why = f"the stripes fit no ID's model ({100 * common['unexplained']:.0f} % of their "
        return StripeDecode(None, why + "variance unexplained)", margin=margin, **common)
    if margin < min_margin:
        close = [int(cand_ids[k]) for k in order if best.log_ratio(float(per_id[k])) < min_margin]
        return StripeDecode(
            None,
            f"IDs {best_id} and {common['runner_up']} fit almost equally "
            f"(margin {max(margin, 0.0):.1f}, at least {min_margin:g} needed)",
            margin=margin,
            **common,
            candidates=tuple(dict.fromkeys([best_id, *close])),
        )
    return StripeDecode(best_id, "", margin=margin, **common)


def _outside_map(
    per_id: np.ndarray, cand_ids: np.ndarray, in_map: np.ndarray, best: _Best, min_margin: float
) -> tuple[int, int | None] | None:
    """The ID of the format, not in the map, that fits the stripes better than the best map
    ID by :data:`MIN_MARGIN` (``min_margin``), if any: (that ID, the same when it is also
    clear of every other ID, the light sending it, else None); None when there is none."""
    others = np.flatnonzero(~in_map)
    if not others.size:
        return None
    ko = int(others[np.argmin(per_id[others])])
    if not best.log_ratio(float(per_id[ko])) < -min_margin:
        return None
    # the ID it does send, when that one is clear of every other ID too
    rest = np.delete(per_id, ko)
    var_o = max(float(per_id[ko]) / best.dof, 1e-12 * best.sigma2) * best.inflation
    clear = (float(rest.min()) - float(per_id[ko])) / (2 * var_o) / _LN10
    return int(cand_ids[ko]), (int(cand_ids[ko]) if clear >= min_margin else None)
