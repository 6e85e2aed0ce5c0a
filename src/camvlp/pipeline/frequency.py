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
period more makes the frequency markedly more precise.  The light's waveform is separated
from its shape (a hot core, a halo) and fitted as what it is, a square wave integrated over
the exposure (:mod:`camvlp.pipeline.light_wave`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.decode import StripeDecode
from camvlp.pipeline.detect import light_support
from camvlp.pipeline.light_wave import light_wave
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

    1 % over 3 periods, falling with the square of the count (4 % over 1.5, 0.25 % over 6,
    0.09 % over 10).  It was set as the worst error of the periodic fit
    (``estimate_stripe_period``); for the waveform fit now used (``light_wave``) it lies well
    above the median errors of ``benchmarks/bench_frequency.py`` (0.1 to 0.7 % over 1.5
    periods, 0.02 to 0.23 % over 4) but below the worst of saturated lights with edges
    sharper than a row (7 % over 1.5 periods, 1.3 % over 4).
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
            # the distance is a log ratio; said as the relative difference it stands for
            reasons[i] = (
                f"{f:.0f} Hz is {100 * (f / map_freqs[j] - 1):+.1f} % off the nearest map "
                f"frequency ({map_freqs[j]:.0f} Hz; at most {100 * np.expm1(max(limit, 0)):.2f} "
                "% accepted here)"
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


#: A light "glows" (its striped area reaches well beyond the detected disc) when its support
#: covers at least this many times the disc's area.
_GLOW_RATIO = 1.5


#: Largest ratio of a disc's ellipse axes for which its outline is drawn as a circle.
_ROUND = 1.1


def _disc_support(blob) -> np.ndarray:
    """The pixels of a plain disc: its lit mask and the circle of its fitted outline.

    The lit mask stops where a dark stripe covers the end of the disc (an LED that is fully
    off there leaves nothing to detect), which would hide a stripe edge and shift the
    period; the outline, fitted to the disc's sides, still reaches there.  For a disc seen
    obliquely (axes differing by more than :data:`_ROUND`) the mask alone is returned.
    """
    a, b = (float(v) for v in blob.axes_px)
    if not (np.isfinite(a) and np.isfinite(b)) or b <= 0 or a / b > _ROUND:
        return blob.mask
    x0, y0 = blob.box[0], blob.box[1]
    h, w = blob.mask.shape
    yy, xx = np.ogrid[:h, :w]
    r = 0.25 * (a + b)
    cx, cy = float(blob.pixel[0]) - x0, float(blob.pixel[1]) - y0
    circle = (xx - cx) ** 2 + (yy - cy) ** 2 <= (r - 0.5) ** 2
    return blob.mask | circle


def _measure_light(blob, gray: np.ndarray, axis: str) -> tuple[float, float, np.ndarray, str]:
    """One light's stripe period (pixels), the periods its support spans, its centre, and why
    the period is unknown ("" when known).

    The light's waveform is separated from its shape and fitted with a square wave
    (:func:`camvlp.pipeline.light_wave.light_wave`) over its whole striped area: down to the
    background for a light that glows (its support covers :data:`_GLOW_RATIO` times the
    disc or more), the disc's own outline otherwise.  A glowing light is centred on its
    radial shape (the detected disc is only the part of it bright enough to clip); a plain
    disc keeps the centre detection fitted to its edges.  When the wave fit fails without
    concluding that the light has no period to measure (clipped all over, steady, under one
    period: the periodic fit would find a wrong one), the periodic fit over the disc
    (:func:`~camvlp.pipeline.stripes.estimate_stripe_period`) is used instead.
    """
    centre = np.asarray(blob.pixel, dtype=float)
    support = light_support(gray, blob.mask, axis, cell=blob.cell)
    glow = bool(support.sum() >= _GLOW_RATIO * blob.mask.sum())
    if not glow:  # a plain disc: its own outline is its striped area, dark ends included
        support = _disc_support(blob)
    along = np.flatnonzero(support.any(axis=1 if axis == "rows" else 0))
    span = float(along[-1] - along[0] + 1) if along.size else 0.0
    x0, y0 = blob.box[0], blob.box[1]
    ellipse = ((centre[0] - x0, centre[1] - y0), tuple(blob.axes_px), blob.angle_deg)
    wave = light_wave(gray, support, ellipse, axis)
    if wave:
        h, w = support.shape
        inside = 0 <= wave.centre[0] < w and 0 <= wave.centre[1] < h
        if glow and inside and not blob.touches_border:
            centre = wave.centre + np.array([x0, y0], dtype=float)
        return wave.period_px, span, centre, ""
    if wave.conclusive:
        return float("nan"), span, centre, wave.message
    est = estimate_stripe_period(gray, support, axis)
    if est:
        return est.period_px, span, centre, ""
    return float("nan"), span, centre, est.message or "no stripe period could be measured"


def decode_frequencies(
    blobs, gray_rois, axis: str, camera: Camera, fixture_map: FixtureMap
) -> tuple[list[StripeDecode], np.ndarray, np.ndarray, str]:
    """Identify frequency-coded fixtures from their stripe periods.

    Each light's period comes from its waveform, separated from its shape and fitted with a
    square wave over its whole striped area (:func:`_measure_light`,
    :func:`camvlp.pipeline.light_wave.light_wave`).  A light whose striped area reaches well
    beyond the disc (a glow: its support down to the background,
    :func:`camvlp.pipeline.detect.light_support`, covers 1.5 times the disc's area or more) is
    centred on its radial shape (returned in ``centres``; the blobs are not changed).  The
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
    centres : ndarray, shape (N, 2)
        Each light's centre ``[u, v]``, full-resolution pixels: the blob's own, or for a
        glowing light, the centre of its radial shape.
    note : str
        A remark on a row time fitted from the ratios ("" otherwise).
    """
    n = len(blobs)
    periods = np.full(n, np.nan)
    spans = np.zeros(n)
    centres = np.array([np.asarray(b.pixel, dtype=float) for b in blobs]).reshape(n, 2)
    failures = [""] * n
    for k, (b, g) in enumerate(zip(blobs, gray_rois, strict=True)):
        periods[k], spans[k], centres[k], failures[k] = _measure_light(b, g, axis)
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
