"""What the stripes of one light say: one record for every decoder (:class:`StripeDecode`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["StripeDecode"]

_NAN = math.nan


@dataclass(frozen=True)
class StripeDecode:
    """What the stripes of one light say, as one of the decoders read them.

    ``method`` says which: ``"runs"`` the run-length decoder
    (:mod:`camvlp.pipeline.decode.run_decode`), ``"model"`` the forward model fitted to every
    ID (:mod:`camvlp.pipeline.decode.model`), ``"frequency"`` a beacon's square wave held against
    each map frequency (:mod:`camvlp.pipeline.decode.frequency`), ``""`` not read.

    Attributes
    ----------
    id : int or None
        The ID (Manchester) or map fixture (frequency) the stripes say, or None.
    reason : str
        Why there is no ID ("" when there is one).
    method : str
        The decoder that read it (above).
    margin : float
        How sure the ID is, on one scale for every decoder that weighs likelihoods: the
        decimal log of the likelihood ratio of the ID over the best other ID (or frequency)
        of the map, from the fit's residuals and its noise (4 means 10,000 times likelier;
        the model fit needs 4, a frequency 5.4).  The model fit takes its noise from the
        best fit's residual per degree of freedom, inflated for residuals correlated from
        line to line, and caps the margin at 99; a frequency takes it from the chosen
        wave's residual per free line, and its margin is inf when the map has one
        frequency.  NaN when not weighed (the run-length decoder: see ``run_margin``).
    run_margin : float
        The run-length decoder's confidence, 0 to 1: how far the worst run length is from a
        decision boundary (1: every run exactly one or two chips long); NaN for the others.
    hamming : int
        Chips that disagree with the decoded (or nearest) ID; -1 when no chips were
        thresholded (the model fit, a frequency).
    rows_per_chip : float
        The chip length, sensor lines (a frequency: half its period); NaN when not measured.
    frames : float
        Frames of the code the profile spans (a frequency: its periods).
    chips : str
        The chips read (``"?"`` where a run's count was uncertain), or the model's best ID's
        chips from the profile's first line on, one frame.
    bleed_rows : float
        How much longer bright runs are than their chip count says (run-length decoder).
    runner_up : int or None
        The best other ID of the map (model fit).
    phase_chips : float
        Chip of the frame at the start of the first line's exposure (model fit).
    gain, offset : float
        Fitted gain and offset, profile units (model fit).
    residual_rms : float
        RMS residual of the best fit, profile units (model fit).
    unexplained : float
        Fraction of the profile's variance the best fit leaves (model fit; 0 = perfect).
    fitted : ndarray, shape (n,), or None
        The best fit's model of the profile (model fit).
    frame_rss : float
        Weighted residual sum of squares of the best fit of any ID of the format (in the map
        or not): how well the stripes read as a frame at all (compares readout directions).
    noise_var : float
        The noise variance the margin assumes, profile units squared (model fit).
    outside_id : int or None
        An ID of the format not in the map that the stripes fit clearly better than any
        other (the light sends it), else None.
    knee : float
        The best ID's saturation knee for this light, a fraction of its on-level (model fit).
    candidates : tuple of int
        When two or more IDs of the map fit almost equally: each of them, best first (the
        pose may tell which).  Else empty.
    """

    id: int | None
    reason: str = ""
    method: str = ""
    margin: float = _NAN
    run_margin: float = _NAN
    hamming: int = -1
    rows_per_chip: float = _NAN
    frames: float = _NAN
    chips: str = ""
    bleed_rows: float = _NAN
    runner_up: int | None = None
    phase_chips: float = _NAN
    gain: float = _NAN
    offset: float = _NAN
    residual_rms: float = _NAN
    unexplained: float = _NAN
    fitted: np.ndarray | None = field(default=None, repr=False, compare=False)
    frame_rss: float = _NAN
    noise_var: float = _NAN
    outside_id: int | None = None
    knee: float = _NAN
    candidates: tuple[int, ...] = ()

    def __bool__(self) -> bool:
        return self.id is not None
