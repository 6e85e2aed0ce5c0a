"""Model-based stripe decoding: fit the sensor's forward model of every ID to a row profile.

The forward model of a fixture's row profile (the LED's chips integrated over each row's
exposure window, through the sensor's saturation knee and gamma, blurred, with gain and offset)
and its FFT fit at every phase are in :mod:`camvlp.pipeline.decode.stripe_model`.

Decoding fits this model for every candidate ID and every phase.  The ID is the best fit
when its likelihood ratio over the best other ID of the map (``margin``, decimal log, from the
residuals and the noise estimated from the best fit) is safe; otherwise there is no ID, with
the reason.  IDs of the format that are not in the map are fitted too: when one of them fits
clearly better than every ID of the map, the fixture is refused rather than given the nearest
map ID.

All fixtures of a photo share ``rows_per_chip``, the exposure, the sensor response and the
blur: :func:`camvlp.pipeline.decode.photo_model.estimate_photo_model` fits them jointly to all
profiles, and :func:`decode_photo` decodes every profile with them, each fixture at its own
saturation knee (fixtures differ in brightness).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from camvlp.model.linecode import FrameFormat
from camvlp.pipeline.decode.photo_model import estimate_photo_model, trimmed_cost
from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.decode.stripe_model import (
    MIN_FRAMES,
    SAMPLES_PER_CHIP,
    Fit,
    Folded,
    SensorModel,
    candidate_ids,
    direct_fit,
    fit_folded,
    fold_profile,
    model_profile,
    model_spectra,
    prepared_profile,
    templates_batch,
)

__all__ = [
    "PhotoDecode",
    "SensorModel",
    "decode_photo",
    "decode_profile_model",
    "estimate_photo_model",
    "model_profile",
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

#: Candidate IDs fitted at every knee: all of them up to this many, else the best ones at the
#: photo's knee (see :func:`_own_knee`).
KNEE_LEADERS = 24

_LN10 = math.log(10.0)


@dataclass(frozen=True)
class PhotoDecode:
    """Photo-wide parameters and every fixture's decode.

    Attributes
    ----------
    model : SensorModel
        The fitted parameters (shared by every fixture of the photo).
    decodes : tuple of StripeDecode
        One per profile, in the order given.
    cost : float
        Trimmed mean, over the fixtures, of the log of the unexplained variance fraction of
        each fixture's best fit (lower is better; compares readout directions).
    """

    model: SensorModel
    decodes: tuple[StripeDecode, ...]
    cost: float

    @property
    def rows_per_chip(self) -> float:
        """Chip length, rows."""
        return self.model.rows_per_chip

    @property
    def fit_cost(self) -> float:
        """Mean unexplained variance fraction of every profile's best fit, the worst dropped
        (inf when none was fitted): compares decodes of the same profiles."""
        un = np.array([d.unexplained for d in self.decodes if np.isfinite(d.gain)])
        return float(trimmed_cost(un)) if un.size else float("inf")

    @property
    def exposure_chips(self) -> float:
        """Exposure window, chips."""
        return self.model.exposure_chips


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
        one = np.ones(kn.size)
        tfs = templates_batch(
            chips[k : k + 1],
            model.rows_per_chip,
            one * model.exposure_chips,
            kn,
            one * model.gamma,
            one * model.blur_rows,
            samples * f,
        )[:, 0]
        ph = phase[k] * f + steps
        rss_v = np.stack([direct_fit(p, w, tf, xf, ph)[0] for tf in tfs])
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


def _decide(
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
    frames = fit.n / (n_chips * model.rows_per_chip)
    leaders = _refine_leaders(fit, chips, knees, model, in_map, p, w, samples)
    per_id = leaders.per_id
    map_rows = np.flatnonzero(in_map)
    order = map_rows[np.argsort(per_id[map_rows], kind="stable")]
    # the best is the best refined one: a refined fit can come out above an unrefined (coarse)
    # one, which then stays in the ranking as the runner-up, a margin below 0: refused
    k1 = int(next(k for k in order if k in leaders.fine))
    order = np.concatenate([[k1], order[order != k1]])
    j1 = float(leaders.phase[k1])
    tf = leaders.fine[k1]
    xs = (fit.x + j1) * FINE_PHASE % tf.size
    model_rows = np.interp(xs, np.arange(tf.size + 1), np.append(tf, tf[0]))
    _, g1, o1 = direct_fit(p, w, tf, fit.x * FINE_PHASE, np.array([j1 * FINE_PHASE]))
    gain1, offset1 = float(g1[0]), float(o1[0])
    resid = p - (gain1 * model_rows + offset1)
    rss1, sigma2, inflation, dof = _noise(resid, w, fit)

    def lr(rss_other: float) -> float:
        return (rss_other - rss1) / (2 * sigma2 * inflation) / _LN10

    runner = int(order[1]) if order.size > 1 else None
    margin = lr(float(per_id[runner])) if runner is not None else float("inf")
    unexplained = rss1 / fit.tss if fit.tss > 0 else 1.0
    phase = (j1 / samples) % n_chips
    chips_str = "".join(
        str(int(x)) for x in np.roll(codebook[cand_ids[k1]], -round(phase) % n_chips)
    )
    frame_rss = float(min(per_id.min(), rss1))
    common = dict(
        frame_rss=frame_rss,
        noise_var=float(sigma2 * inflation),
        method="model",
        runner_up=int(cand_ids[runner]) if runner is not None else None,
        phase_chips=float(phase),
        gain=float(gain1),
        offset=float(offset1),
        residual_rms=math.sqrt(rss1 / max(float(w.sum()), 1e-300)),
        unexplained=float(unexplained),
        rows_per_chip=model.rows_per_chip,
        frames=float(frames),
        chips=chips_str,
        fitted=gain1 * model_rows + offset1,
        knee=float(leaders.knees[k1]),
    )
    margin = float(min(margin, 99.0))
    best_id = int(cand_ids[k1])
    others = np.flatnonzero(~in_map)
    if others.size:
        ko = int(others[np.argmin(per_id[others])])
        if lr(float(per_id[ko])) < -min_margin:
            # the ID it does send, when that one is clear of every other ID too
            rest = np.delete(per_id, ko)
            var_o = max(float(per_id[ko]) / dof, 1e-12 * sigma2) * inflation  # its own fit's
            clear = (float(rest.min()) - float(per_id[ko])) / (2 * var_o) / _LN10
            return StripeDecode(
                None,
                f"fits ID {int(cand_ids[ko])}, which is not in the map, better than any of the "
                f"map's (nearest in the map: {best_id})",
                margin=margin,
                outside_id=int(cand_ids[ko]) if clear >= min_margin else None,
                **common,
            )
    if unexplained > MAX_UNEXPLAINED:
        why = f"the stripes fit no ID's model ({100 * unexplained:.0f} % of their variance "
        return StripeDecode(None, why + "unexplained)", margin=margin, **common)
    if margin < min_margin:
        close = [int(cand_ids[k]) for k in order if lr(float(per_id[k])) < min_margin]
        return StripeDecode(
            None,
            f"IDs {best_id} and {common['runner_up']} fit almost equally "
            f"(margin {max(margin, 0.0):.1f}, at least {min_margin:g} needed)",
            margin=margin,
            **common,
            candidates=tuple(dict.fromkeys([best_id, *close])),
        )
    return StripeDecode(best_id, "", margin=margin, **common)


def decode_profile_model(
    profile,
    frame: FrameFormat,
    ids,
    model: SensorModel,
    *,
    weights=None,
    min_margin: float = MIN_MARGIN,
    samples: int = SAMPLES_PER_CHIP,
) -> StripeDecode:
    """Decode one fixture's row profile by fitting the forward model of every ID.

    Parameters
    ----------
    profile : array_like, shape (n,)
        Mean intensity per sensor row across the fixture, in readout order (any units).
    frame : FrameFormat
        The map's frame format.
    ids : iterable of int
        The IDs of the map (the only IDs returned).
    model : SensorModel
        The photo's parameters (see :func:`estimate_photo_model`).
    weights : array_like, shape (n,), optional
        Relative weight of each row (e.g. the pixels it averages); equal by default.
    min_margin : float
        Smallest decimal log likelihood ratio over the runner-up for an ID.
    samples : int
        Template grid points per chip (phase resolution ``1 / samples`` chip).

    Returns
    -------
    StripeDecode
        Falsy, with a reason, when the stripes do not give one ID safely.
    """
    p, w = prepared_profile(profile, weights)
    cand, in_map = candidate_ids(frame, ids)
    chips = frame.codebook[cand]
    return _decode_with(
        p,
        w,
        frame,
        cand,
        in_map,
        chips,
        model_spectra(chips, model, samples),
        model,
        min_margin,
        samples,
    )


def _fail_small(p: np.ndarray, model: SensorModel, n_chips: int, reason: str) -> StripeDecode:
    frames = p.size / (n_chips * model.rows_per_chip)
    return StripeDecode(
        None,
        reason,
        method="model",
        margin=0.0,
        unexplained=1.0,
        rows_per_chip=model.rows_per_chip,
        frames=frames,
    )


def _decode_with(p, w, frame, cand, in_map, chips, spec, model, min_margin, samples, cache=None):
    n = frame.n_chips
    frames = p.size / (n * model.rows_per_chip)
    if p.size < 8:
        return _fail_small(p, model, n, f"too small to decode ({p.size} rows)")
    if frames < MIN_FRAMES:
        return _fail_small(
            p, model, n, f"spans {frames:.2f} frames of the code, at least {MIN_FRAMES:g} needed"
        )
    # every phase on a grid of half the templates' resolution, by FFT; the leaders are then
    # refined on the full one (see _decide)
    fo = fold_profile(p, w, model.rows_per_chip, samples // 2, n)
    fit = Fit(*fit_folded(fo, *spec), fo.spp, p.size, fo.x)
    if fit.tss <= 0:
        return _fail_small(p, model, n, "no stripes (a steady light)")
    fit, knees = _own_knee(fit, fo, chips, in_map, model, samples, cache)
    fit = replace(fit, x=2 * fit.x)
    return _decide(
        fit, chips, cand, in_map, p, w, model, n, samples, min_margin, frame.codebook, knees
    )


def _own_knee(fit: Fit, fo: Folded, chips, in_map, model: SensorModel, samples, cache):
    """Each candidate's fits at its own best saturation knee (internal).

    ``fit`` is at the photo's knee (``fo``: the profile folded for it); the
    leading candidates (all of them for small formats, see :data:`KNEE_LEADERS`) are fitted
    again at every knee of :data:`FIXTURE_KNEES`, and each keeps its best.  Returns the fit
    (rss, gain and offset of each candidate at its knee) and the knees (I,).
    """
    n_cand = chips.shape[0]
    knees = np.full(n_cand, float(model.knee))
    if n_cand <= KNEE_LEADERS:
        lead = np.arange(n_cand)
    else:
        best = fit.rss.min(axis=1)
        map_rows, others = np.flatnonzero(in_map), np.flatnonzero(~in_map)
        top = map_rows[np.argsort(best[map_rows], kind="stable")][: KNEE_LEADERS - 4]
        lead = np.concatenate([top, others[np.argsort(best[others], kind="stable")][:4]])
    key = tuple(lead.tolist())
    if cache is not None and key in cache:
        spec_k = cache[key]
    else:
        kn = np.asarray(FIXTURE_KNEES, dtype=np.float64)
        spec_k = model_spectra(chips[lead], model, samples, kn)
        if cache is not None:
            cache[key] = spec_k
    rss, gain, offset = fit_folded(fo, *spec_k)  # each (K, L, P)
    kb = rss.min(axis=2).argmin(axis=0)  # (L,)
    li = np.arange(lead.size)
    better = rss[kb, li].min(axis=1) < fit.rss[lead].min(axis=1)
    rows, ks = lead[better], kb[better]
    out_rss, out_gain, out_offset = (a.copy() for a in (fit.rss, fit.gain, fit.offset))
    out_rss[rows] = rss[ks, li[better]]
    out_gain[rows] = gain[ks, li[better]]
    out_offset[rows] = offset[ks, li[better]]
    knees[rows] = np.asarray(FIXTURE_KNEES)[ks]
    return replace(fit, rss=out_rss, gain=out_gain, offset=out_offset), knees


def decode_photo(
    profiles,
    frame: FrameFormat,
    ids,
    *,
    weights=None,
    rows_per_chip: float | None = None,
    model: SensorModel | None = None,
    gamma: float | None = 1.0,
    min_margin: float = MIN_MARGIN,
    samples: int = SAMPLES_PER_CHIP,
    rank=None,
) -> PhotoDecode:
    """Decode every fixture of a photo with photo-wide parameters fitted to all of them.

    Parameters
    ----------
    profiles : sequence of array_like, each shape (n_k,)
        Row profiles, in readout order.
    frame : FrameFormat
    ids : iterable of int
        The map's IDs.
    weights : sequence of array_like, optional
        Row weights per profile.
    rows_per_chip : float, optional
        Seed of the chip length (camera row time and map chip rate), rows.
    model : SensorModel, optional
        Use these parameters instead of fitting them.
    gamma : float or None
        Known gamma (default 1), or None to fit it.
    min_margin : float
        See :func:`decode_profile_model`.
    samples : int
        Template grid points per chip.
    rank : sequence of float, optional
        Which profiles the parameters are fitted to first
        (:func:`~camvlp.pipeline.decode.photo_model.estimate_photo_model`).

    Returns
    -------
    PhotoDecode
        The parameters and one :class:`StripeDecode` per profile.
    """
    ps = [np.asarray(p, dtype=np.float64) for p in profiles]
    ws = [None] * len(ps) if weights is None else list(weights)
    cost = float("nan")
    if model is None:
        try:
            model, cost = estimate_photo_model(
                ps, frame, ids, weights=ws, rows_per_chip=rows_per_chip, gamma=gamma, rank=rank
            )
        except ValueError as exc:
            t = float(rows_per_chip) if rows_per_chip else float("nan")
            fallback = SensorModel(t if math.isfinite(t) else 1.0)
            decodes = tuple(
                _fail_small(p, fallback, frame.n_chips, f"no sensor model: {exc}") for p in ps
            )
            return PhotoDecode(fallback, decodes, float("inf"))
    cand, in_map = candidate_ids(frame, ids)
    chips = frame.codebook[cand]
    spec = model_spectra(chips, model, samples)
    cache: dict = {}  # the knees' templates, shared by the fixtures with the same leaders
    decodes = []
    for p, w in zip(ps, ws, strict=True):
        pp, wp = prepared_profile(p, w)
        decodes.append(
            _decode_with(
                pp, wp, frame, cand, in_map, chips, spec, model, min_margin, samples, cache
            )
        )
    if not math.isfinite(cost):
        un = np.array([d.unexplained for d in decodes if np.isfinite(d.unexplained)])
        cost = float(trimmed_cost(un)) if un.size else float("inf")
    return PhotoDecode(model, tuple(decodes), cost)
