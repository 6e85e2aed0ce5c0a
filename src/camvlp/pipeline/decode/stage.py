"""Stages 2 and 3, profile and decode: each light's row profile, and what its stripes say
(a Manchester ID, or a frequency of the map), or why they say nothing."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np

from camvlp.imaging.gray import to_gray
from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.frequency import decode_frequencies
from camvlp.pipeline.decode.glow_split import decode_from_glows
from camvlp.pipeline.decode.manchester import Manchester, decode_manchester
from camvlp.pipeline.decode.model import SensorModel
from camvlp.pipeline.decode.profile import shape_profiles
from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.detect.blob import Blob
from camvlp.pipeline.lights import STRIPE_SHARE, STRIPED, UNCLEAR_AXIS, Lights, spread_out
from camvlp.pipeline.prepare import Prepared

__all__ = ["CLEAR", "Decoded", "Profiles", "decode", "no_stripes", "read_profiles", "unread"]


@dataclass(frozen=True)
class Profiles:
    """Each light's row profile (:func:`read_profiles`).

    Attributes
    ----------
    gray_rois : tuple of ndarray of uint8
        Each light's region of interest in gray levels.
    extents : ndarray, shape (n,)
        Sensor lines each light's disc spans along the readout.
    profiles, weights : tuple of ndarray, each shape (n_k,)
        Each light's level per sensor line, in the order the sensor read them, and each
        line's weight for the model fit (the inverse of its variance, up to a constant).
    """

    gray_rois: tuple[np.ndarray, ...]
    extents: np.ndarray
    profiles: tuple[np.ndarray, ...]
    weights: tuple[np.ndarray, ...]


def read_profiles(image: np.ndarray, blobs, readout: Readout) -> Profiles:
    """Stage 2: each blob's gray region, its extent along the readout and its row profile
    (:func:`~camvlp.pipeline.decode.profile.shape_profiles`), in the order the sensor read
    it (reversed for a reversed readout)."""
    gray_rois = [
        b.gray if b.gray is not None else to_gray(image[b.box[1] : b.box[3], b.box[0] : b.box[2]])
        for b in blobs
    ]
    extents = np.array([extent(b, readout.axis) for b in blobs])
    step = -1 if readout.reversed else 1
    shaped = shape_profiles(
        gray_rois,
        [b.mask for b in blobs],
        readout.axis,
        [(b.pixel[0] - b.box[0], b.pixel[1] - b.box[1]) for b in blobs],
        [b.axes_px for b in blobs],
        [b.angle_deg for b in blobs],
    )
    return Profiles(
        tuple(gray_rois),
        extents,
        tuple(p[::step] for p, _, _ in shaped),
        tuple(w[::step] for _, _, w in shaped),
    )


def extent(blob: Blob, axis: str) -> float:
    """Sensor lines a detected disc spans along the readout axis ("rows" or "columns"): the
    side of its mask's bounding box (0 for an empty mask)."""
    _, _, w, h = cv2.boundingRect(blob.mask.view(np.uint8))
    return float(h if axis == "rows" else w)


@dataclass(frozen=True)
class Decoded:
    """What the lights' stripes say (:func:`decode`).

    Attributes
    ----------
    decodes : tuple of StripeDecode
        Per light: its ID (or None) and why not.
    frequencies : ndarray, shape (n,)
        Per light, the frequency its stripes were measured at, Hz (NaN on a Manchester map).
    blobs : tuple of Blob
        The lights; a frequency-coded one centred on its whole striped area.
    beacons : tuple
        Per frequency-coded light, its beacon fit, for the debug pictures (empty otherwise).
    manchester : Manchester or None
        The Manchester decode with its photo-wide parameters (None on a frequency map).
    profiles : Profiles
        The profiles, a light read from its glow with its waveform as its profile.
    notes : tuple of str
        What the user should know.
    """

    decodes: tuple
    frequencies: np.ndarray
    blobs: tuple[Blob, ...]
    beacons: tuple
    manchester: Manchester | None
    profiles: Profiles
    notes: tuple[str, ...] = ()


#: Why a light was not decoded: its ID is known otherwise (:func:`decode`'s ``skip``).
NOT_DECODED = "not decoded: its ID comes from the track"


def decode(
    prepared: Prepared,
    lights: Lights,
    profiles: Profiles,
    fixture_map: FixtureMap,
    *,
    skip=(),
    rows_per_chip: float | None = None,
    model: SensorModel | None = None,
) -> Decoded:
    """Stage 3: what each readable light's stripes say; the others are refused with why.

    Parameters
    ----------
    prepared, lights, profiles
        The earlier stages' results.
    fixture_map : FixtureMap
        Its mode (Manchester IDs or frequencies), frame format, IDs and frequencies.
    skip : iterable of int
        Lights not to decode (a video's, whose IDs the track knows).
    rows_per_chip : float, optional
        The chip length when known otherwise (a video's earlier frames), rows.
    model : SensorModel, optional
        The photo-wide parameters when known otherwise (a video's earlier frames): the
        Manchester decoder starts from them and fits its own only when they do not explain
        the photo (:func:`~camvlp.pipeline.decode.manchester.decode_manchester`).
    """
    blobs = list(lights.blobs)
    if lights.readout is None:
        return Decoded(
            tuple(unread(blobs)), np.full(len(blobs), np.nan), tuple(blobs), (), None, profiles
        )
    skipped = set(skip)
    keep = [k for k in lights.readable if k not in skipped]
    refused = [
        StripeDecode(None, NOT_DECODED, frames=0.0) if k in skipped else no_stripes(b)
        for k, b in enumerate(blobs)
    ]
    if fixture_map.mode == "frequency":
        return _frequencies(prepared, lights, profiles, fixture_map, keep, refused)
    return _manchester(prepared, lights, profiles, fixture_map, keep, refused, rows_per_chip, model)


def _frequencies(prepared, lights, profiles, fixture_map, keep, refused) -> Decoded:
    """:func:`decode` on a frequency-coded map: each readable light held against a beacon at
    each map frequency (:func:`~camvlp.pipeline.decode.frequency.decode_frequencies`)."""
    blobs = list(lights.blobs)
    sub = [blobs[k] for k in keep]
    got, freqs, centres, note, fits = decode_frequencies(
        sub,
        [profiles.gray_rois[k] for k in keep],
        lights.readout.axis,
        prepared.camera,
        fixture_map,
    )
    moved = [
        b if np.array_equal(c, b.pixel) else dataclasses.replace(b, pixel=c)
        for b, c in zip(sub, centres, strict=True)
    ]
    frequencies = np.full(len(blobs), np.nan)
    frequencies[keep] = freqs
    return Decoded(
        tuple(spread_out(got, keep, refused)),
        frequencies,
        tuple(spread_out(moved, keep, blobs)),
        tuple(spread_out(fits, keep, [(None, None, None)] * len(blobs))),
        None,
        profiles,
        (note,) if note else (),
    )


#: Lights whose stripe contrast times share (:attr:`Blob.stripe_contrast`,
#: :attr:`Blob.stripe_share`) reaches this are all alike clearly striped (the stress grid's
#: lamps: 2.2 and up; a burned-in text's characters: 1.2 at most): the photo-wide parameters
#: are fitted to the longest of them first.
CLEAR = 2.0


def _manchester(
    prepared, lights, profiles, fixture_map, keep, refused, rows_per_chip, model
) -> Decoded:
    """:func:`decode` on a Manchester map: :func:`decode_manchester` of the readable lights,
    then those it refused read from their glows
    (:func:`~camvlp.pipeline.decode.glow_split.decode_from_glows`), whose waveforms become
    their profiles."""
    blobs = list(lights.blobs)
    sub_p = [profiles.profiles[k] for k in keep]
    sub_w = [profiles.weights[k] for k in keep]
    # the photo-wide parameters from the clearly striped lights, the longest first
    rank = [min(blobs[k].stripe_contrast * float(blobs[k].stripe_share), CLEAR) for k in keep]
    man = decode_manchester(
        sub_p,
        lights.readout,
        lights.direction_known,
        prepared.camera,
        fixture_map,
        sub_w,
        rank,
        rows_per_chip,
        model,
    )
    glows = any(lights.glowing) or not lights.glowing  # (not told: as if some did)
    man, waves = decode_from_glows(
        prepared.image, [blobs[k] for k in keep], man, fixture_map, glows
    )
    step = -1 if lights.readout.reversed else 1  # (in the order of the others)
    all_p, all_w = list(profiles.profiles), list(profiles.weights)
    for j, wave in waves.items():
        all_p[keep[j]], all_w[keep[j]] = wave.level[::step], wave.weight[::step]
    if len(keep) < len(blobs):
        other = None if man.other is None else tuple(spread_out(man.other, keep, refused))
        man = dataclasses.replace(
            man, decodes=tuple(spread_out(man.decodes, keep, refused)), other=other
        )
    return Decoded(
        tuple(man.decodes),
        np.full(len(blobs), np.nan),
        tuple(blobs),
        (),
        man,
        dataclasses.replace(profiles, profiles=tuple(all_p), weights=tuple(all_w)),
        (man.note,) if man.note else (),
    )


def no_stripes(blob) -> StripeDecode:
    """The decode of a blob that shows no stripes to read
    (:func:`~camvlp.pipeline.lights.striped`), with why."""
    share = float(blob.stripe_share)
    if not np.isfinite(share):
        why = "no stripes to read"
    elif share < STRIPE_SHARE:
        why = (
            f"no stripes to read: its lines explain {100 * share:.0f} % of its pixels (text, "
            "a steady light, or not a coded light)"
        )
    else:
        why = (
            f"no stripes to read along the {blob.axis}: its level varies {blob.stripe_contrast:.1f}"
            f" times as much from line to line along them as across (more than {STRIPED:g} "
            "needed)"
        )
    return StripeDecode(None, why)


def unread(blobs) -> list[StripeDecode]:
    """Every blob left unread, as when the photo's readout axis is unclear."""
    return [StripeDecode(None, UNCLEAR_AXIS) for _ in blobs]
