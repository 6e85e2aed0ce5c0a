"""The forward model of a fixture's row profile, and its least-squares fit at every phase.

A rolling-shutter sensor row ``r`` integrates the LED over its exposure window.  In units of
chips, row ``r`` starts at ``u = r / rows_per_chip + phase`` and sees the mean of the frame's
chips (repeated cyclically) over ``[u, u + exposure]``: a box of ``exposure`` chips.  The sensor
responds to that on-fraction ``s`` through a saturation knee and an optional gamma,
``h(s) = (min(s, knee) / knee) ** gamma`` (an LED that is not fully off, and the background,
only add an offset before the knee, which with ``gamma = 1`` the fitted offset absorbs);
processing blurs the rows (a Gaussian of ``blur_rows``); the profile is then
``gain * h + offset``.

The model is periodic (one frame), so on a grid of ``S`` samples per chip every phase of every
ID is one circular cross-correlation of the profile (folded onto the frame's period) with the
ID's template: three FFT correlations give, for all IDs and phases at once, the sums from which
the least-squares gain and offset and the residual follow in closed form
(:mod:`camvlp.pipeline.decode.model` decides the ID from them).
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["SAMPLES_PER_CHIP", "SensorModel", "model_profile"]

#: Samples per chip of the periodic templates (phase resolution 1/32 chip).
SAMPLES_PER_CHIP = 32

#: Smallest fraction of one frame a profile must span to be decoded (below one frame, IDs that
#: differ only in the chips not seen fit equally, and the margin refuses them).  A frame with
#: check bits (``FrameFormat.check_bits``) is read only whole
#: (:mod:`~camvlp.pipeline.decode.model`).
MIN_FRAMES = 0.8


@dataclass(frozen=True)
class SensorModel:
    """The photo-wide parameters of the forward model.

    Attributes
    ----------
    rows_per_chip : float
        Chip length in sensor rows (chip duration / row time).
    exposure_chips : float
        Exposure window of a row, chips (the box the LED is integrated over).
    knee : float
        Saturation knee as a fraction of the LED's full on-level: on-fractions above it read
        as full scale (1 = no saturation; 0.25 = the LED is 4x the sensor's full scale).
    gamma : float
        Exponent of the sensor's tone curve after the knee (1 = linear).
    blur_rows : float
        Sigma of the Gaussian blur along the readout axis, rows.
    """

    rows_per_chip: float
    exposure_chips: float = 0.5
    knee: float = 1.0
    gamma: float = 1.0
    blur_rows: float = 0.0

    def __post_init__(self) -> None:
        for name in ("rows_per_chip", "exposure_chips", "knee", "gamma"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v!r}")
        if not (math.isfinite(self.blur_rows) and self.blur_rows >= 0):
            raise ValueError(f"blur_rows must be a non-negative number, got {self.blur_rows!r}")


# --------------------------------------------------------------------------------------------
# The forward model


def _on_time(cum: np.ndarray, chips: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Cumulative on-time (chips) of cyclic chip streams up to times ``t`` (chips).

    ``cum`` (I, N + 1) is each stream's cumulative on-time at the chip boundaries, ``chips``
    (I, N) its chips, ``t`` any shape ``S``; returns shape ``S + (I,)``.
    """
    n = chips.shape[1]
    cycles = np.floor(t / n)
    tt = t - cycles * n
    k = np.minimum(tt.astype(np.int64), n - 1)
    frac = tt - k
    return cycles[..., None] * cum[:, -1] + cum.T[k] + frac[..., None] * chips.T[k]


def templates_batch(
    chips: np.ndarray,
    rows_per_chip: float,
    exposure: np.ndarray,
    knee: np.ndarray,
    gamma: np.ndarray,
    blur_rows: np.ndarray,
    samples: int,
) -> np.ndarray:
    """One period of each ID's noise-free profile, for several parameter sets at once.

    Parameters
    ----------
    chips : ndarray of {0, 1}, shape (I, N)
    rows_per_chip : float
    exposure, knee, gamma, blur_rows : ndarray, shape (V,)
        Parameter sets (see :class:`SensorModel`).
    samples : int
        Grid points per chip.

    Returns
    -------
    ndarray of float64, shape (V, I, N * samples)
        ``h(s)`` blurred, where sample ``k`` is the row whose exposure starts at chip
        ``k / samples``; values in [0, 1].
    """
    c = np.asarray(chips, dtype=np.float64)
    n = c.shape[1]
    cum = np.concatenate([np.zeros((c.shape[0], 1)), np.cumsum(c, axis=1)], axis=1)
    u = np.arange(n * samples) / samples
    e = np.asarray(exposure, dtype=np.float64)[:, None]
    start = _on_time(cum, c, u)  # (P, I)
    stop = _on_time(cum, c, u[None, :] + e)  # (V, P, I)
    s = np.moveaxis((stop - start[None]) / e[:, :, None], 2, 1)  # (V, I, P)
    kn = np.asarray(knee, dtype=np.float64)[:, None, None]
    h = np.minimum(s, kn) / kn
    g = np.asarray(gamma, dtype=np.float64)[:, None, None]
    if np.any(g != 1.0):
        h = np.power(np.clip(h, 0.0, 1.0), g)
    b = np.asarray(blur_rows, dtype=np.float64)
    if np.any(b > 0):
        sigma = (b / rows_per_chip * samples)[:, None, None]  # in samples
        f = np.fft.rfftfreq(h.shape[2])[None, None, :]
        h = np.fft.irfft(
            np.fft.rfft(h, axis=2) * np.exp(-2 * (np.pi * sigma * f) ** 2), n=h.shape[2], axis=2
        )
    return h


def templates(chips: np.ndarray, model: SensorModel, samples: int) -> np.ndarray:
    """:func:`templates_batch` for one parameter set: shape (I, N * samples)."""
    return templates_batch(
        chips,
        model.rows_per_chip,
        np.array([model.exposure_chips]),
        np.array([model.knee]),
        np.array([model.gamma]),
        np.array([model.blur_rows]),
        samples,
    )[0]


class KeptArrays:
    """Templates and spectra kept by everything they are made of, read-only, the least
    recently used dropped beyond ``budget`` bytes: a photo's fixtures, both its readout
    directions and a video's frames read with carried parameters fit the same ones.  Safe
    to share between threads (the service's)."""

    def __init__(self, budget: int) -> None:
        self._items: OrderedDict[tuple, tuple[np.ndarray, ...]] = OrderedDict()
        self._bytes, self._budget = 0, budget
        self._lock = threading.Lock()

    def get(self, key: tuple, make: Callable[[], tuple[np.ndarray, ...]]):
        """The arrays kept under ``key``, else ``make()``'s (then kept)."""
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
        value = make()
        for a in value:
            a.flags.writeable = False
        size = sum(a.nbytes for a in value)
        with self._lock:
            if size <= self._budget and key not in self._items:
                self._items[key] = value
                self._bytes += size
                while self._bytes > self._budget:
                    _, dropped = self._items.popitem(last=False)
                    self._bytes -= sum(a.nbytes for a in dropped)
        return value


#: Bytes of templates and spectra kept (:class:`KeptArrays`): a parameter set's take some
#: 2.2 MB with the thesis' 4-bit frame (most of it the spectra at every knee), 9 MB with a
#: 7-bit frame with 8 check bits (40 chips, 128 IDs).
_KEPT = KeptArrays(64 * 2**20)


def _key(chips: np.ndarray, model: SensorModel, samples: int, knees: np.ndarray | None):
    c = np.ascontiguousarray(chips)
    return (
        c.shape,
        c.dtype.str,
        c.tobytes(),
        model,
        samples,
        None if knees is None else knees.tobytes(),
    )


def knee_templates(chips: np.ndarray, model: SensorModel, knees, samples: int) -> np.ndarray:
    """:func:`templates_batch` of ``model``'s parameters at each saturation knee of ``knees``
    (K,) instead of its own: shape (K, I, N * samples), read-only (kept for the next call
    with the same arguments)."""
    kn = np.asarray(knees, dtype=np.float64).reshape(-1)
    v = np.ones(kn.size)

    def make() -> tuple[np.ndarray]:
        t = templates_batch(
            chips,
            model.rows_per_chip,
            v * model.exposure_chips,
            kn,
            v * model.gamma,
            v * model.blur_rows,
            samples,
        )
        return (t,)

    return _KEPT.get(("knees", *_key(chips, model, samples, kn)), make)[0]


def model_profile(
    chips, model: SensorModel, n_rows: int, phase_chips: float = 0.0, *, samples: int = 64
) -> np.ndarray:
    """The forward model: a fixture's row profile with unit gain and zero offset.

    Parameters
    ----------
    chips : array_like of {0, 1}, shape (N,)
        One frame of chips (1 = on), e.g. ``FrameFormat().chips(5)``.
    model : SensorModel
        Photo-wide parameters.
    n_rows : int
        Rows of the profile.
    phase_chips : float
        Chip (fractional) of the frame at which row 0's exposure starts.
    samples : int
        Grid points per chip of the periodic template (the model is exact on the grid and
        linearly interpolated between its points).

    Returns
    -------
    ndarray of float64, shape (n_rows,)
        Values in [0, 1]: 0 for the LED off throughout, 1 for full scale.
    """
    c = np.asarray(chips, dtype=np.float64).reshape(1, -1)
    t = templates(c, model, samples)[0]
    period = t.size
    x = (np.arange(n_rows) / model.rows_per_chip + phase_chips) * samples
    return np.interp(x % period, np.arange(period + 1), np.append(t, t[0]))


# --------------------------------------------------------------------------------------------
# Fitting


@dataclass(frozen=True)
class Folded:
    """A profile folded onto the template grid's period at one chip length (internal).

    Row ``r`` falls at grid position ``x = r * samples / rows_per_chip`` (modulo the period),
    between grid points ``i = floor(x)`` and ``i + 1`` with fraction ``f``; the template is
    interpolated linearly there, so each sum of the fit is a correlation of a folded vector
    with a template, its square, or its product with its next point.
    """

    qh: np.ndarray  # (F,) conj. spectrum of sum w p ((1 - f) at i, f at i + 1)
    wh: np.ndarray  # (F,) the same for the weights
    ah: np.ndarray  # (F,) weights (1 - f)^2 at i and f^2 at i + 1 (for m^2)
    bh: np.ndarray  # (F,) weights 2 f (1 - f) at i (for m[i] m[i + 1])
    s0: float  # sum of weights
    spp: float  # weighted sum of squares of the centred profile (total sum of squares)
    centre: float  # weighted mean removed from the profile
    x: np.ndarray  # (n,) grid position of each row at phase 0
    period: int  # grid points per frame


def fold_profile(p: np.ndarray, w: np.ndarray, rows_per_chip: float, samples: int, n_chips: int):
    """Fold a profile onto one frame's grid (see :class:`Folded`)."""
    period = n_chips * samples
    centre = float((w * p).sum() / max(w.sum(), 1e-300))
    pc = p - centre
    x = (np.arange(p.size) * (samples / rows_per_chip)) % period
    i0 = np.floor(x).astype(np.int64)
    f = x - i0
    i0 %= period
    i1 = (i0 + 1) % period
    both = np.concatenate([i0, i1])

    def spec(v0: np.ndarray, v1: np.ndarray | None = None) -> np.ndarray:
        v = (
            np.bincount(i0, weights=v0, minlength=period)
            if v1 is None
            else np.bincount(both, weights=np.concatenate([v0, v1]), minlength=period)
        )
        return np.conj(np.fft.rfft(v))

    wp = w * pc
    return Folded(
        spec(wp * (1 - f), wp * f),
        spec(w * (1 - f), w * f),
        spec(w * (1 - f) ** 2, w * f * f),
        spec(2 * w * f * (1 - f)),
        float(w.sum()),
        float((w * pc * pc).sum()),
        centre,
        x,
        period,
    )


def fit_folded(fo: Folded, mh: np.ndarray, m2h: np.ndarray, mmh: np.ndarray):
    """Least-squares ``gain * template(phase) + offset`` for every template and phase.

    ``mh``, ``m2h`` and ``mmh`` (..., F) are the spectra of the templates, of their squares
    and of their products with their next grid point; the correlations with the folded
    profile give, for every phase ``j`` (grid point of the frame at row 0), ``sum w p m``,
    ``sum w m`` and ``sum w m^2``, hence the fit in closed form.  Returns ``rss, gain,
    offset``, each of shape (..., P); a candidate whose best gain is not positive (stripes
    the wrong way round) gets the residual of a constant.
    """
    a = np.fft.irfft(fo.qh * mh, n=fo.period)  # sum w p m
    b = np.fft.irfft(fo.wh * mh, n=fo.period)  # sum w m
    c = np.fft.irfft(fo.ah * m2h + fo.bh * mmh, n=fo.period)  # sum w m^2
    s0 = fo.s0
    det = c * s0 - b * b
    ok = det > 1e-9 * s0 * s0
    safe = np.where(ok, det, 1.0)
    gain = np.where(ok, a * s0 / safe, 0.0)  # sum w p = 0 after centring
    offset = np.where(ok, -b * a / safe, 0.0) + fo.centre
    rss = np.where(ok & (gain > 0), fo.spp - gain * a, fo.spp)
    return np.maximum(rss, 0.0), gain, offset


def template_spectra(t: np.ndarray):
    """Spectra of templates (..., P), of their squares and of their products with the next."""
    return (
        np.fft.rfft(t, axis=-1),
        np.fft.rfft(t * t, axis=-1),
        np.fft.rfft(t * np.roll(t, -1, axis=-1), axis=-1),
    )


def direct_fit(
    p: np.ndarray, w: np.ndarray, template: np.ndarray, x: np.ndarray, phases: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted least-squares fits of templates at given (fractional) phases.

    ``template`` (..., P) is sampled at ``(x + phase) mod P`` with linear interpolation (``x``
    (n,) the rows' grid positions); returns ``rss, gain, offset``, each of shape (..., K) for
    ``phases`` (K,); a fit with a gain that is not positive gets the residual of a constant.
    """
    period = template.shape[-1]
    xs = (x[None, :] + np.asarray(phases, dtype=np.float64)[:, None]) % period
    i0 = np.floor(xs).astype(np.int64)
    f = xs - i0
    i0 %= period
    # (..., K, n), laid out in that order: each fit's sums over its rows then come out the
    # same whichever templates are fitted with it
    m = np.ascontiguousarray(template[..., i0] * (1 - f) + template[..., (i0 + 1) % period] * f)
    s0 = w.sum()
    mw = (m * w).sum(axis=-1) / s0
    pw = (p * w).sum() / s0
    mc = m - mw[..., None]
    pc = p - pw
    smm = (w * mc * mc).sum(axis=-1)
    spm = (w * mc * pc).sum(axis=-1)
    spp = (w * pc * pc).sum()
    gain = np.where(smm > 0, spm / np.where(smm > 0, smm, 1.0), 0.0)
    rss = np.where(gain > 0, spp - gain * spm, spp)
    return np.maximum(rss, 0.0), gain, pw - gain * mw


@dataclass(frozen=True)
class Fit:
    """Least-squares fits of every candidate at every phase (internal)."""

    rss: np.ndarray  # (I, P) weighted residual sum of squares
    gain: np.ndarray  # (I, P)
    offset: np.ndarray  # (I, P)
    tss: float  # weighted total sum of squares around the mean
    n: int  # rows
    x: np.ndarray  # (n,) grid position of each row at phase 0


def model_spectra(chips: np.ndarray, model: SensorModel, samples: int, knees=None):
    """Spectra (see :func:`template_spectra`) of the templates on the search grid: every
    other point of the ``samples``-per-chip grid; read-only (kept for the next call with the
    same arguments).

    With ``knees`` (K,), those of the templates at each of these saturation knees instead of
    the model's: shapes (K, I, F) instead of (I, F).
    """
    kn = None if knees is None else np.asarray(knees, dtype=np.float64).reshape(-1)

    def make():
        if kn is None:
            t = templates(chips, model, samples)
        else:
            t = knee_templates(chips, model, kn, samples)
        return template_spectra(t[..., ::2])

    return _KEPT.get(("spectra", *_key(chips, model, samples, kn)), make)


def prepared_profile(profile, weights) -> tuple[np.ndarray, np.ndarray]:
    """A light's profile (levels per line, shape (n,)) and its weights per line (shape (n,),
    or None for equal ones) ready for the model's fits: the weights that are not finite
    or not positive set to 0, the others scaled to a mean of 1, and a line whose level is
    not finite given level 0 and weight 0.  An empty profile gives two empty arrays.

    Raises
    ------
    ValueError
        Weights of another shape than the profile's.
    """
    p = np.asarray(profile, dtype=np.float64).reshape(-1)
    if weights is None:
        w = np.ones(p.size)
    else:
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        if w.shape != p.shape:
            raise ValueError("weights must have the profile's shape")
        w = np.where(np.isfinite(w) & (w > 0), w, 0.0)
        if w.size:  # (the mean of no lines is not a number)
            w = w / max(w.mean(), 1e-300)
    good = np.isfinite(p)
    return np.where(good, p, 0.0), np.where(good, w, 0.0)


def candidate_ids(frame, ids, max_extra: int = 1024):
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
