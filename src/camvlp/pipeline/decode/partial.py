"""The chips of a disc that shows less than a frame of its code, and an ID from such chips
gathered over a video's frames.

A fixture repeats its frame (preamble, ID, check bits, postamble) without gaps, and a video's
frames do not start in step with it: a disc too short for a whole frame shows another stretch
of the code in each frame.  Two steps read them:

**Reading** (:func:`read_partials`).  The run-length decoder's chips of the profile
(:func:`~camvlp.pipeline.decode.run_decode.profile_chips`), each with its run's margin as its
confidence, are cut into *pieces* at every chip that is not sure: a run whose length is not
clearly one chip or two (a margin under
:data:`~camvlp.pipeline.decode.manchester.MIN_FAST_MARGIN`) makes its own count, and so the
place of every chip after it, doubtful.  A piece of fewer than :data:`MIN_PIECE` chips, or
one that breaks the Manchester rule (no phase in which every pair of chips is ``01`` or
``10``), is dropped.  Only a profile whose sure chips do not cover a whole frame is read so;
the others are the single-photo decoders'.

**Where a piece sits in the code, and the ID.**  Each piece is held against every rotation
of every ID's frame (:meth:`~camvlp.model.linecode.FrameFormat.stretch_distances`), read
both ways along the readout's axis; its *fit* to an ID is its least distance from any
rotation, and its place in that ID's cycle is the rotation of that least distance (rotation
0 starts at the preamble: the preamble anchors the cycle).  Each frame's piece is placed on
its own, by its chips, and not by the clock:

* placing a frame's piece from the time since an earlier frame needs that time, the chip
  rate and the row time to a fraction of a chip over the whole gathering (a chip lasts
  0.1 ms at 10,000 chips/s): a phone's frame times (a variable frame rate, rounded time stamps), an
  LED's clock (its crystal's tolerance) and a row time that is not always known each miss
  that within a few frames, and a piece placed one chip off reads as other chips;
* chaining the pieces by their overlap with what was gathered (an assembly) commits to a
  place for each: one placed wrong spoils the cycle for good.

So each ID is weighed on its own (:class:`ChipEvidence`): its distance is the sum, over the
pieces of the last frames, of each piece's fit to it (the likelihood of the ID with each
frame's phase a nuisance parameter of its own, at its best).  The best ID (with its
direction, when the readout's is not known) is taken only when

* its pieces hold a whole frame: each at its place (a piece with two equally good places
  counts for none) they cover every chip of its frame;
* they fit it: at most ``(min_distance - 1) // 2`` chips disagree in all (the errors a whole
  frame's decode corrects, :attr:`~camvlp.model.linecode.FrameFormat.min_distance`);
* it stands apart: every other ID (read either way, when the readout's direction is not
  known) is ``min_distance`` chips or more farther, as another ID's whole frame is.

A wrong ID then needs at least ``min_distance`` sure chips read wrong, each of them as that
ID's.  Anything else (too few chips, chips that fit no ID, two IDs nearly alike) gives no ID,
with the reason.  When the readout's direction is not known, an ID whose frame read
backwards is another's (:attr:`~camvlp.model.linecode.FrameFormat.reversed_ids`) ties with
that one and is refused (one whose frame read backwards is its own is given, its direction
untold); the direction is told when the other way fits the ID ``min_distance`` chips worse.
A frame period that is a whole number of the code's periods shows a still disc the same
stretch in every frame (it moves on only as the disc moves along the readout).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from camvlp.model.linecode import FrameFormat
from camvlp.model.readout import Readout
from camvlp.pipeline.decode.manchester import MIN_FAST_MARGIN
from camvlp.pipeline.decode.run_decode import profile_chips

__all__ = ["MIN_PIECE", "ChipEvidence", "Gathered", "PartialRead", "piece_fits", "read_partials"]

#: Fewest chips a piece must have to be kept.
MIN_PIECE = 8


@dataclass(frozen=True)
class PartialRead:
    """What one light's stripes show of its code in one frame, less than a frame.

    Attributes
    ----------
    pieces : tuple of ndarray of uint8
        Its pieces (each shape (L,), chips 1 = on), in the order of the readout's axis read
        forward (top to bottom, left to right), whichever way the sensor read it.
    fits : ndarray of int16, shape (len(pieces), 2, n_ids)
        Each piece's least distance (chips) from any rotation of each ID's frame, its chips
        in the sensor's time order if it read the axis forward (``[:, 0]``) or backward
        (``[:, 1]``).
    chips : str
        The chips read (``?`` where unsure), in the sensor's order.
    rows_per_chip : float
        The chip length read with, rows.
    """

    pieces: tuple[np.ndarray, ...]
    fits: np.ndarray = field(repr=False)
    chips: str = ""
    rows_per_chip: float = float("nan")


def read_partials(
    profiles, frame: FrameFormat, readout: Readout, *, rows_per_chip: float | None = None
) -> list[PartialRead | None]:
    """The pieces of code each profile that shows less than a frame holds (see the module's
    docstring); None for a profile that holds a whole frame, or whose stripes cannot be
    read, or that has no piece.

    Parameters
    ----------
    profiles : sequence of ndarray, each shape (n_k,)
        Row profiles in the order ``readout`` reads them.
    frame : FrameFormat
    readout : Readout
        The readout the profiles were read with (its direction may be a guess: the pieces
        are kept in the axis' order and fit both ways).
    rows_per_chip : float, optional
        The chip length when known, rows; else each profile's is measured.
    """
    got = profile_chips(profiles, rows_per_chip=rows_per_chip)
    out: list[PartialRead | None] = [None] * len(profiles)
    n = frame.n_chips
    cut: dict[int, list[np.ndarray]] = {}
    for k, (chips, known, _, _, conf), t in zip(got.which, got.read, got.t.tolist(), strict=True):
        seen = np.bincount(np.flatnonzero(known) % n, minlength=n)
        if seen.min() > 0:
            continue  # a whole frame: the single-photo decoders'
        pieces = _pieces(chips, known & (conf >= MIN_FAST_MARGIN))
        if pieces:
            cut[k] = [p[::-1] if readout.reversed else p for p in pieces]
            out[k] = PartialRead((), np.zeros((0, 2, frame.n_ids), np.int16), "", t)
    if not cut:
        return out
    fits = piece_fits(frame, [p for k in cut for p in cut[k]])
    at = 0
    texts = dict(zip(got.which, (r[2] for r in got.read), strict=True))
    for k, pieces in cut.items():
        read = out[k]
        out[k] = PartialRead(
            tuple(pieces), fits[at : at + len(pieces)], texts[k], read.rows_per_chip
        )
        at += len(pieces)
    return out


def piece_fits(frame: FrameFormat, pieces) -> np.ndarray:
    """Each piece's fit to each ID: its least distance from any rotation of the ID's frame,
    read forward and backward (both in one matrix product).

    Parameters
    ----------
    frame : FrameFormat
    pieces : sequence of ndarray of uint8, each shape (L,)
        Chips in the order of the readout's axis read forward.

    Returns
    -------
    ndarray of int16, shape (len(pieces), 2, n_ids)
        As :attr:`PartialRead.fits`.
    """
    pieces = list(pieces)
    if not pieces:
        return np.zeros((0, 2, frame.n_ids), np.int16)
    both = [(p, None) for p in pieces] + [(p[::-1], None) for p in pieces]
    dist = frame.stretch_distances(both).min(axis=2).astype(np.int16)
    return dist.reshape(2, len(pieces), -1).transpose(1, 0, 2)


def _pieces(chips: np.ndarray, sure: np.ndarray) -> list[np.ndarray]:
    """The stretches of sure chips, :data:`MIN_PIECE` long or more, that keep the Manchester
    rule."""
    out = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], sure.view(np.int8), [0]])))
    for a, b in zip(edges[0::2].tolist(), edges[1::2].tolist(), strict=True):
        piece = chips[a:b]
        if piece.size >= MIN_PIECE and _manchester(piece):
            out.append(piece)
    return out


def _manchester(chips: np.ndarray) -> bool:
    """Whether in one of the two phases every whole pair of chips is ``01`` or ``10``."""
    for phase in (0, 1):
        c = chips[phase:]
        c = c[: c.size - c.size % 2].reshape(-1, 2)
        if np.all(c[:, 0] != c[:, 1]):
            return True
    return False


#: The distance of no hypothesis (a direction ruled out, an ID left out).
_NONE = np.iinfo(np.int64).max // 4


@dataclass(frozen=True)
class Gathered:
    """What a light's gathered chips say (:meth:`ChipEvidence.decide`).

    Attributes
    ----------
    id : int or None
        The ID, or None (``reason`` says why).
    reversed : bool or None
        With an ID: whether the sensor read the axis backward (as given, or as the chips
        say); None when they fit it both ways alike (an ID whose frame read backwards is its
        own) or without an ID.
    distance : int
        Chips of the pieces that disagree with the best ID's frame, each at its place (-1
        without pieces).
    runner_up : int
        The same for the next best ID (or direction).
    covered : int
        Chips of the best ID's frame the pieces cover at their places.
    frames : int
        Frames whose pieces were weighed.
    reason : str
        Why there is no ID ("" with one).
    """

    id: int | None
    reversed: bool | None = None
    distance: int = -1
    runner_up: int = -1
    covered: int = 0
    frames: int = 0
    reason: str = ""

    def __bool__(self) -> bool:
        return self.id is not None


class ChipEvidence:
    """One light's pieces of code over a video's frames, and the ID they say (see the
    module's docstring).

    Parameters
    ----------
    frame : FrameFormat
    window : int
        The pieces of this many frames count: those of the last ``window`` frames before the
        one decided (an old misread leaves the evidence after it).
    """

    def __init__(self, frame: FrameFormat, window: int) -> None:
        if window < 1:
            raise ValueError(f"window must be at least 1, got {window!r}")
        self.frame = frame
        self.window = int(window)
        self._reads: list[tuple[int, PartialRead]] = []

    def add(self, index: int, read: PartialRead) -> None:
        """Gather the pieces ``read`` in frame ``index`` (frames in increasing order)."""
        if read.pieces:
            self._reads.append((int(index), read))

    def decide(self, index: int, reversed_readout: bool | None = None) -> Gathered:
        """The ID the pieces of the frames up to ``index`` say, or why none.

        Parameters
        ----------
        index : int
            The current frame (the pieces of frames ``index - window + 1`` to ``index``
            count).
        reversed_readout : bool or None
            Whether the sensor reads the axis backward, when known; None weighs both ways.
        """
        self._reads = [(i, r) for i, r in self._reads if i > index - self.window]
        frame = self.frame
        frames = len({i for i, _ in self._reads})
        if not self._reads:
            return Gathered(None, reason="no chips gathered")
        fits = np.concatenate([r.fits for _, r in self._reads]).sum(axis=0, dtype=np.int64)
        if reversed_readout is not None:  # the other way is no hypothesis
            fits[1 - int(reversed_readout)] = _NONE
        way, fid = divmod(int(fits.argmin()), frame.n_ids)
        best = int(fits[way, fid])
        # the runner-up: the best other ID, either way (the same ID read the other way is
        # the same ID: it says only that the direction is not told)
        others = fits.copy()
        others[:, fid] = _NONE
        other = int(others.min(axis=0).argmin())
        second = int(others[:, other].min())
        covered = self._covered(fid, bool(way))
        common = dict(distance=best, runner_up=second, covered=covered, frames=frames)
        n, d = frame.n_chips, frame.min_distance
        if covered < n:
            why = f"{covered} of the {n} chips of a frame gathered in {frames} frames"
            return Gathered(None, reason=why, **common)
        if best > (d - 1) // 2:
            why = f"the chips gathered fit no ID: {best} disagree with the nearest ID's frame"
            return Gathered(None, reason=why, **common)
        if second - best < d:
            why = (
                f"the chips gathered fit ID {fid} and ID {other} too nearly alike "
                f"({best} and {second} chips off)"
            )
            return Gathered(None, reason=why, **common)
        rev = int(frame.reversed_ids[fid])
        if reversed_readout is None and rev not in (-1, fid):  # (tied: refused above too)
            why = f"ID {fid} read backwards is ID {rev}: the readout's direction must be known"
            return Gathered(None, reason=why, **common)
        told = int(fits[1 - way, fid]) - best >= d  # the other way fits clearly worse
        return Gathered(fid, bool(way) if told else None, **common)

    def _covered(self, fid: int, backward: bool) -> int:
        """Chips of ID ``fid``'s frame the pieces cover, each at its one best place, their
        chips in the time order of a sensor that reads the axis ``backward`` or not."""
        n = self.frame.n_chips
        stream = self.frame.codebook[fid]
        hit = np.zeros(n, bool)
        for _, read in self._reads:
            for p in read.pieces:
                c = p[::-1] if backward else p
                at = (np.arange(n)[:, None] + np.arange(c.size)[None, :]) % n  # (rotation, chip)
                off = (stream[at] != c[None, :]).sum(axis=1)
                best = np.flatnonzero(off == off.min())
                if best.size == 1:
                    hit[at[int(best[0])]] = True
        return int(hit.sum())
