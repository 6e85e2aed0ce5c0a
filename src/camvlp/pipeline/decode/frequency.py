"""Frequency-coded fixtures: each light blinks a 50 % square wave at its own frequency.

A rolling shutter turns a light blinking at ``f`` Hz into stripes with a period of
``1 / (f * row_time)`` sensor rows.  Each light's stripes are held against the forward model
of a beacon at each of the map's frequencies (:mod:`camvlp.pipeline.decode.beacon`: a 50 %
square wave integrated over the exposure, times and above smooth envelopes that take the
light's shape, a hot core or a glow); the light gets the frequency that explains them, by a
margin over every other, or none, with the reason
(:mod:`camvlp.pipeline.decode.beacon_match`).  Without the row time, the set of the stripes'
periods is matched to the set of map frequencies by their ratios first: the row time is the
one that makes the most periods land on distinct map frequencies.

A light's stripes are measured over its whole striped area, down to the background
(:func:`camvlp.pipeline.detect.disc.light_support`), not only over the bright disc detection
outlines: a real light with a hot core and a glow shows its stripes well beyond it, and every
period more tells the frequency better.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.pipeline.decode.beacon import BeaconProfile, light_profile
from camvlp.pipeline.decode.beacon_match import hold_against, stripes_period
from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.detect.disc import light_support
from camvlp.pipeline.lamp.light_wave import LightWave, separated_wave

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
    0.09 % over 10): what the ratios of a photo's periods are matched with when the row
    time is not given (:func:`assign_frequencies`).
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


def _support(blob, gray: np.ndarray, axis: str) -> tuple[np.ndarray, bool]:
    """A light's striped area, and whether it glows: down to the background for a light that
    glows (its support covers :data:`_GLOW_RATIO` times the disc or more,
    :func:`~camvlp.pipeline.detect.disc.light_support`), the disc's own outline otherwise."""
    support = light_support(gray, blob.mask, axis, cell=blob.cell)
    if support.sum() >= _GLOW_RATIO * blob.mask.sum():
        return support, True
    return _disc_support(blob), False


def _profile(blob, gray: np.ndarray, support: np.ndarray, axis: str) -> BeaconProfile:
    """A light's waveform per line, separated from its radial shape
    (:func:`~camvlp.pipeline.lamp.light_wave.separated_wave`: on the real photos' lights the true
    frequency's fit then leaves every other map frequency 2.6 times its residual or more,
    against 1.6 on the mean level per line), else (the separation fails, or leaves too few
    lines unclipped: a light saturated all over) its mean level per line
    (:func:`~camvlp.pipeline.decode.beacon.light_profile`)."""
    x0, y0 = blob.box[0], blob.box[1]
    ellipse = ((blob.pixel[0] - x0, blob.pixel[1] - y0), tuple(blob.axes_px), blob.angle_deg)
    got = separated_wave(gray, support, ellipse, axis)
    if not isinstance(got, LightWave):
        profile = BeaconProfile(*got[:6])
        if profile.usable:
            return profile
    return BeaconProfile(*light_profile(gray, support, axis))


def _centre(blob, support: np.ndarray) -> np.ndarray:
    """A glowing light's centre ``[u, v]`` (photo pixels): the centre of an ellipse fitted to
    the outline of its whole striped area, down to the background.  A real light's stripes,
    its hot core and its glow are all about its centre, where its bright part (what
    detection outlines) is not: on Luxapose's photo of five lights, 2 to 10 px from the
    lights' own pixels where the bright parts' are 5 to 52 px, and 1.0 cm from Luxapose's
    position where the centres of their radial shapes give 8.7 cm.  The blob's own centre
    when the outline is too short to fit or its centre falls outside the support.  (A plain
    disc keeps the centre detection fitted to its edges.)"""
    contours, _ = cv2.findContours(
        support.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
    )
    if not contours:
        return np.asarray(blob.pixel, dtype=float)
    outline = max(contours, key=cv2.contourArea)
    if outline.shape[0] < 12 or blob.touches_border:
        return np.asarray(blob.pixel, dtype=float)
    (cx, cy), _, _ = cv2.fitEllipse(outline)
    h, w = support.shape
    if not (0 <= cx < w and 0 <= cy < h and support[int(cy), int(cx)]):
        return np.asarray(blob.pixel, dtype=float)
    return np.array([cx + blob.box[0], cy + blob.box[1]], dtype=float)


#: Fewest lights identified at the camera file's row time that rescale it for the others.
_SCALE_LIGHTS = 2
#: The least relative uncertainty left once the row time is rescaled by the photo's lights:
#: drivers blink off their nominal frequencies (the real photos' LEDs by up to 1.5 %), so map
#: frequencies closer than about twice this are not told apart.
_SCALE_FLOOR = 0.01


def _told_apart(tests, profiles, free, map_freqs, row_time: float, periods) -> list:
    """The tests again, of lights whose map frequencies lie too close together to tell apart
    at the row time's tolerance, with the row time rescaled by the lights identified (their
    stripes' periods against their map frequencies; :data:`_SCALE_LIGHTS` or more) and a
    tolerance of what that scale's spread leaves (three times its standard error, at least
    :data:`_SCALE_FLOOR`).  A photo's lights share one row time, so the lights of far-apart
    frequencies tell it to all."""
    sure = [k for k, t in enumerate(tests) if t.index is not None]
    close = [k for k, t in enumerate(tests) if t.crowded]
    if len(sure) < _SCALE_LIGHTS or not close:
        return tests
    ratios = np.array([periods[k] * map_freqs[tests[k].index] * row_time for k in sure])
    scale = float(np.median(ratios))
    spread = 1.4826 * float(np.median(np.abs(ratios - scale))) / np.sqrt(len(sure))
    tolerance = max(3.0 * spread, _SCALE_FLOOR)
    rt = row_time * scale
    out = list(tests)
    for k in close:
        out[k] = hold_against(profiles[k], 1.0 / (map_freqs * rt), free[k], tolerance, rt)
    return out


def decode_frequencies(
    blobs, gray_rois, axis: str, camera: Camera, fixture_map: FixtureMap
) -> tuple[list[StripeDecode], np.ndarray, np.ndarray, str, list]:
    """Identify frequency-coded fixtures: each light's stripes held against the forward model
    of a beacon at each map frequency (:mod:`camvlp.pipeline.decode.beacon`).

    Each light's mean level per line over its striped area (:func:`_support`) is fitted with
    a 50 % square wave integrated over a window, times and above smooth envelopes (the
    light's shape).  A light gets the map frequency whose wave explains its stripes best, by
    a margin over every other map frequency, nearly as well as any frequency at all and line
    by line (:func:`~camvlp.pipeline.decode.beacon_match.hold_against`); a light that sends
    data, text, or a light at no map frequency is refused with the reason.  Two lights that
    choose the same frequency are both refused.  Without the camera's row time, the stripes'
    own periods are matched to the map's frequencies by their ratios first
    (:func:`assign_frequencies`).

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
        Per blob: the map ID or None with the reason; ``margin`` how much better its
        frequency explains the stripes than the next map frequency: the decimal log of
        their likelihood ratio
        (:attr:`~camvlp.pipeline.decode.beacon_match.FrequencyTest.log_ratio`; inf when the
        map has one frequency, NaN when not weighed); ``rows_per_chip`` half the stripes'
        period (rows), ``frames`` the periods shown.
    frequencies_hz : ndarray, shape (N,)
        Measured frequency per blob (the stripes' own period), Hz; NaN where unknown.
    centres : ndarray, shape (N, 2)
        Each light's centre ``[u, v]``, full-resolution pixels (:func:`_centre`).
    note : str
        A remark on a row time fitted from the ratios ("" otherwise).
    beacons : list of tuple
        Per blob, its :class:`~camvlp.pipeline.decode.beacon.BeaconProfile`, its
        :class:`~camvlp.pipeline.decode.beacon_match.FrequencyTest` (None where the row time
        is unknown) and the map's periods it was held against (lines): what the debug pictures draw.
    """
    n = len(blobs)
    map_freqs = np.array([f.frequency_hz for f in fixture_map.fixtures], dtype=float)
    ids_of = [f.id for f in fixture_map.fixtures]
    found = [_support(b, g, axis) for b, g in zip(blobs, gray_rois, strict=True)]
    supports = [m for m, _ in found]
    centres = np.array(
        [
            _centre(b, m) if glows else np.asarray(b.pixel, dtype=float)
            for b, (m, glows) in zip(blobs, found, strict=True)
        ]
    )
    centres = centres.reshape(n, 2)
    profiles = [_profile(b, g, m, axis) for b, g, m in zip(blobs, gray_rois, supports, strict=True)]
    row_time = camera.row_time_s
    seeds = 1.0 / (map_freqs * row_time) if row_time else ()
    free = [stripes_period(p, seeds) for p in profiles]
    periods = np.array([w[0] for _, w in free], dtype=float)
    note = ""
    if not row_time:
        with np.errstate(invalid="ignore", divide="ignore"):
            spans = np.array([p.span for p in profiles]) / periods
        fa = assign_frequencies(periods, fixture_map, None, periods_spanned=spans)
        row_time = fa.row_time_s if np.isfinite(fa.row_time_s) else None
        note = "the camera file has no row_time_s: stripe periods were matched to the map's " + (
            f"frequencies by their ratios (fitted row time {1e6 * row_time:.2f} us)"
            if row_time
            else "frequencies by their ratios, and no consistent match was found"
        )
    if not row_time:
        why = "the row time is unknown and the periods fit no set of the map's frequencies"
        decodes = [StripeDecode(None, why, "frequency", rows_per_chip=0.5 * p) for p in periods]
        return decodes, np.full(n, np.nan), centres, note, [(p, None, None) for p in profiles]
    tests = [
        hold_against(p, 1.0 / (map_freqs * row_time), f, row_time_s=row_time)
        for p, f in zip(profiles, free, strict=True)
    ]
    tests = _told_apart(tests, profiles, free, map_freqs, row_time, periods)
    chosen = [t.index for t in tests]
    decodes = []
    for t in tests:
        fid, reason = (None, t.reason) if t.index is None else (ids_of[t.index], "")
        claims = chosen.count(t.index) if t.index is not None else 0
        if claims > 1:
            fid, reason = None, f"{claims} lights measure {map_freqs[t.index]:.0f} Hz"
        decodes.append(
            StripeDecode(
                fid,
                reason,
                "frequency",
                margin=t.log_ratio,
                rows_per_chip=0.5 * t.period_px,
                frames=float(t.periods_seen),
            )
        )
    with np.errstate(invalid="ignore", divide="ignore"):
        frequencies = 1.0 / (periods * row_time)
    measured = np.where(np.isfinite(frequencies), frequencies, np.nan)
    map_periods = 1.0 / (map_freqs * row_time)
    beacons = [(p, t, map_periods) for p, t in zip(profiles, tests, strict=True)]
    return decodes, measured, centres, note, beacons
