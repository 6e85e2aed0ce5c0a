"""Stage 1, detect: the photo's lights, the readout axis their stripes show, and each
readable light centred as its look asks (:mod:`camvlp.pipeline.lamp`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from camvlp.model.fixtures import FixtureMap
from camvlp.model.readout import Readout
from camvlp.pipeline.detect.blob import Blob
from camvlp.pipeline.detect.candidates import Detection, detect_fixtures
from camvlp.pipeline.lamp.glow import centred_on_glow, glowing
from camvlp.pipeline.prepare import Prepared
from camvlp.pipeline.settings import LocateSettings

__all__ = [
    "AXIS_MARGIN",
    "STRIPED",
    "STRIPE_SHARE",
    "UNCLEAR_AXIS",
    "Lights",
    "find_lights",
    "spread_out",
    "striped",
    "stripes_axis",
]


@dataclass(frozen=True)
class Lights:
    """The photo's lights (:func:`find_lights`).

    Attributes
    ----------
    detection : Detection
        What the detector found (its blobs as detected).
    blobs : tuple of Blob
        The lights, each readable one centred as its look asks.
    readout : Readout or None
        The readout: given, or its axis from the stripes (None: unclear, nothing is read).
    direction_known : bool
        The readout's direction is given (the call, the camera file or the photo's EXIF);
        otherwise the decoders find it.
    readable : tuple of int
        The lights that show stripes to read (:func:`striped`).
    notes : tuple of str
        What the user should know (an EXIF hint overruled or needed).
    glowing : tuple of bool
        Per light, whether it was centred as a glowing one
        (:func:`~camvlp.pipeline.lamp.glow.glowing`, or as ``glows`` told); empty when no
        light was told (a frequency map, or no readout).
    """

    detection: Detection
    blobs: tuple[Blob, ...]
    readout: Readout | None
    direction_known: bool
    readable: tuple[int, ...]
    notes: tuple[str, ...] = ()
    glowing: tuple[bool, ...] = ()


def find_lights(
    prepared: Prepared,
    fixture_map: FixtureMap,
    settings: LocateSettings,
    readout: Readout | None = None,
    glows: Callable[[list[Blob]], np.ndarray] | None = None,
) -> Lights:
    """Stage 1: the lights of a prepared photo and its readout.

    ``readout``, when given, is taken as known (e.g. a video's, once decided); else the
    call's (``settings.readout``) or the camera's, else the stripes tell the axis
    (:func:`detected_with_readout`).  On a Manchester map each readable glowing light is
    centred on its radial shape (:func:`~camvlp.pipeline.lamp.glow.centred_on_glow`); a
    frequency-coded light is centred as its stripes are measured (stage 3).  ``glows``, when
    given, tells which readable lights (as detected) glow, one flag each (a video's tracker,
    from what earlier frames showed of each fixture); else each light's ring tells
    (:func:`~camvlp.pipeline.lamp.glow.glowing`).
    """
    given = readout or settings.readout or prepared.camera.readout
    detection, found, known, note = detected_with_readout(prepared.image, given, settings)
    blobs = list(detection.blobs)
    readable = [k for k, b in enumerate(blobs) if striped(b)]
    glow_flags: tuple[bool, ...] = ()
    if fixture_map.mode != "frequency" and found is not None:
        sub = [blobs[k] for k in readable]
        which = glowing(prepared.image, sub)[0] if glows is None else glows(sub)
        centred = centred_on_glow(prepared.image, sub, found.axis, which)
        blobs = spread_out(centred, readable, blobs)
        glow_flags = tuple(spread_out([bool(w) for w in which], readable, [False] * len(blobs)))
    notes = (note,) if note else ()
    return Lights(detection, tuple(blobs), found, known, tuple(readable), notes, glow_flags)


def spread_out(values, keep: list[int], default: list) -> list:
    """``default`` with ``values`` (one per index of ``keep``) put at those indices."""
    out = list(default)
    for k, v in zip(keep, values, strict=True):
        out[k] = v
    return out


#: A blob counts as striped, and votes for its readout axis, when the stripes' variation
#: along one axis is at least this many times that along the other
#: (:attr:`Blob.stripe_contrast`)...
STRIPED = 2.0


#: ...and its lines along that axis explain at least this share of its pixels' variance
#: (:attr:`Blob.stripe_share`: 0.6 to 0.98 for the real photos' lights and plain renders,
#: 0.37 to 0.42 for their lamps saturated 7 times over, 0.15 to 0.44 for renders of lamps
#: whose hot core is 5 times their rim's level, with soft stripes; a camera's burned-in text
#: spreads from 0.02 to 0.6: the share weighs a blob's vote, and the decoders refuse text).
STRIPE_SHARE = 0.1


#: The photo's readout axis is clear when the striped blobs' votes for it (each its share)
#: outweigh those for the other axis this many times over.
AXIS_MARGIN = 3.0


def stripes_axis(blobs) -> tuple[str | None, float, float]:
    """The readout axis the photo's stripes show, voted by its striped blobs.

    Each blob whose stripes run clearly one way (:data:`STRIPED`) and whose lines along
    that way explain most of its pixels (:data:`STRIPE_SHARE`) votes for its axis with that
    share; a text, a steady light or a blob of noise has no say.  Returns the axis ("rows"
    or "columns"), or None when the votes do not clear :data:`AXIS_MARGIN` (no striped
    blob, or blobs striped both ways), and the votes for rows and for columns.
    """
    votes = {"rows": 0.0, "columns": 0.0}
    for b in blobs:
        share = float(b.stripe_share)
        if b.stripe_contrast > STRIPED and share >= STRIPE_SHARE:
            votes[b.axis] += share
    rows, cols = votes["rows"], votes["columns"]
    if max(rows, cols) <= 0 or max(rows, cols) < AXIS_MARGIN * min(rows, cols):
        return None, rows, cols
    return ("rows" if rows > cols else "columns"), rows, cols


def detected_with_readout(
    img: np.ndarray, given: Readout | None, st: LocateSettings
) -> tuple[Detection, Readout | None, bool, str]:
    """The fixtures, and the readout: ``given`` (the call's or the camera file's),
    else the axis the stripes show (:func:`stripes_axis`), its direction the photo's EXIF
    hint's (``st.readout_hint``) where that hint's axis is the same, else forward and found
    later.  Returns the detection, the readout (None: the axis is unclear), whether its
    direction is known, and a note ("" or where the hint was overruled or needed)."""

    def detect(axis: str | None) -> Detection:
        return detect_fixtures(
            img, readout=axis, kernel_px=st.kernel_px, min_diameter_px=st.min_diameter_px
        )

    if given is not None:
        return detect(given.axis), given, True, ""
    detection = detect(None)
    axis, rows, cols = stripes_axis(detection.blobs)
    hint, note = st.readout_hint, ""
    if axis is None and hint is not None:
        axis = hint.axis
        note = (
            f"the stripes do not show the readout axis (votes rows {rows:.1f}, columns "
            f"{cols:.1f}): the photo's EXIF orientation gives {hint}"
        )
    elif axis is not None and hint is not None and hint.axis != axis:
        note = (
            f"the photo's EXIF orientation suggests a {hint} readout; its stripes run along {axis}"
        )
        hint = None
    if axis is None:
        return detection, None, False, ""
    if any(b.axis != axis for b in detection.blobs):  # each disc bridged along the photo's axis
        detection = detect(axis)
    if hint is not None:
        return detection, hint, True, note
    return detection, Readout.of(axis), False, note


def striped(blob) -> bool:
    """Whether a blob shows stripes to read: they vary clearly along one axis
    (:data:`STRIPED`) and its lines along it explain a share of its pixels' variance
    (:data:`STRIPE_SHARE`).  A camera's burned-in text, a steady light or a reflection does
    not; it is neither centred nor decoded."""
    return blob.stripe_contrast > STRIPED and float(blob.stripe_share) >= STRIPE_SHARE


#: Why no light of a photo is read when its stripes do not say the readout axis.
UNCLEAR_AXIS = (
    "the stripes do not show which way the sensor read (rows or columns): give the readout "
    "(--readout, or readout in the camera file)"
)
