"""The run-length decoder: a fixture's ID read from its stripes' runs (thesis sections 5.3
and 5.4, made robust).

Per fixture:

1. binarise its row profile with a threshold of its own and measure its runs to a fraction
   of a row (:mod:`camvlp.pipeline.decode.runs`);
2. measure the chip length and the bleeding, and count each run's chips, one or two
   (:mod:`camvlp.pipeline.decode.chips`);
3. decode the chips cyclically against every ID's frame (:meth:`FrameFormat.decode`), every
   whole copy of the frame required to agree.

The result says which ID, or why none, with the Hamming distance, the run margin, and the
measured chip length and bleeding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camvlp.model.linecode import FrameFormat
from camvlp.pipeline.decode.chips import bleeds, chip_lengths, read_chips
from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.decode.runs import flat_runs, stripe_levels_many

__all__ = ["ProfileChips", "decode_profile", "decode_profiles", "profile_chips"]


def _refused(reason: str, **kw) -> StripeDecode:
    fields = dict(method="runs", run_margin=0.0, frames=0.0)
    fields.update(kw)
    return StripeDecode(None, reason, **fields)


def _verdicts(read, t: np.ndarray, b: np.ndarray, frame: FrameFormat) -> list[StripeDecode]:
    """Each profile's decode from its chips (``read`` as
    :func:`~camvlp.pipeline.decode.chips.read_chips` gives them): the ID of the whole
    stretch, which every whole copy of the frame must agree with.

    Only the copies of a stretch read as an ID with chips in error are decoded: where none
    is, each copy's known chips are a rotation of that ID's frame, so a copy reads as that ID
    (every chip known) or as none (one unknown, not a whole frame), never another."""
    n = frame.n_chips
    whole = frame.decode_many([(chips, known) for chips, known, *_ in read])
    checked = [k for k, res in enumerate(whole) if res and res.distance > 0]
    spans = [range(0, read[k][0].size - n + 1, n) for k in checked]
    copies = [
        (read[k][0][j : j + n], read[k][1][j : j + n])
        for k, span in zip(checked, spans, strict=True)
        for j in span
    ]
    decoded = iter(frame.decode_many(copies))
    others = dict.fromkeys(range(len(read)))
    for k, span in zip(checked, spans, strict=True):
        subs = [next(decoded) for _ in span]
        others[k] = next((s.id for s in subs if s.id is not None and s.id != whole[k].id), None)
    out = []
    for k, ((chips, _, text, margin, _), rpc, bleed) in enumerate(
        zip(read, t.tolist(), b.tolist(), strict=True)
    ):
        res, other = whole[k], others[k]
        frames = chips.size / n
        common = dict(rows_per_chip=rpc, bleed_rows=bleed, chips=text, frames=frames)
        if not res:
            out.append(_refused(res.reason, hamming=res.distance, **common))
        elif other is not None:
            reason = f"copies of the frame disagree ({res.id} and {other})"
            out.append(_refused(reason, hamming=res.distance, **common))
        else:
            out.append(
                StripeDecode(res.id, "", "runs", run_margin=margin, hamming=res.distance, **common)
            )
    return out


def decode_profile(
    profile: np.ndarray,
    frame: FrameFormat,
    *,
    rows_per_chip: float | None = None,
    max_rows_per_chip: float = 64.0,
    threshold_level: float = 0.6,
) -> StripeDecode:
    """Decode the ID carried by a fixture's row profile.

    Parameters
    ----------
    profile : ndarray, shape (n,)
        Mean intensity per sensor row across the disc, in readout order.
    frame : FrameFormat
        The frame format of the map.
    rows_per_chip : float, optional
        Known chip length in rows (chip duration / row time); measured when None.
    max_rows_per_chip : float
        Longest chip length considered when measuring it.
    threshold_level : float
        Binarisation threshold (see :func:`stripe_threshold`).

    Returns
    -------
    StripeDecode
        Falsy, with a reason, when the stripes do not give one ID with confidence.
    """
    return decode_profiles(
        [profile],
        frame,
        rows_per_chip=rows_per_chip,
        max_rows_per_chip=max_rows_per_chip,
        threshold_level=threshold_level,
    )[0]


def decode_profiles(
    profiles,
    frame: FrameFormat,
    *,
    rows_per_chip: float | None = None,
    max_rows_per_chip: float = 64.0,
    threshold_level: float = 0.6,
) -> list[StripeDecode]:
    """:func:`decode_profile` of several profiles (sequence of 1-D arrays), the same
    decodes, each step worked for all of them at once."""
    got = profile_chips(
        profiles,
        rows_per_chip=rows_per_chip,
        max_rows_per_chip=max_rows_per_chip,
        threshold_level=threshold_level,
    )
    out = list(got.refused)
    if got.which:
        for k, d in zip(got.which, _verdicts(got.read, got.t, got.bleed, frame), strict=True):
            out[k] = d
    return out


@dataclass(frozen=True)
class ProfileChips:
    """The chips of several profiles (:func:`profile_chips`).

    Attributes
    ----------
    refused : list of StripeDecode or None
        Per profile, why its chips were not read (None for those read).
    which : list of int
        The profiles read.
    read : list of tuple
        Per profile read, as :func:`~camvlp.pipeline.decode.chips.read_chips` gives it: its
        chips (uint8), which are sure, the chips as text, its run margin, each chip's
        confidence.
    t, bleed : ndarray, shape (len(which),)
        Per profile read, its chip length and its bleeding, rows.
    """

    refused: list[StripeDecode | None]
    which: list[int]
    read: list[tuple]
    t: np.ndarray
    bleed: np.ndarray


def profile_chips(
    profiles,
    *,
    rows_per_chip: float | None = None,
    max_rows_per_chip: float = 64.0,
    threshold_level: float = 0.6,
) -> ProfileChips:
    """The chips each profile's runs hold (steps 1 and 2 of the module's docstring): each
    profile binarised at ``threshold_level`` of the way from its dark to its bright level,
    its chip length (``rows_per_chip`` when given, else measured, at most
    ``max_rows_per_chip``) and bleeding, and each run's chips; or why not."""
    ps = [np.asarray(p, dtype=float).reshape(-1) for p in profiles]
    out: list[StripeDecode | None] = [None] * len(ps)
    live = [k for k, p in enumerate(ps) if p.size >= 8]
    for k, p in enumerate(ps):
        if p.size < 8:
            out[k] = _refused(f"too small to decode ({p.size} rows)")
    if live:
        dark, bright = stripe_levels_many([ps[k] for k in live])
        thresholds = []
        for k, lo, hi in zip(live, dark.tolist(), bright.tolist(), strict=True):
            if hi - lo < 8:
                out[k] = _refused("no stripes (a steady light, or too little contrast)")
            else:
                thresholds.append(lo + threshold_level * (hi - lo))
        live = [k for k in live if out[k] is None]
    if not live:
        return ProfileChips(out, [], [], np.zeros(0), np.zeros(0))
    r = flat_runs([ps[k] for k in live], np.array(thresholds))
    if rows_per_chip:
        t = np.full(len(live), float(rows_per_chip))
    else:
        t = chip_lengths(r, max_rows_per_chip)
    few = r.n_edges < 4
    irregular = ~few & ~(np.isfinite(t) & (t > 0))
    for q, k in enumerate(live):
        if few[q]:
            out[k] = _refused("no stripes (a steady light, or too few stripes)")
        elif irregular[q]:
            out[k] = _refused("stripes too irregular to measure the chip length")
    which = (~few & ~irregular).nonzero()[0]
    if not which.size:
        return ProfileChips(out, [], [], np.zeros(0), np.zeros(0))
    b = bleeds(r, t, which)
    read = read_chips(r, t[which], b, which)
    return ProfileChips(out, [live[q] for q in which.tolist()], read, t[which], b)
