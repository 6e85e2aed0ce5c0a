"""Stage 1, detect: the lit fixtures of a photo, each one region with its disc's outline and
centre, and the axis its stripes run along.

:func:`~camvlp.pipeline.detect.candidates.detect_fixtures` finds candidates on a reduced copy
of the photo (:mod:`~camvlp.pipeline.detect.candidates`), splits regions that hold several
lights whose glows join (:mod:`~camvlp.pipeline.detect.touching`,
:mod:`~camvlp.pipeline.detect.chords`) and works each one at full resolution
(:mod:`~camvlp.pipeline.detect.refine`).
"""

from camvlp.pipeline.detect.blob import Blob
from camvlp.pipeline.detect.candidates import Detection, detect_fixtures

__all__ = ["Blob", "Detection", "detect_fixtures"]
