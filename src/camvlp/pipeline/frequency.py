"""Frequency-coded fixtures: each light blinks a 50 % square wave at its own frequency.

A rolling shutter turns a light blinking at ``f`` Hz into stripes with a period of
``1 / (f * row_time)`` sensor rows.  With the camera's row time known, each measured period
gives a frequency, and the map's nearest frequency identifies the fixture, but only when it
is unambiguous: near enough, clearly nearer than any other map frequency, and claimed by no
other fixture in the photo.  Without the row time, the set of periods is matched to the set
of map frequencies by their ratios: the row time is the one that makes the most periods
land on distinct map frequencies.

A light's stripes are measured over its whole striped area, down to the background
(:func:`camvlp.pipeline.detect.light_support`), not only over the bright disc detection
outlines: a real light with a hot core and a glow shows its stripes well beyond it, and every
period more makes the frequency markedly more precise.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.decode import StripeDecode
from camvlp.pipeline.detect import gray_float, light_support
from camvlp.pipeline.stripes import estimate_stripe_period

__all__ = [
    "FrequencyAssignment",
    "assign_frequencies",
    "decode_frequencies",
    "period_uncertainty",
]


@dataclass(frozen=True)
class FrequencyAssignment:
    """Which map fixture each measured stripe period belongs to.

    Attributes
    ----------
    ids : tuple of (int or None)
        Map ID per period, None where unidentified.
    frequencies_hz : ndarray, shape (N,)
        Measured frequency per period, Hz (NaN where the period is unknown).
    reasons : tuple of str
        Why each unidentified period has no ID ("" where identified).
    row_time_s : float
        Row time used, seconds (NaN when none could be found).
    row_time_fitted : bool
        True when the row time was found from the periods' ratios, not given.
    """

    ids: tuple[int | None, ...]
    frequencies_hz: np.ndarray
    reasons: tuple[str, ...]
    row_time_s: float
    row_time_fitted: bool


def period_uncertainty(periods_spanned) -> np.ndarray:
    """Relative uncertainty of a stripe period measured over ``periods_spanned`` periods.

    A conservative model of the estimator's worst errors (``estimate_stripe_period``): 1 %
    over 3 periods, falling with the square of the count (0.25 % over 6, 0.09 % over 10).
    """
    n = np.maximum(np.asarray(periods_spanned, dtype=float), 1.0)
    return 0.01 * (3.0 / n) ** 2


def _match(
    freqs: np.ndarray, map_freqs: np.ndarray, tolerance: float, sigma: np.ndarray | None = None
) -> tuple[list[int | None], list[str], np.ndarray]:
    """Nearest unambiguous map frequency per measured frequency (indices into map_freqs).

    Unambiguous: within ``tolerance``, and nearer than half-way to the next map frequency
    by at least twice the measurement's relative uncertainty ``sigma``.
    """
    n = freqs.size
    sig = np.zeros(n) if sigma is None else np.asarray(sigma, dtype=float)
    # relative gap of each map frequency to its nearest neighbour in the map
    gaps = np.full(map_freqs.size, np.inf)
    for j, f in enumerate(map_freqs):
        others = map_freqs[np.arange(map_freqs.size) != j]
        if others.size:
            gaps[j] = float(np.min(np.abs(np.log(others / f))))
    picks: list[int | None] = [None] * n
    reasons = ["" for _ in range(n)]
    resid = np.full(n, np.nan)
    for i, f in enumerate(freqs):
        if not np.isfinite(f):
            reasons[i] = "no stripe period could be measured"
            continue
        d = np.abs(np.log(map_freqs / f))
        j = int(np.argmin(d))
        resid[i] = d[j]
        limit = min(tolerance, 0.5 * gaps[j] - 2.0 * sig[i])
        if d[j] > limit:
            reasons[i] = (
                f"{f:.0f} Hz is {100 * d[j]:.1f} % from the nearest map frequency "
                f"({map_freqs[j]:.0f} Hz; at most {100 * max(limit, 0):.2f} % accepted here)"
            )
            continue
        picks[i] = j
    for j in set(p for p in picks if p is not None):
        claim = [i for i, p in enumerate(picks) if p == j]
        if len(claim) > 1:
            for i in claim:
                picks[i] = None
                reasons[i] = f"{len(claim)} lights measure {map_freqs[j]:.0f} Hz"
    return picks, reasons, resid


def assign_frequencies(
    periods_rows,
    fixture_map: FixtureMap,
    row_time_s: float | None,
    *,
    periods_spanned=None,
    tolerance: float = 0.05,
) -> FrequencyAssignment:
    """Identify frequency-coded fixtures from their stripe periods.

    Parameters
    ----------
    periods_rows : array_like, shape (N,)
        Stripe period of each detected light, sensor rows (NaN where unknown).
    fixture_map : FixtureMap
        A map in frequency mode (each fixture has ``frequency_hz``).
    row_time_s : float or None
        Seconds between sensor rows; None to fit it from the periods' ratios.
    periods_spanned : array_like, shape (N,), optional
        How many stripe periods each light spans; sets each measurement's uncertainty
        (:func:`period_uncertainty`).  Default: 3 periods (1 %).
    tolerance : float
        Largest relative difference between a measured and a map frequency.  A light is also
        left unidentified unless it is nearer than half-way to the next map frequency by
        twice its measurement's uncertainty.

    Returns
    -------
    FrequencyAssignment
    """
    if fixture_map.mode != "frequency":
        raise ValueError("fixture_map must be in frequency mode")
    p = np.asarray(periods_rows, dtype=float).reshape(-1)
    spans = np.full(p.size, 3.0) if periods_spanned is None else periods_spanned
    sigma = period_uncertainty(spans).reshape(-1)
    map_freqs = np.array([f.frequency_hz for f in fixture_map.fixtures], dtype=float)
    ids_of = [f.id for f in fixture_map.fixtures]
    fitted = row_time_s is None
    if fitted:
        row_time_s = _fit_row_time(p, map_freqs, tolerance, sigma)
    rt = float(row_time_s) if row_time_s is not None else float("nan")
    freqs = 1.0 / (p * rt) if np.isfinite(rt) else np.full(p.size, np.nan)
    if not np.isfinite(rt):
        reasons = tuple(
            "the row time is unknown and the periods fit no set of the map's frequencies" for _ in p
        )
        return FrequencyAssignment((None,) * p.size, freqs, reasons, rt, fitted)
    picks, reasons, _ = _match(freqs, map_freqs, tolerance, sigma)
    ids = tuple(None if j is None else ids_of[j] for j in picks)
    return FrequencyAssignment(ids, freqs, tuple(reasons), rt, fitted)


def _fit_row_time(
    periods: np.ndarray, map_freqs: np.ndarray, tolerance: float, sigma: np.ndarray
) -> float | None:
    """The row time that puts the most periods on distinct map frequencies, or None.

    Every pairing of a period with a map frequency proposes a row time; each proposal is
    scored by how many periods it identifies and how closely.  The best must identify at
    least two lights and be clearly better than any proposal with a different assignment.
    """
    good = np.isfinite(periods) & (periods > 0)
    if good.sum() < 2:
        return None
    cands = (1.0 / (periods[good][:, None] * map_freqs[None, :])).ravel()
    scored = []
    for rt in cands:
        picks, _, _ = _match(1.0 / (periods * rt), map_freqs, tolerance, sigma)
        hits = [i for i, j in enumerate(picks) if j is not None]
        if len(hits) < 2:
            continue
        # refine: least squares in log over the identified lights
        logs = [-np.log(periods[i] * map_freqs[picks[i]]) for i in hits]
        rt2 = float(np.exp(np.mean(logs)))
        picks2, _, resid2 = _match(1.0 / (periods * rt2), map_freqs, tolerance, sigma)
        hits2 = [i for i, j in enumerate(picks2) if j is not None]
        if len(hits2) < 2:
            continue
        cost = float(np.sqrt(np.nanmean(resid2[hits2] ** 2)))
        scored.append((-len(hits2), cost, rt2, tuple(picks2)))
    if not scored:
        return None
    scored.sort(key=lambda s: (s[0], s[1]))
    best = scored[0]
    for other in scored[1:]:
        if other[3] != best[3] and other[0] == best[0] and other[1] < 2.0 * best[1] + 0.002:
            return None  # two different assignments fit about as well: ambiguous
    return best[2]


# --------------------------------------------------------------------------------------------
# The stripes' forward model, fitted over the whole striped profile


def _wave(x: np.ndarray, period, phase, exposure, knee) -> np.ndarray:
    """A 50 % square wave integrated over each row's exposure, through a saturation knee.

    ``x`` (n,) rows; ``period`` (rows), ``phase`` (cycles at row 0), ``exposure`` (cycles)
    and ``knee`` (0-1) broadcast against each other to shape ``G``; returns ``G + (n,)``
    values in [0, 1]: the on-fraction ``s`` of each row's window, read as
    ``min(s, knee) / knee`` (a light brighter than full scale clips at ``knee``).
    """
    t = x / np.asarray(period)[..., None] + np.asarray(phase)[..., None]
    e = np.asarray(exposure)[..., None]

    def on_time(u: np.ndarray) -> np.ndarray:  # cycles of on-time up to u (cycles)
        whole = np.floor(u)
        return 0.5 * whole + np.minimum(u - whole, 0.5)

    s = (on_time(t + e) - on_time(t)) / e
    k = np.asarray(knee)[..., None]
    return np.minimum(s, k) / k


def _wave_cost(x, y, sw, basis, period, phase, exposure, knee) -> tuple[np.ndarray, np.ndarray]:
    """Weighted residuals of the best ``offset + envelope(x) * wave`` for each parameter set.

    ``basis`` (n, d) is the envelope's basis (low-order Legendre polynomials), ``sw`` (n,)
    the square roots of the rows' weights; the offset and the envelope's coefficients are
    solved by linear least squares.  Returns the residual sums (G,) and residuals (G, n).
    """
    h = _wave(x, period, phase, exposure, knee)  # (G, n)
    design = np.concatenate(
        [np.broadcast_to(sw, h.shape)[..., None], (h * sw)[..., None] * basis], axis=-1
    )  # (G, n, 1 + d)
    target = y * sw
    gram = np.einsum("gnp,gnq->gpq", design, design)
    rhs = np.einsum("gnp,n->gp", design, target)
    gram += 1e-9 * np.trace(gram, axis1=1, axis2=2)[:, None, None] * np.eye(gram.shape[1])
    coef = np.linalg.solve(gram, rhs[..., None])[..., 0]
    resid = target - np.einsum("gnp,gp->gn", design, coef)
    return np.einsum("gn,gn->g", resid, resid), resid


#: Multiples of the first guess of a period around which the fit searches.
_ALIASES = np.array([0.5, 1.0, 2.0])


def _wave_jacobian(x, y, sw, basis, p: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Forward-difference Jacobian (n, 4) of :func:`_wave_cost`'s residuals at ``p`` (4,),
    steps ``h`` (4,): the five parameter sets evaluated in one batch."""
    sets = np.vstack([p, p + np.diag(h)])  # (5, 4)
    _, r = _wave_cost(x, y, sw, basis, *sets.T)
    return ((r[1:] - r[0]) / h[:, None]).T


def _fit_wave(y: np.ndarray, w: np.ndarray, period0: float, min_degree: int = 2) -> float:
    """The stripe period (rows) of a profile, by fitting the stripes' forward model.

    The profile ``y`` (n,), with weights ``w`` (n,), is modelled as an offset plus a smooth
    envelope (a polynomial, of higher degree over more periods) times :func:`_wave`: a 50 %
    square wave of unknown period and phase, integrated over an unknown exposure, clipped
    at an unknown knee.  A grid of periods around ``period0`` (wider over fewer periods),
    phases, exposures and knees seeds a bounded least-squares refinement of all four.
    Returns NaN when the profile is too short.
    """
    from scipy.optimize import least_squares  # here: SciPy's import costs 0.3 s

    n = y.size
    if n < 6 or not (np.isfinite(period0) and period0 > 0):
        return float("nan")
    x = np.arange(n, dtype=np.float64)
    seen = n / period0
    degree = int(np.clip(seen / 2.0, min_degree, 8))
    basis = np.polynomial.legendre.legvander(np.linspace(-1.0, 1.0, n), degree)
    sw = np.sqrt(np.maximum(w, 0.0))
    reach = 1.0 + min(0.6, 3.0 / seen)
    step = min(0.02, 0.2 / seen)
    # around the first guess, and around its half and double (a guess over a short profile
    # can lock onto an alias)
    lo_p, hi_p = max(0.5 * period0 / reach, 2.2), min(2.0 * period0 * reach, 4.0 * n)
    if hi_p <= lo_p * (1 + step):
        return float("nan")
    periods = np.exp(np.arange(np.log(lo_p), np.log(hi_p), step))
    periods = periods[
        np.min(np.abs(np.log(periods[:, None] / (period0 * _ALIASES))), 1) < np.log(reach)
    ]
    grid = np.meshgrid(
        periods,
        np.arange(24 if seen < 4 else 8) / (24 if seen < 4 else 8),
        (0.02, 0.1, 0.25, 0.45),
        (0.95, 0.5, 0.2),
        indexing="ij",
    )
    cost, _ = _wave_cost(x, y, sw, basis, *(g.ravel() for g in grid))
    bounds = ([lo_p, -np.inf, 0.01, 0.05], [hi_p, np.inf, 1.5, 1.0])
    best_p, best_cost = float("nan"), np.inf
    scale = np.array([0.01 * period0, 0.01, 0.02, 0.02])
    order = np.argsort(cost)
    tried: list[float] = []
    for g in order[:40]:
        start = np.array([grid[i].ravel()[g] for i in range(4)])
        start[0] = np.clip(start[0], lo_p * (1 + 1e-9), hi_p * (1 - 1e-9))
        if any(abs(np.log(start[0] / t)) < 2 * step for t in tried):
            continue
        tried.append(start[0])
        fit = least_squares(
            lambda p: _wave_cost(x, y, sw, basis, *p[:, None])[1][0],
            start,
            jac=lambda p: _wave_jacobian(x, y, sw, basis, p, 1e-4 * scale),
            bounds=bounds,
            x_scale=scale,
            xtol=1e-7,
        )
        if fit.cost < best_cost:
            best_p, best_cost = float(fit.x[0]), fit.cost
        if len(tried) == 3:
            break
    return best_p


#: A light "glows" (its striped area reaches well beyond the detected disc) when its support
#: covers at least this many times the disc's area.
_GLOW_RATIO = 1.5


def _centre_on_support(blob, support: np.ndarray, axis: str) -> np.ndarray:
    """The light's centre ``[u, v]`` with its coordinate along the readout axis on its support.

    Across the readout axis the detected centre (an ellipse fitted to the disc's edges along
    the lit rows) is kept; along it, a light with a glow is centred on its whole striped
    area: an ellipse fitted to the sides of the support's outline (the points where it runs
    along the readout axis; its two caps are cut wherever a dark stripe falls, and are left
    out).  The detected centre is returned as it is when the support reaches the region's
    edge along the readout axis (the area would be cut), the disc is cut by the image border,
    or there are too few side points.  ``blob`` is not changed.
    """
    pixel = np.array(blob.pixel, dtype=float)
    if blob.touches_border:
        return pixel
    j = 1 if axis == "rows" else 0  # pixel coordinate along the readout: v for rows
    lines = np.flatnonzero(support.any(axis=1 - j))
    if lines[0] == 0 or lines[-1] == support.shape[1 - j] - 1:
        return pixel
    # the outline's sides (running along the readout axis): its caps are cut by the stripes
    contours, _ = cv2.findContours(
        support.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
    )
    pts = max(contours, key=cv2.contourArea)[:, 0, :].astype(float)  # (M, 2) as (x, y)
    if pts.shape[0] < 20:
        return pixel
    tangent = np.roll(pts, -2, axis=0) - np.roll(pts, 2, axis=0)
    sides = pts[np.abs(tangent[:, j]) > np.abs(tangent[:, 1 - j])]
    if sides.shape[0] < 12:
        return pixel
    (cx, cy), _, _ = cv2.fitEllipse(sides.astype(np.float32))
    centre = cy if j == 1 else cx
    if 0 <= centre < support.shape[1 - j]:
        pixel[j] = blob.box[j] + centre
    return pixel


def _mean_profile(gray: np.ndarray, region: np.ndarray, axis: str) -> tuple[np.ndarray, np.ndarray]:
    """Mean gray level (n,) and pixel count (n,) of ``region``'s lines along the readout.

    Lines with under a quarter of the widest line's pixels are cut from both ends.
    """
    a = 1 if axis == "rows" else 0
    counts = region.sum(axis=a).astype(np.float64)
    idx = np.flatnonzero(counts >= 0.25 * counts.max()) if counts.max() > 0 else []
    if len(idx) == 0:
        return np.zeros(0), np.zeros(0)
    sums = np.where(region, gray, 0.0).sum(axis=a)
    c = counts[idx[0] : idx[-1] + 1]
    return sums[idx[0] : idx[-1] + 1] / np.maximum(c, 1.0), c


def _glow_profile(
    gray: np.ndarray, region: np.ndarray, axis: str, period: float
) -> tuple[np.ndarray, np.ndarray]:
    """A glowing light's normalised stripe profile along the readout (n,), lines' weights (n,).

    Each pixel is put on the scale of its own stripes: between the lowest and highest level
    within one stripe period along the readout axis (``period``, pixels), which do not
    depend on the stripes' phase.  A light's brightness across its area (a hot core, a glow,
    a disc's rim) then leaves the same stripes everywhere, clipped where the light saturates.
    Each line's mean over the pixels of ``region`` (and 2 px around it) with a contrast over
    a fifth of the largest is weighted by their summed contrast; of a saturated light only
    the pixels that never reach full scale are used (a clipped pixel's stripes have lost
    their shape) when most lines have two or more.  Lines with under a quarter of the
    largest weight are cut from both ends.
    """
    g = gray if axis == "rows" else gray.T
    r = region if axis == "rows" else region.T
    r = cv2.dilate(r.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0  # and its rim
    if not r.any():
        return np.zeros(0), np.zeros(0)
    kernel = np.ones((int(np.ceil(period)) + 1, 1), np.uint8)
    hi = cv2.dilate(g, kernel, borderType=cv2.BORDER_REPLICATE)
    lo = cv2.erode(g, kernel, borderType=cv2.BORDER_REPLICATE)
    contrast = hi - lo
    use = r & (contrast > 0.2 * np.percentile(contrast[r], 95))
    top = float(g[r].max())
    if np.mean(g[r] >= top - 2.0) > 0.05:  # a saturated light: its stripes' shape is clipped
        linear = use & (hi < top - 4.0)  # pixels that never reach full scale keep it whole
        lines = linear.sum(axis=1)
        if np.mean(lines[use.any(axis=1)] >= 2) > 0.75:
            use = linear
    weight = np.where(use, contrast, 0.0).sum(axis=1)
    y = np.where(use, g - lo, 0.0).sum(axis=1) / np.maximum(weight, 1e-12)
    idx = np.flatnonzero(weight >= 0.25 * weight.max())
    if idx.size == 0:
        return np.zeros(0), np.zeros(0)
    return y[idx[0] : idx[-1] + 1], weight[idx[0] : idx[-1] + 1]


def decode_frequencies(
    blobs, gray_rois, axis: str, camera: Camera, fixture_map: FixtureMap
) -> tuple[list[StripeDecode], np.ndarray, str]:
    """Identify frequency-coded fixtures from their stripe periods.

    Each light's period is measured (:func:`camvlp.pipeline.stripes.estimate_stripe_period`)
    over its disc.  A light whose striped area reaches well beyond the disc (a glow: its
    support down to the background, :func:`camvlp.pipeline.detect.light_support`, covers
    1.5 times the disc's area or more) has its period refined over that whole area, starting
    from the disc's (the refinement is kept when within 15 % of it), and its centre along the
    readout axis moved to the area's centre (``blob.pixel`` is updated in place).  The
    periods are then matched to the map's frequencies (:func:`assign_frequencies`).

    Parameters
    ----------
    blobs : sequence of Blob
        The detected lights.
    gray_rois : sequence of ndarray
        Each blob's region of interest, gray (shape of its ``mask``).
    axis : {"rows", "columns"}
        The readout axis.
    camera : Camera
        Its ``row_time_s`` converts periods to frequencies (fitted from ratios when None).
    fixture_map : FixtureMap
        A map in frequency mode.

    Returns
    -------
    decodes : list of StripeDecode
        Per blob: the map ID or None with the reason; ``rows_per_chip`` is half the period
        (rows), ``frames`` the periods the support spans.
    frequencies_hz : ndarray, shape (N,)
        Measured frequency per blob, Hz (NaN where unknown).
    note : str
        A remark on a row time fitted from the ratios ("" otherwise).
    """
    n = len(blobs)
    periods = np.full(n, np.nan)
    spans = np.zeros(n)
    centres = np.array([np.asarray(b.pixel, dtype=float) for b in blobs]).reshape(n, 2)
    failures = [""] * n
    for k, (b, g) in enumerate(zip(blobs, gray_rois, strict=True)):
        g = gray_float(g)
        support = light_support(g, b.mask, axis)
        glow = bool(support.sum() >= _GLOW_RATIO * b.mask.sum())
        if not glow:  # a plain disc: its own outline is its striped area
            support = b.mask
        along = support.any(axis=1 if axis == "rows" else 0)
        idx = np.flatnonzero(along)
        spans[k] = float(idx[-1] - idx[0] + 1) if idx.size else 0.0
        if glow:
            centres[k] = _centre_on_support(b, support, axis)
        est = estimate_stripe_period(g, b.mask, axis)  # the disc's: the fit's first guess
        if not est:
            failures[k] = est.message or "no stripe period could be measured"
            continue
        if glow:
            y, w = _glow_profile(g, support, axis, est.period_px)
        else:
            y, w = _mean_profile(g, support, axis)
            degree = 2
        periods[k] = _fit_wave(y, w, est.period_px, 2 if glow else degree)
        if not np.isfinite(periods[k]):
            failures[k] = "no stripe period could be measured"
    with np.errstate(invalid="ignore", divide="ignore"):
        seen = np.where(np.isfinite(periods), spans / periods, 0.0)
    fa = assign_frequencies(periods, fixture_map, camera.row_time_s, periods_spanned=seen)
    note = ""
    if fa.row_time_fitted:
        note = "the camera file has no row_time_s: stripe periods were matched to the map's " + (
            f"frequencies by their ratios (fitted row time {1e6 * fa.row_time_s:.2f} us)"
            if np.isfinite(fa.row_time_s)
            else "frequencies by their ratios, and no consistent match was found"
        )
    decodes = []
    for k in range(n):
        reason = failures[k] or fa.reasons[k]
        fid = fa.ids[k] if not failures[k] else None
        margin = 0.0
        if fid is not None:
            target = fixture_map.get(fid).frequency_hz
            margin = float(np.clip(1 - 20 * abs(np.log(fa.frequencies_hz[k] / target)), 0, 1))
        decodes.append(
            StripeDecode(
                fid,
                "" if fid is not None else reason,
                -1,
                margin,
                0.5 * periods[k],
                float("nan"),
                "",
                float(seen[k]),
            )
        )
    return decodes, fa.frequencies_hz, centres, note
