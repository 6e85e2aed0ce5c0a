"""The photo-wide parameters of the stripes' forward model, fitted to all fixtures at once.

All fixtures of a photo share the chip length in rows, the exposure, the sensor's response
(gamma) and the blur; :func:`estimate_photo_model` fits them jointly to the fixtures'
profiles (a trimmed cost, so one bad fixture does not pull them), seeded by the chip length
when the camera's row time and the map's chip rate are known.  The saturation knee is fitted
too, as a start: each fixture is then judged at its own (:mod:`camvlp.pipeline.decode.model`).
"""

from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np

from camvlp.model.linecode import FrameFormat
from camvlp.pipeline.decode.stripe_model import (
    MIN_FRAMES,
    SAMPLES_PER_CHIP,
    Folded,
    SensorModel,
    candidate_ids,
    fit_folded,
    fold_profile,
    prepared_profile,
    template_spectra,
    templates,
    templates_batch,
)
from camvlp.pipeline.paths import path

__all__ = ["SEEDED_CHIP_SPAN", "estimate_photo_model"]

#: How far (a fraction) the fitted chip length may end from a seed given to
#: :func:`estimate_photo_model`: its last step searches that span around the seed.
SEEDED_CHIP_SPAN = 0.01


_EXPOSURES = (0.08, 0.15, 0.25, 0.35, 0.5, 0.65, 0.8, 0.9, 1.0, 1.15, 1.35, 1.6)
_KNEES = (1.0, 0.7, 0.5, 0.35, 0.25, 0.17, 0.12, 0.085, 0.06)
_BLURS = (0.0, 0.4, 0.8, 1.3, 2.0)
_GAMMAS = (1.0, 0.7, 0.45)


def trimmed_cost(costs: np.ndarray) -> np.ndarray:
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
        self._folds: dict[float, list[Folded]] = {}

    def folds(self, rows_per_chip: float) -> list[Folded]:
        key = float(rows_per_chip)
        if key not in self._folds:
            self._folds[key] = [
                fold_profile(p, w, key, self.samples, self.n_chips) for p, w in self.data
            ]
        return self._folds[key]

    def costs(self, rows_per_chip: float, exposure, knee, gamma, blur) -> np.ndarray:
        """Photo cost of each parameter set (arrays of shape (V,)) at one chip length: (V,).

        A profile that spans fewer than :data:`MIN_FRAMES` frames at this chip length cannot
        be read: nothing of it counts as explained (a few chips fit any ID, so a chip length
        too long for most of the lights would otherwise fit them best)."""
        t = templates_batch(self.chips, rows_per_chip, exposure, knee, gamma, blur, self.samples)
        spectra = template_spectra(t)  # each (V, I, F)
        un = np.ones((t.shape[0], len(self.data)))
        for k, fo in enumerate(self.folds(rows_per_chip)):
            if self.data[k][0].size < MIN_FRAMES * self.n_chips * rows_per_chip:
                continue
            sel = self.own[k]
            rss = fit_folded(fo, *(h[:, sel] for h in spectra))[0]
            un[:, k] = rss.reshape(rss.shape[0], -1).min(axis=1) / max(fo.spp, 1e-300)
        return trimmed_cost(un)

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
    spec = template_spectra(templates(chips, m, s))
    tops = [
        np.argsort(fit_folded(fo, *spec)[0].min(axis=1))[:keep] for fo in f.folds(m.rows_per_chip)
    ]
    union = np.unique(np.concatenate(tops))
    return _PhotoFitter(data, chips[union], s, n, [np.searchsorted(union, t) for t in tops])


@path("photo-wide model")
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
    rank=None,
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
        The chip length when known (row time and chip rate): refined within
        :data:`SEEDED_CHIP_SPAN` of it (the result never ends farther); searched
        over ``rows_per_chip_range`` otherwise.
    gamma : float or None
        The sensor's gamma when known (1 for linear raw data); None fits it.
    max_fixtures : int
        Profiles used for the fit (the longest ones, or the first by ``rank``; the cost drops
        the worst of them).
    rank : sequence of float, optional
        Per profile, how clearly its light is striped (e.g. the blob's stripe contrast times
        its stripe share): the profiles ranked first are fitted (a camera's burned-in text
        or a light that sends data, longer than the lamps, would draw the fit off).
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
    use = _fitted_profiles(ps, rank, max_fixtures)
    if not use:
        raise ValueError("no profile long enough to fit the sensor model")
    data = [prepared_profile(ps[k], ws[k]) for k in use]
    cand, _ = candidate_ids(frame, ids)
    chips = frame.codebook[cand]
    n = frame.n_chips
    start = SensorModel(1.0, 0.5, 0.4, 1.0 if gamma is None else float(gamma), 0.5)
    # a fitter on s samples per chip with each profile's `keep` best IDs under a model
    own_fitter = functools.partial(_own_fitter, data, chips, n)

    # 1. the chip length: seeded, or searched with a middling exposure and knee
    if rows_per_chip is None:
        t0 = _search_chip_length(data, chips, n, start, rows_per_chip_range)
    else:
        t0 = float(rows_per_chip)
    model = replace(start, rows_per_chip=t0)
    # 2. exposure and knee on a joint grid (they trade off), coarsely, with each profile's
    #    two best IDs
    starts = _exposure_knee_starts(own_fitter(16, model, 2), model)
    # 3. finely, with each profile's best ID, from the two best starts of the grid (exposure
    #    and knee trade off: one start can stall): one parameter at a time
    grids: dict[str, tuple[float, ...]] = {
        "blur_rows": _BLURS,
        "exposure_chips": _EXPOSURES,
        "knee": _KNEES,
    }
    if gamma is None:
        grids["gamma"] = _GAMMAS
    results = [_swept(own_fitter(samples // 2, m, 1), m, grids) for m in starts]
    _, model = min(results, key=lambda r: r[0])
    # 4. on the full grid: the chip length, then the exposure, knee and blur between their
    #    grid points
    span = SEEDED_CHIP_SPAN if rows_per_chip is not None else 0.006
    return _polished(own_fitter(samples, model, 1), model, t0 * (1 + np.linspace(-span, span, 5)))


def _fitted_profiles(ps: list[np.ndarray], rank, max_fixtures: int) -> list[int]:
    """The profiles the photo-wide parameters are fitted to: the first ``max_fixtures`` by
    ``rank`` (the most striped first, then the longest), or the longest; 8 rows at least."""
    if rank is None:
        order = np.argsort([-p.size for p in ps], kind="stable")
    else:  # the most striped first, then the longest
        order = np.lexsort(([-p.size for p in ps], -np.asarray(rank, dtype=float)))
    return [int(k) for k in order[:max_fixtures] if ps[k].size >= 8]


def _exposure_knee_starts(coarse: _PhotoFitter, model: SensorModel) -> list[SensorModel]:
    """``model`` at the two best exposures and knees of their joint grid
    (:data:`_EXPOSURES` x :data:`_KNEES`), its other parameters kept."""
    ee, kk = (a.ravel() for a in np.meshgrid(_EXPOSURES, _KNEES))
    costs = coarse.costs(
        model.rows_per_chip,
        ee,
        kk,
        np.full(ee.size, model.gamma),
        np.full(ee.size, model.blur_rows),
    )
    return [
        replace(model, exposure_chips=float(ee[k]), knee=float(kk[k]))
        for k in np.argsort(costs)[:2]
    ]


def _swept(
    fitter: _PhotoFitter, m: SensorModel, grids: dict[str, tuple[float, ...]]
) -> tuple[float, SensorModel]:
    """``m``'s parameters swept over their ``grids`` one at a time, twice at most (once when
    the second round would gain less than 5 %): the cost and the model."""
    best = float("inf")
    for _ in range(2):
        before = best
        for name, values in grids.items():
            m, best = fitter.sweep(m, name, values)
        if best >= 0.95 * before:
            break
    return best, m


def _polished(
    fitter: _PhotoFitter, model: SensorModel, chip_lengths: np.ndarray
) -> tuple[SensorModel, float]:
    """``model`` refined on the full grid: its chip length over ``chip_lengths`` (rows),
    then its exposure, knee and blur between their grid points; the model and its cost."""
    model, best = fitter.sweep(model, "rows_per_chip", chip_lengths)
    for name, step in (("exposure_chips", 0.03), ("knee", 0.02), ("blur_rows", 0.15)):
        v = getattr(model, name) + step * np.arange(-2, 3)
        v = (
            v[(v > 0.02) & ((v <= 1.0) if name == "knee" else True)]
            if name != "blur_rows"
            else v[v >= 0]
        )
        model, best = fitter.sweep(model, name, v)
    return model, best
