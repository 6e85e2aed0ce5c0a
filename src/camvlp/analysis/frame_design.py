"""Frame formats for a site: enough IDs, errors detected, safe when read backwards, and short
enough for a fixture's disc (``camvlp encode --design``).

A photo reads a fixture's ID when its disc spans a whole frame of chips (the thesis asks for
1.2 frames, a margin for the rows its rim blurs): ``rows / (n_chips * rows_per_chip)``.  More
IDs need more bits, and each bit costs two chips; a check of the ID (``check_bits``, a CRC)
lets the decoder tell a frame read with errors from another ID's; a format is safe under
readout reversal when no ID's frame read backwards is another ID's
(:attr:`~camvlp.model.linecode.FrameFormat.reversed_ids`), so a photo whose readout direction
is not known never reads one ID as another.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from camvlp.model.linecode import CRC_POLYNOMIALS, FrameFormat

__all__ = ["ONE_PHOTO_FRAMES", "FrameDesign", "design_frames"]

#: Frames of rows a disc must span for one photo to read its ID.
ONE_PHOTO_FRAMES = 1.2


@dataclass(frozen=True)
class FrameDesign:
    """A candidate frame format and what it gives.

    Attributes
    ----------
    frame : FrameFormat
    min_distance : int
        Least Hamming distance (chips) between two IDs' frames, any rotation: errors up to
        ``min_distance - 1`` chips are detected, ``(min_distance - 1) // 2`` corrected.
    reversal_pairs : int
        IDs whose frame read backwards is another ID's frame.
    frames_per_disc : float
        Frames of chips a disc of the given rows spans.
    """

    frame: FrameFormat
    min_distance: int
    reversal_pairs: int
    frames_per_disc: float

    @property
    def one_photo(self) -> bool:
        """Whether one photo reads the ID (:data:`ONE_PHOTO_FRAMES` frames a disc or more)."""
        return self.frames_per_disc >= ONE_PHOTO_FRAMES


def design_frames(
    n_fixtures: int,
    rows: float,
    rows_per_chip: float,
    *,
    framings: tuple[tuple[str, str], ...] = (("111", "00"), ("1111", "000")),
) -> list[FrameDesign]:
    """Frame formats with an ID for each of ``n_fixtures`` fixtures (the fewest ID bits that
    give one) that no rotation makes ambiguous and no readout reversal confuses, best first:
    those one photo reads first (the larger ``min_distance``, then the fewer chips), then the
    others (the fewer chips, then the larger ``min_distance``).

    Parameters
    ----------
    n_fixtures : int
        Fixtures that need IDs of their own (1 to 4096).
    rows : float
        Sensor rows a fixture's disc spans along the readout.
    rows_per_chip : float
        Rows one chip lasts (``1 / (chip_rate_hz * row_time_s)``).
    framings : tuple of (str, str)
        The preambles and postambles tried.

    Returns
    -------
    list of FrameDesign
        Empty when no format tried fits.
    """
    if not 1 <= n_fixtures <= 4096:
        raise ValueError(f"n_fixtures must be from 1 to 4096, got {n_fixtures}")
    if not (rows > 0 and rows_per_chip > 0):
        raise ValueError("rows and rows_per_chip must be positive")
    least = max(1, math.ceil(math.log2(n_fixtures)))
    out: list[FrameDesign] = []
    for id_bits in range(least, 13):  # the fewest ID bits that give a format
        for check in (0, *CRC_POLYNOMIALS):
            for pre, post in framings:
                design = _design(pre, id_bits, post, check, rows, rows_per_chip)
                if design is not None:
                    out.append(design)
        if out:
            break
    # those one photo reads, surest first; then the others, shortest first
    out.sort(
        key=lambda d: (
            (not d.one_photo, -d.min_distance, d.frame.n_chips)
            if d.one_photo
            else (True, d.frame.n_chips, -d.min_distance)
        )
    )
    return out


def _design(pre: str, id_bits: int, post: str, check: int, rows: float, rows_per_chip: float):
    """The :class:`FrameDesign` of one format, or None when it is not allowed, ambiguous or
    confused by a readout reversal."""
    try:
        frame = FrameFormat(pre, id_bits, post, check)
    except ValueError:
        return None
    pairs = int((frame.reversed_ids >= 0).sum())
    if pairs:
        return None
    return FrameDesign(frame, frame.min_distance, pairs, rows / (frame.n_chips * rows_per_chip))
