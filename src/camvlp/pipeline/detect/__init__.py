"""Stage 1, detect: the lit fixtures of a photo, each one region with its disc's outline and
centre, and the axis its stripes run along.

:func:`~camvlp.pipeline.detect.candidates.detect_fixtures` finds candidates on a reduced copy
of the photo (:mod:`~camvlp.pipeline.detect.candidates`), splits regions that hold several
lights whose glows join (:mod:`~camvlp.pipeline.detect.touching`, by the peaks of their
brighter parts, :mod:`~camvlp.pipeline.detect.peaks`, their codes,
:mod:`~camvlp.pipeline.detect.codes`, their faces in the dark stripes,
:mod:`~camvlp.pipeline.detect.faces`, or their clipped chords,
:mod:`~camvlp.pipeline.detect.chords`) and works each one at full resolution
(:mod:`~camvlp.pipeline.detect.refine`: the disc with its stripes bridged,
:mod:`~camvlp.pipeline.detect.disc`, its readout axis, :mod:`~camvlp.pipeline.detect.readout`,
and the ellipse fitted to its edge points).  What it finds is a
:class:`~camvlp.pipeline.detect.blob.Blob` each.
"""

from camvlp.pipeline.detect.blob import Blob
from camvlp.pipeline.detect.candidates import Detection, detect_fixtures

__all__ = ["Blob", "Detection", "detect_fixtures"]
