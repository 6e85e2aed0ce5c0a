"""Manchester IDs of a photo's fixtures, and the readout direction when it is not known.

First the run-length decoder (:func:`camvlp.pipeline.decode.run_decode.decode_profiles`, a
few milliseconds per photo): an ID it reads with no chip in error, every whole copy of the frame
agreeing, a clear run margin, and a chip length that agrees with the other fixtures' (and with
the camera's row time and the map's chip rate when both are known) is taken as it is.  The
model fit (:mod:`camvlp.pipeline.decode.model`) runs only for the fixtures it refuses, with the
chip length it measured as the seed, and not at all when it refuses none.

When the readout's direction is not known, the run-length decoder reads every profile both
ways.  An ID whose frame read backwards is no ID's frame says which way the sensor read; the
fast path takes a direction only when two or more fixtures say it and none says the other.
Otherwise every fixture goes to the model fit under both directions (and then, if that does not
decide, to the pose), as without the fast path.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, replace

import numpy as np

from camvlp.model.camera import Camera
from camvlp.model.fixtures import FixtureMap
from camvlp.model.linecode import FrameFormat
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.model import (
    PhotoDecode,
    SensorModel,
    decode_photo,
    estimate_photo_model,
    too_short,
)
from camvlp.pipeline.decode.model_choice import MIN_MARGIN
from camvlp.pipeline.decode.photo_model import SEEDED_CHIP_SPAN
from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.decode.run_decode import decode_profiles
from camvlp.pipeline.decode.stripe_model import MIN_FRAMES
from camvlp.pipeline.paths import path

__all__ = ["MIN_FAST_MARGIN", "Manchester", "decode_manchester"]

#: Smallest run margin (see :class:`StripeDecode`) of an ID taken from the run-length decoder.
MIN_FAST_MARGIN = 0.3

#: Largest relative disagreement of a fixture's measured chip length with the photo's.
CHIP_AGREEMENT = 0.03


@dataclass(frozen=True)
class Manchester:
    """The Manchester decode of a photo.

    Attributes
    ----------
    decodes : tuple of StripeDecode
        One per profile: the run-length decoder's where it was taken, else the model fit's.
    readout : Readout
        The readout the profiles were read with.
    rows_per_chip : float
        The photo's chip length, rows (the model's when it was fitted, else the run-length
        decoder's median).
    model : SensorModel or None
        The fitted photo-wide parameters (None when no fixture needed the model: the
        run-length decoder read them all, or those it left are too short to read at any
        chip length the fit could reach).
    other : tuple or None
        The decodes under the other direction, when the stripes fit both about equally (the
        pose decides).
    other_model : SensorModel or None
        The parameters fitted under the other direction.
    note : str
        Something the user should know ("" when nothing): the chip length the map's
        ``chip_rate_hz`` and the camera's ``row_time_s`` give against the one the stripes'
        runs show, when no fixture was identified and they disagree.
    """

    decodes: tuple[StripeDecode, ...]
    readout: Readout
    rows_per_chip: float = float("nan")
    model: SensorModel | None = None
    other: tuple[StripeDecode, ...] | None = None
    other_model: SensorModel | None = None
    note: str = ""

    @property
    def exposure_chips(self) -> float:
        """Fitted exposure window, chips (NaN when the model was not needed)."""
        return float("nan") if self.model is None else self.model.exposure_chips


def _fast(profiles, frame: FrameFormat, map_ids: set[int], skip=()):
    """The run-length decodes that may be taken as they are (None for the others, and for
    the profiles ``skip`` flags), and the chip lengths it measured (NaN where it could not)."""
    out: list[StripeDecode | None] = [None] * len(profiles)
    lengths = np.full(len(profiles), np.nan)
    todo = [k for k in range(len(profiles)) if not (k < len(skip) and skip[k])]
    for k, d in zip(todo, decode_profiles([profiles[k] for k in todo], frame), strict=True):
        sure = d.id is not None and d.id in map_ids and d.hamming == 0
        out[k] = d if sure and d.run_margin >= MIN_FAST_MARGIN else None
        if d:
            lengths[k] = d.rows_per_chip
    return out, lengths


def _measured(lengths: np.ndarray) -> float | None:
    """The chip length of the IDs the run-length decoder read when two of them agree."""
    t = lengths[np.isfinite(lengths)]
    if t.size >= 2:
        med = float(np.median(t))
        if np.sum(np.abs(t / med - 1) < CHIP_AGREEMENT) >= 2:
            return med
    return None


def _agreeing(decodes: list[list[StripeDecode | None]], seed: float | None):
    """The photo's chip length from the run-length decodes, and the decodes that agree with
    it (the others set to None).  With no seed, two fixtures must agree."""
    t = [d.rows_per_chip for ds in decodes for d in ds if d is not None]
    ref = seed if seed else (statistics.median(t) if t else math.nan)
    ok = [x for x in t if abs(x / ref - 1) <= CHIP_AGREEMENT]
    if not seed and len(ok) < 2:
        ref = math.nan
    if math.isfinite(ref) and ok and not seed:
        ref = statistics.median(ok)

    def agrees(d: StripeDecode | None) -> bool:
        return d is not None and abs(d.rows_per_chip / ref - 1) <= CHIP_AGREEMENT

    finite = math.isfinite(ref)
    kept = [[d if finite and agrees(d) else None for d in ds] for ds in decodes]
    return (ref if finite else None), kept


def _with_model(
    profiles,
    fast,
    frame: FrameFormat,
    ids,
    t: float | None,
    weights=None,
    rank=None,
    carried: SensorModel | None = None,
):
    """The fast decodes, completed by the model fit for the fixtures they lack: with the
    ``carried`` parameters when they explain those fixtures (:func:`_explains`), else with
    parameters fitted to this photo (the carried ones kept when they read more IDs)."""
    refused = [k for k, d in enumerate(fast) if d is None]
    if not refused:
        return list(fast), None
    sub = [profiles[k] for k in refused]
    sub_w = None if weights is None else [weights[k] for k in refused]
    photo = kept = None
    if carried is not None:
        kept = decode_photo(sub, frame, ids, weights=sub_w, model=carried)
        photo = kept if _explains(kept) else None
    reach = t * (1 - SEEDED_CHIP_SPAN) if t else None  # (the shortest chip the fit may end at)
    if photo is None and reach and all(too_short(p, frame, reach) is not None for p in sub):
        # none is long enough to be read at any chip length the fit can reach from ``t``:
        # no parameters are fitted (the carried ones' reads kept), each refused as too short
        if kept is not None and _read(kept) > 0:
            photo = kept
        else:
            out = list(fast)
            for k, p in zip(refused, sub, strict=True):
                out[k] = too_short(p, frame, t)
            return out, None
    if photo is None:
        try:  # the photo-wide parameters from every fixture, seeded by the chip length
            model, _ = estimate_photo_model(
                profiles, frame, ids, weights=weights, rows_per_chip=t, rank=rank
            )
            photo = decode_photo(sub, frame, ids, weights=sub_w, model=model)
        except ValueError:
            photo = decode_photo(sub, frame, ids, weights=sub_w, rows_per_chip=t)
        if kept is not None and _read(kept) > _read(photo):
            photo = kept
    out = list(fast)
    for k, d in zip(refused, photo.decodes, strict=True):
        out[k] = d
    return out, photo.model


def _read(photo: PhotoDecode) -> int:
    """IDs a model decode read."""
    return sum(d.id is not None for d in photo.decodes)


def _explains(photo: PhotoDecode) -> bool:
    """Whether parameters carried from elsewhere (a video's earlier frames) explain a photo's
    profiles, decoded with them in ``photo``: every profile that spans a frame of the code
    (:data:`~camvlp.pipeline.decode.stripe_model.MIN_FRAMES`) got an ID, of the map or one it
    lacks (``outside_id``: a light of a site's fixtures elsewhere, or one of another map).
    Otherwise (fewer IDs than the profiles promise) the photo's own parameters are fitted."""
    return all(
        d.id is not None or d.outside_id is not None or not d.frames >= MIN_FRAMES
        for d in photo.decodes
    )


def _one_way(
    profiles,
    fast,
    frame: FrameFormat,
    ids,
    seed: float | None,
    fallback,
    readout: Readout,
    weights=None,
    rank=None,
    carried: SensorModel | None = None,
) -> Manchester:
    """The decode of one readout direction taken as known: its run-length decodes ``fast``
    whose chip lengths agree (with ``seed`` or each other), the model fit for the rest (with
    the ``carried`` parameters when they explain them), seeded by that chip length, else
    ``seed``, else ``fallback`` (rows)."""
    t, (kept,) = _agreeing([fast], seed)
    t = t or seed or fallback
    decodes, model = _with_model(profiles, kept, frame, ids, t, weights, rank, carried)
    return _manchester(decodes, readout, model, t)


def _manchester(decodes, readout: Readout, model: SensorModel | None, t) -> Manchester:
    rpc = model.rows_per_chip if model is not None else (float(t) if t else float("nan"))
    return Manchester(tuple(decodes), readout, rpc, model)


def _direction_votes(a: PhotoDecode, b: PhotoDecode, rev: np.ndarray) -> tuple[int, int]:
    """How many fixtures say the direction of ``a`` and how many that of ``b``.

    A fixture says a direction when read that way it gives a clear ID (of the map or not)
    whose frame read backwards is no frame (``rev`` < 0), and its best frame fit that way is
    better than the other way's by a decimal log likelihood ratio of :data:`MIN_MARGIN` (the
    noise the smaller of the two fits').  An ID whose backwards frame is another ID's fits
    both ways alike (the forward model is symmetric in time), whatever the fits say.
    """

    def firm(d) -> bool:
        i = d.id if d.id is not None else getattr(d, "outside_id", None)
        return i is not None and rev[i] < 0

    for_a = for_b = 0
    for da, db in zip(a.decodes, b.decodes, strict=True):
        ra, rb = da.frame_rss, db.frame_rss
        var = min(da.noise_var, db.noise_var)
        if not (np.isfinite(ra) and np.isfinite(rb) and np.isfinite(var) and var > 0):
            continue
        lr = (rb - ra) / (2 * var) / np.log(10)
        for_a += lr >= MIN_MARGIN and firm(da)
        for_b += lr <= -MIN_MARGIN and firm(db)
    return for_a, for_b


@path("both readout directions")
def _model_directions(
    profiles, readout: Readout, frame: FrameFormat, ids, seed, weights=None, rank=None
) -> Manchester:
    """Model-based decode of every profile both ways (see the module's docstring).

    The profiles are decoded both ways (first with one way's parameters, refitted if that
    does not decide).  A reversed frame is no frame for half the IDs: a direction is taken
    when two or more fixtures fit a frame clearly better read that way and none the other
    way (:func:`_direction_votes`); otherwise both are kept for the pose to decide.
    """
    fwd = decode_photo(profiles, frame, ids, weights=weights, rows_per_chip=seed, rank=rank)
    backwards = [p[::-1] for p in profiles]
    bw = None if weights is None else [w[::-1] for w in weights]
    rev = frame.reversed_ids
    flipped = Readout.of(readout.axis, not readout.reversed)

    def better(a: PhotoDecode, b: PhotoDecode) -> bool:
        # read the wrong way, a fixture whose backwards frame is no frame (half the IDs) fits
        # no ID's frame well; one whose backwards frame is another ID's fits both ways alike
        # and says nothing.  A direction is taken when two or more fixtures say it clearly
        # and none says the other (as on the fast path)
        for_a, for_b = _direction_votes(a, b, rev)
        return for_a >= 2 and for_b == 0

    def done(p: PhotoDecode, r: Readout) -> Manchester:
        return Manchester(p.decodes, r, p.model.rows_per_chip, p.model)

    # the parameters do not depend on the direction: first try the other way with them
    back = decode_photo(backwards, frame, ids, weights=bw, model=fwd.model)
    if better(fwd, back):
        return done(fwd, readout)
    # refitted, from this way's chip length (it does not depend on the direction either);
    # the two directions are then compared under the same parameters, those that fit best
    # either way (fits under two different estimates would compare the estimates)
    t_fwd = fwd.model.rows_per_chip if np.isfinite(fwd.cost) else seed
    back2 = decode_photo(backwards, frame, ids, weights=bw, rows_per_chip=t_fwd, rank=rank)
    if back2.fit_cost < min(fwd.fit_cost, back.fit_cost):
        fwd, back = decode_photo(profiles, frame, ids, weights=weights, model=back2.model), back2
    if better(fwd, back):
        return done(fwd, readout)
    if better(back, fwd):
        return done(back, flipped)
    # no fixture says which way (every fixture seen has an ID whose backwards frame is
    # another's): the pose decides
    m = done(fwd, readout)
    return Manchester(m.decodes, readout, m.rows_per_chip, m.model, back.decodes, back.model)


def decode_manchester(
    profiles,
    readout: Readout,
    direction_known: bool,
    camera: Camera,
    fixture_map: FixtureMap,
    weights=None,
    rank=None,
    rows_per_chip: float | None = None,
    model: SensorModel | None = None,
) -> Manchester:
    """Decode every profile: the run-length decoder's sure IDs, the model fit for the rest.

    Parameters
    ----------
    profiles : list of ndarray, each shape (n_k,)
        Row profiles in the order ``readout`` reads them.
    readout : Readout
        The readout (its direction a guess when ``direction_known`` is False).
    direction_known : bool
        The camera file, the call or the photo's EXIF says which way the sensor read.
    camera : Camera
        Its row time (with the map's chip rate) seeds the chip length.
    fixture_map : FixtureMap
        The map's frame format and IDs.
    weights : list of ndarray, each shape (n_k,), optional
        Each profile's row weights for the model fit (the inverse of each row's variance,
        up to a constant per profile); None weighs every row alike.
    rank : sequence of float, optional
        Per profile, how clearly its light is striped: the photo-wide parameters are fitted
        to the first ones (:func:`~camvlp.pipeline.decode.photo_model.estimate_photo_model`).
    rows_per_chip : float, optional
        The chip length when known otherwise (a video's earlier frames), rows: it seeds the
        decoders in place of the camera's row time and the map's chip rate.
    model : SensorModel, optional
        The photo-wide parameters when known otherwise (fitted to a video's earlier frames):
        once the readout's direction is known (given, or said by the run-length IDs), the
        profiles the run-length decoder refuses are decoded with them, and parameters are
        fitted to this photo only when they leave a profile that spans a frame of the code
        without an ID.

    Returns
    -------
    Manchester
        The decodes, the readout they were read with, the photo-wide parameters (``model``
        when it explained the photo; None when the run-length decoder read every profile, or
        every one it left is too short to read).
    """
    seed = rows_per_chip
    if seed is None and camera.row_time_s and fixture_map.chip_rate_hz:
        seed = 1.0 / (camera.row_time_s * fixture_map.chip_rate_hz)
    man = _decode_manchester(
        profiles, readout, direction_known, fixture_map, seed, weights, rank, model
    )
    if seed is None or any(d.id is not None for d in man.decodes):
        return man
    # nothing identified with the chip length the files give: do the stripes' runs say
    # another?  (the run-length IDs that disagree with it were dropped)
    measured = _measured(_fast(profiles, fixture_map.frame, set(fixture_map.distinct_ids))[1])
    if measured is None or abs(measured / seed - 1) <= CHIP_AGREEMENT:
        return man
    note = (
        f"the map's chip_rate_hz and the camera's row_time_s give {seed:.2f} rows per chip, "
        f"the stripes {measured:.2f}: check both"
    )
    return replace(man, note=note)


def _decode_manchester(
    profiles,
    readout: Readout,
    direction_known: bool,
    fixture_map: FixtureMap,
    seed,
    weights,
    rank=None,
    carried: SensorModel | None = None,
) -> Manchester:
    """:func:`decode_manchester` with the chip length the files give (``seed``, rows, or
    None) and the ``carried`` parameters (or None)."""
    frame, ids = fixture_map.frame, fixture_map.distinct_ids
    map_ids = {int(i) for i in ids}
    fwd, lengths = _fast(profiles, frame, map_ids)
    if direction_known:
        fallback = _measured(lengths)
        return _one_way(profiles, fwd, frame, ids, seed, fallback, readout, weights, rank, carried)
    fast_f = fwd  # (fwd is narrowed below to the chip lengths both ways agree on)
    backwards = [p[::-1] for p in profiles]
    bw = None if weights is None else [w[::-1] for w in weights]
    # read backwards, the chips of an ID read forwards with none in error are that ID's frame
    # reversed: a frame (rev[id], which does not say the direction) or none
    bwd, _ = _fast(backwards, frame, map_ids, skip=[d is not None for d in fwd])
    t, (fwd, bwd) = _agreeing([fwd, bwd], seed)
    t = t or seed or _measured(lengths)
    rev = frame.reversed_ids.tolist()  # (Python ints: indexed once a fixture)
    firm_f = sum(d is not None and rev[d.id] < 0 for d in fwd)
    firm_b = sum(d is not None and rev[d.id] < 0 for d in bwd)
    if firm_f >= 2 and firm_b == 0:
        decodes, model = _with_model(profiles, fwd, frame, ids, t, weights, rank, carried)
        return _manchester(decodes, readout, model, t)
    flipped = Readout.of(readout.axis, not readout.reversed)
    if firm_b >= 2 and firm_f == 0:
        decodes, model = _with_model(backwards, bwd, frame, ids, t, bw, rank, carried)
        return _manchester(decodes, flipped, model, t)
    man = _model_directions(profiles, readout, frame, ids, t, weights, rank)
    if man.other is None:
        return man
    # the stripes do not say the direction: each is read as if it were known (its sure
    # run-length IDs, the model fitted to it for the rest), and the pose decides.  Parameters
    # fitted one way can blur the other way's IDs into look-alikes
    one = _one_way(profiles, fast_f, frame, ids, seed, man.rows_per_chip, readout, weights, rank)
    bwd_all = _fast(backwards, frame, map_ids)[0]
    other = _one_way(backwards, bwd_all, frame, ids, seed, man.rows_per_chip, flipped, bw, rank)
    return Manchester(
        one.decodes, readout, one.rows_per_chip, one.model, other.decodes, other.model
    )
