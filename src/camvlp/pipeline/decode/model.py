"""Model-based stripe decoding: fit the sensor's forward model of every ID to a row profile.

The forward model of a fixture's row profile (the LED's chips integrated over each row's
exposure window, through the sensor's saturation knee and gamma, blurred, with gain and offset)
and its FFT fit at every phase are in :mod:`camvlp.pipeline.decode.stripe_model`.

Decoding fits this model for every candidate ID and every phase.  The ID is the best fit
when its likelihood ratio over the best other ID of the map (``margin``, decimal log, from the
residuals and the noise estimated from the best fit) is safe; otherwise there is no ID, with
the reason.  IDs of the format that are not in the map are fitted too: when one of them fits
clearly better than every ID of the map, the fixture is refused rather than given the nearest
map ID.  That choice is :func:`camvlp.pipeline.decode.model_choice.decide_id`.

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
from camvlp.pipeline.decode.model_choice import FIXTURE_KNEES, MIN_MARGIN, decide_id
from camvlp.pipeline.decode.photo_model import estimate_photo_model, trimmed_cost
from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.decode.stripe_model import (
    MIN_FRAMES,
    SAMPLES_PER_CHIP,
    Fit,
    Folded,
    SensorModel,
    candidate_ids,
    fit_folded,
    fold_profile,
    model_profile,
    model_spectra,
    prepared_profile,
)
from camvlp.pipeline.paths import path

__all__ = [
    "PhotoDecode",
    "SensorModel",
    "decode_photo",
    "decode_profile_model",
    "estimate_photo_model",
    "least_frames",
    "model_profile",
    "too_short",
]


#: Candidate IDs fitted at every knee: all of them up to this many, else the best ones at the
#: photo's knee (see :func:`_own_knee`).
KNEE_LEADERS = 24


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


def _fail_small(p: np.ndarray, rows_per_chip: float, n_chips: int, reason: str) -> StripeDecode:
    frames = p.size / (n_chips * rows_per_chip)
    return StripeDecode(
        None,
        reason,
        method="model",
        margin=0.0,
        unexplained=1.0,
        rows_per_chip=rows_per_chip,
        frames=frames,
    )


def least_frames(frame: FrameFormat) -> float:
    """The fewest frames of ``frame``'s code a light's profile must span to be read: a whole
    one when the frame checks its ID (the check bits a disc does not show check nothing, and
    a light sending data may match the part it shows), else :data:`MIN_FRAMES`."""
    return 1.0 if frame.check_bits else MIN_FRAMES


def too_short(profile: np.ndarray, frame: FrameFormat, rows_per_chip: float) -> StripeDecode | None:
    """The refusal of a profile (shape (n,)) too short to be read at ``rows_per_chip`` (under
    8 rows, or spanning fewer frames of ``frame``'s code than :func:`least_frames`), or None
    when it is long enough to try."""
    profile, n = np.asarray(profile), frame.n_chips
    if profile.size < 8:
        return _fail_small(profile, rows_per_chip, n, f"too small to decode ({profile.size} rows)")
    frames, least = profile.size / (n * rows_per_chip), least_frames(frame)
    if frames < least:
        return _fail_small(
            profile,
            rows_per_chip,
            n,
            f"spans {frames:.2f} frames of the code, at least {least:g} needed",
        )
    return None


def _decode_with(p, w, frame, cand, in_map, chips, spec, model, min_margin, samples):
    n = frame.n_chips
    short = too_short(p, frame, model.rows_per_chip)
    if short is not None:
        return short
    # every phase on a grid of half the templates' resolution, by FFT; the leaders are then
    # refined on the full one (see decide_id)
    fo = fold_profile(p, w, model.rows_per_chip, samples // 2, n)
    fit = Fit(*fit_folded(fo, *spec), fo.spp, p.size, fo.x)
    if fit.tss <= 0:
        return _fail_small(p, model.rows_per_chip, n, "no stripes (a steady light)")
    fit, knees = _own_knee(fit, fo, chips, in_map, model, samples)
    fit = replace(fit, x=2 * fit.x)
    return decide_id(
        fit, chips, cand, in_map, p, w, model, n, samples, min_margin, frame.codebook, knees
    )


def _own_knee(fit: Fit, fo: Folded, chips, in_map, model: SensorModel, samples):
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
    # (kept: the fixtures with the same leaders, and the other readout direction, share them)
    spec_k = model_spectra(chips[lead], model, samples, FIXTURE_KNEES)
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


@path("model decode")
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
                _fail_small(p, fallback.rows_per_chip, frame.n_chips, f"no sensor model: {exc}")
                for p in ps
            )
            return PhotoDecode(fallback, decodes, float("inf"))
    cand, in_map = candidate_ids(frame, ids)
    chips = frame.codebook[cand]
    spec = model_spectra(chips, model, samples)
    decodes = []
    for p, w in zip(ps, ws, strict=True):
        pp, wp = prepared_profile(p, w)
        decodes.append(
            _decode_with(pp, wp, frame, cand, in_map, chips, spec, model, min_margin, samples)
        )
    if not math.isfinite(cost):
        un = np.array([d.unexplained for d in decodes if np.isfinite(d.unexplained)])
        cost = float(trimmed_cost(un)) if un.size else float("inf")
    return PhotoDecode(model, tuple(decodes), cost)
