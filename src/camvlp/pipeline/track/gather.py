"""Each light of a video followed from frame to frame by its place in the image, gathering
the pieces of code its stripes show (:mod:`camvlp.pipeline.decode.partial`), for the video
tracker (:mod:`camvlp.pipeline.track.tracker`).

A light is followed before it has an ID (the tracker's predictions follow fixtures, which
need IDs): each blob of a frame continues the light predicted nearest it (where it was last
seen, moved on at its velocity), when that is within a gate and no other light or blob is
nearly as close; otherwise it starts a light of its own.  A light no blob continues is
dropped, its pieces with it: a light that leaves the picture and comes back starts over
(its fixture keeps its ID only through the tracker's predictions).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from camvlp.model.linecode import FrameFormat
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.partial import ChipEvidence, read_partials
from camvlp.pipeline.decode.result import StripeDecode
from camvlp.pipeline.track.predict import Sighting, remember, sighted_pixels

__all__ = ["Gathering", "LightTracks"]


@dataclass(frozen=True)
class Gathering:
    """A frame's lights after their pieces of code were gathered (:meth:`LightTracks.gather`).

    Attributes
    ----------
    decodes : list of StripeDecode
        The frame's decodes, with the IDs the gathered chips say (``method`` ``"gathered"``)
        given to the lights the decoders left without one and the track does not know.
    gathered : set of int
        Those lights.
    reversed : bool or None
        The readout's direction the gathered chips say, when it was not known: two lights or
        more read one way (each an ID whose frame read backwards is no ID's) and none the
        other; else None.
    """

    decodes: list
    gathered: set[int]
    reversed: bool | None


class LightTracks:
    """The lights of a video followed by their places in the image.

    Parameters
    ----------
    frame : FrameFormat
        The map's frame format.
    window : int
        Frames whose pieces a light weighs (:class:`~camvlp.pipeline.decode.partial.ChipEvidence`).
    gate : float
        Largest distance from a light's predicted place to the blob that continues it, pixels.
    ambiguity : float
        A blob continues a light only when every other light (and every other blob) is this
        many times farther.
    """

    def __init__(self, frame: FrameFormat, window: int, gate: float, ambiguity: float) -> None:
        self.frame = frame
        self.window = window
        self.gate = gate
        self.ambiguity = ambiguity
        self._seen: dict[int, Sighting] = {}  # each light's last sighting, by its number
        self._evidence: dict[int, ChipEvidence] = {}
        self._next = 0
        self._axis: str | None = None

    def follow(self, blobs, t: float, axis: str) -> list[ChipEvidence]:
        """The lights the blobs of a frame at ``t`` (s) continue, or start.

        Parameters
        ----------
        blobs : sequence of Blob
            The frame's lights (their ``pixel``, pixels).
        t : float
            The frame's time, s (later than the last frame's).
        axis : str
            The readout axis the stripes are read along; when it changes, every light
            starts over (its pieces were read along the other).

        Returns
        -------
        list of ChipEvidence
            Per blob, its light's pieces (to add the frame's to, and decide).
        """
        if axis != self._axis:
            self._seen, self._evidence, self._axis = {}, {}, axis
        keys = list(self._seen)
        at = sighted_pixels(self._seen, t, math.inf)  # moved on at their velocities
        pred = np.array([at[i] for i in keys]).reshape(-1, 2)
        pixels = np.array([b.pixel for b in blobs], dtype=float).reshape(-1, 2)
        pairs = self._pairs(np.linalg.norm(pixels[:, None, :] - pred[None, :, :], axis=2))
        numbers = []
        for k in range(len(pixels)):
            if k in pairs:
                numbers.append(keys[pairs[k]])
            else:
                numbers.append(self._next)
                self._next += 1
        # the lights no blob continues are dropped; the others' velocities updated
        self._seen = {i: self._seen[i] for i in numbers if i in self._seen}
        remember(self._seen, blobs, numbers, t, math.inf)
        self._evidence = {
            i: self._evidence.get(i) or ChipEvidence(self.frame, self.window) for i in numbers
        }
        return [self._evidence[i] for i in numbers]

    def gather(
        self,
        index: int,
        t: float,
        blobs,
        readable,
        profiles,
        readout: Readout,
        decodes,
        *,
        known=(),
        reversed_readout: bool | None = None,
        rows_per_chip: float | None = None,
    ) -> Gathering:
        """Follow a frame's lights, gather the pieces of code of those the decoders left
        without an ID and the track does not know, and give each the ID its light's pieces
        say (when they say one).

        Parameters
        ----------
        index : int
            The frame's index.
        t : float
            Its time, s.
        blobs : sequence of Blob
            Its lights (their ``pixel``).
        readable : iterable of int
            The lights that show stripes.
        profiles : sequence of ndarray
            Each light's row profile, in the order ``readout`` reads them.
        readout : Readout
            The readout the profiles were read with.
        decodes : sequence of StripeDecode
            Each light's decode.
        known : iterable of int
            Lights whose IDs the track knows (not read; they are followed).
        reversed_readout : bool or None
            Whether the sensor reads the axis backward, when known.
        rows_per_chip : float, optional
            The chip length, rows, when known.
        """
        evidence = self.follow(blobs, t, readout.axis)
        skip = set(known)
        todo = [k for k in sorted(set(readable)) if decodes[k].id is None and k not in skip]
        reads = read_partials(
            [profiles[k] for k in todo], self.frame, readout, rows_per_chip=rows_per_chip
        )
        out, got, says = list(decodes), set(), []
        n = self.frame.n_chips
        for k, read in zip(todo, reads, strict=True):
            if read is not None:
                evidence[k].add(index, read)
            g = evidence[k].decide(index, reversed_readout)
            if not g:
                if g.frames:  # its pieces say why they give no ID
                    d = out[k]
                    out[k] = dataclasses.replace(d, reason=f"{d.reason}; gathered: {g.reason}")
                continue
            says.append(g.reversed)
            rpc = read.rows_per_chip if read is not None else float("nan")
            text = read.chips if read is not None else ""
            out[k] = StripeDecode(
                g.id,
                method="gathered",
                hamming=g.distance,
                rows_per_chip=rpc,
                frames=len(text) / n,
                chips=text,
            )
            got.add(k)
        way = None
        if reversed_readout is None:
            firm = [w for w in says if w is not None]
            for w in (False, True):
                if firm.count(w) >= 2 and (not w) not in firm:
                    way = w
        return Gathering(out, got, way)

    def _pairs(self, dist: np.ndarray) -> dict[int, int]:
        """Blob -> light: each blob's nearest light within the gate, with no rival light for
        the blob, nor rival blob for the light, within ``ambiguity`` times as far."""
        pairs: dict[int, int] = {}
        if dist.size == 0:
            return pairs
        for k in range(dist.shape[0]):
            j = int(np.argmin(dist[k]))
            d = dist[k, j]
            if d > self.gate:
                continue
            near = self.ambiguity * max(d, 1.0)
            rivals = np.count_nonzero(dist[k] < near) + np.count_nonzero(dist[:, j] < near)
            if rivals == 2:  # (the pair itself, once each way)
                pairs[k] = j
        return pairs
