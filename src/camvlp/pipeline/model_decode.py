"""Model-based stripe decoding: fit the sensor's forward model of every ID to a row profile.

The forward model of a fixture's row profile (the LED's chips integrated over each row's
exposure window, through the sensor's saturation knee and gamma, blurred, with gain and offset)
and its FFT fit at every phase are in :mod:`camvlp.pipeline.stripe_model`.

Decoding fits this model for every candidate ID and every phase.  The ID is the best fit
when its likelihood ratio over the best other ID of the map (``margin``, decimal log, from the
residuals and the noise estimated from the best fit) is safe; otherwise there is no ID, with
the reason.  IDs of the format that are not in the map are fitted too: when one of them fits
clearly better than every ID of the map, the fixture is refused rather than given the nearest
map ID.

All fixtures of a photo share ``rows_per_chip``, the exposure, the sensor response and the
blur: :func:`estimate_photo_model` fits them jointly to all profiles (a trimmed cost, so one bad
fixture does not pull them), seeded by the chip length when the camera's row time and the
map's chip rate are known, and :func:`decode_photo` decodes every profile with them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from camvlp.model.linecode import FrameFormat
from camvlp.pipeline.stripe_model import (
    SAMPLES_PER_CHIP,
    SensorModel,
    _direct_fit,
    _Fit,
    _fit_folded,
    _fold,
    _Folded,
    _prepare,
    _spectra,
    _template_spectra,
    _templates,
    _templates_batch,
    model_profile,
)

__all__ = [
    "ModelDecode",
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

#: Smallest fraction of one frame a profile must span to be decoded (below one frame, IDs that
#: differ only in the chips not seen fit equally, and the margin refuses them).
MIN_FRAMES = 0.8

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
class ModelDecode:
    """What the model fit says about one fixture's stripes.

    Attributes
    ----------
    id : int or None
        Decoded ID, or None.
    reason : str
        Why there is no ID ("" when decoded).
    margin : float
        Decimal log of the likelihood ratio of the best ID over the best other ID of the map
        (0 when none was fitted); an ID is returned only from :data:`MIN_MARGIN` on.
    runner_up : int or None
        The best other ID of the map.
    phase_chips : float
        Chip of the frame (fractional) at the start of the profile's first row's exposure.
    gain, offset : float
        Fitted gain and offset, profile units.
    residual_rms : float
        RMS residual of the best fit, profile units.
    unexplained : float
        Fraction of the profile's variance the best fit leaves (0 = perfect).
    rows_per_chip : float
        Chip length used, rows.
    frames : float
        Frames of the code the profile spans.
    hamming : int
        Always -1 (no chips are thresholded); kept for the run-length decoder's interface.
    bleed_rows : float
        NaN (the model has a saturation knee instead); kept for the same reason.
    chips : str
        The best ID's chips from the profile's first row on, one frame ("" when no fit).
    fitted : ndarray, shape (n,), or None
        The best fit's model of the profile, profile units (None when no fit).
    frame_rss : float
        Weighted residual sum of squares of the best fit of any ID of the format (in the map
        or not): how well the stripes read as a frame at all (compares readout directions).
    noise_var : float
        The noise variance the margin assumes (residual variance times the inflation for
        correlated residuals), profile units squared.
    outside_id : int or None
        An ID of the format that is not in the map and that the stripes fit clearly better
        than any other ID (the light sends it), else None.
    knee : float
        The best ID's saturation knee for this fixture (fraction of its on-level; see
        :data:`FIXTURE_KNEES`), NaN when no fit.
    """

    id: int | None
    reason: str
    margin: float
    runner_up: int | None
    phase_chips: float
    gain: float
    offset: float
    residual_rms: float
    unexplained: float
    rows_per_chip: float
    frames: float
    hamming: int = -1
    bleed_rows: float = float("nan")
    chips: str = ""
    fitted: np.ndarray | None = field(default=None, repr=False, compare=False)
    frame_rss: float = float("nan")
    noise_var: float = float("nan")
    outside_id: int | None = None
    knee: float = float("nan")

    def __bool__(self) -> bool:
        return self.id is not None


@dataclass(frozen=True)
class PhotoDecode:
    """Photo-wide parameters and every fixture's decode.

    Attributes
    ----------
    model : SensorModel
        The fitted parameters (shared by every fixture of the photo).
    decodes : tuple of ModelDecode
        One per profile, in the order given.
    cost : float
        Trimmed mean, over the fixtures, of the log of the unexplained variance fraction of
        each fixture's best fit (lower is better; compares readout directions).
    """

    model: SensorModel
    decodes: tuple[ModelDecode, ...]
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
        return float(_trimmed(un)) if un.size else float("inf")

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


def _refine_leaders(fit: _Fit, chips, knees, model: SensorModel, in_map, p, w, samples):
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
        tfs = _templates_batch(
            chips[k : k + 1],
            model.rows_per_chip,
            one * model.exposure_chips,
            kn,
            one * model.gamma,
            one * model.blur_rows,
            samples * f,
        )[:, 0]
        ph = phase[k] * f + steps
        rss_v = np.stack([_direct_fit(p, w, tf, xf, ph)[0] for tf in tfs])
        v, i = np.unravel_index(int(np.argmin(rss_v)), rss_v.shape)
        rss_k, tf = rss_v[v], tfs[v]
        best, at = float(rss_k[i]), float(ph[i])
        if 0 < i < steps.size - 1:  # the parabola through the minimum and its neighbours
            c0, c1, c2 = rss_k[i - 1 : i + 2]
            den = c0 - 2 * c1 + c2
            if den > 0:
                x = float(ph[i] + np.clip(0.5 * (c0 - c2) / den, -0.5, 0.5))
                r = float(_direct_fit(p, w, tf, xf, np.array([x]))[0][0])
                if r < best:
                    best, at = r, x
        per_id[k], phase[k], fine[k], knees[k] = best, at / f, tf, kn[v]
    return _Leaders(per_id, phase, fine, knees)


def _noise(resid: np.ndarray, w: np.ndarray, fit: _Fit) -> tuple[float, float, float, int]:
    """The best fit's own weighted residual sum of squares, the noise variance it implies, the
    variance inflation of its correlated residuals (AR(1)) and its degrees of freedom."""
    wn = w > 0
    rss1 = float(np.sum(w * resid * resid))  # the best fit's own residual, not the parabola's
    dof = max(int(wn.sum()) - 4, 1)
    sigma2 = max(rss1 / dof, 1e-12 * max(fit.tss / max(fit.n, 1), 1e-300))
    r = resid[wn]
    rho = 0.0
    if r.size > 3:
        rho = float(np.clip(np.dot(r[1:], r[:-1]) / max(np.dot(r, r), 1e-300), 0.0, 0.95))
    return rss1, sigma2, (1 + rho) / (1 - rho), dof


def _decide(
    fit: _Fit,
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
) -> ModelDecode:
    """Pick the ID from the fits of every candidate, each at its own knee (internal)."""
    nan = float("nan")
    frames = fit.n / (n_chips * model.rows_per_chip)
    leaders = _refine_leaders(fit, chips, knees, model, in_map, p, w, samples)
    per_id = leaders.per_id
    map_rows = np.flatnonzero(in_map)
    order = map_rows[np.argsort(per_id[map_rows], kind="stable")]
    k1 = int(order[0])
    j1 = float(leaders.phase[k1])
    tf = leaders.fine[k1]
    xs = (fit.x + j1) * FINE_PHASE % tf.size
    model_rows = np.interp(xs, np.arange(tf.size + 1), np.append(tf, tf[0]))
    _, g1, o1 = _direct_fit(p, w, tf, fit.x * FINE_PHASE, np.array([j1 * FINE_PHASE]))
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
            return ModelDecode(
                None,
                f"fits ID {int(cand_ids[ko])}, which is not in the map, better than any of the "
                f"map's (nearest in the map: {best_id})",
                margin,
                outside_id=int(cand_ids[ko]) if clear >= min_margin else None,
                **common,
            )
    if unexplained > MAX_UNEXPLAINED:
        return ModelDecode(
            None,
            f"the stripes fit no ID's model ({100 * unexplained:.0f} % of their variance "
            "unexplained)",
            margin,
            **common,
        )
    if margin < min_margin:
        return ModelDecode(
            None,
            f"IDs {best_id} and {common['runner_up']} fit almost equally "
            f"(margin {max(margin, 0.0):.1f}, at least {min_margin:g} needed)",
            margin,
            **common,
        )
    del nan
    return ModelDecode(best_id, "", margin, **common)


def _candidates(frame: FrameFormat, ids, max_extra: int = 1024):
    """Candidate IDs (the map's first, then the format's others) and which are in the map."""
    map_ids = np.unique(np.asarray(list(ids), dtype=np.int64))
    if map_ids.size == 0:
        raise ValueError("no IDs to decode against")
    for i in map_ids:
        frame.check_id(int(i))
    extra = np.setdiff1d(np.arange(frame.n_ids), map_ids)
    if frame.n_ids > max_extra:
        extra = extra[:0]
    cand = np.concatenate([map_ids, extra])
    return cand, np.arange(cand.size) < map_ids.size


def decode_profile_model(
    profile,
    frame: FrameFormat,
    ids,
    model: SensorModel,
    *,
    weights=None,
    min_margin: float = MIN_MARGIN,
    samples: int = SAMPLES_PER_CHIP,
) -> ModelDecode:
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
    ModelDecode
        Falsy, with a reason, when the stripes do not give one ID safely.
    """
    p, w = _prepare(profile, weights)
    cand, in_map = _candidates(frame, ids)
    chips = frame.codebook[cand]
    return _decode_with(
        p,
        w,
        frame,
        cand,
        in_map,
        chips,
        _spectra(chips, model, samples),
        model,
        min_margin,
        samples,
    )


def _fail_small(p: np.ndarray, model: SensorModel, n_chips: int, reason: str) -> ModelDecode:
    nan = float("nan")
    frames = p.size / (n_chips * model.rows_per_chip)
    return ModelDecode(
        None, reason, 0.0, None, nan, nan, nan, nan, 1.0, model.rows_per_chip, frames
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
    *spectra, t = spec
    # every phase on a grid of half the templates' resolution, by FFT; the leaders are then
    # refined on the full one (see _decide)
    fo = _fold(p, w, model.rows_per_chip, samples // 2, n)
    fit = _Fit(*_fit_folded(fo, *spectra), fo.spp, p.size, fo.x)
    if fit.tss <= 0:
        return _fail_small(p, model, n, "no stripes (a steady light)")
    fit, t, knees = _own_knee(fit, fo, t, chips, in_map, model, samples, cache)
    fit = replace(fit, x=2 * fit.x)
    return _decide(
        fit, chips, cand, in_map, p, w, model, n, samples, min_margin, frame.codebook, knees
    )


def _own_knee(
    fit: _Fit, fo: _Folded, t: np.ndarray, chips, in_map, model: SensorModel, samples, cache
):
    """Each candidate's fits at its own best saturation knee (internal).

    ``fit`` and ``t`` (I, P) are at the photo's knee (``fo``: the profile folded for it); the
    leading candidates (all of them for small formats, see :data:`KNEE_LEADERS`) are fitted
    again at every knee of :data:`FIXTURE_KNEES`, and each keeps its best.  Returns the fit
    (rss, gain and offset of each candidate at its knee), the templates (I, P) at those knees
    and the knees (I,).
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
        spec_k = _spectra(chips[lead], model, samples, kn)
        if cache is not None:
            cache[key] = spec_k
    *spectra, tk = spec_k  # (K, L, ...)
    rss, gain, offset = _fit_folded(fo, *spectra)
    kb = rss.min(axis=2).argmin(axis=0)  # (L,)
    li = np.arange(lead.size)
    better = rss[kb, li].min(axis=1) < fit.rss[lead].min(axis=1)
    rows, ks = lead[better], kb[better]
    out_rss, out_gain, out_offset, out_t = (a.copy() for a in (fit.rss, fit.gain, fit.offset, t))
    out_rss[rows] = rss[ks, li[better]]
    out_gain[rows] = gain[ks, li[better]]
    out_offset[rows] = offset[ks, li[better]]
    out_t[rows] = tk[ks, li[better]]
    knees[rows] = np.asarray(FIXTURE_KNEES)[ks]
    return replace(fit, rss=out_rss, gain=out_gain, offset=out_offset), out_t, knees


# --------------------------------------------------------------------------------------------
# Photo-wide parameters

_EXPOSURES = (0.08, 0.15, 0.25, 0.35, 0.5, 0.65, 0.8, 0.9, 1.0, 1.15, 1.35, 1.6)
_KNEES = (1.0, 0.7, 0.5, 0.35, 0.25, 0.17, 0.12, 0.085, 0.06)
_BLURS = (0.0, 0.4, 0.8, 1.3, 2.0)
_GAMMAS = (1.0, 0.7, 0.45)


def _trimmed(costs: np.ndarray) -> np.ndarray:
    """Photo cost from per-fixture unexplained fractions (..., F): mean log, worst dropped."""
    c = np.sort(costs, axis=-1)
    if c.shape[-1] >= 3:
        c = c[..., :-1]  # one bad fixture does not pull the photo's parameters
    return c.mean(axis=-1)


class _PhotoFitter:
    """Evaluates the photo cost of many parameter sets at once (internal).

    Each profile is fitted with its own candidate IDs (``own``: indices into ``chips``).
    """

    def __init__(self, data, chips: np.ndarray, samples: int, n_chips: int, own=None) -> None:
        self.data = data  # list of (p, w)
        self.chips = chips
        self.samples = samples
        self.n_chips = n_chips
        self.own = own if own is not None else [slice(None)] * len(data)
        self._folds: dict[float, list[_Folded]] = {}

    def folds(self, rows_per_chip: float) -> list[_Folded]:
        key = float(rows_per_chip)
        if key not in self._folds:
            self._folds[key] = [_fold(p, w, key, self.samples, self.n_chips) for p, w in self.data]
        return self._folds[key]

    def costs(self, rows_per_chip: float, exposure, knee, gamma, blur) -> np.ndarray:
        """Photo cost of each parameter set (arrays of shape (V,)) at one chip length: (V,)."""
        t = _templates_batch(self.chips, rows_per_chip, exposure, knee, gamma, blur, self.samples)
        spectra = _template_spectra(t)  # each (V, I, F)
        un = np.empty((t.shape[0], len(self.data)))
        for k, fo in enumerate(self.folds(rows_per_chip)):
            sel = self.own[k]
            rss = _fit_folded(fo, *(h[:, sel] for h in spectra))[0]
            un[:, k] = rss.reshape(rss.shape[0], -1).min(axis=1) / max(fo.spp, 1e-300)
        return _trimmed(un)

    def sweep(self, model: SensorModel, name: str, values) -> tuple[SensorModel, float]:
        """Best of ``model`` with ``name`` set to each of ``values`` (and its cost)."""
        vals = np.asarray(values, dtype=np.float64)
        fields = {
            k: np.full(vals.size, getattr(model, k))
            for k in ("exposure_chips", "knee", "gamma", "blur_rows")
        }
        if name == "rows_per_chip":
            one = [f[:1] for f in fields.values()]
            costs = np.array([self.costs(float(v), *one)[0] for v in vals])
        else:
            fields[name] = vals
            costs = self.costs(model.rows_per_chip, *fields.values())
        k = int(np.argmin(costs))
        best, cost = float(vals[k]), float(costs[k])
        if name == "rows_per_chip" and 0 < k < vals.size - 1:  # between grid points
            c0, c1, c2 = costs[k - 1 : k + 2]
            den = c0 - 2 * c1 + c2
            if den > 0:
                off = float(np.clip(0.5 * (c0 - c2) / den, -0.5, 0.5))
                best += off * 0.5 * (vals[k + 1] - vals[k - 1])
                c = float(self.costs(best, *(f[:1] for f in fields.values()))[0])
                if c < cost:
                    cost = c
                else:
                    best = float(vals[k])
        return replace(model, **{name: best}), cost


def _search_chip_length(data, chips: np.ndarray, n: int, start: SensorModel, rows_range) -> float:
    """The chip length (rows) searched over ``rows_range`` with ``start``'s other parameters:
    a coarse log grid, then around its best few local minima."""
    lo, hi = rows_range
    hi = min(hi, max(p.size for p, _ in data) / (MIN_FRAMES * n))
    if hi <= lo:
        raise ValueError("profiles too short to measure the chip length")
    coarse = _PhotoFitter(data, chips, 8, n)
    grid = np.exp(np.arange(np.log(lo), np.log(hi), 0.02))
    one = [np.array([getattr(start, k)]) for k in ("exposure_chips", "knee", "gamma")]
    one.append(np.array([start.blur_rows]))
    costs = np.array([coarse.costs(float(t), *one)[0] for t in grid])
    minima = np.flatnonzero((costs <= np.roll(costs, 1)) & (costs <= np.roll(costs, -1)))
    seeds = grid[minima[np.argsort(costs[minima])[:4]]] if minima.size else grid[:1]
    fine = np.unique(np.concatenate([s * np.exp(np.arange(-4, 5) * 0.005) for s in seeds]))
    fine = fine[(fine >= lo) & (fine <= hi)]
    return coarse.sweep(start, "rows_per_chip", fine)[0].rows_per_chip


def _own_fitter(data, chips: np.ndarray, n: int, s: int, m: SensorModel, keep: int):
    """A :class:`_PhotoFitter` on ``s`` samples per chip with each profile's ``keep`` best
    IDs under ``m``."""
    f = _PhotoFitter(data, chips, s, n)
    spec = _template_spectra(_templates(chips, m, s))
    tops = [
        np.argsort(_fit_folded(fo, *spec)[0].min(axis=1))[:keep] for fo in f.folds(m.rows_per_chip)
    ]
    union = np.unique(np.concatenate(tops))
    return _PhotoFitter(data, chips[union], s, n, [np.searchsorted(union, t) for t in tops])


def estimate_photo_model(
    profiles,
    frame: FrameFormat,
    ids,
    *,
    weights=None,
    rows_per_chip: float | None = None,
    rows_per_chip_range: tuple[float, float] = (1.5, 48.0),
    gamma: float | None = 1.0,
    max_fixtures: int = 5,
    samples: int = SAMPLES_PER_CHIP,
) -> tuple[SensorModel, float]:
    """Fit the photo-wide parameters of the forward model to all fixtures' profiles.

    Parameters
    ----------
    profiles : sequence of array_like, each shape (n_k,)
        Row profiles of the photo's fixtures, in readout order.
    frame : FrameFormat
    ids : iterable of int
        The map's IDs.
    weights : sequence of array_like, optional
        Row weights per profile.
    rows_per_chip : float, optional
        The chip length when known (row time and chip rate): refined within 2 %; searched
        over ``rows_per_chip_range`` otherwise.
    gamma : float or None
        The sensor's gamma when known (1 for linear raw data); None fits it.
    max_fixtures : int
        Profiles used for the fit (the longest ones; the cost drops the worst of them).
    samples : int
        Template grid points per chip while fitting.

    Returns
    -------
    model : SensorModel
    cost : float
        Trimmed mean log unexplained variance of the fit (lower is better).

    Raises
    ------
    ValueError
        No profile long enough to fit.
    """
    ps = [np.asarray(p, dtype=np.float64) for p in profiles]
    ws = [None] * len(ps) if weights is None else list(weights)
    order = np.argsort([-p.size for p in ps], kind="stable")
    use = [int(k) for k in order[:max_fixtures] if ps[k].size >= 8]
    if not use:
        raise ValueError("no profile long enough to fit the sensor model")
    data = [_prepare(ps[k], ws[k]) for k in use]
    cand, _ = _candidates(frame, ids)
    chips = frame.codebook[cand]
    n = frame.n_chips
    start = SensorModel(1.0, 0.5, 0.4, 1.0 if gamma is None else float(gamma), 0.5)

    # 1. the chip length: seeded, or searched with a middling exposure and knee
    if rows_per_chip is None:
        t0 = _search_chip_length(data, chips, n, start, rows_per_chip_range)
    else:
        t0 = float(rows_per_chip)
    model = replace(start, rows_per_chip=t0)

    # 2. exposure and knee on a joint grid (they trade off), coarsely, with each profile's
    #    two best IDs
    def own_fitter(s: int, m: SensorModel, keep: int) -> _PhotoFitter:
        return _own_fitter(data, chips, n, s, m, keep)

    coarse = own_fitter(16, model, 2)
    ee, kk = (a.ravel() for a in np.meshgrid(_EXPOSURES, _KNEES))
    costs = coarse.costs(
        t0, ee, kk, np.full(ee.size, model.gamma), np.full(ee.size, model.blur_rows)
    )
    # 3. finely, with each profile's best ID, from the two best starts of the grid (exposure
    #    and knee trade off: one start can stall): one parameter at a time
    grids: dict[str, tuple[float, ...]] = {
        "blur_rows": _BLURS,
        "exposure_chips": _EXPOSURES,
        "knee": _KNEES,
    }
    if gamma is None:
        grids["gamma"] = _GAMMAS
    starts = np.argsort(costs)[:2]
    results = []
    for k in starts:
        m = replace(model, exposure_chips=float(ee[k]), knee=float(kk[k]))
        fitter = own_fitter(samples // 2, m, 1)
        best = float("inf")
        for _ in range(2):
            before = best
            for name, values in grids.items():
                m, best = fitter.sweep(m, name, values)
            if best >= 0.95 * before:
                break
        results.append((best, m, fitter))
    best, model, _ = min(results, key=lambda r: r[0])
    # 4. on the full grid: the chip length, then the exposure, knee and blur between their
    #    grid points
    fitter = own_fitter(samples, model, 1)
    span = 0.01 if rows_per_chip is not None else 0.006
    model, best = fitter.sweep(model, "rows_per_chip", t0 * (1 + np.linspace(-span, span, 5)))
    for name, step in (("exposure_chips", 0.03), ("knee", 0.02), ("blur_rows", 0.15)):
        v = getattr(model, name) + step * np.arange(-2, 3)
        v = (
            v[(v > 0.02) & ((v <= 1.0) if name == "knee" else True)]
            if name != "blur_rows"
            else v[v >= 0]
        )
        model, best = fitter.sweep(model, name, v)
    return model, best


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

    Returns
    -------
    PhotoDecode
        The parameters and one :class:`ModelDecode` per profile.
    """
    ps = [np.asarray(p, dtype=np.float64) for p in profiles]
    ws = [None] * len(ps) if weights is None else list(weights)
    cost = float("nan")
    if model is None:
        try:
            model, cost = estimate_photo_model(
                ps, frame, ids, weights=ws, rows_per_chip=rows_per_chip, gamma=gamma
            )
        except ValueError as exc:
            t = float(rows_per_chip) if rows_per_chip else float("nan")
            fallback = SensorModel(t if math.isfinite(t) else 1.0)
            decodes = tuple(
                _fail_small(p, fallback, frame.n_chips, f"no sensor model: {exc}") for p in ps
            )
            return PhotoDecode(fallback, decodes, float("inf"))
    cand, in_map = _candidates(frame, ids)
    chips = frame.codebook[cand]
    spec = _spectra(chips, model, samples)
    cache: dict = {}  # the knees' templates, shared by the fixtures with the same leaders
    decodes = []
    for p, w in zip(ps, ws, strict=True):
        pp, wp = _prepare(p, w)
        decodes.append(
            _decode_with(
                pp, wp, frame, cand, in_map, chips, spec, model, min_margin, samples, cache
            )
        )
    if not math.isfinite(cost):
        un = np.array([d.unexplained for d in decodes if np.isfinite(d.unexplained)])
        cost = float(_trimmed(un)) if un.size else float("inf")
    return PhotoDecode(model, tuple(decodes), cost)
